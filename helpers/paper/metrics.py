"""Table II metrics of an up-hold-down recording: peak tension, overshoot and settling time per motion.

Definitions (``docs/metrics.md``). A recording holds an Up motion (from the first step of the up move to the
first step of the down move) and a Down motion (from the first step of the down move to the end of the
recording). With the tension ``y(t)``:

- motion start: detected from the recorded ``steps`` (the DAQ board's count of the stepper's pulses), never
  from the nominal profile times. The start is the time of the first sample whose step count shows the move
  (the first step happened within the sample interval before it, so at 1 kHz the start is at most 1 ms late);
- window of a motion: ``start <= t < end`` (the sample at ``end`` belongs to the next motion), except that a
  window ending at or after the last sample includes it;
- initial value ``y0``: median of the :data:`PRE_S` = 0.5 s before the start; final value ``yf``: median of
  the last :data:`FINAL_S` = 1.0 s of the window;
- Up: ``peak = max y`` over the window, ``overshoot = 100 (peak - yf) / (yf - y0)``;
  Down: ``peak = min y``, ``overshoot = 100 (yf - peak) / (y0 - yf)``;
- settling time: from the start to the *settling instant*, the last time the signal leaves the band
  ``|y - yf| <= band * |yf - y0|``: after it the signal never leaves the band within the window. It is found
  at sub-sample resolution by linear interpolation between the last sample outside the band and the next one
  (which is inside), i.e. the time at which the straight line between them crosses the band's edge. An
  excursion that lies wholly between two samples is not seen (the sampled signal is all there is).

A metric that cannot be computed is NaN and the row's ``reason`` says why; no number is ever made up:

- a gap in the samples of the analysed span (more than :data:`MAX_MISSING` consecutive samples missing; NaN
  tension samples count as missing): every metric of that motion is NaN;
- less than ``PRE_S`` of data before the start, or a window shorter than ``FINAL_S``: every metric is NaN;
- a zero step (``|yf - y0|`` at most 10 times the white-noise level of the pre-motion
  samples, estimated robustly from their second difference): overshoot and settling time are NaN (the peak
  is still reported);
- a step of the wrong sign for the motion (the tension falls across an Up motion or rises across a Down
  one): the overshoot is NaN (its formula assumes the expected direction);
- never settles (the last sample of the window is outside the band) or settles less than :data:`MIN_HOLD_S`
  before the window ends (it cannot be confirmed that it stays): the settling time is NaN.

Range check (hardware and virtual recordings alike): a sample whose ADC reading is *clipped*
(:func:`clipped_samples`: at the ADC's rails or at the amplifier loop's saturation, :func:`clip_limits`)
does not show the tension. A clipped sample inside a motion's window makes its peak a *bound* (a lower bound
of an Up peak, an upper bound of a Down minimum) and its overshoot a lower bound: both are kept,
``peak_is_bound`` is True and the row's ``reason`` says so. A clipped sample in the spans of ``y0`` or ``yf``
makes the overshoot and the settling time NaN (the step itself is unknown).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from typing import Any, Literal

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from helpers import rigfile
from helpers.base.noise import white_noise_std
from helpers.paper import numbers as paper
from helpers.rigfile.recorded import calibration_of, recording_rig

FloatArray = NDArray[np.float64]

PRE_S = 0.5
"""Seconds before a motion's start whose median is the initial value ``y0``."""

FINAL_S = 1.0
"""Seconds at the end of a motion's window whose median is the final value ``yf``."""

MIN_HOLD_S = 0.5
"""A settling instant counts only if the window continues at least this long after it (the signal must be seen
to stay in the band)."""

MAX_MISSING = 2
"""Most consecutive missing samples tolerated inside an analysed span before its metrics become NaN."""

MOTIONS = ("Up", "Down")
METRIC_COLUMNS = ("peak_n", "overshoot_pct", "settling_ms")
"""The three Table II metrics, as column names."""


