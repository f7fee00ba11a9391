// Reply and line output shared by both boards (board-independent).
//
// A Reply builds one outgoing line in its LineWriter and hands the finished bytes ("<body>*hh\n") to the
// write function the board supplies (Serial.write on the boards; anything on the host). Plain C++ with no
// Arduino dependency, like proto.h. Every string argument is a string in flash: PSTR("...").
#ifndef FIRMWARE_COMMON_REPLY_H
#define FIRMWARE_COMMON_REPLY_H

#include <stdint.h>

#include "proto.h"

// Writes n bytes to the link (blocking is allowed: replies are short and rare).
typedef void (*ReplyWriteFn)(const uint8_t *buf, uint8_t n);

struct Reply {
  LineWriter line;
  ReplyWriteFn write;

  // Start a line; then append with line.put/str/u32/i32 and finish with send().
  void begin() { line.begin(); }
  // Appends the checksum and the newline and writes the line.
  void send();
  // "<text>"
  void text(const char *s);
  // "ERR <code> <text>"
  void err(const char *code, const char *text);
  // "<word> <v>", e.g. word_u32(PSTR("OK RATE"), 500) -> "OK RATE 500"
  void word_u32(const char *word, uint32_t v);
  // "<word> <v>", signed
  void word_i32(const char *word, int32_t v);
};

#endif
