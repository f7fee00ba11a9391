// The CRC-8 of firmware/PROTOCOL.md (see crc8.h).
#include "crc8.h"

#include "flash.h"

// One table entry, computed by the compiler: the byte shifted bit by bit through the reflected register.
static constexpr uint8_t shift8(uint8_t c, uint8_t k) {
  return k == 0 ? c : shift8((uint8_t)((c & 1) ? ((c >> 1) ^ CRC8_POLY_REFLECTED) : (c >> 1)), (uint8_t)(k - 1));
}
static_assert(CRC8_POLY_REFLECTED == (((CRC8_POLY & 0x01) << 7) | ((CRC8_POLY & 0x02) << 5) |
                                      ((CRC8_POLY & 0x04) << 3) | ((CRC8_POLY & 0x08) << 1) |
                                      ((CRC8_POLY & 0x10) >> 1) | ((CRC8_POLY & 0x20) >> 3) |
                                      ((CRC8_POLY & 0x40) >> 5) | ((CRC8_POLY & 0x80) >> 7)),
              "CRC8_POLY_REFLECTED must be CRC8_POLY bit-reversed");

#define CRC8_E(n) shift8((uint8_t)(n), 8)
#define CRC8_R4(n) CRC8_E(n), CRC8_E(n + 1), CRC8_E(n + 2), CRC8_E(n + 3)
#define CRC8_R16(n) CRC8_R4(n), CRC8_R4(n + 4), CRC8_R4(n + 8), CRC8_R4(n + 12)
#define CRC8_R64(n) CRC8_R16(n), CRC8_R16(n + 16), CRC8_R16(n + 32), CRC8_R16(n + 48)
static const uint8_t CRC8_TABLE[256] PROGMEM = {CRC8_R64(0), CRC8_R64(64), CRC8_R64(128), CRC8_R64(192)};

uint8_t crc8_update(uint8_t crc, uint8_t byte) { return pgm_read_byte(&CRC8_TABLE[crc ^ byte]); }

uint8_t crc8(const char *s, uint8_t n) {
  uint8_t crc = CRC8_INIT;
  while (n--) crc = crc8_update(crc, (uint8_t)*s++);
  return crc;
}
