"""Two modes from one ring-down: the dominant mode and the next one that carries a share of the vibration.

:func:`helpers.paper.identify.identify` finds the dominant mode of a free decay (a damped sine). Away from
rest the
arm's second bending mode also rings (about 65-130 rad/s on the virtual rig), and a shaper designed for the
first alone leaves it. :func:`fit_two_modes` fits, by nonlinear least squares (``scipy.optimize``),

    y(t) = c + sum_i exp(-zeta_i omega_i t') (a_i cos(omega_di t') + b_i sin(omega_di t')),  i = 1, 2,

with ``t' = t - t[0]`` and ``omega_i = omega_di / sqrt(1 - zeta_i^2)``: first one mode, started from the
spectrum's highest peak, then both, the other started from the highest peak of the one-mode residual's
spectrum at least ``min_ratio`` away from the first (above or below, under a fifth of the sampling rate).
The two are then ordered by frequency: mode 1 is the lower (the arm's lowest bending mode, which the paper's
shapers target), mode 2 the higher. The standard
errors come from the Jacobian at the solution (``s^2 (J^T J)^-1``), like the single-mode fit's.

The **share** of the second (higher) mode is its amplitude over the sum of both at the window's start,
``A2 / (A1 + A2)`` with ``A_i = sqrt(a_i^2 + b_i^2)`` (its standard error by the delta method): the fraction
of the ring-down the second mode carries. A second mode smaller than three times the fit's residual noise is
not reported (None).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy import optimize

from helpers.paper.identify import fft_peak

MIN_RATIO = 1.3
"""The other mode is sought at least this factor away from the first fitted one (above or below it)."""
ZETA_START = 0.04
"""Damping ratio the fits start from (the paper's arm: 0.044)."""
MIN_AMPLITUDE_NOISE = 3.0
"""A second mode is reported only if its amplitude exceeds this many residual standard deviations."""


@dataclass(frozen=True)
class TwoModeFit:
    """The two modes of a ring-down with their standard errors.

    Attributes
    ----------
    omega_d, zeta, amplitude : float
        First (dominant) mode: damped frequency (rad/s), damping ratio, amplitude at the window's start.
    omega_d_se, zeta_se : float
        Their standard errors.
    omega_d2, zeta2, amplitude2, omega_d2_se, zeta2_se : float or None
        The second mode (None when it is not resolved).
    share2, share2_se : float or None
        ``amplitude2 / (amplitude + amplitude2)`` and its standard error.
    residual_rms : float
        Root mean square of the fit's residual (the noise floor of the estimate), in the units of ``y``.
    """

    omega_d: float
    zeta: float
    amplitude: float
    omega_d_se: float
    zeta_se: float
    omega_d2: float | None
    zeta2: float | None
    amplitude2: float | None
    omega_d2_se: float | None
    zeta2_se: float | None
    share2: float | None
    share2_se: float | None
    residual_rms: float


def _model(p: np.ndarray, tau: np.ndarray, n_modes: int) -> np.ndarray:
    y = np.full(tau.shape, p[0])
    for i in range(n_modes):
        a, b, wd, z = p[1 + 4 * i : 5 + 4 * i]
        wn = wd / math.sqrt(max(1.0 - z * z, 1e-12))
        y += np.exp(-z * wn * tau) * (a * np.cos(wd * tau) + b * np.sin(wd * tau))
    return y


def _fit(
    p0: np.ndarray, tau: np.ndarray, y: np.ndarray, n_modes: int
) -> tuple[np.ndarray, np.ndarray, float]:
    """Least squares from ``p0``: parameters, their covariance, residual rms."""
    lower = np.full(p0.size, -np.inf)
    upper = np.full(p0.size, np.inf)
    for i in range(n_modes):
        lower[3 + 4 * i], upper[4 + 4 * i] = 0.0, 0.9  # omega_d > 0, zeta in [0, 0.9]
        lower[4 + 4 * i] = 0.0
    sol = optimize.least_squares(lambda p: _model(p, tau, n_modes) - y, p0, bounds=(lower, upper),
                                 x_scale="jac", method="trf")  # fmt: skip
    dof = max(y.size - p0.size, 1)
    s2 = float(np.sum(sol.fun**2)) / dof
    jtj = sol.jac.T @ sol.jac
    cov = np.linalg.pinv(jtj) * s2
    return sol.x, cov, math.sqrt(s2)


def fit_two_modes(t: ArrayLike, y: ArrayLike, min_ratio: float = MIN_RATIO) -> TwoModeFit:
    """Fit the lowest mode and, when it is there, a second one to a free decay.

    Parameters
    ----------
    t, y : array_like
        The ring-down window: time (s), uniformly sampled, and the signal (N or ADC counts).
    min_ratio : float
        The other mode is sought at least this factor above or below the first fitted one.

    Returns
    -------
    TwoModeFit
        Without a resolved second mode its fields are None.

    Raises
    ------
    ValueError
        Arrays of different shapes or fewer than 50 samples.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.ndim != 1 or t.shape != y.shape or t.size < 50:
        raise ValueError(f"t and y must be 1-D of equal length >= 50, got {t.shape} and {y.shape}")
    tau = t - t[0]
    # one mode first, from the spectrum's peak, a light damping, amplitude and phase by linear least squares
    wd1, z1 = fft_peak(t, y - np.mean(y)).omega_d, ZETA_START
    wn1 = wd1 / math.sqrt(1 - z1 * z1)
    env = np.exp(-z1 * wn1 * tau)
    basis = np.column_stack([np.ones_like(tau), env * np.cos(wd1 * tau), env * np.sin(wd1 * tau)])
    coef, *_ = np.linalg.lstsq(basis, y, rcond=None)
    p1 = np.array([coef[0], coef[1], coef[2], wd1, z1])
    p1, cov1, rms1 = _fit(p1, tau, y, 1)
    second = ("omega_d2", "zeta2", "amplitude2", "omega_d2_se", "zeta2_se", "share2", "share2_se")
    one = TwoModeFit(omega_d=float(p1[3]), zeta=float(p1[4]), amplitude=math.hypot(p1[1], p1[2]),
                     omega_d_se=math.sqrt(cov1[3, 3]), zeta_se=math.sqrt(cov1[4, 4]), residual_rms=rms1,
                     **dict.fromkeys(second))  # fmt: skip
    # the other mode: the residual's highest peak at least ``min_ratio`` away from the first, either side,
    # below a fifth of the sampling rate (well resolved, never aliased)
    residual = y - _model(p1, tau, 1)
    f1 = p1[3] / (2 * math.pi)
    f_top = 0.2 / float(np.median(np.diff(t)))
    candidates = []
    for lo, hi in ((None, f1 / min_ratio), (f1 * min_ratio, f_top)):
        if hi is not None and (lo or 0.0) >= hi:
            continue
        try:
            candidates.append(fft_peak(t, residual, f_min_hz=lo, f_max_hz=hi))
        except ValueError:
            continue
    if not candidates:
        return one
    spectrum = max(candidates, key=lambda c: c.peak_amplitude)
    p0 = np.concatenate([p1, [1.5 * float(spectrum.peak_amplitude), 0.0, spectrum.omega_d, ZETA_START]])
    try:
        p, cov, rms = _fit(p0, tau, y, 2)
    except (ValueError, np.linalg.LinAlgError):
        return one
    if p[7] < p[3]:  # order the modes by frequency: the first is the lower
        order = [0, 5, 6, 7, 8, 1, 2, 3, 4]
        p, cov = p[order], cov[np.ix_(order, order)]
    a1, a2 = math.hypot(p[1], p[2]), math.hypot(p[5], p[6])
    separated = p[7] > 1.15 * p[3] and p[7] < 2 * math.pi * f_top
    if not (min(a1, a2) > MIN_AMPLITUDE_NOISE * rms and separated):
        return one
    share = a2 / (a1 + a2)
    # delta method for the share through (a1x, a1y, a2x, a2y)
    grad = np.zeros(p.size)
    total = (a1 + a2) ** 2
    for k, (ax, ay, own) in enumerate(((p[1], p[2], False), (p[5], p[6], True))):
        amp = math.hypot(ax, ay) or 1e-300
        d_share = (a1 if own else -a2) / total  # d share / d A_k
        grad[1 + 4 * k] = d_share * ax / amp
        grad[2 + 4 * k] = d_share * ay / amp
    share_se = math.sqrt(max(float(grad @ cov @ grad), 0.0))
    return TwoModeFit(
        omega_d=float(p[3]), zeta=float(p[4]), amplitude=a1,
        omega_d_se=math.sqrt(cov[3, 3]), zeta_se=math.sqrt(cov[4, 4]),
        omega_d2=float(p[7]), zeta2=float(p[8]), amplitude2=a2,
        omega_d2_se=math.sqrt(cov[7, 7]), zeta2_se=math.sqrt(cov[8, 8]),
        share2=share, share2_se=share_se, residual_rms=rms,
    )  # fmt: skip
