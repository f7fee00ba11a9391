"""Streams: every tendon's velocity set-points through the stepper board's shaper (``docs/streaming.md``).

The stepper board's streaming mode (``firmware/PROTOCOL.md``) takes one set-point per tendon and 10 ms control
period from an 8-deep FIFO (``V <v>`` on a one-axis board, ``MV <v_0> ... <v_{A-1}>`` on one of several
axes) and shapes every tendon with the one loaded shaper. :func:`stream` runs a stream on a
:class:`~helpers.rig.driver.Rig` as one experiment, in the rig's guard, for 1 to 4 tendons. Its parts:

- :class:`SetpointSource`: cable speeds (mm/s) from an array (checked whole before the run), an iterable or
  a live source (checked one period at a time as it is taken), in board units: finite, within the stream's
  speed limit, at most ``max_programme_s`` long;
- :class:`ShapedCheck`: the board's own planner (:class:`~helpers.board.stream_reference.AxesRun`) run ahead
  of the board on what the host is about to send, with the commanded cable of every tendon: a set-point is
  refused before it is sent when it would leave every tendon slack (the rig file's statics,
  :func:`~helpers.rig.safety.check_slack`) or make the board clamp the shaped motion (travel
  ``-release..travel``, speed); with ``allow_clamps``, when its integral takes a tendon past its travel; an
  array as a whole before the run;
- :class:`Pacer`: when to send the next set-point, from the DAQ's clock, so that the FIFO holds about
  ``lead`` of them: neither ``ERR FULL`` nor an underrun;
- :class:`StreamRecord`: what the recording's ``scenario.stream`` says (the shaper as loaded, every set-point
  and the period the board gave it, a digest, the notices and counts).

During the stream a board reset or silence, the watchdog (:class:`StreamStarved`), a clamp the board reports
unless ``allow_clamps`` (:class:`StreamLimit`), any exception or signal stop it as every run is stopped:
``ABORT``, ``EN 0``, the DAQ's ``STOP``, and what was recorded is saved under an aborted name.
"""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from helpers.board import stream_reference as hs
from helpers.recordings import Recording, reserve
from helpers.rig.driver import Rig, RunState
from helpers.rig.link import BoardError, CommandRefused, ints
from helpers.rig.safety import SafetyError, check_slack
from helpers.rig.trim import TensionGuard
from helpers.rigfile import RigFile, derived

STREAM_RATE_HZ = round(1.0 / (hs.PERIOD_TICKS * hs.TICK_S))
"""The board's control rate: one set-point per 10 ms period (100 Hz)."""

PERIOD_US = round(hs.PERIOD_TICKS * hs.TICK_S * 1e6)
"""The control period (us)."""

STEPS_PER_UNIT_PERIOD = hs.PERIOD / (1 << 16)
"""Steps one set-point unit moves in one control period (625 DELTA x 2^-16 step per DELTA)."""

STREAM_FIRMWARE = (2, 1)
"""The oldest stepper firmware that streams: 2.0.x held the last set-point through a period without one."""

FEED_READ_S = 0.005
"""The DAQ's read timeout during a stream (s): device time advances in steps under a control period."""


class StreamLimit(SafetyError):
    """The board would clamp (or clamped) the shaped motion at a limit during a stream (``N,LIMIT,...``)."""


class StreamStarved(BoardError):
    """The stream's watchdog fired (``N,WATCHDOG``): the board went 100 ms without a set-point."""


def v_max(rig: RigFile) -> int:
    """The build's set-point limit: ``floor(2^20 / min_interval_us)`` (1640 for 639 us, 2001 for 524 us)."""
    return hs.v_max(derived(rig).min_interval_us)


def unit_mm_s(rig: RigFile) -> list[float]:
    """Every tendon's cable speed of one set-point unit (mm/s): 0.2434 mm/s on the paper's rig."""
    return [hs.STEPS_PER_S_PER_UNIT * mm for mm in derived(rig).mm_per_step]


