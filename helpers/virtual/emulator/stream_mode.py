"""The emulated stepper's streaming mode (``SHAPER``, ``IMP``, ``STREAM``, ``V``, ``MV``, ``END``), A axes.

Every rule and every number comes from :mod:`helpers.board.stream_reference`, the reference of the firmware's
streaming shaper: the impulse checks (:func:`~helpers.board.stream_reference.impulse_problem`), the set-point
FIFO, ``V``, ``MV``, ``END``, the watchdog and the control tick (:class:`~helpers.board.stream_reference.
StreamSession`, of one axis or several), the step times (:class:`~helpers.board.stream_reference.Planner`, one
per axis, with the build's travel and set-point limit). This module only loads the shaper as the firmware's
``IMP`` handler does, runs the control ticks on the world's device clock (tick k at ``STREAM`` + k x 10 ms)
and words the replies and notices as the firmware does.

A build with several axes: every axis planned from the one shaper with its own travel, ``MV`` for every
axis's set-point, notices naming axes 1.., the STEP edges 24 us after their ticks (the firmware's
``STREAM_LEAD_AXES``; 16 us on a one-axis build), the longest delay 0.62 s.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from helpers.board import stream_reference as hs

STEP_EDGE_S = 16e-6
"""A streamed STEP edge follows its planned tick by 16 us (the firmware's ``STREAM_STEP_LEAD_TICKS``)."""

STEP_EDGE_AXES_S = 24e-6
"""On a build with several axes a streamed STEP edge follows its tick by 24 us (``STREAM_LEAD_AXES``)."""

PERIOD_S = hs.PERIOD_TICKS * hs.TICK_S
"""The control period (10 ms)."""

AMPLITUDE_TEXT = "ERR RANGE amplitude -16384..16384 (>= 0 unless allowed)"


def delay_text(max_delay_us: int) -> str:
    """The refusal of a delay (``<= 1 s``; ``<= 0.62 s`` on a build with several axes)."""
    return f"ERR RANGE delay: 0 first, rising, 16 us units, <= {max_delay_us / 1e6:g} s"


class ShaperLoader:
    """``SHAPER <n> <neg>`` then ``IMP <i> <a> <d_us>`` for i = 0 .. n-1, checked impulse by impulse.

    ``max_delay_us``: the build's longest delay (``MAX_DELAY_US``; ``MAX_DELAY_US_AXES`` for several axes).
    """

    def __init__(self, max_delay_us: int = hs.MAX_DELAY_US) -> None:
        self.max_delay_us = max_delay_us
        self.ready: hs.StreamShaper | None = None
        """The loaded shaper (None until a complete, valid one has been loaded)."""
        self._expect = 0
        self._amplitudes: list[int] = []
        self._delays: list[int] = []
        self._negative = False

    def begin(self, n: int, negative: int) -> str:
        """``SHAPER``: the reply (the caller has checked the arguments' count and the state)."""
        if not 1 <= n <= hs.MAX_IMPULSES:
            return f"ERR RANGE 1-{hs.MAX_IMPULSES} impulses"
        if negative not in (0, 1):
            return "ERR RANGE negative amplitudes 0 or 1"
        self.ready = None  # SHAPER discards the loaded shaper
        self._expect, self._negative = n, bool(negative)
        self._amplitudes, self._delays = [], []
        return f"OK SHAPER {n}"

    def impulse(self, index: int, amplitude: int, delay_us: int) -> str:
        """``IMP``: the reply; after the last impulse the shaper is :attr:`ready` if it sums to 1."""
        i = len(self._amplitudes)
        if not self._expect or index != i:
            return "ERR STATE SHAPER first, impulses in order"
        previous = self._delays[-1] if self._delays else -1
        problem = hs.impulse_problem(i, amplitude, delay_us, previous, self._negative, self.max_delay_us)
        if problem is not None:
            self._expect = 0  # the shaper is discarded: start again with SHAPER
            return AMPLITUDE_TEXT if problem == "amplitude" else delay_text(self.max_delay_us)
        self._amplitudes.append(amplitude)
        self._delays.append(delay_us)
        if len(self._amplitudes) == self._expect:
            self._expect = 0
            if sum(self._amplitudes) != hs.AMP_ONE:
                return f"ERR RANGE amplitudes must sum to {hs.AMP_ONE}"
            self.ready = hs.StreamShaper(tuple(self._amplitudes), tuple(self._delays), self._negative)
        return f"OK IMP {i}"


class StreamMode:
    """One stream of the emulated stepper, on the world's device clock, for a build of one or several axes.

    Parameters
    ----------
    shaper : helpers.board.stream_reference.StreamShaper
        The loaded shaper (every axis's).
    positions : sequence of int
        Each axis's step count at ``STREAM``.
    travels : sequence of int
        Each axis's travel (the build's).
    t0 : float
        Device time of ``STREAM`` (s): control tick k falls at ``t0 + k * PERIOD_S``.
    send : callable
        Queues one line from the board (notices, with ``,<axis>`` for axes 1..).
    releases : sequence of int or None
        Each axis's paid-out range below zero (the build's; default none).
    v_max : int
        The build's set-point limit (:func:`helpers.board.stream_reference.v_max` of its fastest step).
    """

    def __init__(
        self, shaper: hs.StreamShaper, positions: Sequence[int], travels: Sequence[int], t0: float,
        send: Callable[[str], None], releases: Sequence[int] | None = None, v_max: int = hs.V_MAX,
    ) -> None:  # fmt: skip
        self.session = hs.StreamSession(hs.AxesRun(shaper, positions, travels, releases, v_max))
        self.edge_s = STEP_EDGE_S if len(positions) == 1 else STEP_EDGE_AXES_S
        self.t0 = t0
        self._send = send
        self._planned = [0] * len(positions)  # each axis's planned steps already moved to the pending arrays
        self._noticed = 0
        self._times = np.zeros(0)
        self._axes = np.zeros(0, dtype=np.int64)
        self._signs = np.zeros(0, dtype=np.int64)
        self.finished = False
        """True once the stream has stopped (``DONE`` is due)."""

    @property
    def next_tick(self) -> float:
        """Device time of the next control tick (s)."""
        return self.t0 + self.session.next_period * PERIOD_S

    def setpoint(self, v: int) -> str:
        """``V``: the reply."""
        try:
            return f"OK V {self.session.setpoint(v)}"
        except hs.StreamRefused as exc:
            return str(exc)

    def setpoints(self, vs: Sequence[int]) -> str:
        """``MV <v_0> ...`` (the caller has checked that there is one per axis): the reply."""
        try:
            return f"OK MV {self.session.setpoints(vs)}"
        except hs.StreamRefused as exc:
            return str(exc)

    def end(self) -> str:
        """``END``: the reply."""
        try:
            return f"OK END {self.session.end()}"
        except hs.StreamRefused as exc:
            return str(exc)

    def _take(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        j = int(np.searchsorted(self._times, t + 1e-12, side="right"))
        out = self._times[:j], self._axes[:j], self._signs[:j]
        self._times, self._axes, self._signs = self._times[j:], self._axes[j:], self._signs[j:]
        return out

    def _tick(self) -> None:
        alive = self.session.tick()
        run = self.session.run
        for n in run.notices[self._noticed :]:
            self._send(n.line)
        self._noticed = len(run.notices)
        times, axes, signs = [self._times], [self._axes], [self._signs]
        for a, planner in enumerate(run.planners):
            done = self._planned[a]
            if len(planner.ticks) > done:
                ticks = np.asarray(planner.ticks[done:], dtype=np.int64)
                times.append(self.t0 + ticks * hs.TICK_S + self.edge_s)
                axes.append(np.full(len(ticks), a, dtype=np.int64))
                signs.append(np.asarray(planner.dirs[done:], dtype=np.int64))
                self._planned[a] = len(planner.ticks)
        if len(times) > 1:
            t, ax = np.concatenate(times), np.concatenate(axes)
            order = np.lexsort((ax, t))  # by time, steps on one tick in the axes' order
            self._times, self._axes, self._signs = t[order], ax[order], np.concatenate(signs)[order]
        self.finished = not alive

    def steps_until(self, t1: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Run the control ticks due by ``t1`` and take the steps due by ``t1``: ``(times, axes, signs)``.

        Times in s (the STEP edges). Stops at the tick where the stream finishes (:attr:`finished`): every
        step it planned is due by then.
        """
        parts = []
        while not self.finished and self.next_tick <= t1 + 1e-12:
            parts.append(self._take(self.next_tick))
            self._tick()
        parts.append(self._take(t1))
        return tuple(np.concatenate(p) for p in zip(*parts, strict=True))  # type: ignore[return-value]
