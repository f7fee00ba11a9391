"""Command scripts shared by the firmware protocol tests and the firmware/virtual-board conformance test.

Each case is ``(command bytes, expected reply)``: the expected reply is a regular expression for the reply
body (the checksum is checked separately), or ``None`` when the line must get no reply. Expectations are
written from firmware/PROTOCOL.md. ``ERR`` texts are free; only the code is part of the protocol.
``long_wait`` marks a command after which the script pauses (a programme runs to its end).
"""

from __future__ import annotations

from crc_reference import LINK_CHECK, xor_hex
from fwsim import with_checksum

V = r"2\.0\.0"


def _c(text: str) -> bytes:
    return text.encode("ascii") + b"\n"


def _k(body: str) -> bytes:
    """A command with a correct checksum."""
    return with_checksum(body).encode("ascii") + b"\n"


def _bad(body: str) -> bytes:
    """A command with a wrong checksum (the right one with its lowest bit flipped)."""
    good = with_checksum(body)
    wrong = f"{int(good[-2:], 16) ^ 1:02X}"
    return f"{body}*{wrong}\n".encode("ascii")


def framing_cases(board: str) -> list[tuple[bytes, str | None]]:
    """Framing, checksum and generic errors, valid for either board (PING is the probe)."""
    pong = rf"PONG {board} {V}"
    return [
        (_c("PING"), pong),
        (_k("PING"), pong),
        (b"PING\r\n", pong),  # \r before \n ignored
        (_bad("PING"), r"ERR CHECKSUM( .*)?"),
        (b"PING*1\n", r"ERR CHECKSUM( .*)?"),  # one hex digit
        (b"PING*XY\n", r"ERR CHECKSUM( .*)?"),  # not hex
        (b"PING*123\n", r"ERR CHECKSUM( .*)?"),  # three digits
        (_bad("FOO"), r"ERR CHECKSUM( .*)?"),  # checksum is checked before the word
        # CRC-8, not XOR: protocol 1's checksum is refused (here it differs from the CRC) ...
        (f"PING*{xor_hex('PING')}\n".encode(), r"ERR CHECKSUM( .*)?"),
        # ... and so is a 2-bit error the XOR misses: bit 1 flipped in two bytes ("RATE 500" -> "RATE 722")
        (f"RATE 722*{with_checksum('RATE 500')[-2:]}\n".encode(), r"ERR CHECKSUM( .*)?"),
        # the check value: the board's CRC of "123456789" is PROTOCOL.md's (the word itself is unknown)
        (f"123456789*{LINK_CHECK:02X}\n".encode(), r"ERR UNKNOWN( .*)?"),
        (f"123456789*{LINK_CHECK ^ 1:02X}\n".encode(), r"ERR CHECKSUM( .*)?"),
        # a '\r' is dropped only just before '\n'; elsewhere it is part of the line (and of the CRC)
        (b"PI\rNG\n", r"ERR UNKNOWN( .*)?"),
        (b"PING\r\r\n", r"ERR UNKNOWN( .*)?"),
        (f"PI\rNG*{with_checksum('PING')[-2:]}\n".encode(), r"ERR CHECKSUM( .*)?"),
        (f"PI\rNG*{with_checksum('PI' + chr(13) + 'NG')[-2:]}\r\n".encode(), r"ERR UNKNOWN( .*)?"),
        (b"\n", None),  # blank line: no reply
        (b"\r\n", None),
        (_c("FOO"), r"ERR UNKNOWN( .*)?"),
        (_c("ping"), r"ERR UNKNOWN( .*)?"),  # command words are upper case
        (_c("PING 1"), r"ERR ARG( .*)?"),
        (_c("PING "), r"ERR ARG( .*)?"),  # trailing space = empty argument
        (b"X" * 64 + b"\n", r"ERR TOOLONG( .*)?"),
        (b"P" * 200 + b"\n", r"ERR TOOLONG( .*)?"),  # one reply however long
        (b"PING" + b" " * 59 + b"\n", r"ERR ARG( .*)?"),  # 63 characters: not too long
        (_c("PING"), pong),  # and the board still answers
    ]


