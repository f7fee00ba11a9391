"""Figures of the pulse identification: the paper's Fig. 5 (force response) and Fig. 6 (log decrement)."""

from __future__ import annotations

import math

import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import ArrayLike

from helpers.paper import numbers as paper
from helpers.paper.identify import IdentificationResult
from helpers.plotting import finish

FIG5_NAME = "fig5_force_response.png"
FIG6_NAME = "fig6_logdec_fft.png"
METHOD_NAMES = {"fit": "damped-sine fit", "logdec": "log decrement", "fft": "FFT"}
"""How the titles name the identification methods of :data:`helpers.paper.identify.METHODS`."""


def _source_note(source: str | None) -> str:
    return " (virtual rig)" if source == "virtual-rig" else ""


def _decimals(step: float) -> int:
    """Decimals that resolve ``step`` (one significant digit of it), for quoting a value no finer."""
    return max(0, -math.floor(math.log10(step))) if step > 0 else 0


def slack_spans(t: ArrayLike, adc: ArrayLike, zero_counts: float, margin: float = 1.0, min_s: float = 0.05
                ) -> list[tuple[float, float]]:  # fmt: skip
    """Stretches where the load cell reads no tension: the cable is slack (a cable cannot push).

    Parameters
    ----------
    t, adc : array_like
        Time (s) and ADC counts.
    zero_counts : float
        The counts at 0 N (the load-cell calibration's offset).
    margin : float
        Counts above ``zero_counts`` that still count as zero tension (the reading's noise).
    min_s : float
        Shortest stretch reported, s.

    Returns
    -------
    list of (float, float)
        Start and end times of each stretch.
    """
    t = np.asarray(t, dtype=float)
    slack = np.asarray(adc, dtype=float) <= zero_counts + margin
    edges = np.flatnonzero(np.diff(np.concatenate([[0], slack.astype(np.int8), [0]])))
    spans = [(float(t[a]), float(t[b - 1])) for a, b in zip(edges[::2], edges[1::2], strict=True)]
    return [(a, b) for a, b in spans if b - a >= min_s]