@dataclass(frozen=True)
class Motions:
    """Where the Up and Down motions of a recording start, detected from the recorded step count.

    Attributes
    ----------
    up_start, down_start, end : float
        Time (s) of the first sample showing the up move, of the first sample showing the down move, and of
        the recording's last sample.
    """

    up_start: float
    down_start: float
    end: float


@dataclass(frozen=True)
class MotionMetrics:
    """Table II metrics of one motion, in the units of the analysed signal (N for tension).

    Attributes
    ----------
    motion : str
        ``"Up"`` or ``"Down"``.
    start_s, end_s : float
        The motion's window (s).
    y0, yf : float
        Initial and final values (medians, see the module docstring).
    peak : float
        Maximum (Up) or minimum (Down) over the window.
    overshoot_pct : float
        Overshoot in percent of the step ``|yf - y0|``.
    settling_ms : float
        Settling time (ms) from the motion's start.
    settled_s : float
        The settling instant (s), for plots.
    band : float
        Half-width of the settling band as a fraction of ``|yf - y0|``.
    reason : str
        Why some metric is NaN or a bound (``""`` when all are computed exactly).
    peak_is_bound : bool
        True when a clipped sample lies in the window: the peak (and the overshoot) is then only a bound.
    n_clipped : int
        Clipped samples in the window.
    """

    motion: str
    start_s: float
    end_s: float
    y0: float
    yf: float
    peak: float
    overshoot_pct: float
    settling_ms: float
    settled_s: float
    band: float
    reason: str = ""
    peak_is_bound: bool = False
    n_clipped: int = 0


LOOP_OFFSET_TOLERANCE_COUNTS = 10.0
"""A calibration whose zero reading is this close to the 4 mA loop's (122.88 counts) is taken to come from the
paper's current-loop chain; otherwise only the ADC's own rails bound the range."""


def clip_limits(calibration: dict[str, Any] | None = None, rig: Any = None) -> tuple[float, float]:
    """ADC counts at or beyond which a reading is clipped, for a recording's load-cell calibration.

    The rig's chain (:func:`helpers.rigfile.derived`; the paper's: current loop, 150 ohm, 10-bit ADC): at or
    below ``clip_low_counts`` (the loop's lower saturation, 3.8 mA, and the ADC's 0) or at or above
    ``clip_high_counts`` (within the noise margin of its upper saturation, 20.5 mA, or the ADC's 1023). A
    calibration whose zero reading (``offset_counts``) is not the loop's 4 mA (within
    :data:`LOOP_OFFSET_TOLERANCE_COUNTS`) comes from another chain, whose saturation is unknown: then only the
    ADC's rails, 0 and 1023, bound the range. ``rig`` is the recording's
    (:func:`helpers.recordings.recording_rig`); None is the paper's rig (``rigs/paper.toml``).
    """
    offset = None if calibration is None else calibration.get("offset_counts")
    d = rigfile.derived(rigfile.default_rig() if rig is None else rig)
    if offset is not None and abs(float(offset) - d.offset_counts) > LOOP_OFFSET_TOLERANCE_COUNTS:
        return 0.0, float(d.adc_max)
    return float(d.clip_low_counts), float(d.clip_high_counts)


def clipped_samples(
    adc: ArrayLike, calibration: dict[str, Any] | None = None, rig: Any = None
) -> NDArray[np.bool_]:
    """Which ADC readings are clipped: at or beyond the signal chain's range (:func:`clip_limits`).

    The check applies to hardware recordings as to virtual ones.

    Parameters
    ----------
    adc : array_like
        ADC counts.
    calibration : dict, optional
        The recording's ``calibration`` metadata (``offset_counts`` decides which chain; default the rig's).
    rig : RigFile, optional
        The recording's rig (its ADC chain); None is the paper's rig.

    Returns
    -------
    numpy.ndarray of bool
    """
    a = np.asarray(adc, dtype=float)
    low, high = clip_limits(calibration, rig)
    return (a <= low) | (a >= high)


