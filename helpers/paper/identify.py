"""Identification of the dominant vibration mode from a free decay (the paper's pulse-release window).

Three independent estimates are made on the same window of samples ``(t, y)``; ``y`` may be the tension in N
or the raw ADC counts (the mode's frequency and damping do not depend on the sensor's gain and offset):

- :func:`log_decrement`: successive extrema of the signal about its equilibrium, a weighted straight-line fit
  of ``ln |extremum - baseline|`` against time (the slope is ``-zeta * omega_n``) and of the extremum times
  against their half-cycle index (the slope is ``pi / omega_d``). The extrema are returned for plotting.
- :func:`fft_peak`: the dominant frequency of the Hann-windowed, zero-padded spectrum, refined by a parabola
  through the three highest bins of the log magnitude. It gives ``omega_d`` only.
- :func:`damped_sine_fit`: nonlinear least squares of
  ``y = c + A exp(-zeta omega_n (t - t0)) sin(omega_d (t - t0) + phi)``, started from the other two, with
  standard errors from the Jacobian at the solution.

:func:`identify` runs all three and reports the one chosen by ``method``. The identified mode's file,
``data/identification/result.json``, is owned here: :func:`save_identification` writes it and
:func:`load_identification` reads it back as an :class:`IdentifiedMode`.

The half-power bandwidth of the spectrum is deliberately not used for the damping: on a power spectrum with a
``1/sqrt(2)`` threshold it underestimates zeta by about 35 % at zeta = 0.044, and the
window holds only a few cycles, so the spectral peak is broadened by the window rather than by the damping.

Standard errors assume independent, identically distributed residuals (white noise, including the ADC's
quantisation once the noise dithers it). Coloured residuals (other modes, nonlinearity) make them optimistic.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import optimize, signal

from helpers.base.jsonfile import DataFileError, read_json, write_json
from helpers.base.noise import white_noise_std
from helpers.base.paths import IDENTIFICATION_RESULT
from helpers.paper.modes import check_mode, omega_n_from_damped

FloatArray = NDArray[np.float64]

MIN_SAMPLES = 16
"""Fewest samples a window may hold."""

MIN_CYCLES = 2.0
"""Fewest damped periods a window must hold for :func:`identify`."""

UNIFORM_TOLERANCE = 0.05
"""Largest relative deviation of any sample interval from the median interval (a uniform time base)."""

PAD_FACTOR = 16
"""The FFT's zero padding: the spectrum holds at least this many times the window's samples."""

METHODS = ("fit", "logdec", "fft")
"""Names of the estimates :func:`identify` can report."""


# ----------------------------------------------------------------------------------------------------
# input checks


def _as_window(
    t: ArrayLike, y: ArrayLike, window: tuple[float, float] | None = None
) -> tuple[FloatArray, FloatArray, float]:
    """Validate ``(t, y)``, cut ``window`` out of it and return ``(t, y, dt)``.

    Raises
    ------
    ValueError
        Naming the problem: shapes, NaN, unsorted or non-uniform time, a window that is empty or too short.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.ndim != 1 or y.ndim != 1:
        raise ValueError(f"t and y must be 1-D arrays, got shapes {t.shape} and {y.shape}")
    if t.shape != y.shape:
        raise ValueError(f"t and y must have the same length, got {t.size} and {y.size}")
    if window is not None:
        lo, hi = (float(w) for w in window)
        if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
            raise ValueError(f"window must be (start, end) with end > start, got {window!r}")
        keep = (t >= lo) & (t <= hi)
        t, y = t[keep], y[keep]
        if t.size == 0:
            raise ValueError(f"window {window!r} holds no samples")
    if t.size < MIN_SAMPLES:
        raise ValueError(f"window too short: {t.size} samples, need at least {MIN_SAMPLES}")
    if not np.all(np.isfinite(t)):
        raise ValueError("t contains NaN or infinite values")
    if not np.all(np.isfinite(y)):
        raise ValueError(f"y contains {int(np.sum(~np.isfinite(y)))} NaN or infinite values")
    dts = np.diff(t)
    if np.any(dts <= 0):
        raise ValueError("t must be strictly increasing (unsorted or repeated time stamps)")
    dt = float(np.median(dts))
    worst = float(np.max(np.abs(dts - dt)) / dt)
    if worst > UNIFORM_TOLERANCE:
        raise ValueError(
            f"t is not uniformly sampled: an interval deviates {100 * worst:.1f} % from the median "
            f"{1e3 * dt:.4f} ms (missing samples?); tolerance {100 * UNIFORM_TOLERANCE:.0f} %"
        )
    return t, y, dt


