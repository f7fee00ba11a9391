r"""The DAQ's data lines in blocks: the CRC-8 of many lines at once, framing and scanning them in numpy.

At 1-5 kHz a line costs more in Python than the twin's physics of its sample, so the emulated DAQ frames a
whole chunk of samples at once (:func:`frame_data_lines`) and the host scans a whole read at once
(:func:`scan_data_lines`); both give exactly what :func:`helpers.board.protocol.frame`,
:func:`~helpers.board.protocol.unframe` and :func:`~helpers.board.protocol.parse_body` give line by line.

The CRC-8 (:mod:`helpers.board.crc8`) is linear over GF(2) apart from its initial value: one step of the
register is ``r -> TABLE[r ^ b] = TABLE[r] ^ TABLE[b]``. A byte ``b`` followed by ``m`` more bytes therefore
adds ``A^m(TABLE[b])`` to the final register (``A``: the map ``r -> TABLE[r]``) and the initial value adds
``A^L(INIT)`` for a line of ``L`` bytes; :func:`crc8_rows` is the XOR of table look-ups over a byte matrix,
whatever the lines' lengths (a test checks it against :func:`~helpers.board.crc8.crc8` and the bitwise
reference).

The scan is a fast path, not a second parser: it accepts only a line that is certainly a valid data line
(``D,`` then the board's number of integer fields of at most 15 digits, counts in range, the right CRC-8), and
gives its fields; every other line goes to the line-by-line parser, which decides it as before.
"""

from __future__ import annotations

import numpy as np

from helpers.board.crc8 import INIT, TABLE, XOROUT

MAX_BYTES = 64
"""Longest run of bytes :func:`crc8_rows` takes per row (a line of the protocol has at most 63)."""

MAX_DIGITS = 15
"""Digits of a field the scan reads (10**15 < 2**53: exact as int64 and as float64)."""


def _tables() -> tuple[np.ndarray, np.ndarray]:
    table = np.frombuffer(TABLE, dtype=np.uint8)
    after = np.empty((MAX_BYTES, 256), dtype=np.uint8)  # after[m, b]: byte b followed by m bytes
    after[0] = table
    init = np.empty(MAX_BYTES + 1, dtype=np.uint8)  # init[L]: the initial value after L bytes
    init[0] = INIT
    for m in range(1, MAX_BYTES + 1):
        init[m] = table[init[m - 1]]
        if m < MAX_BYTES:
            after[m] = table[after[m - 1]]
    return after.reshape(-1), init


_AFTER, _INIT_AFTER = _tables()
_POW10 = 10 ** np.arange(MAX_DIGITS + 4, dtype=np.int64)
_HEX = np.frombuffer(b"0123456789ABCDEF", dtype=np.uint8)
_HEX_VALUE = np.full(256, -1, dtype=np.int16)
_HEX_VALUE[_HEX] = np.arange(16)
COMMA, MINUS, STAR, NEWLINE = b",-*\n"
_WEIGHT = np.full(256, 4096, dtype=np.int64)
_WEIGHT[48:58], _WEIGHT[COMMA], _WEIGHT[MINUS] = 0, 1, 64
_AFTER_OFFSET = 256 * np.arange(MAX_BYTES, dtype=np.int64)


def _crc8(index: np.ndarray, length: np.ndarray) -> np.ndarray:
    """The CRC-8 of rows of bytes given as ``index = 256 * (bytes after it in its row) + byte`` (0: none)."""
    crc = np.bitwise_xor.reduce(_AFTER[index], axis=1) if index.shape[1] else np.zeros(len(index), np.uint8)
    return crc ^ _INIT_AFTER[length] ^ XOROUT


