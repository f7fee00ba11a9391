"""Reference implementation of the stepper board's streaming input shaper (``firmware/PROTOCOL.md``).

The board convolves a stream of velocity set-points with one loaded shaper and turns the shaped velocity into
step times. This module does exactly what the firmware (``firmware/stepper_uno``) does, with the same integer
arithmetic, so that its step times can be compared with the firmware's tick for tick, and it also gives the
exact (floating-point) shaped trajectory that the steps follow. It imports numpy only.

Fixed point (all integers):

- time: the timer tick is 0.5 us; the shaper's delays and the velocity's time base are ``DELTA`` = 32 ticks
  (16 us); a control period is ``PERIOD`` = 625 DELTA = 10 ms;
- velocity set-point ``v``: units of 2^-16 step per DELTA (0.95367431640625 steps/s), ``|v| <= V_MAX`` = 1640
  (1564.0 steps/s = 399.2 mm/s: a step every 639.375 us at most);
- amplitude ``a``: units of 2^-12 (4096 = 1), ``|a| <= 16384``; the amplitudes sum to exactly 4096;
- shaped velocity ``S = sum a_i v(t - d_i)``: units of 2^-28 step per DELTA, clamped to
  ``+-S_MAX`` = 1640 * 4096;
- position: the step count ``c`` and a residual ``r`` (units of 2^-28 step, ``|r| < 2^28``) with the exact
  position ``x = c + r / 2^28``. ``r`` is exact at every DELTA boundary: nothing is rounded, ever.

Step-time rule: within a piece of constant ``S`` (the pieces of a period are cut at the shaper's delays modulo
the period), a step up is due when ``x`` reaches ``c + 1`` and a step down when it reaches ``c - 1`` (a
hysteresis of one step: the count is within one step of ``x`` at every instant and a small oscillation does
not chatter); it is issued at the first timer tick at or after that exact instant (a ceiling). The travel
limits clamp the exact position: at ``c = 156`` with ``r = 0`` an upward ``S`` is held at zero
(``N,LIMIT,TRAVEL``), likewise at 0. Timeline: set-point k (the k-th period's, k >= 1) is taken at control
tick k (``k * 10 ms`` after ``STREAM``) and drives the velocity over ``[(k + 1) * 10 ms, (k + 2) * 10 ms)``.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

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
"""Largest set-point magnitude: 1640 * 2^-16 step per 16 us = 1564.0 steps/s (a step every 639.375 us)."""
S_MAX = V_MAX * AMP_ONE
"""Largest shaped velocity magnitude (the speed limit on the shaped output)."""
TRAVEL_MAX = 156
MAX_IMPULSES = 8
DELAY_UNIT_US = 16
MAX_DELAY_US = 1_000_000
WATCHDOG_PERIODS = 10
"""Control periods without a set-point (100 ms) after which the board feeds zero and then stops."""
FIFO_DEPTH = 8
HISTORY = 128
"""Set-points the board remembers (the longest delay needs 102)."""
STEPS_PER_S_PER_UNIT = (1.0 / (1 << 16)) / (DELTA * TICK_S)
"""Steps per second of one set-point unit (0.95367431640625)."""


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


def shaper_error(amplitudes: Sequence[int], delays_us: Sequence[int], allow_negative: bool) -> str | None:
    """The board's checks of a shaper, in its order; the reason it refuses the shaper, or None."""
    n = len(amplitudes)
    if not 1 <= n <= MAX_IMPULSES or len(delays_us) != n:
        return f"1 to {MAX_IMPULSES} impulses, one delay each"
    previous = -1
    for i, (a, d) in enumerate(zip(amplitudes, delays_us, strict=True)):
        if not -AMP_MAX <= a <= AMP_MAX or (a < 0 and not allow_negative):
            return f"impulse {i}: amplitude {a} outside {'-' if allow_negative else ''}{AMP_MAX}..{AMP_MAX}"
        if d % DELAY_UNIT_US or not 0 <= d <= MAX_DELAY_US or (i == 0 and d != 0) or d <= previous:
            return f"impulse {i}: delay {d} us (0 first, then increasing, multiples of 16, <= 1 s)"
        previous = d
    if sum(amplitudes) != AMP_ONE:
        return f"amplitudes sum to {sum(amplitudes)}, not {AMP_ONE}"
    return None


