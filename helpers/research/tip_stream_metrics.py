"""What a recorded tip stream did: the tip at the stops and along the plan, every tendon's least tension.

A recording of :mod:`helpers.research.tip_stream`'s plan (``helpers.rig.stream``; on the virtual rig its
frame has the twin's tip, ``tip_x_mm`` ..) is measured against the plan:

- :func:`stop_metrics`: at every stop away from the start, the window of ``window_s`` from the end of the
  shaped motion (the stop's first set-point period plus the board's two-period lag and the shaper's duration):
  the tip's residual vibration (peak to peak and RMS of its distance from its mean over the window, mm), its
  offset from where the statics puts it (mm), and each tendon's tension peak to peak (N);
- :func:`tracking`: the delay of the tip behind the plan's static tip path that best aligns them, and the RMS
  distance left at that delay (mm);
- :func:`tension_summary`: each tendon's least tension over the stream (a pre-pull and its let-out included)
  and the samples below the floor (raw, and over a 20 ms moving mean that leaves out the steps' transients).

Times are from the path's period 0 (:func:`stream_clock`): the board's ``STREAM``, plus the periods of a
pre-pull (``scenario.prepull_periods``, :func:`helpers.research.tip_stream.plan_stream`).

On the virtual rig every figure is **simulated** (the twin's tip is not measured).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from helpers.recordings import Recording
from helpers.research.tip_stream import PERIOD_S, StreamPlan

__all__ = ["stop_metrics", "tracking", "tension_summary", "stream_clock", "prepull_s", "summary"]

_TIP = ("tip_x_mm", "tip_y_mm", "tip_z_mm")


def prepull_s(rec: Recording) -> float:
    """Seconds from the board's ``STREAM`` to the path's period 0 (0 without a pre-pull).

    A pre-pull's periods: the pull and its settling, ``scenario.prepull_periods``.
    """
    return float(rec.meta["scenario"].get("prepull_periods") or 0) * PERIOD_S


def stream_clock(rec: Recording) -> np.ndarray:
    """Every sample's time from the path's period 0, s: the board's ``STREAM``, plus a pre-pull's periods.

    The recording's ``t_go_us`` (for a stream, the device time of ``STREAM``); recordings of format 3 kept it
    in ``scenario.t_stream_us``. Without a pre-pull (every recording before ``scenario.prepull_periods``) the
    time from ``STREAM``.
    """
    t0 = rec.meta["scenario"].get("t_stream_us", rec.meta.get("t_go_us"))
    if t0 is None:
        raise ValueError(f"{rec.path}: the recording does not say when the stream started (t_go_us)")
    return (rec.frame["t_us"].to_numpy(dtype=float) - t0) * 1e-6 - prepull_s(rec)


def _shaper_s(rec: Recording) -> float:
    delays = rec.meta["scenario"]["stream"]["impulses"]["delays_us"]
    return max(delays) * 1e-6


def _tip(rec: Recording) -> np.ndarray:
    if not all(c in rec.frame.columns for c in _TIP):
        raise ValueError("the recording has no tip (the in-process virtual rig records the twin's)")
    return rec.frame[list(_TIP)].to_numpy(dtype=float)


def stop_metrics(rec: Recording, plan: StreamPlan, window_s: float = 1.0) -> pd.DataFrame:
    """The tip's residual vibration and every tendon's tension swing at each stop (module docstring).

    Returns
    -------
    pandas.DataFrame
        One row per stop after the first: ``stop``, ``direction_deg``, ``bend_mm``, ``t_s`` (the window's
        start from ``STREAM``), ``tip_pp_mm``, ``tip_rms_mm``, ``tip_offset_mm`` and ``tension_pp_n_<i>``
        (tendon i, 1-based).
    """
    t = stream_clock(rec)
    tip = _tip(rec)
    n = plan.units.shape[1]
    rows = []
    for s, (a, b) in enumerate(plan.path.stops[1:], start=1):
        start = (a + 2) * PERIOD_S + _shaper_s(rec)
        end = min(start + window_s, (b + 2) * PERIOD_S)
        w = (t >= start) & (t <= end)
        if not w.any():
            continue
        here = tip[w]
        dist = np.linalg.norm(here - here.mean(axis=0), axis=1)
        d, m = plan.path.polar(a)
        row = {
            "stop": s, "direction_deg": round(d, 3), "bend_mm": round(m, 3), "t_s": round(start, 3),
            "tip_pp_mm": float(np.ptp(here, axis=0).max()), "tip_rms_mm": float(np.sqrt(np.mean(dist**2))),
            "tip_offset_mm": float(np.linalg.norm(here.mean(axis=0) - plan.tip_mm[a])),
        }  # fmt: skip
        for i in range(n):
            row[f"tension_pp_n_{i + 1}"] = float(np.ptp(rec.frame[f"tension_n_{i}"].to_numpy()[w]))
        rows.append(row)
    return pd.DataFrame(rows)


def tracking(rec: Recording, plan: StreamPlan, max_lag_s: float = 0.6) -> tuple[float, float]:
    """The tip's delay behind the plan's static tip path (s, 1 ms resolution) and the RMS distance at it (mm).

    The plan's boundary ``k`` is where the board's unshaped motion is at ``(k + 2)`` periods after ``STREAM``;
    the comparison covers the stream from its first set-point to its last boundary.
    """
    t = stream_clock(rec)
    tip = _tip(rec)
    planned_t = (np.arange(plan.path.periods + 1) + 2) * PERIOD_S
    inside = (t >= planned_t[0]) & (t <= planned_t[-1])
    best = (np.inf, 0.0)
    for lag in np.arange(0.0, max_lag_s, 0.001):
        ref = np.column_stack([np.interp(t[inside] - lag, planned_t, plan.tip_mm[:, j]) for j in range(3)])
        err = float(np.sqrt(np.mean(np.sum((tip[inside] - ref) ** 2, axis=1))))
        best = min(best, (err, float(lag)))
    return best[1], best[0]


def tension_summary(rec: Recording, floor_n: float, smooth_s: float = 0.02) -> pd.DataFrame:
    """Each tendon's least tension from ``STREAM`` on and the samples below ``floor_n``.

    From ``STREAM`` to the recording's end: a pre-pull's pull, the path, and the let-out after it.

    Also over the tension's centred moving mean of ``smooth_s``: each step of a stepper moves its tendon's
    tension by several newtons for a few milliseconds (the cable's stiffness before the arm follows), and the
    smoothed figures separate those transients from a tendon that stays slack.

    Returns
    -------
    pandas.DataFrame
        One row per tendon (1-based): ``tendon``, ``least_n``, ``at_s`` (:func:`stream_clock`),
        ``below_floor`` (samples), ``least_smoothed_n``, ``below_floor_smoothed``, ``samples``.
    """
    t = stream_clock(rec)
    after = t >= -prepull_s(rec)
    width = max(1, round(smooth_s * float(rec.meta["rate_hz"])))
    rows = []
    for i in range(rec.meta["tendons"]):
        raw = rec.frame[f"tension_n_{i}"].to_numpy(dtype=float)
        smooth = pd.Series(raw).rolling(width, center=True, min_periods=1).mean().to_numpy()
        y, ys = raw[after], smooth[after]
        k = int(np.argmin(y))
        rows.append({
            "tendon": i + 1, "least_n": float(y[k]), "at_s": float(t[after][k]),
            "below_floor": int(np.count_nonzero(y < floor_n)), "least_smoothed_n": float(ys.min()),
            "below_floor_smoothed": int(np.count_nonzero(ys < floor_n)), "samples": int(y.size),
        })  # fmt: skip
    return pd.DataFrame(rows)


def summary(rec: Recording, plan: StreamPlan) -> dict[str, float | int]:
    """One row for a recorded tip stream: the tip at the stops, its tracking, the least tensions.

    ``tip_pp_mean_mm`` / ``tip_pp_max_mm`` (:func:`stop_metrics`'s ``tip_pp_mm`` over the stops),
    ``tip_offset_max_mm``, ``lag_s`` and ``track_rms_mm`` (:func:`tracking`), ``least_n_<i>`` and
    ``least_smoothed_n_<i>`` per tendon, ``below_floor`` and ``below_floor_smoothed`` (samples, every tendon).
    """
    stops = stop_metrics(rec, plan)
    lag, rms = tracking(rec, plan)
    ten = tension_summary(rec, plan.floor_n)
    row: dict[str, float | int] = {
        "tip_pp_mean_mm": float(stops["tip_pp_mm"].mean()), "tip_pp_max_mm": float(stops["tip_pp_mm"].max()),
        "tip_offset_max_mm": float(stops["tip_offset_mm"].max()), "lag_s": lag, "track_rms_mm": rms,
    }  # fmt: skip
    for _, r in ten.iterrows():
        row[f"least_n_{int(r.tendon)}"] = float(r.least_n)
    for _, r in ten.iterrows():
        row[f"least_smoothed_n_{int(r.tendon)}"] = float(r.least_smoothed_n)
    row["below_floor"] = int(ten["below_floor"].sum())
    row["below_floor_smoothed"] = int(ten["below_floor_smoothed"].sum())
    return row
