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
- :class:`FloorWatch`: during a run, every parsed sample's calibrated tension of every tendon against
  ``[arm] tension_floor_n``; a tendon below it for longer than ``[arm] floor_watch_ms`` (default 20 ms; a
  pay-out step's dip lasts 3 ms at the median, the pre-pull's let-out 2-4 samples) raises :class:`BelowFloor`
  naming the tendon, how long and when (device time), and the driver's guard saves the run ``aborted`` with
  that reason. Time is counted in samples at the DAQ's rate, never on the wall clock.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from helpers.rig.safety import SafetyError

__all__ = [
    "TRIM_MAX_STEPS", "TRIM_TOLERANCE_N", "BelowFloor", "FloorWatch", "TrimFailed", "TrimResult",
    "trim_steps",
]  # fmt: skip

TRIM_MAX_STEPS = 6
"""Most moves of one step a tendon makes in one trim (about 16 N on the four-tendon rigs)."""

TRIM_TOLERANCE_N = 0.1
"""A measured tension this far below its target counts as at it (2-3 ADC counts of the four-tendon rigs'
0.041 N per count: the mean over the rest window of a tendon exactly at its target reads within it)."""


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
        """Check a block of parsed samples; :class:`BelowFloor` at the first sample past the watch time."""
        r = np.asarray(rows, dtype=float).reshape(len(rows), -1) if len(rows) else np.zeros((0, 2 + self.n))
        self.seen += len(r)
        tension = (r[:, 2 : 2 + self.n] - self.offset) * self.npc
        below = tension < self.floor_n
        for k in range(len(r)):
            for i in range(self.n):
                if not below[k, i]:
                    self.run[i], self.least[i] = 0, np.inf
                    continue
                if self.run[i] == 0:
                    self.first_us[i] = int(r[k, 1])
                self.run[i] += 1
                self.least[i] = min(self.least[i], tension[k, i])
                self.longest[i] = max(self.longest[i], self.run[i])
                if self.run[i] > self.limit:
                    ms = self.run[i] * 1000.0 / self.rate_hz
                    t0, clock = (0, "on the DAQ's clock") if self.t0_us is None else (self.t0_us, "after GO")
                    raise BelowFloor(
                        f"tendon {i + 1} below the floor {self.floor_n:.2f} N for {ms:g} ms ({self.run[i]} "
                        f"samples at {self.rate_hz} Hz, least {self.least[i]:.2f} N) at device time "
                        f"t = {(r[k, 1] - t0) / 1e6:.3f} s {clock} (from {(self.first_us[i] - t0) / 1e6:.3f} "
                        f"s): longer than the floor watch's {self.watch_ms:g} ms ([arm] floor_watch_ms)"
                    )
