"""Residual vibration after each move of a recording, beside its noise floor (the shaper tuning's measure).

Beyond the paper's Table II: :mod:`helpers.research.tune` verifies its designs with it, notebook 07 shows it.
The residual itself (half the peak-to-peak 0.1-1.1 s after the move, in % of the step) is
:func:`helpers.paper.metrics.residual_vibration`, the measure notebook 03 uses on the linear model.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from helpers.paper import metrics

SLACK_N = 0.05
"""Below this tension (N) the cable counts as slack (it cannot push; the load cell reads its zero)."""


def move_residuals(frame: pd.DataFrame, column: str = "tension_n", band: float = 0.05) -> pd.DataFrame:
    """Residual vibration of the Up and Down moves of one recording, with the measure's noise floor.

    Each move ends at its last step (from the recorded step count: the last sample before the count stops
    changing); the residual is :func:`~metrics.residual_vibration` of ``column`` after it, with ``y0`` and
    ``yf`` of the Table II metrics (:func:`~metrics.recording_metrics`). The **noise floor** is the same
    measure on the recording's first second, before anything moves: half the peak-to-peak of the signal at
    rest, in % of the move's step (what the residual would read on a perfectly still arm).

    Parameters
    ----------
    frame : pandas.DataFrame
        ``t_s``, ``steps`` and ``column``.
    column : str
        The signal (tension in N by default).
    band : float
        Settling band for the Table II metrics reported beside.

    Returns
    -------
    pandas.DataFrame
        One row per motion: ``motion``, ``move_start_s``, ``move_end_s``, ``move_duration_s``,
        ``residual_pct``, ``noise_floor_pct``, ``slack`` (the cable read slack in the residual window),
        ``peak_n``, ``overshoot_pct``, ``settling_ms``, ``reason``.
    """
    t = frame["t_s"].to_numpy(dtype=float)
    steps = frame["steps"].to_numpy(dtype=float)
    y = frame[column].to_numpy(dtype=float)
    motions = metrics.segment_motions(t, steps)
    table = metrics.recording_metrics(frame, band, column=column)
    rest = (t >= t[0]) & (t < min(t[0] + metrics.RESIDUAL_LENGTH_S, motions.up_start))
    rows = []
    spans = (("Up", motions.up_start, motions.down_start), ("Down", motions.down_start, t[-1]))
    for motion, start, stop in spans:
        inside = (t >= start) & (t < stop) if motion == "Up" else t >= start
        moving = np.flatnonzero(np.diff(steps[inside]) != 0)
        idx = np.flatnonzero(inside)
        end = float(t[idx[moving[-1] + 1]]) if moving.size else float(start)
        row = table.loc[table["motion"] == motion].iloc[0]
        y0, yf = float(row["y0_n"]), float(row["yf_n"])
        residual = metrics.residual_vibration(t, y, end, y0, yf)
        step = abs(yf - y0)
        enough = step > 0 and np.count_nonzero(rest) > 1
        floor = 100.0 * (np.ptp(y[rest]) / 2.0) / step if enough else math.nan
        lo = end + metrics.RESIDUAL_START_S
        window = (t >= lo) & (t <= lo + metrics.RESIDUAL_LENGTH_S)
        slack = bool(np.any(y[window] < SLACK_N))
        reason = str(row["reason"])
        if slack:
            reason = "; ".join(filter(None, [reason, "the cable went slack in the residual window"]))
        if not window.any() or t[window][-1] < lo + metrics.RESIDUAL_LENGTH_S - 0.01:
            reason = "; ".join(filter(None, [reason, "the recording ends before the residual window does"]))
        rows.append({
            "motion": motion, "move_start_s": float(start), "move_end_s": end,
            "move_duration_s": end - float(start), "residual_pct": residual, "noise_floor_pct": floor,
            "slack": slack, "peak_n": float(row["peak_n"]), "overshoot_pct": float(row["overshoot_pct"]),
            "settling_ms": float(row["settling_ms"]), "reason": reason,
        })  # fmt: skip
    return pd.DataFrame(rows)
