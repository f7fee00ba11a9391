"""Moves in task space: a bend direction and magnitude turned into every tendon's whole steps by the statics.

A **move** is a bend (``docs/spatial_twin.md``, section 5): a direction ``direction_deg`` around the backbone
(0 = towards tendon 1, counter-clockwise seen from the tip's side) and a magnitude ``bend_mm`` (mm of cable).
:func:`plan_move` turns it into every tendon's displacement by the spatial twin's statics
(:func:`helpers.virtual.spatial.direction_map.bend_equilibrium`, the frequency map's own definition of a
bend), with this **pretension policy**:

1. every tendon facing the direction is pulled as the map pulls it; every other tendon is held at its rest
   pretension, the statics saying how far its spool turns (an antagonist pays out);
2. each tendon's stepper command (the statics' spool displacement plus its rotor's change of lag) is rounded
   to whole steps, and the static tensions are solved again with the steppers commanded there (rotors free);
3. a tendon whose planned tension is below the rig file's floor (``[arm] tension_floor_n``) is pulled in one
   more step and the tensions solved again, at most :data:`MAX_TRIM_STEPS` times per tendon (rounding can
   leave a held tendon short by a few tenths of a newton: one step is about 2.7 N).

Refused before any byte, in one line naming the tendon and the figure
(:class:`~helpers.rig.safety.SafetyError`, exit status 3, ``docs/safety.md``): a tendon whose rest pretension
is below the floor, a plan that leaves a tendon below the floor after the trimming, a tendon the statics load
to its stepper's pull-out tension, a direction no tendon faces, and (:func:`check_travel`) a displacement past
a tendon's travel from where it stands: ``-release..travel`` steps, position 0 being the rest and ``release``
the rig file's ``[hardware] release_mm`` below it (a rig without one cannot pay a tendon out from rest).

:func:`move_programme` makes the coordinated programme (``MSEG``/``WAIT`` items of a
:class:`~helpers.board.programmes.Programme`): a lead-in, the move out (every tendon's steps in the
same window, the lead tendon at the given speed), a hold, the move back, a tail; a shaper convolves every
tendon's move with the same impulses (each constant piece of the shaped velocity one item).
:func:`move_design` designs the paper's ZV/ZVD from the direction map's dominant mode at the bend.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from helpers.board.programmes import Dwell, Move, Programme
from helpers.paper.shapers import Shaper, design_tdfs
from helpers.rig.safety import SafetyError
from helpers.rigfile import RigFile
from helpers.rigfile.derived import derived, lead_tendon
from helpers.virtual.spatial.direction_map import bend_command, bend_equilibrium, frequency_map
from helpers.virtual.spatial.from_rig import spatial_rig
from helpers.virtual.spatial.rig import SpatialRig
from helpers.virtual.spatial.statics import equilibrium

__all__ = [
    "MovePlan",
    "MoveDesign",
    "shaper_metadata",
    "plan_move",
    "check_travel",
    "move_design",
    "move_programme",
    "MAX_TRIM_STEPS",
    "SHAPERS",
]

MAX_TRIM_STEPS = 3
"""Most steps the pretension policy pulls one tendon in to bring it up to the floor."""

SHAPERS = ("none", "zv", "zvd")
"""The shapers a task-space move can run (the paper's two)."""


@dataclass(frozen=True)
class MovePlan:
    """A planned move: every tendon's whole steps and the static tensions they give.

    Attributes
    ----------
    direction_deg, bend_mm : float
        The bend.
    steps : tuple of int
        Each tendon's displacement in whole steps from the move's start (+ pulls).
    displacement_mm : tuple of float
        ``steps`` x the tendon's mm per step.
    command_mm : tuple of float
        The statics' stepper command before rounding, mm.
    tension_n : tuple of float
        The static tensions with every stepper commanded to ``steps`` (rotors free), N.
    floor_n : float
        The rig file's tension floor, N.
    pulled : tuple of bool
        Which tendons face the direction (pulled as the map pulls them; the others held at pretension).
    trimmed : tuple of int
        Steps the pretension policy added to each tendon to keep it at the floor.
    lead : int
        The tendon (0-based) that pulls most towards the bend
        (:func:`helpers.rigfile.derived.lead_tendon`): its cable moves at the programme's speed.
    """

    direction_deg: float
    bend_mm: float
    steps: tuple[int, ...]
    displacement_mm: tuple[float, ...]
    command_mm: tuple[float, ...]
    tension_n: tuple[float, ...]
    floor_n: float
    pulled: tuple[bool, ...]
    trimmed: tuple[int, ...]
    lead: int

    def lines(self) -> list[str]:
        """One line per tendon: its displacement, its planned static tension against the floor."""
        out = []
        for i, (n, mm, t) in enumerate(zip(self.steps, self.displacement_mm, self.tension_n, strict=True)):
            role = "pulled" if self.pulled[i] else "held at its pretension"
            if not self.pulled[i] and n < 0:
                role = "paid out below its rest, held at its pretension"
            trim = f", {self.trimmed[i]} step(s) pulled in to keep the floor" if self.trimmed[i] else ""
            out.append(
                f"tendon {i + 1}: {n:+d} steps ({mm:+.2f} mm, {role}{trim}); static tension {t:.2f} N "
                f"(floor {self.floor_n:.2f} N, margin {t - self.floor_n:+.2f} N)"
            )
        return out


def shaper_metadata(shaper: Shaper, name: str, **design: object) -> dict[str, object]:
    """A shaped move's or stream's design for a recording's scenario (every design class of the research).

    Parameters
    ----------
    shaper : Shaper
        The shaper (an unshaped design records ``{"shaper": "none"}`` instead).
    name : str
        The design's command-line name.
    **design
        What the design was made from, in the order recorded (after ``shaper``, before the impulses).

    Returns
    -------
    dict
        ``shaper``, the ``design`` fields, ``amplitudes`` and ``times_s``.
    """
    return {
        "shaper": name, **design, "amplitudes": [float(a) for a in shaper.amplitudes],
        "times_s": [float(t) for t in shaper.times],
    }  # fmt: skip


@dataclass(frozen=True)
class MoveDesign:
    """A shaper designed for a move, and the mode it was designed from."""

    shaper: Shaper | None
    name: str
    omega_d: float | None = None
    zeta: float | None = None
    tendon: int | None = None
    """The tendon (0-based) whose tension's dominant mode the design used."""
    higher: tuple[tuple[float, float], ...] = ()
    """``(omega_d, zeta)`` of each mode above the dominant pair a ZV was convolved in for (none: empty)."""

    def describe(self) -> str:
        """One line: the shaper and the mode it used."""
        if self.shaper is None:
            return "unshaped (every tendon's move a constant-speed ramp)"
        times = ", ".join(f"{1e3 * t:.1f}" for t in self.shaper.times)
        return (
            f"{self.name}: impulses at {times} ms, designed from the direction map's dominant mode of tendon "
            f"{self.tendon + 1}'s tension at the bend (rotors free): omega_d = {self.omega_d:.3f} rad/s, "
            f"zeta = {self.zeta:.4f}"
        )

    def metadata(self) -> dict[str, object]:
        """The design for a recording's scenario."""
        if self.shaper is None:
            return {"shaper": "none"}
        modes = [{"omega_d_rad_s": o, "zeta": z} for o, z in self.higher]
        higher = {"higher_modes": modes} if modes else {}
        return shaper_metadata(
            self.shaper, self.name, mode="dominant mode of the lead tendon's tension (direction map)",
            tendon=int(self.tendon) + 1, omega_d_rad_s=float(self.omega_d), zeta=float(self.zeta), **higher,
        )  # fmt: skip


def _twin(rig: RigFile, spatial: SpatialRig | None) -> SpatialRig:
    return spatial_rig(rig) if spatial is None else spatial


def _check_bend(direction_deg: float, bend_mm: float) -> None:
    if not (math.isfinite(direction_deg) and math.isfinite(bend_mm)):
        raise ValueError(f"direction and bend must be finite, got {direction_deg!r} deg, {bend_mm!r} mm")
    if bend_mm <= 0:
        raise ValueError(f"bend_mm must be > 0 mm (a move), got {bend_mm!r}")


def plan_move(
    rig: RigFile, direction_deg: float, bend_mm: float, spatial: SpatialRig | None = None
) -> MovePlan:
    """Every tendon's whole steps for a bend, by the twin's statics and the pretension policy (module doc).

    Parameters
    ----------
    rig : RigFile
        The rig file (tendons, steps, the floor ``[arm] tension_floor_n``).
    direction_deg, bend_mm : float
        The bend: direction (deg) and magnitude (mm of cable, > 0).
    spatial : SpatialRig, optional
        The twin of ``rig`` (default :func:`~helpers.virtual.spatial.from_rig.spatial_rig`).

    Raises
    ------
    SafetyError
        A tendon below the floor at rest or in the plan, at its stepper's pull-out, or no tendon facing the
        direction: one line naming the tendon and the figure.
    ValueError
        A non-finite direction or bend, or a bend <= 0.
    """
    _check_bend(direction_deg, bend_mm)
    twin = _twin(rig, spatial)
    floor = float(rig.arm.tension_floor_n)
    where = f"{bend_mm:g} mm towards {direction_deg:g} deg"
    for i, t in enumerate(rig.tendons):
        if t.pretension_n < floor:
            raise SafetyError(
                f"tendon {i + 1}: its rest pretension {t.pretension_n:.2f} N is below the tension floor "
                f"{floor:.2f} N ([arm] tension_floor_n): the move {where} would start with it short"
            )
    try:
        u_pull, pulled = bend_command(twin, direction_deg, bend_mm)
    except ValueError as exc:
        raise SafetyError(f"move {where} refused: {exc}") from None
    mm = np.array(derived(rig).mm_per_step)
    d = derived(rig)
    u_kin = u_pull * 1e3  # the map's pull of the facing tendons, mm
    over = np.flatnonzero(np.round(u_kin / mm) > np.array(d.travel_steps))
    if over.size:  # beyond the travel already by the map's pull: refuse before the statics
        i = int(over[0])
        raise SafetyError(
            f"tendon {i + 1}: the move {where} pulls it {u_kin[i]:.2f} mm, past its travel of "
            f"{d.travel_steps[i] * mm[i]:.2f} mm ({d.travel_steps[i]} steps)"
        )
    try:
        eq = bend_equilibrium(twin, direction_deg, bend_mm)
        command = eq.command * 1e3
        steps = np.round(command / mm).astype(int)
        trimmed = np.zeros(rig.n_tendons, dtype=int)
        tension = equilibrium(twin, steps * mm * 1e-3, rotor="free", start=eq).tension
        while True:
            short = np.flatnonzero((tension < floor) & (trimmed < MAX_TRIM_STEPS))
            if not short.size:
                break
            i = int(short[np.argmin(tension[short])])
            steps[i] += 1
            trimmed[i] += 1
            tension = equilibrium(twin, steps * mm * 1e-3, rotor="free", start=eq).tension
    except ValueError as exc:  # the statics' pull-out refusal names the tendon
        raise SafetyError(f"move {where} refused: {exc}") from None
    low = np.flatnonzero(tension < floor)
    if low.size:
        i = int(low[np.argmin(tension[low])])
        raise SafetyError(
            f"tendon {i + 1}: the move {where} leaves it at {tension[i]:.2f} N by statics, below the tension "
            f"floor {floor:.2f} N ([arm] tension_floor_n), even pulled in {trimmed[i]} step(s)"
        )
    return MovePlan(
        direction_deg=float(direction_deg), bend_mm=float(bend_mm), steps=tuple(int(n) for n in steps),
        displacement_mm=tuple(float(v) for v in steps * mm), command_mm=tuple(float(v) for v in command),
        tension_n=tuple(float(v) for v in tension), floor_n=floor, pulled=tuple(bool(p) for p in pulled),
        trimmed=tuple(int(v) for v in trimmed),
        lead=lead_tendon(rig.tendons, direction_deg),
    )  # fmt: skip


def check_travel(plan: MovePlan, rig: RigFile, start: Sequence[int] | None = None) -> tuple[int, ...]:
    """Refuse a plan that takes a tendon past its travel from ``start`` (default every tendon at 0, the rest).

    A tendon's travel is ``-release_steps..travel_steps`` (the rig file's ``[hardware] release_mm`` below
    position 0 = its rest, ``travel_mm`` above). Returns the positions at the bend (steps from zero).

    Raises
    ------
    SafetyError
        ``tendon i: ... needs n steps (mm) from position p, past its travel of -R-N steps``.
    """
    d = derived(rig)
    start = tuple(start) if start is not None else (0,) * rig.n_tendons
    if len(start) != rig.n_tendons:
        raise SafetyError(f"{len(start)} start positions for the rig's {rig.n_tendons} tendons")
    ends = []
    for i, (p, n) in enumerate(zip(start, plan.steps, strict=True)):
        travel, release = d.travel_steps[i], d.release_steps[i]
        if not -release <= p + n <= travel:
            why = ""
            if p + n < -release:
                why = (
                    ": the rig's position 0 is its rest (every tendon at its pretension), so a tendon cannot "
                    "pay out from there ([hardware] release_mm = 0)"
                    if not release
                    else f": it pays out at most {release} steps ({release * d.mm_per_step[i]:.2f} mm, "
                    "[hardware] release_mm) below its rest"
                )
            raise SafetyError(
                f"tendon {i + 1}: the move {plan.bend_mm:g} mm towards {plan.direction_deg:g} deg needs "
                f"{n:+d} steps ({n * d.mm_per_step[i]:+.2f} mm) from position {p}, past its travel of "
                f"{-release if release else 0}-{travel} steps{why}"
            )
        ends.append(p + n)
    return tuple(ends)


def move_design(
    rig: RigFile,
    direction_deg: float,
    bend_mm: float,
    shaper: str = "none",
    spatial: SpatialRig | None = None,
) -> MoveDesign:
    """The shaper of a move: the paper's ZV or ZVD from the direction map's dominant mode at the bend.

    The mode is the map's ``dominant_omega_d_rad_s`` / ``dominant_zeta`` at ``(direction_deg, bend_mm)``: the
    mode with the largest weight in the lead tendon's tension (rotors free) after a step of the command that
    moves the bend on (:func:`helpers.virtual.spatial.direction_map.frequency_map`).
    """
    if shaper not in SHAPERS:
        raise ValueError(f"shaper must be one of {', '.join(SHAPERS)}, got {shaper!r}")
    if shaper == "none":
        return MoveDesign(None, "none")
    _check_bend(direction_deg, bend_mm)
    twin = _twin(rig, spatial)
    row = frequency_map(twin, (float(direction_deg),), (float(bend_mm),), n_modes=1).iloc[0]
    omega_d, zeta = float(row["dominant_omega_d_rad_s"]), float(row["dominant_zeta"])
    u, _ = bend_command(twin, direction_deg, 1.0)
    zv, zvd = design_tdfs(omega_d, zeta)
    return MoveDesign(zv if shaper == "zv" else zvd, shaper, omega_d, zeta, int(np.argmax(u)))


def _pieces(
    steps: Sequence[int], window_s: float, shaper: Shaper | None, sign: int, min_interval_us: float = 0.0
) -> list[Move | Dwell]:
    """The items of one move: every tendon's ramp convolved with the shaper, each constant piece an item.

    A piece too short for the whole steps its rounding gives it (a step faster than ``min_interval_us``: two
    of the shaper's edges a fraction of a millisecond apart, as where a ramp's end meets a later impulse) is
    merged into the next piece, its steps and its time with it; the last piece is never merged.
    """
    amps, times = ((1.0,), (0.0,)) if shaper is None else (tuple(shaper.amplitudes), tuple(shaper.times))
    edges_us = sorted({round(1e6 * t) for t in times} | {round(1e6 * (t + window_s)) for t in times})
    n = np.asarray(steps, dtype=float)

    def reached(t_us: int) -> np.ndarray:
        frac = sum(
            a * min(max((t_us * 1e-6 - t) / window_s, 0.0), 1.0) for a, t in zip(amps, times, strict=True)
        )
        return np.round(sign * n * frac).astype(int)

    items: list[Move | Dwell] = []
    carry_us = 0
    pending = np.zeros(len(n), dtype=int)
    pairs = list(zip(edges_us[:-1], edges_us[1:], strict=True))
    for k, (a, b) in enumerate(pairs):
        counts = reached(b) - reached(a) + pending
        width = b - a + carry_us
        if not counts.any():  # a pause between impulses: whole ms, the rest carried into the next item
            ms, carry_us = divmod(width, 1000)
            if ms:
                items.append(Dwell(ms))
            continue
        if k < len(pairs) - 1 and np.abs(counts).max() * min_interval_us > width:
            pending, carry_us = counts, width  # too fast for the board: into the next piece
            continue
        pending[:] = 0
        carry_us = 0
        items.append(Move(int(width), tuple(int(c) for c in counts)))
    return items


def move_programme(
    plan: MovePlan,
    rig: RigFile,
    speed_mm_s: float = 200.0,
    shaper: Shaper | None = None,
    t_up_s: float = 1.0,
    t_down_s: float = 8.0,
    t_end_s: float = 12.0,
) -> Programme:
    """The coordinated Up-hold-Down programme of a move (starting and ending where the tendons stand).

    A lead-in dwell to ``t_up_s``; the move out: every tendon's steps in one window, the lead tendon's cable
    at ``speed_mm_s`` (convolved with ``shaper`` if given); a hold to ``t_down_s``; the move back (the
    mirror); a tail to ``t_end_s``. The board's checks
    (:func:`helpers.rig.safety.check_programme`) are the rig's, at run time.
    """
    if not (math.isfinite(speed_mm_s) and speed_mm_s > 0):
        raise ValueError(f"speed_mm_s must be > 0, got {speed_mm_s!r}")
    if not 0 <= t_up_s < t_down_s < t_end_s:
        raise ValueError(
            f"times must satisfy 0 <= t_up < t_down < t_end, got {t_up_s}, {t_down_s}, {t_end_s}"
        )
    limit = rig.hardware.speed_limit_mm_s
    if speed_mm_s > limit:
        raise ValueError(f"the lead tendon at {speed_mm_s:g} mm/s exceeds the rig's speed limit: at most "
                         f"{limit:g} mm/s (speed_limit_mm_s)")  # fmt: skip
    mm = derived(rig).mm_per_step
    lead = plan.lead
    window_s = abs(plan.steps[lead]) * mm[lead] / speed_mm_s
    # at the rig's speed limit, the rounded speed may ask for a step a fraction of a us too fast: the fastest
    # the board takes (as the pulse's quantiser does)
    window_s = max(window_s, max(map(abs, plan.steps)) * derived(rig).min_interval_us / 1e6)
    duration = window_s + (float(shaper.times[-1]) if shaper is not None else 0.0)
    if t_up_s + duration > t_down_s or t_down_s + duration > t_end_s:
        raise ValueError(f"the move lasts {duration:.3f} s: it does not fit between t_up, t_down and t_end")
    fastest = derived(rig).min_interval_us
    up = _pieces(plan.steps, window_s, shaper, +1, fastest)
    down = _pieces(plan.steps, window_s, shaper, -1, fastest)

    def span_ms(items: list[Move | Dwell]) -> float:
        return sum(it.duration_us for it in items) / 1000

    longest = rig.hardware.max_dwell_ms

    def dwell(ms: int) -> list[Move | Dwell]:  # split at the board's longest dwell
        whole, rest = divmod(ms, longest) if ms > 0 else (0, 0)
        return [Dwell(longest)] * whole + ([Dwell(rest)] if rest else [])

    items: list[Move | Dwell] = dwell(round(1000 * t_up_s))
    items += up
    items += dwell(round(1000 * t_down_s - 1000 * t_up_s - span_ms(up)))
    items += down
    tail = round(1000 * t_end_s - 1000 * t_down_s - span_ms(down))
    ends_us = 1000 * tail + sum(it.duration_us for it in items)  # the roundings may end it past t_end: trim
    tail -= max(0, math.ceil((ends_us - 1e6 * t_end_s) / 1000 - 1e-9))
    items += dwell(tail)
    return Programme(tuple(items))
