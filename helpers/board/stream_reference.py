"""Reference implementation of the stepper board's streaming input shaper (``firmware/PROTOCOL.md``).

The board convolves a stream of velocity set-points with one loaded shaper and turns the shaped velocity into
step times. This module does exactly what the firmware (``firmware/stepper_uno``) does, with the same integer
arithmetic, so that its step times can be compared with the firmware's tick for tick (the exact shaped
trajectory that the steps follow, in floating point, is the tests' independent check of it:
``tests/stream_exact.py``). It imports numpy only.

Fixed point (all integers):

- time: the timer tick is 0.5 us; the shaper's delays and the velocity's time base are ``DELTA`` = 32 ticks
  (16 us); a control period is ``PERIOD`` = 625 DELTA = 10 ms;
- velocity set-point ``v``: units of 2^-16 step per DELTA (0.95367431640625 steps/s), ``|v| <= v_max``, the
  build's :func:`v_max` ``= floor(2^20 / min_interval_us)``: the paper's ``V_MAX`` = 1640 (1564.0 steps/s =
  399.2 mm/s: a step every 639.375 us at most), 2001 on a build whose fastest step is 524 us;
- amplitude ``a``: units of 2^-12 (4096 = 1), ``|a| <= 16384``; the amplitudes sum to exactly 4096;
- shaped velocity ``S = sum a_i v(t - d_i)``: units of 2^-28 step per DELTA, clamped to
  ``+-v_max * 4096`` (the paper's ``S_MAX`` = 1640 * 4096);
- position: the step count ``c`` and a residual ``r`` (units of 2^-28 step, ``|r| < 2^28``) with the exact
  position ``x = c + r / 2^28``. ``r`` is exact at every DELTA boundary: nothing is rounded, ever.

Step-time rule: within a piece of constant ``S`` (the pieces of a period are cut at the shaper's delays modulo
the period), a step up is due when ``x`` reaches ``c + 1`` and a step down when it reaches ``c - 1`` (a
hysteresis of one step: the count is within one step of ``x`` at every instant and a small oscillation does
not chatter); it is issued at the first timer tick at or after that exact instant (a ceiling). The travel
limits clamp the exact position: at ``c = 156`` with ``r = 0`` an upward ``S`` is held at zero
(``N,LIMIT,TRAVEL``), likewise at ``-release`` (0 on a build without a paid-out range below zero,
``RIG_AXIS_RELEASE_STEPS``). Timeline: set-point k (the k-th period's, k >= 1) is taken at control
tick k (``k * 10 ms`` after ``STREAM``) and drives the velocity over ``[(k + 1) * 10 ms, (k + 2) * 10 ms)``.

Several axes (a build with ``RIG_AXES`` > 1, ``MV``): every axis is this planner with its own set-points and
travel, shaped by the one shaper (:class:`AxesRun` tick by tick, :class:`StreamSession` with ``MV``'s FIFO,
:func:`drive_axes` through a whole stream); the longest delay there is ``MAX_DELAY_US_AXES``. One axis is the
case A = 1 of the same classes. (The tests run it through the streams a board took, ``tests/stream_run.py``.)
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

TICK_S = 0.5e-6
"""Timer1 tick (s)."""
DELTA = 32
"""Ticks per DELTA (16 us): the unit of shaper delays and the time base of velocities."""
PERIOD = 625
"""DELTA per control period (10 ms)."""
PERIOD_TICKS = PERIOD * DELTA
FRAC_BITS = 28
ONE = 1 << FRAC_BITS
"""One step in residual units."""
AMP_ONE = 4096
"""Amplitude units per 1 (2^12)."""
AMP_MAX = 16384
"""Largest amplitude magnitude (4.0)."""
V_MAX = 1640
"""The paper's build's largest set-point magnitude (:func:`v_max` of its 639 us): 1640 * 2^-16 step per 16 us
= 1564.0 steps/s (a step every 639.375 us). Another build's is :func:`v_max` of its fastest step."""
S_MAX = V_MAX * AMP_ONE
"""The paper's build's largest shaped velocity magnitude (the speed limit on the shaped output)."""
TRAVEL_MAX = 156
MAX_IMPULSES = 8
DELAY_UNIT_US = 16
MAX_DELAY_US = 1_000_000
WATCHDOG_PERIODS = 10
"""Control periods without a set-point (100 ms) after which the board feeds zero and then stops."""
FIFO_DEPTH = 8
HISTORY = 128
"""Set-points the board remembers (the longest delay needs 102)."""
MAX_DELAY_US_AXES = 620_000
"""The longest delay on a build with several axes (64 set-points of history per axis, PROTOCOL.md)."""
HISTORY_AXES = 64
"""Set-points each axis remembers on a build with several axes."""
STEPS_PER_S_PER_UNIT = (1.0 / (1 << 16)) / (DELTA * TICK_S)
"""Steps per second of one set-point unit (0.95367431640625)."""


