"""``python -m helpers --rig FILE tune`` on a rig with several tendons: map, design, verify over directions.

The map is over direction and bend, the designs come from it, and the verification is on a grid of
task-space moves.

The one-tendon ``tune`` (:mod:`helpers.research.tune`) measures the arm's modes along its one cable; a rig
with several tendons bends its tip in any direction (``docs/task_space.md``), and its modes depend on the
direction and the magnitude of the bend. So, on the rig (the in-process virtual rig by default):

1. **measure the map**: an unshaped move (:func:`helpers.research.task_space.plan_move`) to each bend of the
   grid (:data:`DIRECTIONS_DEG` x :data:`BENDS_MM`); the dominant mode (``omega_d``, ``zeta``) of the lead
   tendon's tension is identified from the ring-down in the hold after the move out (:func:`identify_hold`:
   the FFT peak and the decay of the envelope), beside the twin's prediction at the same
   bend (``frequency_map``'s dominant mode: what the twin predicts, not measured);
2. **design** (:data:`SYSTEMS`): unshaped; the paper's ZV and ZVD designed **once**, from the mode measured
   at the reference bend (:data:`REFERENCE`: 10 mm towards tendon 1, as one would tune along one tendon);
   and the **direction-scheduled** ZV and ZVD, each move's designed from the map's mode at its own direction
   and bend (:func:`scheduled_mode`: the map interpolated, periodic in the direction, linear in the bend);
   and ``zvd-zv34``, the fixed ZVD convolved with a ZV on each mode of the arm's second bending pair at the
   move (the twin's third and fourth modes, kept in the map as ``predicted_higher`` and interpolated as the
   dominant mode is: the hold's ring-down identifies the dominant mode only);
3. **verify** each design on every bend of the grid, ``repetitions`` runs each: the residual vibration of
   every tendon's tension and of the tip after the Up and Down motions, and the samples below the tension
   floor (:func:`helpers.research.residuals.recording_residuals`: the lead tendon that pulls most towards the
   bend, the pre-pull apart from the move);
4. **report**: per direction and design, the worst residual of the lead tendon and of the tip over the
   bends and repetitions, the slack samples, the move's duration; the wall time of the whole run.

Every move of a design lasts its ramp plus the shaper's last impulse time: ZV and the scheduled ZV last
about half a period longer than unshaped, ZVD one period, ``zvd-zv34`` ZVD's and half a period of each
mode of the pair (63-96 ms longer than the ZVD; durations are in the report; comparisons across families are
not at equal duration).
"""

from __future__ import annotations

import contextlib
import itertools
import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from helpers import __version__ as HELPERS_VERSION
from helpers.base.jsonfile import atomic_write, write_json
from helpers.base.locks import folder_lock
from helpers.base.paths import repo_path
from helpers.base.tables import to_markdown
from helpers.paper.identify import fft_peak
from helpers.paper.shapers import Shaper, design_tdfs
from helpers.recordings import Recording, RecordingExists
from helpers.research.lane_runs import in_lanes, record_in_lanes
from helpers.research.residuals import recording_residuals
from helpers.research.task_shaping import (
    MAX_PREPULL_STEPS,
    design_move,
    higher_modes,
    prepull_programme,
    pretensioned,
    simulate_move,
    verify_auto,
    with_higher_modes,
)
from helpers.research.task_space import MoveDesign, MovePlan, check_travel, move_programme, plan_move
from helpers.rig import Rig
from helpers.rig.safety import SafetyError
from helpers.rig.trim import TensionGuard
from helpers.rigfile import RigFile
from helpers.virtual.plant import LANE_WIDTHS
from helpers.virtual.spatial.direction_map import frequency_map, parse_values
from helpers.virtual.spatial.from_rig import spatial_rig
from helpers.virtual.spatial.plant import SpatialPlant

__all__ = [
    "DIRECTIONS_DEG", "BENDS_MM", "REFERENCE", "SYSTEMS", "SEARCH_BAND", "ENVELOPE_FLOOR", "MOVE_TIMES_S",
    "MapPoint", "scheduled_mode", "scheduled",
    "design_for", "run_move", "identify_hold", "measure_map", "verify", "SUMMARY_COLUMNS", "summarise",
    "tune_tendons", "choose_prepull", "tendon_folder", "run_tendons", "write_report", "reference", "grid",
]  # fmt: skip

