"""A table-free CRC in the Rocksoft/Williams parameter model, written from its definition (test reference).

It shifts most-significant bit first and reflects explicitly, unlike the code under test
(``helpers.board.crc8`` and
``firmware/common/crc8.cpp``: a right-shifting register with a 256-entry table), and it is anchored to the
check values that the CRC catalogue (Greg Cook's "Catalogue of parametrised CRC algorithms") publishes for
well-known 8-bit variants (:data:`CATALOGUE`). The link's variant is :data:`LINK` (firmware/PROTOCOL.md).
"""

from __future__ import annotations


def _reflect(value: int, width: int) -> int:
    return int(f"{value:0{width}b}"[::-1], 2)


def crc_rocksoft(
    data: bytes, *, width: int = 8, poly: int, init: int, refin: bool, refout: bool, xorout: int
) -> int:
    """CRC of ``data`` by the textbook bit-serial algorithm (MSB-first register, explicit reflection)."""
    top, mask = 1 << (width - 1), (1 << width) - 1
    crc = init
    for byte in data:
        if refin:
            byte = _reflect(byte, 8)
        crc ^= byte << (width - 8)
        for _ in range(8):
            crc = ((crc << 1) ^ poly) & mask if crc & top else (crc << 1) & mask
    if refout:
        crc = _reflect(crc, width)
    return crc ^ xorout


# name: (poly, init, refin, refout, xorout, published check value of b"123456789")
CATALOGUE = {
    "CRC-8/SMBUS": (0x07, 0x00, False, False, 0x00, 0xF4),
    "CRC-8/ROHC": (0x07, 0xFF, True, True, 0x00, 0xD0),
    "CRC-8/MAXIM-DOW": (0x31, 0x00, True, True, 0x00, 0xA1),
    "CRC-8/TECH-3250": (0x1D, 0xFF, True, True, 0x00, 0x97),
    "CRC-8/SAE-J1850": (0x1D, 0xFF, False, False, 0xFF, 0x4B),
    "CRC-8/AUTOSAR": (0x2F, 0xFF, False, False, 0xFF, 0xDF),
}

LINK = {"poly": 0x65, "init": 0xFF, "refin": True, "refout": True, "xorout": 0x00}
"""The variant of firmware/PROTOCOL.md."""

LINK_CHECK = 0x20
"""PROTOCOL.md's check value: the link's CRC of ``b"123456789"``."""


def link_crc(data: bytes | str) -> int:
    """The link's CRC-8 of ``data`` (str is encoded as ASCII)."""
    raw = data.encode("ascii") if isinstance(data, str) else data
    return crc_rocksoft(raw, **LINK)


def link_hex(data: bytes | str) -> str:
    """The link's CRC-8 as two upper-case hex digits."""
    return f"{link_crc(data):02X}"


def xor_hex(data: bytes | str) -> str:
    """Protocol 1's checksum (firmware 1.x): the XOR of the bytes, two upper-case hex digits."""
    raw = data.encode("ascii") if isinstance(data, str) else data
    x = 0
    for b in raw:
        x ^= b
    return f"{x:02X}"
