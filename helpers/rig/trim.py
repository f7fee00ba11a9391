"""Tension held by measurement, on the host: the trim of every tendon by whole steps, and the floor watch.

The load cells are on the DAQ board (the Mega) and the steppers on the stepper board (the Uno), and nothing
links the two: a trim in firmware would need the Uno to read the Mega's tensions. The host reads every
sample, calibrated per tendon, and already waits for the arm to come to rest (:meth:`Rig.wait_for_rest
<helpers.rig.driver.Rig.wait_for_rest>`), so the host trims (``docs/safety.md``, ``docs/task_space.md``).

- :func:`trim_steps`, the rule: at rest, each tendon's mean calibrated tension over the rest window is
  compared with its target (the planner's static tension at that pose, passed in as numbers: this module
  imports neither the twin nor the research wing), and each tendon is moved by whole steps to **the fewest
  whole steps at which its measured tension is >= its target** (less :data:`TRIM_TOLERANCE_N`, the reading's
  resolution): pulled in one step at a time while below, and, where it is above by at least the tension the
  planner predicts for one step, let out one step at a time while it stays there (the step that takes it
  below is pulled back). One step is about 2.7 N
  on the four-tendon rigs (1 N is about 47 um of cable), so a band of +-1 N would oscillate; the band is
  ``[target - tolerance, target - tolerance + one step)``. At most :data:`TRIM_MAX_STEPS` moves per tendon;
  past them, :class:`TrimFailed` naming the tendon. Off for one tendon (the paper's Table II unchanged).
- :func:`trim` (with :func:`rest_tensions`, :func:`nudge`): the rule on a :class:`~helpers.rig.driver.Rig`.
- :class:`TensionGuard`: what a run of several tendons is given (``Rig.run(..., guard=...)``, ``stream(...,
  guard=...)``): the trim before it (its targets, optional), the trims at a stream's rests (optional) and the
  floor watch during it. The driver only calls it, so this module is off the paper's one-tendon path
  (``tests/test_reading_path.py``).
- :func:`rest_steps` and :meth:`TensionGuard.at_rests`: the trim at a stream's rest, where the stream goes on
  and the host cannot wait and measure again: one measurement (each tendon's mean tension over the last
  :data:`REST_WINDOW_S` of samples), the rule's whole steps from it at once, and one set-point that takes
  each tendon's commanded position just past them, sent in place of one of the rest's zero set-points (so it
  is shaped by the board's shaper as every set-point, and checked by the host's copy of the board's planner
  before it is sent, as every set-point).
- :class:`FloorWatch`: during a run, every parsed sample's calibrated tension of every tendon against
  ``[arm] tension_floor_n``; a tendon below it for longer than ``[arm] floor_watch_ms`` (default 20 ms; a
  pay-out step's dip lasts 3 ms at the median, the pre-pull's let-out 2-4 samples) raises :class:`BelowFloor`
  naming the tendon, how long and when (device time), and the driver's guard saves the run ``aborted`` with
  that reason. Time is counted in samples at the DAQ's rate, never on the wall clock.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from helpers.board import stream_reference as hs
from helpers.board.programmes import Move, Programme
from helpers.rig.driver import Rig, RunState
from helpers.rig.link import BoardError, ints
from helpers.rig.safety import SafetyError, check_programme

__all__ = [
    "REST_WINDOW_S", "TRIM_MAX_STEPS", "TRIM_TOLERANCE_N", "BelowFloor", "FloorWatch", "Rest",
    "TensionGuard", "TrimFailed", "TrimResult", "nudge", "rest_steps", "rest_tensions", "trim", "trim_steps",
]  # fmt: skip

TRIM_MAX_STEPS = 6
"""Most moves of one step a tendon makes in one trim (about 16 N on the four-tendon rigs)."""

TRIM_TOLERANCE_N = 0.1
"""A measured tension this far below its target counts as at it (2-3 ADC counts of the four-tendon rigs'
0.041 N per count: the mean over the rest window of a tendon exactly at its target reads within it)."""


REST_WINDOW_S = 0.3
"""Device seconds of samples a stream's rest trim averages each tendon's tension over (the last before its
set-point is taken): about one period of the four-tendon arm's dominant mode (0.28 s at 22.7 rad/s), so that
what still rings of the stop averages out."""

PAST_STEP = 0.05
"""Steps. The board steps when the commanded position reaches the count's next whole step (a hysteresis of one
step, ``helpers.board.stream_reference``), and a set-point unit is 1/104.86 of a step, so no whole number
of units moves a position by exactly whole steps: a rest trim moves it by its steps rounded up to a unit,
where it stands at least this far on the side of the count it moves to, and otherwise (a pull only) to this
far past the last step's threshold; a let-out from elsewhere is not made. So the count moves by exactly the
trim's steps, and every later count is the plan's plus them or one step more, never less: the plan places a
stop's position a thousandth of a step or so past its count, finer than a unit, and a later pay-out (the
pre-pull's let-out included) may then stop one step short. Taut, never slacker."""