DIRECTIONS_DEG = tuple(45.0 * k for k in range(8))
"""The grid's bend directions, deg (0 = towards tendon 1, counter-clockwise)."""

BENDS_MM = (10.0, 20.0)
"""The grid's bend magnitudes, mm of cable."""

REFERENCE = (0.0, 10.0)
"""(direction deg, bend mm) whose measured mode the fixed ZV and ZVD are designed from: 10 mm towards tendon 1
(at 0 deg on the shipped rigs; :func:`reference` gives a rig's)."""


def reference(rig: RigFile) -> tuple[float, float]:
    """The fixed designs' bend on ``rig``: :data:`REFERENCE`'s bend towards its tendon 1."""
    return float(rig.tendons[0].angle_deg % 360.0), REFERENCE[1]

SYSTEMS = ("unshaped", "zv", "zvd", "scheduled-zv", "scheduled-zvd", "auto", "zvd-zv34")
"""The designs verified, by the name each recording's scenario carries (``auto``: the automatic choice of
:mod:`helpers.research.task_shaping`, designed from the twin's modes and checked in it; ``zvd-zv34``: the
fixed ZVD convolved with a ZV on each mode of the second bending pair, the twin's third and fourth modes at
the move, :func:`helpers.research.task_shaping.higher_modes`, read off the map's ``predicted_higher``)."""

MOVE_TIMES_S = (1.5, 4.5, 8.0)
"""(move out, move back, end) of every tuning run, s: 1.5 s at rest first, so that the ringing a run leaves
has decayed (below 1 % at zeta 0.045, 25 rad/s) before the next run's first second, its noise floor."""

SPEED_MM_S = 200.0
"""The lead tendon's cable speed, mm/s (Table I's slower speed)."""


@dataclass(frozen=True)
class MapPoint:
    """The dominant mode at one bend: measured on the rig, and the twin's prediction."""

    direction_deg: float
    bend_mm: float
    omega_d: float
    zeta: float
    predicted_omega_d: float
    predicted_zeta: float
    recording: str
    predicted_split: tuple[float, float] = (math.nan, math.nan)
    """The twin's two lowest bending modes with every spool held, rad/s: the pair the bend splits."""
    predicted_higher: tuple[tuple[float, float], ...] = ()
    """The twin's modes above the dominant pair at the bend, ``(omega_d, zeta)`` lowest first (the second
    bending pair, :func:`helpers.research.task_shaping.higher_modes`; rotors free): predicted, not measured
    (the hold's ring-down identifies the dominant mode only)."""


def scheduled_mode(points: Sequence[MapPoint], direction_deg: float, bend_mm: float) -> tuple[float, float]:
    """The map's (omega_d, zeta) at a bend: linear between the grid's directions (periodic) and bends.

    Outside the grid's bends the nearest bend's values are used (no extrapolation).
    """
    w, z = scheduled(points, direction_deg, bend_mm, lambda p: (p.omega_d, p.zeta))
    return float(w), float(z)


def scheduled(
    points: Sequence[MapPoint], direction_deg: float, bend_mm: float,
    values: Callable[[MapPoint], Sequence[float]],
) -> np.ndarray:  # fmt: skip
    """``values`` of the map's points at a bend, interpolated as :func:`scheduled_mode` does."""
    cols = [f"v{i}" for i in range(len(values(points[0])))]
    table = pd.DataFrame([(p.direction_deg % 360.0, p.bend_mm, *values(p)) for p in points],
                         columns=["d", "b", *cols])  # fmt: skip
    ds = np.sort(table["d"].unique())
    bs = np.sort(table["b"].unique())
    grid = table.set_index(["d", "b"])
    d = direction_deg % 360.0
    i = int(np.searchsorted(ds, d, side="right")) - 1  # the grid's directions by index: no float modulo
    i0, i1 = i % len(ds), (i + 1) % len(ds)
    d0 = ds[i0] - (360.0 if i < 0 else 0.0)
    d1 = ds[i1] + (360.0 if i + 1 >= len(ds) else 0.0)
    fd = 0.0 if d1 == d0 else (d - d0) / (d1 - d0)
    b = min(max(bend_mm, bs[0]), bs[-1])
    j = min(int(np.searchsorted(bs, b, side="right")) - 1, len(bs) - 1)
    b0, b1 = bs[j], bs[min(j + 1, len(bs) - 1)]
    fb = 0.0 if b1 == b0 else (b - b0) / (b1 - b0)

    def at(k: int, bb: float) -> np.ndarray:
        return grid.loc[(ds[k], bb), cols].to_numpy(float)

    lo = (1 - fd) * at(i0, b0) + fd * at(i1, b0)
    hi = (1 - fd) * at(i0, b1) + fd * at(i1, b1)
    return (1 - fb) * lo + fb * hi


