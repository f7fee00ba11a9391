"""Input-shaper families beyond the paper's ZV and ZVD, and the registry of every family as data.

Each family's valid damping range and duration are held as data beside its constructor in :data:`FAMILIES`.
The families are the ones the input-shaping literature and 3D-printer firmware (Klipper's
``klippy/extras/shaper_defs.py``) offer, with the same impulses for the same ``(omega_n, zeta)``; like the
paper's (:mod:`helpers.paper.shapers`), every constructor takes ``(omega_n, zeta)``:

- ZV, ZVD, ZVDD, MZV: closed forms. Klipper takes the frequency in Hz, ``f = omega_n / (2 pi)``, and spaces
  the impulses in fractions of the damped period ``1/(f sqrt(1 - zeta^2)) = 2 pi / omega_d``, exactly as here.
  Klipper leaves the amplitudes unnormalised and divides by their sum when it applies them; we normalise.
- EI, two-hump EI, three-hump EI: Singhose's published polynomial fits in ``zeta`` (and ``V_tol`` for EI),
  normalised to sum 1 (the multi-hump fits sum to 1 only to about 5e-4). Their times are fractions of the
  **undamped** period ``2 pi / omega_n``. Klipper uses the undamped period for the multi-hump shapers too but
  the damped period for EI; checking the fit numerically (the EI hump maximum, the two-hump zero and the
  three-hump centre hump sit closer to the design frequency with the undamped period: e.g. at zeta = 0.1 the
  EI maximum is at omega/omega_n = 1.001 versus 0.996) we use the undamped period throughout. At this
  arm's zeta = 0.044 the two choices differ by sqrt(1 - zeta^2) - 1 = -0.1 % in the EI times.
- UM-ZV (unity-magnitude, negative impulses ``1, -1, 1``): the two switch times are solved exactly from the
  zero-vibration conditions (no fit), starting from the undamped solution ``T/6, T/3``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import root

from helpers.paper.modes import check_mode
from helpers.paper.shapers import Shaper, damped_decay, zv, zvd

MULTI_HUMP_VTOL = 0.05
"""Singhose's damped two- and three-hump EI fits exist only for a 5 % vibration tolerance."""


def normalised(amplitudes: Iterable[float], times: Iterable[float], name: str = "shaper") -> Shaper:
    """A shaper from amplitudes that need dividing by their sum (as Klipper stores them).

    Parameters
    ----------
    amplitudes, times : array_like
        Unnormalised amplitudes and their times (s).
    name : str
        Label.

    Returns
    -------
    Shaper
    """
    a = np.asarray(amplitudes, dtype=float)
    total = a.sum()
    if not np.isfinite(total) or total == 0.0:
        raise ValueError(f"cannot normalise amplitudes that sum to {total!r}")
    return Shaper(a / total, times, name)


def zvdd(omega_n: float, zeta: float) -> Shaper:
    """ZVDD shaper: ``zv**3``, amplitudes ``[1, 3K, 3K^2, K^3]/(1+K)^3`` at 0, T, 2T, 3T (1.5 damped periods).

    Parameters
    ----------
    omega_n : float
        Undamped natural frequency (rad/s).
    zeta : float
        Damping ratio in [0, 1).

    Returns
    -------
    Shaper
    """
    omega_d, k = damped_decay(omega_n, zeta)
    half = math.pi / omega_d
    a = np.array([1.0, 3 * k, 3 * k * k, k**3]) / (1.0 + k) ** 3
    return Shaper(a, half * np.arange(4.0), "ZVDD")


