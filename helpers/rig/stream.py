"""Streaming a trajectory to the stepper board: the set-points, their checks, the pacing and the record.

The stepper board's streaming mode (``firmware/PROTOCOL.md``) takes one velocity set-point per 10 ms control
period from an 8-deep FIFO and shapes it with the loaded shaper.
:meth:`helpers.rig.stream_rig.StreamRig.stream` runs a stream
as an experiment; this module holds its parts, none of which touches a port:

- :class:`SetpointSource`: an array, an iterable or a live source of cable speeds (mm/s), turned into board
  units one at a time and checked (finite, within the speed limit) before anything is sent;
- :class:`ShapedCheck`: the board's own planner (:mod:`helpers.board.stream_reference`) run ahead of the
board on what the
  host is about to send, so that a set-point that would make the board clamp (travel, speed) is refused before
  it is sent: an array as a whole before the run starts, an iterable set-point by set-point;
- :class:`Pacer`: when to send the next set-point, from the device clock, so that the FIFO holds about
  ``lead`` of them: neither ``ERR FULL`` nor an underrun;
- :class:`StreamRecord`: what the recording's ``scenario.stream`` says about the stream (the shaper as loaded,
  the rate, every set-point and the period the board assigned it, a digest, the notices and counts).
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from helpers.board import stream_reference as hs
from helpers.paper.hardware import MAX_PROGRAMME_S, MM_PER_STEP
from helpers.rig.boards import BoardError
from helpers.rig.safety import SafetyError

STREAM_RATE_HZ = round(1.0 / (hs.PERIOD_TICKS * hs.TICK_S))
"""The board's control rate: one set-point per 10 ms period (100 Hz)."""

PERIOD_US = round(hs.PERIOD_TICKS * hs.TICK_S * 1e6)
"""The control period (us)."""

UNIT_MM_S = hs.STEPS_PER_S_PER_UNIT * MM_PER_STEP
"""Cable speed of one set-point unit (mm/s): 0.2434 mm/s."""

V_MAX_MM_S = hs.V_MAX * UNIT_MM_S
"""The stream's speed limit (mm/s): 1640 units = 399.2 mm/s (just under the 400 mm/s of programmes)."""

MAX_SETPOINTS = int(MAX_PROGRAMME_S * STREAM_RATE_HZ)
"""Most set-points in one stream (the host's 600 s limit on a run)."""


class StreamLimit(SafetyError):
    """The board clamped the shaped motion at a limit during a stream (``N,LIMIT,...``): the run stopped."""


class StreamStarved(BoardError):
    """The stream's watchdog fired (``N,WATCHDOG``): the board went 100 ms without a set-point."""


def refuse_notice(line: str, allow_clamps: bool) -> None:
    """Stop a stream on the board's notice ``line``: always on the watchdog, on a clamp unless allowed.

    Raises
    ------
    StreamStarved
        ``N,WATCHDOG``: the host fell behind.
    StreamLimit
        Any other notice (a speed or travel clamp) unless ``allow_clamps``.
    """
    if line.startswith("N,WATCHDOG"):
        raise StreamStarved(
            f"the stepper board's stream watchdog fired ({line}): it went 100 ms without a "
            "set-point (the host fell behind)"
        )
    if not allow_clamps:
        raise StreamLimit(f"the stepper board clamped the shaped motion ({line}): stream stopped")


def units(mm_s: float) -> int:
    """The board's set-point (units of 2^-16 step per 16 us) nearest to a cable speed in mm/s."""
    return hs.velocity_units(mm_s, MM_PER_STEP)


