"""The residual of a design on a time-varying model: one mode whose frequency follows the map during the move.

The predicted residual of :mod:`helpers.research.design.predict` judges a shaper mode by mode with frozen
frequencies. During a move the arm's frequency changes; this module judges a design on the simplest model
that has that change, the **quasi-static single-mode model**: the mode's deflection ``y`` obeys

    y'' + 2 zeta(x) omega_n(x) y' + omega_n(x)^2 y = -u''(t),

where ``u(t)`` is the commanded cable position (mm), ``x = u(t)``, and ``omega_n(x)``, ``zeta(x)`` are the
mode map's dominant mode (monotone cubic interpolation). A piecewise-constant velocity command makes ``u''``
a train of velocity steps, so ``y'`` jumps by minus each step and the mode rings freely between them
(integrated with ``scipy.integrate.solve_ivp``, DOP853, relative tolerance 1e-10). After the last step the
arm rests at the destination, where the ringing's amplitude is
``R = sqrt(y^2 + ((y' + sigma y) / omega_d)^2)`` (``sigma = zeta omega_n``).

The **time-varying residual** of a shaped move is its ``R`` when its last step has been taken, divided by
the unshaped move's ``R`` when its last step has been taken (Singer and Seering's convention: each command is
judged when it ends). For a map that does not depend on position this is exactly the shaper's ``V``
(tested), so the two measures agree where they should and differ only by what the map's variation does
during the move.

What the model leaves out: the second mode, modal gains and mode shapes that change with the configuration,
the cable's slack and the stepper's steps (the virtual rig has all of these).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import numpy as np
import pandas as pd
from scipy.integrate import solve_ivp
from scipy.interpolate import PchipInterpolator

from helpers.base.validate import check_positive
from helpers.paper.shapers import Shaper
from helpers.research.design.formats import Design, MoveSchedule, Schedule, Shaping, up_down
from helpers.research.modemap import ModeMap

RTOL = 1e-10
"""Relative tolerance of the integration between velocity steps."""


def move_edges(
    shaping: Shaper | MoveSchedule | None, v_in_mm_s: float, x_f_mm: float, direction: int
) -> tuple[np.ndarray, np.ndarray]:
    """The velocity steps of one shaped move: times (s from its start, sorted) and steps (mm/s).

    Parameters
    ----------
    shaping : Shaper, MoveSchedule or None
        The move's shaper (convolved with the pulse), its sub-moves, or None (unshaped).
    v_in_mm_s, x_f_mm : float
        The move.
    direction : int
        +1 (Up) or -1 (Down).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
    """
    if isinstance(shaping, MoveSchedule):
        return shaping.edges(v_in_mm_s, direction)
    shaper = Shaper.unit() if shaping is None else shaping
    t_p = x_f_mm / v_in_mm_s
    t = np.concatenate([shaper.times, shaper.times + t_p])
    dv = np.concatenate([shaper.amplitudes, -shaper.amplitudes]) * direction * v_in_mm_s
    order = np.argsort(t, kind="stable")
    return t[order], dv[order]


class _Oscillator:
    """The quasi-static single-mode model of the module docstring, on one mode map."""

    def __init__(self, mode_map: ModeMap) -> None:
        x = mode_map.positions_mm
        self.lo, self.hi = float(x[0]), float(x[-1])
        self.wd = PchipInterpolator(x, mode_map.omega_d)
        self.z = PchipInterpolator(x, mode_map.zeta)

    def mode(self, x: float) -> tuple[float, float, float]:
        """``(omega_n, zeta, omega_d)`` at cable position ``x``."""
        xc = min(max(x, self.lo), self.hi)
        wd, z = float(self.wd(xc)), float(self.z(xc))
        return wd / math.sqrt(1.0 - z * z), z, wd

    def ring(self, t: np.ndarray, dv: np.ndarray, x0: float) -> float:
        """Apply the steps from rest at ``x0``; return the ringing amplitude after the last one."""
        y = np.zeros(2)
        x, v, now = x0, 0.0, float(t[0])
        for te, jump in zip(t, dv, strict=True):
            if te > now:
                x_start, v_now, t_start = x, v, now

                def rhs(tt: float, s: np.ndarray, x1=x_start, v1=v_now, t1=t_start) -> list[float]:
                    wn, z, _ = self.mode(x1 + v1 * (tt - t1))
                    return [s[1], -2.0 * z * wn * s[1] - wn * wn * s[0]]

                sol = solve_ivp(rhs, (now, te), y, method="DOP853", rtol=RTOL, atol=1e-12 * max(1.0, abs(v)))
                y = sol.y[:, -1]
                x += v * (te - now)
                now = float(te)
            y = y + np.array([0.0, -jump])
            v += jump
        wn, z, wd = self.mode(x)
        sigma = z * wn
        return math.hypot(y[0], (y[1] + sigma * y[0]) / wd)


def time_varying_residual(
    shaping: Shaping | Design | None,
    mode_map: ModeMap,
    x_f_mm: float,
    v_in_mm_s: float,
    start_mm: float = 0.0,
) -> dict[str, float]:
    """The time-varying residual (fraction of the unshaped move's) of each move of a pulse experiment.

    Parameters
    ----------
    shaping : Shaper, ShaperPair, Schedule, Design or None
        The design (None: unshaped, which gives 1.0).
    mode_map : ModeMap
        The map the model follows; the moves must lie inside it.
    x_f_mm, v_in_mm_s : float
        The move (mm, mm/s).
    start_mm : float
        Where the Up move starts.

    Returns
    -------
    dict
        ``{"up": ..., "down": ...}``.
    """
    x_f = check_positive(x_f_mm, "x_f_mm")
    v = check_positive(v_in_mm_s, "v_in_mm_s")
    inner = shaping.shaping if isinstance(shaping, Design) else shaping
    start, end = float(start_mm), float(start_mm) + x_f
    mode_map.sweep(start, end)
    if isinstance(inner, Schedule):
        inner.check_move(v, x_f)
        moves: tuple = (inner.up, inner.down)
    else:
        moves = up_down(inner)
    osc = _Oscillator(mode_map)
    out = {}
    for name, move, direction, x0 in (("up", moves[0], 1, start), ("down", moves[1], -1, end)):
        shaped = osc.ring(*move_edges(move, v, x_f, direction), x0)
        out[name] = shaped / osc.ring(*move_edges(None, v, x_f, direction), x0)
    return out


def compare_time_varying(
    designs: Mapping[str, Shaping | Design | None],
    mode_map: ModeMap,
    moves: Iterable[tuple[float, float]],
    start_mm: float = 0.0,
) -> pd.DataFrame:
    """Time-varying residuals (percent) of several designs over several moves.

    Parameters
    ----------
    designs : mapping
        Label -> design, or label -> ``callable(v_in, x_f) -> design`` for designs that depend on the move
        (scheduled, map-following).
    mode_map : ModeMap
        The map.
    moves : iterable of (v_in_mm_s, x_f_mm)
        The moves.
    start_mm : float
        Where each Up move starts.

    Returns
    -------
    pandas.DataFrame
        ``v_in_mm_s``, ``x_f_mm``, ``design``, ``up_pct``, ``down_pct``.
    """
    rows = []
    for v, x in moves:
        for label, d in designs.items():
            design = d(v, x) if callable(d) else d
            r = time_varying_residual(design, mode_map, x, v, start_mm)
            row = {"v_in_mm_s": v, "x_f_mm": x, "design": label}
            rows.append({**row, "up_pct": 100 * r["up"], "down_pct": 100 * r["down"]})
    return pd.DataFrame(rows)