UNITS_PER_STEP = (1 << 16) / hs.PERIOD
"""Set-point units held for one period per step (104.8576)."""


class TrimFailed(SafetyError):
    """A tendon did not reach its target within :data:`TRIM_MAX_STEPS` moves (or a target was unusable)."""


class BelowFloor(SafetyError):
    """A tendon's measured tension stayed below the floor for longer than the watch time during a run."""


@dataclass(frozen=True)
class TrimResult:
    """What a trim did.

    Attributes
    ----------
    steps : tuple of int
        Each tendon's net whole steps (+ pulled in).
    moves : int
        Moves of one step made (each followed by a wait for rest).
    targets_n, before_n, after_n : tuple of float
        Each tendon's target, and its mean measured tension before and after the trim, N.
    tolerance_n : float
        The tolerance below the target (:data:`TRIM_TOLERANCE_N`).
    """

    steps: tuple[int, ...]
    moves: int
    targets_n: tuple[float, ...]
    before_n: tuple[float, ...]
    after_n: tuple[float, ...]
    tolerance_n: float

    def metadata(self) -> dict[str, Any]:
        """A recording's ``scenario.measured_trim``."""
        return {
            "steps": list(self.steps), "moves": self.moves,
            "targets_n": [round(v, 6) for v in self.targets_n],
            "before_n": [round(v, 6) for v in self.before_n], "after_n": [round(v, 6) for v in self.after_n],
            "tolerance_n": self.tolerance_n,
        }  # fmt: skip


def _targets(targets_n: Sequence[float]) -> np.ndarray:
    t = np.asarray(targets_n, dtype=float).reshape(-1)
    if t.size == 0 or not np.all(np.isfinite(t)) or np.any(t < 0):
        raise TrimFailed(
            f"trim targets must be finite tensions >= 0 N, one per tendon, got {list(targets_n)}"
        )
    return t