def crc8_rows(grid: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """The CRC-8 of every row's valid bytes in their order (the bytes between are skipped).

    Parameters
    ----------
    grid : ndarray of uint8, shape (n, w)
        The bytes, ``w <= MAX_BYTES`` valid ones per row at most.
    valid : ndarray of bool, shape (n, w)
        Which bytes belong to the row's line.

    Returns
    -------
    ndarray of uint8, shape (n,)
        ``crc8(bytes(grid[i][valid[i]]))`` for every row ``i``.
    """
    kept = np.cumsum(valid, axis=1)
    length = kept[:, -1] if grid.shape[1] else np.zeros(len(grid), dtype=np.int64)
    if length.size and length.max() > MAX_BYTES:
        raise ValueError(f"a row of {length.max()} bytes: the CRC tables cover {MAX_BYTES}")
    return _crc8(np.where(valid, (length[:, None] - kept) * 256 + grid, 0), length)


def frame_data_lines(fields: np.ndarray) -> bytes:
    r"""``D,<f_0>,<f_1>,...*hh\n`` for every row of ``fields``, joined: the bytes of ``frame`` line by line.

    Parameters
    ----------
    fields : ndarray of int, shape (n, F)
        Every line's integers (``seq, t_us, adc_0.., steps_0..``), any sign, at most 18 digits.
    """
    fields = np.asarray(fields, dtype=np.int64)
    n, f = fields.shape
    if n == 0:
        return b""
    mag = np.abs(fields)
    digits = 1 + np.count_nonzero(mag[..., None] >= _POW10[1:19], axis=-1)  # (n, F)
    w = int(digits.max())
    slot = np.empty((n, f, w + 2), dtype=np.uint8)  # per field: ',', '-', w digits right-aligned
    slot[..., 0] = COMMA
    slot[..., 1] = MINUS
    slot[..., 2:] = (mag[..., None] // _POW10[w - 1 :: -1]) % 10 + 48
    keep = np.empty((n, f, w + 2), dtype=bool)
    keep[..., 0] = True
    keep[..., 1] = fields < 0
    keep[..., 2:] = np.arange(w) >= (w - digits)[..., None]
    body = np.concatenate([np.full((n, 1), ord("D"), np.uint8), slot.reshape(n, -1)], axis=1)
    body_keep = np.concatenate([np.ones((n, 1), bool), keep.reshape(n, -1)], axis=1)
    crc = crc8_rows(body, body_keep)
    tail = np.empty((n, 4), dtype=np.uint8)
    tail[:, 0], tail[:, 1], tail[:, 2], tail[:, 3] = STAR, _HEX[crc >> 4], _HEX[crc & 15], NEWLINE
    grid = np.concatenate([body, tail], axis=1)
    return grid[np.concatenate([body_keep, np.ones((n, 4), bool)], axis=1)].tobytes()


def scan_data_lines(
    data: np.ndarray, channels: int, axes: int, adc_max: int, max_line: int, wrap: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    r"""Split complete lines and read the certainly valid data lines among them, all at once.

    Parameters
    ----------
    data : ndarray of uint8
        Complete lines, each ending in ``\n``.
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
    ends = np.flatnonzero(data == NEWLINE)
    starts = np.empty_like(ends)
    starts[:1], starts[1:] = 0, ends[:-1] + 1
    # every byte weighs: a comma 1, a minus 64, anything but a digit 4096; a line holds fewer than 64 of each
    weight = np.zeros(len(data) + 1, dtype=np.int64)
    np.cumsum(_WEIGHT[data], out=weight[1:])
    after_d = np.minimum(starts + 1, ends)
    e = np.maximum(ends - 3, after_d)  # the body's end (at the '*')
    inside = weight[e] - weight[after_d]  # of the fields: from the first comma to the '*'
    hi, lo = _HEX_VALUE[data[np.maximum(ends - 2, 0)]], _HEX_VALUE[data[np.maximum(ends - 1, 0)]]
    ok = (
        (ends - starts >= 2 * k + 4) & (ends - starts <= max_line) & (inside % 64 == k) & (inside < 4096)
        & (data[starts] == ord("D")) & (data[after_d] == COMMA) & (data[e] == STAR) & (hi >= 0) & (lo >= 0)
    )  # fmt: skip
    fast = np.zeros(len(ends), dtype=bool)
    if not ok.any():
        return starts, ends, fast, np.zeros((0, k), dtype=np.int64)
    commas = np.flatnonzero(data == COMMA)
    commas = commas[ok[np.searchsorted(ends, commas)]].reshape(-1, k)  # k in every line kept, in order
    idx = np.flatnonzero(ok)
    s, e = starts[idx], e[idx]
    first = commas + 1
    last = np.empty_like(commas)  # one past each field's end
    last[:, :-1], last[:, -1] = commas[:, 1:], e
    signed = data[first] == MINUS
    width = last - first - signed
    good = (
        np.all((width >= 1) & (width <= MAX_DIGITS) & ((np.arange(k) >= 2 + channels) | ~signed), axis=1)
        & (np.count_nonzero(signed, axis=1) == inside[idx] // 64)
    )  # fmt: skip
    w = int(np.clip(width, 1, MAX_DIGITS).max(initial=1))  # a wider field is not read (not good)
    pos = last[..., None] - w + np.arange(w)
    digits = np.where(pos >= (first + signed)[..., None], data[np.maximum(pos, 0)].astype(np.int64) - 48, 0)
    values = digits @ _POW10[w - 1 :: -1]
    values = np.where(signed, -values, values)
    good &= (values[:, 1] < wrap) & np.all(values[:, 2 : 2 + channels] <= adc_max, axis=1)
    w = int((e - s).max(initial=0))  # the longest body: right-aligned, byte j has w - 1 - j after it
    pos = e[:, None] - w + np.arange(w)
    index = np.where(pos >= s[:, None], data[np.maximum(pos, 0)] + _AFTER_OFFSET[w - 1 :: -1], 0)
    good &= _crc8(index, e - s) == hi[idx] * 16 + lo[idx]
    fast[idx[good]] = True
    return starts, ends, fast, values[good]