def _check_time(t: FloatArray, name: str = "t") -> None:
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"{name} must be a 1-D array of at least 2 samples, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise ValueError(f"{name} contains NaN or infinite values")
    if np.any(np.diff(t) <= 0):
        raise ValueError(f"{name} must be strictly increasing (unsorted or repeated time stamps)")


def segment_motions(t: ArrayLike, steps: ArrayLike) -> Motions:
    """Find the starts of the Up and Down motions from the recorded motor position.

    The up move starts at the first sample whose step count exceeds the initial count; the down move starts at
    the first sample, after the count first reaches its maximum, whose count is below that maximum.

    Parameters
    ----------
    t : array_like
        Sample times (s), strictly increasing.
    steps : array_like
        Signed motor position (steps, positive when the cable is pulled) at each sample.

    Returns
    -------
    Motions
        Start times.

    Raises
    ------
    ValueError
        For mismatched or invalid input, or a recording without an up or without a down move.
    """
    t = np.asarray(t, dtype=float)
    s = np.asarray(steps, dtype=float)
    _check_time(t)
    if s.shape != t.shape:
        raise ValueError(f"t and steps must have the same length, got {t.size} and {s.size}")
    if not np.all(np.isfinite(s)):
        raise ValueError("steps contains NaN or infinite values")
    up = np.flatnonzero(s > s[0])
    if up.size == 0:
        raise ValueError(f"no up move: the step count never rises above its initial value {s[0]:.0f}")
    i_up = int(up[0])
    i_max = i_up + int(np.argmax(s[i_up:]))
    down = np.flatnonzero(s[i_max:] < s[i_max])
    if down.size == 0:
        raise ValueError(
            f"no down move: the step count never falls after reaching its maximum {s[i_max]:.0f} "
            f"at t = {t[i_max]:.3f} s"
        )
    i_down = i_max + int(down[0])
    return Motions(up_start=float(t[i_up]), down_start=float(t[i_down]), end=float(t[-1]))


def _metrics(motion: str, start: float, end: float, band: float, reason: str, **known: Any) -> MotionMetrics:
    """One motion's metrics: the ``known`` ones, NaN for the others."""
    undefined = ("y0", "yf", "peak", "overshoot_pct", "settling_ms", "settled_s")
    values = dict.fromkeys(undefined, math.nan) | known
    return MotionMetrics(motion=motion, start_s=start, end_s=end, band=band, reason=reason, **values)


