"""Figures of real ring-downs (notebook 11): a trial, one ring-down, the map up and down, damping, residuals.

Data are labelled **"DROPBEAR, real hardware"** (measured by the dataset's authors, CC BY-SA 4.0: the figures
derived from it are too); anything modelled is labelled **"predicted"**. Each function returns the figure;
the notebook saves it (:func:`helpers.plotting.save`).
"""

from __future__ import annotations

from collections.abc import Mapping

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from helpers.paper.identify import IdentificationResult
from helpers.research.modemap import ModeMap

__all__ = ["REAL", "PREDICTED", "trial_overview", "ringdown_fit", "frequency_map", "damping", "residuals"]

REAL = "DROPBEAR, real hardware"
"""The label of measured data."""

PREDICTED = "predicted"
"""The label of anything modelled."""

_MARKERS = {"up": "^", "down": "v"}


def trial_overview(
    t: np.ndarray, position: np.ndarray, vibration: np.ndarray, table: pd.DataFrame, skipped: pd.DataFrame,
    name: str,
) -> plt.Figure:  # fmt: skip
    """The configuration signal with every rest found, and the band-passed vibration with the windows used.

    Parameters
    ----------
    t, position, vibration : numpy.ndarray
        Time (s), the configuration signal (V) and a band-passed vibration channel (V).
    table, skipped : pandas.DataFrame
        The identified ring-downs and the skipped rests (:class:`helpers.research.rest_ringdowns.Ringdowns`).
    name : str
        The trial.
    """
    fig, (a, b) = plt.subplots(2, 1, figsize=(7.0, 4.4), sharex=True)
    a.plot(t, position, color="0.3", lw=0.8)
    a.plot(table["t_stop_s"], table["position"], "o", color="C0", ms=4, label="rest >= 0.3 s: identified")
    if len(skipped):
        a.plot(skipped["t_stop_s"], skipped["position"], "x", color="C3", ms=5, label="shorter rest: skipped")
    a.set_ylabel("PinLoc, V")
    a.set_title(f"{REAL}: {name}")
    a.legend(loc="lower right")
    b.plot(t, vibration, color="0.3", lw=0.5)
    for row in table.itertuples():
        b.axvspan(row.t_stop_s, row.t_stop_s + row.window_s, color="C0", alpha=0.15, lw=0)
    b.set_xlabel("time, s")
    b.set_ylabel("low-g accel. 10-80 Hz, V")
    fig.tight_layout()
    return fig


def ringdown_fit(t: np.ndarray, y: np.ndarray, result: IdentificationResult, title: str) -> plt.Figure:
    """One ring-down (band-passed) with the damped-sine fit and the log decrement's extrema over it."""
    fig, ax = plt.subplots(figsize=(7.0, 3.0))
    lo, hi = result.window_s
    keep = (t >= lo) & (t <= hi)
    ax.plot(t[keep], y[keep], color="0.3", lw=0.8, label=REAL)
    ax.plot(t[keep], result.fit(t[keep]), color="C1", lw=0.9, ls="--", label="damped-sine fit")
    ld = result.logdec
    ax.plot(ld.peak_times, ld.peak_values, "o", color="C0", ms=3, label="log decrement: extrema")
    ax.plot(ld.trough_times, ld.trough_values, "o", color="C0", ms=3)
    ax.set_xlabel("time, s")
    ax.set_ylabel("V")
    ax.set_title(title)
    ax.legend(loc="upper right", ncol=3)
    fig.tight_layout()
    return fig


