"""Arbitrary motion of the tip: a two-dimensional bend stream turned into every tendon's set-points.

A **tip path** is the bend vector ``b = bend_mm (cos beta, sin beta)`` (mm of cable; ``beta`` the bend's
direction around the backbone, 0 = towards tendon 1, counter-clockwise, exactly as the frequency map and
:func:`helpers.research.task_space.plan_move` define a bend) at every boundary of the stream's 10 ms control
periods, the integral of a joystick-like bend-velocity command ``(v_x, v_y)`` (mm/s). :func:`figure_path`
makes the scripted figures (``square``, ``star``, ``circle``) and a seeded smooth random one (``random``),
each starting and ending at rest with stops; :func:`velocity_path` integrates any command.

:func:`plan_stream` turns a path into every tendon's cable set-points on the host:

1. **The statics along the path.** The spatial twin's bend equilibrium (the task-space pretension policy:
   the tendons facing the bend pulled as the map pulls them, every other held at its rest pretension, the
   statics saying how far its spool turns) is solved by continuation at **knots** along the path (every
   ``knot_mm`` of the bend's path length, every stop, the ends), each stepper's command interpolated
   linearly in the path's length between knots (the interpolation error, against the statics solved at the
   knots' midpoints, is printed by the dry run when any period is interpolated).
2. **Whole steps at the stops.** At every stop (a stretch of periods where the bend holds) each tendon's
   command is rounded to whole steps and trimmed to the floor as :func:`plan_move` does (so a stop holds
   ``plan_move``'s steps); the difference (under half a step plus the trim) is blended in linearly over the
   motion leading to the stop.
3. **Board units, ending where the plan says.** Each tendon's position is kept as a running sum of whole
   set-point units (``65536 / 625`` unit-periods per step; error diffusion as
   :func:`helpers.research.teleop.on_board_units`), and at a stop it is rounded to the side it comes from
   (a step count follows the cable with a one-step hysteresis, ``firmware/PROTOCOL.md``), so that the board's
   count stands at the stop's whole steps (checked with the board's planner: :func:`board_counts`).

**The tension floor on the plan** (:func:`plan_stream`, before any byte): at every period's planned positions
(the integrated set-points) the static tensions (the twin's statics, rotors free: the rig at rest there) must
be at or above the rig file's ``[arm] tension_floor_n``; a path that leaves one below is refused in one line
naming the tendon, the period and time, the bend and the figure (:class:`~helpers.rig.safety.SafetyError`,
exit status 3, ``docs/safety.md``). The travel and the speed limits, and the board's shaped motion, are the
stream's own checks (:func:`~helpers.rig.stream.check_stream`, called by :func:`check_plan`).

**The floor at the board's whole steps** (:func:`check_whole_steps`, before any byte): the board does not
stand at the planned positions but at whole-step counts that follow its shaped cable with a one-step
hysteresis (:func:`board_path`); one step of a tendon against its antagonist is about 2.7 N of static tension
on the four-tendon rig, more than its rest pretension, so the static tensions at those counts
(:func:`board_tensions`) at every period's end are checked against the floor too, refused in one line naming
the tendon, the period (:meth:`StreamPlan.board_where`) and the figure (exit status 3).

**A pre-pull** (``plan_stream(..., prepull=k)``, a move's
:func:`~helpers.research.task_shaping.pretensioned` rest for a stream): every tendon pulled ``k`` whole steps
in at once (one period), :data:`PREPULL_SETTLE_PERIODS` at rest, the path planned and designed from that
pre-pulled rest, then each tendon let out one at a time
(:func:`~helpers.research.task_shaping.release_order`), :data:`RELEASE_GAP_PERIODS` apart: all of it
set-points of the one stream (:attr:`StreamPlan.board_units`), shaped by the board like the path.

**One shaper for every tendon** (:func:`stream_design`): the paper's ZV or ZVD designed from the direction
map's dominant mode, averaged over the path's stops away from rest (each stop's ``dominant_omega_d_rad_s``
and ``dominant_zeta``; the mean): one shaper loaded on the board shapes every axis.

Everything here is the spatial twin's statics and modes: **simulated**, never measured.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from helpers.board import stream_reference as hs
from helpers.board.programmes import Limits
from helpers.paper.shapers import Shaper, design_tdfs
from helpers.research.task_shaping import (
    MAX_PREPULL_STEPS,
    PREPULL_SETTLE_MS,
    RELEASE_GAP_MS,
    pretensioned,
    release_order,
)
from helpers.research.task_space import MAX_TRIM_STEPS, shaper_metadata
from helpers.rig.safety import SafetyError
from helpers.rig.stream import CheckedStream, SetpointSource, check_stream
from helpers.rig.trim import Rest
from helpers.rigfile import RigFile
from helpers.rigfile.derived import derived
from helpers.virtual.spatial.direction_map import bend_equilibrium, frequency_map
from helpers.virtual.spatial.from_rig import spatial_rig
from helpers.virtual.spatial.rig import SpatialRig
from helpers.virtual.spatial.statics import SpatialEquilibrium, equilibrium

__all__ = [
    "PERIOD_S",
    "FIGURES",
    "SHAPERS",
    "UNITS_PER_STEP",
    "TipPath",
    "StreamPlan",
    "StreamDesign",
    "velocity_path",
    "figure_path",
    "MAPPINGS",
    "plan_stream",
    "check_floor",
    "check_plan",
    "board_path",
    "board_counts",
    "board_tensions",
    "check_whole_steps",
    "PREPULL_SETTLE_PERIODS",
    "RELEASE_GAP_PERIODS",
    "stream_design",
    "interpolation_error",
]

PERIOD_S = 0.01
"""The stream's control period, s (100 Hz)."""

FIGURES = ("square", "star", "circle", "random", "line")
"""The paths :func:`figure_path` makes."""

SHAPERS = ("none", "zv", "zvd")
"""The shapers a tip stream loads on the board (the paper's two)."""

UNITS_PER_STEP = (1 << 16) / hs.PERIOD
"""Set-point units held for one period per step (104.8576): a tendon's position is ``sum(units) / this``."""