def trim_steps(
    targets_n: Sequence[float],
    measure: Callable[[], Sequence[float]],
    move: Callable[[tuple[int, ...]], None],
    *,
    max_steps: int = TRIM_MAX_STEPS,
    tolerance_n: float = TRIM_TOLERANCE_N,
    step_n: Sequence[float] | None = None,
) -> TrimResult:
    """Trim every tendon by whole steps to the fewest at which its measured tension is >= its target.

    Parameters
    ----------
    targets_n : sequence of float
        Each tendon's target, N (the planner's static tension at the pose).
    measure : callable
        ``measure() -> tensions``: waits for rest and gives each tendon's mean calibrated tension over the
        rest window, N.
    move : callable
        ``move(steps)``: moves every tendon by its whole ``steps`` (+ pulls in; one tendon at a time here).
    max_steps : int
        Most moves of one step per tendon; past them :class:`TrimFailed` names the tendon.
    tolerance_n : float
        A tension this far below its target counts as at it.
    step_n : sequence of float, optional
        Each tendon's tension change per step as the planner predicts it, N (about 2.7 on the four-tendon
        rigs). Where given, a tendon whose measured tension is above its target by at least that is let out
        one step at a time while it is (a let-out that took it below is pulled back); None: tendons above
        their targets are left where they are (pulled in only).

    Returns
    -------
    TrimResult

    Raises
    ------
    TrimFailed
        A tendon still below its target after ``max_steps`` moves, or a measurement that is not one finite
        tension per tendon.
    """
    targets = _targets(targets_n)
    n = targets.size
    goal = targets - float(tolerance_n)

    def read() -> np.ndarray:
        got = np.asarray(measure(), dtype=float).reshape(-1)
        if got.size != n or not np.all(np.isfinite(got)):
            raise TrimFailed(f"the trim measured {got.tolist()}, not one finite tension per tendon ({n})")
        return got

    def step(i: int, sign: int) -> np.ndarray:
        if moved[i] >= max_steps:
            raise TrimFailed(
                f"tendon {i + 1}: {tension[i]:.2f} N measured after {moved[i]} move(s) of one step "
                f"(net {net[i]:+d}), not yet at its target {targets[i]:.2f} N (less {tolerance_n:g} N): "
                f"more than the trim's {max_steps} moves; is its cable slack or its load cell off?"
            )
        vector = [0] * n
        vector[i] = sign
        move(tuple(vector))
        moved[i] += 1
        net[i] += sign
        return read()

    per_step = None if step_n is None else np.broadcast_to(np.asarray(step_n, dtype=float), (n,))
    if per_step is not None and not np.all(np.isfinite(per_step) & (per_step > 0)):
        raise TrimFailed(f"the tension per step must be > 0 N, one per tendon, got {list(step_n or [])}")
    tension = before = read()
    moved, net = [0] * n, [0] * n
    if per_step is not None:  # let out: a whole step's tension above the target, and measured still above
        for i in range(n):
            while net[i] <= 0 and tension[i] - per_step[i] >= goal[i]:
                tension = step(i, -1)
                if tension[i] < goal[i]:  # one step too far: back to the fewest steps that hold it
                    tension = step(i, +1)
                    break
    while True:  # pull in: one step on the tendon farthest below its target, then measure again
        low = np.flatnonzero(tension < goal)
        if low.size == 0:
            break
        i = int(low[np.argmin((tension - goal)[low])])
        tension = step(i, +1)
    return TrimResult(
        steps=tuple(net), moves=sum(moved), targets_n=tuple(map(float, targets)),
        before_n=tuple(map(float, before)), after_n=tuple(map(float, tension)),
        tolerance_n=float(tolerance_n),
    )  # fmt: skip


@dataclass(frozen=True)
class Rest:
    """A stream's rest where every tendon is trimmed (:meth:`TensionGuard.at_rests`).

    Attributes
    ----------
    setpoint : int
        The index of a set-point inside the rest: zero set-points from where the stop's shaped motion and its
        ringing have settled, at least :data:`REST_WINDOW_S` before it, to where the trim's own shaped motion
        has ended.
    targets_n : tuple of float
        Each tendon's target there, N (the planner's static tension at that pose).
    per_step_n : numpy.ndarray, optional
        The planner's tension change of every tendon per step of each (N; ``[i, j]``: tendon ``i`` when
        tendon ``j`` is pulled one step), which :func:`rest_steps` predicts with. None: one step on the
        tendon farthest below, measured again at the next rest.
    """

    setpoint: int
    targets_n: tuple[float, ...]
    per_step_n: Any = None