class SetpointSource:
    """Every tendon's cable speeds (mm/s, + = pull) as checked board units, one row per control period.

    Parameters
    ----------
    setpoints : array_like or iterable
        One speed per period (one tendon) or one row of every tendon's per period. A sequence or array is
        checked whole before the run starts; any other iterable (a generator, a live source such as a
        gamepad, which must return its present value at once) one period at a time, as it is taken.
    rig : RigFile
        The rig: its tendons, speed limit and ``max_programme_s``.

    Raises
    ------
    SafetyError
        (here, from :meth:`check_all` or :meth:`__next__`) a value that is not a finite number, a speed beyond
        the limit, the wrong number of tendons, or too many periods; one line naming the tendon and period.
    """

    def __init__(self, setpoints: Any, rig: RigFile) -> None:
        if isinstance(setpoints, str | bytes) or not isinstance(setpoints, Iterable):
            got = repr(setpoints)
            raise SafetyError(f"set-points must be an array or an iterable of speeds in mm/s, got {got}")
        self.rig, self.n = rig, rig.n_tendons
        self.sized = isinstance(setpoints, np.ndarray) or hasattr(setpoints, "__len__")
        self.name = "array" if self.sized else type(setpoints).__name__  # where they come from, recorded
        self.values = list(setpoints) if self.sized else None
        if self.values is not None and not self.values:
            raise SafetyError("no set-points: the stream is empty")
        self._iter: Iterator[Any] = iter(setpoints)
        self.taken = 0
        self.limit = int(rig.hardware.max_programme_s * STREAM_RATE_HZ)

    def check_all(self) -> np.ndarray:
        """Every set-point of a sized source in board units, shape (periods, tendons), refused as a whole."""
        assert self.values is not None
        if len(self.values) > self.limit:
            raise SafetyError(
                f"{len(self.values)} set-points last {len(self.values) / STREAM_RATE_HZ:.0f} s, over the "
                f"host's limit of {self.rig.hardware.max_programme_s:.0f} s"
            )
        return np.array([self._check(k, v) for k, v in enumerate(self.values)], dtype=np.int64)

    def _check(self, k: int, value: Any) -> tuple[int, ...]:
        row = value if self.n > 1 or np.ndim(value) == 1 else [value]
        try:
            speeds = [float(x) for x in row]
        except (TypeError, ValueError, OverflowError):
            raise SafetyError(f"set-point {k}: {value!r} is not a number (a cable speed in mm/s)") from None
        if len(speeds) != self.n:
            raise SafetyError(f"set-point {k}: {len(speeds)} speeds for the rig's {self.n} tendon(s)")
        out = []
        for i, (x, unit) in enumerate(zip(speeds, unit_mm_s(self.rig), strict=True)):
            who = f"tendon {i + 1}, " if self.n > 1 else ""
            if not math.isfinite(x):
                raise SafetyError(f"{who}set-point {k}: {x} mm/s is not finite")
            u = int(round(x / unit))
            if abs(u) > v_max(self.rig):
                raise SafetyError(
                    f"{who}set-point {k}: {x:g} mm/s exceeds the stream's speed limit of "
                    f"{v_max(self.rig) * unit:.1f} mm/s ({v_max(self.rig)} board units)"
                )
            out.append(u)
        return tuple(out)

    def __iter__(self) -> SetpointSource:
        return self

    def __next__(self) -> tuple[int, ...]:
        """The next period's set-points in board units (checked); ``StopIteration`` when exhausted."""
        value = next(self._iter)
        if self.taken >= self.limit:
            raise SafetyError(
                f"the stream goes on for over {self.rig.hardware.max_programme_s:.0f} s, the host's limit"
            )
        self.taken += 1
        return self._check(self.taken - 1, value)