def v_max(min_interval_us: int) -> int:
    """A build's largest set-point magnitude: ``floor(2^20 / min_interval_us)`` (the firmware's ``SP_V_MAX``).

    A set-point ``v`` steps every ``2^20 / v`` us, so the board's fastest step interval bounds it: 1640 for
    the paper's 639 us, 2001 for 524 us. The shaped velocity is clamped at ``v_max * 4096``.
    """
    return (1 << 20) // min_interval_us


# --- shapers -----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StreamShaper:
    """A shaper as the board holds it: amplitudes in 2^-12, delays in microseconds (multiples of 16).

    Attributes
    ----------
    amplitudes : tuple of int
        ``a_i``, summing to exactly 4096.
    delays_us : tuple of int
        ``d_i``: 0 = d_0 < d_1 < ... <= 1 000 000, multiples of 16.
    allow_negative : bool
        Negative amplitudes are refused unless this is set (``SHAPER <n> 1``).
    """

    amplitudes: tuple[int, ...]
    delays_us: tuple[int, ...]
    allow_negative: bool = False

    def __post_init__(self) -> None:
        error = shaper_error(self.amplitudes, self.delays_us, self.allow_negative)
        if error is not None:
            raise ValueError(error)

    @property
    def delays_delta(self) -> tuple[int, ...]:
        """Delays in DELTA units."""
        return tuple(d // DELAY_UNIT_US for d in self.delays_us)

    @property
    def duration_s(self) -> float:
        """The last impulse's delay (s)."""
        return self.delays_us[-1] * 1e-6

    def commands(self) -> list[str]:
        """The command bodies that load this shaper (``SHAPER``, then one ``IMP`` per impulse)."""
        out = [f"SHAPER {len(self.amplitudes)} {int(self.allow_negative)}"]
        pairs = zip(self.amplitudes, self.delays_us, strict=True)
        out += [f"IMP {i} {a} {d}" for i, (a, d) in enumerate(pairs)]
        return out

    @classmethod
    def quantise(
        cls, amplitudes: Sequence[float], delays_s: Sequence[float], allow_negative: bool = False
    ) -> StreamShaper:
        """Round a real shaper to the board's representation.

        Delays are rounded to 16 us; amplitudes to 2^-12, and the rounding remainder (so that they sum to
        exactly 4096) goes to the largest impulse. Impulses that land on the same 16 us are merged.

        Raises
        ------
        ValueError
            If the result is not a valid board shaper (too many impulses, delay over 1 s, ...).
        """
        a = np.asarray(amplitudes, dtype=float)
        d = np.asarray(delays_s, dtype=float)
        if a.shape != d.shape or a.ndim != 1 or len(a) == 0:
            raise ValueError("amplitudes and delays must be two 1-D sequences of the same, non-zero length")
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(d))):
            raise ValueError("amplitudes and delays must be finite")
        d_units = np.rint((d - d[0]) * 1e6 / DELAY_UNIT_US).astype(np.int64)
        merged: dict[int, float] = {}
        for du, ai in zip(d_units.tolist(), a.tolist(), strict=True):
            merged[du] = merged.get(du, 0.0) + ai
        keys = sorted(merged)
        total = sum(merged.values())
        amps = [round(merged[k] / total * AMP_ONE) for k in keys]
        largest = max(range(len(amps)), key=lambda i: abs(amps[i]))
        amps[largest] += AMP_ONE - sum(amps)
        return cls(tuple(amps), tuple(k * DELAY_UNIT_US for k in keys), allow_negative)