def motion_metrics(
    t: ArrayLike,
    y: ArrayLike,
    start: float,
    end: float,
    motion: Literal["Up", "Down"],
    band: float = 0.05,
    *,
    clipped: ArrayLike | None = None,
) -> MotionMetrics:
    """Peak, overshoot and settling time of one motion (definitions in the module docstring).

    Parameters
    ----------
    t, y : array_like
        Sample times (s, strictly increasing) and the signal (tension in N); NaN samples of ``y`` count as
        missing.
    start, end : float
        The motion's start (from :func:`segment_motions`) and the end of its window (s).
    motion : {"Up", "Down"}
        Which formulas apply.
    band : float
        Half-width of the settling band as a fraction of ``|yf - y0|`` (0 < band < 1).
    clipped : array_like of bool, optional
        Per sample, whether the sensor clipped it (:func:`clipped_samples`); default none.

    Returns
    -------
    MotionMetrics
        The metrics, NaN with a reason where they cannot be computed, flagged where they are bounds.

    Raises
    ------
    ValueError
        For invalid arguments (not for signals whose metrics are undefined: those give NaN).
    """
    _check_motion_args(motion, band, start, end)
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    _check_time(t)
    if y.shape != t.shape:
        raise ValueError(f"t and y must have the same length, got {t.size} and {y.size}")

    clip = np.zeros(t.shape, dtype=bool) if clipped is None else np.asarray(clipped, dtype=bool)
    if clip.shape != t.shape:
        raise ValueError(f"clipped must have one flag per sample, got {clip.size} for {t.size}")

    dt = float(np.median(np.diff(t)))
    valid = np.isfinite(y)
    tv, yv, cv = t[valid], y[valid], clip[valid]
    in_window = (tv >= start) & ((tv < end) | (end >= t[-1]))
    t_w, y_w, c_w = tv[in_window], yv[in_window], cv[in_window]
    pre = (tv >= start - PRE_S) & (tv < start)
    problem = _coverage_problem(t, tv, t_w, start, end, dt)
    if problem:
        return _metrics(motion, start, end, band, problem)

    final = t_w >= t_w[-1] - FINAL_S
    y0 = float(np.median(yv[pre]))
    yf = float(np.median(y_w[final]))
    peak = float(np.max(y_w)) if motion == "Up" else float(np.min(y_w))
    n_clipped = int(np.count_nonzero(c_w))
    known = {"y0": y0, "yf": yf, "peak": peak, "peak_is_bound": n_clipped > 0, "n_clipped": n_clipped}
    reasons = []
    if n_clipped:
        which = "lower" if motion == "Up" else "upper"
        reasons.append(
            f"peak is a {which} bound: {n_clipped} sample(s) of the window are clipped at the sensor's range "
            "(the ADC's rails or the amplifier loop's saturation); the overshoot is a lower bound"
        )
    step = yf - y0
    # the smallest step: 10 times the pre-motion samples' white noise (robust), at least 1e-9 of the levels
    min_step = max(10.0 * white_noise_std(yv[pre]), 1e-9 * max(abs(y0), abs(yf)))
    if np.any(cv[pre]) or np.any(c_w[final]):
        reasons.append("y0 or yf read from clipped samples: overshoot and settling undefined")
    elif abs(step) <= min_step or abs(step) == 0.0:
        reasons.append(
            f"zero step: |yf - y0| = {abs(step):.4g} <= {min_step:.4g}; overshoot and settling undefined"
        )
    else:
        known["overshoot_pct"], more = _overshoot(motion, peak, y0, yf)
        known["settling_ms"], known["settled_s"], later = _settling(t_w, y_w, yf, step, band, start)
        reasons += more + later
    return _metrics(motion, start, end, band, "; ".join(reasons), **known)


def _check_motion_args(motion: str, band: float, start: float, end: float) -> None:
    if motion not in MOTIONS:
        raise ValueError(f"motion must be 'Up' or 'Down', got {motion!r}")
    if not (0.0 < band < 1.0):
        raise ValueError(f"band must lie in (0, 1), got {band!r}")
    if not (math.isfinite(start) and not math.isnan(end) and end > start):
        raise ValueError(f"need start < end, got start={start!r}, end={end!r}")


def _coverage_problem(
    t: FloatArray, tv: FloatArray, t_w: FloatArray, start: float, end: float, dt: float
) -> str:
    """Why the analysed span ``[start - PRE_S, end of the window]`` cannot give metrics ("" if it can)."""
    lo = start - PRE_S
    if t[0] > lo + 0.5 * dt:
        return (
            f"only {max(start - t[0], 0.0):.3f} s of data before the motion starts, need {PRE_S:.3f} s for y0"
        )
    if t_w.size < 2 or t_w[-1] - t_w[0] < FINAL_S:
        return f"window shorter than {FINAL_S:.3f} s, the span of yf"
    span = tv[(tv >= lo) & (tv <= t_w[-1])]
    # the span's ends are the nominal ones, so that missing samples at either end count as a gap too
    span = np.concatenate([[lo], span, [min(end, float(t[-1]))]])
    gaps = np.diff(span)
    worst = int(np.argmax(gaps))
    if gaps[worst] > (MAX_MISSING + 1.5) * dt:
        return (
            f"gap of {1e3 * gaps[worst]:.1f} ms in the samples at t = {span[worst]:.3f} s (more than "
            f"{MAX_MISSING} consecutive samples missing)"
        )
    return ""


