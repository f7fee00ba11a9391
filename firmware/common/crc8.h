// The CRC-8 of firmware/PROTOCOL.md, shared by both boards (and compiled for the host in the unit tests).
//
// Width 8, polynomial 0x65 (x^8 + x^6 + x^5 + x^2 + 1), reflected input and output, initial value 0xFF, final
// XOR 0x00; check value crc8("123456789") = 0x20. Table-driven: the 256-byte table is built at compile time
// from the polynomial and kept in flash (PROGMEM), so it costs no RAM.
#ifndef FIRMWARE_COMMON_CRC8_H
#define FIRMWARE_COMMON_CRC8_H

#include <stdint.h>

#define CRC8_POLY 0x65            // normal (MSB-first) form, without the x^8 term
#define CRC8_POLY_REFLECTED 0xA6  // the same polynomial as a right-shifting register sees it
#define CRC8_INIT 0xFF

// Continues a CRC over one byte.
uint8_t crc8_update(uint8_t crc, uint8_t byte);

// CRC-8 of n bytes (from the initial value).
uint8_t crc8(const char *s, uint8_t n);

#endif