UNIT_SHAPER = StreamShaper((AMP_ONE,), (0,))
"""The identity: the stream is passed through unshaped (load it when the host shapes the stream itself)."""


def velocity_units(mm_per_s: float, mm_per_step: float) -> int:
    """The set-point (units of 2^-16 step per 16 us) nearest to a cable speed."""
    return int(round(mm_per_s / mm_per_step / STEPS_PER_S_PER_UNIT))


# --- the set-point of every period ------------------------------------------------------------------------
@dataclass
class PeriodCommands:
    """The set-points the board uses, from what it told the host.

    Parameters
    ----------
    assigned : dict
        ``{period: v}`` from the ``OK V <period>`` replies to ``V <v>``.
    end_period : int or None
        From ``OK END <period>``: the first period fed with zero.

    The board's rules: a period without a set-point holds the previous one (an underrun); after
    ``WATCHDOG_PERIODS`` such periods in a row the watchdog fires and that period and every later one is zero;
    from ``end_period`` on every period is zero.
    """

    assigned: dict[int, int]
    end_period: int | None = None

    def __iter__(self) -> Iterator[tuple[int, int, str]]:
        """Yield ``(period, v, state)`` for periods 1, 2, ...; ``state``: active, end or watchdog."""
        previous, underruns, state = 0, 0, "active"
        k = 0
        while True:
            k += 1
            if state == "active" and self.end_period is not None and k >= self.end_period:
                state = "end"
            if k in self.assigned:
                v, underruns = self.assigned[k], 0
            elif state != "active":
                v = 0
            else:
                underruns += 1
                if underruns > WATCHDOG_PERIODS:
                    state, v = "watchdog", 0
                else:
                    v = previous
            previous = v
            yield k, v, state


# --- the planner -----------------------------------------------------------------------------------------
@dataclass
class Notice:
    """An unsolicited ``N,...`` line: ``kind`` is ``LIMIT,SPEED``, ``LIMIT,TRAVEL`` or ``WATCHDOG``."""

    kind: str
    value: int
    period: int