def design_for(
    system: str,
    points: Sequence[MapPoint],
    direction_deg: float,
    bend_mm: float,
    fixed_at: tuple[float, float] = REFERENCE,
) -> MoveDesign:
    """The design ``system`` (:data:`SYSTEMS`) of a move to a bend, from the measured map.

    The fixed designs use the map's mode at ``fixed_at`` (direction, bend: :func:`reference`), interpolated
    or clamped to the grid where the grid does not hold it.
    """
    if system not in SYSTEMS:
        raise ValueError(f"system must be one of {', '.join(SYSTEMS)}, got {system!r}")
    if system == "unshaped":
        return MoveDesign(None, "none")
    where = fixed_at if not system.startswith("scheduled") else (direction_deg, bend_mm)
    omega_d, zeta = scheduled_mode(points, *where)
    zv, zvd = design_tdfs(omega_d, zeta)
    if system == "zvd-zv34":  # the fixed ZVD and a ZV on each mode of the second bending pair at the move
        if any(not p.predicted_higher for p in points):
            raise ValueError("zvd-zv34 needs the map's predicted_higher at every point (a map measured "
                             "before it was kept has none: tune again)")  # fmt: skip
        flat = scheduled(points, direction_deg, bend_mm, lambda p: [v for m in p.predicted_higher for v in m])
        higher = tuple((float(flat[i]), float(flat[i + 1])) for i in range(0, len(flat), 2))
        shaper = with_higher_modes(zvd, higher, "ZVD * ZV * ZV (second bending pair)")
        return MoveDesign(shaper, system, omega_d, zeta, 0, higher)
    shaper: Shaper = zvd if system.endswith("zvd") else zv
    return MoveDesign(shaper, system, omega_d, zeta, 0)


def run_move(
    trig: Rig,
    plan: MovePlan,
    design: MoveDesign,
    target: Path,
    *,
    rate_hz: int = 1000,
    seed: int | None = None,
    reseed: Callable[[int], None] | None = None,
    replace: bool = False,
    extra: dict[str, Any] | None = None,
    prepull: int = 0,
) -> Recording:
    """Run one move from rest and save its recording (scenario ``kind`` "move" with the bend and design).

    ``prepull``: every tendon pulled that many steps in first and let out after
    (:func:`helpers.research.task_shaping.prepull_programme`); ``plan`` counts from there.
    """
    rig = trig.rig
    check_travel(plan, rig, tuple(p + prepull for p in trig.positions()))
    programme = move_programme(plan, rig, SPEED_MM_S, design.shaper, *MOVE_TIMES_S)
    programme, _, _ = prepull_programme(programme, prepull, rig.n_tendons)
    if reseed is not None and seed is not None:
        reseed(seed)
    scenario = {
        "kind": "move", "direction_deg": plan.direction_deg, "bend_mm": plan.bend_mm, "shaper": design.name,
        "design": design.metadata(), "speed_mm_s": SPEED_MM_S, "steps": list(plan.steps),
        "planned_tension_n": list(plan.tension_n), "tension_floor_n": plan.floor_n,
        "trimmed_steps": list(plan.trimmed), "noise_seed": seed, "prepull_steps": prepull,
        **(extra or {}),
    }  # fmt: skip
    # every move recorded whole, the unshaped reference too (it dips below the floor for 20-110 ms at 20 mm):
    # the verification counts every sample below the floor itself (below_floor) instead of the floor watch
    return trig.run(programme, path=target, scenario=scenario, rate_hz=rate_hz, tail_s=0.5, replace=replace,
                    progress=False, guard=TensionGuard(watch=False))  # fmt: skip