def three_tap(omega_n: float, zeta: float, delay: float, name: str = "3-tap") -> Shaper:
    """The general three-tap time-delay filter that cancels the mode for any delay ``T``.

    ``1 - 2 e^{-zeta omega_n T} cos(omega_d T) e^{-sT} + e^{-2 zeta omega_n T} e^{-2sT}``, normalised to unit
    sum. ``T = pi/omega_d`` gives ZVD, ``T = 3 pi / (4 omega_d)`` the MZV shaper.

    Parameters
    ----------
    omega_n, zeta : float
        The mode (rad/s, -).
    delay : float
        ``T`` in s, > 0; ``T <= pi/omega_d`` keeps every amplitude positive.
    name : str
        Label.

    Returns
    -------
    Shaper
    """
    omega_d, _ = damped_decay(omega_n, zeta)
    if not (math.isfinite(delay) and delay > 0):
        raise ValueError(f"delay must be a positive number of seconds, got {delay!r}")
    e = math.exp(-zeta * omega_n * delay)
    a = np.array([1.0, -2.0 * e * math.cos(omega_d * delay), e * e])
    return normalised(a, np.array([0.0, delay, 2 * delay]), name)


def mzv(omega_n: float, zeta: float) -> Shaper:
    """MZV shaper as in 3D-printer firmware: the three-tap filter with ``T = 3 pi / (4 omega_d)``.

    Amplitudes ``[1, sqrt(2) K', K'^2]`` (normalised), ``K' = exp(-0.75 zeta pi / sqrt(1-zeta^2))``, at
    ``0, 3/8, 3/4`` damped periods; identical, after Klipper's normalisation, to Klipper's ``mzv``.

    Parameters
    ----------
    omega_n : float
        Undamped natural frequency (rad/s).
    zeta : float
        Damping ratio in [0, 1).

    Returns
    -------
    Shaper
    """
    omega_d, _ = damped_decay(omega_n, zeta)
    return three_tap(omega_n, zeta, 0.75 * math.pi / omega_d, "MZV")


def _check_vtol(vtol: float) -> None:
    if not (isinstance(vtol, int | float | np.floating) and math.isfinite(vtol) and 0.0 < vtol < 1.0):
        raise ValueError(f"vtol must lie in (0, 1), got {vtol!r}")


def ei(omega_n: float, zeta: float, vtol: float = 0.05) -> Shaper:
    """Extra-insensitive (EI) shaper: ``V = vtol`` at the design frequency, zeros either side.

    Singhose's fit (valid for 0 <= zeta <= 0.3, vtol up to about 0.15): ``A1``, ``A3`` and ``t2`` are
    polynomials in ``zeta`` and ``vtol``, ``A2 = 1 - A1 - A3``, ``t3`` = one undamped period. For
    ``zeta = 0`` this is ``[(1+V)/4, (1-V)/2, (1+V)/4]`` at ``[0, T/2, T]`` to within the fit (~1e-3).

    Parameters
    ----------
    omega_n : float
        Undamped natural frequency (rad/s).
    zeta : float
        Damping ratio in [0, 1).
    vtol : float
        Tolerated vibration at the design point (0.05 = 5 %).

    Returns
    -------
    Shaper
    """
    check_mode(omega_n, zeta)
    _check_vtol(vtol)
    v, z = float(vtol), float(zeta)
    a1 = 0.24968 + 0.24961 * v + (0.80008 + 1.23328 * v) * z + (0.49599 + 3.17316 * v) * z**2
    a3 = 0.25149 + 0.21474 * v + (-0.83249 + 1.41498 * v) * z + (0.85181 - 4.90094 * v) * z**2
    t2 = (
        0.49990
        + (0.46159 * v + 8.57843 * v**2) * z
        + (4.26169 * v - 108.644 * v**2) * z**2
        + (1.75601 * v + 336.989 * v**2) * z**3
    )
    period = 2.0 * math.pi / omega_n
    return normalised([a1, 1.0 - a1 - a3, a3], [0.0, t2 * period, period], "EI")


