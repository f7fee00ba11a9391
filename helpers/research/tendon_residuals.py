"""Residual vibration after a task-space move, of every tendon's tension and of the tip, and slack samples.

A move of a rig with several tendons (``record move``, ``docs/task_space.md``) is an Up-hold-Down
programme; its Up and Down motions are found on the step count of the **lead tendon** (the one whose count
has the largest range: it moves most, and a bend always pulls it) by
:func:`helpers.paper.metrics.segment_motions`. Each motion ends at the lead's last step (the last sample
before its count stops changing). After it, for every signal (each tendon's tension ``tension_n_i`` in N,
and, where the twin provides it, the tip's displacement magnitude ``|p - p0|`` in mm):

- ``residual``: half the peak-to-peak of the signal 0.1-1.1 s after the motion's end (the window of
  :func:`helpers.paper.metrics.residual_vibration`), in the signal's unit;
- ``step``: the signal's change over the motion, the median of its last 0.5 s before the next motion (or
  the recording's end) minus the median of its 0.5 s before the motion;
- ``residual_pct``: ``100 residual / |step|`` (NaN where the step is below ``MIN_STEP``: a tendon the move
  hardly changes has no meaningful percentage, its ``residual`` in N is what counts);
- ``noise``: the same half peak-to-peak over the recording's first second, before anything moves;
- ``below_floor``: how many samples of the whole motion (its start to the end of its residual window) read a
  tension below the floor (tendons only): the **slack events** of a move.

Everything here reads recordings; on the virtual rig the figures are the twin's (simulated).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from helpers.paper import metrics
from helpers.recordings import TIP_MM_COLUMNS

__all__ = ["MIN_STEP", "HOLD_WINDOW_S", "lead_tendon", "tip_displacement", "move_residuals_tendons"]

MIN_STEP = {"N": 0.05, "mm": 0.05}
"""Smallest step (per unit) for which a residual is also given in % of it."""

HOLD_WINDOW_S = 0.5
"""Length of the windows whose medians give a signal's level before and after a motion, s."""


def lead_tendon(frame: pd.DataFrame, tendons: int) -> int:
    """The tendon (0-based) whose step count has the largest range (the lowest index of equals)."""
    ranges = [np.ptp(frame[f"steps_{i}"].to_numpy()) for i in range(tendons)]
    return int(np.argmax(ranges))


def tip_displacement(frame: pd.DataFrame) -> np.ndarray | None:
    """The tip's displacement magnitude from its first sample, mm; None without the twin's tip columns."""
    if not all(c in frame.columns for c in TIP_MM_COLUMNS) or len(frame) == 0:
        return None
    p = frame.loc[:, list(TIP_MM_COLUMNS)].to_numpy(float)
    return np.linalg.norm(p - p[0], axis=1)


def _level(t: np.ndarray, y: np.ndarray, lo: float, hi: float) -> float:
    inside = (t >= lo) & (t < hi)
    return float(np.median(y[inside])) if inside.any() else math.nan


def move_residuals_tendons(
    frame: pd.DataFrame, tendons: int, floor_n: float, prepull: int = 0
) -> pd.DataFrame:
    """Residual vibration of every tendon and of the tip after the Up and Down motions of one move.

    Parameters
    ----------
    frame : pandas.DataFrame
        A loaded recording of several tendons: ``t_s``, ``steps_i`` and ``tension_n_i`` for each tendon,
        optionally the tip's ``tip_x_mm`` .. ``tip_z_mm``.
    tendons : int
        How many tendons the recording has.
    floor_n : float
        The tension floor, N (the rig file's ``[arm] tension_floor_n``).
    prepull : int
        Steps every tendon was pulled in before the move and let out after it: the motions are found on the
        lead's count above that (the pre-pull's own steps are no motion).

    Returns
    -------
    pandas.DataFrame
        One row per motion and signal: ``motion`` (Up/Down), ``signal`` (``tendon 1`` .. or ``tip``),
        ``unit``, ``lead`` (the lead tendon, 1-based), ``move_start_s``, ``move_end_s``, ``residual``,
        ``step``, ``residual_pct``, ``noise``, ``below_floor`` (samples; 0 for the tip), ``least`` (the
        signal's least value from the motion's start to the end of its residual window).

    Raises
    ------
    ValueError
        The lead tendon's count makes no Up-hold-Down move.
    """
    t = frame["t_s"].to_numpy(dtype=float)
    lead = lead_tendon(frame, tendons)
    steps = np.maximum(frame[f"steps_{lead}"].to_numpy(dtype=float) - prepull, 0.0)
    motions = metrics.segment_motions(t, steps)
    signals: list[tuple[str, str, np.ndarray]] = [
        (f"tendon {i + 1}", "N", frame[f"tension_n_{i}"].to_numpy(dtype=float)) for i in range(tendons)
    ]
    tip = tip_displacement(frame)
    if tip is not None:
        signals.append(("tip", "mm", tip))
    rest = t < min(t[0] + metrics.RESIDUAL_LENGTH_S, motions.up_start)
    rows = []
    spans = (("Up", motions.up_start, motions.down_start), ("Down", motions.down_start, t[-1] + 1.0))
    for motion, start, stop in spans:
        inside = np.flatnonzero((t >= start) & (t < stop))
        moving = np.flatnonzero(np.diff(steps[inside]) != 0)
        end = float(t[inside[moving[-1] + 1]]) if moving.size else float(start)
        lo = end + metrics.RESIDUAL_START_S
        hi = lo + metrics.RESIDUAL_LENGTH_S
        window = (t >= lo) & (t <= hi)
        span = (t >= start) & (t <= hi)
        for name, unit, y in signals:
            before = _level(t, y, start - HOLD_WINDOW_S, start)
            after = _level(t, y, min(stop, t[-1]) - HOLD_WINDOW_S, stop)
            step = after - before
            residual = float(np.ptp(y[window]) / 2.0) if np.count_nonzero(window) > 1 else math.nan
            pct = 100.0 * residual / abs(step) if abs(step) >= MIN_STEP[unit] else math.nan
            below = int(np.count_nonzero(y[span] < floor_n)) if unit == "N" else 0
            rows.append({
                "motion": motion, "signal": name, "unit": unit, "lead": lead + 1,
                "move_start_s": float(start), "move_end_s": end, "residual": residual, "step": step,
                "residual_pct": pct,
                "noise": float(np.ptp(y[rest]) / 2.0) if np.count_nonzero(rest) > 1 else math.nan,
                "below_floor": below, "least": float(np.min(y[span])) if span.any() else math.nan,
            })  # fmt: skip
    return pd.DataFrame(rows)