@dataclass(frozen=True)
class TipPath:
    """A bend trajectory sampled at the boundaries of the control periods.

    Attributes
    ----------
    name : str
        The figure (``square``, ``star``, ``circle``, ``random``) or the command's name.
    bend_mm : float
        The figure's size: the largest bend magnitude, mm.
    bends : numpy.ndarray
        Shape (periods + 1, 2): the bend vector ``(b_x, b_y)`` (mm; x towards 0 deg, y towards 90 deg) at the
        start of every period and at the end of the last.
    stops : tuple of (int, int)
        Each hold: the first and last boundary index of a run of periods with the bend unchanged.
    speed_mm_s : float
        The speed the figure's legs were made at (mm of bend per second), for the record.
    """

    name: str
    bend_mm: float
    bends: np.ndarray
    stops: tuple[tuple[int, int], ...]
    speed_mm_s: float = math.nan

    @property
    def periods(self) -> int:
        """Number of control periods (set-points per tendon)."""
        return len(self.bends) - 1

    @property
    def velocity_mm_s(self) -> np.ndarray:
        """The bend-velocity command, shape (periods, 2), mm/s."""
        return np.diff(self.bends, axis=0) / PERIOD_S

    def polar(self, k: int) -> tuple[float, float]:
        """``(direction_deg, bend_mm)`` at boundary ``k`` (direction 0 at rest)."""
        x, y = (float(v) for v in self.bends[k])
        m = math.hypot(x, y)
        return (math.degrees(math.atan2(y, x)) % 360.0 + 0.0 if m > 1e-9 else 0.0), m

    def where(self, k: int) -> str:
        """``period k (t = ... s), bend ... mm towards ... deg``."""
        d, m = self.polar(k)
        return f"period {k} (t = {k * PERIOD_S:.2f} s, bend {m:.2f} mm towards {d:.1f} deg)"

    def summary(self) -> str:
        """One line: the figure, its size, its stops and its length."""
        away = [self.polar(a) for a, _ in self.stops if self.polar(a)[1] > 1e-9]
        stops = ", ".join(f"{m:g} mm towards {d:g}" for d, m in _unique(away))
        speed = f" at {self.speed_mm_s:g} mm/s" if math.isfinite(self.speed_mm_s) else ""
        return (
            f"{self.name} path of {self.bend_mm:g} mm{speed}: {self.periods} periods "
            f"({self.periods * PERIOD_S:.2f} s), {len(self.stops)} stops, away from rest at {stops or 'none'}"
        )

    def metadata(self) -> dict[str, object]:
        """The path for a recording's scenario."""
        return {
            "summary": self.summary(),
            "figure": self.name, "bend_mm": float(self.bend_mm), "speed_mm_s": float(self.speed_mm_s),
            "periods": int(self.periods), "period_s": PERIOD_S,
            "stops": [{"first_period": int(a), "last_period": int(b),
                       "direction_deg": round(self.polar(a)[0], 6), "bend_mm": round(self.polar(a)[1], 6)}
                      for a, b in self.stops],
            "bends_mm": [[round(float(x), 6), round(float(y), 6)] for x, y in self.bends],
        }  # fmt: skip


def _unique(points: Sequence[tuple[float, float]]) -> list[tuple[float, float]]:
    out: list[tuple[float, float]] = []
    for d, m in points:
        p = (round(d, 3), round(m, 3))
        if p not in out:
            out.append(p)
    return out


def _stops(bends: np.ndarray) -> tuple[tuple[int, int], ...]:
    """Runs of periods where the bend does not change, as (first, last) boundary indices."""
    still = np.all(np.abs(np.diff(bends, axis=0)) < 1e-12, axis=1)
    out = []
    k = 0
    while k < len(still):
        if still[k]:
            j = k
            while j + 1 < len(still) and still[j + 1]:
                j += 1
            out.append((k, j + 1))
            k = j + 1
        else:
            k += 1
    return tuple(out)


def velocity_path(
    velocity_mm_s: np.ndarray, name: str = "command", start_mm: Sequence[float] = (0.0, 0.0)
) -> TipPath:
    """A path from a joystick-like bend-velocity command ``(v_x, v_y)`` per 10 ms period (mm/s).

    Raises
    ------
    ValueError
        A command that is not a finite array of shape (periods, 2).
    """
    v = np.asarray(velocity_mm_s, dtype=float)
    if v.ndim != 2 or v.shape[1] != 2 or not len(v) or not np.all(np.isfinite(v)):
        raise ValueError(f"a bend-velocity command is a finite array of shape (periods, 2), got {v.shape}")
    bends = np.vstack([np.asarray(start_mm, dtype=float), np.asarray(start_mm) + np.cumsum(v, 0) * PERIOD_S])
    bends[np.abs(bends) < 1e-12] = 0.0
    size = float(np.max(np.hypot(bends[:, 0], bends[:, 1])))
    return TipPath(name, size, bends, _stops(bends))


def _leg(a: np.ndarray, b: np.ndarray, speed: float) -> np.ndarray:
    """A straight leg from ``a`` to ``b`` at ``speed`` (whole periods, the speed adjusted to arrive)."""
    n = max(1, round(float(np.hypot(*(b - a))) / speed / PERIOD_S))
    f = np.arange(1, n + 1)[:, None] / n
    return a + (b - a) * f


def _hold(b: np.ndarray, seconds: float) -> np.ndarray:
    return np.repeat(b[None, :], max(1, round(seconds / PERIOD_S)), axis=0)


def _at(direction_deg: float, bend_mm: float) -> np.ndarray:
    r = math.radians(direction_deg)
    return np.array([bend_mm * math.cos(r), bend_mm * math.sin(r)])