def _overshoot(motion: str, peak: float, y0: float, yf: float) -> tuple[float, list[str]]:
    """Overshoot in % of the step, NaN with the reason when the step has the wrong sign for the motion."""
    step = yf - y0
    expected = 1.0 if motion == "Up" else -1.0
    if np.sign(step) != expected:
        direction = "falls" if motion == "Up" else "rises"
        return math.nan, [
            f"the signal {direction} across the {motion} motion (yf - y0 = {step:.4g}): overshoot undefined"
        ]
    if motion == "Up":
        return 100.0 * (peak - yf) / (yf - y0), []
    return 100.0 * (yf - peak) / (y0 - yf), []


def _settling(
    t_w: FloatArray, y_w: FloatArray, yf: float, step: float, band: float, start: float
) -> tuple[float, float, list[str]]:
    """Settling time (ms) and instant (s): the last exit from the band, interpolated, seen to hold."""
    reasons: list[str] = []
    settled_s = math.nan
    half_width = band * abs(step)
    outside = np.abs(y_w - yf) > half_width
    if not outside.any():
        settled_s = float(t_w[0])
    elif outside[-1]:
        reasons.append(f"never settles: still outside the +-{100 * band:g} % band at the end of the window")
    else:
        k = int(np.flatnonzero(outside)[-1])
        edge = yf + math.copysign(half_width, y_w[k] - yf)
        frac = (y_w[k] - edge) / (y_w[k] - y_w[k + 1])
        settled_s = float(t_w[k] + frac * (t_w[k + 1] - t_w[k]))
    if not math.isfinite(settled_s):
        return math.nan, math.nan, reasons
    if t_w[-1] - settled_s < MIN_HOLD_S:
        reasons.append(
            f"settles only {1e3 * (t_w[-1] - settled_s):.0f} ms before the window ends "
            f"(< {1e3 * MIN_HOLD_S:.0f} ms): cannot confirm it stays in the band"
        )
        return math.nan, math.nan, reasons
    return 1e3 * (settled_s - start), settled_s, reasons


def recording_metrics(
    frame: pd.DataFrame,
    band: float = 0.05,
    *,
    column: str = "tension_n",
    calibration: dict[str, Any] | None = None,
    rig: Any = None,
    **kwargs: Any,
) -> pd.DataFrame:
    """Table II metrics of one recording: one row per motion (Up, Down).

    Parameters
    ----------
    frame : pandas.DataFrame
        A loaded recording's frame with columns ``t_s``, ``steps`` and ``column``; with an ``adc`` column the
        range check (:func:`clipped_samples`) flags clipped samples.
    band : float
        Settling band (fraction of the step).
    column : str
        The analysed signal (default the tension in N).
    calibration : dict, optional
        The recording's ``calibration`` metadata, for the range check's limits (:func:`clip_limits`).
    rig : RigFile, optional
        The recording's rig, whose ADC chain bounds the range (None: the paper's rig).
    **kwargs
        Passed to :func:`motion_metrics`.

    Returns
    -------
    pandas.DataFrame
        Columns ``motion``, ``start_s``, ``end_s``, ``y0_n``, ``yf_n``, ``peak_n``, ``overshoot_pct``,
        ``settling_ms``, ``settled_s``, ``band``, ``reason``, ``peak_is_bound``, ``n_clipped`` (``_n``
        columns are in the units of ``column``). If the motions cannot be segmented, both rows are NaN with
        the reason.

    Raises
    ------
    ValueError
        If a column is missing.
    """
    missing = [c for c in ("t_s", "steps", column) if c not in frame.columns]
    if missing:
        raise ValueError(f"recording frame lacks column(s) {missing}; has {list(frame.columns)}")
    t = frame["t_s"].to_numpy(dtype=float)
    y = frame[column].to_numpy(dtype=float)
    if "clipped" not in kwargs and "adc" in frame.columns:
        kwargs = {**kwargs, "clipped": clipped_samples(frame["adc"].to_numpy(), calibration, rig)}
    try:
        m = segment_motions(t, frame["steps"].to_numpy(dtype=float))
    except ValueError as err:
        rows = [
            _metrics(name, math.nan, math.nan, band, f"segmentation failed: {err}") for name in MOTIONS
        ]
    else:
        rows = [
            motion_metrics(t, y, m.up_start, m.down_start, "Up", band, **kwargs),
            motion_metrics(t, y, m.down_start, m.end, "Down", band, **kwargs),
        ]
    df = pd.DataFrame([asdict(r) for r in rows])  # columns in MotionMetrics' order
    return df.rename(columns={"y0": "y0_n", "yf": "yf_n", "peak": "peak_n"})


