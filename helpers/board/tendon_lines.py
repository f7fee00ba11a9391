"""Data lines of a DAQ board built for several tendons (``firmware/PROTOCOL.md``, *several tendons*).

``D,<seq>,<t_us>,<adc_0>,...,<adc_{C-1}>,<steps_0>,...,<steps_{A-1}>``.

:class:`TendonStreamParser` is :class:`~helpers.board.protocol.StreamParser` for such lines: the same
framing, CRC-8 check, sequence, clock unwrapping and exact fault counts; each sample is the tuple
``(seq, t_us_unwrapped, adc_0, ..., adc_{C-1}, steps_0, ..., steps_{A-1})``. A line with another number
of fields, a non-integer field or an ADC count above 1023 is counted as corrupted.
"""

from __future__ import annotations

from helpers.board.protocol import (
    WRAP_US,
    FramingError,
    LegacyChecksum,
    Overrun,
    StreamParser,
    parse_body,
    unframe,
)
from helpers.paper.hardware import ADC_MAX

__all__ = ["TendonStreamParser", "parse_tendon_line"]


def parse_tendon_line(body: str, channels: int, axes: int) -> tuple[int, ...]:
    """The integers of a checked data line body of ``channels`` ADC counts and ``axes`` step counts.

    Raises
    ------
    FramingError
        Another number of fields, a malformed field or one out of range.
    """
    parts = body.split(",")
    if len(parts) != 3 + channels + axes:
        raise FramingError(f"data line with {len(parts)} fields, expected {3 + channels + axes}")
    try:
        values = tuple(int(p) for p in parts[1:])
    except ValueError:
        raise FramingError("data line with a non-integer field") from None
    if any(not p.lstrip("-").isdigit() for p in parts[1:]):
        raise FramingError("data line with a non-integer field")
    seq, t_us, adcs = values[0], values[1], values[2 : 2 + channels]
    if seq < 0 or not 0 <= t_us < WRAP_US or any(not 0 <= a <= ADC_MAX for a in adcs):
        raise FramingError("data line field out of range")
    return values


class TendonStreamParser(StreamParser):
    """The DAQ stream of a board with ``channels`` load cells and ``axes`` step counters."""

    def __init__(self, channels: int, axes: int) -> None:
        super().__init__(max_step_rate_hz=None)
        self.channels = channels
        self.axes = axes

    def feed(self, data: bytes) -> tuple[list[tuple[int, ...]], list[str]]:  # type: ignore[override]
        """Parse ``data`` (any chunking) and return the samples and messages it completes."""
        samples: list[tuple[int, ...]] = []
        messages: list[str] = []
        for line in self._lines(data):
            if not line.strip(b"\r"):
                continue
            try:
                body = unframe(line)
                item = (parse_tendon_line(body, self.channels, self.axes) if body.startswith("D,")
                        else parse_body(body))  # fmt: skip
            except FramingError as exc:
                self._corrupt(line, str(exc))
                if isinstance(exc, LegacyChecksum) and self.legacy is None:
                    self.legacy = line.rstrip(b"\r").rpartition(b"*")[0].decode("ascii", "replace")
                continue
            if isinstance(item, tuple):
                seq = item[0]
                if self.last_seq is not None and seq <= self.last_seq:
                    self._corrupt(line, f"seq {seq} after {self.last_seq}")
                    continue
                t_us = self.unwrap(item[1])
                self.stats.dropped += seq - (0 if self.last_seq is None else self.last_seq + 1)
                self.last_seq = seq
                self.stats.samples += 1
                samples.append((seq, t_us, *item[2:]))
            elif isinstance(item, Overrun):
                self.stats.overruns += item.n
            else:
                messages.append(item)
        return samples, messages