def impulse_problem(
    index: int,
    amplitude: int,
    delay_us: int,
    previous_us: int,
    allow_negative: bool,
    max_delay_us: int = MAX_DELAY_US,
) -> str | None:
    """The board's check of one impulse as ``IMP`` receives it (the firmware's ``sp_check_impulse``).

    Parameters
    ----------
    index : int
        The impulse's index (0 first).
    amplitude, delay_us : int
        As sent: units of 1/4096, microseconds.
    previous_us : int
        The previous impulse's delay (-1 before the first).
    allow_negative : bool
        ``SHAPER <n> 1``.
    max_delay_us : int
        The build's longest delay: ``MAX_DELAY_US`` (one axis), ``MAX_DELAY_US_AXES`` (several axes).

    Returns
    -------
    str or None
        ``"amplitude"`` or ``"delay"`` (the board's two ``ERR RANGE`` cases), or None when acceptable.
    """
    if not -AMP_MAX <= amplitude <= AMP_MAX or (amplitude < 0 and not allow_negative):
        return "amplitude"
    if delay_us % DELAY_UNIT_US or not 0 <= delay_us <= max_delay_us:
        return "delay"
    if (delay_us != 0) if index == 0 else (delay_us <= previous_us):
        return "delay"
    return None


def shaper_error(amplitudes: Sequence[int], delays_us: Sequence[int], allow_negative: bool) -> str | None:
    """The board's checks of a shaper, in its order; the reason it refuses the shaper, or None."""
    n = len(amplitudes)
    if not 1 <= n <= MAX_IMPULSES or len(delays_us) != n:
        return f"1 to {MAX_IMPULSES} impulses, one delay each"
    previous = -1
    for i, (a, d) in enumerate(zip(amplitudes, delays_us, strict=True)):
        problem = impulse_problem(i, a, d, previous, allow_negative)
        if problem == "amplitude":
            return f"impulse {i}: amplitude {a} outside {-AMP_MAX if allow_negative else 0}..{AMP_MAX}"
        if problem == "delay":
            return f"impulse {i}: delay {d} us (0 first, then increasing, multiples of 16, <= 1 s)"
        previous = d
    if sum(amplitudes) != AMP_ONE:
        return f"amplitudes sum to {sum(amplitudes)}, not {AMP_ONE}"
    return None


UNIT_SHAPER = StreamShaper((AMP_ONE,), (0,))
"""The identity: the stream is passed through unshaped (load it when the host shapes the stream itself)."""


def board_shaper(shaper: object | None) -> StreamShaper:
    """The shaper to load on the board for ``shaper``.

    Parameters
    ----------
    shaper : StreamShaper, object with ``amplitudes`` and ``times`` (s), or None
        A board shaper as it is; a real one (e.g. :class:`helpers.paper.shapers.Shaper`) rounded by
        :meth:`StreamShaper.quantise` (negative amplitudes allowed when it has any); None: the unit shaper
        (no shaping).

    Raises
    ------
    ValueError
        Naming the problem: amplitudes that do not sum to 1, an impulse beyond 1 s, more than 8 impulses, ...
    """
    if shaper is None:
        return UNIT_SHAPER
    if isinstance(shaper, StreamShaper):
        return shaper
    try:
        amplitudes = np.asarray(shaper.amplitudes, dtype=float)  # type: ignore[attr-defined]
        times = np.asarray(shaper.times, dtype=float)  # type: ignore[attr-defined]
    except (AttributeError, TypeError, ValueError):
        raise ValueError(f"a shaper needs amplitudes and times, got {type(shaper).__name__}") from None
    name = getattr(shaper, "name", "shaper")
    if amplitudes.size and np.all(np.isfinite(amplitudes)) and abs(amplitudes.sum() - 1.0) > 1e-6:
        raise ValueError(f"shaper {name!r}: the amplitudes sum to {amplitudes.sum():.6g}, not 1")
    try:
        return StreamShaper.quantise(amplitudes, times, allow_negative=bool(np.any(amplitudes < 0)))
    except ValueError as exc:
        raise ValueError(f"shaper {name!r} cannot be loaded on the board: {exc}") from None