def daq_cases() -> list[tuple[bytes, str | None]]:
    """Every DAQ command and error reply, from the reset state (not streaming, 1000 Hz)."""
    return [
        (_c("STOP"), r"OK STOP 0"),
        (_c("RATE"), r"ERR ARG( .*)?"),
        (_c("RATE 1 2"), r"ERR ARG( .*)?"),
        (_c("RATE x"), r"ERR ARG( .*)?"),
        (_c("RATE 1.5"), r"ERR ARG( .*)?"),
        (_c("RATE +500"), r"ERR ARG( .*)?"),
        (_c("RATE  500"), r"ERR ARG( .*)?"),
        (_c("RATE 99"), r"ERR RANGE( .*)?"),
        (_c("RATE 2001"), r"ERR RANGE( .*)?"),
        (_c("RATE -1000"), r"ERR RANGE( .*)?"),
        (_c("RATE 99999999999999999999"), r"ERR RANGE( .*)?"),
        (_c("RATE 100"), r"OK RATE 100"),
        (_c("RATE 2000"), r"OK RATE 2000"),
        (_k("RATE 500"), r"OK RATE 500"),
        (_c("RATE " + "0" * 54 + "1000"), r"OK RATE 1000"),  # exactly 63 characters
        (_c("RATE " + "0" * 55 + "1000"), r"ERR TOOLONG( .*)?"),  # 64
        (_c("ZERO 0"), r"ERR ARG( .*)?"),
        (_c("ZERO"), r"OK ZERO"),
        (b"ZERO*DE\n", r"OK ZERO"),  # CRC-8 values from the reference implementation
        (b"RATE 500*7A\n", r"OK RATE 500"),
        (b"RATE 1000*67\n", r"OK RATE 1000"),
        (_c("START 1"), r"ERR ARG( .*)?"),
        (_c("STOP 1"), r"ERR ARG( .*)?"),
        (_c("START"), r"OK START 1000"),
        (_c("PING"), rf"PONG daq {V}"),
        (_c("START"), r"ERR STATE( .*)?"),
        (_c("RATE 500"), r"ERR STATE( .*)?"),
        (_c("RATE 5"), r"ERR STATE( .*)?"),  # STATE before RANGE
        (_c("RATE"), r"ERR ARG( .*)?"),  # ARG before STATE
        (_c("ZERO"), r"OK ZERO"),
        (_c("STOP"), r"OK STOP \d+"),
        (_c("STOP"), r"OK STOP 0"),
        (_c("RATE 200"), r"OK RATE 200"),
        (_c("START"), r"OK START 200"),
        (_c("STOP"), r"OK STOP \d+"),
    ]


