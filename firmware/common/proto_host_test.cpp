// Host-side driver for the unit tests of proto.cpp (tests/firmware/test_proto_host.py), built with g++.
// Reads commands from stdin, one per line, and prints one result line each:
//   F <hex bytes>   feed the bytes to a LineReader: prints the events, "R:<line>" or "T" (TOOLONG), space separated
//   P <hex bytes>   proto_parse of the line: "<status> <word> <nargs> <bad> <arg0> <arg1> <arg2>"
//   U <decimal>     LineWriter u32 + finish: the line without its '\n'
//   I <decimal>     LineWriter i32 + finish
//   C <hex bytes>   crc8 of the bytes: two upper-case hex digits
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "proto.h"

static size_t unhex(const char *s, char *out, size_t cap) {
  size_t n = 0;
  while (s[0] && s[1] && n < cap) {
    char h[3] = {s[0], s[1], 0};
    out[n++] = (char)strtoul(h, NULL, 16);
    s += 2;
  }
  return n;
}

int main() {
  static char line[100000];
  static char bytes[50000];
  LineReader reader;
  while (fgets(line, sizeof line, stdin)) {
    line[strcspn(line, "\n")] = 0;
    if (line[0] == 'F') {
      size_t n = unhex(line + 2, bytes, sizeof bytes);
      reader.reset();
      for (size_t i = 0; i < n; i++) {
        LineEvent ev = reader.feed(bytes[i]);
        if (ev == LINE_READY) {
          printf(" R:");
          for (uint8_t k = 0; k < reader.len; k++) printf("%02x", (unsigned char)reader.buf[k]);
          reader.reset();
        } else if (ev == LINE_TOOLONG) {
          printf(" T");
          reader.reset();
        }
      }
      printf("\n");
    } else if (line[0] == 'P') {
      size_t n = unhex(line + 2, bytes, PROTO_MAX_LINE);
      char buf[PROTO_MAX_LINE + 1];
      memcpy(buf, bytes, n);
      buf[n] = 0;
      Command cmd;
      ProtoStatus st = proto_parse(buf, (uint8_t)n, &cmd);
      const char *names[] = {"OK", "EMPTY", "CHECKSUM"};
      printf("%s ", names[st]);
      for (const char *w = cmd.word; *w; w++) printf("%02x", (unsigned char)*w);
      printf(" %u %u", cmd.nargs, cmd.bad);
      for (int i = 0; i < PROTO_MAX_ARGS; i++) printf(" %ld", (long)(i < cmd.nargs && !cmd.bad ? cmd.arg[i] : 0));
      printf("\n");
    } else if (line[0] == 'C') {
      size_t n = unhex(line + 2, bytes, 255);
      printf("%02X\n", crc8(bytes, (uint8_t)n));
    } else if (line[0] == 'U' || line[0] == 'I') {
      LineWriter w;
      w.begin();
      if (line[0] == 'U') w.u32((uint32_t)strtoull(line + 2, NULL, 10));
      else w.i32((int32_t)strtoll(line + 2, NULL, 10));
      uint8_t n = w.finish();
      fwrite(w.buf, 1, n - 1, stdout);
      printf("\n");
    }
    fflush(stdout);
  }
  return 0;
}