# --- the set-point of every period ------------------------------------------------------------------------
class SetpointRules:
    """The board's rule for the set-point of each control period (the first half of its control tick).

    ``take(k, arrived)`` gives period ``k``'s set-point: the one that arrived for it (``OK V <k>``), else zero
    (an underrun: the period moves nothing, so the cable never goes further than the set-points sent, however
    late the host is; firmware 2.0.0 held the previous set-point instead); after ``WATCHDOG_PERIODS``
    underruns in a row the watchdog fires and that period and every later one is zero; from ``end_period`` on
    (``OK END``) every period without a set-point is zero. ``state`` is ``active``, ``end`` or ``watchdog``.
    """

    def __init__(self, end_period: int | None = None) -> None:
        self.end_period = end_period
        self.state = "active"
        self.underruns = 0

    def take(self, k: int, arrived: int | None) -> int:
        """The set-point of period ``k`` (periods are taken in order: 1, 2, ...)."""
        if self.state == "active" and self.end_period is not None and k >= self.end_period:
            self.state = "end"
        if arrived is not None:
            self.underruns = 0
            return arrived
        if self.state == "active":
            self.underruns += 1
            if self.underruns > WATCHDOG_PERIODS:
                self.state = "watchdog"
        return 0


# --- the planner -----------------------------------------------------------------------------------------
@dataclass
class Notice:
    """An unsolicited ``N,...`` line: ``kind`` is ``LIMIT,SPEED``, ``LIMIT,TRAVEL`` or ``WATCHDOG``.

    ``axis``: the axis a limit notice is about (the board appends ``,<axis>`` for axes 1, 2, 3).
    """

    kind: str
    value: int
    period: int
    axis: int = 0

    @property
    def line(self) -> str:
        """The notice as the board sends it."""
        return f"N,{self.kind},{self.value}" + (f",{self.axis}" if self.axis else "")


def _ceil_ticks(rem: int, s: int) -> int:
    """``ceil(DELTA * rem / s)`` for 0 <= rem < s (the firmware does 5 steps of long division)."""
    x, q = rem, 0
    for _ in range(5):
        x <<= 1
        q <<= 1
        if x >= s:
            x -= s
            q |= 1
    return q + (1 if x else 0)