# Singhose's fits for the damped multi-hump EI shapers (vtol = 5 %): coefficient rows are the impulses,
# columns the powers zeta^0..zeta^3; times are in undamped periods.
_TWO_HUMP_T = (
    (0.0, 0.0, 0.0, 0.0),
    (0.49890, 0.16270, -0.54262, 6.16180),
    (0.99748, 0.18382, -1.58270, 8.17120),
    (1.49920, -0.09297, -0.28338, 1.85710),
)
_TWO_HUMP_A = (
    (0.16054, 0.76699, 2.26560, -1.22750),
    (0.33911, 0.45081, -2.58080, 1.73650),
    (0.34089, -0.61533, -0.68765, 0.42261),
    (0.15997, -0.60246, 1.00280, -0.93145),
)
_THREE_HUMP_T = (
    (0.0, 0.0, 0.0, 0.0),
    (0.49974, 0.23834, 0.44559, 12.4720),
    (0.99849, 0.29808, -2.36460, 23.3990),
    (1.49870, 0.10306, -2.01390, 17.0320),
    (1.99960, -0.28231, 0.61536, 5.40450),
)
_THREE_HUMP_A = (
    (0.11275, 0.76632, 3.29160, -1.44380),
    (0.23698, 0.61164, -2.57850, 4.85220),
    (0.30008, -0.19062, -2.14560, 0.13744),
    (0.23775, -0.73297, 0.46885, -2.08650),
    (0.11244, -0.45439, 0.96382, -1.46000),
)


_HUMP_FITS: dict[int, tuple[tuple, tuple]] = {
    2: (_TWO_HUMP_T, _TWO_HUMP_A),
    3: (_THREE_HUMP_T, _THREE_HUMP_A),
}
"""Singhose's fits by number of humps: (times in periods, amplitudes), each a cubic in zeta."""


def multi_hump_ei(omega_n: float, zeta: float, humps: int = 2, vtol: float = MULTI_HUMP_VTOL) -> Shaper:
    """Multi-hump EI shaper (Singhose's fits): ``humps`` humps of ``vtol``, ``(humps + 1) / 2`` periods long.

    Two humps: ``V = 0`` at the design point, 1.5 periods; three humps: ``V = vtol`` at the design frequency,
    2 periods.

    Parameters
    ----------
    omega_n : float
        Undamped natural frequency (rad/s).
    zeta : float
        Damping ratio in [0, 1) (fit valid to about 0.3).
    humps : int
        2 or 3.
    vtol : float
        Must be 0.05: the damped fits exist only for 5 %.

    Returns
    -------
    Shaper
    """
    if humps not in _HUMP_FITS:
        raise ValueError(f"multi-hump EI: Singhose's fits exist for 2 or 3 humps, got {humps!r}")
    name = f"{humps}-hump EI"
    check_mode(omega_n, zeta)
    _check_vtol(vtol)
    if abs(vtol - MULTI_HUMP_VTOL) > 1e-12:
        raise ValueError(
            f"{name}: Singhose's fits are published only for vtol = {MULTI_HUMP_VTOL}, got vtol = {vtol}"
        )
    t_rows, a_rows = _HUMP_FITS[humps]
    powers = float(zeta) ** np.arange(4)
    period = 2.0 * math.pi / omega_n
    times = np.array(t_rows) @ powers * period
    amps = np.array(a_rows) @ powers
    return normalised(amps, times, name)


