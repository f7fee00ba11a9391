r"""The CRC-8 that ends every line of the serial protocol (``firmware/PROTOCOL.md``), standard library only.

Variant (Rocksoft/Williams parameters): width 8, polynomial 0x65 (x^8 + x^6 + x^5 + x^2 + 1; Koopman notation
0xb2, the reciprocal of his 0xa6 "CRC-8K/3", with the same Hamming weights), reflected input and output,
initial value 0xFF, final XOR 0x00. Check value: ``crc8(b"123456789") == 0x20`` (:data:`CHECK`).

It covers the bytes of a line before its ``*`` and is sent as two upper-case hex digits. Reflection makes the
CRC's bit order the UART's (least significant bit first), so a burst on the wire is a burst for the CRC.
Guarantee for a line of up to 63 characters whose framing survives (no byte turned into ``\n``): every 1-bit
error and every burst of up to 8 bits is detected; every 2-bit error is detected in bodies of up to 20
bytes, and inside the body in bodies of up to 30 bytes (the polynomial is primitive: Hamming distance 3 up to
247 data bits); longer bodies miss a few 2-bit patterns (PROTOCOL.md lists them). Other errors pass about 1
time in 256.
"""

from __future__ import annotations

WIDTH = 8
POLY = 0x65
"""The generator polynomial x^8 + x^6 + x^5 + x^2 + 1 in normal (MSB-first) form, without the x^8 term."""
INIT = 0xFF
XOROUT = 0x00
REFLECTED = True
CHECK = 0x20
"""The CRC of the ASCII bytes ``123456789``."""

_POLY_REFLECTED = int(f"{POLY:08b}"[::-1], 2)  # 0xA6: the polynomial as a right-shifting register sees it


def _entry(byte: int) -> int:
    crc = byte
    for _ in range(8):
        crc = (crc >> 1) ^ _POLY_REFLECTED if crc & 1 else crc >> 1
    return crc


TABLE = bytes(_entry(b) for b in range(256))
"""``TABLE[i]``: the register after shifting the byte ``i`` through it (reflected form); 256 bytes."""


def crc8(data: bytes | str, crc: int = INIT) -> int:
    """Return the CRC-8 of ``data``.

    Parameters
    ----------
    data : bytes or str
        The bytes covered (a str is encoded as ASCII).
    crc : int
        The register to continue from (default: the initial value, i.e. a fresh CRC).

    Returns
    -------
    int
        0..255; e.g. ``crc8(b"123456789") == 0x20``.
    """
    raw = data.encode("ascii") if isinstance(data, str) else data
    for b in raw:
        crc = TABLE[crc ^ b]
    return crc ^ XOROUT
