"""The serial protocol of both boards (``firmware/PROTOCOL.md``): framing, checksums, line splitting, parsing.

The host driver (``helpers.rig``) and the emulated boards (``helpers.virtual.emulator``)
both speak it through this module. Every line a board sends ends in ``*hh``, the CRC-8 of all bytes before the
``*`` (:mod:`helpers.board.crc8`) as two upper-case hex digits. This module turns a byte stream into
classified lines and never raises on garbage: a line that fails any check (non-ASCII, missing or wrong
checksum, too long, malformed data fields) is reported as corrupted. A line whose checksum is the XOR of
protocol 1 (firmware 1.x) is also corrupted, and when it is such a board's ``HELLO``, ``PONG`` or
``ERR CHECKSUM``, :attr:`StreamParser.legacy` keeps it so that the driver can stop with one clear error (there
is no fallback to XOR).

:class:`StreamParser` is the one place where the DAQ stream's bookkeeping happens, for a board of any number
of load-cell channels and step counters (``D,<seq>,<t_us>,<adc_0>,...,<adc_{C-1}>,<steps_0>,...,
<steps_{A-1}>``): it counts exactly

- ``dropped``: sequence numbers missing between consecutive data lines that arrived intact (lines lost in
  transport or destroyed by corruption; a corrupted data line's ``seq`` is therefore also counted as dropped),
- ``overruns``: sample periods the board itself reports as missed (``W,OVERRUN,<n>``),
- ``corrupted``: non-blank lines that failed a check,
- ``implausible``: data lines that passed every check but describe the impossible: an axis's step count that
  changed faster than the step-rate limit allows, one outside the range the running programme can reach, or
  one that changed while the programme makes no step on that axis; they are rejected (their ``seq`` then
  counts as dropped too),

and unwraps the board's 32-bit microsecond clock.

The CRC-8 (:mod:`helpers.board.crc8`) is linear over GF(2) apart from its initial value: one step of the
register is ``r -> TABLE[r ^ b] = TABLE[r] ^ TABLE[b]``. A byte ``b`` followed by ``m`` more bytes therefore
adds ``A^m(TABLE[b])`` to the final register (``A``: the map ``r -> TABLE[r]``) and the initial value adds
``A^L(INIT)`` for a line of ``L`` bytes: the CRC-8s of many lines are XORs of table look-ups over their bytes
whatever the lines' lengths (:func:`crc8_spans`; a test checks it against the bitwise reference). The host
checks every line of a read at once with them (:func:`unframe`), the emulated DAQ frames its chunks of
samples with them (:mod:`helpers.virtual.emulator.framing`): at 1-5 kHz a line costs more in Python than the
twin's physics of its sample.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cache, reduce
from operator import xor

import numpy as np

from helpers.board.crc8 import INIT, TABLE, XOROUT, crc8

FW_VERSION = "2.3.0"
"""The protocol version the firmware and the emulated boards report (``MAJOR.MINOR.PATCH``)."""

PAPER_RIG_HASH = "481e87e3"
"""The rig hash the paper's one-tendon build reports: the hash of ``rigs/paper.toml``, generated into
``firmware/common/rig_config_paper.h`` (a test checks that the three agree)."""


MAX_LINE = 63
"""Characters a line may hold before its ``\\n`` (PROTOCOL.md)."""

WRAP_US = 1 << 32
"""The boards' ``micros()`` wraps after 2**32 microseconds."""

PROTOCOL_MAJOR = int(FW_VERSION.split(".")[0])
"""The MAJOR firmware version this host speaks (CRC-8 framing); a board reporting another is refused."""

MAX_PENDING = 4 * (MAX_LINE + 1)
"""Bytes of an unterminated line kept before it is declared corrupted (garbage without newlines)."""

MAX_DIGITS = 15
"""Digits of a field read as int64 (10**15 < 2**53: exact as float64 too); a longer one is a Python int."""

