"""Input shapers: impulse sequences that cancel a lightly damped mode, and how robust they are.

A shaper is a sequence of impulses ``A_i`` at times ``t_i`` (``t_0 = 0``, amplitudes summing to 1) that is
convolved with a command. Its residual vibration for a mode ``(omega_n, zeta)`` is (Singer and Seering)::

    V = exp(-zeta omega_n t_N) sqrt(C^2 + S^2),
    C = sum A_i exp(zeta omega_n t_i) cos(omega_d t_i),  S = sum A_i exp(zeta omega_n t_i) sin(omega_d t_i),

with ``omega_d = omega_n sqrt(1 - zeta^2)``: the vibration left after the shaped command relative to the
unshaped one (1.0 for no shaping, 0 for a perfect shaper).

The paper's two time-delay filters (TDFs) are standard shapers:

- the **non-robust TDF** ``A0 + A1 exp(-sT)`` with ``T = pi/omega_d`` is the **ZV** shaper (:func:`zv`);
- the **robust TDF** ``(A0 + A1 exp(-sT))^2`` is the **ZVD** shaper (:func:`zvd`), impulses at 0, T, 2T.

Every constructor takes the **undamped** natural frequency ``omega_n`` (rad/s) and the damping ratio
``zeta``, in that order (the package's convention, :mod:`helpers.modes`, whose ``omega_n_from_damped``
converts an identified damped frequency). Each family's valid damping range and duration are held as data
beside its constructor in :data:`FAMILIES`. The families are the ones the
input-shaping literature and 3D-printer firmware (Klipper's ``klippy/extras/shaper_defs.py``) offer, with
the same impulses for the same ``(omega_n, zeta)``:

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

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import brentq, root

from helpers import paper
from helpers.modes import check_mode, omega_n_from_damped

SUM_TOLERANCE = 1e-9
"""How far the amplitudes of a :class:`Shaper` may sum from 1."""

MERGE_TOLERANCE_S = 1e-12
"""Impulses closer than this (s) are merged when shapers are convolved."""

MULTI_HUMP_VTOL = 0.05
"""Singhose's damped two- and three-hump EI fits exist only for a 5 % vibration tolerance."""

def _as_1d_float(x: Any, what: str) -> np.ndarray:
    arr = np.array(x, dtype=float, ndmin=1)
    if arr.ndim != 1:
        raise ValueError(f"{what} must be one-dimensional, got shape {arr.shape}")
    return arr


