"""Checks of a reproduced Table II beyond the paper's: the held-out shaped rows, its orderings, the band.

The paper prints one Table II and concludes from it that either shaper beats the pulse and the robust one
the non-robust one. A reproduction on the virtual rig, tuned on the unshaped rows only, can be checked
further (notebook 06): the shaped rows as held-out predictions (:func:`prediction_errors`), each of the
paper's orderings per condition and motion (:func:`ordering_agreement`), and the settling time against a
band the paper does not state (:func:`band_sweep`). The metrics themselves are
:mod:`helpers.paper.metrics`'s.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import pandas as pd

from helpers.paper import numbers as paper
from helpers.paper.metrics import KEYS, MOTIONS, paper_comparison, scenario_table


def band_sweep(recordings: Sequence[Any], bands: Iterable[float], **kwargs: Any) -> pd.DataFrame:
    """Settling time against the band: :func:`helpers.paper.metrics.scenario_table` for each band, stacked.

    Parameters
    ----------
    recordings : sequence
        Recordings as for :func:`helpers.paper.metrics.metrics_by_run`.
    bands : iterable of float
        Band fractions, e.g. ``(0.02, 0.05, 0.10)``.
    **kwargs
        Passed to :func:`helpers.paper.metrics.motion_metrics`.

    Returns
    -------
    pandas.DataFrame
        ``band``, the keys, ``settling_ms_mean``, ``settling_ms_std``, ``settling_ms_n``.
    """
    parts = [
        scenario_table(recordings, b, **kwargs)[
            ["band", *KEYS, "settling_ms_mean", "settling_ms_std", "settling_ms_n"]
        ]
        for b in bands
    ]
    return pd.concat(parts, ignore_index=True)


ORDERINGS = (("zv", "unshaped"), ("zvd", "zv"), ("zvd", "unshaped"))
"""The paper's orderings, per condition and motion: each pair ``(a, b)`` claims ``a`` below ``b`` (in
overshoot and in settling time): a shaper beats the pulse, the robust shaper beats the non-robust one."""

INFORMATIVE_ORDERINGS = (("zvd", "zv"),)
"""The orderings that tell the designs apart: robust against non-robust. A shaped move below the unshaped
pulse (the other two) is all but certain for any shaper near the mode, so those 16 of the 24 are trivial."""


def prediction_errors(table: pd.DataFrame, systems: Sequence[str] = ("zv", "zvd")) -> pd.DataFrame:
    """Errors of a Table II (means) against the paper's, for the rows of ``systems``.

    Parameters
    ----------
    table : pandas.DataFrame
        Output of :func:`helpers.paper.metrics.scenario_table` (or a stored copy of it).
    systems : sequence of str
        The systems whose rows are compared (default the shaped ones: the held-out predictions).

    Returns
    -------
    pandas.DataFrame
        The keys, then ``peak_err_n``, ``overshoot_err_pp``, ``settling_err_ms`` (ours minus the paper's) and
        ``peak_is_bound`` (False if the table does not say).
    """
    cmp = paper_comparison(table)
    cmp = cmp[cmp["system"].isin(systems)].copy()
    out = cmp[KEYS].copy()
    out["peak_err_n"] = cmp["peak_n"] - cmp["peak_n_paper"]
    out["overshoot_err_pp"] = cmp["overshoot_pct"] - cmp["overshoot_pct_paper"]
    out["settling_err_ms"] = cmp["settling_ms"] - cmp["settling_ms_paper"]
    bound = cmp["peak_is_bound"] if "peak_is_bound" in cmp else pd.Series(False, index=cmp.index)
    out["peak_is_bound"] = bound.fillna(False).astype(bool)
    return out.reset_index(drop=True)


def ordering_agreement(table: pd.DataFrame, metric: str) -> pd.DataFrame:
    """Whether a Table II reproduces the paper's orderings (:data:`ORDERINGS`) of ``metric``, row by row.

    Parameters
    ----------
    table : pandas.DataFrame
        Output of :func:`helpers.paper.metrics.scenario_table` (means in ``<metric>_mean``).
    metric : {"overshoot_pct", "settling_ms"}
        The metric compared.

    Returns
    -------
    pandas.DataFrame
        Per condition, motion and ordering ``a < b``: ``informative`` (robust against non-robust,
        :data:`INFORMATIVE_ORDERINGS`; the others are trivial), ``paper`` (does the paper's table show it),
        ``ours`` (does ``table``), ``agrees`` (the same answer) and ``ours_margin`` (``b - a`` in ``table``,
        in the metric's unit: a disagreement by a hair is a tie).
    """
    if metric not in ("overshoot_pct", "settling_ms"):
        raise ValueError(f"metric must be 'overshoot_pct' or 'settling_ms', got {metric!r}")
    ours = table.set_index(KEYS)[f"{metric}_mean"]
    theirs = paper.table_ii().set_index(KEYS)[metric]
    rows = []
    for v, x in paper.TABLE_I_CONDITIONS:
        for motion in MOTIONS:
            for a, b in ORDERINGS:
                key_a, key_b = (float(v), float(x), a, motion), (float(v), float(x), b, motion)
                p_ok = bool(theirs.loc[key_a] < theirs.loc[key_b])
                try:
                    margin = float(ours.loc[key_b] - ours.loc[key_a])
                    o_ok = bool(ours.loc[key_a] < ours.loc[key_b])
                except KeyError:
                    margin, o_ok = math.nan, None
                rows.append({"v_in_mm_s": v, "x_f_mm": x, "motion": motion, "ordering": f"{a} < {b}",
                             "informative": (a, b) in INFORMATIVE_ORDERINGS, "paper": p_ok, "ours": o_ok,
                             "agrees": o_ok == p_ok, "ours_margin": margin})  # fmt: skip
    return pd.DataFrame(rows)