def fig5_force_response(
    t: ArrayLike,
    adc: ArrayLike,
    window: tuple[float, float] = paper.IDENTIFICATION_RUN["window_s"],
    *,
    source: str | None = None,
    pulse: dict | None = None,
    zero_counts: float | None = None,
    save: bool = False,
) -> plt.Figure:
    """Fig. 5: the force response to the velocity pulse in raw ADC counts, the identification window shaded.

    Parameters
    ----------
    t, adc : array_like
        Time (s) and ADC counts of the identification run.
    window : (float, float)
        The identification window (s), shaded.
    source : str, optional
        The recording's source (``"hardware"`` or ``"virtual-rig"``); ``"virtual-rig"`` is named in the title.
    pulse : dict, optional
        The pulse as a recording's ``scenario`` holds it (``v_in_mm_s``, ``x_f_mm``, ``t_up_s``,
        ``t_down_s``), named in the title.
    zero_counts : float, optional
        The counts at 0 N (the calibration's offset): stretches at that level are marked as a slack cable
        (:func:`slack_spans`).
    save : bool
        Save as ``figures/fig5_force_response.png``.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    t = np.asarray(t, dtype=float)
    adc = np.asarray(adc, dtype=float)
    if t.shape != adc.shape:
        raise ValueError(f"t and adc must have the same length, got {t.size} and {adc.size}")
    fig, ax = plt.subplots(figsize=(7.0, 4.2))
    ax.plot(t, adc, color="C0", lw=0.8, label="load cell")
    ax.axvspan(*window, color="C1", alpha=0.2, label=f"identification window {window[0]:g}-{window[1]:g} s")
    if zero_counts is not None:
        spans = slack_spans(t, adc, zero_counts)
        for i, (a, b) in enumerate(spans):
            label = "cable slack: the load cell reads 0 N (a cable cannot push)" if i == 0 else None
            ax.axvspan(a, b, facecolor="none", edgecolor="0.4", hatch="///", lw=0.0, label=label)
        ax.axhline(zero_counts, color="0.5", lw=0.6, ls=":")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("ADC counts")
    ax.set_xlim(t[0], t[-1])
    what = ""
    if pulse is not None:
        what = (
            f"\n{pulse['v_in_mm_s']:g} mm/s, {pulse['x_f_mm']:g} mm, up at {pulse['t_up_s']:g} s, "
            f"down at {pulse['t_down_s']:g} s"
        )
    ax.set_title(f"Fig. 5{_source_note(source)}: force response to the velocity pulse{what}", fontsize=10)
    ax.legend(loc="upper right", fontsize=8)
    return finish(fig, FIG5_NAME if save else None)


def fig6_logdec_fft(
    result: IdentificationResult,
    t: ArrayLike,
    y: ArrayLike,
    *,
    source: str | None = None,
    save: bool = False,
) -> plt.Figure:
    """Fig. 6: upper, the window with the detected peaks and the decay envelope; lower, the FFT amplitude.

    Parameters
    ----------
    result : IdentificationResult
        From :func:`helpers.paper.identify.identify` on (a window of) ``t, y``.
    t, y : array_like
        The signal (ADC counts); only ``result.window_s`` is drawn when it is set.
    source : str, optional
        ``"virtual-rig"`` is named in the title.
    save : bool
        Save as ``figures/fig6_logdec_fft.png``.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if result.window_s is not None:
        keep = (t >= result.window_s[0]) & (t <= result.window_s[1])
        t, y = t[keep], y[keep]
    ld, fft = result.logdec, result.fft
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7.0, 5.4))
    ax1.plot(t, y, color="C0", lw=0.9, label="signal")
    # the envelope from half a period before the first extremum on (it grows without bound backwards)
    t_env = t[t >= ld.t_ref - math.pi / ld.omega_d]
    upper, lower = ld.envelope(t_env)
    ax1.plot(
        t_env, upper, color="C1", ls="--", lw=1.0,
        label=f"log-decrement envelope: zeta_ld = {ld.zeta:.4f}, omega_ld = {ld.omega_d:.2f} rad/s",
    )  # fmt: skip
    ax1.plot(t_env, lower, color="C1", ls="--", lw=1.0)
    ax1.plot(ld.peak_times, ld.peak_values, "v", color="C3", label=f"{ld.peak_times.size} peaks")
    ax1.plot(ld.trough_times, ld.trough_values, "^", color="C2", label=f"{ld.trough_times.size} troughs")
    ax1.axhline(ld.baseline, color="0.5", lw=0.8)
    ax1.set_xlabel("time (s)")
    ax1.set_ylabel("ADC counts")
    ax1.set_title(
        f"Fig. 6{_source_note(source)}: identified zeta = {result.zeta:.4f}, omega_d = {result.omega_d:.3f} "
        f"rad/s ({METHOD_NAMES.get(result.method, result.method)})\nthe log decrement's envelope and the FFT",
        fontsize=9,
    )
    low, high = ax1.get_ylim()
    ax1.set_ylim(low, high + 0.45 * (high - low))  # room for the legend above the signal
    ax1.legend(loc="upper right", ncol=2, fontsize=8)

    f_top = min(float(fft.freqs_hz[-1]), max(5.0 * fft.frequency_hz, 10.0))
    show = fft.freqs_hz <= f_top
    ax2.plot(fft.freqs_hz[show], fft.amplitude[show], color="C0")
    # a window of length T resolves frequencies only to 1/T: quote the peak no finer than half a bin
    half_bin = fft.resolution_hz / 2.0
    digits = _decimals(half_bin)
    ax2.plot(
        [fft.frequency_hz],
        [fft.peak_amplitude],
        "o",
        color="C3",
        label=(
            f"peak {fft.frequency_hz:.{digits}f} ± {half_bin:.{digits}f} Hz "
            f"({1.0 / fft.resolution_hz:.2g} s window: bins {fft.resolution_hz:.2g} Hz apart)"
        ),
    )
    ax2.set_xlabel("frequency (Hz)")
    ax2.set_ylabel("amplitude (ADC counts)")
    ax2.set_xlim(0.0, f_top)
    ax2.set_title("Single-sided amplitude spectrum (Hann window)")
    ax2.legend(loc="upper right", fontsize=8)
    return finish(fig, FIG6_NAME if save else None)
