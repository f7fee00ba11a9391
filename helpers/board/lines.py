r"""The CRC-8 of many lines at once, in numpy: the host checks a whole read with it, the emulated DAQ frames.

At 1-5 kHz a line costs more in Python than the twin's physics of its sample, so the host checks every line
of a read at once (:func:`helpers.board.protocol.unframe`) and the emulated DAQ frames its chunks of samples
with the same CRC-8s (:mod:`helpers.virtual.emulator.framing`).

The CRC-8 (:mod:`helpers.board.crc8`) is linear over GF(2) apart from its initial value: one step of the
register is ``r -> TABLE[r ^ b] = TABLE[r] ^ TABLE[b]``. A byte ``b`` followed by ``m`` more bytes therefore
adds ``A^m(TABLE[b])`` to the final register (``A``: the map ``r -> TABLE[r]``) and the initial value adds
``A^L(INIT)`` for a line of ``L`` bytes: the CRC-8s of many lines are XORs of table look-ups over their bytes
whatever the lines' lengths (:func:`crc8_spans`; a test checks it against the bitwise reference).
"""

from __future__ import annotations

import numpy as np

from helpers.board.crc8 import INIT, TABLE, XOROUT

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