def _quantum(y: FloatArray) -> float:
    """The quantisation step of ``y`` if it lies on a grid (e.g. ADC counts), else 0."""
    levels = np.unique(y)
    if levels.size < 2 or levels.size > y.size // 2:
        return 0.0
    return float(np.min(np.diff(levels)))


# ----------------------------------------------------------------------------------------------------
# FFT


@dataclass(frozen=True, eq=False)
class FftResult:
    """Dominant frequency of a window by FFT.

    Attributes
    ----------
    omega_d : float
        Dominant angular frequency, rad/s (interpolated between bins).
    frequency_hz : float
        The same in Hz.
    peak_amplitude : float
        Single-sided amplitude at the peak, in the units of ``y``.
    freqs_hz, amplitude : numpy.ndarray
        The single-sided amplitude spectrum (zero-padded, Hann window, amplitude-corrected), for plotting.
    resolution_hz : float
        Bin spacing without zero padding, ``1 / (n dt)``.
    """

    omega_d: float
    frequency_hz: float
    peak_amplitude: float
    freqs_hz: FloatArray
    amplitude: FloatArray
    resolution_hz: float


def fft_peak(
    t: ArrayLike,
    y: ArrayLike,
    *,
    f_min_hz: float | None = None,
    f_max_hz: float | None = None,
) -> FftResult:
    """Dominant frequency of ``y(t)`` from its windowed, zero-padded FFT.

    The mean is removed, a Hann window applied and the spectrum zero-padded to at least :data:`PAD_FACTOR`
    times the window length; the highest bin in ``[f_min_hz, f_max_hz]`` (default: above 1.5 cycles per
    window, so that the leakage of the removed mean cannot win, up to Nyquist) is refined by a parabola
    through the logarithms of it and its two neighbours.

    Parameters
    ----------
    t, y : array_like
        Uniformly sampled time (s) and signal.
    f_min_hz, f_max_hz : float, optional
        Search band in Hz.

    Returns
    -------
    FftResult
        The dominant frequency and the spectrum.

    Raises
    ------
    ValueError
        For invalid input or an empty search band.
    """
    t, y, dt = _as_window(t, y)
    n = t.size
    n_fft = 1 << int(math.ceil(math.log2(n * PAD_FACTOR)))
    w = signal.windows.hann(n, sym=False)
    spectrum = np.fft.rfft((y - y.mean()) * w, n_fft)
    amplitude = 2.0 * np.abs(spectrum) / w.sum()
    freqs = np.fft.rfftfreq(n_fft, dt)
    resolution = 1.0 / (n * dt)
    lo = 1.5 * resolution if f_min_hz is None else float(f_min_hz)
    hi = 0.5 / dt if f_max_hz is None else float(f_max_hz)
    band = np.flatnonzero((freqs >= lo) & (freqs <= hi))
    band = band[(band > 0) & (band < freqs.size - 1)]
    if band.size == 0:
        raise ValueError(f"FFT search band {lo:.3f}-{hi:.3f} Hz holds no interior bins")
    k = int(band[np.argmax(amplitude[band])])
    a, b, c = np.log(np.maximum(amplitude[k - 1 : k + 2], np.finfo(float).tiny))
    denom = a - 2.0 * b + c
    shift = 0.0 if denom == 0 else float(np.clip(0.5 * (a - c) / denom, -0.5, 0.5))
    f_peak = float(freqs[k] + shift * (freqs[1] - freqs[0]))
    peak_amp = float(np.exp(b - 0.25 * (a - c) * shift))
    return FftResult(
        omega_d=2.0 * math.pi * f_peak,
        frequency_hz=f_peak,
        peak_amplitude=peak_amp,
        freqs_hz=freqs,
        amplitude=amplitude,
        resolution_hz=resolution,
    )


# ----------------------------------------------------------------------------------------------------
# log decrement