def rest_steps(
    measured_n: Sequence[float], targets_n: Sequence[float], per_step_n: Any = None, *,
    tolerance_n: float = TRIM_TOLERANCE_N, max_steps: int = TRIM_MAX_STEPS,
) -> tuple[int, ...]:  # fmt: skip
    """The trim's rule (:func:`trim_steps`) from one measurement: each tendon's whole steps (+ pulls in).

    Where the stream goes on, the host cannot measure after each step, so it predicts with the planner's
    tension per step, ``per_step_n`` (a matrix: every tendon's change per step of each, since pulling one
    tendon of an opposed pair lifts both; a vector: no coupling). As :func:`trim_steps` measures, it predicts:
    one step on the tendon farthest below its target less ``tolerance_n`` until none is, then, while every
    tendon stays at its target, one step let out of the one farthest above. Without ``per_step_n``: one step
    on the tendon farthest below (measured again at the next rest), none let out.

    Raises
    ------
    TrimFailed
        Not one finite measurement per tendon, an unusable ``per_step_n``, or a tendon that needs more than
        ``max_steps`` (named).
    """
    targets = _targets(targets_n)
    n = targets.size
    measured = np.asarray(measured_n, dtype=float).reshape(-1)
    if measured.size != n or not np.all(np.isfinite(measured)):
        raise TrimFailed(f"the trim measured {measured.tolist()}, not one finite tension per tendon ({n})")
    goal = targets - float(tolerance_n)
    steps = np.zeros(n, dtype=int)
    if per_step_n is None:
        if np.any(measured < goal):
            steps[int(np.argmin(measured - goal))] = 1
        return tuple(int(k) for k in steps)
    k = np.asarray(per_step_n, dtype=float)
    k = np.diag(np.broadcast_to(k, (n,))) if k.ndim <= 1 else k
    if k.shape != (n, n) or not np.all(np.isfinite(k)) or not np.all(np.diag(k) > 0):
        raise TrimFailed(f"the tension per step must be finite, > 0 N on each tendon's own, one per tendon "
                         f"(or {n} x {n}), got {np.asarray(per_step_n).tolist()}")  # fmt: skip
    predicted = measured.copy()
    while np.any(predicted < goal):  # pull in: the tendon farthest below, then predicted again
        i = int(np.argmin(predicted - goal))
        if steps[i] >= max_steps:
            raise TrimFailed(
                f"tendon {i + 1}: {measured[i]:.2f} N measured at rest against its target {targets[i]:.2f} N "
                f"needs more than the trim's {max_steps} steps; is its cable slack or its load cell off?"
            )
        steps[i] += 1
        predicted += k[:, i]
    while True:  # let out: the tendon farthest above, while every tendon stays at its target
        free = [i for i in range(n) if -max_steps < steps[i] <= 0 and np.all(predicted - k[:, i] >= goal)]
        if not free:
            return tuple(int(v) for v in steps)
        i = max(free, key=lambda m: predicted[m] - goal[m])
        steps[i] -= 1
        predicted -= k[:, i]


def rest_tensions(rig: Rig, rate_hz: int = 1000) -> tuple[dict[str, Any], np.ndarray]:
    """Wait for rest; its dict and every tendon's mean tension over the rest window, N.

    :meth:`Rig.wait_for_rest <helpers.rig.driver.Rig.wait_for_rest>`, then each tendon's counts in the window
    averaged and calibrated with its load cell's calibration.
    """
    rest = rig.wait_for_rest(rate_hz)
    counts = np.asarray(rig.rest_window, dtype=float).reshape(len(rig.rest_window), -1).mean(axis=0)
    return rest, np.array([(counts[i] - c.offset_counts) * c.newtons_per_count
                           for i, c in enumerate(rig.calibration)])  # fmt: skip


