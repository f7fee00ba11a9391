"""The robustness atlas's numbers from stored sweeps (notebook 09): percentiles, durations, the target.

Every function reads a sweep's dataset (:func:`helpers.research.sweep.load_sweep`) and returns a table;
nothing here
runs the rig. A residual case is one move of one run: the Up and the Down residual count alike, as in the
uncertainty model (:mod:`helpers.research.robustness.model`).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

__all__ = [
    "TARGET_REDUCTION", "definition_of", "equal_duration_table", "percentile_table", "target_check",
    "worst_move",
]  # fmt: skip

TARGET_REDUCTION = 0.30
"""The robust design's target: a 95th-percentile residual at least 30 % below the best compared family of the
same duration."""

EQUAL_DURATION_MS = 0.5
"""Designed durations this close count as equal (the quantised programme moves pieces by up to 1 ms)."""


def worst_move(ds: xr.Dataset, variable: str = "residual_pct") -> xr.DataArray:
    """The larger of the Up and the Down move's value, per run."""
    return ds[variable].max("move")


def _cases(ds: xr.Dataset, shaper: str) -> np.ndarray:
    """All residual cases (runs x moves) of one shaper, in a fixed order."""
    r = ds["residual_pct"].sel(shaper=shaper)
    return r.transpose(..., "move").values.reshape(-1)


def percentile_table(ds: xr.Dataset, q: float = 95.0, n_boot: int = 2000, seed: int = 0) -> pd.DataFrame:
    """Per shaper: the ``q``-th percentile residual over all cases, its bootstrap interval, the durations.

    Parameters
    ----------
    ds : xarray.Dataset
        A sweep over a random sample (dimension ``sample``).
    q : float
        The percentile.
    n_boot : int
        Bootstrap resamples (of the sample's points, both moves of a point together).
    seed : int
        The bootstrap's seed.

    Returns
    -------
    pandas.DataFrame
        Index ``shaper``; ``p{q}_pct``, ``low_pct``, ``high_pct`` (the 5th and 95th percentiles of the
        bootstrap), ``median_pct``, ``shaper_ms`` and ``move_ms`` (mean over the cases), ``refused``.
    """
    n = ds.sizes["sample"]
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, n, size=(n_boot, n))
    rows = []
    for shaper in ds["shaper"].values:
        r = ds["residual_pct"].sel(shaper=shaper).transpose("sample", "move").values
        cases = r.reshape(-1)
        boot = np.percentile(r[picks].reshape(n_boot, -1), q, axis=1)
        rows.append({
            "shaper": str(shaper),
            f"p{q:g}_pct": float(np.percentile(cases, q)),
            "low_pct": float(np.percentile(boot, 5)),
            "high_pct": float(np.percentile(boot, 95)),
            "median_pct": float(np.median(cases)),
            # to the microsecond, the programme's resolution; the unshaped pulse's quantised ramp may end a
            # microsecond before t_p, which is no negative shaper
            "shaper_ms": max(0.0, round(1e3 * float(ds["shaper_duration_s"].sel(shaper=shaper).mean()), 3)),
            "move_ms": round(1e3 * float(ds["move_duration_s"].sel(shaper=shaper).mean()), 3) + 0.0,
            "refused": int((ds["status"].sel(shaper=shaper) > 0).sum()),
        })  # fmt: skip
    return pd.DataFrame(rows).set_index("shaper")


def _designed_ms(ds: xr.Dataset, table: pd.DataFrame) -> Callable[[str], float]:
    """A shaper's designed duration (ms): the design set's, else the sweep's mean.

    The quantised programme moves a duration by microseconds, so the design's own is the one compared.
    """
    designed = {k: v.get("duration_s") for k, v in definition_of(ds)["custom_shapers"].items()}

    def duration(name: str) -> float:
        d = designed.get(name)
        return 1e3 * d if d is not None else float(table.loc[name, "shaper_ms"])

    return duration