@dataclass(frozen=True, eq=False)
class LogDecrementResult:
    """Log-decrement estimate from the successive extrema of a free decay.

    Attributes
    ----------
    zeta, zeta_std : float
        Damping ratio and its standard error (from the envelope regression).
    omega_d, omega_d_std : float
        Damped angular frequency (rad/s) from the extremum spacing, and its standard error.
    sigma : float
        Decay rate ``zeta * omega_n`` (1/s), minus the slope of ``ln |extremum - baseline|``.
    baseline : float
        The equilibrium the extrema are measured from.
    envelope_amplitude : float
        Envelope ``|y - baseline|`` at ``t_ref``; the envelope is
        ``envelope_amplitude exp(-sigma (t - t_ref))``.
    t_ref : float
        Time of the first extremum.
    peak_times, peak_values : numpy.ndarray
        Detected maxima (sub-sample refined), for plotting.
    trough_times, trough_values : numpy.ndarray
        Detected minima (sub-sample refined), for plotting.
    """

    zeta: float
    zeta_std: float
    omega_d: float
    omega_d_std: float
    sigma: float
    baseline: float
    envelope_amplitude: float
    t_ref: float
    peak_times: FloatArray
    peak_values: FloatArray
    trough_times: FloatArray
    trough_values: FloatArray

    def envelope(self, t: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Return the upper and lower decay envelopes ``baseline +- a exp(-sigma (t - t_ref))`` at ``t``."""
        t = np.asarray(t, dtype=float)
        e = self.envelope_amplitude * np.exp(-self.sigma * (t - self.t_ref))
        return self.baseline + e, self.baseline - e


def _refine_extremum(
    t: FloatArray, y: FloatArray, k: int, half: int, sign: float
) -> tuple[float, float] | None:
    """Least-squares parabola through ``y`` around sample ``k``; return its vertex (time, value).

    The neighbourhood (``k +- half`` samples) is re-centred on the vertex up to three times, because the
    noisy sample maximum can sit well off the true extremum where the peak is flat. Returns None (the
    extremum is dropped) when the neighbourhood would cross the window's edge, the parabola curves the wrong
    way (``sign`` +1 for a maximum, -1 for a minimum) or its vertex lies outside the neighbourhood.
    """
    for _ in range(4):
        lo, hi = k - half, k + half + 1
        if lo < 0 or hi > t.size:
            return None
        tau = t[lo:hi] - t[k]
        c2, c1, c0 = np.polyfit(tau, y[lo:hi], 2)
        if sign * c2 >= 0:
            return None
        x = -c1 / (2.0 * c2)
        if not (tau[0] <= x <= tau[-1]):
            return None
        k_new = int(np.argmin(np.abs(t - (t[k] + x))))
        if k_new == k:
            break
        k = k_new
    return float(t[k] + x), float(c0 - c1 * c1 / (4.0 * c2))


def _weighted_line(x: FloatArray, y: FloatArray, w: FloatArray) -> tuple[float, float, float]:
    """Weighted least-squares line ``y = a + b x`` (weights = inverse variances up to a factor).

    Returns
    -------
    (a, b, b_std)
        Intercept, slope, and the slope's standard error with the residual variance estimated from the data
        (its callers pass the extrema of a window, at least three: :func:`_extrema` refuses fewer).
    """
    sw = w.sum()
    xm = float((w * x).sum() / sw)
    ym = float((w * y).sum() / sw)
    sxx = float((w * (x - xm) ** 2).sum())
    b = float((w * (x - xm) * (y - ym)).sum() / sxx)
    a = ym - b * xm
    resid = y - a - b * x
    s2 = float((w * resid**2).sum() / (x.size - 2))
    return a, b, math.sqrt(s2 / sxx)


def log_decrement(
    t: ArrayLike,
    y: ArrayLike,
    *,
    omega_hint: float | None = None,
) -> LogDecrementResult:
    """Damping and damped frequency from the successive extrema of a free decay.

    Steps:

    1. a rough frequency from :func:`fft_peak` (or ``omega_hint``) sets the minimum distance between
       extrema of one sign (0.6 periods) and the half-width of the sub-sample refinement (1/8 period);
    2. maxima and minima are found with :func:`scipy.signal.find_peaks`; an extremum counts only if its
       prominence exceeds the larger of 6 times the noise (estimated robustly from the second difference),
       3 quantisation steps (if ``y`` lies on a grid such as ADC counts) and 2 % of the window's range; each
       is refined by a least-squares parabola through its neighbourhood (an extremum whose neighbourhood
       crosses the window's edge is dropped);
    3. the baseline (the equilibrium) is fitted together with the envelope, ``c +- B exp(-sigma t)``, through
       all extrema (the extrema of a damped sine lie exactly on such an envelope);
    4. ``sigma`` is minus the slope of a weighted line through ``ln |extremum - baseline|`` against time
       (weights ``|extremum - baseline|^2``, the inverse variance of the logarithm), ``omega_d`` is ``pi``
       over the slope of the extremum times against their half-cycle index, and
       ``zeta = delta / sqrt(4 pi^2 + delta^2)`` with ``delta = 2 pi sigma / omega_d``.

    Parameters
    ----------
    t, y : array_like
        Uniformly sampled time (s) and signal (N or ADC counts).
    omega_hint : float, optional
        Rough damped frequency (rad/s) instead of the FFT estimate.

    Returns
    -------
    LogDecrementResult
        The estimate and the extrema.

    Raises
    ------
    ValueError
        For invalid input, or fewer than two maxima / three extrema (less than about one cycle).
    """
    t, y, dt = _as_window(t, y)
    omega = float(omega_hint) if omega_hint is not None else fft_peak(t, y).omega_d
    if not (math.isfinite(omega) and omega > 0):
        raise ValueError(f"omega_hint must be a positive frequency, got {omega_hint!r}")
    period = 2.0 * math.pi / omega
    prominence = max(6.0 * white_noise_std(y), 3.0 * _quantum(y), 0.02 * float(np.ptp(y)))
    peaks, troughs = _extrema(t, y, dt, period, prominence)
    ext_t = np.concatenate([peaks[:, 0], troughs[:, 0]])
    ext_y = np.concatenate([peaks[:, 1], troughs[:, 1]])
    sign = np.concatenate([np.ones(len(peaks)), -np.ones(len(troughs))])
    order = np.argsort(ext_t)
    ext_t, ext_y, sign = ext_t[order], ext_y[order], sign[order]
    t_ref = float(ext_t[0])
    omega_d, omega_d_std = _frequency_from_extrema(ext_t, period)
    c = _envelope_baseline(ext_t - t_ref, ext_y, sign, omega_d)
    amp = sign * (ext_y - c)
    if np.any(amp <= 0):
        raise ValueError(
            f"baseline {c:.6g} does not lie between the peaks and troughs; the window is not a free decay "
            "about one equilibrium (drift?) - try another window"
        )
    ln_a, neg_sigma, sigma_std = _weighted_line(ext_t - t_ref, np.log(amp), amp**2)
    sigma = -neg_sigma
    delta = sigma * 2.0 * math.pi / omega_d
    zeta = delta / math.sqrt(4.0 * math.pi**2 + delta**2)
    dzeta_ddelta = 4.0 * math.pi**2 / (4.0 * math.pi**2 + delta**2) ** 1.5
    zeta_std = abs(dzeta_ddelta) * 2.0 * math.pi / omega_d * sigma_std
    return LogDecrementResult(
        zeta=zeta,
        zeta_std=zeta_std,
        omega_d=omega_d,
        omega_d_std=omega_d_std,
        sigma=sigma,
        baseline=c,
        envelope_amplitude=float(math.exp(ln_a)),
        t_ref=t_ref,
        peak_times=peaks[:, 0].copy(),
        peak_values=peaks[:, 1].copy(),
        trough_times=troughs[:, 0].copy(),
        trough_values=troughs[:, 1].copy(),
    )


def _peaks(y: FloatArray, prominence: float, distance: int) -> np.ndarray:
    """``scipy.signal.find_peaks(y, prominence=, distance=)`` with ties broken the same on every CPU.

    SciPy thins peaks closer than ``distance`` from the highest down, ordered by ``numpy.argsort``, whose
    default sort orders equal heights (common on ADC counts) differently depending on the SIMD sort numpy
    dispatches to. Here the order is a stable sort (equal heights: the later peak first), then the
    prominence filter, as in SciPy.
    """
    peaks, _ = signal.find_peaks(y)
    keep = np.ones(peaks.size, dtype=bool)
    for j in np.argsort(y[peaks], kind="stable")[::-1]:
        if not keep[j]:
            continue
        near = np.abs(peaks - peaks[j]) < distance
        near[j] = False
        keep[near] = False
    peaks = peaks[keep]
    prominences = signal.peak_prominences(y, peaks)[0]
    return peaks[prominences >= prominence]


def _extrema(
    t: FloatArray, y: FloatArray, dt: float, period: float, prominence: float
) -> tuple[FloatArray, FloatArray]:
    """Peaks and troughs ``(time, value)`` above ``prominence``, refined by parabolas (step 2 above)."""
    distance = max(1, int(0.6 * period / dt))
    half = max(2, int(round(period / 8.0 / dt)))
    idx_max = _peaks(y, prominence, distance)
    idx_min = _peaks(-y, prominence, distance)
    if idx_max.size < 2 or idx_max.size + idx_min.size < 3:
        raise ValueError(
            f"too few cycles above the noise: found {idx_max.size} peaks and {idx_min.size} troughs with "
            f"prominence >= {prominence:.4g}; the log decrement needs at least 2 peaks (about 2 cycles)"
        )
    refined_max = [_refine_extremum(t, y, int(k), half, 1.0) for k in idx_max]
    refined_min = [_refine_extremum(t, y, int(k), half, -1.0) for k in idx_min]
    peaks = np.array([p for p in refined_max if p is not None]).reshape(-1, 2)
    troughs = np.array([p for p in refined_min if p is not None]).reshape(-1, 2)
    if len(peaks) < 2 or len(peaks) + len(troughs) < 3:
        raise ValueError(
            f"too few cycles: only {len(peaks)} peaks and {len(troughs)} troughs lie a full refinement "
            f"neighbourhood ({half} samples) inside the window; the log decrement needs at least 2 peaks"
        )
    return peaks, troughs


def _frequency_from_extrema(ext_t: FloatArray, period: float) -> tuple[float, float]:
    """Damped frequency and its standard error from the extremum times, half a period apart.

    The index advances by the locally rounded number of half periods, so a dropped extremum or a rough
    hint cannot shift the count.
    """
    steps = np.maximum(1.0, np.round(np.diff(ext_t) / (0.5 * period)))
    half_index = np.concatenate([[0.0], np.cumsum(steps)])
    _, slope, slope_std = _weighted_line(half_index, ext_t, np.ones_like(ext_t))
    return math.pi / slope, math.pi * slope_std / slope**2


def _envelope_baseline(tau: FloatArray, ext_y: FloatArray, sign: FloatArray, omega_d: float) -> float:
    """Fit ``ext_y = c + sign * B exp(-s tau)`` to the extrema and return ``c``."""
    c0 = 0.5 * (float(ext_y[sign > 0].mean()) + float(ext_y[sign < 0].mean()))
    b0 = max(float(np.max(np.abs(ext_y - c0))), np.finfo(float).tiny)

    def resid(p: FloatArray) -> FloatArray:
        c, b, s = p
        return c + sign * b * np.exp(-s * tau) - ext_y

    sol = optimize.least_squares(resid, [c0, b0, 0.05 * omega_d], method="lm", x_scale="jac")
    c = float(sol.x[0])
    return c if (sol.success and math.isfinite(c)) else c0


# ----------------------------------------------------------------------------------------------------
# damped-sine fit


@dataclass(frozen=True, eq=False)
class DampedSineFit:
    """Least-squares fit of ``y = c + A exp(-zeta omega_n (t - t0)) sin(omega_d (t - t0) + phi)``.

    Attributes
    ----------
    zeta, omega_d, amplitude, phase, offset : float
        Fitted parameters (``omega_n = omega_d / sqrt(1 - zeta^2)``).
    zeta_std, omega_d_std : float
        Standard errors from ``s^2 (J^T J)^-1`` at the solution, ``s^2`` the residual variance.
    t0 : float
        Time origin (the window's first sample).
    rms_residual : float
        Root-mean-square residual, in the units of ``y``.
    """

    zeta: float
    omega_d: float
    amplitude: float
    phase: float
    offset: float
    zeta_std: float
    omega_d_std: float
    t0: float
    rms_residual: float

    def __call__(self, t: ArrayLike) -> FloatArray:
        """Evaluate the fitted model at ``t``."""
        return _damped_sine(
            np.asarray(t, dtype=float) - self.t0,
            self.offset,
            self.amplitude,
            self.zeta,
            self.omega_d,
            self.phase,
        )


def _damped_sine(tau: FloatArray, c: float, a: float, zeta: float, wd: float, phi: float) -> FloatArray:
    sigma = zeta * wd / math.sqrt(max(1.0 - zeta * zeta, 1e-12))
    return c + a * np.exp(-sigma * tau) * np.sin(wd * tau + phi)


def damped_sine_fit(t: ArrayLike, y: ArrayLike, *, zeta0: float, omega_d0: float) -> DampedSineFit:
    """Fit a damped sinusoid plus a constant to ``y(t)`` by nonlinear least squares.

    The start values are given (:func:`identify`: ``omega_d`` from :func:`fft_peak`, ``zeta`` from
    :func:`log_decrement`); offset, amplitude and phase then follow from a linear least-squares fit with the
    decay fixed. The fit is :func:`scipy.optimize.least_squares` (Levenberg-Marquardt).

    Parameters
    ----------
    t, y : array_like
        Uniformly sampled time (s) and signal.
    zeta0, omega_d0 : float
        Start values for the damping ratio and the damped frequency (rad/s).

    Returns
    -------
    DampedSineFit
        Parameters and standard errors.

    Raises
    ------
    ValueError
        For invalid input.
    RuntimeError
        If the fit does not converge to a decaying oscillation (``0 < zeta < 1``).
    """
    t, y, _ = _as_window(t, y)
    tau = t - t[0]
    sigma0 = zeta0 * omega_d0 / math.sqrt(1.0 - zeta0**2)
    env = np.exp(-sigma0 * tau)
    basis = np.column_stack([np.ones_like(tau), env * np.sin(omega_d0 * tau), env * np.cos(omega_d0 * tau)])
    (c0, s0, k0), *_ = np.linalg.lstsq(basis, y, rcond=None)
    p0 = np.array([c0, math.hypot(s0, k0), zeta0, omega_d0, math.atan2(k0, s0)])

    def resid(p: FloatArray) -> FloatArray:
        return _damped_sine(tau, *p) - y

    sol = optimize.least_squares(resid, p0, method="lm", x_scale="jac")
    c, a, zeta, wd, phi = (float(v) for v in sol.x)
    if a < 0:  # the same curve with a positive amplitude
        a, phi = -a, phi + math.pi
    phi = (phi + math.pi) % (2.0 * math.pi) - math.pi
    if not (sol.success and 0.0 < zeta < 1.0 and wd > 0):
        raise RuntimeError(
            f"damped-sine fit did not converge to a decaying oscillation (zeta={zeta:.4g}, "
            f"omega_d={wd:.4g} rad/s, status {sol.status}: {sol.message})"
        )
    n, n_par = y.size, p0.size
    rss = float(np.sum(sol.fun**2))
    jac = sol.jac
    try:
        cov = np.linalg.inv(jac.T @ jac) * rss / (n - n_par)
        std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        std = np.full(n_par, math.nan)
    return DampedSineFit(
        zeta=zeta,
        omega_d=wd,
        amplitude=a,
        phase=phi,
        offset=c,
        zeta_std=float(std[2]),
        omega_d_std=float(std[3]),
        t0=float(t[0]),
        rms_residual=math.sqrt(rss / n),
    )


# ----------------------------------------------------------------------------------------------------
# entry point


MISSING_HINT = (
    "record and analyse the identification run first: `python -m helpers record all`, or the live cell of "
    "notebook 02"
)


@dataclass(frozen=True)
class IdentifiedMode:
    """The content of ``data/identification/result.json``: the identified mode and where it came from.

    Attributes
    ----------
    omega_d, zeta : float
        Damped frequency (rad/s) and damping ratio of the dominant mode.
    omega_d_std, zeta_std : float
        Their standard errors (NaN where the method gives none).
    method : str
        ``"fit"``, ``"logdec"`` or ``"fft"``.
    window_s : tuple of float or None
        The analysed window.
    recording, source : str or None
        The analysed recording's name and its source (``"hardware"`` or ``"virtual-rig"``).
    """

    omega_d: float
    zeta: float
    omega_d_std: float = math.nan
    zeta_std: float = math.nan
    method: str = "fit"
    window_s: tuple[float, float] | None = None
    recording: str | None = None
    source: str | None = None

    @property
    def omega_n(self) -> float:
        """Undamped natural frequency, rad/s."""
        return omega_n_from_damped(self.omega_d, self.zeta)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> IdentifiedMode:
        """Read the file's content; ``ValueError`` names a missing key or a value out of range."""
        missing = [k for k in ("zeta", "omega_d", "method") if k not in data]
        if missing:
            raise ValueError(f"missing key(s) {', '.join(missing)}")
        omega_d, zeta = data["omega_d"], data["zeta"]
        check_mode(omega_d, zeta, "omega_d")
        method = data["method"]
        if method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {method!r}")
        window = data.get("window_s")
        if window is not None:
            if not (isinstance(window, list | tuple) and len(window) == 2):
                raise ValueError(f"window_s must be [start, end], got {window!r}")
            window = (float(window[0]), float(window[1]))

        def std(key: str) -> float:
            v = data.get(key)
            return math.nan if v is None else float(v)

        return cls(
            omega_d=float(omega_d),
            zeta=float(zeta),
            omega_d_std=std("omega_d_std"),
            zeta_std=std("zeta_std"),
            method=str(method),
            window_s=window,
            recording=data.get("recording"),
            source=data.get("source"),
        )

    def to_dict(self) -> dict[str, Any]:
        """The keys :meth:`from_dict` reads (NaN as None), and ``omega_n``."""
        return {
            "zeta": float(self.zeta),
            "omega_d": float(self.omega_d),
            "zeta_std": _json_float(self.zeta_std),
            "omega_d_std": _json_float(self.omega_d_std),
            "omega_n": float(self.omega_n),
            "method": self.method,
            "window_s": None if self.window_s is None else [float(w) for w in self.window_s],
            "recording": self.recording,
            "source": self.source,
        }


@dataclass(frozen=True, eq=False, kw_only=True)
class IdentificationResult(IdentifiedMode):
    """The dominant mode identified from one window (an :class:`IdentifiedMode`) and every method's result.

    Attributes
    ----------
    zeta, zeta_std, omega_d, omega_d_std, method, window_s, recording, source
        As :class:`IdentifiedMode`'s: the estimate of the method named by ``method`` (for ``"fft"``, which
        gives no damping, the log decrement's damping, and no standard error of ``omega_d``: an interpolated
        spectral peak has no statistical error of its own; its accuracy on synthetic decays is stated in the
        tests); ``window_s`` as requested (None: the whole input); the provenance set by
        :func:`identify_recording`.
    n_cycles : float
        Damped periods in the analysed window.
    fit, logdec, fft : sub-results
        :class:`DampedSineFit` (None if it failed and was not the chosen method), :class:`LogDecrementResult`,
        :class:`FftResult`.
    """

    n_cycles: float
    fit: DampedSineFit | None
    logdec: LogDecrementResult
    fft: FftResult

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (the content of ``data/identification/result.json``).

        :meth:`IdentifiedMode.to_dict`'s keys (what :func:`load_identification` reads back), then
        ``n_cycles`` and ``estimates`` (each method's ``zeta``/``omega_d`` for comparison). Use
        :func:`dataclasses.replace` to set the provenance of a result from :func:`identify`.
        """
        fft = {"zeta": None, "zeta_std": None, "omega_d": float(self.fft.omega_d), "omega_d_std": None}
        estimates = {"logdec": _estimate(self.logdec), "fft": fft}
        if self.fit is not None:
            estimates["fit"] = _estimate(self.fit)
        return {**super().to_dict(), "n_cycles": float(self.n_cycles), "estimates": estimates}

    def summary(self) -> str:
        """A fixed-precision, multi-line summary for notebooks."""
        names = {"fit": "damped-sine fit", "logdec": "log decrement", "fft": "FFT peak (zeta: log decrement)"}
        window = self.window_s
        where = "whole input" if window is None else f"window {window[0]:.3f}-{window[1]:.3f} s"
        lines = [
            f"method  : {names[self.method]} on the {where} ({self.n_cycles:.1f} cycles)",
            f"zeta    : {self.zeta:.4f} +- {_pm(self.zeta_std, 4)}",
            f"omega_d : {self.omega_d:.3f} +- {_pm(self.omega_d_std, 3)} rad/s "
            f"(f_d = {self.omega_d / (2.0 * math.pi):.4f} Hz)",
            f"omega_n : {self.omega_n:.3f} rad/s",
            f"log decrement : zeta = {self.logdec.zeta:.4f}, omega_d = {self.logdec.omega_d:.3f} rad/s "
            f"({self.logdec.peak_times.size} peaks, {self.logdec.trough_times.size} troughs)",
            f"FFT peak      : omega_d = {self.fft.omega_d:.3f} rad/s",
        ]
        if self.fit is not None:
            lines.append(
                f"damped-sine fit: zeta = {self.fit.zeta:.4f}, omega_d = {self.fit.omega_d:.3f} rad/s "
                f"(rms residual {self.fit.rms_residual:.3g})"
            )
        return "\n".join(lines)


def _pm(x: float, digits: int) -> str:
    return f"{x:.{digits}f}" if math.isfinite(x) else "n/a"


def _json_float(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _estimate(result: LogDecrementResult | DampedSineFit) -> dict[str, float | None]:
    """One method's estimate as :meth:`IdentificationResult.to_dict` lists it."""
    return {
        "zeta": float(result.zeta),
        "zeta_std": _json_float(result.zeta_std),
        "omega_d": float(result.omega_d),
        "omega_d_std": _json_float(result.omega_d_std),
    }


def identify(
    t: ArrayLike,
    y: ArrayLike,
    window: tuple[float, float] | None = None,
    method: Literal["fit", "logdec", "fft"] = "fit",
) -> IdentificationResult:
    """Identify the dominant mode (zeta, omega_d) from a free decay.

    Parameters
    ----------
    t, y : array_like
        Time (s) and signal (tension in N or ADC counts) of a recording.
    window : (float, float), optional
        Analyse only ``window[0] <= t <= window[1]`` (the paper: ``(9.0, 10.0)``).
    method : {"fit", "logdec", "fft"}
        Which estimate to report: the damped-sine fit (default), the log decrement, or the FFT peak frequency
        with the log decrement's damping. All three are computed and kept in the result.

    Returns
    -------
    IdentificationResult
        The estimate and every method's sub-result.

    Raises
    ------
    ValueError
        For invalid input, an unknown method, or a window with fewer than :data:`MIN_CYCLES` cycles (counted
        from the FFT peak).
    RuntimeError
        If ``method="fit"`` and the fit does not converge.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    win = None if window is None else (float(window[0]), float(window[1]))
    tw, yw, dt = _as_window(t, y, win)
    duration = tw.size * dt
    fft = fft_peak(tw, yw)
    cycles = fft.frequency_hz * duration
    if cycles < MIN_CYCLES:
        raise ValueError(
            f"too few cycles: the window ({duration:.3f} s) holds {cycles:.2f} damped periods of the "
            f"dominant oscillation, need at least {MIN_CYCLES:g}"
        )
    logdec = log_decrement(tw, yw, omega_hint=fft.omega_d)
    try:
        fit: DampedSineFit | None = damped_sine_fit(tw, yw, zeta0=logdec.zeta, omega_d0=fft.omega_d)
    except RuntimeError:
        if method == "fit":
            raise
        fit = None
    chosen = fit if method == "fit" else logdec  # the FFT gives no damping: the log decrement's
    assert chosen is not None
    zeta, zeta_std = chosen.zeta, chosen.zeta_std
    omega_d, omega_d_std = chosen.omega_d, chosen.omega_d_std
    if method == "fft":
        omega_d, omega_d_std = fft.omega_d, math.nan
    return IdentificationResult(
        zeta=zeta,
        omega_d=omega_d,
        zeta_std=zeta_std,
        omega_d_std=omega_d_std,
        method=method,
        window_s=win,
        n_cycles=duration * omega_d / (2.0 * math.pi),
        fit=fit,
        logdec=logdec,
        fft=fft,
    )


def identify_recording(
    recording: Any,
    window: tuple[float, float] | None = (9.0, 10.0),
    method: Literal["fit", "logdec", "fft"] = "fit",
    *,
    column: str = "adc",
) -> IdentificationResult:
    """:func:`identify` on a loaded recording's ``frame`` (time ``t_s`` and the signal ``column``).

    The result's provenance (``recording``: the recording's ``name``; ``source``: ``meta["source"]["kind"]``)
    is filled in for :meth:`IdentificationResult.to_dict`.

    Parameters
    ----------
    recording : object
        Anything with a ``frame`` DataFrame holding ``t_s`` and ``column`` (a :mod:`helpers.recordings`
        recording).
    window : (float, float), optional
        The analysed window (s); the paper's is 9-10 s.
    method : {"fit", "logdec", "fft"}
        See :func:`identify`.
    column : str
        ``"adc"`` (raw counts, as the paper's Fig. 5) or ``"tension_n"``.

    Returns
    -------
    IdentificationResult
        As :func:`identify`.

    Raises
    ------
    ValueError
        If the frame lacks a column, and as :func:`identify`.
    """
    frame = recording.frame
    missing = [c for c in ("t_s", column) if c not in frame.columns]
    if missing:
        raise ValueError(f"recording frame lacks column(s) {missing}; has {list(frame.columns)}")
    result = identify(frame["t_s"].to_numpy(dtype=float), frame[column].to_numpy(dtype=float), window, method)
    meta = getattr(recording, "meta", None) or {}
    src = meta.get("source")
    if isinstance(src, dict):
        src = src.get("kind")
    name = getattr(recording, "name", None)
    return replace(
        result,
        recording=name if isinstance(name, str) else None,
        source=src if isinstance(src, str) else None,
    )


def save_identification(
    result: IdentificationResult, path: str | os.PathLike = IDENTIFICATION_RESULT
) -> Path:
    """Write ``result.to_dict()`` as JSON (atomically) where the shaper design reads it.

    Parameters
    ----------
    result : IdentificationResult
        The identified mode, with its provenance (see :func:`identify_recording`).
    path : path-like
        Default ``data/identification/result.json``.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    return write_json(path, result.to_dict(), sort_keys=False)


def load_identification(path: str | os.PathLike = IDENTIFICATION_RESULT) -> IdentifiedMode:
    """Read the identified mode that notebook 02's live cell or ``record all`` saved.

    Parameters
    ----------
    path : path-like
        Default ``data/identification/result.json``.

    Returns
    -------
    IdentifiedMode

    Raises
    ------
    helpers.base.jsonfile.MissingDataError
        If there is none yet (the message says how to make it).
    helpers.base.jsonfile.DataFileError
        If it is malformed (the message names the file and the key or value).
    """
    data = read_json(path, "identification result", MISSING_HINT)
    try:
        return IdentifiedMode.from_dict(data)
    except (TypeError, ValueError) as exc:
        raise DataFileError(f"{path}: identification result: {exc}") from None
