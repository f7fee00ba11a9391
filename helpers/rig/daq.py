"""Driver of the DAQ board (Arduino Mega 2560, 500000 baud): rate, zero, start, stop and the sample stream."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from helpers.board.protocol import StreamParser, StreamStats
from helpers.paper.hardware import (
    DAQ_BAUD,
    DAQ_RATE_DEFAULT_HZ,
    DAQ_RATE_MAX_HZ,
    DAQ_RATE_MIN_HZ,
    MAX_STEP_RATE_HZ,
)
from helpers.rig.boards import BoardError, BoardLink, BoardTimeout

RATE_MIN_HZ, RATE_MAX_HZ = DAQ_RATE_MIN_HZ, DAQ_RATE_MAX_HZ


class ProgrammeStreamParser(StreamParser):
    """:class:`~helpers.board.protocol.StreamParser` that also knows the running programme.

    Besides a step count that changes faster than the step-rate limit, it rejects as implausible one outside
    :attr:`steps_range` and one that changes outside :attr:`step_windows` (their ``seq`` then counts as
    dropped too).
    """

    def __init__(self, max_step_rate_hz: float | None = None) -> None:
        super().__init__(max_step_rate_hz)
        self.steps_range: tuple[int, int] | None = None
        """The step counts the running programme can reach (from ``ZERO``), or None (no check)."""
        self.step_windows: tuple[np.ndarray, np.ndarray] | None = None
        """Sorted, disjoint ``(starts, ends)`` in device us where the programme makes steps, or None (no
        check): a count that changes outside them is impossible."""

    def _plausible(self, t_us: int, steps: int) -> bool:
        """Within the programme's range, no faster than allowed, changed only while the programme steps."""
        rng = self.steps_range
        if rng is not None and not rng[0] <= steps <= rng[1]:
            return False
        if not super()._plausible(t_us, steps):
            return False
        last, windows = self._last_sample, self.step_windows
        if windows is not None and last is not None and steps != last[1]:
            # the count changed in (last t, t]: some window must overlap that interval
            i = int(np.searchsorted(windows[0], t_us, side="right")) - 1
            if i < 0 or windows[1][i] < last[0]:
                return False
        return True


class DaqBoard(BoardLink):
    """The DAQ board: samples (``seq``, ``t_us`` unwrapped, ``adc``, ``steps``) with exact fault counts.

    ``stats`` (a :class:`helpers.board.protocol.StreamStats`) counts, since the last :meth:`start`:
    ``dropped``
    sequence numbers (lines lost or destroyed in transport, including any lost after the last one received,
    known once :meth:`stop` reports how many were sent), ``overruns`` (sample periods the board reports it
    missed) and ``corrupted`` lines. Nothing here raises on garbage.
    """

    kind = "daq"
    baudrate = DAQ_BAUD

    def __init__(self, port, timeout: float = 2.0) -> None:
        super().__init__(port, timeout)
        self.parser = ProgrammeStreamParser(max_step_rate_hz=MAX_STEP_RATE_HZ)
        self.rate_hz = DAQ_RATE_DEFAULT_HZ
        self.streaming = False

    def expect_steps(self, lo: int, hi: int) -> None:
        """Reject (and count as implausible) step counts outside ``lo..hi`` until the next :meth:`start`."""
        self.parser.steps_range = (int(lo), int(hi))

    def expect_steps_within(self, starts_us: np.ndarray, ends_us: np.ndarray) -> None:
        """Reject (and count as implausible) a step count that changes outside these device-time windows.

        Parameters
        ----------
        starts_us, ends_us : numpy.ndarray
            Sorted, disjoint windows (device us, the samples' clock) in which the programme makes steps.
        """
        starts, ends = np.asarray(starts_us, dtype=np.int64), np.asarray(ends_us, dtype=np.int64)
        self.parser.step_windows = (starts, ends)

    @property
    def stats(self) -> StreamStats:
        """Counts of the present (or last) stream."""
        return self.parser.stats

    def set_rate(self, hz: int) -> int:
        """``RATE <hz>``; ``hz`` must be an integer in 100-2000 (checked before sending)."""
        if isinstance(hz, bool) or not isinstance(hz, int) or not RATE_MIN_HZ <= hz <= RATE_MAX_HZ:
            raise ValueError(f"DAQ rate must be an integer in {RATE_MIN_HZ}-{RATE_MAX_HZ} Hz, got {hz!r}")
        self.command(f"RATE {hz}")
        self.rate_hz = hz
        return hz

    def zero(self) -> None:
        """``ZERO``: reset the board's step counter."""
        self.command("ZERO")

    def start(self) -> int:
        """``START``: begin streaming; ``seq`` restarts at 0 and the counts are reset. Returns the rate."""
        self.rows.clear()
        self.parser.restart()
        self.parser.steps_range = None
        self.parser.step_windows = None
        reply = self.command("START")
        self.streaming = True
        words = reply.split()
        if len(words) == 3 and words[2].isdigit():
            self.rate_hz = int(words[2])
        return self.rate_hz

    def stop(self, timeout: float | None = None) -> int:
        """``STOP``; return how many samples the board sent; count those lost after the last one seen.

        Samples that arrive before the reply are kept (read them with :meth:`take_rows`).
        """
        reply = self.command("STOP", timeout=timeout)
        self.streaming = False
        words = reply.split()
        if len(words) != 3 or not words[2].isdigit():
            raise BoardError(f"malformed reply to STOP from the daq board: {reply!r}")
        n = int(words[2])
        last = self.parser.last_seq
        received_span = 0 if last is None else last + 1
        if n > received_span:
            self.parser.stats.dropped += n - received_span
        return n

    def take_rows(self) -> list[tuple[int, int, int, int]]:
        """Return and forget the samples received so far."""
        rows, self.rows = self.rows, []
        return rows

    def read_rows(self) -> list[tuple[int, int, int, int]]:
        """Read once (waiting up to the port's read timeout) and return the new samples."""
        self.pump()
        self.check_reset()
        return self.take_rows()

    def samples(self, silence_timeout: float | None = None) -> Iterator[list[tuple[int, int, int, int]]]:
        """Yield chunks of samples while streaming.

        Raises :class:`BoardTimeout` after ``silence_timeout`` s without a sample and
        :class:`helpers.rig.boards.BoardReset` if the board reboots.
        """
        silence = self.waiter(self.timeout if silence_timeout is None else silence_timeout)
        while True:
            rows = self.read_rows()
            if rows:
                silence = self.waiter(silence.timeout)
                yield rows
            else:
                silence.idle(self.port.timeout or 0.0)
                if silence.expired:
                    raise BoardTimeout(
                        f"the daq board sent no sample for {silence.timeout:.1f} s (it stopped answering)"
                    )