def figure_path(
    figure: str,
    bend_mm: float,
    speed_mm_s: float = 100.0,
    hold_s: float = 1.5,
    lead_s: float = 0.3,
    seed: int = 0,
    turn_deg: float = 0.0,
) -> TipPath:
    """A scripted or seeded figure of bends, from rest back to rest, with stops (deterministic).

    - ``square``: the corners ``bend_mm`` towards 0, 90, 180 and 270 deg (each tendon in turn), straight
      edges; out from rest to the first corner, round the square, back to rest;
    - ``star``: out to ``bend_mm`` and back to rest in 8 directions, 0, 45, ... 315 deg;
    - ``circle``: out to ``bend_mm`` towards 0 deg, once round the circle counter-clockwise at the speed,
      back to rest;
    - ``random``: a joystick-like command: six moves to random bends inside the disc of ``bend_mm``
      (``seed``), each with a smooth (Hann) speed profile peaking at up to ``speed_mm_s``, then back to rest;
    - ``line``: out to ``bend_mm`` towards 0 deg and back to rest (an arm whose tendons do not surround its
      backbone bends only towards the directions they face: two tendons, for one).

    ``turn_deg`` turns the whole figure about the backbone (the line's direction, the square's first corner).

    Every leg is followed by a stop of ``hold_s`` (the circle stops only before and after going round); the
    path starts with ``lead_s`` at rest.

    Raises
    ------
    ValueError
        An unknown figure, or a non-positive size, speed or hold.
    """
    if figure not in FIGURES:
        raise ValueError(f"path must be one of {', '.join(FIGURES)}, got {figure!r}")
    for what, value in (("bend_mm", bend_mm), ("speed_mm_s", speed_mm_s), ("hold_s", hold_s)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{what} must be > 0, got {value!r}")
    rest = np.zeros(2)
    parts = [_hold(rest, lead_s)]

    def go(points: Sequence[np.ndarray]) -> None:
        here = rest
        for p in [*points, rest]:
            parts.extend([_leg(here, p, speed_mm_s), _hold(p, hold_s)])
            here = p

    if figure == "line":
        go([_at(0, bend_mm)])
    elif figure == "square":
        go([_at(d, bend_mm) for d in (0, 90, 180, 270, 0)])
    elif figure == "star":
        go([p for d in range(0, 360, 45) for p in (_at(d, bend_mm), rest)][:-1])
    elif figure == "circle":
        start = _at(0, bend_mm)
        n = max(8, round(2 * math.pi * bend_mm / speed_mm_s / PERIOD_S))
        arc = np.array([_at(360.0 * j / n, bend_mm) for j in range(1, n + 1)])
        arc[-1] = start
        parts += [_leg(rest, start, speed_mm_s), _hold(start, hold_s), arc, _hold(start, hold_s),
                  _leg(start, rest, speed_mm_s), _hold(rest, hold_s)]  # fmt: skip
    else:
        rng = np.random.default_rng(seed)
        here = rest
        targets = [_at(float(rng.uniform(0, 360)), bend_mm * math.sqrt(float(rng.uniform(0.05, 1.0))))
                   for _ in range(6)]  # fmt: skip
        for p in [*targets, rest]:
            distance = float(np.hypot(*(p - here)))
            peak = float(rng.uniform(0.5, 1.0)) * speed_mm_s
            n = max(round(2.0 * distance / peak / PERIOD_S), 4)
            w = np.cumsum(np.hanning(n + 2)[1:-1])
            parts += [here + (p - here) * (w / w[-1])[:, None], _hold(p, hold_s)]
            here = p
    bends = np.vstack(parts)
    if turn_deg:
        if not math.isfinite(turn_deg):
            raise ValueError(f"turn_deg must be finite, got {turn_deg!r}")
        c, s = math.cos(math.radians(turn_deg)), math.sin(math.radians(turn_deg))
        bends = bends @ np.array([[c, s], [-s, c]])
    bends[np.abs(bends) < 1e-12] = 0.0
    return TipPath(figure, float(bend_mm), bends, _stops(bends), float(speed_mm_s))


# --- the statics along the path --------------------------------------------------------------------------
def _length(path: TipPath) -> np.ndarray:
    """The bend's path length (mm) at every boundary."""
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path.bends, axis=0).T))])


def _knots(path: TipPath, knot_mm: float) -> np.ndarray:
    """Boundaries where the statics is solved: every ``knot_mm`` of path length, every stop, the ends."""
    if not (math.isfinite(knot_mm) and knot_mm > 0):
        raise ValueError(f"knot_mm must be > 0, got {knot_mm!r}")
    cells = np.floor(_length(path) / knot_mm + 1e-9)
    picks = {0, path.periods, *np.flatnonzero(np.diff(cells) != 0) + 1}
    for a, b in path.stops:
        picks |= {a, b}
    return np.array(sorted(picks))


def _bend_eq(twin: SpatialRig, bend: np.ndarray, start: SpatialEquilibrium | None) -> SpatialEquilibrium:
    """The bend's equilibrium, continued from ``start``; solved afresh where the continuation fails.

    Continuing along a square's edge from its corner (a tendon that faced the corner side-on is pulled past
    it), the solver can leave the branch and report a pull-out no fresh solve finds, or not converge (the
    four-tendon twin pre-pulled one step, the square of 5 mm at 200 mm/s, 3.95 mm towards 18.4 deg:
    111.7 N from the corner's state, 8.53 N from its own); a pull-out the fresh solve finds too is refused
    as before.
    """
    m = float(np.hypot(*bend))
    # at rest any direction is the rest: tendon 1's, which it faces (0 deg may face no tendon)
    d = math.degrees(math.atan2(bend[1], bend[0])) if m > 1e-9 else twin.tendons[0].angle_deg
    try:
        return bend_equilibrium(twin, d, m, start=start)
    except (ValueError, RuntimeError):
        if start is None:
            raise
        return bend_equilibrium(twin, d, m)


def _commands(twin: SpatialRig, path: TipPath, knots: np.ndarray) -> tuple[np.ndarray, list]:
    """Every stepper's command (m) at every boundary, and the knots' states.

    Solved at the knots, linear in the path's length between them.
    """
    eqs: list[SpatialEquilibrium] = []
    eq = None
    for k in knots:
        eq = _bend_eq(twin, path.bends[k], eq)
        eqs.append(eq)
    at_knots = np.array([e.command for e in eqs])
    length = _length(path)
    cmd = np.empty((path.periods + 1, at_knots.shape[1]))
    for j, (a, b) in enumerate(zip(knots[:-1], knots[1:], strict=True)):
        span = length[b] - length[a]  # linear in the path's length between two knots (0 over a stop)
        f = (length[a : b + 1] - length[a]) / span if span > 0 else np.zeros(b - a + 1)
        cmd[a : b + 1] = at_knots[j] + f[:, None] * (at_knots[j + 1] - at_knots[j])
    return cmd, eqs


def interpolation_error(
    rig: RigFile, path: TipPath, knot_mm: float = 1.0, spatial: SpatialRig | None = None
) -> float:
    """The largest error (steps) of the linear interpolation between the statics' knots.

    Against the statics solved at the midpoint boundary of every pair of knots more than one period apart.
    """
    twin = spatial_rig(rig) if spatial is None else spatial
    knots = _knots(path, knot_mm)
    cmd, eqs = _commands(twin, path, knots)
    mm = np.asarray(derived(rig).mm_per_step) * 1e-3
    worst = 0.0
    for j, (a, b) in enumerate(zip(knots[:-1], knots[1:], strict=True)):
        if b - a < 2:
            continue
        mid = (a + b) // 2
        exact = _bend_eq(twin, path.bends[mid], eqs[j]).command
        worst = max(worst, float(np.max(np.abs(exact - cmd[mid]) / mm)))
    return worst