def nudge(rig: Rig, steps: Sequence[int], rate_hz: int = 1000, window_us: int = 20_000) -> tuple[int, ...]:
    """Move every tendon by its whole ``steps`` in one ``MSEG`` item of ``window_us`` (not recorded).

    Checked against every tendon's limits from where the stepper says they are; ``DONE`` awaited in device
    time as a run's; on any exception (a signal included) the stepper is aborted and disabled and the DAQ
    stopped before it is raised. Returns every tendon's position after it.
    """
    start = rig.positions()
    programme = Programme((Move(window_us, tuple(int(s) for s in steps)),))
    check_programme(programme, rig.rig, start)
    end = tuple(int(p) for p in programme.positions(start, rig.n)[-1])
    rig.stepper.command("ABORT")
    rig.daq.command("STOP")
    replies = rig.stepper.send_all(programme.commands(rig.n))
    if ints(replies[-1])[-1] != len(programme):
        raise BoardError(f"the stepper board holds {replies[-1]}, not {len(programme)} items")
    rig._start(rate_hz, None, zero=False)
    rig.stepper.command("EN 1")
    state = RunState(start=start)
    try:
        rig._go(state, "GO")
        rig._until_done(state, lambda now: (programme.duration_us, end), rate_hz, 0.0, None, False)
    except BaseException:  # a signal, a board gone: ABORT, EN 0 and STOP as a run's guard sends them
        rig._cleanup(True)
        rig.daq.rows.clear()
        raise
    rig.daq.command("STOP")
    rig.daq.rows.clear()
    rig.stepper.command("EN 0")  # as a run leaves it
    return end


def trim(rig: Rig, targets_n: Sequence[float], rate_hz: int = 1000, step_n: Any = None) -> TrimResult:
    """Trim every tendon of ``rig`` by whole steps to its target tension, measured at rest (several tendons).

    :func:`trim_steps` with each measurement a wait for rest and its mean calibrated tension
    (:func:`rest_tensions`), each move one whole step of one tendon (:func:`nudge`).

    Raises
    ------
    ValueError
        One tendon (the paper's protocol has no trim), or not one target per tendon.
    TrimFailed
        A tendon not at its target within :data:`TRIM_MAX_STEPS` moves (named).
    """
    if rig.n == 1:
        raise ValueError("the trim is for rigs of several tendons (one tendon: the paper's protocol)")
    if len(np.atleast_1d(np.asarray(targets_n, dtype=float))) != rig.n:
        raise ValueError(f"{len(targets_n)} trim target(s) for the rig's {rig.n} tendons")
    return trim_steps(targets_n, lambda: rest_tensions(rig, rate_hz)[1],
                      lambda steps: nudge(rig, steps, rate_hz), step_n=step_n)  # fmt: skip