@dataclass(frozen=True, eq=False)
class Shaper:
    """A sequence of impulses ``amplitudes[i]`` at ``times[i]`` (s).

    Parameters
    ----------
    amplitudes : numpy.ndarray
        Impulse amplitudes; they must sum to 1 (so a shaped move ends where the unshaped one does). Negative
        amplitudes are allowed (UM shapers).
    times : numpy.ndarray
        Impulse times in s: ``times[0] == 0``, non-decreasing, finite.
    name : str
        A short label used in tables and plots.

    Raises
    ------
    ValueError
        If the arrays differ in length, are empty, hold non-finite values, the times do not start at 0 or
        decrease, or the amplitudes do not sum to 1.
    """

    amplitudes: np.ndarray
    times: np.ndarray
    name: str = "shaper"

    def __post_init__(self) -> None:
        a = _as_1d_float(self.amplitudes, "amplitudes")
        t = _as_1d_float(self.times, "times")
        if a.size == 0:
            raise ValueError("a shaper needs at least one impulse")
        if a.shape != t.shape:
            raise ValueError(f"amplitudes ({a.size}) and times ({t.size}) differ in length")
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(t))):
            raise ValueError(f"shaper {self.name!r}: amplitudes and times must be finite")
        if t[0] != 0.0:
            raise ValueError(f"shaper {self.name!r}: times[0] must be 0, got {t[0]!r}")
        if np.any(np.diff(t) < 0):
            raise ValueError(f"shaper {self.name!r}: times must be non-decreasing, got {t.tolist()}")
        if abs(a.sum() - 1.0) > SUM_TOLERANCE:
            raise ValueError(f"shaper {self.name!r}: amplitudes must sum to 1, they sum to {a.sum():.12g}")
        a.flags.writeable = False
        t.flags.writeable = False
        object.__setattr__(self, "amplitudes", a)
        object.__setattr__(self, "times", t)

    # -- construction -------------------------------------------------------------------------------------
    @classmethod
    def normalised(cls, amplitudes: Iterable[float], times: Iterable[float], name: str = "shaper") -> Shaper:
        """Build a shaper from amplitudes that need dividing by their sum (as Klipper stores them).

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
        a = _as_1d_float(amplitudes, "amplitudes")
        total = a.sum()
        if not np.isfinite(total) or total == 0.0:
            raise ValueError(f"cannot normalise amplitudes that sum to {total!r}")
        return cls(a / total, _as_1d_float(times, "times"), name)

    @classmethod
    def unit(cls) -> Shaper:
        """The unit impulse: no shaping (``V = 1`` everywhere)."""
        return cls(np.array([1.0]), np.array([0.0]), "unshaped")

    # -- properties ---------------------------------------------------------------------------------------
    @property
    def duration(self) -> float:
        """Time of the last impulse (s): the delay the shaper adds to a move."""
        return float(self.times[-1])

    def __len__(self) -> int:
        return int(self.amplitudes.size)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Shaper):
            return NotImplemented
        return (
            self.amplitudes.shape == other.amplitudes.shape
            and bool(np.array_equal(self.amplitudes, other.amplitudes))
            and bool(np.array_equal(self.times, other.times))
        )

    def __hash__(self) -> int:
        return hash((self.amplitudes.tobytes(), self.times.tobytes()))

    def __repr__(self) -> str:
        return (
            f"Shaper(name={self.name!r}, amplitudes={np.round(self.amplitudes, 6).tolist()}, "
            f"times={np.round(self.times, 6).tolist()})"
        )

    def allclose(self, other: Shaper, rtol: float = 1e-9, atol: float = 1e-12) -> bool:
        """True if ``other`` has as many impulses at numerically the same times and amplitudes."""
        return (
            len(self) == len(other)
            and bool(np.allclose(self.amplitudes, other.amplitudes, rtol=rtol, atol=atol))
            and bool(np.allclose(self.times, other.times, rtol=rtol, atol=atol))
        )

    # -- analysis -----------------------------------------------------------------------------------------
    def vibration(self, omega_n: float | np.ndarray, zeta: float | np.ndarray) -> np.ndarray | float:
        """Residual vibration ``V(omega_n, zeta)`` relative to an unshaped command.

        Parameters
        ----------
        omega_n : float or array_like
            Undamped natural frequency of the mode (rad/s); arrays are evaluated element-wise.
        zeta : float or array_like
            Damping ratio in [0, 1); broadcast against ``omega_n``.

        Returns
        -------
        float or numpy.ndarray
            ``V`` (1.0 for the unit impulse, 0 where the shaper cancels the mode); a float for scalar inputs.
        """
        w = np.asarray(omega_n, dtype=float)
        z = np.asarray(zeta, dtype=float)
        if np.any(~np.isfinite(w)) or np.any(w < 0):
            raise ValueError("omega_n must be finite and >= 0")
        if np.any(~np.isfinite(z)) or np.any((z < 0) | (z >= 1)):
            raise ValueError("zeta must lie in [0, 1)")
        w_b, z_b = np.broadcast_arrays(w, z)
        wd = w_b * np.sqrt(1.0 - z_b**2)
        t = self.times
        # exp(zeta omega_n (t_i - t_N)) keeps the exponentials bounded for long shapers.
        decay = np.exp((z_b * w_b)[..., None] * (t - t[-1]))
        phase = wd[..., None] * t
        c = np.sum(self.amplitudes * decay * np.cos(phase), axis=-1)
        s = np.sum(self.amplitudes * decay * np.sin(phase), axis=-1)
        v = np.hypot(c, s)
        return float(v) if v.ndim == 0 else v

    def sensitivity(
        self, omega_model: float, zeta: float, ratios: np.ndarray | Iterable[float]
    ) -> np.ndarray:
        """Sensitivity curve: ``V`` against ``omega / omega_model`` at fixed ``zeta``.

        Parameters
        ----------
        omega_model : float
            The undamped frequency (rad/s) the shaper was designed for.
        zeta : float
            Damping ratio of the actual mode.
        ratios : array_like
            Values of ``omega_n / omega_model`` (e.g. ``np.linspace(0, 2, 2001)``).

        Returns
        -------
        numpy.ndarray
            ``V`` at ``omega_n = ratios * omega_model``, same shape as ``ratios``.
        """
        check_mode(omega_model, zeta)
        r = _as_1d_float(ratios, "ratios")
        return np.asarray(self.vibration(r * omega_model, zeta))

    def insensitivity(
        self, omega_model: float, zeta: float, vtol: float = 0.05, hump_slack: float = 0.1
    ) -> tuple[float, float, float]:
        """Width of the band of ``omega/omega_model`` around 1 where ``V <= vtol``.

        The band is the connected range around the design point in which ``V`` stays below
        ``vtol * (1 + hump_slack)``; its edges are the outermost crossings of ``V = vtol`` in that range.
        The slack lets the humps of EI-type shapers (which touch ``vtol`` by design; Singhose's fits miss
        it by up to ~7 %) count as inside, as the literature counts them.

        Parameters
        ----------
        omega_model, zeta : float
            Design frequency (rad/s) and the damping ratio at which ``V`` is evaluated.
        vtol : float
            Vibration tolerance, e.g. 0.05.
        hump_slack : float
            Relative excess over ``vtol`` tolerated inside the band.

        Returns
        -------
        low, high, width : float
            Band edges as ratios and ``high - low``; ``nan`` if ``V > vtol`` throughout.
        """
        r = np.linspace(0.01, 3.0, 29901)
        v = np.asarray(self.vibration(r * omega_model, zeta))
        loose = v <= vtol * (1.0 + hump_slack)
        i1 = int(np.argmin(np.abs(r - 1.0)))
        if not loose[i1]:
            return math.nan, math.nan, math.nan
        lo = i1
        while lo > 0 and loose[lo - 1]:
            lo -= 1
        hi = i1
        while hi < r.size - 1 and loose[hi + 1]:
            hi += 1
        inside = np.flatnonzero(v[lo : hi + 1] <= vtol) + lo
        if inside.size == 0:
            return math.nan, math.nan, math.nan

        def g(x: float) -> float:
            return float(self.vibration(x * omega_model, zeta)) - vtol

        a, b = int(inside[0]), int(inside[-1])
        low = brentq(g, r[a - 1], r[a]) if a > 0 else r[0]
        high = brentq(g, r[b], r[b + 1]) if b < r.size - 1 else r[-1]
        return float(low), float(high), float(high - low)

    # -- composition and application ----------------------------------------------------------------------
    def convolve(self, other: Shaper, name: str | None = None) -> Shaper:
        """Compose two shapers (their transfer functions multiply); impulses at equal times merge.

        Parameters
        ----------
        other : Shaper
            The shaper to compose with.
        name : str, optional
            Label of the result; default ``"<self>*<other>"``.

        Returns
        -------
        Shaper
            ``V`` of the result is the product of the two ``V`` for every mode.
        """
        t = (self.times[:, None] + other.times[None, :]).ravel()
        a = (self.amplitudes[:, None] * other.amplitudes[None, :]).ravel()
        order = np.argsort(t, kind="stable")
        t, a = t[order], a[order]
        merged_t: list[float] = []
        merged_a: list[float] = []
        for ti, ai in zip(t, a, strict=True):
            if merged_t and ti - merged_t[-1] <= MERGE_TOLERANCE_S:
                merged_a[-1] += ai
            else:
                merged_t.append(float(ti))
                merged_a.append(float(ai))
        merged = np.array(merged_t)
        merged[0] = 0.0
        return Shaper(np.array(merged_a), merged, name or f"{self.name}*{other.name}")

    def __mul__(self, other: Shaper) -> Shaper:
        if not isinstance(other, Shaper):
            return NotImplemented
        return self.convolve(other)

    def apply(self, t: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Shape a command sampled at times ``t``: ``y(t) = sum_i A_i u(t - t_i)``.

        Before ``t[0]`` the command is taken to be at rest at ``u[0]`` (zero for a move that starts from
        rest at zero). Delays that are not whole multiples of the sample spacing use linear interpolation,
        so for an exact result put the impulse times on the grid (or use
        :meth:`helpers.profiles.VelocityProfile.shaped` for piecewise-constant commands).

        Parameters
        ----------
        t : numpy.ndarray
            Increasing sample times (s), usually uniform.
        u : numpy.ndarray
            The command at those times (any unit).

        Returns
        -------
        numpy.ndarray
            The shaped command at the same times.
        """
        t = _as_1d_float(t, "t")
        u = _as_1d_float(u, "u")
        if t.shape != u.shape:
            raise ValueError(f"t ({t.size}) and u ({u.size}) differ in length")
        if t.size == 0:
            return u.copy()
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(u))):
            raise ValueError("t and u must be finite")
        if np.any(np.diff(t) <= 0):
            raise ValueError("t must be strictly increasing")
        out = np.zeros_like(u)
        for a, ti in zip(self.amplitudes, self.times, strict=True):
            out += a * np.interp(t - ti, t, u, left=u[0])
        return out

    def impulse_table(self) -> pd.DataFrame:
        """The impulses as a table: ``time_s``, ``amplitude``, ``cumulative`` (running sum)."""
        return pd.DataFrame(
            {
                "time_s": self.times,
                "amplitude": self.amplitudes,
                "cumulative": np.cumsum(self.amplitudes),
            },
            index=pd.RangeIndex(len(self), name="impulse"),
        )