# --- the plan --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StreamPlan:
    """A tip path turned into every tendon's set-points, with the static tensions along it.

    Attributes
    ----------
    path : TipPath
    units : numpy.ndarray
        Set-points in board units, shape (periods, tendons).
    setpoints_mm_s : numpy.ndarray
        The same as cable speeds (mm/s, + pulls), what :func:`helpers.rig.stream.stream` takes.
    positions : numpy.ndarray
        Each tendon's planned position (steps from rest, the integrated set-points) at every boundary,
        shape (periods + 1, tendons).
    stop_steps : tuple of tuple of int
        Each stop's whole steps (the task-space policy: rounded, trimmed to the floor).
    trimmed : tuple of tuple of int
        Steps each stop's trimming pulled each tendon in.
    tension_n : numpy.ndarray
        The static tensions (rotors free) at every boundary's planned positions, N.
    tip_mm : numpy.ndarray
        Where the statics puts the tip there (mm, the clamp frame), shape (periods + 1, 3).
    floor_n : float
        The rig file's tension floor, N.
    knot_mm : float
        The statics' knot spacing along the path.
    board_units, board_setpoints_mm_s : numpy.ndarray
        What the board is sent: ``units`` (``setpoints_mm_s``) with a pre-pull's periods before them (the
        pull, its settling) and after them (the let-out, one tendon at a time); ``units`` without a pre-pull.
    """

    path: TipPath
    units: np.ndarray
    setpoints_mm_s: np.ndarray
    positions: np.ndarray
    stop_steps: tuple[tuple[int, ...], ...]
    trimmed: tuple[tuple[int, ...], ...]
    tension_n: np.ndarray
    tip_mm: np.ndarray
    floor_n: float
    knot_mm: float
    board_units: np.ndarray
    board_setpoints_mm_s: np.ndarray
    margin_n: float = 0.0
    """The margin above the floor the stops were trimmed to, N."""
    interpolated: int = 0
    """Boundaries in motion whose command was interpolated between knots (not solved there)."""
    prepull: int = 0
    """Steps every tendon is pulled in before the path and let out after it (:func:`plan_stream`); 0: none.
    ``positions``, ``stop_steps`` and ``tension_n`` count from the pre-pulled rest."""
    offset: int = 0
    """The board's periods before the path's first (the pre-pull and its settling; 0 without one)."""

    def stop_counts(self) -> list[tuple[int, ...]]:
        """Every stop's whole steps as the board counts them (from the rest before any pre-pull)."""
        return [tuple(int(v) + self.prepull for v in s) for s in self.stop_steps]

    def board_where(self, r: int) -> str:
        """Where boundary ``r`` of the board's set-points lies (a row of :func:`board_path`).

        The path's :meth:`TipPath.where`, or the pre-pull before it, or the let-out (or the shaper's tail)
        after it.
        """
        k = r - self.offset
        if k < 0:
            return f"the pre-pull (t = {k * PERIOD_S:.2f} s, before the path's period 0)"
        if k <= self.path.periods:
            return self.path.where(k)
        t = f"t = {k * PERIOD_S:.2f} s"
        return (f"the let-out ({t}, after the path's period {self.path.periods})" if self.prepull
                else f"the shaper's tail ({t}, after the path's period {self.path.periods})")  # fmt: skip

    def least_tension(self) -> list[tuple[float, int]]:
        """Each tendon's least planned static tension and the boundary where it is."""
        return [(float(self.tension_n[k, i]), int(k))
                for i, k in enumerate(np.argmin(self.tension_n, axis=0))]  # fmt: skip

    def lines(self, rig: RigFile) -> list[str]:
        """One line per tendon: its range of set-points (positions, speeds), its least planned tension."""
        mm = derived(rig).mm_per_step
        out = []
        for i, (t, k) in enumerate(self.least_tension()):
            lo, hi = float(self.positions[:, i].min()), float(self.positions[:, i].max())
            v = self.setpoints_mm_s[:, i]
            out.append(
                f"tendon {i + 1}: positions {lo:+.2f} to {hi:+.2f} steps ({lo * mm[i]:+.2f} to "
                f"{hi * mm[i]:+.2f} mm; its travel {Limits.of(rig).travel_text(i)}), speeds {v.min():+.1f} "
                f"to {v.max():+.1f} mm/s; least static tension "
                f"{t:.2f} N at {self.path.where(k)} (floor {self.floor_n:.2f} N, margin "
                f"{t - self.floor_n:+.2f} N)"
            )
        return out

    def metadata(self) -> dict[str, object]:
        """The plan for a recording's scenario (beside the path's)."""
        return {
            "stop_steps": [list(s) for s in self.stop_steps],
            "trimmed_steps": [list(s) for s in self.trimmed],
            "planned_min_tension_n": [round(t, 6) for t, _ in self.least_tension()],
            "tension_floor_n": self.floor_n, "margin_n": self.margin_n, "knot_mm": self.knot_mm,
            "interpolated_periods": self.interpolated, "prepull_steps": self.prepull,
            "prepull_periods": self.offset,
            "release_periods": len(self.board_units) - self.offset - len(self.units),
        }  # fmt: skip


def _whole_steps(
    twin: SpatialRig, command_m: np.ndarray, mm_m: np.ndarray, floor: float, start: SpatialEquilibrium
) -> tuple[np.ndarray, np.ndarray, SpatialEquilibrium]:
    """The task-space policy at a stop: whole steps, a tendon below the floor pulled in (<= 3 steps)."""
    steps = np.round(command_m / mm_m).astype(int)
    trimmed = np.zeros(len(steps), dtype=int)
    eq = equilibrium(twin, steps * mm_m, rotor="free", start=start)
    while True:
        short = np.flatnonzero((eq.tension < floor) & (trimmed < MAX_TRIM_STEPS))
        if not short.size:
            return steps, trimmed, eq
        i = int(short[np.argmin(eq.tension[short])])
        steps[i] += 1
        trimmed[i] += 1
        eq = equilibrium(twin, steps * mm_m, rotor="free", start=start)