class SetpointSource:
    """Cable speeds (mm/s, + = pull) from an array, an iterable or a live source, as checked board units.

    Parameters
    ----------
    setpoints : array_like or iterable of float
        One speed per 10 ms control period. A sequence or array is checked whole before the run starts; any
        other iterable (a generator, a live source such as a gamepad) one value at a time, as it is taken
        (a live source must return its present value at once: the host paces the stream).
    name : str, optional
        Where the set-points come from, for the recording (default ``"array"`` for sequences, else the
        iterable's type name).

    Raises
    ------
    SafetyError
        (from :meth:`check_all` or :meth:`__next__`) a value that is not a finite number, a speed beyond
        :data:`V_MAX_MM_S`, or more than :data:`MAX_SETPOINTS` values; the message names the set-point.
    """

    def __init__(self, setpoints: Any, name: str | None = None) -> None:
        sequence = hasattr(setpoints, "__len__") and hasattr(setpoints, "__getitem__")
        self.sized = isinstance(setpoints, np.ndarray) or (sequence and not isinstance(setpoints, str))
        if isinstance(setpoints, str | bytes) or not isinstance(setpoints, Iterable):
            raise SafetyError(
                f"set-points must be an array or an iterable of speeds in mm/s, got {setpoints!r}"
            )
        self.name = name or ("array" if self.sized else type(setpoints).__name__)
        self.values: list[Any] | None = None
        if self.sized:
            try:
                shape = np.shape(setpoints)
            except ValueError:  # ragged nesting
                shape = (len(setpoints), -1)
            if len(shape) != 1:
                raise SafetyError(f"set-points must be one-dimensional, got shape {shape}")
            self.values = list(setpoints)
            if not self.values:
                raise SafetyError("no set-points: the stream is empty")
        self._iter: Iterator[Any] = iter(setpoints)
        self.taken = 0

    def check_all(self) -> np.ndarray:
        """Every set-point of a sized source, in board units (refused as a whole, before anything is sent)."""
        assert self.values is not None
        n = len(self.values)
        if n > MAX_SETPOINTS:
            raise SafetyError(
                f"{n} set-points last {n / STREAM_RATE_HZ:.0f} s, over the host's limit of "
                f"{MAX_PROGRAMME_S:.0f} s"
            )
        return np.array([self._check(i, v) for i, v in enumerate(self.values)], dtype=np.int64)

    @staticmethod
    def _check(i: int, value: Any) -> int:
        try:
            x = float(value)
        except (TypeError, ValueError, OverflowError):
            raise SafetyError(f"set-point {i}: {value!r} is not a number (a cable speed in mm/s)") from None
        if not math.isfinite(x):
            raise SafetyError(f"set-point {i}: {x} mm/s is not finite")
        u = units(x)
        if abs(u) > hs.V_MAX:
            raise SafetyError(
                f"set-point {i}: {x:g} mm/s exceeds the stream's speed limit of {V_MAX_MM_S:.1f} mm/s "
                f"({hs.V_MAX} board units)"
            )
        return u

    def __iter__(self) -> SetpointSource:
        return self

    def __next__(self) -> int:
        """The next set-point in board units (checked); ``StopIteration`` when the source is exhausted."""
        value = next(self._iter)
        if self.taken >= MAX_SETPOINTS:
            raise SafetyError(
                f"the stream goes on for over {MAX_PROGRAMME_S:.0f} s, the host's limit on a run"
            )
        u = self._check(self.taken, value)
        self.taken += 1
        return u


