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
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import reduce
from operator import xor

import numpy as np

from helpers.board.crc8 import crc8
from helpers.board.lines import MAX_DIGITS, scan_data_lines

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

_HEX = "0123456789ABCDEF"
_LEGACY_BODY = re.compile(r"(HELLO|PONG) (daq|stepper) 1\.[0-9]+\.[0-9]+|ERR CHECKSUM( .*)?")


class FramingError(ValueError):
    """A line failed a framing check; the message names the check."""


class LegacyChecksum(FramingError):
    """The line's CRC-8 is wrong but its ``*hh`` is the XOR checksum of protocol 1 (firmware 1.x)."""


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


def unframe(line: bytes) -> str:
    r"""Check one line (without its ``\\n``) and return its body.

    Parameters
    ----------
    line : bytes
        The raw line; a trailing ``\\r`` is ignored. Every line of protocol 2 carries a checksum, commands
        included.

    Returns
    -------
    str
        The text before ``*hh``.

    Raises
    ------
    FramingError
        Non-ASCII or control bytes, too long, missing or malformed or wrong checksum
        (:class:`LegacyChecksum` when the wrong checksum is the XOR of protocol 1).
    """
    line = line.removesuffix(b"\r")
    if len(line) > MAX_LINE:
        raise FramingError(f"line of {len(line)} characters exceeds {MAX_LINE}")
    try:
        text = line.decode("ascii")
    except UnicodeDecodeError:
        raise FramingError("non-ASCII bytes") from None
    if not text.isprintable():
        raise FramingError("control characters")
    body, star, given = text.rpartition("*")
    if not star:
        raise FramingError("missing checksum")
    if "*" in body:
        raise FramingError("more than one '*'")
    if len(given) != 2 or any(c not in _HEX for c in given):
        raise FramingError(f"malformed checksum {given!r}")
    x = crc8(body)
    if x != int(given, 16):
        if reduce(xor, body.encode("ascii"), 0) == int(given, 16):
            raise LegacyChecksum(f"checksum {given} is the XOR of protocol 1 (firmware 1.x), not the CRC-8")
        raise FramingError(f"checksum {given} does not match {x:02X}")
    return body


@dataclass(frozen=True)
class Overrun:
    """``W,OVERRUN,<n>``: the board missed ``n`` sample periods."""

    n: int


def parse_body(
    body: str, channels: int = 1, axes: int = 1, adc_max: int = 1023
) -> tuple[int, ...] | Overrun | str:
    """Classify a checked line body (printable ASCII, :func:`unframe`'s) of a board with C channels, A axes.

    Returns
    -------
    tuple of int, Overrun or str
        A data line ``(seq, t_us, adc_0..adc_{C-1}, steps_0..steps_{A-1})`` (``t_us`` as sent), an overrun
        warning, or any other message (replies, ``HELLO``, ``DONE``) as text.

    Raises
    ------
    FramingError
        A body starting with ``D,`` or ``W,`` whose fields are malformed (another number of them too) or out
        of range.
    """
    if body.startswith("D,"):
        parts = body.split(",")[1:]
        if len(parts) != 2 + channels + axes:
            raise FramingError(f"data line with {len(parts) + 1} fields, expected {3 + channels + axes}")
        if not re.fullmatch(rf"D(,\d+){{{2 + channels}}}(,-?\d+){{{axes}}}", body):  # counts >= 0, steps any
            raise FramingError("data line with a non-integer field")
        values = tuple(int(f) for f in parts)
        if values[1] >= WRAP_US or max(values[2 : 2 + channels]) > adc_max:
            raise FramingError("data line field out of range")
        return values
    if body.startswith("W,"):
        if not (warning := re.fullmatch(r"W,OVERRUN,(\d+)", body)):
            raise FramingError(f"malformed warning {body!r}")
        return Overrun(int(warning[1]))
    return body


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
        self._t_offset = 0
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
                self._t_offset, self._last_raw_t = int(t[k - 1] - values[k - 1, 1]), int(values[k - 1, 1])
                rows = np.concatenate([values[:k, :1], t[:k, None], values[:k, 2:]], axis=1).tolist()
                self._last = (rows[-1][1], tuple(rows[-1][2 + self.channels :]))
                out.extend(map(tuple, rows))
            if k < len(values):
                if self.last_seq is not None and values[k, 0] <= self.last_seq:
                    self.stats.corrupted += 1
                else:
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
        last_raw = t_raw[0] if self._last_raw_t is None else self._last_raw_t
        t = t_raw + self._t_offset + WRAP_US * np.cumsum(t_raw < np.concatenate([[last_raw], t_raw[:-1]]))
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

    def _line(self, line: bytes, samples: list, messages: list) -> None:
        r"""Check and classify one complete line (without its ``\n``), line by line."""
        if not line.strip(b"\r"):
            return
        try:
            item = parse_body(unframe(line), self.channels, self.axes, self.adc_max)
        except FramingError as exc:
            self.stats.corrupted += 1
            if isinstance(exc, LegacyChecksum) and self.legacy is None:
                body = line.rstrip(b"\r").rpartition(b"*")[0].decode("ascii")
                if _LEGACY_BODY.fullmatch(body):
                    self.legacy = body
            return
        if isinstance(item, tuple):
            self._place(np.array([item], dtype=object), samples)  # its numbers may be of any size
        elif isinstance(item, Overrun):
            self.stats.overruns += item.n
        else:
            messages.append(item)

    @property
    def pending(self) -> int:
        """Bytes of an unfinished line held back."""
        return len(self._buf)

    def feed(self, data: bytes) -> tuple[list[tuple[int, ...]], list[str]]:
        r"""Parse ``data`` (any chunking) and return the samples and messages it completes.

        The lines it completes are scanned at once (:func:`~helpers.board.lines.scan_data_lines`): the valid
        data lines among them are placed in blocks (:meth:`_place`), every other line is checked on its own
        (:meth:`_line`), in the order they came. A run of bytes without ``\n`` longer than
        :data:`MAX_PENDING` is taken as one line (so it is flagged corrupted) and the rest of it up to the
        next ``\n`` is discarded into a second corrupted line at most.
        """
        samples: list[tuple[int, ...]] = []
        messages: list[str] = []
        self._buf += data
        cut = self._buf.rfind(b"\n") + 1
        complete, rest = bytes(self._buf[:cut]), self._buf[cut:]
        self._buf = bytearray() if len(rest) > MAX_PENDING else rest
        if complete:
            c, a = self.channels, self.axes
            starts, ends, fast, values = scan_data_lines(complete, c, a, self.adc_max, MAX_LINE, WRAP_US)
            done = row = 0  # lines handled, rows of values placed
            for j in [*np.flatnonzero(~fast).tolist(), len(ends)]:  # the lines checked alone, the end
                if j > done:  # lines done .. j - 1: valid data lines
                    self._place(values[row : row + j - done], samples)
                    row += j - done
                if j < len(ends):
                    self._line(complete[starts[j] : ends[j]], samples, messages)
                done = j + 1
        if len(rest) > MAX_PENDING:
            self._line(bytes(rest), samples, messages)
        return samples, messages