def _units(x_steps: np.ndarray, path: TipPath, stop_steps: list[np.ndarray]) -> np.ndarray:
    """Cumulative set-point units per boundary: rounded, and at a stop rounded to the side it comes from."""
    cum = np.rint(x_steps * UNITS_PER_STEP)
    for (a, b), s in zip(path.stops, stop_steps, strict=True):
        for i, target in enumerate(s):
            exact = target * UNITS_PER_STEP
            lo, hi = math.floor(exact + 1e-9), math.ceil(exact - 1e-9)
            before = cum[:a, i]
            away = before[(before < lo) | (before > hi)]
            # the last position before the stop off its two candidates says which side the tendon comes from
            if away.size:
                cum[a : b + 1, i] = hi if away[-1] < exact else lo
            else:  # it has stood there since the start (or the last stop): it stays
                cum[a : b + 1, i] = before[-1] if a else hi
    return cum


MAPPINGS = ("statics", "kinematic")
"""How :func:`plan_stream` turns bends into cable: the statics (the task-space policy), or the
constant-curvature cable lengths of every tendon (no statics: the antagonists pay out as much as the pulled
take in; a comparison, and the floor check's test: it leaves the tendon opposite a bend short)."""


def plan_stream(
    rig: RigFile,
    path: TipPath,
    knot_mm: float = 1.0,
    spatial: SpatialRig | None = None,
    mapping: str = "statics",
    margin_n: float = 0.0,
    prepull: int = 0,
) -> StreamPlan:
    """Every tendon's set-points for a tip path, the static tensions checked against the floor (module doc).

    Parameters
    ----------
    rig : RigFile
        A rig file with several tendons.
    path : TipPath
        From rest (its first boundary at bend 0).
    knot_mm : float
        Path length between the statics' knots, mm of bend.
    spatial : SpatialRig, optional
        The twin of ``rig`` at its own rest, never pre-pulled (default
        :func:`~helpers.virtual.spatial.from_rig.spatial_rig`).
    mapping : {"statics", "kinematic"}
        :data:`MAPPINGS`; with ``"kinematic"`` every tendon's cable is ``b (r_i / r_mean) cos(beta - a_i)``
        and a stop's steps are only rounded (the floor is still checked by the statics).
    margin_n : float
        At the stops, trim every tendon up to the floor plus this margin (N; 0: ``plan_move``'s policy), for
        the ringing on arrival: a tendon the rounding leaves just above the floor (1.18 N beside a bend of
        10 mm towards a tendon of the four-tendon rig) dips below it as the arm settles.
    prepull : int
        Every tendon pulled this many whole steps in before the path and let out after it, as a move's
        pre-pull (0 to :data:`~helpers.research.task_shaping.MAX_PREPULL_STEPS`; module docstring): the path
        is planned on the pre-pulled twin (:func:`~helpers.research.task_shaping.pretensioned`), its rest that
        pre-pulled rest; the board is sent the pull, :data:`PREPULL_SETTLE_PERIODS` at rest, the path, and the
        let-out (``board_units``).

    Raises
    ------
    SafetyError
        A tendon below the floor by statics at some period, a rest pretension below the floor, a tendon the
        statics load to its stepper's pull-out, or a set-point over the stream's speed limit: one line naming
        the tendon and the figure.
    ValueError
        A path that does not start at rest, a bad ``knot_mm``, a pre-pull out of range or on an arm whose
        tendons do not balance (pulling every tendon in would bend it).
    """
    if float(np.hypot(*path.bends[0])) > 1e-9:
        raise ValueError(f"a tip stream starts at rest: the path starts at bend {path.polar(0)[1]:.2f} mm")
    if isinstance(prepull, bool) or not isinstance(prepull, int | np.integer) or not \
            0 <= prepull <= MAX_PREPULL_STEPS:  # fmt: skip
        raise ValueError(f"prepull must be a whole number of steps in 0-{MAX_PREPULL_STEPS}, got {prepull!r}")
    twin = spatial_rig(rig) if spatial is None else spatial
    if prepull:
        twin = pretensioned(rig, twin, int(prepull))
    floor = float(rig.arm.tension_floor_n)
    what = f"the {path.name} path ({path.bend_mm:g} mm)"
    for i, t in enumerate(rig.tendons):
        if t.pretension_n < floor:
            raise SafetyError(
                f"tendon {i + 1}: its rest pretension {t.pretension_n:.2f} N is below the tension floor "
                f"{floor:.2f} N ([arm] tension_floor_n): {what} would start with it short"
            )
    if not (math.isfinite(margin_n) and margin_n >= 0):
        raise ValueError(f"margin_n must be >= 0 N, got {margin_n!r}")
    if mapping not in MAPPINGS:
        raise ValueError(f"mapping must be one of {', '.join(MAPPINGS)}, got {mapping!r}")
    mm_m = np.asarray(derived(rig).mm_per_step, dtype=float) * 1e-3
    knots = _knots(path, knot_mm)
    stop_steps, trims = [], []
    if mapping == "statics":
        try:
            cmd, eqs = _commands(twin, path, knots)
            for a, _b in path.stops:
                if path.polar(a)[1] <= 1e-9:  # at rest: position 0, every tendon at its pretension
                    stop_steps.append(np.zeros(rig.n_tendons, dtype=int))
                    trims.append(np.zeros(rig.n_tendons, dtype=int))
                    continue
                j = int(np.searchsorted(knots, a))
                s, tr, _ = _whole_steps(twin, cmd[a], mm_m, floor + margin_n, eqs[j])
                stop_steps.append(s)
                trims.append(tr)
        except ValueError as exc:  # the statics' pull-out refusal names the tendon
            raise SafetyError(f"{what} refused: {exc}") from None
    else:
        r = np.array([t.offset_mm for t in twin.tendons])
        e = (r / r.mean())[None, :] * np.vstack([np.cos(twin.angles), np.sin(twin.angles)])
        cmd = path.bends @ e * 1e-3
        eqs = None
        for a, _b in path.stops:
            stop_steps.append(np.round(cmd[a] / mm_m).astype(int))
            trims.append(np.zeros(rig.n_tendons, dtype=int))
    x = cmd / mm_m  # steps
    # the whole steps at the stops, the difference blended in over the motion before each stop
    corr = np.zeros_like(x)
    anchors = [(0, np.zeros(x.shape[1]))]
    for (a, b), s in zip(path.stops, stop_steps, strict=True):
        anchors += [(a, s - x[a]), (b, s - x[b])]
    if anchors[-1][0] != path.periods:
        anchors.append((path.periods, anchors[-1][1]))
    ks = np.array([k for k, _ in anchors], dtype=float)
    ds = np.array([d for _, d in anchors])
    idx = np.arange(path.periods + 1)
    for i in range(x.shape[1]):
        corr[:, i] = np.interp(idx, ks, ds[:, i])
    # the board counts from the rest before the pre-pull: whole set-point units there, and at every stop on
    # the side the count comes from
    cum = _units(x + corr + prepull, path, [s + prepull for s in stop_steps])
    cum[0] = math.ceil(prepull * UNITS_PER_STEP - 1e-9)  # the pull's units: the count reaches the pre-pull
    units = np.diff(cum, axis=0).astype(np.int64)
    mm_s = units * hs.STEPS_PER_S_PER_UNIT * (mm_m * 1e3)
    _refuse_too_fast(units, rig, path, what)
    SetpointSource(mm_s, rig).check_all()  # the speed limit, one line naming the tendon and the set-point
    positions = cum / UNITS_PER_STEP - prepull
    tension, tip = _tensions(twin, positions * mm_m, knots, eqs, what, path)
    check_floor(tension, floor, path, what)
    board = _prepulled(units, cum[0].astype(np.int64), cum[-1].astype(np.int64))
    return StreamPlan(
        path=path, units=units, setpoints_mm_s=mm_s, positions=positions,
        stop_steps=tuple(tuple(int(v) for v in s) for s in stop_steps),
        trimmed=tuple(tuple(int(v) for v in t) for t in trims), tension_n=tension, tip_mm=tip, floor_n=floor,
        knot_mm=float(knot_mm), board_units=board,
        board_setpoints_mm_s=board * hs.STEPS_PER_S_PER_UNIT * (mm_m * 1e3), margin_n=float(margin_n),
        interpolated=_interpolated(path, knots) if mapping == "statics" else 0, prepull=int(prepull),
        offset=PREPULL_SETTLE_PERIODS + 1 if prepull else 0,
    )  # fmt: skip