class ShapedCheck:
    """The board's planner run ahead of the board, to refuse a set-point that would make the board clamp.

    Planning period k needs only the set-points of periods up to k (the shaper delays, it never
    anticipates), so the clamp a set-point would cause is known before it is sent. :meth:`setpoint` plans
    the next period on the assumption that the board takes it there (no underrun: what the :class:`Pacer`
    is for); once the board's ``OK V <k>`` says where it went, :meth:`confirm` keeps the plan or, when the
    board ran short (periods without a set-point, which move nothing), plans those periods as the board did,
    so the prediction follows the board whatever the host's timing. The board clamps whatever happens, and
    the host stops the run on its notice.

    Parameters
    ----------
    shaper : helpers.board.stream_reference.StreamShaper
    position : int
        The step count at ``STREAM``.
    refuse : bool
        Raise on a predicted clamp (False: only predict, e.g. the reach of a stream whose clamps are allowed).
    """

    def __init__(self, shaper: hs.StreamShaper, position: int, refuse: bool = True) -> None:
        self.refuse = refuse
        self.run = hs.StreamRun(shaper, position)
        self.rules = hs.SetpointRules()
        self.period = 0
        self.start = position
        self.gaps = 0
        """Periods the board got no set-point for, so far."""

    def _plan(self, v: int | None, late: str = "") -> None:
        self.period += 1
        k = self.period
        v_k = self.rules.take(k, v)
        self.run.tick(k, v_k, self.rules.state)
        notices = [n for n in self.run.notices if n.kind.startswith("LIMIT")]
        if notices and self.refuse:
            n = notices[0]
            what = (
                f"reach the travel limit ({n.value} steps)"
                if n.kind == "LIMIT,TRAVEL"
                else f"exceed the speed limit of {V_MAX_MM_S:.1f} mm/s (the shaper overshoots)"
            )
            if self.gaps and not late:
                late = f"the host fell behind earlier ({self.gaps} period(s) without a set-point), so "
            raise StreamLimit(f"set-point {k - 1}: {late}the shaped stream would {what} in period {n.period}")

    def checkpoint(self) -> tuple:
        """The prediction's state, to go back to when the board assigns the set-point another period."""
        r = self.rules
        return self.run.checkpoint(), self.period, (r.state, r.underruns, r.watchdog_period, r.end_period)

    def rollback(self, state: tuple) -> None:
        """Forget what was planned since :meth:`checkpoint` (e.g. a set-point the board refused as FULL)."""
        run, self.period, rules = state
        self.run.rollback(run)
        self.rules.state, self.rules.underruns, self.rules.watchdog_period, self.rules.end_period = rules

    def setpoint(self, u: int) -> None:
        """Plan the next period with set-point ``u``; :class:`StreamLimit` if the board would clamp."""
        self._plan(u)

    def confirm(self, state: tuple, u: int, period: int) -> bool:
        """The board took ``u`` (planned since ``state``) for ``period``; True if it is not the one planned.

        Then the periods before it had no set-point: they are planned as the board planned them (zero), and
        :class:`StreamLimit` is raised if the shaped motion would now clamp.
        """
        if period == self.period:
            return False
        self.rollback(state)
        first = self.period + 1
        self.gaps += period - first
        for _ in range(first, period):
            self._plan(None)
        late = f"the host fell behind (periods {first}-{period - 1} had no set-point and moved nothing), so "
        self._plan(u, late)
        return True

    def end(self) -> None:
        """Plan the stream's end (``END``: zeros until the shaped motion is over)."""
        self.rules.end_period = self.period + 1
        while self.run.finish_tick is None:
            self._plan(None)

    def reach(self) -> tuple[int, int]:
        """The lowest and highest step counts the planned steps reach (from the start position)."""
        path = self.start + np.cumsum(np.asarray(self.run.planner.dirs, dtype=np.int64))
        return int(path.min(initial=self.start)), int(path.max(initial=self.start))


class Pacer:
    """When to send the next set-point, so that the board's FIFO holds about ``lead`` of them.

    The board takes set-point k at its control tick k (k x 10 ms after ``STREAM``, on its own clock). The
    host, reading the device time from the DAQ's samples, sends the set-point of period ``p`` once the device
    time reaches ``t_anchor + (p - p_anchor - lead) * 10 ms``: it then waits ``lead`` periods in the FIFO,
    which absorbs the host's jitter. The anchor starts at ``STREAM`` (period 0); two replies move it, if the
    two boards' clocks drift apart (on the virtual rigs they are one clock, and neither happens):

    - ``ERR FULL``: the FIFO holds 8, so the board plans the 8th-last set-point at its next tick: the anchor
      moves there and the refused set-point is sent again when due;
    - ``OK V <k>`` with ``k`` later than expected: the missing periods had no set-point and moved nothing
      (an underrun, counted: the motion is the command's, later); the board is planning ``k`` at its next
      tick: the anchor moves there.

    Parameters
    ----------
    t_stream_us : int
        Device time of ``STREAM`` (the newest DAQ sample when its reply arrived), us.
    lead : int
        Periods a set-point waits in the FIFO (1-7).
    """

    def __init__(self, t_stream_us: int, lead: int = 4) -> None:
        if isinstance(lead, bool) or not isinstance(lead, int) or not 1 <= lead < hs.FIFO_DEPTH:
            raise ValueError(
                f"lead must be an integer number of periods in 1-{hs.FIFO_DEPTH - 1}, got {lead!r}"
            )
        self.lead = lead
        self.t_anchor = float(t_stream_us)
        self.p_anchor = 0.0
        self.next_period = 1
        """The period the next set-point is expected to drive."""
        self.full = 0
        self.underruns = 0
        """Periods without a set-point between the first set-point and the last (the board fed zero there)."""
        self.late_start = 0
        """Periods without a set-point before the first (the stream started that much later: at rest)."""
        self.accepted_count = 0

    def due_us(self) -> float:
        """Device time (us) at which the next set-point is due."""
        return self.t_anchor + (self.next_period - self.p_anchor - self.lead) * PERIOD_US

    def due(self, now_us: float) -> bool:
        """True when the next set-point should be sent."""
        return now_us >= self.due_us()

    def accepted(self, period: int, now_us: float) -> None:
        """``OK V <period>``: the set-point drives ``period``."""
        if period > self.next_period:
            if self.accepted_count:
                self.underruns += period - self.next_period
            else:
                self.late_start += period - self.next_period
            self.t_anchor, self.p_anchor = now_us, period - 0.5  # tick period - 1 fell within the last period
        self.next_period = period + 1
        self.accepted_count += 1

    def refused_full(self, now_us: float) -> None:
        """``ERR FULL``: the FIFO holds the 8 set-points before ``next_period``."""
        self.full += 1
        self.t_anchor, self.p_anchor = now_us, self.next_period - hs.FIFO_DEPTH - 0.5

    def finish_due_us(self, end_period: int, q_max: int, grace_us: float) -> float:
        """Device time (us) by which ``DONE`` must have come after ``OK END <end_period>``."""
        finish_tick = end_period + q_max + 4  # StreamRun's rule at its latest
        return self.t_anchor + (finish_tick - self.p_anchor) * PERIOD_US + grace_us


