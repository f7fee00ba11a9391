"""Command scripts shared by the firmware protocol tests and the firmware/virtual-board conformance test.

Each case is ``(command bytes, expected reply)``: the expected reply is a regular expression for the reply
body (the checksum is checked separately), or ``None`` when the line must get no reply. Expectations are
written from firmware/PROTOCOL.md. ``ERR`` texts are free; only the code is part of the protocol. Commands
carry their ``*hh`` (protocol 2.0.0 requires it) unless a case is about a command without it.
"""

from __future__ import annotations

from crc_reference import LINK_CHECK, xor_hex
from fwsim import with_checksum

V = r"2\.3\.0\+481e87e3"


def _c(body: str) -> bytes:
    """A command with its correct checksum (as the host drivers send every command)."""
    return with_checksum(body).encode("ascii") + b"\n"


def _bare(text: str) -> bytes:
    """A command without ``*hh`` (as a person might type it): refused with ``ERR NOCRC``."""
    return text.encode("ascii") + b"\n"


NOCRC = r"ERR NOCRC( .*)?"


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
        (_bare("PING"), NOCRC),  # every command must carry its *hh ...
        (_bare("FOO"), NOCRC),  # ... which is looked at before the word
        (_bare("PING 1"), NOCRC),
        (b"PING\r\n", NOCRC),
        (_c("PING")[:-1] + b"\r\n", pong),  # \r before \n ignored
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
        (b"PI\rNG\n", NOCRC),
        (_c("PING")[:-1] + b"\r\r\n", r"ERR CHECKSUM( .*)?"),  # "*hh\r": a malformed checksum
        (f"PI\rNG*{with_checksum('PING')[-2:]}\n".encode(), r"ERR CHECKSUM( .*)?"),
        (f"PI\rNG*{with_checksum('PI' + chr(13) + 'NG')[-2:]}\r\n".encode(), r"ERR UNKNOWN( .*)?"),
        (b"\n", None),  # blank line: no reply
        (b"\r\n", None),
        (b"*FF\n", None),  # an empty body with its CRC (the initial value 0xFF): blank too
        (_c("FOO"), r"ERR UNKNOWN( .*)?"),
        (_c("ping"), r"ERR UNKNOWN( .*)?"),  # command words are upper case
        (_c("PING 1"), r"ERR ARG( .*)?"),
        (_c("PING "), r"ERR ARG( .*)?"),  # trailing space = empty argument
        (b"X" * 64 + b"\n", r"ERR TOOLONG( .*)?"),
        (b"P" * 200 + b"\n", r"ERR TOOLONG( .*)?"),  # one reply however long
        (_c("PING" + " " * 56), r"ERR ARG( .*)?"),  # 63 characters with "*hh": not too long
        (_c("PING" + " " * 57), r"ERR TOOLONG( .*)?"),  # 64
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
        (_c("RATE 500"), r"OK RATE 500"),
        (_c("RATE " + "0" * 51 + "1000"), r"OK RATE 1000"),  # exactly 63 characters with "*hh"
        (_c("RATE " + "0" * 52 + "1000"), r"ERR TOOLONG( .*)?"),  # 64
        (_c("ZERO 0"), r"ERR ARG( .*)?"),
        (_c("ZERO"), r"OK ZERO"),
        (b"ZERO*DE\n", r"OK ZERO"),  # CRC-8 values from the reference implementation
        (b"RATE 500*7A\n", r"OK RATE 500"),
        (b"RATE 1000*67\n", r"OK RATE 1000"),
        (_c("START 1"), r"ERR ARG( .*)?"),
        (_c("STOP 1"), r"ERR ARG( .*)?"),
        (_bare("START"), NOCRC),  # executes nothing ...
        (_c("STOP"), r"OK STOP 0"),  # ... so the board is not streaming
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
        (_c("CONFIG"), r"OK CONFIG 1 1 100 2000"),  # protocol 2.2
        (_c("CONFIG 1"), r"ERR ARG( .*)?"),
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
        (_c("SEG -1 10 1000"), r"OK SEG 3", 0, n),
        (_bare("EN 1"), NOCRC, 0, n),  # executes nothing: the driver stays disabled
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
        # protocol 2.2: CONFIG, and MSEG on the one axis (its steps spread over the window on 0.5 us ticks)
        (_c("CONFIG"), r"OK CONFIG 1 64 639 1000000 156", 0, n),
        (_c("CONFIG 1"), r"ERR ARG( .*)?", 0, n),
        (_c("MSEG 1000"), r"ERR ARG( .*)?", 0, n),
        (_c("MSEG 10000 1 1"), r"ERR ARG( .*)?", 0, n),
        (_c("MSEG 0 1"), r"ERR RANGE( .*)?", 0, n),
        (_c("MSEG 100000 157"), r"ERR RANGE( .*)?", 0, n),
        (_c("MSEG 1000 2"), r"ERR RANGE( .*)?", 0, n),  # 500 us per step: faster than 400 mm/s
        (_c("MSEG 3000001 3"), r"ERR RANGE( .*)?", 0, n),  # slower than a step per second
        (_c("MSEG 100000 0"), r"ERR RANGE( .*)?", 0, n),  # nothing moves: a dwell is WAIT
        (_c("EN 1"), r"OK EN 1", 0, n),
        (_c("MSEG 7001 3"), r"OK MSEG 1", 0, n),  # 2333.67 us per step
        (_c("MSEG 7001 -3"), r"OK MSEG 2", 0, n),
        (_c("GO"), r"OK GO 2", 0.03, r"DONE \d+"),  # 14.0 ms
        (_c("CLEAR"), r"OK CLEAR", 0, n),
    ]
    return cases


