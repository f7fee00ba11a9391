"""Command profiles: the paper's velocity pulse and its shaped versions, as exact piecewise-constant maths.

The paper drives the cable with a velocity pulse (its eq. 14): ``v_in`` from ``t_up`` for ``t_p = x_f/v_in``,
a hold, ``-v_in`` from ``t_down`` for ``t_p``. Shaping a piecewise-constant velocity with an input shaper
gives another piecewise-constant velocity (a sum of delayed, scaled copies), represented exactly by
:class:`VelocityProfile`. Turning a profile into whole stepper steps and board commands is the job of
:mod:`helpers.board.programmes`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from helpers.base.validate import check_positive, check_time
from helpers.paper import numbers as paper
from helpers.paper.shapers import Shaper, freeze_arrays

TIME_TOLERANCE_S = 1e-12
"""Breakpoints closer than this (s) are merged."""


# -- the paper's pulse and exact piecewise-constant profiles -----------------------------------------------
def pulse_time(v_in_mm_s: float, x_f_mm: float) -> float:
    """Pulse time ``t_p = x_f / v_in`` (s)."""
    return check_positive(x_f_mm, "x_f_mm") / check_positive(v_in_mm_s, "v_in_mm_s")


@dataclass(frozen=True, eq=False)
class VelocityProfile:
    """A piecewise-constant velocity: ``velocities[k]`` on ``[breakpoints[k], breakpoints[k+1])``, 0 outside.

    Parameters
    ----------
    breakpoints : numpy.ndarray
        Strictly increasing times (s), one more than ``velocities``.
    velocities : numpy.ndarray
        Velocity on each interval (mm/s).
    """

    breakpoints: np.ndarray
    velocities: np.ndarray

    def __post_init__(self) -> None:
        b = np.array(self.breakpoints, dtype=float, ndmin=1)
        v = np.array(self.velocities, dtype=float, ndmin=1)
        if b.ndim != 1 or v.ndim != 1 or b.size != v.size + 1:
            raise ValueError(f"need n+1 breakpoints for n velocities, got {b.size} and {v.size}")
        if v.size == 0:
            raise ValueError("a velocity profile needs at least one piece")
        if not (np.all(np.isfinite(b)) and np.all(np.isfinite(v))):
            raise ValueError("breakpoints and velocities must be finite")
        if np.any(np.diff(b) <= 0):
            raise ValueError("breakpoints must be strictly increasing")
        freeze_arrays(self, breakpoints=b, velocities=v)

    @property
    def start(self) -> float:
        """First breakpoint (s)."""
        return float(self.breakpoints[0])

    @property
    def end(self) -> float:
        """Last breakpoint (s)."""
        return float(self.breakpoints[-1])

    @property
    def piece_displacements(self) -> np.ndarray:
        """Displacement of each piece (mm): its velocity times its length."""
        return self.velocities * np.diff(self.breakpoints)

    def sample(self, t: np.ndarray | float) -> np.ndarray:
        """Velocity (mm/s) at times ``t`` (right-continuous: a piece includes its start, not its end)."""
        t = np.asarray(t, dtype=float)
        k = np.searchsorted(self.breakpoints, t, side="right") - 1
        inside = (k >= 0) & (k < self.velocities.size)
        return np.where(inside, self.velocities[np.clip(k, 0, self.velocities.size - 1)], 0.0)

    def displacement(self, t: np.ndarray | float) -> np.ndarray:
        """Exact displacement (mm) from rest at 0 before the first breakpoint, at times ``t``."""
        t = np.asarray(t, dtype=float)
        tc = np.clip(t, self.start, self.end)
        k = np.clip(np.searchsorted(self.breakpoints, tc, side="right") - 1, 0, self.velocities.size - 1)
        reached = np.concatenate([[0.0], np.cumsum(self.piece_displacements)])  # at each breakpoint
        return reached[k] + self.velocities[k] * (tc - self.breakpoints[k])

    def simplified(self) -> VelocityProfile:
        """The same profile with equal neighbouring velocities merged."""
        keep = np.concatenate([[True], np.diff(self.velocities) != 0])
        b = np.concatenate([self.breakpoints[:-1][keep], [self.end]])
        return VelocityProfile(b, self.velocities[keep])

    def shaped(self, shaper: Shaper | None) -> VelocityProfile:
        """The exact shaped profile ``sum_i A_i v(t - t_i)`` (still piecewise constant).

        Parameters
        ----------
        shaper : Shaper or None
            None returns the profile unchanged.

        Returns
        -------
        VelocityProfile
            Breakpoints at every ``breakpoint + t_i``; same total displacement (amplitudes sum to 1).
        """
        if shaper is None:
            return self
        b = np.sort((self.breakpoints[:, None] + shaper.times[None, :]).ravel())
        b = b[np.concatenate([[True], np.diff(b) > TIME_TOLERANCE_S])]
        mid = 0.5 * (b[:-1] + b[1:])
        v = np.zeros_like(mid)
        for a, ti in zip(shaper.amplitudes, shaper.times, strict=True):
            v += a * self.sample(mid - ti)
        v[np.abs(v) < 1e-9 * max(1.0, float(np.max(np.abs(self.velocities))))] = 0.0
        return VelocityProfile(b, v).simplified()


def single_pulse(v_in_mm_s: float, x_f_mm: float, t_start: float, direction: int = 1) -> VelocityProfile:
    """One move: ``direction * v_in`` from ``t_start`` for ``t_p = x_f / v_in``.

    Parameters
    ----------
    v_in_mm_s, x_f_mm : float
        Speed (mm/s) and displacement (mm), both > 0.
    t_start : float
        Start (s).
    direction : int
        +1 pull, -1 release.

    Returns
    -------
    VelocityProfile
    """
    if direction not in (1, -1):
        raise ValueError(f"direction must be +1 or -1, got {direction!r}")
    t_p = pulse_time(v_in_mm_s, x_f_mm)
    t0 = check_time(t_start, "t_start")
    return VelocityProfile(np.array([t0, t0 + t_p]), np.array([direction * float(v_in_mm_s)]))


def pulse_profile(
    v_in_mm_s: float,
    x_f_mm: float,
    t_up: float = paper.PULSE_T_UP_S,
    t_down: float = paper.PULSE_T_DOWN_S,
) -> VelocityProfile:
    """The paper's Up-hold-Down velocity pulse (its eq. 14) as an exact :class:`VelocityProfile`.

    ``v_in`` for ``t_up <= t < t_up + t_p``, ``-v_in`` for ``t_down <= t < t_down + t_p``, else 0, with
    ``t_p = x_f / v_in``: its :meth:`~VelocityProfile.sample` gives the velocity at any times, its
    :meth:`~VelocityProfile.shaped` the pulse shaped by a shaper, exactly.

    Parameters
    ----------
    v_in_mm_s, x_f_mm : float
        Cable speed (mm/s) and the displacement of each move (mm), both > 0.
    t_up, t_down : float
        Start of the up and down moves (s; the paper uses 1 s and 8 s); the up move must end by ``t_down``.

    Returns
    -------
    VelocityProfile
    """
    t_p = pulse_time(v_in_mm_s, x_f_mm)
    t_up = check_time(t_up, "t_up")
    t_down = check_time(t_down, "t_down")
    if t_up + t_p > t_down:
        raise ValueError(f"the up move ends at {t_up + t_p:.4f} s, after the down move starts ({t_down} s)")
    v = float(v_in_mm_s)
    if t_up + t_p == t_down:
        return VelocityProfile(np.array([t_up, t_down, t_down + t_p]), np.array([v, -v]))
    return VelocityProfile(np.array([t_up, t_up + t_p, t_down, t_down + t_p]), np.array([v, 0.0, -v]))


def table_i() -> pd.DataFrame:
    """The paper's Table I: twelve scenarios (three systems x four conditions).

    Returns
    -------
    pandas.DataFrame
        Columns ``profile`` (the paper's name), ``system`` (``unshaped``/``zv``/``zvd``), ``v_in_mm_s``,
        ``x_f_mm``, ``t_p_s`` (= x_f / v_in, computed).
    """
    labels = {s: paper.SYSTEM_LABELS[s] + ("" if s == "unshaped" else " TDF") for s in paper.SYSTEMS}
    rows = [
        (labels[system], system, v, x, x / v)
        for system in paper.SYSTEMS
        for v, x in paper.TABLE_I_CONDITIONS
    ]
    return pd.DataFrame(rows, columns=["profile", "system", "v_in_mm_s", "x_f_mm", "t_p_s"])