PREPULL_SETTLE_PERIODS = round(PREPULL_SETTLE_MS / 1e3 / PERIOD_S)
"""Periods at rest after a stream's pre-pull, before the path (a move's
:data:`~helpers.research.task_shaping.PREPULL_SETTLE_MS`)."""

RELEASE_GAP_PERIODS = round(RELEASE_GAP_MS / 1e3 / PERIOD_S)
"""Periods at rest after each tendon's let-out (a move's
:data:`~helpers.research.task_shaping.RELEASE_GAP_MS`)."""


def _prepulled(units: np.ndarray, pull: np.ndarray, end: np.ndarray) -> np.ndarray:
    """The board's set-points for a pre-pulled path (``units``); ``units`` alone without a pre-pull.

    The pull (``pull`` units on every tendon in one period), the settling, the path's ``units``, then each
    tendon's ``end`` units let out in one period, one tendon at a time
    (:func:`~helpers.research.task_shaping.release_order`), every let-out followed by its gap at rest.

    """
    if not pull.any():
        return units
    n = units.shape[1]
    rows = [pull[None, :], np.zeros((PREPULL_SETTLE_PERIODS, n), dtype=np.int64), units]
    for j in release_order(n):
        out = np.zeros((1 + RELEASE_GAP_PERIODS, n), dtype=np.int64)
        out[0, j] = -end[j]
        rows.append(out)
    return np.vstack(rows).astype(np.int64)


def _interpolated(path: TipPath, knots: np.ndarray) -> int:
    held = np.zeros(path.periods + 1, dtype=bool)
    for a, b in path.stops:
        held[a : b + 1] = True
    held[knots] = True
    return int(np.count_nonzero(~held))


def check_floor(
    tension_n: np.ndarray,
    floor_n: float,
    path: TipPath,
    what: str,
    where: Callable[[int], str] | None = None,
    how: str = "by statics",
) -> None:
    """Refuse static tensions (one row per boundary) with a tendon below the floor.

    ``where(k)`` names row ``k`` (default the path's :meth:`TipPath.where`); ``how`` says what the tensions
    are (the plan's, or those at the board's whole steps).

    Raises
    ------
    SafetyError
        ``tendon i: <what> leaves it at T N <how> at period k (t = ... s, bend ...), below the tension floor
        F N ([arm] tension_floor_n)``: the first period with a tendon short, its lowest tendon; when the least
        tension is elsewhere, ``(the least: L N, tendon j at ...)`` after it.
    """
    tension_n = np.asarray(tension_n)
    where = path.where if where is None else where
    low = np.argwhere(tension_n < floor_n)
    if low.size:
        k = int(low[0, 0])
        row = tension_n[k]
        i = int(np.argmin(row))
        kl, il = np.unravel_index(int(np.argmin(tension_n)), tension_n.shape)
        least = ("" if tension_n[kl, il] >= row[i] else
                 f" (the least: {tension_n[kl, il]:.2f} N, tendon {il + 1} at {where(int(kl))})")  # fmt: skip
        raise SafetyError(
            f"tendon {i + 1}: {what} leaves it at {row[i]:.2f} N {how} at {where(k)}, below the "
            f"tension floor {floor_n:.2f} N ([arm] tension_floor_n){least}"
        )


def _tensions(
    twin: SpatialRig, u_m: np.ndarray, knots: np.ndarray, eqs: list | None, what: str, path: TipPath
) -> tuple[np.ndarray, np.ndarray]:
    """Static tensions (N) and tip (mm, clamp frame) at every boundary (rotors free).

    Each solved from the bend's state at the knot before (repeated rows reused).
    """
    out = np.empty_like(u_m)
    tip = np.empty((len(u_m), 3))
    nearest = np.searchsorted(knots, np.arange(len(u_m)), side="right") - 1
    eq = None
    last = None
    for k, row in enumerate(u_m):
        if last is None or np.any(row != last):
            # from the bend's state at the knot at or before (the command there, within a step or so), or
            # (no statics along the path) from the last boundary's
            start = eq if eqs is None else eqs[nearest[k]]
            try:
                eq = equilibrium(twin, row, rotor="free", start=start)
            except ValueError as exc:
                raise SafetyError(f"{what} refused at {path.where(k)}: {exc}") from None
            last = row
        out[k] = eq.tension
        tip[k] = eq.tip * 1e3
    return out, tip


class TooFast(SafetyError):
    """A figure whose set-points exceed the stream's speed limit at its speed.

    A slower one may fit: the set-points of a line scale with the figure's speed; at a corner the statics
    make them scale less.
    """


