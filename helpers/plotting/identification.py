"""Figures of the pulse identification: the paper's Fig. 5 (force response) and Fig. 6 (log decrement)."""

from __future__ import annotations

import math

import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import ArrayLike

from helpers import paper
from helpers.identify import IdentificationResult
from helpers.plotting import save as save_figure

FIG5_NAME = "fig5_force_response.png"
FIG6_NAME = "fig6_logdec_fft.png"


def _source_note(source: str | None) -> str:
    return " (virtual rig)" if source == "virtual-rig" else ""


def fig5_force_response(
    t: ArrayLike,
    adc: ArrayLike,
    window: tuple[float, float] = paper.IDENTIFICATION_RUN["window_s"],
    *,
    source: str | None = None,
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
    fig, ax = plt.subplots()
    ax.plot(t, adc, color="C0", lw=0.8, label="load cell")
    ax.axvspan(*window, color="C1", alpha=0.2, label=f"identification window {window[0]:g}-{window[1]:g} s")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("ADC counts")
    ax.set_xlim(t[0], t[-1])
    ax.set_title("Force response to the velocity pulse" + _source_note(source))
    ax.legend(loc="best")
    if save:
        save_figure(fig, FIG5_NAME)
    return fig


def fig6_logdec_fft(
    result: IdentificationResult,
    t: ArrayLike,
    y: ArrayLike,
    *,
    unit: str = "ADC counts",
    source: str | None = None,
    save: bool = False,
) -> plt.Figure:
    """Fig. 6: upper, the window with the detected peaks and the decay envelope; lower, the FFT amplitude.

    Parameters
    ----------
    result : IdentificationResult
        From :func:`helpers.identify.identify` on (a window of) ``t, y``.
    t, y : array_like
        The signal; only ``result.window`` is drawn when it is set.
    unit : str
        The unit of ``y`` for the axis labels.
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
    if result.window is not None:
        keep = (t >= result.window[0]) & (t <= result.window[1])
        t, y = t[keep], y[keep]
    ld, fft = result.logdec, result.fft
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7.0, 5.4))
    ax1.plot(t, y, color="C0", lw=0.9, label="signal")
    # the envelope from half a period before the first extremum on (it grows without bound backwards)
    t_env = t[t >= ld.t_ref - math.pi / ld.omega_d]
    upper, lower = ld.envelope(t_env)
    ax1.plot(t_env, upper, color="C1", ls="--", lw=1.0, label=f"envelope, zeta = {ld.zeta:.4f}")
    ax1.plot(t_env, lower, color="C1", ls="--", lw=1.0)
    ax1.plot(ld.peak_times, ld.peak_values, "v", color="C3", label=f"{ld.peak_times.size} peaks")
    ax1.plot(ld.trough_times, ld.trough_values, "^", color="C2", label=f"{ld.trough_times.size} troughs")
    ax1.axhline(ld.baseline, color="0.5", lw=0.8)
    ax1.set_xlabel("time (s)")
    ax1.set_ylabel(unit)
    ax1.set_title(
        f"Log decrement: zeta = {result.zeta:.4f}, omega_d = {result.omega_d:.3f} rad/s "
        f"({result.method}){_source_note(source)}"
    )
    ax1.legend(loc="upper right", ncol=2)

    f_top = min(float(fft.freqs_hz[-1]), max(5.0 * fft.frequency_hz, 10.0))
    show = fft.freqs_hz <= f_top
    ax2.plot(fft.freqs_hz[show], fft.amplitude[show], color="C0")
    ax2.plot(
        [fft.frequency_hz],
        [fft.peak_amplitude],
        "o",
        color="C3",
        label=f"{fft.frequency_hz:.3f} Hz = {2.0 * math.pi * fft.frequency_hz:.3f} rad/s",
    )
    ax2.set_xlabel("frequency (Hz)")
    ax2.set_ylabel(f"amplitude ({unit})")
    ax2.set_xlim(0.0, f_top)
    ax2.set_title("Single-sided amplitude spectrum (Hann window)")
    ax2.legend(loc="upper right")
    fig.tight_layout()
    if save:
        save_figure(fig, FIG6_NAME)
    return fig