def frequency_map(rows: pd.DataFrame, mode_map: ModeMap, held_out: pd.DataFrame | None = None) -> plt.Figure:
    """The first mode against the configuration, up and down moves of every trial, and the spread about it.

    Parameters
    ----------
    rows : pandas.DataFrame
        The ring-downs the map was made of (with ``trial``, ``direction``, ``position``, ``f_hz``).
    mode_map : ModeMap
        The map (its positions in volts).
    held_out : pandas.DataFrame, optional
        Ring-downs of other trials, drawn beside it.
    """
    fig, (a, b) = plt.subplots(1, 2, figsize=(7.6, 3.4), gridspec_kw={"width_ratios": [3, 2]})
    x = np.linspace(*mode_map.range_mm, 200)
    a.plot(x, mode_map.at(x).omega_d / (2 * np.pi), color="0.6", lw=1.0, label="map (mean per position)")
    colours = {trial: f"C{i}" for i, trial in enumerate(sorted(rows["trial"].unique()))}
    for (trial, direction), g in rows.groupby(["trial", "direction"]):
        a.plot(g["position"], g["f_hz"], _MARKERS[direction], color=colours[trial], ms=5, mfc="none",
               label=f"{trial}, {direction}")  # fmt: skip
    if held_out is not None and len(held_out):
        a.plot(held_out["position"], held_out["f_hz"], "s", color="C3", ms=4, mfc="none",
               label=", ".join(sorted(held_out["trial"].unique())))  # fmt: skip
    a.set_xlabel("PinLoc (roller position), V")
    a.set_ylabel("first mode, Hz")
    a.set_title(f"{REAL}: the map up and down")
    a.legend(fontsize=7)
    ref = mode_map.at(rows["position"].clip(*mode_map.range_mm)).omega_d / (2 * np.pi)
    for (trial, direction), g in rows.assign(dev=rows["f_hz"] - ref).groupby(["trial", "direction"]):
        b.plot(g["position"], g["dev"], _MARKERS[direction], color=colours[trial], ms=5, mfc="none")
    b.axhline(0.0, color="0.6", lw=0.8)
    b.set_xlabel("PinLoc, V")
    b.set_ylabel("ring-down minus map, Hz")
    b.set_title("spread over trials and directions")
    fig.tight_layout()
    return fig


def damping(rows: pd.DataFrame) -> plt.Figure:
    """Each ring-down's damping ratio (the fit) with its interval (every estimate of that ring-down)."""
    fig, ax = plt.subplots(figsize=(7.0, 3.2))
    colours = {trial: f"C{i}" for i, trial in enumerate(sorted(rows["trial"].unique()))}
    for trial, g in rows.groupby("trial"):
        lo = np.clip(g["zeta_lo"], 1e-5, None)
        ax.errorbar(g["position"], g["zeta"], yerr=[g["zeta"] - lo, g["zeta_hi"] - g["zeta"]], fmt="o", ms=3,
                    color=colours[trial], elinewidth=0.8, capsize=2, label=trial)  # fmt: skip
    ax.set_yscale("log")
    ax.set_xlabel("PinLoc, V")
    ax.set_ylabel("damping ratio")
    ax.set_title(f"{REAL}: damping, fit and the interval of every estimate (clipped at 1e-5)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def residuals(table: pd.DataFrame, order: list[str], durations: Mapping[str, str]) -> plt.Figure:
    """Each design's predicted residual on every held-out ring-down's fitted model (worst over its zeta).

    Parameters
    ----------
    table : pandas.DataFrame
        :func:`helpers.research.ringdown_map.predicted_residuals`.
    order : list of str
        The designs, top to bottom.
    durations : mapping
        Design -> its duration as text (for the labels).
    """
    fig, ax = plt.subplots(figsize=(7.0, 0.45 * len(order) + 1.2))
    for i, name in enumerate(order):
        g = table[table["design"] == name]
        y = np.full(len(g), float(len(order) - 1 - i)) + np.linspace(-0.15, 0.15, max(len(g), 1))[: len(g)]
        ax.plot(np.clip(g["v_worst_pct"], 0.01, None), y, "|", color="C3", ms=7)
        ax.plot(np.clip(g["v_pct"], 0.01, None), y, ".", color="C0", ms=4)
    ax.set_yticks(range(len(order)), [f"{n} ({durations[n]})" for n in reversed(order)])
    ax.set_xscale("log")
    ax.set_xlabel("residual vibration, % of unshaped (dot: fitted zeta; bar: worst over its interval)")
    ax.set_title(f"{PREDICTED}: residual on each held-out ring-down's fitted modal model")
    fig.tight_layout()
    return fig