OFF_TICK = 0.005
"""Pause after ``STREAM``: with the 20 ms spacing and pauses of whole 10 ms periods, every later command is
sent 4 ms after a control tick and executed about 5 ms after it, far from any tick, so that the periods it is
assigned do not depend on the fraction of a millisecond its bytes spend on the wire, and the lines a tick
sends (notices, ``DONE``: at most 2 ms on the wire) arrive before it."""


def stream_cases() -> list[tuple[bytes, str | None, float]]:
    """The stepper's streaming commands and every error reply, from the reset state.

    Fields: command, expected reply, pause (s) after the command (whole control periods, or ``OFF_TICK``
    after ``STREAM``).
    """
    cases: list[tuple[bytes, str | None, float]] = [
        (_bare("SHAPER 2 0"), r"ERR NOCRC( .*)?", 0),  # every command must carry *hh
        (_bare("V 0"), r"ERR NOCRC( .*)?", 0),
        (_bare("STREAM"), r"ERR NOCRC( .*)?", 0),
        (_c("SHAPER"), r"ERR ARG( .*)?", 0),
        (_c("SHAPER 0 0"), r"ERR RANGE( .*)?", 0),
        (_c("SHAPER 9 0"), r"ERR RANGE( .*)?", 0),
        (_c("SHAPER 2 2"), r"ERR RANGE( .*)?", 0),
        (_c("IMP 0 4096 0"), r"ERR STATE( .*)?", 0),  # no SHAPER yet
        (_c("STREAM"), r"ERR STATE( .*)?", 0),  # no shaper
        (_c("V 0"), r"ERR STATE( .*)?", 0),  # not streaming
        (_c("MV 0"), r"ERR STATE( .*)?", 0),  # (MV: every build; one axis here)
        (_c("END"), r"ERR STATE( .*)?", 0),
        (_c("SHAPER 2 0"), r"OK SHAPER 2", 0),
        (_c("IMP 1 2048 160"), r"ERR STATE( .*)?", 0),  # impulses in order
        (_c("IMP 0 2048 16"), r"ERR RANGE( .*)?", 0),  # the first delay is 0; the shaper is discarded
        (_c("IMP 0 2048 0"), r"ERR STATE( .*)?", 0),
        (_c("SHAPER 2 0"), r"OK SHAPER 2", 0),
        (_c("IMP 0 -1 0"), r"ERR RANGE( .*)?", 0),  # negative amplitudes not allowed
        (_c("SHAPER 3 1"), r"OK SHAPER 3", 0),
        (_c("IMP 0 -1 0"), r"OK IMP 0", 0),  # ... unless SHAPER allowed them
        (_c("IMP 1 16385 160"), r"ERR RANGE( .*)?", 0),  # |a| <= 16384
        (_c("SHAPER 3 0"), r"OK SHAPER 3", 0),
        (_c("IMP 0 1000 0"), r"OK IMP 0", 0),
        (_c("IMP 1 1000 0"), r"ERR RANGE( .*)?", 0),  # delays strictly increasing
        (_c("SHAPER 2 0"), r"OK SHAPER 2", 0),
        (_c("IMP 0 2048 0"), r"OK IMP 0", 0),
        (_c("IMP 1 2048 100"), r"ERR RANGE( .*)?", 0),  # not a multiple of 16 us
        (_c("SHAPER 2 0"), r"OK SHAPER 2", 0),
        (_c("IMP 0 2048 0"), r"OK IMP 0", 0),
        (_c("IMP 1 2048 1000016"), r"ERR RANGE( .*)?", 0),  # over 1 s
        (_c("SHAPER 2 0"), r"OK SHAPER 2", 0),
        (_c("IMP 0 2048 0"), r"OK IMP 0", 0),
        (_c("IMP 1 2047 1000000"), r"ERR RANGE( .*)?", 0),  # amplitudes sum to 4095, not 4096
        (_c("STREAM"), r"ERR STATE( .*)?", 0),  # so there is no shaper
        (_c("SHAPER 2 1"), r"OK SHAPER 2", 0),
        (_c("IMP 0 6144 0"), r"OK IMP 0", 0),
        (_c("IMP 1 -2048 1000000"), r"OK IMP 1", 0),  # 1.5 - 0.5: a valid negative shaper, 1 s long
        (_c("STREAM"), r"ERR STATE( .*)?", 0),  # driver disabled
        (_c("EN 1"), r"OK EN 1", 0),
        (_c("STREAM 1"), r"ERR ARG( .*)?", 0),
        (_c("STREAM"), r"OK STREAM 0", OFF_TICK),
        # (a valid set-point at least every 100 ms, or the watchdog would end the stream)
        (_c("V 0"), r"OK V \d+", 0),
        (_c("STREAM"), r"ERR STATE( .*)?", 0),  # already streaming
        (_c("SHAPER 1 0"), r"ERR STATE( .*)?", 0),
        (_c("GO"), r"ERR STATE( .*)?", 0),
        (_c("V 0"), r"OK V \d+", 0),
        (_c("V"), r"ERR ARG( .*)?", 0),
        (_c("V 1 2"), r"ERR ARG( .*)?", 0),
        (_c("MV 0"), r"OK MV \d+", 0),  # one axis: MV <v> is V <v>
        (_c("MV 1 2"), r"ERR ARG( .*)?", 0),  # one set-point per axis
        (_c("MV 1641"), r"ERR RANGE( .*)?", 0),
        (_c("V 1641"), r"ERR RANGE( .*)?", 0),
        (_c("V 0"), r"OK V \d+", 0),
        (_c("V -1641"), r"ERR RANGE( .*)?", 0),
        (_c("V 99999999999"), r"ERR RANGE( .*)?", 0),
        (_c("SEG 1 10 1000"), r"OK SEG 1", 0),  # the programme may be edited meanwhile
        (_c("V 0"), r"OK V \d+", 0),
        (_c("POS"), r"OK POS 0", 0),
        (_c("END"), r"OK END \d+", 0),
        (_c("END"), r"ERR STATE( .*)?", 0),  # already ending
        (_c("V 5"), r"ERR STATE( .*)?", 1.2),  # and then DONE, after the 1 s shaper has run out
        (_c("POS"), r"OK POS 0", 0),
        (_c("STREAM"), r"OK STREAM 0", OFF_TICK),  # the shaper stays loaded
        (_c("V 1640"), r"OK V \d+", 0.0504),  # ABORT then falls 0.3 ms from the nearest steps
        (_c("ABORT"), r"ABORTED \d+", 0),  # stops at once and disables the driver
        (_c("V 1"), r"ERR STATE( .*)?", 0),
        (_c("STREAM"), r"ERR STATE( .*)?", 0),  # driver disabled
        (_c("MEM 1"), r"ERR ARG( .*)?", 0),
        (_c("MEM"), r"OK MEM \d+", 0),
    ]
    return cases


