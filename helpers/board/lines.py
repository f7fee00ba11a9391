r"""The DAQ's data lines in blocks, host-side: the CRC-8 of many lines at once, and scanning a read in numpy.

At 1-5 kHz a line costs more in Python than the twin's physics of its sample, so the host scans a whole read
at once (:func:`scan_data_lines`), with exactly the result of :func:`helpers.board.protocol.unframe` and
:func:`~helpers.board.protocol.parse_body` line by line. The emulated DAQ frames its chunks of samples with
the same CRC-8s (:mod:`helpers.virtual.emulator.framing`).

The CRC-8 (:mod:`helpers.board.crc8`) is linear over GF(2) apart from its initial value: one step of the
register is ``r -> TABLE[r ^ b] = TABLE[r] ^ TABLE[b]``. A byte ``b`` followed by ``m`` more bytes therefore
adds ``A^m(TABLE[b])`` to the final register (``A``: the map ``r -> TABLE[r]``) and the initial value adds
``A^L(INIT)`` for a line of ``L`` bytes: the CRC-8s of many lines are XORs of table look-ups over their bytes
whatever the lines' lengths (:func:`crc8_spans`; a test checks it against the bitwise reference).

The scan is a fast path, not a second parser: it accepts only a line that is certainly a valid data line
(``D,`` then the board's number of integer fields of at most 15 digits, counts in range, the right CRC-8, a
``\r`` before its ``\n`` or none), and gives its fields; every other line goes to the line-by-line parser,
which decides it as before.
"""

from __future__ import annotations

import re
from functools import cache

import numpy as np

from helpers.board.crc8 import INIT, TABLE, XOROUT

MAX_BYTES = 64
"""Longest span :func:`crc8_spans` takes (a line of the protocol has at most 63 bytes)."""

MAX_DIGITS = 15
"""Digits of a field the scan reads (10**15 < 2**53: exact as int64 and as float64)."""


def _tables() -> tuple[np.ndarray, np.ndarray]:
    """``after[256 m + b]``: byte ``b`` followed by ``m`` more bytes; ``init[L]``: INIT after ``L`` bytes."""
    after, init = [np.frombuffer(TABLE, dtype=np.uint8)], [INIT]
    for _ in range(MAX_BYTES):
        after.append(after[0][after[-1]])
        init.append(TABLE[init[-1]])
    return np.concatenate(after[:MAX_BYTES]), np.array(init, dtype=np.uint8)


_AFTER, _INIT_AFTER = _tables()
_HEX_VALUE = np.full(256, -1, dtype=np.int16)
_HEX_VALUE[np.frombuffer(b"0123456789ABCDEF", dtype=np.uint8)] = np.arange(16)
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
    """
    length = ends - starts
    w = int(length.max(initial=0))
    if w > MAX_BYTES:
        raise ValueError(f"a span of {w} bytes: the CRC tables cover {MAX_BYTES}")
    pos = np.arange(-w, 0)[:, None] + ends  # a column per span, right-aligned: w - 1 - j bytes after row j
    index = data.take(pos, mode="wrap") + 256 * np.arange(w - 1, -1, -1)[:, None]
    index[pos < starts] = 0  # before the span: no byte (the register unchanged by it)
    return np.bitwise_xor.reduce(_AFTER[index], axis=0) ^ _INIT_AFTER[length] ^ XOROUT


@cache
def _patterns(channels: int, axes: int) -> tuple[re.Pattern[bytes], re.Pattern[bytes]]:
    r"""A data line's shape (fields of at most :data:`MAX_DIGITS` digits, ``\r\n`` or ``\n``), any number."""
    count, step = rb",[0-9]{1,%d}" % MAX_DIGITS, rb",-?[0-9]{1,%d}" % MAX_DIGITS
    line = rb"D(?:%s){%d}(?:%s){%d}\*[0-9A-F]{2}\r?\n" % (count, 2 + channels, step, axes)
    return re.compile(line), re.compile(rb"(?:%s)*" % line)


_BETWEEN = re.compile(rb"\*[0-9A-F]{2}\r?\n(?:D,|$)")
"""From one data line's fields to the next's, or to the end."""


def scan_data_lines(
    raw: bytes, channels: int, axes: int, adc_max: int, max_line: int, wrap: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    r"""Split complete lines and read the certainly valid data lines among them, all at once.

    Parameters
    ----------
    raw : bytes
        One or more complete lines, each ending in ``\n``.
    channels, axes : int
        The board's fields: ``D,<seq>,<t_us>,<adc_0>..<adc_{C-1}>,<steps_0>..<steps_{A-1}>``.
    adc_max, max_line, wrap : int
        The largest count, the longest line and the clock's wrap (:mod:`helpers.board.protocol`).

    Returns
    -------
    starts, ends : ndarray of int64
        Every line's first byte and its ``\n``.
    fast : ndarray of bool
        The lines that are valid data lines (every check of ``unframe`` and ``parse_body`` passes), each with
        at most :data:`MAX_DIGITS` digits per field.
    values : ndarray of int64, shape (fast.sum(), 2 + channels + axes)
        Their fields, as ``parse_body`` gives them.
    """
    k = 2 + channels + axes
    data = np.frombuffer(raw, dtype=np.uint8)
    ends = np.flatnonzero(data == NEWLINE)
    starts = np.concatenate([[0], ends[:-1] + 1])
    line, block = _patterns(channels, axes)
    if block.fullmatch(raw):  # every line has a data line's shape (the usual case)
        shaped, fields = np.ones(len(ends), dtype=bool), raw
    else:
        bounds = list(zip(starts.tolist(), (ends + 1).tolist(), strict=True))
        shaped = np.array([line.fullmatch(raw, a, b) is not None for a, b in bounds], dtype=bool)
        fields = b"".join([raw[a:b] for (a, b), ok in zip(bounds, shaped.tolist(), strict=True) if ok])
    # every shaped line's fields, one comma-separated list of integers
    values = np.fromstring(_BETWEEN.sub(b",", fields)[2:-1], dtype=np.int64, sep=",").reshape(-1, k)
    idx = np.flatnonzero(shaped)
    s, e = starts[idx], ends[idx] - 3 - (data[ends[idx] - 1] == ord("\r"))  # the body, up to the '*'
    good = (e + 3 - s <= max_line) & (values[:, 1] < wrap)
    good &= np.all(values[:, 2 : 2 + channels] <= adc_max, axis=1)
    s = np.maximum(s, e - max_line)  # a longer line is refused by its length above: its CRC is not needed
    good &= crc8_spans(data, s, e) == _HEX_VALUE[data[e + 1]] * 16 + _HEX_VALUE[data[e + 2]]
    fast = np.zeros(len(ends), dtype=bool)
    fast[idx[good]] = True
    return starts, ends, fast, values[good]