def um_zv(omega_n: float, zeta: float) -> Shaper:
    """Unity-magnitude ZV shaper (negative impulses ``1, -1, 1``), about a third of a damped period long.

    The switch times solve the two zero-vibration equations exactly (``scipy.optimize.root`` in the
    dimensionless phase ``omega_d t``, from the undamped solution ``pi/3, 2 pi/3``), so they agree with
    Singhose's tabulated fits to the fits' accuracy. A unity-magnitude shaper suits a bang-bang or
    on/off actuator; it excites unmodelled high modes more than positive shapers.

    Parameters
    ----------
    omega_n : float
        Undamped natural frequency (rad/s).
    zeta : float
        Damping ratio in [0, 1).

    Returns
    -------
    Shaper
    """
    omega_d, _ = damped_decay(omega_n, zeta)
    rate = zeta / math.sqrt(1.0 - zeta**2)  # zeta omega_n / omega_d

    def residual(th: np.ndarray) -> list[float]:
        e2, e3 = math.exp(rate * th[0]), math.exp(rate * th[1])
        return [
            1.0 - e2 * math.cos(th[0]) + e3 * math.cos(th[1]),
            -e2 * math.sin(th[0]) + e3 * math.sin(th[1]),
        ]

    def jacobian(th: np.ndarray) -> list[list[float]]:
        e2, e3 = math.exp(rate * th[0]), math.exp(rate * th[1])
        c2, s2, c3, s3 = math.cos(th[0]), math.sin(th[0]), math.cos(th[1]), math.sin(th[1])
        return [
            [-e2 * (rate * c2 - s2), e3 * (rate * c3 - s3)],
            [-e2 * (rate * s2 + c2), e3 * (rate * s3 + c3)],
        ]

    sol = root(residual, [math.pi / 3, 2 * math.pi / 3], jac=jacobian, method="hybr", tol=1e-14).x
    if np.hypot(*residual(sol)) > 1e-10 or not 0 < sol[0] < sol[1]:  # converges for zeta <= 0.76
        raise ValueError(f"UM-ZV: the zero-vibration equations have no solution for zeta = {zeta}")
    return Shaper(np.array([1.0, -1.0, 1.0]), np.array([0.0, sol[0], sol[1]]) / omega_d, "UM-ZV")


@dataclass(frozen=True)
class Family:
    """A shaper family as data: its constructor, the damping range its design holds for, and its length.

    Calling a family builds the shaper and refuses a damping ratio outside ``zeta_range``.

    Attributes
    ----------
    name : str
        Display name.
    make : callable
        ``make(omega_n, zeta) -> Shaper``.
    zeta_range : (float, float)
        Damping ratios the design is valid for (the published fits' range for EI and the multi-hump EI).
    periods : float
        Duration in damped periods at ``zeta = 0`` (the literature's figure).
    """

    name: str
    make: Callable[[float, float], Shaper]
    zeta_range: tuple[float, float]
    periods: float

    def __call__(self, omega_n: float, zeta: float) -> Shaper:
        """Build the shaper for the mode ``(omega_n, zeta)``."""
        lo, hi = self.zeta_range
        if not lo <= zeta <= hi:
            raise ValueError(f"{self.name}: the design holds for {lo} <= zeta <= {hi}, got zeta = {zeta!r}")
        return self.make(omega_n, zeta)


FAMILIES: dict[str, Family] = {
    f.name: f
    for f in (
        Family("ZV", zv, (0.0, 0.99), 0.5),
        Family("ZVD", zvd, (0.0, 0.99), 1.0),
        Family("ZVDD", zvdd, (0.0, 0.99), 1.5),
        Family("MZV", mzv, (0.0, 0.99), 0.75),
        Family("EI", ei, (0.0, 0.3), 1.0),
        Family("2-hump EI", functools.partial(multi_hump_ei, humps=2), (0.0, 0.3), 1.5),
        Family("3-hump EI", functools.partial(multi_hump_ei, humps=3), (0.0, 0.3), 2.0),
        Family("UM-ZV", um_zv, (0.0, 0.76), 1.0 / 3.0),
    )
}
"""Every single-mode family, by display name; each is called as ``family(omega_n, zeta)``."""


def multi_mode(
    modes: Iterable[tuple[float, float]], family: Callable[[float, float], Shaper] = zv
) -> Shaper:
    """Shaper for several modes: the convolution of one ``family`` shaper per mode.

    Parameters
    ----------
    modes : iterable of (omega_n, zeta)
        Undamped frequency (rad/s) and damping ratio of each mode.
    family : callable
        A constructor such as :func:`zv` or :func:`zvd`.

    Returns
    -------
    Shaper
        ``V`` is the product of the single-mode ``V``; duration the sum of durations.
    """
    modes = list(modes)
    if not modes:
        raise ValueError("multi_mode needs at least one (omega_n, zeta) mode")
    result = Shaper.unit()
    parts = []
    for omega_n, zeta in modes:
        s = family(omega_n, zeta)
        parts.append(s.name)
        result = result.convolve(s)
    return Shaper(result.amplitudes, result.times, " * ".join(parts))
