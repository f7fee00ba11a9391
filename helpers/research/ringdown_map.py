"""Ring-downs of real trials as a mode map over the configuration, and the shapers designed from it.

The ring-downs of one or more trials (:func:`helpers.research.rest_ringdowns.identify_ringdowns`) become a
:class:`~helpers.research.modemap.ModeMap` over the configuration signal, as ``tune`` builds one for the arm
(:func:`ringdown_map`): ring-downs whose positions lie within a tolerance of each other are one map point;
its frequency and damping are their means, with standard errors from their spread over the ring-downs (the
spread over trials, up and down moves), and a point measured once keeps its fit's standard error. The map's
``positions_mm`` then hold the configuration in the unit its ``source["position_unit"]`` names (DROPBEAR:
PinLoc volts, not millimetres).

From the map the shapers are made (:func:`designs`): a fixed ZV and ZVD at one configuration (the paper's
way: one mode), the same families scheduled on the map (each move's shaper designed at the mode where that
move stops: :func:`helpers.research.design.scheduled_pair`), and the extra-insensitive families centred on
the band of the whole range (:func:`helpers.research.design.band_centred`). Their **predicted** residual
(:func:`predicted_residuals`) is Singer and Seering's ``V`` of each shaper on a linear modal model fitted to
each ring-down it is judged on (that ring-down's damped-sine fit), the worst over the ring-down's interval of
zeta. These are predictions on the fitted models, not measurements: no trial was shaped.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from helpers.paper.modes import omega_n_from_damped
from helpers.paper.shapers import Shaper
from helpers.research.design import band_centred, scheduled_pair
from helpers.research.design.scheduled import family
from helpers.research.modemap import ModeMap, mode_at

__all__ = [
    "TOLERANCE", "ringdown_map", "map_points", "Candidate", "designs", "predicted_residuals", "summary",
]  # fmt: skip

TOLERANCE = 0.05
"""Ring-downs whose positions lie within this of a map point's running mean are that point (the signal's
unit: DROPBEAR's steps are 0.43 V apart)."""


def map_points(tables: Mapping[str, pd.DataFrame], tolerance: float = TOLERANCE) -> pd.DataFrame:
    """Group the ring-downs of every trial by position.

    Parameters
    ----------
    tables : mapping of str to pandas.DataFrame
        Trial name -> its ring-down table (:data:`helpers.research.rest_ringdowns.COLUMNS`).
    tolerance : float
        Positions within this of a group's running mean join it.

    Returns
    -------
    pandas.DataFrame
        One row per ring-down with its ``trial`` and ``point`` (the group's index, by position).
    """
    rows = pd.concat([t.assign(trial=name) for name, t in tables.items()], ignore_index=True)
    rows = rows.sort_values("position", kind="stable").reset_index(drop=True)
    point, means, members = [], [], []
    for x in rows["position"]:
        if means and abs(x - means[-1]) <= tolerance:
            members[-1].append(x)
            means[-1] = float(np.mean(members[-1]))
        else:
            means.append(float(x))
            members.append([x])
        point.append(len(means) - 1)
    return rows.assign(point=point)


def ringdown_map(
    tables: Mapping[str, pd.DataFrame],
    source: Mapping[str, object],
    tolerance: float = TOLERANCE,
) -> tuple[ModeMap, pd.DataFrame]:
    """The mode map of the ring-downs of ``tables``, and its points' statistics.

    Parameters
    ----------
    tables : mapping of str to pandas.DataFrame
        Trial name -> ring-down table.
    source : mapping
        The map's provenance (``kind``, ``method``, ``position_unit``, the dataset and its licence).
    tolerance : float
        See :func:`map_points`.

    Returns
    -------
    (ModeMap, pandas.DataFrame)
        The map, and per point: ``position``, ``n``, ``f_hz`` (mean), ``f_sd_hz`` (spread over ring-downs),
        ``f_se_hz``, ``f_min_hz``, ``f_max_hz``, ``zeta`` (mean of the fits), ``zeta_se``, ``zeta_median``,
        ``zeta_lo`` and ``zeta_hi`` (the widest of the ring-downs' intervals), ``trials``, ``directions``.
    """
    rows = map_points(tables, tolerance)
    stats = []
    for _, g in rows.groupby("point", sort=True):
        n = len(g)
        f = g["f_hz"].to_numpy()
        z = g["zeta"].to_numpy()
        f_sd = float(np.std(f, ddof=1)) if n > 1 else float(g["f_se_hz"].iloc[0])
        z_sd = float(np.std(z, ddof=1)) if n > 1 else float(g["zeta_se"].iloc[0])
        stats.append({
            "position": float(g["position"].mean()), "n": n, "f_hz": float(f.mean()), "f_sd_hz": f_sd,
            "f_se_hz": f_sd / math.sqrt(n), "f_min_hz": float(f.min()), "f_max_hz": float(f.max()),
            "zeta": float(z.mean()), "zeta_se": z_sd / math.sqrt(n), "zeta_median": float(np.median(z)),
            "zeta_lo": float(g["zeta_lo"].min()), "zeta_hi": float(g["zeta_hi"].max()),
            "trials": ", ".join(sorted(set(g["trial"]))),
            "directions": ", ".join(sorted(set(g["direction"]))),
        })  # fmt: skip
    points = pd.DataFrame(stats)
    two_pi = 2.0 * math.pi
    mode_map = ModeMap(
        points["position"].to_numpy(), two_pi * points["f_hz"].to_numpy(), points["zeta"].to_numpy(),
        omega_d_se=two_pi * points["f_se_hz"].to_numpy(), zeta_se=points["zeta_se"].to_numpy(),
        source=dict(source),
    )  # fmt: skip
    return mode_map, points