def stepper_cases() -> list[tuple[bytes, str | None, float, str | None]]:
    """Every stepper command and error reply, from the reset state.

    Fields: command, expected reply, pause (s) after the command (besides the usual spacing), and the
    expected unsolicited ``DONE`` line in that window (``None``: no ``DONE`` may arrive).
    """
    n: str | None = None
    cases: list[tuple[bytes, str | None, float, str | None]] = [
        (_c("POS"), r"OK POS 0", 0, n),
        (b"POS*8e\n", r"OK POS 0", 0, n),  # hex digits of either case
        (b"POS*8E\n", r"OK POS 0", 0, n),
        (_c("GO"), r"ERR STATE( .*)?", 0, n),  # empty programme
        (_c("ABORT"), r"ABORTED 0", 0, n),  # also when idle
        (_c("CLEAR 1"), r"ERR ARG( .*)?", 0, n),
        (_c("CLEAR"), r"OK CLEAR", 0, n),
        (_c("SEG 1 10"), r"ERR ARG( .*)?", 0, n),
        (_c("SEG 1 10 1000 5"), r"ERR ARG( .*)?", 0, n),
        (_c("SEG 1 x 1000"), r"ERR ARG( .*)?", 0, n),
        (_c("SEG 1 10 1e3"), r"ERR ARG( .*)?", 0, n),
        (_c("SEG 0 10 1000"), r"ERR RANGE( .*)?", 0, n),
        (_c("SEG 2 10 1000"), r"ERR RANGE( .*)?", 0, n),
        (_c("SEG 1 0 1000"), r"ERR RANGE( .*)?", 0, n),
        (_c("SEG 1 157 1000"), r"ERR RANGE( .*)?", 0, n),
        (_c("SEG 1 10 638"), r"ERR RANGE( .*)?", 0, n),  # faster than 400 mm/s
        (_c("SEG 1 10 1000001"), r"ERR RANGE( .*)?", 0, n),
        (_c("SEG 1 10 -1000"), r"ERR RANGE( .*)?", 0, n),
        (_c("SEG 1 10 99999999999"), r"ERR RANGE( .*)?", 0, n),
        (_c("WAIT"), r"ERR ARG( .*)?", 0, n),
        (_c("WAIT -1"), r"ERR RANGE( .*)?", 0, n),
        (_c("WAIT 60001"), r"ERR RANGE( .*)?", 0, n),
        (_c("SEG -1 10 1000"), r"OK SEG 1", 0, n),
        (_c("EN 1"), r"OK EN 1", 0, n),
        (_c("GO"), r"ERR RANGE( .*)?", 0, n),  # would go below zero
        (_c("CLEAR"), r"OK CLEAR", 0, n),
        (_c("EN 0"), r"OK EN 0", 0, n),
        (_c("SEG 1 10 639"), r"OK SEG 1", 0, n),
        (_c("WAIT 0"), r"OK WAIT 2", 0, n),
        (_k("SEG -1 10 1000"), r"OK SEG 3", 0, n),
        (_c("GO"), r"ERR STATE( .*)?", 0, n),  # driver disabled
        (_c("EN"), r"ERR ARG( .*)?", 0, n),
        (_c("EN 2"), r"ERR RANGE( .*)?", 0, n),
        (_c("EN -1"), r"ERR RANGE( .*)?", 0, n),
        (_c("EN 1"), r"OK EN 1", 0, n),
        (_c("GO 1"), r"ERR ARG( .*)?", 0, n),
        (_c("GO"), r"OK GO 3", 0.05, r"DONE 0"),  # 16.39 ms
        (_c("POS"), r"OK POS 0", 0, n),
        (_c("CLEAR"), r"OK CLEAR", 0, n),
        (_c("SEG 1 100 1000"), r"OK SEG 1", 0, n),
        (_c("SEG 1 57 1000"), r"OK SEG 2", 0, n),
        (_c("GO"), r"ERR RANGE( .*)?", 0, n),  # 157 steps > 40 mm of travel
        (_c("CLEAR"), r"OK CLEAR", 0, n),
        (_c("SEG 1 156 639"), r"OK SEG 1", 0, n),
        (_c("GO"), r"OK GO 1", 0.12, r"DONE 156"),  # the whole travel at the top speed: 99.7 ms
        (_c("POS"), r"OK POS 156", 0, n),
        (_c("GO"), r"ERR RANGE( .*)?", 0, n),  # already at the top
        (_c("CLEAR"), r"OK CLEAR", 0, n),
        (_c("SEG -1 50 1000"), r"OK SEG 1", 0, n),
        (_c("WAIT 500"), r"OK WAIT 2", 0, n),
        (_c("GO"), r"OK GO 2", 0, n),  # 550 ms programme; commands while it runs:
        (_c("CLEAR"), r"ERR STATE( .*)?", 0, n),
        (_c("SEG 1 1 1000"), r"ERR STATE( .*)?", 0, n),
        (_c("WAIT 1"), r"ERR STATE( .*)?", 0, n),
        (_c("GO"), r"ERR STATE( .*)?", 0, n),
        (_c("SEG 1 1"), r"ERR ARG( .*)?", 0, n),  # ARG before STATE
        (_c("PING"), rf"PONG stepper {V}", 0, n),
        (_c("POS"), r"OK POS 106", 0, n),  # in the dwell
        (_c("ABORT"), r"ABORTED 106", 0, n),
        (_c("GO"), r"ERR STATE( .*)?", 0.6, n),  # ABORT disabled the driver; no DONE follows
        (_c("EN 1"), r"OK EN 1", 0, n),
        (_c("GO"), r"OK GO 2", 0.01, n),  # the programme was kept
        (_c("EN 0"), r"OK EN 0", 0.6, n),  # aborts the run part way: no DONE follows
        (_c("CLEAR"), r"OK CLEAR", 0, n),
    ]
    cases += [(_c("WAIT 0"), rf"OK WAIT {i}", 0, n) for i in range(1, 64)]
    cases += [
        (_c("WAIT 60000"), r"OK WAIT 64", 0, n),
        (_c("WAIT 1"), r"ERR FULL( .*)?", 0, n),
        (_c("SEG 1 1 1000"), r"ERR FULL( .*)?", 0, n),
        (_c("SEG 1 1 1"), r"ERR RANGE( .*)?", 0, n),  # RANGE before FULL
        (_c("WAIT 60001"), r"ERR RANGE( .*)?", 0, n),
        (_c("CLEAR"), r"OK CLEAR", 0, n),
        (_c("POS"), r"OK POS \d+", 0, n),
    ]
    return cases