def _refuse_too_fast(units: np.ndarray, rig: RigFile, path: TipPath, what: str) -> None:
    """Refuse set-points over the stream's speed limit, naming the fastest tendon and the speed that fits."""
    limit = hs.v_max(derived(rig).min_interval_us)
    peak = np.abs(units).max(axis=0) if len(units) else np.zeros(rig.n_tendons)
    i = int(np.argmax(peak))
    if peak[i] <= limit:
        return
    unit = hs.STEPS_PER_S_PER_UNIT * derived(rig).mm_per_step[i]
    who = f"tendon {i + 1}" if rig.n_tendons > 1 else "the cable"
    raise TooFast(
        f"{what} at {path.speed_mm_s:g} mm/s refused: {who} would run at {peak[i] * unit:.1f} mm/s, over the "
        f"stream's speed limit of {limit * unit:.1f} mm/s"
    )


def check_plan(
    plan: StreamPlan,
    rig: RigFile,
    shaper: Shaper | hs.StreamShaper | None,
    start: Sequence[int] | None = None,
) -> CheckedStream:
    """The stream's own checks of the plan (travel, speed, the board's shaped motion) before any byte.

    Raises
    ------
    SafetyError
        As :func:`~helpers.rig.stream.check_stream`: one line naming the tendon and the figure.
    """
    start = tuple(start) if start is not None else (0,) * rig.n_tendons
    return check_stream(plan.board_setpoints_mm_s, rig, start, shaper)


def board_path(plan: StreamPlan, rig: RigFile, shaper: Shaper | hs.StreamShaper | None) -> np.ndarray:
    """Every tendon's step count at every boundary of what the board is sent, by the board's own planner.

    :attr:`StreamPlan.board_units`: the path, and a pre-pull's periods before and after it; the shaped
    motion, from rest.

    Row ``k`` is the count ``(k + 2)`` periods after ``STREAM`` (row ``r`` of the set-points, taken at tick
    ``r + 1``, drives ``[(r + 2) T, (r + 3) T)``); a last row is the count when the board has finished (the
    shaper's delays carry the motion past the set-points). Shape (board periods + 2, tendons); the path's
    boundary ``k`` is row ``k + plan.offset`` (:meth:`StreamPlan.board_where` names a row).
    """
    board = hs.board_shaper(shaper)
    d = derived(rig)
    v_max = hs.v_max(d.min_interval_us)  # the build's set-point limit
    run = hs.AxesRun(board, (0,) * rig.n_tendons, d.travel_steps, d.release_steps, v_max)
    hs.drive_axes(run, plan.board_units.tolist())
    edges = np.append((np.arange(len(plan.board_units) + 1) + 2) * hs.PERIOD_TICKS, np.iinfo(np.int64).max)
    out = np.zeros((len(edges), rig.n_tendons), dtype=np.int64)
    for i, p in enumerate(run.planners):
        ticks, dirs = np.asarray(p.ticks, dtype=np.int64), np.asarray(p.dirs, dtype=np.int64)
        where = np.searchsorted(ticks, edges, side="left")  # steps strictly before each edge
        out[:, i] = np.concatenate([[0], np.cumsum(dirs)])[where]
    return out


def board_counts(
    plan: StreamPlan, rig: RigFile, shaper: Shaper | hs.StreamShaper | None
) -> list[tuple[int, ...]]:
    """Every tendon's step count at the end of each stop, by the board's own planner (:func:`board_path`).

    The count at the last boundary of a stop (a stop lasts longer than the shaper), or when the board has
    finished for a stop that ends a path without a pre-pull; counted from the rest before any pre-pull (to
    compare with :meth:`StreamPlan.stop_counts`).
    """
    counts = board_path(plan, rig, shaper)
    n = plan.path.periods
    return [tuple(int(c) for c in counts[plan.offset + b if b < n or plan.prepull else -1])
            for _a, b in plan.path.stops]  # fmt: skip


def board_tensions(
    plan: StreamPlan, rig: RigFile, shaper: Shaper | hs.StreamShaper | None, spatial: SpatialRig | None = None
) -> np.ndarray:
    """The static tensions (rotors free, N) at the board's whole-step counts at every boundary.

    Rows as :func:`board_path`'s (a pre-pull, its let-out and the shaper's tail included), solved on the twin
    of ``rig`` at its own rest (``spatial``: never a pre-pulled twin; the counts include the pre-pull). The
    board's count follows the shaped cable with a one-step hysteresis, and one step is 2-3 N on a tendon of
    the four-tendon rigs, so these can fall well below the plan's (:attr:`StreamPlan.tension_n`, at the
    integrated set-points) while the tendons move: a tendon paid out from its pretension is a step ahead of
    its cable. :func:`check_whole_steps` checks them against the floor.
    """
    twin = spatial_rig(rig) if spatial is None else spatial
    mm_m = np.asarray(derived(rig).mm_per_step, dtype=float) * 1e-3
    counts = board_path(plan, rig, shaper)
    out = np.empty(counts.shape)
    eq = None
    cache: dict[tuple[int, ...], np.ndarray] = {}
    for k, row in enumerate(counts):
        key = tuple(int(c) for c in row)
        if key not in cache:
            eq = equilibrium(twin, row * mm_m, rotor="free", start=eq)
            cache[key] = eq.tension
        out[k] = cache[key]
    return out


def check_whole_steps(
    plan: StreamPlan, rig: RigFile, shaper: Shaper | hs.StreamShaper | None, spatial: SpatialRig | None = None
) -> np.ndarray:
    """Refuse a plan whose static tensions at the board's whole-step counts leave a tendon below the floor.

    :func:`board_tensions` at every boundary the board runs (a pre-pull and its let-out included), checked
    with :func:`check_floor`; returns them, shape as :func:`board_path`'s.

    Raises
    ------
    SafetyError
        ``tendon i: the <figure> path (B mm) leaves it at T N by statics at the board's whole steps at period
        k (t = ..., bend ...), below the tension floor F N ([arm] tension_floor_n)``, the least after it.
    """
    tension = board_tensions(plan, rig, shaper, spatial)
    what = f"the {plan.path.name} path ({plan.path.bend_mm:g} mm)"
    if plan.prepull:
        what += f" pre-pulled {plan.prepull} step(s)"
    check_floor(tension, plan.floor_n, plan.path, what, plan.board_where,
                "by statics at the board's whole steps")  # fmt: skip
    return tension