def _hold_window(rec: Recording, lead: int) -> tuple[float, float]:
    """The hold after the move out: from 0.1 s after the lead's last step to 0.05 s before the move back."""
    f = rec.frame
    t = f["t_s"].to_numpy(float)
    s = f[f"steps_{lead}"].to_numpy()
    changes = np.flatnonzero(np.diff(s) != 0)
    back = changes[t[changes] >= MOVE_TIMES_S[1] - 0.01]
    out = changes[t[changes] < MOVE_TIMES_S[1] - 0.01]
    return float(t[out[-1] + 1]) + 0.1, float(t[back[0]]) - 0.05


ENVELOPE_FLOOR = 0.2
"""Periods whose peak-to-peak is below this fraction of the largest are left out of the envelope's decay."""

SEARCH_BAND = (0.6, 1.5)
"""The FFT peak is searched between these multiples of the twin's predicted frequency at the bend."""


def identify_hold(rec: Recording, lead: int, omega0: float) -> tuple[float, float]:
    """(omega_d, zeta) of the lead tendon's tension in the hold after the move out.

    The frequency is the FFT peak of the hold (:func:`helpers.paper.identify.fft_peak`) within
    :data:`SEARCH_BAND` of ``omega0`` (the twin's prediction: the band keeps a harmonic out). The damping
    comes from the envelope: the peak-to-peak of each whole damped period of the hold, whose logarithm falls
    by ``sigma = zeta omega_n`` per second (a least-squares line through those above :data:`ENVELOPE_FLOOR`
    of the largest),
    ``zeta = sigma / sqrt(sigma^2 + omega_d^2)``. Not the paper's log decrement or the damped-sine fit: a
    bend between tendons excites two modes of close frequencies, whose beating is no single decay about one
    level (the log decrement refuses it, and the fit can wander off to another frequency); the
    period-by-period envelope takes both as one decay, which is what a single-mode design sees.
    """
    lo, hi = _hold_window(rec, lead)
    f = rec.frame
    inside = (f["t_s"] >= lo) & (f["t_s"] <= hi)
    t = f.loc[inside, "t_s"].to_numpy(float)
    y = f.loc[inside, f"tension_n_{lead}"].to_numpy(float)
    f0 = omega0 / (2 * math.pi)
    omega_d = float(fft_peak(t, y, f_min_hz=SEARCH_BAND[0] * f0, f_max_hz=SEARCH_BAND[1] * f0).omega_d)
    period = 2 * math.pi / omega_d
    edges = np.arange(t[0], t[-1] - period, period)
    mids = edges + period / 2
    ptp = np.array([np.ptp(y[(t >= a) & (t < a + period)]) for a in edges])
    keep = ptp >= ENVELOPE_FLOOR * ptp.max()  # the tail, where noise and harmonics hold the envelope up, out
    keep[: min(3, keep.size)] = True  # a fast decay: its first three periods
    if np.count_nonzero(keep) < 3:
        raise ValueError(f"the hold of {rec.path} rings for fewer than three periods: no decay to measure")
    sigma = -float(np.polyfit(mids[keep], np.log(ptp[keep]), 1)[0])
    return omega_d, sigma / math.hypot(sigma, omega_d)