_FRAMED = re.compile(rb"([ -)+-~]{0,%d})\*[0-9A-F]{2}\r?\n" % (MAX_LINE - 3))
"""A framed line: printable ASCII, one ``*`` and two upper-case hex digits, at most MAX_LINE long."""
_HEX_DIGITS = np.frombuffer(b"0123456789ABCDEF", dtype=np.uint8)
_LEGACY_BODY = re.compile(rb"(HELLO|PONG) (daq|stepper) 1\.[0-9]+\.[0-9]+|ERR CHECKSUM( .*)?")
_OVERRUN = re.compile(rb"W,OVERRUN,([0-9]+)")
_BETWEEN = re.compile(rb"\*[0-9A-F]{2}\r?\n(?:D,|$)")
"""From one data line's fields to the next's, or to the end."""


MAX_BYTES = 64
"""Longest span :func:`crc8_spans` takes (a line of the protocol has at most 63 bytes)."""


def _tables() -> tuple[np.ndarray, np.ndarray]:
    """``after[256 m + b]``: byte ``b`` followed by ``m`` more bytes; ``init[L]``: INIT after ``L`` bytes."""
    after, init = [np.frombuffer(TABLE, dtype=np.uint8)], [INIT]
    for _ in range(MAX_BYTES):
        after.append(after[0][after[-1]])
        init.append(TABLE[init[-1]])
    return np.concatenate(after[:MAX_BYTES]), np.array(init, dtype=np.uint8)


_AFTER, _INIT_AFTER = _tables()
NEWLINE = ord("\n")


