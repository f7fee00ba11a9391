"""Designs scheduled on the mode map: a pair for the residual's configurations, and a map-following schedule.

**Scheduled pair** (:func:`scheduled_pair`). Each move's shaper is a classical family designed for the mode
at the configuration where that move's residual vibration rings: the Up move's at its destination
``start + x_f``, the Down move's at the rest position ``start``.

**Map-following schedule** (:func:`map_following`). A shaped move is a sum of sub-moves: sub-move ``k``
runs at ``A_k v_in`` from ``s_k`` for ``d_k`` (a convolution with a shaper has ``s_k = t_k`` and every
``d_k = t_p = x_f / v_in``). Each start and each stop is a velocity step that excites the mode; in the
quasi-static picture (the mode's frequency is the map's at the cable position the command has reached) the
vibration excited at time ``t1`` has turned by the phase

    Theta(t2) - Theta(t1),   Theta(t) = integral of omega_d(x(t')) dt'

by time ``t2``, where ``x(t)`` is the commanded cable position. A classical shaper cancels its mode because
its impulses are spaced by the phases ``phi_k = omega_d t_k`` (ZV: 0, pi; ZVD: 0, pi, 2 pi). The rule:

    Theta(s_k) - Theta(s_{k-1}) = phi_k - phi_{k-1}     (the starts)
    Theta(e_k) - Theta(e_{k-1}) = phi_k - phi_{k-1}     (the stops, e_k = s_k + d_k)

so the starts cancel each other's vibration and the stops cancel each other's, each at the frequencies the
arm has while they happen, and the first sub-move's duration ``d_0`` is chosen so that the move still covers
``x_f``: ``v_in sum A_k d_k = x_f``. ``x(t)`` depends only on steps already taken, so the instants follow
one by one (event by event, the phase integral exact for the monotone cubic interpolant of the map), and
``d_0`` by a one-dimensional root search. The amplitudes ``A_k`` and phases ``phi_k`` are the family's at the
reference configuration of the scheduled pair (Up: destination; Down: rest). For a map that does not depend
on position ``Theta(t) = omega_d t``, so ``s_k = t_k`` and ``d_k = t_p``: the schedule **is** the
convolution with the family's shaper (ZV, ZVD, ...), to the root search's tolerance (1e-12 s).

What the rule leaves out: damping and modal gain that change during the move (the amplitudes are the
reference configuration's) and the adiabatic change of amplitude with frequency; these are second-order next
to the phase for this arm (``docs/shaper_design.md`` quantifies it on the time-varying model).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.optimize import brentq

from helpers.base.validate import check_positive
from helpers.paper.modes import omega_d_from_natural
from helpers.paper.shapers import Shaper
from helpers.research.design.formats import Design, MoveSchedule, Schedule, ShaperPair, SubMove
from helpers.research.families import FAMILIES
from helpers.research.modemap import ModeMap, mode_at

TIME_TOLERANCE_S = 1e-13
"""Tolerance of the root searches that place the sub-moves' instants."""


def family(name: str) -> Any:
    """The shaper family called ``name`` (:data:`helpers.research.families.FAMILIES`; case-insensitive)."""
    by_lower = {k.lower(): v for k, v in FAMILIES.items()}
    if not isinstance(name, str) or name.lower() not in by_lower:
        raise ValueError(f"unknown shaper family {name!r}; choose from {', '.join(FAMILIES)}")
    return by_lower[name.lower()]


def _named(shaper: Shaper, name: str) -> Shaper:
    return Shaper(shaper.amplitudes, shaper.times, name)


def _map_info(mode_map: ModeMap) -> dict[str, Any]:
    return {
        "source": dict(mode_map.source),
        "range_mm": list(mode_map.range_mm),
        "n_positions": len(mode_map),
    }


def _move_info(x_f_mm: float, start_mm: float, v_in_mm_s: float | None = None) -> dict[str, float]:
    info = {"x_f_mm": float(x_f_mm), "start_mm": float(start_mm)}
    if v_in_mm_s is not None:
        info["v_in_mm_s"] = float(v_in_mm_s)
    return info