def stream_conformance_cases() -> list[tuple[bytes, float]]:
    """More streaming for the conformance test (replies compared with the emulated board, not with patterns):
    the speed clamp's notice, ``ERR FULL`` from a burst, ``END`` and ``DONE``, the travel clamp at both ends,
    the watchdog (its notice, ``DONE``, the driver disabled), ``MEM``. Fields: command bytes, pause (s)."""
    overshoot = ["SHAPER 2 1", "IMP 0 6144 0", "IMP 1 -2048 50000"]  # 1.5 v, then -0.5 v after 50 ms
    unit = ["SHAPER 1 0", "IMP 0 4096 0"]
    burst = b"".join(_c("V 1500") for _ in range(9))  # nine within 7.8 ms, in one period: the FIFO holds 8
    script: list[tuple[bytes, float]] = [(_c(c), 0.0) for c in ["EN 1", *overshoot]]
    script += [(_c("STREAM"), OFF_TICK)]
    script += [(_c("V 1500"), 0.0) for _ in range(4)]  # 1.5 x 1500 > 1640: N,LIMIT,SPEED
    script += [(_c("V 1500"), 0.006)]  # the burst is sent 0.1 ms after a tick ...
    script += [(burst, 0.004), (_c("END"), 0.3), (_c("POS"), 0.0)]  # ... and DONE follows the shaped stop
    script += [(_c(c), 0.0) for c in unit]
    script += [(_c("STREAM"), OFF_TICK)]
    # to the top: N,LIMIT,TRAVEL,156 (one set-point per period: a period without one moves nothing)
    script += [(_c("V 1640"), 0.01) for _ in range(11)]
    script += [(_c("POS"), 0.2)]  # no set-point for 200 ms: N,WATCHDOG, DONE, driver disabled
    script += [(_c("STREAM"), 0.0), (_c("V 0"), 0.0), (_c("EN 1"), 0.0), (_c("STREAM"), OFF_TICK)]
    script += [(_c("V -1640"), 0.01) for _ in range(11)]  # to the bottom: N,LIMIT,TRAVEL,0
    script += [(_c("END"), 0.1), (_c("POS"), 0.0), (_c("MEM"), 0.0)]
    return script
