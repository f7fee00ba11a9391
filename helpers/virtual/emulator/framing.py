"""Framing the emulated DAQ's data lines in blocks: a whole chunk of samples formatted and CRC'd at once.

The same bytes as :func:`helpers.board.protocol.frame` line by line, without its checks (the emulator makes
the bodies); an emulated board streaming at 1-5 kHz faster than real time needs the speed. The CRC-8s are the
host's own (:func:`helpers.board.protocol.crc8_spans`, which the host checks lines with).
"""

from __future__ import annotations

import numpy as np

from helpers.board.protocol import NEWLINE, crc8_spans

_HEX2 = [f"{x:02X}" for x in range(256)]


def frame_data_lines(fields: np.ndarray) -> bytes:
    r"""``D,<f_0>,<f_1>,...*hh\n`` for every row of ``fields``, joined: the bytes of ``frame`` line by line.

    Parameters
    ----------
    fields : ndarray of int, shape (n, F)
        Every line's integers (``seq, t_us, adc_0.., steps_0..``), a line's body at most
        :data:`~helpers.board.protocol.MAX_BYTES` long.

    Returns
    -------
    bytes
        The framed lines, each ending in ``\n``; empty for no rows.
    """
    fields = np.asarray(fields)
    if len(fields) == 0:
        return b""
    form = "D" + ",%d" * fields.shape[1]
    bodies = [form % tuple(row) for row in fields.tolist()]
    data = np.frombuffer("\n".join(bodies).encode("ascii") + b"\n", dtype=np.uint8)
    ends = np.flatnonzero(data == NEWLINE)
    crc = crc8_spans(data, np.concatenate([[0], ends[:-1] + 1]), ends).tolist()
    return "".join([f"{b}*{_HEX2[c]}\n" for b, c in zip(bodies, crc, strict=True)]).encode("ascii")
