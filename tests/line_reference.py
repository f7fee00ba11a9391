"""The line-by-line checks of protocol 2 as the host made them before it checked reads at once: a reference.

``unframe`` checks one line's framing and CRC-8, ``parse_body`` classifies its body; :func:`check_line` is
what the parser did with one line (tests compare ``helpers.board.protocol.StreamParser`` against it).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import reduce
from operator import xor

import numpy as np

from helpers.board.crc8 import crc8
from helpers.board.protocol import MAX_LINE, WRAP_US

_HEX = "0123456789ABCDEF"
_LEGACY_BODY = re.compile(r"(HELLO|PONG) (daq|stepper) 1\.[0-9]+\.[0-9]+|ERR CHECKSUM( .*)?")


class FramingError(ValueError):
    """A line failed a framing check; the message names the check."""


class LegacyChecksum(FramingError):
    """The line's CRC-8 is wrong but its ``*hh`` is the XOR checksum of protocol 1 (firmware 1.x)."""


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


def check_line(self, line: bytes, samples: list, messages: list) -> None:
    r"""What ``StreamParser`` ``self`` did with one complete line (without its ``\n``), line by line."""
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