# -- conversions and checks ----------------------------------------------------------------------------------
def _damped(omega_n: float, zeta: float) -> tuple[float, float]:
    """Return ``(omega_d, K)`` with ``K = exp(-zeta pi / sqrt(1 - zeta^2))``, the half-period decay."""
    check_mode(omega_n, zeta)
    root = math.sqrt(1.0 - zeta**2)
    return omega_n * root, math.exp(-zeta * math.pi / root)


# -- the families -------------------------------------------------------------------------------------------
def zv(omega_n: float, zeta: float) -> Shaper:
    """Zero-vibration (ZV) shaper: the paper's **non-robust TDF** ``A0 + A1 exp(-sT)``.

    ``A0 = 1/(1+K)``, ``A1 = K/(1+K)`` with ``K = exp(-zeta pi/sqrt(1-zeta^2))`` (equivalently the paper's
    ``A0 = e^x/(1+e^x)``, ``x = zeta pi/sqrt(1-zeta^2)``), ``T = pi/omega_d``: half a damped period.

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
    omega_d, k = _damped(omega_n, zeta)
    return Shaper(np.array([1.0, k]) / (1.0 + k), np.array([0.0, math.pi / omega_d]), "ZV")


def zvd(omega_n: float, zeta: float) -> Shaper:
    """Zero-vibration-and-derivative (ZVD) shaper: the paper's **robust TDF** ``(A0 + A1 exp(-sT))^2``.

    Amplitudes ``[1, 2K, K^2]/(1+K)^2`` at ``0, T, 2T`` with ``T = pi/omega_d`` (one damped period long):
    exactly ``zv * zv``, a double zero on the mode's poles.

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
    omega_d, k = _damped(omega_n, zeta)
    half = math.pi / omega_d
    return Shaper(np.array([1.0, 2 * k, k * k]) / (1.0 + k) ** 2, np.array([0.0, half, 2 * half]), "ZVD")


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
    omega_d, k = _damped(omega_n, zeta)
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
    omega_d, _ = _damped(omega_n, zeta)
    if not (math.isfinite(delay) and delay > 0):
        raise ValueError(f"delay must be a positive number of seconds, got {delay!r}")
    e = math.exp(-zeta * omega_n * delay)
    a = np.array([1.0, -2.0 * e * math.cos(omega_d * delay), e * e])
    return Shaper.normalised(a, np.array([0.0, delay, 2 * delay]), name)


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
    omega_d, _ = _damped(omega_n, zeta)
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
    return Shaper.normalised([a1, 1.0 - a1 - a3, a3], [0.0, t2 * period, period], "EI")


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