KEYS = ["v_in_mm_s", "x_f_mm", "system", "motion"]
"""The columns that name a row of Table II: condition, system, motion."""


def _scenario_of(rec: Any, i: int) -> dict[str, Any]:
    try:
        sc = rec.meta["scenario"]
        return {
            "v_in_mm_s": round(float(sc["v_in_mm_s"]), 6),
            "x_f_mm": round(float(sc["x_f_mm"]), 6),
            "system": str(sc["system"]),
            "repetition": int(sc.get("repetition", i)),
        }
    except (AttributeError, KeyError, TypeError, ValueError) as err:
        raise ValueError(
            f"recording {i}: meta['scenario'] must hold v_in_mm_s, x_f_mm and system ({err!r})"
        ) from err


def metrics_by_run(
    recordings: Iterable[Any],
    band: float = 0.05,
    *,
    include_aborted: bool = False,
    mix_rigs: bool = False,
    **kwargs: Any,
) -> pd.DataFrame:
    """Metrics of every recording and motion, one row each (the long form behind :func:`scenario_table`).

    Parameters
    ----------
    recordings : iterable
        Objects with ``.frame`` (see :func:`recording_metrics`) and ``.meta`` (a dict whose
        ``"scenario"`` holds ``v_in_mm_s``, ``x_f_mm``, ``system`` and optionally ``repetition``).
    band : float
        Settling band.
    include_aborted : bool
        Also analyse recordings whose ``status`` is not ``complete`` (by default they are left out, and
        listed in ``table.attrs["skipped"]`` with the reason).
    mix_rigs : bool
        Accept recordings of different rigs (rig files, ``meta["rig"]``; older recordings are the paper's) in
        one table; by default that is refused (``ValueError``). Each recording's sensor range is its rig's.
    **kwargs
        Passed to :func:`motion_metrics`.

    Returns
    -------
    pandas.DataFrame
        ``v_in_mm_s``, ``x_f_mm``, ``system``, ``repetition`` and the columns of :func:`recording_metrics`.
    """
    parts = []
    skipped: list[str] = []
    rigs: dict[str, str] = {}
    for i, rec in enumerate(recordings):
        meta = getattr(rec, "meta", None) or {}
        status = meta.get("status", "complete")
        if status != "complete" and not include_aborted:
            skipped.append(f"{getattr(rec, 'name', i)}: {status}")
            continue
        sc = _scenario_of(rec, i)
        rig = recording_rig(meta, source=str(getattr(rec, "name", i)))
        rigs[rig.hash] = rig.name
        if len(rigs) > 1 and not mix_rigs:
            raise ValueError(
                f"recordings of {len(rigs)} rigs in one table ({', '.join(sorted(rigs.values()))}): "
                "pass mix_rigs=True to mix them"
            )
        calibration = calibration_of(meta) if "calibration" in meta else None  # tendon 1's, any version
        df = recording_metrics(rec.frame, band, calibration=calibration, rig=rig, **kwargs)
        for key, value in sc.items():
            df[key] = value
        parts.append(df)
    if not parts:
        note = f" (skipped: {'; '.join(skipped)})" if skipped else ""
        raise ValueError(f"no complete recordings given{note}")
    out = pd.concat(parts, ignore_index=True)
    front = ["v_in_mm_s", "x_f_mm", "system", "repetition"]
    table = paper_order(out[front + [c for c in out.columns if c not in front]])
    table.attrs["skipped"] = skipped
    return table