class ShapedCheck:
    """The board's planner and every tendon's commanded cable, run ahead of the board (module docstring).

    Planning period k needs only the set-points of periods up to k (the shaper delays, it never anticipates),
    so what a set-point would do is known before it is sent. :meth:`setpoint` plans the next period on the
    assumption that the board takes it there (what the :class:`Pacer` is for); once the board's reply says
    where it went, :meth:`confirm` keeps the plan or, when the board ran short (periods without a set-point,
    which move nothing), plans those periods as the board did, so the prediction follows the board whatever
    the host's timing. The board clamps whatever happens, and the host stops the run on its notice.

    Parameters
    ----------
    shaper : helpers.board.stream_reference.StreamShaper
    start : tuple of int
        Every tendon's step count at ``STREAM``.
    rig : RigFile
    refuse : bool
        Raise on a predicted clamp (False: ``allow_clamps``: then a command past the travel is refused).
    """

    def __init__(self, shaper: hs.StreamShaper, start: tuple[int, ...], rig: RigFile, refuse: bool = True
                 ) -> None:  # fmt: skip
        d = derived(rig)
        self.rig, self.refuse = rig, refuse
        self.travel, self.release = d.travel_steps, d.release_steps
        self.run = hs.AxesRun(shaper, start, d.travel_steps, d.release_steps, v_max(rig))
        self.rules = hs.SetpointRules()
        self.period = 0
        self.commanded = np.array(start, dtype=float)
        self.gaps = 0
        """Periods the board got no set-point for, so far."""

    def _plan(self, row: tuple[int, ...] | None, late: str = "", where: str = "") -> None:
        self.period += 1
        k = self.period
        before = len(self.run.notices)
        self.run.tick(k, self.rules.take(k, row), self.rules.state)
        limits = [x for x in self.run.notices[before:] if x.kind.startswith("LIMIT")]
        if limits and self.refuse:
            x = limits[0]
            who = f"tendon {x.axis + 1}, " if self.rig.n_tendons > 1 else ""
            what = (f"reach the travel limit ({x.value} steps)" if x.kind == "LIMIT,TRAVEL"
                    else "exceed the speed limit (the shaper overshoots)")  # fmt: skip
            if self.gaps and not late:
                late = f"the host fell behind earlier ({self.gaps} period(s) without a set-point), so "
            where = where or f"set-point {k - 1}: "
            raise StreamLimit(f"{who}{where}{late}the shaped stream would {what} in period {x.period}")

    def checkpoint(self) -> tuple:
        """The prediction's state, to go back to when the board assigns the set-point another period."""
        r = self.rules
        return (self.run.checkpoint(), self.period, self.commanded.copy(),
                (r.state, r.underruns, r.end_period))  # fmt: skip

    def rollback(self, state: tuple) -> None:
        """Forget what was planned since :meth:`checkpoint` (e.g. a set-point the board refused as FULL)."""
        run, self.period, self.commanded, rules = state
        self.run.rollback(run)
        self.rules.state, self.rules.underruns, self.rules.end_period = rules

    def setpoint(self, row: tuple[int, ...]) -> None:
        """Plan the next period with ``row``; ``SafetyError`` if the command or the board's motion fails.

        The board's planner refuses any clamp of the shaped motion; where clamps are allowed, a command whose
        integral leaves a tendon's travel is refused still (a clamp would be certain, not an overshoot).
        """
        self.commanded = self.commanded + np.asarray(row) * STEPS_PER_UNIT_PERIOD
        for i, x in enumerate(self.commanded):
            if not self.refuse and not -self.release[i] - 1e-9 <= x <= self.travel[i] + 1e-9:
                who = f"tendon {i + 1}, " if self.rig.n_tendons > 1 else ""
                lim = -self.release[i], self.travel[i]
                raise SafetyError(
                    f"{who}set-point {self.period}: the set-points integrate to {x:.2f} steps, past its "
                    f"travel of {lim[0]}-{lim[1]} steps"
                )
        check_slack(self.rig, self.commanded[None, :], [f"set-point {self.period}"])
        self._plan(row)

    def confirm(self, state: tuple, row: tuple[int, ...], period: int) -> bool:
        """The board took ``row`` (planned since ``state``) for ``period``; True if it is not the one planned.

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
        self.commanded = self.commanded + np.asarray(row) * STEPS_PER_UNIT_PERIOD
        gap = f"periods {first}-{period - 1} had no set-point and moved nothing"
        self._plan(row, f"the host fell behind ({gap}), so ")
        return True

    def end(self) -> tuple[int, ...]:
        """Plan the stream's end (``END``: zeros until the shaped motion is over); the tendons' positions."""
        self.rules.end_period = self.period + 1
        while self.run.finish_tick is None:
            self._plan(None, where="after the last set-point, ")
        return tuple(p.c for p in self.run.planners)

    def where(self) -> tuple[list[int], np.ndarray]:
        """Every tendon's step count and exact commanded position after the set-points planned so far."""
        return [p.c for p in self.run.planners], self.commanded.copy()

    def reach(self) -> list[tuple[int, int]]:
        """Every tendon's lowest and highest step count the planned steps reach, from its start (``ZERO``)."""
        out = []
        for p in self.run.planners:
            path = np.cumsum(np.asarray(p.dirs, dtype=np.int64))
            out.append((int(path.min(initial=0)), int(path.max(initial=0))))
        return out


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
            most = hs.FIFO_DEPTH - 1
            raise ValueError(f"lead must be an integer number of periods in 1-{most}, got {lead!r}")
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

    def finish_us(self, end_period: int, q_max: int) -> float:
        """Device time (us) at which the board ends the stream (``DONE``) after ``OK END <end_period>``."""
        return self.t_anchor + (end_period + q_max + 4 - self.p_anchor) * PERIOD_US  # AxesRun's, at latest