class Candidate:
    """A shaper design to judge: a name, and the shaper a move from ``start`` to ``end`` gets.

    Parameters
    ----------
    name : str
        How tables and figures call it.
    shaper_for : callable
        ``shaper_for(start, end) -> Shaper``.
    """

    def __init__(self, name: str, shaper_for) -> None:  # noqa: ANN001 - a callable
        self.name = name
        self.shaper_for = shaper_for


def _fixed(shaper: Shaper) -> object:
    return lambda start, end: shaper


def _scheduled(mode_map: ModeMap, family_name: str) -> object:
    """The scheduled pair's shaper for the move: the mode where the move stops."""

    def shaper_for(start: float, end: float) -> Shaper:
        if end >= start:
            return scheduled_pair(mode_map, end - start, family_name, start_mm=start).shaping.up
        return scheduled_pair(mode_map, start - end, family_name, start_mm=end).shaping.down

    return shaper_for


def designs(mode_map: ModeMap, design_position: float) -> list[Candidate]:
    """The candidates: unshaped, fixed ZV/ZVD at ``design_position``, scheduled ZV/ZVD, band-centred EI.

    The band-centred EI and 2-hump EI are one shaper each over the map's whole range.
    """
    mode = mode_at(mode_map, design_position)
    low, high = mode_map.range_mm
    out = [Candidate("unshaped", _fixed(Shaper.unit()))]
    for name in ("ZV", "ZVD"):
        out.append(Candidate(f"fixed {name} at {design_position:.2f}", _fixed(family(name)(*mode))))
    for name in ("ZV", "ZVD"):
        out.append(Candidate(f"scheduled {name}", _scheduled(mode_map, name)))
    for name in ("EI", "2-hump EI"):
        shaper = band_centred(mode_map, high - low, name, start_mm=low).shaping
        out.append(Candidate(f"{name} centred on {low:.2f}-{high:.2f}", _fixed(shaper)))
    return out


def predicted_residuals(
    candidates: Sequence[Candidate], moves: pd.DataFrame, mode_map: ModeMap
) -> pd.DataFrame:
    """Each candidate's predicted residual on each move's fitted modal model.

    Parameters
    ----------
    candidates : sequence of Candidate
        The designs (:func:`designs`).
    moves : pandas.DataFrame
        Ring-downs with ``start`` (the previous rest's position) and ``position`` (where the move stopped),
        ``f_hz``, ``zeta``, ``zeta_lo``, ``zeta_hi`` (their fits), ``trial``, ``t_stop_s``.
    mode_map : ModeMap
        Moves that start or stop outside its range are left out (a schedule would extrapolate).

    Returns
    -------
    pandas.DataFrame
        One row per candidate and move: ``design``, ``trial``, ``t_stop_s``, ``start``, ``position``,
        ``duration_ms``, ``v_pct`` (at the fitted zeta), ``v_worst_pct`` (the worst over its zeta interval).
    """
    low, high = mode_map.range_mm
    inside = moves[moves["start"].between(low, high) & moves["position"].between(low, high)]
    rows = []
    for cand in candidates:
        for m in inside.itertuples():
            shaper = cand.shaper_for(float(m.start), float(m.position))
            wd = 2.0 * math.pi * m.f_hz
            zetas = [m.zeta, max(m.zeta_lo, 0.0), min(m.zeta_hi, 0.99)]
            v = [float(shaper.vibration(omega_n_from_damped(wd, z), z)) for z in zetas]
            rows.append({"design": cand.name, "trial": m.trial, "t_stop_s": m.t_stop_s, "start": m.start,
                         "position": m.position, "duration_ms": 1e3 * float(shaper.times[-1]),
                         "v_pct": 100.0 * v[0], "v_worst_pct": 100.0 * max(v)})  # fmt: skip
    return pd.DataFrame(rows)


def summary(residuals: pd.DataFrame) -> pd.DataFrame:
    """Per design: its duration (shortest, longest over the moves), median and worst predicted residual."""
    g = residuals.groupby("design", sort=False)
    return pd.DataFrame({
        "duration_min_ms": g["duration_ms"].min(), "duration_max_ms": g["duration_ms"].max(),
        "median_v_pct": g["v_pct"].median(), "worst_v_pct": g["v_worst_pct"].max(), "moves": g.size(),
    })  # fmt: skip