def paper_order(df: pd.DataFrame) -> pd.DataFrame:
    """Sort rows as the paper does: Table I conditions, then pulse/non-robust/robust, then Up/Down.

    Conditions, systems and motions the paper does not have follow, sorted by value.
    """
    cond = {c: i for i, c in enumerate(paper.TABLE_I_CONDITIONS)}
    sys_ = {s: i for i, s in enumerate(paper.SYSTEMS)}
    mot = {m: i for i, m in enumerate(MOTIONS)}
    key = pd.DataFrame(
        {
            "c": [cond.get((v, x), len(cond)) for v, x in zip(df["v_in_mm_s"], df["x_f_mm"], strict=True)],
            "v": df["v_in_mm_s"].to_numpy(),
            "x": df["x_f_mm"].to_numpy(),
            "s": [sys_.get(s, len(sys_)) for s in df["system"]],
            "sn": df["system"].to_numpy(),
            "r": df["repetition"].to_numpy() if "repetition" in df else np.zeros(len(df)),
            "m": [mot.get(m, len(mot)) for m in df["motion"]],
        },
        index=df.index,
    )
    order = key.sort_values(["c", "v", "x", "s", "sn", "r", "m"], kind="stable").index
    return df.loc[order].reset_index(drop=True)


def scenario_table(recordings: Iterable[Any], band: float = 0.05, **kwargs: Any) -> pd.DataFrame:
    """Table II: metrics per condition, system and motion, with mean and spread over repetitions.

    Parameters
    ----------
    recordings : iterable
        Recordings as for :func:`metrics_by_run`.
    band : float
        Settling band (fraction of the step), reported in the ``band`` column and ``table.attrs["band"]``.
    **kwargs
        Passed to :func:`metrics_by_run` (``include_aborted``) and :func:`motion_metrics`.

    Returns
    -------
    pandas.DataFrame
        :func:`summarise` of :func:`metrics_by_run`.
    """
    return summarise(metrics_by_run(recordings, band, **kwargs), band)


def summarise(runs: pd.DataFrame, band: float) -> pd.DataFrame:
    """Means and spreads over repetitions of a per-run table (the aggregation behind :func:`scenario_table`).

    Parameters
    ----------
    runs : pandas.DataFrame
        Output of :func:`metrics_by_run` (``attrs["skipped"]`` is carried over).
    band : float
        The settling band the runs were analysed with.

    Returns
    -------
    pandas.DataFrame
        One row per (``v_in_mm_s``, ``x_f_mm``, ``system``, ``motion``) in the paper's order, with
        ``n_runs`` and, for each metric ``m`` of ``peak_n``, ``overshoot_pct``, ``settling_ms``: ``m_mean``
        and ``m_std`` (sample standard deviation, ddof = 1; NaN with fewer than two values) over the runs
        where ``m`` is not NaN, and ``m_n``, the number of such runs. ``peak_is_bound`` is True if any
        repetition's peak is a bound (a clipped sample in its window; the mean is then a bound too) and
        ``n_clipped`` counts the clipped samples. ``reason`` lists, per repetition, why values are missing or
        bounds.
    """
    rows = []
    for keys, g in runs.groupby(KEYS, sort=False):
        row: dict[str, Any] = dict(zip(KEYS, keys, strict=True))
        row["n_runs"] = len(g)
        for m in METRIC_COLUMNS:
            vals = g[m].to_numpy(dtype=float)
            vals = vals[np.isfinite(vals)]
            row[f"{m}_mean"] = float(vals.mean()) if vals.size else math.nan
            row[f"{m}_std"] = float(vals.std(ddof=1)) if vals.size >= 2 else math.nan
            row[f"{m}_n"] = int(vals.size)
        row["band"] = band
        row["peak_is_bound"] = bool(g["peak_is_bound"].any())
        row["n_clipped"] = int(g["n_clipped"].sum())
        row["reason"] = "; ".join(
            f"rep {r}: {why}" for r, why in zip(g["repetition"], g["reason"], strict=True) if why
        )
        rows.append(row)
    table = paper_order(pd.DataFrame(rows))
    table.attrs["band"] = band
    table.attrs["skipped"] = runs.attrs.get("skipped", [])
    return table