@dataclass
class StreamRecord:
    """What a stream did, kept as it goes: the recording's ``scenario.stream`` (``docs/recording_format.md``).

    ``setpoints`` lists tendon 1's set-points (axis 0), ``tendon_setpoints`` every tendon's; the digest covers
    every tendon's, period by period (int16, little-endian). The lists grow in place, so an aborted run's
    recording says what was sent before it stopped.
    """

    shaper: hs.StreamShaper
    source: str
    lead_periods: int
    tendons: int
    data: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._digest = hashlib.sha256()
        sh = self.shaper
        impulses = {"amplitudes": list(sh.amplitudes), "delays_us": list(sh.delays_us),
                    "allow_negative": sh.allow_negative, "amplitude_unit": 1 / hs.AMP_ONE}  # fmt: skip
        self.data.update(
            rate_hz=STREAM_RATE_HZ, impulses=impulses, source=self.source, setpoints=[], periods=[],
            n_setpoints=0, setpoints_sha256=self._digest.hexdigest(), end_period=None,
            lead_periods=self.lead_periods, fifo_full=0, underruns=0, late_start_periods=0, notices=[],
            clamps={"speed": 0, "travel": 0}, watchdog=False,
        )  # fmt: skip
        self.data["tendon_setpoints"] = [[] for _ in range(self.tendons)]

    @property
    def q_max(self) -> int:
        """Whole control periods in the shaper's longest delay."""
        return max(self.shaper.delays_delta) // hs.PERIOD

    def sent(self, row: tuple[int, ...], period: int) -> None:
        """A period's set-points the board accepted for ``period``."""
        self.data["setpoints"].append(int(row[0]))
        for i, u in enumerate(row):
            self._digest.update(int(u).to_bytes(2, "little", signed=True))
            self.data["tendon_setpoints"][i].append(int(u))
        self.data["setpoints_sha256"] = self._digest.hexdigest()
        self.data["periods"].append(int(period))
        self.data["n_setpoints"] += 1

    def notice(self, line: str, allow_clamps: bool) -> None:
        """An ``N,...`` line, noted; it stops the stream (the watchdog always, a clamp unless allowed)."""
        self.data["notices"].append(line)
        kind = {"N,LIMIT,SPEED": "speed", "N,LIMIT,TRAVEL": "travel"}.get(",".join(line.split(",")[:3]))
        if kind:
            self.data["clamps"][kind] += 1
        if line.startswith("N,WATCHDOG"):
            self.data["watchdog"] = True
            raise StreamStarved(
                f"the stepper board's stream watchdog fired ({line}): it went 100 ms without a set-point "
                "(the host fell behind)"
            )
        if not allow_clamps:
            raise StreamLimit(f"the stepper board clamped the shaped motion ({line}): stream stopped")

    def counts(self, pacer: Pacer) -> None:
        """Copy the pacer's counts."""
        self.data.update(fifo_full=pacer.full, underruns=pacer.underruns, late_start_periods=pacer.late_start)

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


