// Line framing, checksums, argument parsing and fast integer formatting shared by both boards.
//
// Implements the framing of firmware/PROTOCOL.md: ASCII lines ending in '\n' (a '\r' just before it is
// ignored), at most PROTO_MAX_LINE characters, a mandatory "*hh" suffix (the CRC-8 of crc8.h over the bytes
// before '*', two hex digits).
// Plain C++ with no Arduino dependency, so the same code can be compiled for the host.
#ifndef FIRMWARE_COMMON_PROTO_H
#define FIRMWARE_COMMON_PROTO_H

#include <stdint.h>

#include "crc8.h"
#include "flash.h"
#include "rig_config.h"

#define PROTO_MAX_LINE 63   // characters before '\n'
// The most arguments any command takes: SEG's 3, or MSEG's 1 + RIG_AXES.
#define PROTO_MAX_ARGS (RIG_AXES + 1 > 3 ? RIG_AXES + 1 : 3)
// Longest line a board sends, "*hh\n" included: 72, or 96 for a DAQ line of several channels and axes
// ("D,<seq>,<t_us>" + RIG_CHANNELS ADC counts + RIG_AXES step counts: at most 91 + 4 characters).
#define PROTO_OUT_MAX (RIG_CHANNELS + RIG_AXES > 2 ? 96 : 72)

// Result of feeding one received byte to the line assembler.
enum LineEvent : uint8_t { LINE_NONE = 0, LINE_READY, LINE_TOOLONG };

// Accumulates received bytes into lines; a line longer than PROTO_MAX_LINE is discarded up to its '\n'
// and reported once (LINE_TOOLONG) when that '\n' arrives, so every line gets exactly one reply.
// A '\r' directly before the '\n' is dropped; any other '\r' is part of the line (so a byte corrupted into
// '\r' is caught by the checksum instead of silently deleting itself).
struct LineReader {
  char buf[PROTO_MAX_LINE + 1];
  uint8_t len;
  uint8_t overflow;
  uint8_t cr;  // a '\r' arrived and is held back: dropped if '\n' follows, placed in the line otherwise
  void reset() { len = 0; overflow = 0; cr = 0; }
  LineEvent feed(char c);
  void place(char c);
};

// Outcome of parsing a line, in the order a command is checked (PROTOCOL.md).
enum ProtoStatus : uint8_t {
  PROTO_OK = 0,
  PROTO_EMPTY,      // blank line: ignored, no reply
  PROTO_CHECKSUM,   // "*hh" present but wrong (CRC-8 mismatch) or malformed
  PROTO_NOCRC,      // no "*hh" at all: refused (every command must carry its checksum)
};

// A parsed command: the command word and up to PROTO_MAX_ARGS integer arguments.
// Integers outside int32 saturate to INT32_MIN/INT32_MAX so that the range checks reject them (ERR RANGE).
struct Command {
  const char *word;   // points into the line buffer, NUL-terminated
  uint8_t nargs;      // number of arguments found (may exceed PROTO_MAX_ARGS: then only the first are parsed)
  uint8_t bad;        // an argument is not a decimal integer, or an empty token (double/trailing space)
  int32_t arg[PROTO_MAX_ARGS];
};

// True when the command has exactly n well-formed integer arguments (otherwise the reply is ERR ARG).
inline bool proto_args_ok(const Command *cmd, uint8_t n) { return !cmd->bad && cmd->nargs == n; }

// Verifies and strips the checksum (PROTO_NOCRC without one), splits the words and parses the integer arguments.
// Modifies `line` in place (NUL-terminates the words). `len` is strlen(line).
ProtoStatus proto_parse(char *line, uint8_t len, Command *cmd);

// True when the command word equals `w`, a string in flash (PSTR("...")).
bool proto_is(const Command *cmd, const char *w);

// Builds one outgoing line and appends "*hh\n" (the CRC-8 of the line, upper-case hex).
struct LineWriter {
  char buf[PROTO_OUT_MAX];
  uint8_t len;
  void begin() { len = 0; }
  void put(char c) { if (len < PROTO_OUT_MAX - 4) buf[len++] = c; }
  void str(const char *s) { while (*s) put(*s++); }
  // Appends a string kept in flash (PSTR("...")).
  void str_P(const char *s) {
    for (char c; (c = (char)pgm_read_byte(s)) != 0; s++) put(c);
  }
  void u32(uint32_t v);
  void i32(int32_t v);
  // Appends "*hh\n"; returns the total length.
  uint8_t finish();
};

#endif
