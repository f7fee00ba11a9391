// Strings in program memory (flash) on the AVR, ordinary strings on the host, so that shared code can take
// PSTR("...") literals and the same sources compile for both: the boards' RAM holds no constant text.
#ifndef FIRMWARE_COMMON_FLASH_H
#define FIRMWARE_COMMON_FLASH_H

#ifdef __AVR__
#include <avr/pgmspace.h>
#else
#include <stdint.h>
#include <string.h>
#define PROGMEM
#define PSTR(s) (s)
#define pgm_read_byte(p) (*(const uint8_t *)(p))
#define pgm_read_word(p) (*(const uint16_t *)(p))
#define pgm_read_dword(p) (*(const uint32_t *)(p))
#define strcmp_P strcmp
#endif

#endif