def shaper_meta(shaper: Any) -> dict[str, Any] | None:
    """A shaper as the recording's ``scenario.shaper`` states it: ``name``, ``amplitudes``, ``times`` (s)."""
    if shaper is None:
        return None
    if isinstance(shaper, hs.StreamShaper):  # a board shaper given as it is
        return {"name": "board", "amplitudes": [a / hs.AMP_ONE for a in shaper.amplitudes],
                "times": [d * 1e-6 for d in shaper.delays_us]}  # fmt: skip
    return {"name": getattr(shaper, "name", None), "amplitudes": [float(a) for a in shaper.amplitudes],
            "times": [float(t) for t in shaper.times]}  # fmt: skip


@dataclass(frozen=True)
class CheckedStream:
    """A whole stream checked before any byte is sent (:func:`check_stream`)."""

    units: np.ndarray
    """Set-points in board units, shape (periods, tendons)."""
    start: tuple[int, ...]
    end: tuple[int, ...]
    """Every tendon's position when the board's shaped motion is over (the board's planner)."""
    reach: list[tuple[int, int]]
    """Every tendon's lowest and highest step count on the way, from its start."""


def board_shaper(shaper: Any, tendons: int) -> hs.StreamShaper:
    """``shaper`` as the board loads it (:func:`~helpers.board.stream_reference.board_shaper`), checked."""
    board = hs.board_shaper(shaper)
    if tendons > 1 and max(board.delays_us) > hs.MAX_DELAY_US_AXES:
        raise SafetyError(
            f"the shaper's last impulse at {max(board.delays_us) / 1e6:.3f} s is beyond the "
            f"{hs.MAX_DELAY_US_AXES / 1e6:.2f} s a stepper board with several axes holds"
        )
    return board


def check_stream(
    setpoints: Any, rig: RigFile, start: tuple[int, ...], shaper: Any, allow_clamps: bool = False
) -> CheckedStream:
    """Check a whole stream of ``rig``'s tendons from ``start`` as :func:`stream` does before any byte.

    Raises
    ------
    SafetyError
        One line naming the tendon, the set-point and the figure (module docstring).
    """
    units = SetpointSource(setpoints, rig).check_all()
    whole = ShapedCheck(board_shaper(shaper, rig.n_tendons), tuple(start), rig, refuse=not allow_clamps)
    for row in units:
        whole.setpoint(tuple(row))
    return CheckedStream(units, tuple(start), whole.end(), whole.reach())


