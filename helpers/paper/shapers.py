"""The paper's input shapers: impulse sequences that cancel a lightly damped mode, and how robust they are.

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
``zeta``, in that order (the package's convention, :mod:`helpers.paper.modes`, whose ``omega_n_from_damped``
converts an identified damped frequency). The families beyond the paper (ZVDD, MZV, EI, multi-hump EI,
UM-ZV) and the registry of every family as data are :mod:`helpers.research.families`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import brentq

from helpers.paper import numbers as paper
from helpers.paper.modes import check_mode, omega_n_from_damped

SUM_TOLERANCE = 1e-9
"""How far the amplitudes of a :class:`Shaper` may sum from 1."""

MERGE_TOLERANCE_S = 1e-12
"""Impulses closer than this (s) to the one before are merged when shapers are convolved."""


def _as_1d_float(x: Any, what: str) -> np.ndarray:
    arr = np.array(x, dtype=float, ndmin=1)
    if arr.ndim != 1:
        raise ValueError(f"{what} must be one-dimensional, got shape {arr.shape}")
    return arr


def freeze_arrays(obj: Any, **arrays: np.ndarray) -> None:
    """Make ``arrays`` read-only and set them as the fields of the frozen dataclass ``obj``."""
    for name, array in arrays.items():
        array.flags.writeable = False
        object.__setattr__(obj, name, array)


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
        freeze_arrays(self, amplitudes=a, times=t)

    # -- construction -------------------------------------------------------------------------------------
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
        same = np.array_equal(self.amplitudes, other.amplitudes) and np.array_equal(self.times, other.times)
        return bool(same)

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
        tight = np.flatnonzero(~loose)  # the band runs between the nearest of these on either side
        lo = int(tight[tight < i1].max(initial=-1)) + 1
        hi = int(tight[tight > i1].min(initial=r.size)) - 1
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
        first = np.concatenate([[True], np.diff(t) > MERGE_TOLERANCE_S])  # the first impulse of each group
        merged = t[first]
        merged[0] = 0.0
        sums = np.bincount(np.cumsum(first) - 1, weights=a)  # each group's amplitudes, added in order
        return Shaper(sums, merged, name or f"{self.name}*{other.name}")

    def __mul__(self, other: Shaper) -> Shaper:
        if not isinstance(other, Shaper):
            return NotImplemented
        return self.convolve(other)

    def apply(self, t: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Shape a command sampled at times ``t``: ``y(t) = sum_i A_i u(t - t_i)``.

        Before ``t[0]`` the command is taken to be at rest at ``u[0]`` (zero for a move that starts from
        rest at zero). Delays that are not whole multiples of the sample spacing use linear interpolation,
        so for an exact result put the impulse times on the grid (or use
        :meth:`helpers.paper.profiles.VelocityProfile.shaped` for piecewise-constant commands).

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
def damped_decay(omega_n: float, zeta: float) -> tuple[float, float]:
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
    omega_d, k = damped_decay(omega_n, zeta)
    return Shaper(np.array([1.0, k]) / (1.0 + k), np.array([0.0, math.pi / omega_d]), "ZV")


def zvd(omega_n: float, zeta: float) -> Shaper:
    """Zero-vibration-and-derivative (ZVD) shaper: the paper's **robust TDF** ``(A0 + A1 exp(-sT))^2``.

    Amplitudes ``[1, 2K, K^2]/(1+K)^2`` at ``0, T, 2T`` with ``T = pi/omega_d`` (one damped period long):
    exactly ``zv * zv``, a double zero on the mode's poles. Parameters as :func:`zv`'s.
    """
    omega_d, k = damped_decay(omega_n, zeta)
    half = math.pi / omega_d
    return Shaper(np.array([1.0, 2 * k, k * k]) / (1.0 + k) ** 2, np.array([0.0, half, 2 * half]), "ZVD")


# -- the paper's filters ------------------------------------------------------------------------------------
def design_tdfs(omega_d: float = paper.OMEGA_D, zeta: float = paper.ZETA) -> tuple[Shaper, Shaper]:
    """The paper's two TDFs from an identified mode ``(omega_d, zeta)`` (default: the paper's).

    With the paper's identified mode (omega_d = 25.085 rad/s, zeta = 0.044): A0 = 0.5345, A1 = 0.4655,
    T = 0.12524 s; robust 0.2857, 0.4976, 0.2167 at 0, T, 2T.

    Parameters
    ----------
    omega_d : float
        **Damped** natural frequency (rad/s), as identified from a free decay (default the paper's 25.085).
    zeta : float
        Damping ratio (default the paper's 0.044).

    Returns
    -------
    (Shaper, Shaper)
        The non-robust TDF (= ZV, ``A0 + A1 e^{-sT}``, ``T = pi/omega_d``) and the robust TDF
        (= its square = ZVD), named ``"zv"`` and ``"zvd"`` like the systems of :mod:`helpers.paper.numbers`.
    """
    omega_n = omega_n_from_damped(omega_d, zeta)
    return replace(zv(omega_n, zeta), name="zv"), replace(zvd(omega_n, zeta), name="zvd")