def scheduled_pair(
    mode_map: ModeMap, x_f_mm: float, family_name: str = "ZV", start_mm: float = 0.0
) -> Design:
    """The scheduled pair: Up shaper at the destination's mode, Down shaper at the rest position's.

    Parameters
    ----------
    mode_map : ModeMap
        The measured map; the move must lie inside it.
    x_f_mm : float
        The move's displacement (mm).
    family_name : str
        A family of :data:`helpers.research.families.FAMILIES` (``"ZV"``, ``"ZVD"``, ``"EI"``, ...).
    start_mm : float
        Where the Up move starts (mm); the paper's pulses start at 0.

    Returns
    -------
    Design
        System ``"scheduled"``, a :class:`~helpers.research.design.formats.ShaperPair`.
    """
    x_f = check_positive(x_f_mm, "x_f_mm")
    fam = family(family_name)
    end = float(start_mm) + x_f
    mode_map.sweep(start_mm, end)
    up_mode, down_mode = mode_at(mode_map, end), mode_at(mode_map, start_mm)
    label = fam.name
    up = _named(fam(*up_mode), f"{label} at {end:g} mm")
    down = _named(fam(*down_mode), f"{label} at {float(start_mm):g} mm")
    provenance = {
        "design": "scheduled pair",
        "family": label,
        "move": _move_info(x_f, start_mm),
        "up_mode": {"position_mm": end, "omega_n": up_mode[0], "zeta": up_mode[1]},
        "down_mode": {"position_mm": float(start_mm), "omega_n": down_mode[0], "zeta": down_mode[1]},
        "mode_map": _map_info(mode_map),
    }
    return Design("scheduled", ShaperPair(up, down), provenance)


class _PhaseClock:
    """``Theta`` along a command: the integral of the map's damped frequency over time (exact for PCHIP)."""

    def __init__(self, mode_map: ModeMap) -> None:
        x, w = mode_map.positions_mm, mode_map.omega_d
        self.lo, self.hi = float(x[0]), float(x[-1])
        self.w = PchipInterpolator(x, w)
        self.w_lo, self.w_hi = float(w[0]), float(w[-1])
        self.w_min = float(np.min(w))
        self.F = self.w.antiderivative()

    def omega(self, x: float) -> float:
        """The damped frequency at ``x`` (held constant beyond the ends, for root bracketing only)."""
        return float(self.w(min(max(x, self.lo), self.hi)))

    def integral(self, x: float) -> float:
        """``int_{lo}^{x} omega_d dx`` (with the ends held beyond the range)."""
        xc = min(max(x, self.lo), self.hi)
        out = float(self.F(xc))
        if x < self.lo:
            out += (x - self.lo) * self.w_lo
        elif x > self.hi:
            out += (x - self.hi) * self.w_hi
        return out

    def advance(self, x: float, velocity: float, dt: float) -> float:
        """Phase gained over ``dt`` seconds from ``x`` at constant ``velocity`` (mm/s)."""
        if velocity == 0.0:
            return self.omega(x) * dt
        return (self.integral(x + velocity * dt) - self.integral(x)) / velocity

    def time_to(self, x: float, velocity: float, dphase: float) -> float:
        """Seconds until the phase has grown by ``dphase`` >= 0 from ``x`` at constant ``velocity``."""
        if dphase <= 0.0:
            return 0.0
        if velocity == 0.0:
            return dphase / self.omega(x)
        hi = dphase / self.w_min * 1.01 + 1e-12
        def gap(dt: float) -> float:
            return self.advance(x, velocity, dt) - dphase

        return brentq(gap, 0.0, hi, xtol=TIME_TOLERANCE_S, rtol=1e-15)


class _Infeasible(Exception):
    """A sub-move would stop before it starts (the first sub-move is too short)."""