def choose_prepull(
    rig: RigFile,
    directions: Sequence[float] = DIRECTIONS_DEG,
    bends: Sequence[float] = BENDS_MM,
    progress: Callable[[str], None] = lambda _line: None,
) -> tuple[int, list[str]]:
    """The fewest steps every tendon is pulled in before each move so that a ZVD keeps the floor everywhere.

    For ``k`` = 0, 1 .. :data:`~helpers.research.task_shaping.MAX_PREPULL_STEPS`: every bend of the grid,
    planned from the rest ``k`` steps in (:func:`~helpers.research.task_shaping.pretensioned`), shaped by the
    ZVD of the twin's dominant mode there, simulated in the twin (**simulated**; the tune's own designs come
    from the measured map later); the first ``k`` with no sample below the floor at any bend. The pretension
    is the same for every move of the tune (the unshaped ones included), so that every comparison is at one
    pretension. Where none does (or the tendons do not balance, so pulling all in bends the arm), the ``k``
    with the fewest samples below is taken and the report says so. Returns ``k`` and one line per ``k`` tried.
    """
    twin = spatial_rig(rig)
    plant = SpatialPlant(twin)
    lines = []
    best = (math.inf, 0)
    for k in range(MAX_PREPULL_STEPS + 1):
        try:
            pre = pretensioned(rig, twin, k)
        except ValueError as exc:  # tendons that do not balance: no pre-pull, the slack is reported as run
            lines.append(f"pre-pull {k} step(s): not possible ({exc})")
            progress(lines[-1])
            break
        worst: tuple[float, str] = (math.inf, "")
        below = 0
        for d in directions:
            for b in bends:
                plan = plan_move(rig, d, b, pre)
                shaping = design_move(rig, plan, "zvd", SPEED_MM_S, twin=pre)
                run = simulate_move(rig, plan, shaping.shaper, SPEED_MM_S, *MOVE_TIMES_S, twin=twin,
                                    plant=plant, prepull=k)  # fmt: skip
                least = run.least_n()
                below += int(run.below(plan.floor_n).sum())
                if least.min() < worst[0]:
                    worst = (
                        float(least.min()),
                        f"tendon {int(np.argmin(least)) + 1}, {b:g} mm towards {d:g} deg",
                    )
        lines.append(f"pre-pull {k} step(s): ZVD at every bend, least {worst[0]:.2f} N ({worst[1]}), "
                     f"{below} samples below the floor (simulated)")  # fmt: skip
        progress(lines[-1])
        if below == 0:
            return k, lines
        best = min(best, (below, k))
    lines.append(f"no pre-pull keeps the floor at every bend: {best[1]} step(s), the fewest samples below it")
    progress(lines[-1])
    return best[1], lines


def measure_map(
    trig: Rig,
    folder: Path,
    directions: Sequence[float] = DIRECTIONS_DEG,
    bends: Sequence[float] = BENDS_MM,
    *,
    prepull: int = 0,
    seeds: Callable[[], int | None] = lambda: None,
    reseed: Callable[[int], None] | None = None,
    replace: bool = False,
    progress: Callable[[str], None] = lambda _line: None,
) -> list[MapPoint]:
    """Record an unshaped move to every bend and identify the lead tendon's dominant mode in its hold.

    The moves start from the rest ``prepull`` steps in, as the verified moves do: the map is the arm's at
    the pretension it runs at.
    """
    rig = trig.rig
    twin = pretensioned(rig, spatial_rig(rig), prepull)
    points = []
    for d in directions:
        for b in bends:
            plan = plan_move(rig, d, b, twin)
            name = f"map_d{d:g}_b{b:g}".replace(".", "p")
            rec = run_move(trig, plan, MoveDesign(None, "none"), folder / name, seed=seeds(), reseed=reseed,
                           replace=replace, extra={"purpose": "mode map"}, prepull=prepull)  # fmt: skip
            pred = frequency_map(twin, (d,), (b,), n_modes=2).iloc[0]
            omega_d, zeta = identify_hold(rec, plan.lead, float(pred["dominant_omega_d_rad_s"]))
            split = (float(pred["omega_d1_rad_s"]), float(pred["omega_d2_rad_s"]))
            points.append(MapPoint(d, b, omega_d, zeta, float(pred["dominant_omega_d_rad_s"]),
                                   float(pred["dominant_zeta"]), name, split,
                                   higher_modes(rig, twin, plan)))  # fmt: skip
            progress(f"map {d:g} deg, {b:g} mm: omega_d {omega_d:.3f} rad/s (twin predicts "
                     f"{points[-1].predicted_omega_d:.3f}), zeta {zeta:.4f}")  # fmt: skip
    return points


def _auto_design(rig: RigFile, plan: MovePlan, prepull: int) -> MoveDesign:
    """The automatic choice of :mod:`helpers.research.task_shaping` at the move, checked in the twin."""
    twin = spatial_rig(rig)
    pre = pretensioned(rig, twin, prepull)
    shaping = design_move(rig, plan, "auto", SPEED_MM_S, twin=pre)
    shaping = verify_auto(rig, plan, shaping, SPEED_MM_S, prepull, twin=twin)
    omega_d, zeta = shaping.modes[0]
    return MoveDesign(shaping.shaper, "auto", float(omega_d), float(zeta), int(shaping.lead))


