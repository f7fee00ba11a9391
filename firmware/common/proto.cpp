// Line framing, CRC-8 checksums, argument parsing and fast integer formatting (see proto.h).
#include "proto.h"

#include <string.h>

LineEvent LineReader::feed(char c) {
  if (c == '\n') {
    LineEvent ev = overflow ? LINE_TOOLONG : LINE_READY;
    buf[overflow ? 0 : len] = '\0';
    if (overflow) len = 0;
    overflow = 0;
    cr = 0;  // PROTOCOL.md: a '\r' just before '\n' is ignored
    return ev;
  }
  if (cr) {  // the held '\r' was not followed by '\n': it belongs to the line
    cr = 0;
    place('\r');
  }
  if (c == '\r') cr = 1;
  else place(c);
  return LINE_NONE;
}

void LineReader::place(char c) {
  if (overflow) return;
  if (len >= PROTO_MAX_LINE) {
    overflow = 1;  // discard the rest of the line, answer once at its '\n'
    len = 0;
    return;
  }
  buf[len++] = c;
}

static int8_t hexval(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

// Parses "-?[0-9]+" into a saturated int32; false if the token is not a decimal integer.
static bool parse_int(const char *s, int32_t *out) {
  bool neg = false;
  if (*s == '-') { neg = true; s++; }
  if (!*s) return false;
  uint32_t v = 0;
  bool big = false;
  for (; *s; s++) {
    if (*s < '0' || *s > '9') return false;
    if (v > 214748364UL) big = true;
    v = v * 10 + (uint8_t)(*s - '0');
    if (v > 2147483647UL) big = true;
    if (big) v = 2147483647UL;  // keep scanning: a later non-digit still makes it an ARG error
  }
  if (big) { *out = neg ? (int32_t)(-2147483647L - 1) : (int32_t)2147483647L; return true; }
  *out = neg ? -(int32_t)v : (int32_t)v;
  return true;
}

ProtoStatus proto_parse(char *line, uint8_t len, Command *cmd) {
  cmd->word = line;
  cmd->nargs = 0;
  cmd->bad = 0;
  if (len == 0) return PROTO_EMPTY;
  char *star = (char *)memchr(line, '*', len);
  if (!star) return PROTO_NOCRC;
  uint8_t body = (uint8_t)(star - line);
  if (len != body + 3) return PROTO_CHECKSUM;  // exactly two hex digits must follow '*'
  int8_t hi = hexval(star[1]), lo = hexval(star[2]);
  if (hi < 0 || lo < 0) return PROTO_CHECKSUM;
  if ((uint8_t)((hi << 4) | lo) != crc8(line, body)) return PROTO_CHECKSUM;
  *star = '\0';
  len = body;
  if (len == 0) return PROTO_EMPTY;
  // Split on single spaces: an empty token (double, leading or trailing space) is an ARG error.
  char *p = line;
  char *tok[1 + PROTO_MAX_ARGS + 1];
  uint8_t ntok = 0;
  bool empty_token = false;
  for (;;) {
    char *sp = strchr(p, ' ');
    if (sp) *sp = '\0';
    if (*p == '\0') empty_token = true;
    if (ntok < sizeof(tok) / sizeof(tok[0])) tok[ntok] = p;
    ntok++;
    if (!sp) break;
    p = sp + 1;
  }
  cmd->word = tok[0];
  cmd->nargs = (uint8_t)(ntok - 1);
  cmd->bad = empty_token;
  uint8_t n = cmd->nargs < PROTO_MAX_ARGS ? cmd->nargs : PROTO_MAX_ARGS;
  for (uint8_t i = 0; i < n && !cmd->bad; i++) {
    if (!parse_int(tok[1 + i], &cmd->arg[i])) cmd->bad = 1;
  }
  return PROTO_OK;
}

bool proto_is(const Command *cmd, const char *w) { return strcmp_P(cmd->word, w) == 0; }

// Decimal conversion by subtracting powers of ten: no 32-bit division (slow on the AVR), at most
// 9 subtractions per digit.
static const uint32_t POW10[10] PROGMEM = {1000000000UL, 100000000UL, 10000000UL, 1000000UL, 100000UL,
                                   10000UL,      1000UL,      100UL,      10UL,      1UL};

static const uint16_t POW10_16[4] PROGMEM = {1000U, 100U, 10U, 1U};

// Values under 10000 (ADC counts, step counts) take 16-bit subtractions; larger ones skip their leading
// zeros by comparisons first (a DAQ line of four channels holds ten numbers: the formatting is most of its
// cost on the board).
void LineWriter::u32(uint32_t v) {
  if (v < 10000UL) {
    uint16_t w = (uint16_t)v;
    uint8_t i = 0;
    while (i < 3 && w < pgm_read_word(&POW10_16[i])) i++;
    for (; i < 4; i++) {
      uint16_t p = pgm_read_word(&POW10_16[i]);
      char d = '0';
      while (w >= p) { w -= p; d++; }
      put(d);
    }
    return;
  }
  uint8_t i = 0;
  while (v < pgm_read_dword(&POW10[i])) i++;  // v >= 10000: stops by i = 5
  for (; i < 10; i++) {
    uint32_t p = pgm_read_dword(&POW10[i]);
    char d = '0';
    while (v >= p) { v -= p; d++; }
    put(d);
  }
}

void LineWriter::i32(int32_t v) {
  if (v < 0) { put('-'); u32((uint32_t)0 - (uint32_t)v); }
  else u32((uint32_t)v);
}

static const char HEX[] = "0123456789ABCDEF";

uint8_t LineWriter::finish() {
  uint8_t x = crc8(buf, len);
  buf[len++] = '*';
  buf[len++] = HEX[x >> 4];
  buf[len++] = HEX[x & 15];
  buf[len++] = '\n';
  return len;
}