def _run(
    clock: _PhaseClock, amps: np.ndarray, phases: np.ndarray, v: float, x0: float, direction: int, d0: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """Place starts and stops event by event for a first-sub-move duration ``d0``; return them and the end."""
    n = amps.size
    starts, stops = [0.0], []
    t, x, theta = 0.0, x0, 0.0
    velocity = direction * amps[0] * v
    theta_start, theta_stop = [0.0], []
    while len(starts) < n or len(stops) < n:
        i, j = len(starts), len(stops)
        candidates = []
        if i < n:
            target = theta_start[-1] + phases[i] - phases[i - 1]
            candidates.append((clock.time_to(x, velocity, target - theta), 0))
        if j < n:
            if j == 0:
                dt = max(d0 - t, 0.0)
            else:
                target = theta_stop[-1] + phases[j] - phases[j - 1]
                dt = clock.time_to(x, velocity, target - theta)
            candidates.append((dt, 1))
        dt, which = min(candidates)
        theta += clock.advance(x, velocity, dt)
        x += velocity * dt
        t += dt
        if which == 0:
            starts.append(t)
            theta_start.append(theta)
            velocity += direction * amps[i] * v
        else:
            if j >= len(starts):
                raise _Infeasible
            stops.append(t)
            theta_stop.append(theta)
            velocity -= direction * amps[j] * v
    return np.array(starts), np.array(stops), x


def follow_move(
    mode_map: ModeMap,
    start_mm: float,
    end_mm: float,
    v_in_mm_s: float,
    amplitudes: np.ndarray,
    phases: np.ndarray,
) -> MoveSchedule:
    """One move's map-following sub-moves (the rule of the module docstring).

    Parameters
    ----------
    mode_map : ModeMap
        The map; the move must lie inside it.
    start_mm, end_mm : float
        Where the move starts and ends (mm); its direction follows.
    v_in_mm_s : float
        The move's speed.
    amplitudes : numpy.ndarray
        The sub-moves' amplitudes (positive, summing to 1).
    phases : numpy.ndarray
        The phases ``phi_k`` (rad) between which the starts (and the stops) are spaced, ``phi_0 = 0``.

    Returns
    -------
    MoveSchedule

    Raises
    ------
    ValueError
        If the move leaves the map, an amplitude is not positive, or no schedule covers the move.
    """
    v = check_positive(v_in_mm_s, "v_in_mm_s")
    mode_map.sweep(start_mm, end_mm)
    amps = np.asarray(amplitudes, dtype=float)
    phases = np.asarray(phases, dtype=float)
    if np.any(amps <= 0):
        raise ValueError("map-following needs positive impulses (a sub-move cannot run backwards)")
    if phases.shape != amps.shape or phases[0] != 0.0 or np.any(np.diff(phases) < 0):
        raise ValueError("map-following: phases must start at 0, not decrease and match the amplitudes")
    x_f = abs(float(end_mm) - float(start_mm))
    if x_f <= 0:
        raise ValueError("map-following: the move must have a length")
    direction = 1 if end_mm > start_mm else -1
    clock = _PhaseClock(mode_map)
    t_p = x_f / v

    def moved(d0: float) -> float:
        try:
            _, _, x_end = _run(clock, amps, phases, v, float(start_mm), direction, d0)
        except _Infeasible:
            return -x_f
        return direction * (x_end - float(start_mm)) - x_f

    hi = t_p
    for _ in range(60):
        if moved(hi) > 0:
            break
        hi *= 2.0
    else:  # pragma: no cover - the displacement grows without bound with d0
        raise ValueError("map-following: no first sub-move is long enough to cover the move")
    d0 = brentq(moved, 0.0, hi, xtol=TIME_TOLERANCE_S, rtol=1e-15)
    try:
        starts, stops, x_end = _run(clock, amps, phases, v, float(start_mm), direction, d0)
    except _Infeasible:
        raise ValueError(
            f"map-following: no schedule covers {x_f:g} mm at {v:g} mm/s with this map: a sub-move would "
            "stop before it starts (the move is too short for the change of frequency it sweeps)"
        ) from None
    durations = stops - starts
    if np.any(durations <= 0):
        raise ValueError("map-following: a sub-move would have no duration (the move is too short)")
    # the first duration comes from the root search; make the displacement exact in it
    rest = math.fsum(a * d for a, d in zip(amps[1:], durations[1:], strict=True))
    durations[0] = (t_p - rest) / amps[0]
    rows = zip(amps, starts, durations, strict=True)
    subs = tuple(SubMove(float(a), float(s), float(d)) for a, s, d in rows)
    return MoveSchedule(subs)


def map_following(
    mode_map: ModeMap, x_f_mm: float, v_in_mm_s: float, family_name: str = "ZV", start_mm: float = 0.0
) -> Design:
    """The map-following schedule of one pulse experiment (rule in the module docstring).

    Parameters
    ----------
    mode_map : ModeMap
        The measured map; the move must lie inside it.
    x_f_mm, v_in_mm_s : float
        The move (mm, mm/s): a schedule belongs to its move.
    family_name : str
        A family with positive impulses (``"ZV"``, ``"ZVD"``, ``"ZVDD"``, ``"MZV"``, ``"EI"``, ...).
    start_mm : float
        Where the Up move starts (mm).

    Returns
    -------
    Design
        System ``"map-following"``, a :class:`~helpers.research.design.formats.Schedule`.
    """
    x_f = check_positive(x_f_mm, "x_f_mm")
    v = check_positive(v_in_mm_s, "v_in_mm_s")
    fam = family(family_name)
    start = float(start_mm)
    end = start + x_f
    mode_map.sweep(start, end)
    moves = {}
    refs = {}
    for name, (a, b, ref) in {"up": (start, end, end), "down": (end, start, start)}.items():
        omega_n, zeta = mode_at(mode_map, ref)
        shaper = fam(omega_n, zeta)
        phases = shaper.times * omega_d_from_natural(omega_n, zeta)
        moves[name] = follow_move(mode_map, a, b, v, shaper.amplitudes, phases)
        refs[name] = {"position_mm": ref, "omega_n": omega_n, "zeta": zeta, "phases_rad": phases.tolist()}
    provenance = {
        "design": "map-following schedule",
        "family": fam.name,
        "rule": "starts and stops each spaced by the family's phases in the map's phase clock",
        "move": _move_info(x_f, start, v),
        "reference_modes": refs,
        "mode_map": _map_info(mode_map),
    }
    return Design("map-following", Schedule(moves["up"], moves["down"], v, x_f), provenance)