def verify(
    trig: Rig,
    points: Sequence[MapPoint],
    folder: Path,
    repetitions: int,
    directions: Sequence[float] = DIRECTIONS_DEG,
    bends: Sequence[float] = BENDS_MM,
    systems: Sequence[str] = SYSTEMS,
    *,
    prepull: int = 0,
    seeds: Callable[[], int | None] = lambda: None,
    reseed: Callable[[int], None] | None = None,
    replace: bool = False,
    progress: Callable[[str], None] = lambda _line: None,
    lanes: int = 0,
) -> pd.DataFrame:
    """Run every design on every bend ``repetitions`` times; one row per run, motion and signal.

    ``lanes`` (0, the default: every run in ``trig``'s world, one after the other, each starting where the
    one before left the arm and the device clock): on the in-process virtual rig, each run in a fresh world of
    its own, up to ``lanes`` of them at once with their plants in the lanes of one kernel call
    (:mod:`helpers.research.lane_runs`; each world reseeded with the run's seed). Its recordings do not depend
    on ``lanes`` (1 to 8), and differ from the chained runs'. Hardware and the pseudo-terminal server ignore
    it.
    """
    if type(lanes) is not int or not 0 <= lanes <= max(LANE_WIDTHS):
        raise ValueError(f"lanes must be an integer in 0-{max(LANE_WIDTHS)}, got {lanes!r}")
    rig = trig.rig
    twin = pretensioned(rig, spatial_rig(rig), prepull)
    jobs = []
    for d in directions:
        for b in bends:
            plan = plan_move(rig, d, b, twin)
            for system in systems:
                design = (
                    _auto_design(rig, plan, prepull) if system == "auto"
                    else design_for(system, points, d, b, reference(rig))
                )  # fmt: skip
                for rep in range(1, repetitions + 1):
                    jobs.append((d, b, system, rep, plan, design))
    names = [f"{system}_d{d:g}_b{b:g}_r{rep}".replace(".", "p") for d, b, system, rep, _, _ in jobs]

    def record(r: Rig, job: tuple, name: str, seed: int | None) -> Recording:
        _, _, _, _, plan, design = job
        again = reseed if r is trig else (r.world.reseed if r.world is not None else None)
        return run_move(r, plan, design, folder / name, seed=seed, reseed=again, replace=replace,
                        prepull=prepull)  # fmt: skip

    if lanes and in_lanes(trig):
        def done(n: int) -> None:
            progress(f"verify: {n} run(s) in lanes")

        recs = record_in_lanes(trig, jobs, names, [seeds() for _ in jobs], record, lanes, done=done)
    else:
        recs = []
        for job, name in zip(jobs, names, strict=True):
            recs.append(record(trig, job, name, seeds()))
            d, b, system, rep = job[:4]
            if rep == repetitions:
                progress(f"verify {d:g} deg, {b:g} mm, {system}: {repetitions} run(s)")
    parts = []
    for (d, b, system, rep, _, design), name, rec in zip(jobs, names, recs, strict=True):
        duration = float(design.shaper.times[-1]) if design.shaper is not None else 0.0
        rows, _, _ = recording_residuals(rec)
        rows.insert(0, "repetition", rep)
        rows.insert(0, "system", system)
        rows.insert(0, "bend_mm", b)
        rows.insert(0, "direction_deg", d)
        rows["shaper_s"] = duration
        rows["shaper"] = design.shaper.name if design.shaper is not None else "none"
        rows["recording"] = name
        parts.append(rows)
    return pd.concat(parts, ignore_index=True)


SUMMARY_COLUMNS = (
    "direction_deg", "system", "lead_residual_n", "lead_residual_pct", "shaper_s", "least_tension_n",
    "below_floor", "tip_residual_mm", "tip_residual_pct",
)  # fmt: skip
"""The columns of :func:`summarise`, in its order (the report's, also for a summary read back from JSON)."""


def summarise(rows: pd.DataFrame) -> pd.DataFrame:
    """Per direction and design: the worst residuals, the slack samples, the shaper's added duration.

    The worst residual of the lead tendon (N, %) and of the tip (mm, %) over the bends, motions and
    repetitions; the least tension and the samples below the floor of every tendon.
    """
    lead = rows[rows["signal"] == "tendon " + rows["lead"].astype(str)]
    tip = rows[rows["signal"] == "tip"]
    tendons = rows[rows["unit"] == "N"]
    keys = ["direction_deg", "system"]
    out = lead.groupby(keys).agg(
        lead_residual_n=("residual", "max"),
        lead_residual_pct=("residual_pct", "max"),
        shaper_s=("shaper_s", "max"),
    )
    out["least_tension_n"] = tendons.groupby(keys)["least"].min()
    out["below_floor"] = tendons.groupby(keys)["below_floor"].sum()
    if not tip.empty:
        out["tip_residual_mm"] = tip.groupby(keys)["residual"].max()
        out["tip_residual_pct"] = tip.groupby(keys)["residual_pct"].max()
    return out.reset_index()