def crc8_spans(data: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """The CRC-8 (:func:`~helpers.board.crc8.crc8`) of every span ``data[starts[i]:ends[i]]``, at once.

    Parameters
    ----------
    data : ndarray of uint8
        The bytes.
    starts, ends : ndarray of int
        The spans, each at most :data:`MAX_BYTES` long.

    Returns
    -------
    ndarray of uint8
        One CRC-8 per span.

    Raises
    ------
    IndexError
        If a span is longer than :data:`MAX_BYTES` (beyond the tables).
    """
    length = ends - starts
    w = int(length.max(initial=0))
    pos = np.arange(-w, 0)[:, None] + ends  # a column per span, right-aligned: w - 1 - j bytes after row j
    index = data.take(pos, mode="wrap") + 256 * np.arange(w - 1, -1, -1)[:, None]
    index[pos < starts] = 0  # before the span: no byte (the register unchanged by it)
    return np.bitwise_xor.reduce(_AFTER[index], axis=0) ^ _INIT_AFTER[length] ^ XOROUT


def checksum(body: bytes | str) -> str:
    """Return the two upper-case hex digits of the CRC-8 of ``body``'s bytes (:func:`~.crc8.crc8`).

    Parameters
    ----------
    body : bytes or str
        The line's bytes before the ``*`` (str is encoded as ASCII).

    Returns
    -------
    str
        E.g. ``"FD"`` for ``b"PONG daq 2.0.0"``.
    """
    return f"{crc8(body):02X}"


def frame(body: str) -> bytes:
    r"""Return ``body`` as a complete line with its checksum: ``b"<body>*hh\\n"``.

    Raises
    ------
    ValueError
        If ``body`` is not printable ASCII, contains ``*`` or a newline, or is longer than the protocol
        allows.
    """
    if not body.isascii() or not body.isprintable() or "*" in body:
        raise ValueError(f"cannot frame {body!r}: only printable ASCII without '*' is allowed")
    line = f"{body}*{checksum(body)}"
    if len(line) > MAX_LINE:
        raise ValueError(f"line {line!r} has {len(line)} characters; the protocol allows {MAX_LINE}")
    return (line + "\n").encode("ascii")


def unframe(raw: bytes, shaped: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    r"""Check complete lines at once: every framed line's body and whether its CRC-8 is right.

    Parameters
    ----------
    raw : bytes
        One or more complete lines, each ending in ``\\n``; a ``\\r`` before it is ignored, and a line of
        nothing but ``\\r`` is blank (neither framed nor corrupted). Every line of protocol 2 carries a
        checksum, commands included.
    shaped : bool
        Every line of ``raw`` is known to be framed but for its length and CRC (the parser's data lines): its
        body is then found from its ``\\n`` alone.

    Returns
    -------
    starts, stars : ndarray of int64
        Every framed line's body ``raw[starts[i]:stars[i]]``: the printable ASCII before its one ``*``.
    good : ndarray of bool
        Its line is at most :data:`MAX_LINE` long and its ``*hh`` is the CRC-8 of its body.
    unframed : int
        The other lines but the blank ones: non-ASCII or control bytes, too long, no or a malformed checksum.
    """
    data, unframed = np.frombuffer(raw, dtype=np.uint8), 0
    if shaped:
        ends = np.flatnonzero(data == NEWLINE) + 1
        starts, stars = np.concatenate([[0], ends[:-1]]), ends - 4 - (data[ends - 2] == ord("\r"))
    else:
        lines = [m.span() for m in re.finditer(rb"[^\n]*\n", raw) if m[0].strip(b"\r\n")]  # blank: left out
        framed = [m.span(1) for a, b in lines if (m := _FRAMED.fullmatch(raw, a, b))]
        starts, stars = np.array(framed, dtype=np.int64).reshape(-1, 2).T
        unframed = len(lines) - len(framed)
    given = 16 * _HEX_DIGITS.searchsorted(data[stars + 1]) + _HEX_DIGITS.searchsorted(data[stars + 2])
    crc = crc8_spans(data, np.maximum(starts, stars - MAX_LINE), stars)  # a longer line: refused by length
    return starts, stars, (stars - starts <= MAX_LINE - 3) & (crc == given), unframed


def _integers(fields: bytes, k: int) -> np.ndarray:
    """Comma-separated integers as rows of ``k``: int64, or Python ints if one has over :data:`MAX_DIGITS`."""
    if re.search(rb"[0-9]{%d}" % (MAX_DIGITS + 1), fields):
        return np.array([int(f) for f in fields.split(b",")], dtype=object).reshape(-1, k)
    return np.fromstring(fields, dtype=np.int64, sep=",").reshape(-1, k)


@cache
def _data_line(channels: int, axes: int) -> tuple[re.Pattern[bytes], re.Pattern[bytes]]:
    r"""A data line's body (integer fields, counts >= 0), and a run of framed data lines."""
    body = rb"D(?:,[0-9]+){%d}(?:,-?[0-9]+){%d}" % (2 + channels, axes)
    return re.compile(body), re.compile(rb"(?:%s\*[0-9A-F]{2}\r?\n)*" % body)


@dataclass
class StreamStats:
    """Exact counts of what went wrong in a stream."""

    dropped: int = 0
    overruns: int = 0
    corrupted: int = 0
    implausible: int = 0
    samples: int = 0


class StreamParser:
    """Turn a board's bytes into samples, messages and exact fault counts; never raises on garbage.

    ``feed(data)`` returns ``(samples, messages)``: the new samples as tuples ``(seq, t_us_unwrapped,
    adc_0..adc_{C-1}, steps_0..steps_{A-1})`` and the other lines' bodies (replies, ``HELLO ...``). ``stats``
    holds the counts. A data line whose ``seq`` does not increase is counted as corrupted (it cannot be
    placed).

    Parameters
    ----------
    channels, axes : int
        The board's load cells and step counters (``CONFIG``): the fields of its data lines.
    max_step_rate_hz : float, optional
        A step count that changes faster than this is implausible (None: no check).
    adc_max : int
        The largest ADC count (a data line beyond it is corrupted): the 10-bit ADC's 1023 of
        ``firmware/PROTOCOL.md`` unless the rig file says otherwise.
    """

    def __init__(
        self, channels: int = 1, axes: int = 1, max_step_rate_hz: float | None = None, adc_max: int = 1023
    ) -> None:
        self._buf = bytearray()  # an unfinished line
        self.channels, self.axes, self.adc_max = channels, axes, adc_max
        self.legacy: str | None = None
        """The first line from a protocol-1 board (XOR-framed ``HELLO``/``PONG`` 1.x or ``ERR CHECKSUM``)."""
        self.max_step_rate_hz = max_step_rate_hz
        self.restart()

    def restart(self) -> None:
        """Forget the counts, the sequence and clock state and the expectations (after ``START``)."""
        self.stats = StreamStats()
        self.last_seq: int | None = None
        self._last_raw_t: int | None = None
        self._last: tuple[int, tuple[int, ...]] | None = None  # (t_us unwrapped, steps) of the last one
        self.steps_range: list[tuple[int, int]] | None = None
        """Every axis's step counts the running programme can reach (from ``ZERO``), or None (no check)."""
        self.step_windows: list[tuple[np.ndarray, np.ndarray]] | None = None
        """Every axis's sorted, disjoint ``(starts, ends)`` in device us where the programme steps it, or None
        (no check): a count that changes outside them is impossible."""

    def _place(self, values: np.ndarray, out: list) -> None:
        """Place the checked data lines ``values`` (rows ``seq, t_us, adc_0.., steps_0..``) in order.

        The rows before the first one that does not follow (:meth:`_block_end`) are placed at once; that
        row is corrupted if its ``seq`` does not increase, else implausible (rejected: its ``seq`` then
        counts as dropped), and the rows after it are placed in the same way.
        """
        while len(values):
            k, t = self._block_end(values)
            if k:
                seq = int(values[k - 1, 0])
                self.stats.dropped += seq - (0 if self.last_seq is None else self.last_seq + 1) - (k - 1)
                self.last_seq = seq
                self.stats.samples += k
                self._last_raw_t = int(values[k - 1, 1])
                rows = np.concatenate([values[:k, :1], t[:k, None], values[:k, 2:]], axis=1).tolist()
                self._last = (rows[-1][1], tuple(rows[-1][2 + self.channels :]))
                out.extend(map(tuple, rows))
            if k < len(values) and self.last_seq is not None and values[k, 0] <= self.last_seq:
                self.stats.corrupted += 1
            elif k < len(values):
                self.stats.implausible += 1
            values = values[k + 1 :]

    def _block_end(self, values: np.ndarray) -> tuple[int, np.ndarray]:
        """``(k, t_us)``: the first row that does not follow, and every row's unwrapped time.

        Row ``k`` is the first whose ``seq`` does not increase or that is implausible: a step count outside
        its axis's range, changed faster than the step-rate limit allows or while no window of the
        programme steps that axis; each row judged as though every row before it was placed (the first
        sample ever by its range only); ``len(values)`` if there is none. The clock unwraps on the same
        assumption (a time earlier than the one before it wrapped).
        """
        seq, t_raw, steps = values[:, 0], values[:, 1].astype(np.int64), values[:, 2 + self.channels :]
        if self._last is not None and max(map(abs, self._last[1])) >= 10**MAX_DIGITS:
            steps = steps.astype(object)  # compared exactly with a count too large for int64 and float64
        last_t, last_raw = (t_raw[0], t_raw[0]) if self._last is None else (self._last[0], self._last_raw_t)
        t = t_raw - last_raw + last_t + WRAP_US * np.cumsum(t_raw < np.concatenate([[last_raw], t_raw[:-1]]))
        refused = seq <= np.concatenate([[-1 if self.last_seq is None else self.last_seq], seq[:-1]])
        if self.steps_range is not None:
            lo, hi = np.array(self.steps_range).T
            refused |= ((steps < lo) | (steps > hi)).any(axis=1)
        t_last, s_last = (t[:1], steps[:1]) if self._last is None else ([self._last[0]], [self._last[1]])
        t_prev, s_prev = np.concatenate([t_last, t[:-1]]), np.concatenate([s_last, steps[:-1]])
        changed = steps != s_prev  # the first sample ever compared with itself: unchanged
        if changed.any() and self.max_step_rate_hz is not None:
            limit = self.max_step_rate_hz * np.maximum(t - t_prev, 0) * 1e-6 + 1
            refused |= (changed & (np.abs(steps - s_prev) > limit[:, None])).any(axis=1)
        if changed.any() and self.step_windows is not None:  # a count changed in (last t, t]: in a window
            for a, (starts, stops) in enumerate(self.step_windows):
                i = np.searchsorted(starts, t, side="right") - 1
                late = np.asarray(stops)[np.maximum(i, 0)] < t_prev if len(starts) else True
                refused |= changed[:, a] & ((i < 0) | late)
        return int(np.argmax(refused)) if refused.any() else len(values), t

    def _lines(self, raw: bytes) -> tuple[list[tuple[int, ...]], list[str]]:
        r"""Check and classify complete lines at once (:func:`unframe`): each as it would be alone.

        Returns the valid data lines placed in the order they came (:meth:`_place`) and the other valid
        lines' bodies (messages); the overruns are counted, and a line that fails a check is corrupted (a data
        line's fields: the board's number of integers, counts >= 0 and in range; a warning:
        ``W,OVERRUN,<n>``).
        """
        line, block = _data_line(self.channels, self.axes)
        shaped = block.fullmatch(raw) is not None  # only data lines (the usual case): their fields at once
        starts, stars, good, corrupted = unframe(raw, shaped)
        for a, b in zip(starts[~good].tolist(), stars[~good].tolist(), strict=True):
            given, body = int(raw[b + 1 : b + 3], 16), raw[a:b]  # protocol 1's XOR of a 1.x board's line?
            if self.legacy is None and reduce(xor, body, 0) == given and _LEGACY_BODY.fullmatch(body):
                self.legacy = body.decode("ascii")
        k = 2 + self.channels + self.axes
        if shaped:
            values, messages = _integers(_BETWEEN.sub(b",", raw)[2:-1], k)[good], []
        else:
            bodies = [raw[a:b] for a, b in zip(starts[good].tolist(), stars[good].tolist(), strict=True)]
            data = [body[2:] for body in bodies if line.fullmatch(body)]
            warnings = [int(m[1]) for body in bodies if (m := _OVERRUN.fullmatch(body))]
            messages = [body.decode("ascii") for body in bodies if not body.startswith((b"D,", b"W,"))]
            corrupted += len(bodies) - len(data) - len(warnings) - len(messages)  # malformed D and W lines
            self.stats.overruns += sum(warnings)
            values = _integers(b",".join(data), k)
        ok = (values[:, 1] < WRAP_US) & np.all(values[:, 2 : 2 + self.channels] <= self.adc_max, axis=1)
        self.stats.corrupted += corrupted + int((~good).sum()) + int((~ok).sum())
        samples: list[tuple[int, ...]] = []
        self._place(values[ok], samples)
        return samples, messages

    def feed(self, data: bytes) -> tuple[list[tuple[int, ...]], list[str]]:
        r"""Parse ``data`` (any chunking) and return the samples and messages it completes.

        The lines it completes are checked and classified at once (:meth:`_lines`). A run of bytes without
        ``\n`` longer than :data:`MAX_PENDING` is taken as one line (so it is flagged corrupted) and the rest
        of it up to the next ``\n`` is discarded into a second corrupted line at most.
        """
        self._buf += data
        cut = self._buf.rfind(b"\n") + 1
        complete, rest = bytes(self._buf[:cut]), self._buf[cut:]
        if len(rest) > MAX_PENDING:  # garbage without newlines: one line (a corrupted one)
            complete, rest = complete + rest + b"\n", bytearray()
        self._buf = rest
        return self._lines(complete) if complete else ([], [])