def _from_fit(
    omega_n: float, zeta: float, t_rows: tuple, a_rows: tuple, vtol: float, name: str
) -> Shaper:
    check_mode(omega_n, zeta)
    _check_vtol(vtol)
    if abs(vtol - MULTI_HUMP_VTOL) > 1e-12:
        raise ValueError(
            f"{name}: Singhose's fits are published only for vtol = {MULTI_HUMP_VTOL}, got vtol = {vtol}"
        )
    powers = float(zeta) ** np.arange(4)
    period = 2.0 * math.pi / omega_n
    times = np.array(t_rows) @ powers * period
    amps = np.array(a_rows) @ powers
    return Shaper.normalised(amps, times, name)


def two_hump_ei(omega_n: float, zeta: float, vtol: float = MULTI_HUMP_VTOL) -> Shaper:
    """Two-hump EI shaper (Singhose's fit, 1.5 periods): ``V = 0`` at the design point, humps of ``vtol``.

    Parameters
    ----------
    omega_n : float
        Undamped natural frequency (rad/s).
    zeta : float
        Damping ratio in [0, 1) (fit valid to about 0.3).
    vtol : float
        Must be 0.05: the damped fit exists only for 5 %.

    Returns
    -------
    Shaper
    """
    return _from_fit(omega_n, zeta, _TWO_HUMP_T, _TWO_HUMP_A, vtol, "2-hump EI")