@dataclass(frozen=True)
class TensionGuard:
    """What holds every tendon of a run of several tendons taut: the trim before it, the floor watch during.

    Attributes
    ----------
    targets_n : sequence of float, optional
        Each tendon's target tension at the start (N, the planner's static tension at that pose): after the
        rest every tendon is trimmed (:func:`trim`, the recording's ``scenario.measured_trim``). None: none.
    step_n : sequence of float, optional
        The planner's tension per step of each tendon (:func:`trim_steps`: a tendon that much above its
        target is let out).
    watch : bool
        Watch every tendon's measured tension on every sample (:class:`FloorWatch`).
    rests : sequence of Rest, optional
        A stream's rests where every tendon is trimmed (:meth:`at_rests`). None: none.
    """

    targets_n: Sequence[float] | None = None
    step_n: Sequence[float] | None = None
    watch: bool = True
    rests: Sequence[Rest] | None = None

    def before(self, rig: Rig, scenario: dict[str, Any], rate_hz: int) -> bool:
        """Trim (if there are targets), noted in ``scenario``; True if it ran (the tendons may have moved)."""
        if self.targets_n is None:
            return False
        scenario["measured_trim"] = trim(rig, self.targets_n, rate_hz, self.step_n).metadata()
        return True

    def at_rests(
        self, feed: Iterator[tuple[int, ...]], rig: Rig, rate_hz: int, where: Callable[[], tuple[Any, Any]],
        widen: Callable[[], None], limit: int, notes: list[dict[str, Any]],
    ) -> Iterator[tuple[int, ...]]:  # fmt: skip
        """``feed`` (a stream's set-points, board units) with every tendon trimmed at this guard's rests.

        At each rest's set-point: each tendon's mean calibrated tension over the last :data:`REST_WINDOW_S`
        of samples received, the whole steps by :func:`rest_steps` (the rest's targets and tension per step),
        and the set-point replaced (it must be
        zero: a rest) by the one that moves every tendon's count by them (:data:`PAST_STEP`), from where
        ``where()`` says the board's planner stands (every tendon's step count and exact commanded position
        after the set-points planned so far). ``widen()`` is called before a trim's set-point is sent (the
        tendons then leave the planned path's step counts); ``limit`` is the build's set-point limit (board
        units); every rest's measurement and steps are appended to ``notes`` (the recording's
        ``stream.rest_trims``).

        Raises
        ------
        TrimFailed
            A rest's set-point that is not zero (not a rest), or a tendon that needs more steps than the trim
            makes (:func:`rest_steps`).
        """
        at = {int(r.setpoint): r for r in self.rests or ()}
        cal = rig.calibration
        npc = np.array([c.newtons_per_count for c in cal])
        offset = np.array([c.offset_counts for c in cal])
        window = max(1, round(REST_WINDOW_S * rate_hz))
        for j, row in enumerate(feed):
            if j in at:
                if any(row):
                    raise TrimFailed(f"the stream's set-point {j} moves {list(row)}: a rest trim needs a "
                                     "rest")  # fmt: skip
                samples = rig.daq.rows[-window:]
                counts = np.asarray(samples, dtype=float).reshape(len(samples), -1)[:, 2 : 2 + rig.n]
                measured = (counts.mean(axis=0) - offset) * npc if len(samples) == window else None
                note: dict[str, Any] = {"setpoint": j, "targets_n": list(at[j].targets_n)}
                if measured is None:  # the lead-in is shorter than the window: nothing measured, no trim
                    note["skipped"] = f"{len(samples)} samples, fewer than the window's {window}"
                else:
                    steps = np.array(rest_steps(measured, at[j].targets_n, at[j].per_step_n))
                    count, x = (np.asarray(v, dtype=float) for v in where())
                    sign = np.sign(steps)
                    along = sign * (x - count) >= PAST_STEP  # it stands on the side of the count it moves to
                    steps = np.where((steps < 0) & ~along, 0, steps)  # a let-out only from there (PAST_STEP)
                    sign = np.sign(steps)
                    units = np.where(along, np.ceil(steps * UNITS_PER_STEP - 1e-9),
                                     np.ceil((count + steps + PAST_STEP - x) * UNITS_PER_STEP))
                    units = np.where(steps != 0, units, 0)
                    if np.abs(units).max() > limit:
                        raise TrimFailed(f"the rest trim at set-point {j} needs {units.tolist()} set-point "
                                         f"units, over the build's limit of {limit}")  # fmt: skip
                    note.update(measured_n=[round(float(v), 6) for v in measured], steps=steps.tolist())
                    if steps.any():
                        widen()
                        row = tuple(int(u) for u in units)
                notes.append(note)
            yield row

    def watcher(self, rig: Rig, rate_hz: int) -> FloorWatch | None:
        """The rig's floor watch at ``rate_hz`` (``[arm] tension_floor_n``, ``floor_watch_ms``), or None."""
        if not self.watch:
            return None
        arm, cal = rig.rig.arm, rig.calibration
        return FloorWatch(arm.tension_floor_n, arm.floor_watch_ms, rate_hz,
                          [c.newtons_per_count for c in cal], [c.offset_counts for c in cal])  # fmt: skip