def tune_tendons(
    trig: Rig,
    folder: Path,
    repetitions: int = 3,
    *,
    directions: Sequence[float] = DIRECTIONS_DEG,
    bends: Sequence[float] = BENDS_MM,
    seeds: Callable[[], int | None] = lambda: None,
    reseed: Callable[[int], None] | None = None,
    replace: bool = False,
    progress: Callable[[str], None] = lambda _line: None,
    lanes: int = 0,
) -> dict[str, Any]:
    """Measure the map, verify every design on the grid, write ``verification.json``; return its document.

    ``lanes``: the verification runs in lanes (:func:`verify`); the map is measured in ``trig``'s world.
    """
    rig: RigFile = trig.rig
    start = time.perf_counter()
    prepull, prepull_lines = choose_prepull(rig, directions, bends, progress)
    points = measure_map(trig, folder / "map", directions, bends, prepull=prepull, seeds=seeds, reseed=reseed,
                         replace=replace, progress=progress)  # fmt: skip
    t_map = time.perf_counter() - start
    rows = verify(trig, points, folder / "verify", repetitions, directions, bends, prepull=prepull,
                  seeds=seeds, reseed=reseed, replace=replace, progress=progress, lanes=lanes)  # fmt: skip
    wall = time.perf_counter() - start
    summary = summarise(rows)
    document = {
        "format": "continuum-arm-tendon-verification", "version": 1, "rig": rig.name, "rig_hash": rig.hash,
        "host": {"helpers": HELPERS_VERSION},
        "source": dict(trig.source), "repetitions": repetitions, "directions_deg": list(directions),
        "bends_mm": list(bends), "reference": list(reference(rig)), "move_times_s": list(MOVE_TIMES_S),
        "speed_mm_s": SPEED_MM_S, "prepull_steps": prepull, "prepull_check": prepull_lines,
        "verify_lanes": lanes,
        "map": [p.__dict__ for p in points],
        "rows": rows.replace({math.nan: None}).to_dict(orient="records"),
        "summary": summary.replace({math.nan: None}).to_dict(orient="records"),
    }  # fmt: skip
    write_json(folder / "verification.json", document)
    write_report(document, folder)
    n_runs = len(rows["recording"].unique())
    progress(f"wall time: map {t_map:.1f} s, all {wall:.1f} s ({n_runs} verification runs)")
    document["wall_s"] = wall
    return document


def write_report(document: dict[str, Any], folder: Path) -> list[Path]:
    """The per-direction report of a verification document: ``tuning_report.md`` in ``folder``.

    (The table's numbers are ``verification.json``'s ``summary``: no CSV beside it, which ``data/`` keeps
    for recordings.)

    One row per direction and design (:func:`summarise`'s columns), and the pre-pull check's lines.
    """
    summary = pd.DataFrame(document["summary"])
    first = [c for c in SUMMARY_COLUMNS if c in summary.columns]  # the same order however the rows were read
    summary = summary[first + [c for c in summary.columns if c not in first]]
    kind = document["source"].get("kind", "hardware")
    grid = f"{len(document['directions_deg'])} directions x {len(document['bends_mm'])} bends"
    lines = [
        f"# Tuning report on '{document['rig']}' ({kind}; {document['repetitions']} run(s) per design and "
        f"bend, {grid})",
        "",
        f"Every move pre-pulled {document.get('prepull_steps', 0)} step(s):",
        "",
        *(f"- {line}" for line in document.get("prepull_check", [])),
        "",
        "Per direction and design: the worst residual of the lead tendon (N, % of its step) and of the tip "
        "(mm, %), the least tension and the samples below the floor of every tendon, the shaper's added "
        "duration (s).",
        "",
        to_markdown(summary, precision=3),
    ]
    folder.mkdir(parents=True, exist_ok=True)
    md = folder / "tuning_report.md"
    atomic_write(md, ("\n".join(lines) + "\n").encode())
    return [md]


