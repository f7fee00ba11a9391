// Reply and line output shared by both boards (see reply.h).
#include "reply.h"

void Reply::send() {
  uint8_t n = line.finish();
  write((const uint8_t *)line.buf, n);
}

void Reply::text(const char *s) {
  line.begin();
  line.str_P(s);
  send();
}

void Reply::err(const char *code, const char *text) {
  line.begin();
  line.str_P(PSTR("ERR "));
  line.str_P(code);
  line.put(' ');
  line.str_P(text);
  send();
}

void Reply::word_u32(const char *word, uint32_t v) {
  line.begin();
  line.str_P(word);
  line.put(' ');
  line.u32(v);
  send();
}

void Reply::word_i32(const char *word, int32_t v) {
  line.begin();
  line.str_P(word);
  line.put(' ');
  line.i32(v);
  send();
}