def stream(
    rig: Rig, setpoints: Any, shaper: Any = None, *, path: str | os.PathLike,
    scenario: dict[str, Any] | None = None, lead_periods: int = 4,
    lead_in_s: float = 1.0, tail_s: float = 1.0, allow_clamps: bool = False, rate_hz: int = 1000,
    progress: bool = True, replace: bool = False, noise_seed: int | None = None,
    guard: TensionGuard | None = None,
) -> Recording:  # fmt: skip
    """Stream every tendon's cable speeds through the board's shaper; return (and save) the recording.

    The run: check everything that can be checked before a byte is sent (the set-points, the shaper; for an
    array, the whole shaped motion from where the tendons are, with the board's own planner), wait until the
    tension is at rest, load the shaper, start the DAQ, record ``lead_in_s``, enable the driver, ``STREAM``,
    feed the set-points at 100 Hz of device time (:class:`Pacer`), ``END``, await ``DONE`` (as a run awaits
    it: in device time, ``POS`` when it is late), record ``tail_s`` more, stop the DAQ and disable the driver.

    Parameters
    ----------
    rig : Rig
        A connected rig.
    setpoints : array_like or iterable
        Cable speeds (mm/s, + = pull), one per 10 ms period (a row of every tendon's on a rig of several).
    shaper : helpers.paper.shapers.Shaper, helpers.board.stream_reference.StreamShaper or None
        Loaded on the board (rounded to its 16 us and 1/4096); None streams unshaped.
    path : path-like
        ``data/<group>/<name>``; an existing recording is refused before anything moves.
    scenario : dict, optional
        More scenario metadata; ``kind`` is ``"stream"``.
    lead_periods : int
        Periods a set-point waits in the board's FIFO (1-7): latency against tolerance of host jitter.
    lead_in_s, tail_s : float
        Device time recorded before ``STREAM`` and after the stream's end (0-60 s).
    allow_clamps : bool
        Go on when the board clamps the shaped motion (the recording is then ``deviated``).
    rate_hz, progress, replace, noise_seed
        As :meth:`Rig.run`'s.
    guard : helpers.rig.trim.TensionGuard, optional
        As :meth:`Rig.run`'s: the trim (several tendons) before the stream, after the rest (the whole stream
        checked again from where it leaves the tendons), and the floor watch on every sample. Unlike a run's,
        optional for several tendons (None: neither): a stream is any motion, a teleoperator's or a test's,
        that may slacken a tendon on purpose.

    Raises
    ------
    SafetyError
        Before anything moves: a set-point that is not finite or beyond the speed limit, a command past a
        tendon's travel or with every tendon slack, one the board would clamp, a stream over the host's limit.
    ValueError
        A shaper that cannot be loaded, an out-of-range ``lead_periods``, ``lead_in_s`` or ``tail_s``.
    """
    rig._check_run(rate_hz, noise_seed, tail_s)
    if type(lead_in_s) not in (int, float) or not 0 <= lead_in_s <= 60:
        raise ValueError(f"lead_in_s must be a number of seconds in 0-60, got {lead_in_s!r}")
    board = board_shaper(shaper, rig.n)
    Pacer(0, lead_periods)  # refuses a bad lead before anything is sent
    source = SetpointSource(setpoints, rig.rig)
    units = source.check_all() if source.sized else None
    _check_firmware(rig.stepper.version)
    with reserve(path, replace) as target:  # a second run to this name is refused now
        start = rig.positions()
        reach = _anywhere(rig.rig, start)
        if units is not None:  # the whole stream, before a byte is sent
            reach = check_stream(units * unit_mm_s(rig.rig), rig.rig, start, board, allow_clamps).reach
        record = StreamRecord(board, source.name, lead_periods, rig.n)
        units_mm_s = unit_mm_s(rig.rig)
        record.data.update(lead_in_s=float(lead_in_s), tail_s=float(tail_s), setpoint_unit_mm_s=units_mm_s)
        scene = {**(scenario or {}), "kind": "stream", "shaper": shaper_meta(shaper), "stream": record.data}
        rig._note_start(scene, start, noise_seed)
        feed = iter([tuple(r) for r in units.tolist()]) if units is not None else source
        check = ShapedCheck(board, start, rig.rig, refuse=not allow_clamps)

        def body(state: RunState) -> None:
            nonlocal reach, check, feed
            if guard is not None and guard.before(rig, scene, rate_hz):
                state.start = rig.positions()  # the stream counts from where the trim left the tendons
                reach = _anywhere(rig.rig, state.start)
                if units is not None:  # the whole stream checked again from there
                    reach = check_stream(units * units_mm_s, rig.rig, state.start, board, allow_clamps).reach
                check = ShapedCheck(board, state.start, rig.rig, refuse=not allow_clamps)
                rig._note_start(scene, state.start, None)
            if guard is not None and guard.rests:  # trimmed at its rests: off the planned path's counts then
                def widen() -> None:
                    rig.daq.parser.steps_range = _anywhere(rig.rig, state.start)

                feed = guard.at_rests(feed, rig, rate_hz, check.where, widen, v_max(rig.rig),
                                      record.data.setdefault("rest_trims", []))  # fmt: skip
            scene["rest"] = rig.wait_for_rest(rate_hz)
            rig.stepper.command("ABORT")  # whatever an earlier session left running stops; driver off
            rig.daq.command("STOP")
            rig.stepper.send_all(board.commands())  # SHAPER first: loading again discards it
            state.watch = None if guard is None else guard.watcher(rig, rate_hz)
            rig._start(rate_hz, reach)
            timeout = rig.daq.port.timeout
            rig.daq.port.timeout = min(timeout or FEED_READ_S, FEED_READ_S)  # device time in small steps
            expected_s = None if units is None else len(units) / STREAM_RATE_HZ + board.duration_s + tail_s
            try:
                _feed(rig, state, feed, check, record, (lead_in_s, tail_s, allow_clamps, rate_hz, expected_s,
                                                         progress))  # fmt: skip
            finally:
                rig.daq.port.timeout = timeout
            state.deviation = record.deviation()
            rig._finish(state)

        return rig._guarded(body, scene, target, rate_hz, replace, start)