class Planner:
    """The board's step planner, period by period (the firmware's ``plan_period``).

    Parameters
    ----------
    shaper : StreamShaper
    position : int
        The step count when ``STREAM`` starts (the residual starts at 0).
    travel : int
        The axis's travel: the position is clamped to ``-release..travel`` steps.
    axis : int
        The axis this planner drives (named by its notices).
    release : int
        How far the axis may pay out below zero (``RIG_AXIS_RELEASE_STEPS``; 0: none).
    v_max : int
        The build's set-point limit (:func:`v_max`): the shaped velocity is clamped at ``v_max * 4096``.

    On a build with several axes each axis is planned by its own planner from the one shaper, with its own
    set-points and travel: the firmware's per-axis state is exactly this class's, so one planner per axis is
    the board (:class:`AxesRun`). Only the history differs (64 set-points per axis there, 128 here),
    which no shaper the board accepts reads beyond (its delays are under 63 periods there).
    """

    def __init__(
        self,
        shaper: StreamShaper,
        position: int = 0,
        travel: int = TRAVEL_MAX,
        axis: int = 0,
        release: int = 0,
        v_max: int = V_MAX,
    ) -> None:
        d = shaper.delays_delta
        self.a = shaper.amplitudes
        self.q = tuple(x // PERIOD for x in d)
        self.p = tuple(x % PERIOD for x in d)
        self.q_max = max(self.q)
        self.offsets = sorted(set(self.p) | {0})
        self.c = position
        self.r = 0
        self.hist: dict[int, int] = {}
        self.ticks: list[int] = []
        self.dirs: list[int] = []
        self.notices: list[Notice] = []
        self._speed_this = False  # this period was clamped
        self._speed_clamped = False  # the previous period was clamped (a notice starts an episode)
        self._travel_clamped = False
        self._period = 0
        self.travel = travel
        self.release = release
        self.axis = axis
        self.s_max = v_max * AMP_ONE

    def _v(self, j: int) -> int:
        return self.hist.get(j, 0)

    def checkpoint(self) -> tuple:
        """The planner's state now, for :meth:`rollback` (a host planning ahead of the board; O(history))."""
        flags = (self._speed_this, self._speed_clamped, self._travel_clamped, self._period)
        return self.c, self.r, dict(self.hist), flags, len(self.ticks), len(self.notices)

    def rollback(self, state: tuple) -> None:
        """Return to a :meth:`checkpoint` (the periods planned since are forgotten)."""
        self.c, self.r, hist, flags, n_steps, n_notices = state
        self.hist = dict(hist)
        self._speed_this, self._speed_clamped, self._travel_clamped, self._period = flags
        del self.ticks[n_steps:], self.dirs[n_steps:], self.notices[n_notices:]

    def plan_period(self, k: int, v: int) -> None:
        """Take set-point ``v`` for period ``k`` and plan the period's steps."""
        self.hist[k] = v
        self.hist.pop(k - HISTORY, None)  # the board keeps the last 128 set-points
        self._period = k
        self._speed_this = False
        base = (k + 1) * PERIOD
        impulses = list(zip(self.a, self.q, self.p, strict=True))
        s = sum(a * self._v(k - q - (1 if p > 0 else 0)) for a, q, p in impulses)
        for n, o in enumerate(self.offsets):
            if o > 0:
                for a, q, p in impulses:
                    if p == o:
                        s += a * (self._v(k - q) - self._v(k - q - 1))
            end = self.offsets[n + 1] if n + 1 < len(self.offsets) else PERIOD
            self._piece(base + o, base + end, s)
        if self._speed_this and not self._speed_clamped:
            self.notices.append(Notice("LIMIT,SPEED", k, k, self.axis))
        self._speed_clamped = self._speed_this

    def _emit(self, tick: int, direction: int) -> None:
        self.ticks.append(tick)
        self.dirs.append(direction)
        self.c += direction

    def _clamp_travel(self) -> None:
        self.r = 0
        if not self._travel_clamped:
            self.notices.append(Notice("LIMIT,TRAVEL", self.c, self._period, self.axis))
        self._travel_clamped = True

    def _piece(self, tb: int, te: int, s: int) -> None:
        if s > self.s_max:
            s, self._speed_this = self.s_max, True
        elif s < -self.s_max:
            s, self._speed_this = -self.s_max, True
        # a step due exactly at the boundary (the exact position reached c +- 1 there)
        if self.r >= ONE:
            self._emit(tb * DELTA, 1)
            self.r -= ONE
        elif self.r <= -ONE:
            self._emit(tb * DELTA, -1)
            self.r += ONE
        if s == 0:
            return
        up = s > 0
        speed = s if up else -s
        limit = self.travel if up else -self.release
        rr = self.r if up else -self.r  # the residual in the direction of motion
        if self.c == limit and rr == 0:
            self._clamp_travel()
            return
        self._travel_clamped = False
        theta = 0 if self.c == limit else ONE
        q, rem = divmod(theta - rr, speed)
        q1, r1 = divmod(ONE, speed)
        length = te - tb
        while q < length:
            if self.c == limit:  # the event was reaching the limit itself
                self._clamp_travel()
                return
            self._emit((tb + q) * DELTA + _ceil_ticks(rem, speed), 1 if up else -1)
            if self.c == limit:  # reached the limit while still moving outward
                self._clamp_travel()
                return
            q += q1
            rem += r1
            if rem >= speed:
                rem -= speed
                q += 1
        theta = 0 if self.c == limit else ONE
        rr = theta - (speed * (q - length) + rem)
        self.r = rr if up else -rr


class AxesRun:
    """A stream of a board of one or several axes, planned control tick by control tick, and when it stops.

    The second half of the board's control tick. Every axis is planned by its own :class:`Planner` from the
    one shaper, with its own travel (one axis: the paper's build). :meth:`tick` takes period ``k``'s
    set-points and the stream's state (from :class:`SetpointRules`), records a ``WATCHDOG`` notice when the
    watchdog has just fired, and plans the period, unless the stream has already stopped: ``finish_tick`` is
    ``k + 3`` for the first control tick ``k`` of a winding-down stream (after ``END`` or the watchdog) at
    which the set-points of every axis of periods ``k - q_max - 1 .. k`` are all zero (no step can follow
    period ``k``'s); at that tick the board stops (``DONE``). :attr:`notices` lists every notice in the order
    the board sends them: a ``WATCHDOG`` notice first in its tick, then each axis's limit notices of the
    period, axis by axis (the firmware plans the axes one after another).

    Parameters
    ----------
    shaper : StreamShaper
    positions : sequence of int
        Each axis's step count at ``STREAM``.
    travels : sequence of int or None
        Each axis's travel (default ``TRAVEL_MAX`` each).
    releases : sequence of int or None
        Each axis's paid-out range below zero (default 0 each).
    v_max : int
        The build's set-point limit (:func:`v_max`; default the paper's build's :data:`V_MAX`).
    """

    def __init__(
        self, shaper: StreamShaper, positions: Sequence[int], travels: Sequence[int] | None = None,
        releases: Sequence[int] | None = None, v_max: int = V_MAX,
    ) -> None:  # fmt: skip
        n = len(positions)
        travels = [TRAVEL_MAX] * n if travels is None else list(travels)
        releases = [0] * n if releases is None else list(releases)
        rows = zip(positions, travels, releases, strict=True)
        self.planners = [Planner(shaper, p, t, a, r, v_max) for a, (p, t, r) in enumerate(rows)]
        self.q_max, self.v_max = self.planners[0].q_max, v_max
        self.finish_tick: int | None = None
        self.last_nonzero = 0
        self.watchdog_seen = False
        self.notices: list[Notice] = []
        """Every notice so far, in the board's order."""

    def tick(self, k: int, v: int | tuple[int, ...], state: str) -> bool:
        """Control tick ``k`` with set-points ``v`` (one per axis; an int: axis 0's, the others zero).

        False (nothing planned) once the board has stopped.
        """
        n = len(self.planners)
        vs = tuple(v) if isinstance(v, tuple) else (v,) + (0,) * (n - 1)
        if state == "watchdog" and not self.watchdog_seen:
            self.watchdog_seen = True
            notice = Notice("WATCHDOG", k, k)
            self.planners[0].notices.append(notice)
            self.notices.append(notice)
        if self.finish_tick is not None and k >= self.finish_tick:
            return False
        for planner, va in zip(self.planners, vs, strict=True):
            before = len(planner.notices)
            planner.plan_period(k, va)
            self.notices.extend(planner.notices[before:])
        if any(vs):
            self.last_nonzero = k
        if self.finish_tick is None and state != "active" and k - self.last_nonzero >= self.q_max + 2:
            self.finish_tick = k + 3
        return True

    def checkpoint(self) -> tuple:
        """The run's state now, for :meth:`rollback` (a host planning ahead of the board)."""
        planners = [p.checkpoint() for p in self.planners]
        return planners, len(self.notices), self.finish_tick, self.last_nonzero, self.watchdog_seen

    def rollback(self, state: tuple) -> None:
        """Return to a :meth:`checkpoint` (the periods planned since are forgotten)."""
        planners, n_notices, self.finish_tick, self.last_nonzero, self.watchdog_seen = state
        for p, st in zip(self.planners, planners, strict=True):
            p.rollback(st)
        del self.notices[n_notices:]


class StreamRefused(Exception):
    """The board refuses a streaming command; the message is its reply: ``ERR <STATE|RANGE|FULL> <text>``."""


class StreamSession:
    """The board's streaming mode as it runs, one axis or several: the FIFO, ``V``, ``MV``, ``END``, the tick.

    The firmware's ``V``, ``MV`` and ``END`` handlers and its control tick, composed of :class:`SetpointRules`
    (which set-point each period takes) and :class:`AxesRun` (planning every axis, stopping). ``MV`` queues
    every axis's set-point for a period, ``V`` axis 0's (the others zero). The emulated stepper board
    (``helpers.virtual.emulator``) runs a stream with it; the tests run the same rules and planner from the
    periods the board reported (``tests/stream_run.py``).

    Parameters
    ----------
    run : AxesRun
        The stream's run from ``STREAM`` on: the loaded shaper, every axis's position, travel and release, the
        build's set-point limit.
    """

    def __init__(self, run: AxesRun) -> None:
        self.run, self.axes, self.v_max = run, len(run.planners), run.v_max
        self.rules = SetpointRules()
        self.fifo: deque[tuple[int, ...]] = deque()
        self.next_period = 1
        self.ended = False
        self.stopped = False

    @property
    def accepting(self) -> bool:
        """True while ``V`` and ``END`` are accepted (an active stream: no ``END`` yet, no watchdog)."""
        return not (self.ended or self.stopped) and self.rules.state == "active"

    @property
    def watchdog(self) -> bool:
        """True once the watchdog has fired (the board then disables the driver when it stops)."""
        return self.rules.state == "watchdog"

    def setpoint(self, v: int) -> int:
        """``V <v>``: queue axis 0's set-point (the others zero) and return the period it drives.

        Raises
        ------
        StreamRefused
            ``STATE`` (not streaming, or ending), ``RANGE`` (|v| > ``v_max``), ``FULL`` (8 queued), in the
            board's order.
        """
        if not self.accepting:
            raise StreamRefused("ERR STATE not streaming")
        if not -self.v_max <= v <= self.v_max:
            raise StreamRefused(f"ERR RANGE set-point -{self.v_max}..{self.v_max}")
        return self._queue((v,))

    def setpoints(self, vs: Sequence[int]) -> int:
        """``MV <v_0> ...``: queue one period's set-points (one per axis) and return the period they drive.

        Raises
        ------
        StreamRefused
            ``STATE`` (not streaming, or ending), ``RANGE`` naming the first axis out of range, ``FULL``, in
            the board's order (the caller has checked that there is one set-point per axis).
        """
        if not self.accepting:
            raise StreamRefused("ERR STATE not streaming")
        for a, v in enumerate(vs):
            if not -self.v_max <= v <= self.v_max:
                raise StreamRefused(f"ERR RANGE axis {a} set-point -{self.v_max}..{self.v_max}")
        return self._queue(tuple(vs))

    def _queue(self, vs: tuple[int, ...]) -> int:
        if len(self.fifo) >= FIFO_DEPTH:
            raise StreamRefused(f"ERR FULL {FIFO_DEPTH} set-points queued")
        self.fifo.append(vs + (0,) * (self.axes - len(vs)))
        return self.next_period + len(self.fifo) - 1

    def end(self) -> int:
        """``END``: the stream ends after the queued set-points; returns the first period fed with zero."""
        if not self.accepting:
            raise StreamRefused("ERR STATE not streaming")
        self.ended = True
        self.rules.end_period = self.next_period + len(self.fifo)
        return self.rules.end_period

    def tick(self) -> bool:
        """The next control tick (period ``next_period``); False once the board has stopped (``DONE``)."""
        k = self.next_period
        v = self.rules.take(k, self.fifo.popleft() if self.fifo else None)
        self.next_period = k + 1
        if not self.run.tick(k, v, self.rules.state):
            self.stopped = True
        return not self.stopped


def drive_axes(run: AxesRun, rows: Sequence[Sequence[int]]) -> int:
    """Feed a whole stream's set-points to ``run``, then zeros until the board would stop; the last period.

    ``rows``: one row per period, one value per axis, then ``END``. As the host streams: period k's row goes
    through :class:`SetpointRules` (what the board accepts and when it ends) and the planner takes the rules'
    state, not the set-point alone.
    """
    rules, k = SetpointRules(len(rows) + 1), 0
    while run.finish_tick is None:  # the board stops: after END, once the shaper is through
        k += 1
        run.tick(k, rules.take(k, tuple(rows[k - 1]) if k <= len(rows) else None), rules.state)
    return k