def three_hump_ei(omega_n: float, zeta: float, vtol: float = MULTI_HUMP_VTOL) -> Shaper:
    """Three-hump EI shaper (Singhose's fit, 2 periods): ``V = vtol`` at the design frequency, three humps.

    Parameters
    ----------
    omega_n : float
        Undamped natural frequency (rad/s).
    zeta : float
        Damping ratio in [0, 1) (fit valid to about 0.3).
    vtol : float
        Must be 0.05: the damped fit exists only for 5 %.

    Returns
    -------
    Shaper
    """
    return _from_fit(omega_n, zeta, _THREE_HUMP_T, _THREE_HUMP_A, vtol, "3-hump EI")


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
    omega_d, _ = _damped(omega_n, zeta)
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
        Family("2-hump EI", two_hump_ei, (0.0, 0.3), 1.5),
        Family("3-hump EI", three_hump_ei, (0.0, 0.3), 2.0),
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


# -- the paper's filters ------------------------------------------------------------------------------------
def design_tdfs(omega_d: float, zeta: float) -> tuple[Shaper, Shaper]:
    """The paper's two TDFs from an identified mode ``(omega_d, zeta)``.

    Parameters
    ----------
    omega_d : float
        **Damped** natural frequency (rad/s), as identified from a free decay.
    zeta : float
        Damping ratio.

    Returns
    -------
    (Shaper, Shaper)
        The non-robust TDF (= ZV, ``A0 + A1 e^{-sT}``, ``T = pi/omega_d``) and the robust TDF
        (= its square = ZVD), named ``"zv"`` and ``"zvd"`` like the systems of :mod:`helpers.paper`.
    """
    omega_n = omega_n_from_damped(omega_d, zeta)
    nonrobust = zv(omega_n, zeta)
    robust = zvd(omega_n, zeta)
    return (
        Shaper(nonrobust.amplitudes, nonrobust.times, "zv"),
        Shaper(robust.amplitudes, robust.times, "zvd"),
    )


def paper_tdfs(omega_d: float = paper.OMEGA_D, zeta: float = paper.ZETA) -> tuple[Shaper, Shaper]:
    """The paper's non-robust TDF (ZV) and robust TDF (ZVD = ZV squared), from its identified mode.

    With the defaults (omega_d = 25.085 rad/s, zeta = 0.044): A0 = 0.5345, A1 = 0.4655, T = 0.12524 s;
    robust 0.2857, 0.4976, 0.2167 at 0, T, 2T.

    Parameters
    ----------
    omega_d : float
        Damped natural frequency in rad/s (default the paper's 25.085).
    zeta : float
        Damping ratio (default the paper's 0.044).

    Returns
    -------
    (Shaper, Shaper)
        ``(zv, zvd)``.
    """
    return design_tdfs(omega_d, zeta)