def equal_duration_table(
    ds: xr.Dataset, compared: list[str], q: float = 95.0, n_boot: int = 2000, seed: int = 0
) -> pd.DataFrame:
    """Each robust design against every compared family of the same duration, with a paired bootstrap.

    Parameters
    ----------
    ds : xarray.Dataset
        The uncertainty sweep (with ``robust``, ``robust-short`` and the families at their durations).
    compared : list of str
        The candidate families' names in the sweep: the tuned families and the families compressed or
        stretched to each robust design's duration (the design set's ``compared`` and ``equal_duration``).
    q, n_boot, seed
        As :func:`percentile_table`.

    Returns
    -------
    pandas.DataFrame
        One row per (robust design, family) whose designed durations agree to :data:`EQUAL_DURATION_MS`,
        sorted by the family's percentile: ``robust``, ``robust_ms``, ``robust_p{q}_pct``, ``family``,
        ``family_ms``, ``family_p{q}_pct``, ``reduction_pct`` (1 - robust / family), its paired bootstrap
        interval (5-95 %) ``reduction_low_pct`` and ``reduction_high_pct``, and ``target_met``
        (:data:`TARGET_REDUCTION`).
    """
    table = percentile_table(ds, q, n_boot=1, seed=seed)
    col = f"p{q:g}_pct"
    n = ds.sizes["sample"]
    picks = np.random.default_rng(seed).integers(0, n, size=(n_boot, n))
    duration = _designed_ms(ds, table)
    rows: list[dict[str, Any]] = []
    for robust in ("robust", "robust-short"):
        if robust not in table.index:
            continue
        fams = [f for f in dict.fromkeys(compared) if f in table.index]
        fams = [f for f in fams if abs(duration(f) - duration(robust)) <= EQUAL_DURATION_MS]
        for fam in sorted(fams, key=lambda f: table.loc[f, col]):
            reduction, low, high = _paired_reduction(ds, robust, fam, q, picks)
            rows.append({
                "robust": robust,
                "robust_ms": duration(robust),
                f"robust_{col}": table.loc[robust, col],
                "family": fam,
                "family_ms": duration(fam),
                f"family_{col}": table.loc[fam, col],
                "reduction_pct": 100 * reduction,
                "reduction_low_pct": 100 * low,
                "reduction_high_pct": 100 * high,
                "target_met": bool(reduction >= TARGET_REDUCTION),
            })  # fmt: skip
    return pd.DataFrame(rows)


def target_check(
    ds: xr.Dataset, compared: list[str], q: float = 95.0, n_boot: int = 2000, seed: int = 0
) -> pd.DataFrame:
    """Each robust design against the best compared family of the same duration (the target's comparison).

    Parameters
    ----------
    ds, compared, q, n_boot, seed
        As :func:`equal_duration_table`.

    Returns
    -------
    pandas.DataFrame
        One row per robust design (index ``robust``): its designed duration (ms) and ``q``-th percentile,
        the best family of the same duration (to :data:`EQUAL_DURATION_MS`; ``best_family``) and its
        percentile, the reduction (1 - robust / family), its paired bootstrap interval (5-95 %), and whether
        the target (:data:`TARGET_REDUCTION`) is met.
    """
    pairs = equal_duration_table(ds, compared, q, n_boot, seed)
    best = pairs.groupby("robust", sort=False).head(1)  # sorted by the family's percentile
    return best.rename(columns={"family": "best_family"}).set_index("robust")


def _paired_reduction(
    ds: xr.Dataset, a_name: str, b_name: str, q: float, picks: np.ndarray
) -> tuple[float, float, float]:
    """``1 - P_q(a) / P_q(b)`` over the sample, and its 5-95 % interval over the bootstrap ``picks``."""
    a = ds["residual_pct"].sel(shaper=a_name).transpose("sample", "move").values
    b = ds["residual_pct"].sel(shaper=b_name).transpose("sample", "move").values
    n_boot = picks.shape[0]
    ratio = np.percentile(a[picks].reshape(n_boot, -1), q, axis=1) / np.percentile(
        b[picks].reshape(n_boot, -1), q, axis=1
    )
    reduction = 1 - np.percentile(a, q) / np.percentile(b, q)
    return float(reduction), float(1 - np.percentile(ratio, 95)), float(1 - np.percentile(ratio, 5))


def reduction_against(
    ds: xr.Dataset, shaper: str, other: str, q: float = 95.0, n_boot: int = 2000, seed: int = 0
) -> tuple[float, float, float]:
    """How much lower ``shaper``'s ``q``-th percentile residual is than ``other``'s, whatever their durations.

    Returns
    -------
    (reduction, low, high)
        ``1 - P_q(shaper) / P_q(other)`` over the sample's moves, and its paired bootstrap interval (5-95 %,
        the same resampling as :func:`target_check`).
    """
    picks = np.random.default_rng(seed).integers(0, ds.sizes["sample"], size=(n_boot, ds.sizes["sample"]))
    return _paired_reduction(ds, shaper, other, q, picks)


def definition_of(ds: xr.Dataset) -> dict[str, Any]:
    """The sweep's resolved definition (from its attributes)."""
    return json.loads(ds.attrs["definition"])
