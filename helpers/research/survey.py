"""The arm's modes across its configurations: hold the cable at a position, ring it, identify, repeat.

The paper identifies one mode at rest. The arm stiffens as the cable bends it, so a shaper that follows the
configuration needs the modes at every position a move passes (``helpers.research.modemap``). This procedure
measures
them through the same drivers on hardware and on the virtual rig (``helpers.rig.Rig.run``), one recording per
position, into a folder of its own (``data/tuning/survey`` by default):

1. from rest at 0, pull the cable slowly (:data:`APPROACH_MM_S`) to the position ``x``;
2. wait :data:`SETTLE_S` for the slow move's small vibration to die out;
3. **kick away**: pull :data:`KICK_MM` more at :data:`KICK_MM_S` (release it instead where pulling would pass
   the travel limit): a short step, like the start of a move, that rings mostly the lowest mode; record the
   free ring-down at ``x + kick`` for :data:`RING_S`;
4. **kick back** the same way to ``x`` and record its ring-down at ``x`` for :data:`RING_S`; return slowly
   to 0.

Each run therefore measures two configurations, ``x`` and ``x +- kick``. :func:`analyse` identifies the modes
of each ring-down on the window :data:`WINDOW_S` after its kick (seconds after the kick's last step) with
:func:`helpers.research.ringdown.fit_two_modes`: the dominant mode's damped frequency and damping with
standard errors,
and the second mode with its share when it is resolved. The first ring-down has decayed to a few percent
when the second kick comes (3 s is more than three of its time constants at rest). :func:`survey` runs every
position
(and repetitions), and :func:`map_from_rows` turns the rows into a :class:`helpers.research.modemap.ModeMap`
whose
standard errors are the larger of the fits' and the spread of the repetitions (divided by sqrt(n)).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from helpers.board.programmes import Dwell, Programme, Segment
from helpers.recordings import Recording
from helpers.research.modemap import ModeMap
from helpers.research.ringdown import fit_two_modes
from helpers.rig.trim import TensionGuard
from helpers.rigfile import RigFile, derived

POSITIONS_MM = tuple(float(x) for x in range(0, 41, 5))
"""Default survey positions, mm (0-40 every 5)."""
APPROACH_MM_S = 20.0
"""Speed of the slow moves to and from a position, mm/s (a tenth of the paper's moves: little excitation)."""
SETTLE_S = 2.5
"""Wait at the position before the kick, s (the slow move's vibration decays by more than 10x)."""
KICK_MM = 2.0
"""Amplitude of the kick, mm of cable (about 0.5 N of tension at rest: small, well above the noise)."""
KICK_MM_S = 100.0
"""Speed of the kick, mm/s (20 ms each way: short against the 250 ms period)."""
RING_S = 3.0
"""Ring-down recorded after the kick, s."""
WINDOW_S = (0.1, 2.1)
"""Identification window, s after the kick's last step (two seconds: 8 periods at rest, 20 at 40 mm)."""
LEAD_S = 0.5
"""Dwell before the first move, s."""


@dataclass(frozen=True)
class SurveyPlan:
    """The programme of one position and where its two ring-downs are.

    Attributes
    ----------
    position_mm : float
        The held position (whole steps), mm.
    programme : helpers.board.programmes.Programme
        What the stepper board runs.
    rings : tuple of (float, float, float)
        ``(cable position mm, window start s, window end s)`` of each ring-down, times after ``GO``: first the
        one after the kick away, then the one back at ``position_mm``.
    """

    position_mm: float
    programme: Programme
    rings: tuple[tuple[float, float, float], ...]


def _move(n: int, mm_per_step: float, speed_mm_s: float, direction: int) -> tuple[Segment, float]:
    """A constant-speed move of ``n`` steps: the segment and the time of its last step after its start."""
    interval = round(mm_per_step / speed_mm_s * 1e6)
    return Segment(direction, n, interval), (n - 1) * interval * 1e-6 if n else 0.0


def survey_plan(position_mm: float, rig: RigFile, kick_mm: float = KICK_MM) -> SurveyPlan:
    """The programme that holds the cable at ``position_mm``, kicks it away and back, and records both rings.

    Parameters
    ----------
    position_mm : float
        Cable position, mm, within the rig's travel (rounded to whole steps, at most the travel limit).
    rig : RigFile
        The rig (one tendon: its cable per step and travel).
    kick_mm : float
        Kick amplitude, mm (pulled, or released where pulling would pass the travel limit).

    Returns
    -------
    SurveyPlan

    Raises
    ------
    ValueError
        A position outside the travel, or a kick outside (0, 10] mm.
    """
    travel = rig.hardware.travel_mm
    if not (math.isfinite(position_mm) and 0.0 <= position_mm <= travel):
        raise ValueError(f"survey position {position_mm!r} mm is outside 0-{travel:g} mm")
    if not (0.0 < kick_mm <= travel / 4):
        raise ValueError(f"kick {kick_mm!r} mm is outside (0, {travel / 4:g}] mm")
    mm = derived(rig).mm_per_step[0]
    limit = derived(rig).travel_steps[0]
    n_position = min(round(position_mm / mm), limit)
    n_kick = round(kick_mm / mm)
    away = +1 if n_position + n_kick <= limit else -1
    items: list[Segment | Dwell] = [Dwell(round(LEAD_S * 1e3))]
    t = LEAD_S
    if n_position:
        seg, _ = _move(n_position, mm, APPROACH_MM_S, +1)
        items.append(seg)
        t += seg.n_steps * seg.interval_us * 1e-6
    items.append(Dwell(round(SETTLE_S * 1e3)))
    t += round(SETTLE_S * 1e3) * 1e-3
    rings = []
    for direction, at in ((away, n_position + away * n_kick), (-away, n_position)):
        seg, last = _move(n_kick, mm, KICK_MM_S, direction)
        items += [seg, Dwell(round(RING_S * 1e3))]
        kick_end = t + last
        rings.append((at * mm, kick_end + WINDOW_S[0], kick_end + WINDOW_S[1]))
        t += seg.n_steps * seg.interval_us * 1e-6 + round(RING_S * 1e3) * 1e-3
    if n_position:
        items.append(_move(n_position, mm, APPROACH_MM_S, -1)[0])
    items.append(Dwell(200))
    return SurveyPlan(n_position * mm, Programme(tuple(items)), tuple(rings))


def analyse(recording: Recording, plan: SurveyPlan, column: str = "tension_n") -> list[dict[str, Any]]:
    """The modes of each ring-down of one survey recording.

    Parameters
    ----------
    recording : helpers.recordings.Recording
        A loaded survey run (derived columns present).
    plan : SurveyPlan
        Its plan (the windows are taken relative to the recording's ``t_go_s``).
    column : str
        The signal (``tension_n`` or ``adc``).

    Returns
    -------
    list of dict
        Per ring-down: ``position_mm``, ``omega_d_rad_s``, ``omega_d_se_rad_s``, ``zeta``, ``zeta_se``, the
        second mode's ``omega_d2_rad_s``, ``omega_d2_se_rad_s``, ``zeta2``, ``zeta2_se``, ``share2``,
        ``share2_se`` (NaN when not resolved), ``residual_rms`` and ``recording``.
    """
    f = recording.frame
    t = f["t_s"].to_numpy() - float(recording.meta.get("t_go_s", 0.0))
    y = f[column].to_numpy(dtype=float)

    def value(x: float | None) -> float:
        return math.nan if x is None else float(x)

    rows = []
    for position, start, end in plan.rings:
        keep = (t >= start) & (t <= end)
        fit = fit_two_modes(t[keep], y[keep])
        rows.append({
            "position_mm": position,
            "omega_d_rad_s": fit.omega_d, "omega_d_se_rad_s": fit.omega_d_se,
            "zeta": fit.zeta, "zeta_se": fit.zeta_se,
            "omega_d2_rad_s": value(fit.omega_d2), "omega_d2_se_rad_s": value(fit.omega_d2_se),
            "zeta2": value(fit.zeta2), "zeta2_se": value(fit.zeta2_se),
            "share2": value(fit.share2), "share2_se": value(fit.share2_se),
            "residual_rms": fit.residual_rms,
            "recording": recording.name,
        })  # fmt: skip
    return rows


def map_from_rows(rows: pd.DataFrame, source: dict[str, Any]) -> ModeMap:
    """A mode map from the survey's rows (one or more repetitions per position).

    Each column is averaged over the repetitions at a position; its standard error is the larger of the mean
    fit error and the repetitions' standard deviation over sqrt(n). The second mode enters the map only if it
    was resolved at every position (otherwise the map has the dominant mode alone, and says so in
    ``source["second_mode"]``).

    Parameters
    ----------
    rows : pandas.DataFrame
        Rows of :func:`analyse`.
    source : dict
        Provenance (``kind``, ``method``, ...).

    Returns
    -------
    helpers.research.modemap.ModeMap
    """
    if rows.empty:
        raise ValueError("no survey rows to build a map from")
    groups = rows.groupby("position_mm", sort=True)

    def mean_se(value: str, se: str) -> tuple[np.ndarray, np.ndarray]:
        mean = groups[value].mean().to_numpy()
        fit_se = groups[se].mean().to_numpy()
        spread = groups[value].std(ddof=1).fillna(0.0).to_numpy() / np.sqrt(groups[value].count().to_numpy())
        return mean, np.maximum(fit_se, spread)

    positions = np.array(sorted(groups.groups), dtype=float)
    omega, omega_se = mean_se("omega_d_rad_s", "omega_d_se_rad_s")
    zeta, zeta_se = mean_se("zeta", "zeta_se")
    source = dict(source)
    second: dict[str, Any] = {}
    if rows["share2"].notna().groupby(rows["position_mm"]).all().all():
        w2, w2_se = mean_se("omega_d2_rad_s", "omega_d2_se_rad_s")
        z2, z2_se = mean_se("zeta2", "zeta2_se")
        s2, s2_se = mean_se("share2", "share2_se")
        second = {"omega_d2": w2, "zeta2": z2, "share2": s2, "omega_d2_se": w2_se, "zeta2_se": z2_se,
                  "share2_se": s2_se}  # fmt: skip
        source["second_mode"] = "resolved at every position"
    else:
        missing = sorted(rows.loc[rows["share2"].isna(), "position_mm"].unique())
        source["second_mode"] = f"not resolved at {', '.join(f'{x:.2f}' for x in missing)} mm: left out"
    return ModeMap(positions, omega, zeta, omega_d_se=omega_se, zeta_se=zeta_se, source=source, **second)


def survey(
    rig: Any,
    folder: str | os.PathLike,
    positions_mm: Sequence[float] = POSITIONS_MM,
    repetitions: int = 1,
    *,
    rate_hz: int = 1000,
    replace: bool = False,
    seeds: Callable[[], int | None] | None = None,
    progress: Callable[[str], None] | None = None,
) -> tuple[ModeMap, pd.DataFrame]:
    """Measure the modes at every position through ``rig`` (hardware or virtual) and save each run.

    Parameters
    ----------
    rig : helpers.rig.Rig
        A connected rig.
    folder : path-like
        Where the recordings go (``survey_x<requested position, mm>_r<k>``).
    positions_mm : sequence of float
        Cable positions, mm.
    repetitions : int
        Runs per position.
    rate_hz : int
        DAQ sample rate.
    replace : bool
        Replace recordings of the same names.
    seeds : callable, optional
        Returns the noise seed of the next run (in-process virtual rig), or None.
    progress : callable, optional
        Called with a line per finished run.

    Returns
    -------
    (helpers.research.modemap.ModeMap, pandas.DataFrame)
        The map and the per-run rows (:func:`analyse`).
    """
    folder = Path(folder)
    rows = []
    for x in positions_mm:
        plan = survey_plan(float(x), rig.rig)
        for k in range(1, repetitions + 1):
            name = f"survey_x{float(x):g}_r{k}".replace(".", "p")
            scenario = {
                "kind": "survey", "system": "unshaped", "position_mm": plan.position_mm, "kick_mm": KICK_MM,
                "rings": [list(r) for r in plan.rings], "repetition": k,
            }  # fmt: skip
            seed = None if seeds is None else seeds()
            rec = rig.run(plan.programme, scenario=scenario, path=folder / name, rate_hz=rate_hz,
                          replace=replace, progress=False, noise_seed=seed,
                          guard=TensionGuard() if rig.n > 1 else None)  # fmt: skip
            for row in analyse(rec if "tension_n" in rec.frame else rec.derive(), plan):
                row["repetition"] = k
                rows.append(row)
                if progress is not None:
                    progress(f"{name} at {row['position_mm']:.2f} mm: omega_d {row['omega_d_rad_s']:.3f} "
                             f"rad/s, zeta {row['zeta']:.4f}")  # fmt: skip
    table = pd.DataFrame(rows)
    kind = (rig.source or {}).get("kind", "hardware")
    made_on = {"name": rig.rig.name, "hash": rig.rig.hash}
    source = {"kind": kind, "method": "survey: kick and ring-down at each position, two-mode fit",
              "kick_mm": KICK_MM, "window_s": list(WINDOW_S), "repetitions": repetitions,
              "recordings": str(folder.name), "rig": made_on}  # fmt: skip
    return map_from_rows(table, source), table