@dataclass
class StreamResult:
    """What the board does for a stream: step ticks (from ``STREAM``), directions, notices, the end."""

    ticks: np.ndarray
    directions: np.ndarray
    notices: list[Notice] = field(default_factory=list)
    finish_tick: int | None = None
    """Control tick at which the board stops (``DONE``)."""
    position: int = 0
    residual: int = 0
    v_by_period: list[int] = field(default_factory=list)
    """The set-point of periods 0, 1, 2, ... as planned (period 0 is always 0)."""


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
    """

    def __init__(self, shaper: StreamShaper, position: int = 0) -> None:
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

    def _v(self, j: int) -> int:
        return self.hist.get(j, 0)

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
            self.notices.append(Notice("LIMIT,SPEED", k, k))
        self._speed_clamped = self._speed_this

    def _emit(self, tick: int, direction: int) -> None:
        self.ticks.append(tick)
        self.dirs.append(direction)
        self.c += direction

    def _clamp_travel(self) -> None:
        self.r = 0
        if not self._travel_clamped:
            self.notices.append(Notice("LIMIT,TRAVEL", self.c, self._period))
        self._travel_clamped = True

    def _piece(self, tb: int, te: int, s: int) -> None:
        if s > S_MAX:
            s, self._speed_this = S_MAX, True
        elif s < -S_MAX:
            s, self._speed_this = -S_MAX, True
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
        limit = TRAVEL_MAX if up else 0
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


def simulate(
    shaper: StreamShaper,
    commands: PeriodCommands,
    position: int = 0,
    max_periods: int = 1_000_000,
) -> StreamResult:
    """Run the board's streaming mode on a stream until it stops (``END`` or the watchdog).

    Returns
    -------
    StreamResult
        Step ticks counted from ``STREAM`` (the instant Timer1 restarts), directions, notices, the
        set-point of every period planned, and the control tick at which the board stops: ``k + 3`` where
        ``k`` is the first control tick of a winding-down stream at which the set-points of periods
        ``k - q_max - 1 .. k`` are all zero (no step can follow period ``k``'s).
    """
    planner = Planner(shaper, position)
    finish, last_nonzero, watchdog_seen = None, 0, False
    v_by_period = [0]
    for k, v, state in commands:
        if state == "watchdog" and not watchdog_seen:
            watchdog_seen = True
            planner.notices.append(Notice("WATCHDOG", k, k))
        planner.plan_period(k, v)
        v_by_period.append(v)
        if v != 0:
            last_nonzero = k
        if state != "active" and k - last_nonzero >= planner.q_max + 2:
            finish = k + 3
            break
        if k >= max_periods:
            break
    return StreamResult(
        np.array(planner.ticks, dtype=np.int64),
        np.array(planner.dirs, dtype=np.int64),
        planner.notices,
        finish,
        planner.c,
        planner.r,
        v_by_period,
    )


# --- the exact trajectory -------------------------------------------------------------------------------
def exact_position(
    shaper: StreamShaper,
    v_by_period: Sequence[int],
    t_ticks: np.ndarray,
    position: int = 0,
    limits: bool = True,
) -> np.ndarray:
    """The exact shaped position (steps, float) at times ``t_ticks`` (ticks from ``STREAM``).

    The velocity is the shaped set-point stream (set-point k on ``[(k + 1) T, (k + 2) T)``), clamped to the
    speed limit, integrated exactly piece by piece in floating point; with ``limits`` the position is
    saturated at 0 and 156 steps (the board's travel clamp). This is independent of :class:`Planner`'s integer
    arithmetic and of its step-time rule.
    """
    d = np.asarray(shaper.delays_us, dtype=float) / (DELAY_UNIT_US) * DELTA  # ticks
    amp = np.asarray(shaper.amplitudes, dtype=float) / AMP_ONE
    v = np.asarray(v_by_period, dtype=float) * (2.0**-16) / DELTA  # steps per tick
    n = len(v)
    # breakpoints of the shaped velocity
    edges = sorted({float((k + 1) * PERIOD_TICKS + di) for k in range(n + 1) for di in d})
    t_query = np.asarray(t_ticks, dtype=float)
    t_end = max(float(t_query.max()) if t_query.size else 0.0, edges[-1])
    edges = [0.0] + [e for e in edges if e < t_end] + [t_end]

    def vcmd(t: float) -> float:
        k = int(np.floor(t / PERIOD_TICKS)) - 1
        return float(v[k]) if 0 <= k < n else 0.0

    s_max = S_MAX / ONE / DELTA  # steps per tick
    x = float(position)
    xs = np.empty(len(edges))
    xs[0] = x
    rates = np.empty(len(edges) - 1)
    for i in range(len(edges) - 1):
        mid = 0.5 * (edges[i] + edges[i + 1])
        s = float(np.sum(amp * np.array([vcmd(mid - di) for di in d])))
        s = min(max(s, -s_max), s_max)
        rates[i] = s
        x = x + s * (edges[i + 1] - edges[i])
        if limits:
            x = min(max(x, 0.0), float(TRAVEL_MAX))
        xs[i + 1] = x
    # positions at the query times: from the piece each falls in
    idx = np.clip(np.searchsorted(edges, t_query, side="right") - 1, 0, len(rates) - 1)
    e0 = np.asarray(edges)[idx]
    out = xs[idx] + rates[idx] * (t_query - e0)
    if limits:
        out = np.clip(out, 0.0, float(TRAVEL_MAX))
    return out