REST_TRIM_LEAD_PERIODS = 4
"""Periods a set-point is sent ahead of the board's taking it (``stream``'s ``lead_periods``): the samples
a rest trim measures end about this much before its set-point."""

REST_TRIM_SETTLE_PERIODS = 20
"""Periods after a stop's shaped motion has ended before a rest trim's window may begin (the shaped stop's
ringing, its residual a few % of an unshaped stop's, decays about 1/e in this time at the dominant mode's
damping; what is left averages out over the window)."""


def rest_trim_points(plan: StreamPlan, shaper: Shaper | hs.StreamShaper | None, window_s: float,
                     ) -> list[int]:  # fmt: skip
    """The board's set-points where the stream's rests are trimmed (``record tip-stream --trim``).

    One per stop long enough for it, counted on the board's set-points (:attr:`StreamPlan.board_units`): the
    trim's set-point ``j`` leaves the stop's end the shaper's duration and :data:`REST_TRIM_SETTLE_PERIODS`
    (its own shaped motion ends and settles before the next leg), and its window of ``window_s`` before it
    (less :data:`REST_TRIM_LEAD_PERIODS`) begins no earlier than the stop's shaped motion ended and settled.
    Every set-point from the stop's start to ``j`` is zero (checked: a rest).
    """
    shaped = math.ceil(hs.board_shaper(shaper).duration_s / PERIOD_S - 1e-9) + 1
    window = math.ceil(window_s / PERIOD_S - 1e-9)
    out = []
    for a, b in plan.path.stops:
        first, last = plan.offset + a, plan.offset + b  # the stop's set-points: first .. last - 1
        j = last - shaped - REST_TRIM_SETTLE_PERIODS
        if j - REST_TRIM_LEAD_PERIODS - window < first + shaped + REST_TRIM_SETTLE_PERIODS:
            continue
        if np.any(plan.board_units[first : j + 1]):
            raise ValueError(f"the stop at set-points {first}-{last - 1} moves a tendon: not a rest")
        out.append(j)
    return out


def rest_trims(
    plan: StreamPlan, rig: RigFile, shaper: Shaper | hs.StreamShaper | None, window_s: float,
    spatial: SpatialRig | None = None,
) -> list[Rest]:  # fmt: skip
    """The rests a stream is trimmed at (``record tip-stream --trim``), the planner's targets and coupling.

    At each of :func:`rest_trim_points`, the board's whole-step counts there (:func:`board_path`): the targets
    are the statics' tensions at them (rotors free, on the twin of ``rig`` at its own rest, as
    :func:`board_tensions`), and the tension per step is the statics' change of every tendon when each is
    pulled one step more (an opposed pair's two tendons both rise: the backbone bends).
    """
    twin = spatial_rig(rig) if spatial is None else spatial
    mm_m = np.asarray(derived(rig).mm_per_step, dtype=float) * 1e-3
    counts = board_path(plan, rig, shaper)
    out = []
    for j in rest_trim_points(plan, shaper, window_s):
        here = equilibrium(twin, counts[j] * mm_m, rotor="free")
        per_step = np.column_stack([
            equilibrium(twin, (counts[j] + e) * mm_m, rotor="free", start=here).tension - here.tension
            for e in np.eye(rig.n_tendons, dtype=np.int64)
        ])  # fmt: skip
        out.append(Rest(j, tuple(round(float(t), 6) for t in here.tension), np.round(per_step, 6)))
    return out


# --- the shaper ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StreamDesign:
    """The one shaper of a tip stream, and the modes it was designed from."""

    shaper: Shaper | None
    name: str
    omega_d: float | None = None
    zeta: float | None = None
    points: tuple[tuple[float, float, float, float], ...] = ()
    """Each stop's ``(direction_deg, bend_mm, dominant omega_d, dominant zeta)``."""

    def describe(self) -> str:
        """One line: the shaper and the modes it used."""
        if self.shaper is None:
            return "unshaped (the board holds the unit shaper)"
        times = ", ".join(f"{1e3 * t:.1f}" for t in self.shaper.times)
        spread = ", ".join(f"{w:.2f}" for _, _, w, _ in self.points)
        return (
            f"{self.name}: impulses at {times} ms, every tendon; designed from the mean of the direction "
            f"map's dominant mode at the path's {len(self.points)} stop(s) away from rest ({spread} rad/s): "
            f"omega_d = {self.omega_d:.3f} rad/s, zeta = {self.zeta:.4f}"
        )

    def metadata(self) -> dict[str, object]:
        """The design for a recording's scenario."""
        if self.shaper is None:
            return {"shaper": "none"}
        return shaper_metadata(
            self.shaper, self.name, mode="mean over the path's stops of the direction map's dominant mode",
            omega_d_rad_s=float(self.omega_d), zeta=float(self.zeta),
            stops=[{"direction_deg": d, "bend_mm": m, "omega_d_rad_s": w, "zeta": z}
                   for d, m, w, z in self.points],
        )  # fmt: skip


def stream_design(
    rig: RigFile, path: TipPath, shaper: str = "none", spatial: SpatialRig | None = None
) -> StreamDesign:
    """The paper's ZV or ZVD from the mean of the direction map's dominant mode at the path's stops.

    Each distinct stop away from rest gives the map's ``dominant_omega_d_rad_s`` and ``dominant_zeta``
    (:func:`~helpers.virtual.spatial.direction_map.frequency_map`); the shaper is designed for their mean
    (a path that never leaves rest uses the map at rest towards 0 deg).
    """
    if shaper not in SHAPERS:
        raise ValueError(f"shaper must be one of {', '.join(SHAPERS)}, got {shaper!r}")
    if shaper == "none":
        return StreamDesign(None, "none")
    twin = spatial_rig(rig) if spatial is None else spatial
    stops = _unique([path.polar(a) for a, _ in path.stops if path.polar(a)[1] > 1e-9]) or [(0.0, 0.0)]
    points = []
    for d, m in stops:
        row = frequency_map(twin, (float(d),), (float(m),), n_modes=1).iloc[0]
        points.append((d, m, float(row["dominant_omega_d_rad_s"]), float(row["dominant_zeta"])))
    omega_d = float(np.mean([p[2] for p in points]))
    zeta = float(np.mean([p[3] for p in points]))
    zv, zvd = design_tdfs(omega_d, zeta)
    return StreamDesign(zv if shaper == "zv" else zvd, shaper, omega_d, zeta, tuple(points))