def paper_comparison(table: pd.DataFrame) -> pd.DataFrame:
    """Set our Table II (means) beside the paper's.

    Parameters
    ----------
    table : pandas.DataFrame
        Output of :func:`scenario_table`.

    Returns
    -------
    pandas.DataFrame
        ``v_in_mm_s``, ``x_f_mm``, ``system``, ``motion``, then for each metric our mean (``peak_n``,
        ``overshoot_pct``, ``settling_ms``) and the paper's (``..._paper``), then ``peak_is_bound`` and
        ``reason`` if the table has them (a clipped peak stays flagged beside the paper's); rows of either
        table without a partner have NaN in the other's columns.
    """
    need = KEYS + [f"{m}_mean" for m in METRIC_COLUMNS]
    missing = [c for c in need if c not in table.columns]
    if missing:
        raise ValueError(f"table lacks column(s) {missing}: pass the output of scenario_table()")
    extra = [c for c in ("peak_is_bound", "reason") if c in table.columns]
    ours = table[need + extra].rename(columns={f"{m}_mean": m for m in METRIC_COLUMNS})
    theirs = paper.table_ii().rename(columns={m: f"{m}_paper" for m in METRIC_COLUMNS})
    merged = ours.merge(theirs, on=KEYS, how="outer")
    cols = KEYS + [c for m in METRIC_COLUMNS for c in (m, f"{m}_paper")] + extra
    return paper_order(merged[cols])


RESIDUAL_START_S = 0.1
"""The residual-vibration window opens this long after the last step of the move, s."""
RESIDUAL_LENGTH_S = 1.0
"""... and lasts this long, s."""


def residual_vibration(
    t: ArrayLike,
    y: ArrayLike,
    move_end_s: float,
    y0: float,
    yf: float,
) -> float:
    """Residual vibration of a move: half the peak-to-peak of ``y`` in a window after it, in % of the step.

    The window runs from :data:`RESIDUAL_START_S` = 0.1 s to ``RESIDUAL_START_S + RESIDUAL_LENGTH_S`` = 1.1 s
    after the last step of the, possibly shaped, move, and the step is ``yf - y0`` as defined for Table II
    (``docs/metrics.md``).

    Parameters
    ----------
    t, y : array_like
        Sample times (s) and the signal (e.g. tension, N).
    move_end_s : float
        Time of the move's last step, s.
    y0, yf : float
        The signal before the move and its final value.

    Returns
    -------
    float
        ``100 * (max - min) / 2 / |yf - y0|`` over the window; NaN if the step is zero or the window holds
        fewer than two finite samples.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.shape != y.shape:
        raise ValueError(f"t and y must have the same length, got {t.size} and {y.size}")
    lo = move_end_s + RESIDUAL_START_S
    window = (t >= lo) & (t <= lo + RESIDUAL_LENGTH_S) & np.isfinite(y)
    step = abs(yf - y0)
    if np.count_nonzero(window) < 2 or step == 0.0 or not math.isfinite(step):
        return math.nan
    w = y[window]
    return float(100.0 * (w.max() - w.min()) / 2.0 / step)