class FloorWatch:
    """Every tendon's calibrated tension, sample by sample, against the floor (device time: samples).

    Parameters
    ----------
    floor_n : float
        ``[arm] tension_floor_n``.
    watch_ms : float
        ``[arm] floor_watch_ms``: below the floor for longer than this is :class:`BelowFloor`.
    rate_hz : int
        The DAQ's sample rate (a sample is ``1000 / rate_hz`` ms of device time).
    newtons_per_count, offset_counts : sequence of float
        Each tendon's load-cell calibration (tension ``(adc - offset) * newtons_per_count``).

    A run of ``k`` consecutive samples below the floor lasts ``k`` sample periods; more than
    ``watch_ms`` of them raises. The rows are the DAQ's parsed samples ``[seq, t_us, adc..., steps...]``.
    """

    def __init__(
        self, floor_n: float, watch_ms: float, rate_hz: int, newtons_per_count: Sequence[float],
        offset_counts: Sequence[float],
    ) -> None:  # fmt: skip
        self.floor_n, self.watch_ms, self.rate_hz = float(floor_n), float(watch_ms), int(rate_hz)
        self.npc = np.asarray(newtons_per_count, dtype=float)
        self.offset = np.asarray(offset_counts, dtype=float)
        self.n = self.npc.size
        self.limit = math.floor(self.watch_ms * self.rate_hz / 1000.0 + 1e-9)
        """The most consecutive samples below the floor that are allowed."""
        self.run = np.zeros(self.n, dtype=np.int64)
        self.first_us = np.zeros(self.n, dtype=np.int64)
        self.least = np.full(self.n, np.inf)
        self.longest = np.zeros(self.n, dtype=np.int64)
        """Each tendon's longest run below the floor so far (samples)."""
        self.t0_us: int | None = None
        """``GO``'s device time once known (the reason then gives times from it)."""
        self.seen = 0
        """Rows checked so far (:meth:`catch_up`)."""

    def catch_up(self, rows: Any) -> None:
        """Check the rows of ``rows`` (a run's growing list of parsed samples) not checked yet."""
        if len(rows) > self.seen:
            self.feed(rows[self.seen :])

    def feed(self, rows: Any) -> None:
        """Check a block of parsed samples; :class:`BelowFloor` at the first sample past the watch time.

        Each tendon's run of samples below the floor is counted across blocks (a run carried over from the
        last block goes on), in one pass of array operations per block.
        """
        if not len(rows):
            return
        r = np.asarray(rows, dtype=float).reshape(len(rows), -1)
        self.seen += len(r)
        tension = (r[:, 2 : 2 + self.n] - self.offset) * self.npc
        below = tension < self.floor_n
        k = np.arange(len(r))[:, None]
        last_above = np.maximum.accumulate(np.where(below, -1, k), axis=0)  # -1: below since the block began
        run = np.where(below, k - last_above + np.where(last_above < 0, self.run, 0), 0)
        over = run > self.limit
        if over.any():
            k_over, i = np.unravel_index(np.argmax(over), over.shape)  # the first sample past the watch time
            count = int(run[k_over, i])
            begin = k_over - min(count, k_over + 1) + 1  # the run's first sample in this block
            least = min(tension[begin : k_over + 1, i].min(), self.least[i] if count > k_over + 1 else np.inf)
            first_us = self.first_us[i] if count > k_over + 1 else int(r[begin, 1])
            ms = count * 1000.0 / self.rate_hz
            t0, clock = (0, "on the DAQ's clock") if self.t0_us is None else (self.t0_us, "after GO")
            raise BelowFloor(
                f"tendon {i + 1} below the floor {self.floor_n:.2f} N for {ms:g} ms ({count} samples at "
                f"{self.rate_hz} Hz, least {least:.2f} N) at device time "
                f"t = {(r[k_over, 1] - t0) / 1e6:.3f} s {clock} (from {(first_us - t0) / 1e6:.3f} s): "
                f"longer than the floor watch's {self.watch_ms:g} ms ([arm] floor_watch_ms)"
            )
        self.longest = np.maximum(self.longest, run.max(axis=0))
        tail = run[-1]  # each tendon's run still going at the block's end, carried to the next block
        for i in np.flatnonzero(tail):
            begin = len(r) - min(int(tail[i]), len(r))
            if tail[i] > len(r):  # going on since an earlier block
                self.least[i] = min(self.least[i], tension[begin:, i].min())
            else:
                self.first_us[i], self.least[i] = int(r[begin, 1]), tension[begin:, i].min()
        self.least[tail == 0] = np.inf
        self.run = tail.astype(np.int64)