@dataclass
class StreamRecord:
    """What a stream did, kept as it goes: the recording's ``scenario.stream`` (``docs/recording_format.md``).

    The lists grow in place, so an aborted run's recording says what was sent before it stopped.
    """

    shaper: hs.StreamShaper
    source: str
    lead_periods: int
    data: dict[str, Any] = field(default_factory=dict)

    @property
    def shaper_q_max(self) -> int:
        """Whole control periods in the shaper's longest delay."""
        return max(self.shaper.delays_delta) // hs.PERIOD

    def __post_init__(self) -> None:
        self._digest = hashlib.sha256()
        self.data.update(
            {
                "rate_hz": STREAM_RATE_HZ,
                "impulses": {
                    "amplitudes": list(self.shaper.amplitudes),
                    "delays_us": list(self.shaper.delays_us),
                    "allow_negative": self.shaper.allow_negative,
                    "amplitude_unit": 1 / hs.AMP_ONE,
                },
                "source": self.source,
                "setpoint_unit_mm_s": UNIT_MM_S,
                "setpoints": [],
                "periods": [],
                "n_setpoints": 0,
                "setpoints_sha256": self._digest.hexdigest(),
                "end_period": None,
                "lead_periods": self.lead_periods,
                "fifo_full": 0,
                "underruns": 0,
                "late_start_periods": 0,
                "notices": [],
                "clamps": {"speed": 0, "travel": 0},
                "watchdog": False,
            }
        )

    def sent(self, u: int, period: int) -> None:
        """A set-point the board accepted for ``period``."""
        self.data["setpoints"].append(int(u))
        self.data["periods"].append(int(period))
        self.data["n_setpoints"] += 1
        self._digest.update(int(u).to_bytes(2, "little", signed=True))
        self.data["setpoints_sha256"] = self._digest.hexdigest()

    def notice(self, line: str) -> None:
        """An ``N,...`` line from the board."""
        self.data["notices"].append(line)
        if line.startswith("N,LIMIT,SPEED"):
            self.data["clamps"]["speed"] += 1
        elif line.startswith("N,LIMIT,TRAVEL"):
            self.data["clamps"]["travel"] += 1
        elif line.startswith("N,WATCHDOG"):
            self.data["watchdog"] = True

    def counts(self, pacer: Pacer) -> None:
        """Copy the pacer's counts."""
        self.data["fifo_full"] = pacer.full
        self.data["underruns"] = pacer.underruns
        self.data["late_start_periods"] = pacer.late_start

    def deviation(self) -> str | None:
        """Why the motion differed from the command (underruns, clamps), or None: it was the command's."""
        why = []
        if self.data["underruns"]:
            why.append(
                f"the host fell behind: {self.data['underruns']} period(s) between set-points had none and "
                "moved nothing (the board's rule), so the motion is the command's stretched in time"
            )
        clamps = self.data["clamps"]
        if clamps["speed"] or clamps["travel"]:
            why.append(
                f"the board clamped the shaped motion ({clamps['travel']} travel and {clamps['speed']} speed "
                "episode(s))"
            )
        return "; ".join(why) or None


def setpoints_digest(setpoints: Iterable[int]) -> str:
    """The sha256 of set-points in board units as the recording states it (int16, little-endian, in order)."""
    h = hashlib.sha256()
    for u in setpoints:
        h.update(int(u).to_bytes(2, "little", signed=True))
    return h.hexdigest()
