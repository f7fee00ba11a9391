"""Residual vibration after the Up and Down moves of a recording of 1 to 4 tendons, and the move's lead.

Beyond the paper's Table II: the shaper tunings verify their designs with it (:mod:`helpers.research.tune`
along one cable, :mod:`helpers.research.tune_tendons` over a bend's direction), notebooks 07 and 10 show it,
and ``python -m helpers metrics`` takes its Table II rows of every tendon and of the tip from it.

**The lead** of a move is the tendon that pulls most towards the bend
(:func:`helpers.rigfile.derived.lead_tendon`: the largest ``(r_i / r_mean) cos(beta - a_i)``, the direction
map's pull; of equal pulls the lowest index); the planner (:mod:`helpers.research.task_space`), the shapers'
modes (:mod:`helpers.research.task_shaping`), the twin's map and this analysis all take it from there. A
recording without a bend's direction (a pulse, a programme of one's own) is led by the tendon whose count
rises most above its first value (:func:`rising_tendon`): never by the largest range, which on three tendons
bent at 45 deg is a tendon paying out.

**The move's phases** (:func:`move_phases`), from the lead's step count: a **pre-pull** (``k`` steps every
tendon is pulled in before the move and let out after it, ``scenario.prepull_steps``) is no part of the move:
the Up motion starts at the first sample whose lead count rises above its pre-pulled level, the Down motion
at the first fall after its maximum, or, where the count falls within its Up (a shaper with a negative
impulse), at the first change after it has held one count for :data:`HOLD_S`; the Down window ends where the
release starts (once the lead is back at its pre-pulled level for :data:`HOLD_S`, the first fall of a tendon's
count below its pre-pulled level), else at the recording's end. Each motion ends at the lead's last step in
it.

**Per signal** (:func:`residual_table`: each tendon's tension in N and, where the twin provides it, the tip's
displacement ``|p - p_0|`` in mm from where it stood before the move, the median of the 0.5 s before Up):

- the Table II metrics over the motion's window (:func:`helpers.paper.metrics.motion_metrics`: ``y0``, ``yf``,
  peak, overshoot, settling time);
- ``residual``: half the peak-to-peak 0.1-1.1 s after the motion's end (the window of
  :func:`helpers.paper.metrics.residual_vibration`), in the signal's unit; ``step = yf - y0``;
  ``residual_pct = 100 residual / |step|`` (NaN below :data:`MIN_STEP`: a signal the move hardly changes);
- ``noise``: the same half peak-to-peak at rest: the recording's first second (the second before Up after a
  pre-pull), and ``noise_floor_pct`` in % of the step;
- ``below_floor`` (samples of the tension below the floor from the motion's start to the end of its residual
  window: the slack events; for the Down motion of a pre-pulled move also every sample from the release's
  first to the recording's last, the **let-out counted with the move**), ``below_floor_letout`` (those of the
  let-out alone: 0 for Up and without a pre-pull), ``least`` (over the same samples), and ``slack`` (a sample
  below :data:`SLACK_N` in the residual window);
- ``role``: ``lead``, ``pulled`` (its count above its pre-pulled level in the hold: an up-hold-down move of
  its own), ``paid out`` or ``held`` (no up-hold-down move: no Table II row in ``metrics``), ``tip``.

Everything here reads recordings; on the virtual rig the figures are the twin's (simulated).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from helpers.paper import metrics
from helpers.recordings import TIP_MM_COLUMNS, Recording, recording_rig
from helpers.rigfile.derived import lead_tendon

__all__ = [
    "SLACK_N", "MIN_STEP", "HOLD_S", "rising_tendon", "recording_lead", "MovePhases", "move_phases",
    "residual_table", "recording_residuals", "move_residuals", "tip_displacement",
]  # fmt: skip

SLACK_N = 0.05
"""Below this tension (N) the cable counts as slack (it cannot push; the load cell reads its zero)."""

MIN_STEP = {"N": 0.05, "mm": 0.05}
"""Smallest step (per unit) for which a residual is also given in % of it."""

HOLD_S = 0.5
"""The least hold between a move out and its move back, s: a shaped move pauses within itself for less (a
fraction of the mode's period, under 0.3 s on the shipped rigs)."""


def rising_tendon(counts: np.ndarray) -> int:
    """The tendon (0-based) whose step count rises most above its first value (the lowest of equals).

    ``counts`` is (samples, tendons).
    """
    c = np.asarray(counts, dtype=float)
    return int(np.argmax(c.max(axis=0) - c[0]))


def _counts(frame: pd.DataFrame, tendons: int) -> np.ndarray:
    if tendons == 1 and "steps_0" not in frame.columns:
        return frame[["steps"]].to_numpy(dtype=float)
    return frame[[f"steps_{i}" for i in range(tendons)]].to_numpy(dtype=float)


def recording_lead(rec: Recording) -> tuple[int, str]:
    """A recording's lead tendon (0-based) and why: by its move's direction, else by its rising count."""
    sc = rec.meta.get("scenario") or {}
    direction = sc.get("direction_deg")
    if rec.tendons == 1:
        return 0, "its only tendon"
    if isinstance(direction, int | float) and math.isfinite(direction):
        rig = recording_rig(rec.meta, rec.name)
        lead = lead_tendon(rig.tendons, direction)
        return lead, f"pulls most towards {direction:g} deg"
    lead = rising_tendon(_counts(rec.frame, rec.tendons))
    return lead, "its count rises most (no bend direction recorded)"


@dataclass(frozen=True)
class MovePhases:
    """Where a move's phases lie in a recording (s); NaN where a phase is absent.

    Attributes
    ----------
    lead : int
        The lead tendon (0-based), whose count the motions are found on.
    prepull : int
        Steps every tendon was pulled in before the move (0: none).
    prepull_s : float
        The first sample at which every tendon stands pulled in (NaN without a pre-pull).
    up_start_s, down_start_s : float
        The first sample of each motion.
    up_end_s, down_end_s : float
        The lead's last step of each motion (the sample that shows it).
    end_s : float
        The end of the Down window: the release's first sample, else the recording's last.
    release_s : float
        The first sample of the pre-pull's release (NaN without one, or a recording that stops before it).
    level : tuple of float
        Every tendon's count before the move (where the programme started, plus the pre-pull).
    """

    lead: int
    prepull: int
    prepull_s: float
    up_start_s: float
    up_end_s: float
    down_start_s: float
    down_end_s: float
    end_s: float
    release_s: float
    level: tuple[float, ...]


def _last_step(t: np.ndarray, s: np.ndarray, lo: float, hi: float, closed: bool) -> float:
    inside = np.flatnonzero((t >= lo) & ((t <= hi) if closed else (t < hi)))
    moving = np.flatnonzero(np.diff(s[inside]) != 0)
    return float(t[inside[moving[-1] + 1]]) if moving.size else float(lo)


def _motions(t: np.ndarray, rel: np.ndarray) -> metrics.Motions:
    """The Up and Down starts of a count above its level (``rel``).

    The paper's rule (:func:`helpers.paper.metrics.segment_motions`: Down at the first fall after the
    maximum), but where the count falls within its Up (a shaper with a negative impulse, UMZV, takes it back
    for a while during the move out), Down at the first change after the first stretch of :data:`HOLD_S` at
    one count above the level.
    """
    m = metrics.segment_motions(t, rel)
    i_up = int(np.searchsorted(t, m.up_start))
    edges = np.concatenate([[i_up], np.flatnonzero(np.diff(rel[i_up:]) != 0) + i_up + 1, [rel.size]])
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        if b < rel.size and t[b - 1] - t[a] >= HOLD_S and rel[a] > 0:
            if m.down_start >= t[b] or rel[b] > rel[a]:
                return m  # no fall before the hold ends (the paper's rule), or the hold ends in a rise
            return metrics.Motions(up_start=m.up_start, down_start=float(t[b]), end=m.end)
    return m


def _rest_after(t: np.ndarray, rel: np.ndarray, after: float) -> float | None:
    """Where the count is back at its level for good (None if never).

    The first stretch at 0 after ``after`` lasting :data:`HOLD_S`: a shaped move back may touch the level
    within itself.
    """
    i = int(np.searchsorted(t, after))
    edges = np.concatenate([[i], np.flatnonzero(np.diff(rel[i:]) != 0) + i + 1, [rel.size]])
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        if rel[a] == 0 and t[b - 1] - t[a] >= HOLD_S:
            return float(t[a])
    return None


def move_phases(
    t: np.ndarray, counts: np.ndarray, lead: int, prepull: int = 0, start: Sequence[float] | None = None
) -> MovePhases:
    """The phases of a move (module docstring) from every tendon's step count.

    Parameters
    ----------
    t : numpy.ndarray
        Sample times, s.
    counts : numpy.ndarray
        (samples, tendons) step counts.
    lead : int
        The lead tendon (0-based).
    prepull : int
        Steps every tendon was pulled in before the move and let out after it.
    start : sequence of float, optional
        Every tendon's count when the programme started (``scenario.start_positions_steps``): a pre-pull of
        a millisecond is often complete at the first sample. Default: the first sample's counts.

    Raises
    ------
    ValueError
        The lead's count makes no up-hold-down move above its pre-pulled level.
    """
    t = np.asarray(t, dtype=float)
    c = np.asarray(counts, dtype=float)
    level = (c[0] if start is None else np.asarray(start, dtype=float)) + prepull
    s = c[:, lead]
    try:
        m = _motions(t, np.maximum(s - level[lead], 0.0))
    except ValueError as exc:
        where = f" {prepull} step(s) above its start (the pre-pull)" if prepull else " its start"
        raise ValueError(f"tendon {lead + 1} (the lead) makes no up-hold-down move from{where}: {exc}") \
            from None
    pre = release = math.nan
    end = float(t[-1])
    if prepull:
        pulled = np.flatnonzero(np.all(c >= level, axis=1))
        pre = float(t[pulled[0]]) if pulled.size else math.nan
        back = _rest_after(t, np.maximum(s - level[lead], 0.0), m.down_start)
        if back is not None:  # the release: a tendon's count falling below its pre-pulled level after that
            falling = np.any((c[1:] < level) & (np.diff(c, axis=0) < 0), axis=1)
            low = np.flatnonzero(falling & (t[1:] >= back))
            if low.size:
                release = end = float(t[low[0] + 1])
    return MovePhases(
        lead=int(lead), prepull=int(prepull), prepull_s=pre, up_start_s=m.up_start,
        up_end_s=_last_step(t, s, m.up_start, m.down_start, closed=False), down_start_s=m.down_start,
        down_end_s=_last_step(t, s, m.down_start, end, closed=math.isnan(release)),
        end_s=end, release_s=release, level=tuple(float(v) for v in level),
    )  # fmt: skip


def tip_displacement(frame: pd.DataFrame, before_s: float | None = None) -> np.ndarray | None:
    """The tip's displacement magnitude, mm; None without the twin's tip columns.

    From where it stood before the move (the median of each coordinate over the 0.5 s before ``before_s``,
    Table II's ``y0`` span), or from its first sample (``before_s`` None, or no sample in that span).
    """
    if not all(c in frame.columns for c in TIP_MM_COLUMNS) or len(frame) == 0:
        return None
    p = frame.loc[:, list(TIP_MM_COLUMNS)].to_numpy(float)
    t = frame["t_s"].to_numpy(float)
    span = np.zeros(t.size, bool) if before_s is None else (t >= before_s - metrics.PRE_S) & (t < before_s)
    p0 = np.median(p[span], axis=0) if span.any() else p[0]
    return np.linalg.norm(p - p0, axis=1)


def _roles(t: np.ndarray, c: np.ndarray, ph: MovePhases) -> list[tuple[str, int]]:
    """Each tendon's role and its count in the hold, relative to its count before the move."""
    hold = np.flatnonzero(t >= ph.up_end_s)[0]  # every tendon's last step of the move out: the window's end
    out = []
    for i in range(c.shape[1]):
        held = int(c[hold, i] - ph.level[i])
        role = "pulled" if held > 0 else "paid out" if held < 0 else "held"
        out.append(("lead" if i == ph.lead else role, held))
    return out


def residual_table(
    frame: pd.DataFrame,
    tendons: int,
    phases: MovePhases,
    *,
    floor_n: float | None = None,
    band: float = 0.05,
    clipped: Sequence[np.ndarray | None] | None = None,
) -> pd.DataFrame:
    """Every tendon's and the tip's residual and Table II metrics after the Up and Down motions of a move.

    Parameters
    ----------
    frame : pandas.DataFrame
        A loaded recording: ``t_s``, ``steps_i`` and ``tension_n_i`` per tendon (a one-tendon frame may have
        ``steps`` and ``tension_n``), optionally the tip's ``tip_x_mm`` .. ``tip_z_mm``.
    tendons : int
        How many tendons the recording has.
    phases : MovePhases
        From :func:`move_phases`.
    floor_n : float, optional
        The tension floor, N (the rig file's ``[arm] tension_floor_n``); None: no samples counted below it.
    band : float
        Settling band of the Table II metrics.
    clipped : sequence of arrays, optional
        Per tendon, its clipped samples (:func:`helpers.paper.metrics.clipped_samples`).

    Returns
    -------
    pandas.DataFrame
        One row per motion and signal (module docstring): ``motion``, ``signal`` (``tendon 1`` .. or
        ``tip``), ``tendon`` (1-based; 0 for the tip), ``role``, ``held_steps``, ``unit``, ``lead`` (1-based),
        ``move_start_s``, ``move_end_s``, ``move_duration_s``, ``window_end_s``, ``residual``, ``step``,
        ``residual_pct``, ``noise``, ``noise_floor_pct``, ``slack``, ``below_floor`` (the Down motion's with
        a pre-pull's let-out), ``below_floor_letout``, ``least``, ``y0``, ``yf``, ``peak``,
        ``overshoot_pct``, ``settling_ms``, ``peak_is_bound``, ``n_clipped``, ``reason``.
    """
    t = frame["t_s"].to_numpy(dtype=float)
    c = _counts(frame, tendons)
    one = tendons == 1 and "tension_n_0" not in frame.columns
    signals: list[tuple[str, int, str, np.ndarray, np.ndarray | None]] = []
    for i, (role, held) in enumerate(_roles(t, c, phases)):
        y = frame["tension_n" if one else f"tension_n_{i}"].to_numpy(dtype=float)
        signals.append((role, held, "N", y, None if clipped is None else clipped[i]))
    tip = tip_displacement(frame, phases.up_start_s)
    if tip is not None:
        signals.append(("tip", 0, "mm", tip, None))
    if phases.prepull:
        rest = (t >= phases.up_start_s - metrics.RESIDUAL_LENGTH_S) & (t < phases.up_start_s)
    else:
        rest = t < min(t[0] + metrics.RESIDUAL_LENGTH_S, phases.up_start_s)
    spans = (("Up", phases.up_start_s, phases.down_start_s, phases.up_end_s),
             ("Down", phases.down_start_s, phases.end_s, phases.down_end_s))  # fmt: skip
    letout = t >= phases.release_s  # the pre-pull's let-out to the end (none: NaN compares False)
    rows = []
    for motion, start, stop, end in spans:
        lo = end + metrics.RESIDUAL_START_S
        hi = lo + metrics.RESIDUAL_LENGTH_S
        window = (t >= lo) & (t <= hi)
        out = letout if motion == "Down" else np.zeros_like(letout)
        span = ((t >= start) & (t <= hi)) | out  # the let-out counted with the move's Down motion
        short = not window.any() or t[window][-1] < hi - 0.01
        for k, (role, held, unit, y, clip) in enumerate(signals):
            m = metrics.motion_metrics(t, y, start, stop, motion, band, clipped=clip)
            step = m.yf - m.y0
            w = y[window & np.isfinite(y)]
            residual = float((w.max() - w.min()) / 2.0) if w.size > 1 else math.nan
            big = math.isfinite(step) and abs(step) >= MIN_STEP[unit]
            pct = 100.0 * (w.max() - w.min()) / 2.0 / abs(step) if big and w.size > 1 else math.nan
            noise = float(np.ptp(y[rest]) / 2.0) if np.count_nonzero(rest) > 1 else math.nan
            slack = unit == "N" and bool(np.any(y[window] < SLACK_N))
            reason = "; ".join(filter(None, [
                m.reason, "the cable went slack in the residual window" if slack else "",
                "the recording ends before the residual window does" if short else "",
            ]))  # fmt: skip
            rows.append({
                "motion": motion, "signal": "tip" if unit == "mm" else f"tendon {k + 1}",
                "tendon": 0 if unit == "mm" else k + 1, "role": role, "held_steps": held, "unit": unit,
                "lead": phases.lead + 1, "move_start_s": float(start), "move_end_s": end,
                "move_duration_s": end - float(start), "window_end_s": float(stop), "residual": residual,
                "step": step, "residual_pct": pct,
                "noise": noise, "noise_floor_pct": 100.0 * noise / abs(step) if big else math.nan,
                "slack": slack,
                "below_floor": int(np.count_nonzero(y[span] < floor_n)) if unit == "N" and floor_n else 0,
                "below_floor_letout": int(np.count_nonzero(y[out] < floor_n)) if unit == "N" and floor_n
                else 0,
                "least": float(np.min(y[span])) if span.any() else math.nan, "y0": m.y0, "yf": m.yf,
                "peak": m.peak, "overshoot_pct": m.overshoot_pct, "settling_ms": m.settling_ms,
                "peak_is_bound": m.peak_is_bound, "n_clipped": m.n_clipped, "reason": reason,
            })  # fmt: skip
    return pd.DataFrame(rows)


def recording_residuals(rec: Recording, band: float = 0.05) -> tuple[pd.DataFrame, MovePhases, str]:
    """:func:`residual_table` of a loaded recording, with its own lead, pre-pull, floor and range check.

    Returns the table, the phases and why the lead leads (:func:`recording_lead`).

    Raises
    ------
    ValueError
        The lead makes no up-hold-down move (the message names it and the pre-pull).
    """
    sc: dict[str, Any] = rec.meta.get("scenario") or {}
    rig = recording_rig(rec.meta, rec.name)
    lead, why = recording_lead(rec)
    prepull = int(sc.get("prepull_steps") or 0)
    start = sc.get("start_positions_steps") if rec.tendons > 1 else [sc.get("start_position_steps")]
    ok = isinstance(start, list) and len(start) == rec.tendons and all(isinstance(v, int) for v in start)
    f = rec.frame
    t = f["t_s"].to_numpy(float)
    phases = move_phases(t, _counts(f, rec.tendons), lead, prepull, start if ok else None)
    clipped = None
    cal = rec.meta.get("calibration")
    if all(f"adc_{i}" in f.columns for i in range(rec.tendons)) and isinstance(cal, dict):
        keys = ("newtons_per_count", "offset_counts", "mm_per_step")
        clipped = [
            metrics.clipped_samples(f[f"adc_{i}"].to_numpy(), {k: _item(cal.get(k), i) for k in keys}, rig)
            for i in range(rec.tendons)
        ]
    table = residual_table(f, rec.tendons, phases, floor_n=float(rig.arm.tension_floor_n), band=band,
                           clipped=clipped)  # fmt: skip
    return table, phases, why


def _item(value: Any, i: int) -> Any:
    return value[i] if isinstance(value, list | tuple) else value


def move_residuals(frame: pd.DataFrame, column: str = "tension_n", band: float = 0.05) -> pd.DataFrame:
    """Residual vibration of the Up and Down moves of a one-tendon recording, with the noise floor.

    :func:`residual_table` of the one tendon (its ``steps``, the signal ``column``), in the shape the
    one-tendon tuning keeps: one row per motion, ``motion``, ``move_start_s``, ``move_end_s``,
    ``move_duration_s``, ``residual_pct`` (:func:`~metrics.residual_vibration`'s measure: half the
    peak-to-peak 0.1-1.1 s after the move's last step, in % of the Table II step ``|yf - y0|``),
    ``noise_floor_pct`` (the same on the recording's first second, before anything moves: what the residual
    would read on a perfectly still arm), ``slack`` (the cable read slack in the residual window),
    ``peak_n``, ``overshoot_pct``, ``settling_ms``, ``reason``.
    """
    t = frame["t_s"].to_numpy(dtype=float)
    phases = move_phases(t, frame[["steps"]].to_numpy(dtype=float), 0)
    one = frame[["t_s", "steps"]].assign(tension_n=frame[column].to_numpy(dtype=float))
    clipped = None if "adc" not in frame.columns else [metrics.clipped_samples(frame["adc"].to_numpy())]
    table = residual_table(one, 1, phases, band=band, clipped=clipped)
    table = table[table["signal"] == "tendon 1"].rename(columns={"peak": "peak_n"})
    cols = ["motion", "move_start_s", "move_end_s", "move_duration_s", "residual_pct", "noise_floor_pct",
            "slack", "peak_n", "overshoot_pct", "settling_ms", "reason"]  # fmt: skip
    return table[cols].reset_index(drop=True)