def tendon_folder(data_dir: Path, rig: RigFile) -> Path:
    """Where ``tune`` on a rig with several tendons writes: ``<data>/tuning/tendons/<rig name>/``."""
    return data_dir / "tuning" / "tendons" / rig.name


def _faced(rig: RigFile, direction_deg: float) -> bool:
    return any(math.cos(math.radians(direction_deg - t.angle_deg)) > 1e-9 for t in rig.tendons)


def grid(rig: RigFile, directions: str | None, bends: str | None) -> tuple[tuple[float, ...], ...]:
    """The tune's directions and bends: the command line's, else the default grid's.

    ``--directions 0,45`` and ``--bends 10`` (or ``start:stop:step``); the default directions leave out those
    no tendon of ``rig`` faces.

    Raises
    ------
    ValueError
        One line: a list that is not numbers, a bend <= 0, a given direction no tendon faces.
    """
    ds = tuple(d for d in DIRECTIONS_DEG if _faced(rig, d))
    if directions is not None:
        ds = parse_values(directions, "--directions")
        for d in ds:
            if not _faced(rig, d):
                angles = ", ".join(f"{t.angle_deg:g}" for t in rig.tendons)
                raise ValueError(f"--directions: no tendon faces {d:g} deg (tendons at {angles} deg)")
    bs = BENDS_MM if bends is None else parse_values(bends, "--bends")
    if any(b <= 0 for b in bs):
        raise ValueError(f"--bends: every bend must be > 0 mm, got {bends!r}")
    return ds, bs


def run_tendons(args: Any, rig: RigFile) -> int:
    """``python -m helpers --rig FILE tune`` on a rig with several tendons (the module's steps 1-4)."""
    if args.reuse_map or args.minimax or args.grid != "table-i":
        raise ValueError(
            "--reuse-map, --minimax and --grid apply to a rig with one tendon; on a rig with several the "
            f"grid is {len(DIRECTIONS_DEG)} directions x {len(BENDS_MM)} bends (--directions, --bends; "
            "docs/task_space.md)"
        )
    directions, bends = grid(rig, args.directions, args.bends)
    repetitions = args.repetitions or 3
    folder = tendon_folder(args.data_dir, rig)
    say = (lambda _line: None) if args.quiet else (lambda line: print(line, file=sys.stderr))
    runs = len(directions) * len(bends) * (1 + len(SYSTEMS) * repetitions)
    left = [d for d in DIRECTIONS_DEG if d not in directions] if args.directions is None else []
    say(
        f"tune on '{rig.name}': {runs} moves of {MOVE_TIMES_S[-1]:g} s ({len(directions)} directions "
        f"x {len(bends)} bends; the map, then {len(SYSTEMS)} designs x {repetitions} repetitions)"
        + (f"; left out (no tendon faces them): {', '.join(f'{d:g}' for d in left)} deg" if left else "")
    )
    with contextlib.ExitStack() as stack:
        stack.enter_context(folder_lock(folder, what="tuning", name=".tuning.lock"))
        trig = stack.enter_context(Rig(args.ports, rig, world="tune"))
        if any(trig.positions()):
            raise SafetyError(
                f"tendons 1-{rig.n_tendons}: the stepper stands at {trig.positions()}, not at rest (0); run "
                "python -m helpers home first"
            )
        world = trig.world
        counter = itertools.count(args.seed)
        seeds = (lambda: next(counter)) if world is not None else (lambda: None)
        if (folder / "verification.json").exists() and not args.replace:
            raise RecordingExists(
                f"{repo_path(folder / 'verification.json')} exists; pass --replace to tune again"
            )
        reseed = None if world is None else world.reseed
        doc = tune_tendons(trig, folder, repetitions, directions=directions, bends=bends, seeds=seeds,
                           reseed=reseed, replace=args.replace, progress=say,
                           lanes=getattr(args, "lanes", 0))  # fmt: skip
    summary = pd.DataFrame(doc["summary"])
    print(summary.to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    print(
        f"-> {repo_path(folder / 'verification.json')}; wall time {doc['wall_s']:.1f} s (machine-dependent)"
    )
    return 0