def _anywhere(rig: RigFile, start: tuple[int, ...]) -> list[tuple[int, int]]:
    """Every step count (from ``ZERO`` at ``start``) a tendon's travel allows: where a stream may take it."""
    d = derived(rig)
    return [(-r - s, t - s) for r, t, s in zip(d.release_steps, d.travel_steps, start, strict=True)]


def _check_firmware(version: str | None) -> None:
    """Refuse a stream on a stepper board whose firmware holds the last set-point when the host is late."""
    try:
        major, minor = (int(x) for x in str(version).split(".")[:2])
    except ValueError:
        major, minor = -1, -1
    if (major, minor) < STREAM_FIRMWARE:
        raise BoardError(
            f"the stepper board runs firmware {version}, whose streams hold the last set-point through a "
            "period the host was late for (the cable then goes further than commanded): flash firmware "
            f"{STREAM_FIRMWARE[0]}.{STREAM_FIRMWARE[1]} or later to stream (make -C firmware upload-stepper)"
        )


def _feed(rig: Rig, state: RunState, feed: Any, check: ShapedCheck, record: StreamRecord, opts: tuple
          ) -> None:  # fmt: skip
    """The lead-in, ``STREAM``, the set-points as they fall due, ``END``, ``DONE``, the tail."""
    lead_in_s, tail_s, allow_clamps, rate_hz, expected_s, progress = opts
    rows, stepper = rig.daq.rows, rig.stepper
    silence = rig.daq.waiter(rig.silence_s)
    while not rows or rows[-1][1] - rows[0][1] < lead_in_s * 1e6:
        _, silence = rig._read(silence)
    stepper.command("EN 1")
    rig._go(state, "STREAM")
    pacer = Pacer(rows[-1][1], record.lead_periods)
    word = "V" if rig.n == 1 else "MV"
    pending: tuple[int, ...] | None = None  # a set-point the board refused with ERR FULL, to send again
    ended: list[Any] = []  # (finish us from GO, every tendon's end) once END is sent
    noticed = 0

    def take_notices() -> None:
        nonlocal noticed
        for line in stepper.notices[noticed:]:
            noticed += 1
            record.notice(line, allow_clamps)

    def step(now: int) -> Any:
        nonlocal pending
        take_notices()
        now += state.t_go_us
        while not ended and pacer.due(now):
            if pending is None:
                try:
                    pending = next(feed)
                except StopIteration:  # the shaper's tail planned first: refused before the board clamps
                    end = check.end()
                    end_period = ints(stepper.command("END"))[-1]
                    record.data["end_period"] = end_period
                    ended.append((pacer.finish_us(end_period, record.q_max) - state.t_go_us, end))
                    break
            planned = check.checkpoint()
            check.setpoint(pending)  # refused before the byte is sent if the board would clamp
            try:
                period: int | None = ints(stepper.command(f"{word} " + " ".join(map(str, pending))))[-1]
            except CommandRefused as exc:
                if exc.code != "FULL":
                    take_notices()  # a stream the board has ended (the watchdog) refuses: say why
                    raise
                period = None
            rig.daq.read(block=False)  # device time went on while the source and the board were asked
            now = rows[-1][1]
            if period is None:
                check.rollback(planned)
                pacer.refused_full(now)
            else:
                record.sent(pending, period)
                if check.confirm(planned, pending, period):  # the board ran short: planned where it went
                    rig.daq.parser.steps_range = _anywhere(rig.rig, state.start)
                pacer.accepted(period, now)
                pending = None
            record.counts(pacer)
        return ended[0] if ended else None

    rig._until_done(state, step, rate_hz, tail_s, expected_s, progress)
