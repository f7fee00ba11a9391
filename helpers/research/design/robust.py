"""Designs robust over the band a move sweeps: a family centred on the band, multi-mode, and minimax.

All three hold one shaper for both moves of a pulse experiment (the Up move and the Down move sweep the same
cable positions) and are judged by the predicted residual of :mod:`helpers.research.design.predict`.

- :func:`band_centred` (system ``"ei"`` for the EI family, ``"custom"`` otherwise): a family designed at the
  band's centre, :meth:`helpers.research.design.predict.Band.centre` (the midpoint of the lowest and highest
  undamped frequency over the band and its uncertainty, and the mean damping ratio). EI-type shapers are
  symmetric in frequency about their design point to first order, so the midpoint centres their
  insensitive band on the band the move sweeps.
- :func:`multi_mode_design` (system ``"multi-mode"``): the dominant mode's shaper convolved with a shaper on
  the second mode, each designed at its band centre (``placement="centre"``, one shaper) or, as the
  scheduled pair, at each move's residual configuration (``placement="scheduled"``, a pair). ``V`` of a
  convolution is the product of the factors' ``V`` for every mode.
- :func:`minimax` (system ``"minimax"``): ``n`` impulses ``A_i >= 0`` summing to 1 at ``0 = t_0 <= t_1
  <= ... <= t_{n-1} <= cap`` that minimise the worst predicted residual over the band,

      minimise  max_p  max_s [ (1 - s) max_c V(A, t; mode 1 at corner c of p)
                             + s max_c V(A, t; mode 2 at corner c of p) ],

  with ``p`` the band's positions, ``c`` the nine uncertainty corners and ``s`` the share's two ends (the
  second-mode term only when the map has one). It is solved in epigraph form by ``scipy.optimize``'s SLSQP
  (variables: amplitudes, times in units of the band-centre period, one bound per position and mode, the
  worst value; constraints ``m_p^2 >= V^2`` with exact gradients) from a fixed set of starting shapers: the
  classical families at the band centre (compressed to the cap if longer), with a second mode also each
  convolved with a ZV on the second mode's band centre, the two-impulse ZV at the frequencies of the band's
  ends, and equally spaced binomial impulses spread over the cap. Every start is
  scored by the exact objective; SLSQP runs from the :data:`MINIMAX_STARTS` best (ties in the order listed),
  every result is scored the same way and the best start or result is kept, so the result is never worse
  than any start (in particular than the classical families at the band centre, compressed to the cap if
  longer). Deterministic: no random starts. In the spirit of Klipper's shaper calibration, which scores each
  candidate shaper by the vibration it leaves over a measured spectrum, pessimised over damping ratios.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.optimize import minimize

from helpers.base.validate import check_int, check_positive
from helpers.paper.shapers import Shaper
from helpers.research.design.formats import Design, ShaperPair
from helpers.research.design.predict import (
    DEFAULT_COVERAGE,
    DEFAULT_N_BETWEEN,
    Band,
    band,
    worst_residual_pct,
)
from helpers.research.design.scheduled import _map_info, _move_info, family
from helpers.research.families import FAMILIES, normalised
from helpers.research.modemap import ModeMap, mode_at

EI_FAMILIES = ("EI", "2-hump EI", "3-hump EI")
"""The extra-insensitive families (system ``"ei"``)."""

MINIMAX_IMPULSES = 5
"""Default number of impulses of a minimax design (:data:`MINIMAX_IMPULSES_TWO_MODES` with a second mode)."""

MINIMAX_IMPULSES_TWO_MODES = 8
"""Default number of impulses of a minimax design over a map with a second mode."""

MINIMAX_STARTS = 4
"""SLSQP runs from this many of the best-scoring starts."""

AMPLITUDE_FLOOR = 1e-7
"""Impulses of a minimax result below this amplitude are dropped (the rest renormalised)."""


def _named(shaper: Shaper, name: str) -> Shaper:
    return Shaper(shaper.amplitudes, shaper.times, name)


def _band_of(mode_map: ModeMap, x_f_mm: float, start_mm: float, coverage: float, n_between: int) -> Band:
    x_f = check_positive(x_f_mm, "x_f_mm")
    return band(mode_map, float(start_mm), float(start_mm) + x_f, coverage, n_between)


def band_centred(
    mode_map: ModeMap,
    x_f_mm: float,
    family_name: str = "EI",
    start_mm: float = 0.0,
    coverage: float = DEFAULT_COVERAGE,
    n_between: int = DEFAULT_N_BETWEEN,
) -> Design:
    """A family designed at the centre of the band the move sweeps (EI and multi-hump EI: system ``"ei"``).

    Parameters
    ----------
    mode_map : ModeMap
        The measured map.
    x_f_mm, start_mm : float
        The move (mm).
    family_name : str
        ``"EI"``, ``"2-hump EI"``, ``"3-hump EI"`` (or any family of
        :data:`helpers.research.families.FAMILIES`).
    coverage, n_between
        The band's uncertainty and positions (:func:`helpers.research.design.predict.band`).

    Returns
    -------
    Design
        One shaper for both moves, with its worst predicted residual in the provenance.
    """
    fam = family(family_name)
    b = _band_of(mode_map, x_f_mm, start_mm, coverage, n_between)
    omega_n, zeta = b.centre()
    shaper = _named(fam(omega_n, zeta), f"{fam.name} centred on {b.low_mm:g}-{b.high_mm:g} mm")
    system = "ei" if fam.name in EI_FAMILIES else "custom"
    provenance = {
        "design": "band-centred",
        "family": fam.name,
        "centre": {"omega_n": omega_n, "zeta": zeta},
        "move": _move_info(x_f_mm, start_mm),
        "band": b.as_dict(),
        "predicted_worst_pct": worst_residual_pct(shaper, b),
        "mode_map": _map_info(mode_map),
    }
    return Design(system, shaper, provenance)


def multi_mode_design(
    mode_map: ModeMap,
    x_f_mm: float,
    family_name: str = "ZVD",
    family2_name: str = "ZV",
    placement: str = "centre",
    start_mm: float = 0.0,
    coverage: float = DEFAULT_COVERAGE,
    n_between: int = DEFAULT_N_BETWEEN,
) -> Design:
    """The dominant mode's shaper convolved with a shaper on the second mode.

    Parameters
    ----------
    mode_map : ModeMap
        A map with a second mode.
    x_f_mm, start_mm : float
        The move (mm).
    family_name, family2_name : str
        Families for the dominant and the second mode.
    placement : str
        ``"centre"``: both designed at their band centre, one shaper for both moves; ``"scheduled"``: designed
        at each move's residual configuration (Up: destination, Down: rest), a pair.
    coverage, n_between
        The band (for ``"centre"`` and the predicted residual).

    Returns
    -------
    Design
        System ``"multi-mode"``.
    """
    if not mode_map.has_second_mode:
        raise ValueError("multi-mode needs a mode map with a second mode (omega_d2, zeta2, share2)")
    f1, f2 = family(family_name), family(family2_name)
    b = _band_of(mode_map, x_f_mm, start_mm, coverage, n_between)
    label = f"{f1.name} * {f2.name}"
    info: dict[str, Any] = {"design": "multi-mode", "family": f1.name, "family2": f2.name}
    info["placement"] = placement
    if placement == "centre":
        m1, m2 = b.centre(), b.centre2()
        shaping: Shaper | ShaperPair = _named(f1(*m1).convolve(f2(*m2)), f"{label} centred")  # type: ignore[misc]
        info["modes"] = {"omega_n": m1[0], "zeta": m1[1], "omega_n2": m2[0], "zeta2": m2[1]}  # type: ignore[index]
        info["predicted_worst_pct"] = worst_residual_pct(shaping, b)  # type: ignore[arg-type]
    elif placement == "scheduled":
        parts = {}
        end = float(start_mm) + float(x_f_mm)
        for name, x in (("up", end), ("down", float(start_mm))):
            p = mode_map.at(x)
            m1 = mode_at(mode_map, x)
            m2 = (float(p.omega_n2), float(p.zeta2))
            parts[name] = _named(f1(*m1).convolve(f2(*m2)), f"{label} at {x:g} mm")
            info[f"{name}_modes"] = {"position_mm": x, "omega_n": m1[0], "zeta": m1[1], "omega_n2": m2[0],
                                     "zeta2": m2[1]}  # fmt: skip
        shaping = ShaperPair(parts["up"], parts["down"])
    else:
        raise ValueError(f"placement must be 'centre' or 'scheduled', got {placement!r}")
    info.update(move=_move_info(x_f_mm, start_mm), band=b.as_dict(), mode_map=_map_info(mode_map))
    return Design("multi-mode", shaping, info)


# -- minimax -----------------------------------------------------------------------------------------------
class _Problem:
    """The epigraph form of the minimax objective (module docstring), on a band's points."""

    def __init__(self, b: Band, n: int, cap_s: float) -> None:
        self.b, self.n = b, n
        self.scale = b.centre()[0]  # time unit 1/omega_c: times in radians of the band centre
        self.cap = cap_s * self.scale
        self.modes = [(b.omega_n1, b.zeta1)] + ([(b.omega_n2, b.zeta2)] if b.omega_n2 is not None else [])
        self.P = b.positions_mm.size
        # per mode: flattened grid points (P*9) and the position each belongs to
        self.grid = []
        for wn, z in self.modes:
            wn, z = wn.ravel(), z.ravel()
            self.grid.append((z * wn / self.scale, wn * np.sqrt(1 - z**2) / self.scale))
        self.owner = np.repeat(np.arange(self.P), 9)
        self.shares = b.shares
        # variable layout: a (n) | theta_1..n-1 (n-1) | m (P per mode) | z
        self.i_a = slice(0, n)
        self.i_t = slice(n, 2 * n - 1)
        first = 2 * n - 1
        self.i_m = [slice(first + k * self.P, first + (k + 1) * self.P) for k in range(len(self.modes))]
        self.size = 2 * n - 1 + len(self.modes) * self.P + 1

    def unpack(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return x[self.i_a], np.concatenate([[0.0], x[self.i_t]])

    def vib2(self, a: np.ndarray, th: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """V^2 at every grid point of mode ``k`` and its gradients in a and theta (theta_0 included)."""
        sig, wd = self.grid[k]
        last = th[-1]
        e = np.exp(sig[:, None] * (th[None, :] - last))
        c, s = np.cos(wd[:, None] * th[None, :]), np.sin(wd[:, None] * th[None, :])
        w = a[None, :] * e
        C, S = np.sum(w * c, axis=1), np.sum(w * s, axis=1)
        v2 = C * C + S * S
        dC_da, dS_da = e * c, e * s
        dC_dt = w * (sig[:, None] * c - wd[:, None] * s)
        dS_dt = w * (sig[:, None] * s + wd[:, None] * c)
        dC_dt[:, -1] -= sig * C
        dS_dt[:, -1] -= sig * S
        g_a = 2 * (C[:, None] * dC_da + S[:, None] * dS_da)
        g_t = 2 * (C[:, None] * dC_dt + S[:, None] * dS_dt)
        return v2, g_a, g_t

    def objective_exact(self, a: np.ndarray, th: np.ndarray) -> float:
        """The minimax objective (fraction) of impulses ``a`` at phases ``th``."""
        worst = []
        for k in range(len(self.modes)):
            v = np.sqrt(self.vib2(a, th, k)[0]).reshape(self.P, 9).max(axis=1)
            worst.append(v)
        if len(worst) == 1:
            return float(worst[0].max())
        s = self.shares
        return float(np.max((1 - s) * worst[0][:, None] + s * worst[1][:, None]))

    def constraints(self) -> list[dict[str, Any]]:
        n, P = self.n, self.P
        cons = []

        def bounds_fun(x: np.ndarray) -> np.ndarray:
            a, th = self.unpack(x)
            out = []
            for k in range(len(self.modes)):
                v2 = self.vib2(a, th, k)[0]
                m = x[self.i_m[k]][self.owner]
                out.append(m * m - v2)
            return np.concatenate(out)

        def bounds_jac(x: np.ndarray) -> np.ndarray:
            a, th = self.unpack(x)
            rows = []
            for k in range(len(self.modes)):
                _, g_a, g_t = self.vib2(a, th, k)
                J = np.zeros((g_a.shape[0], self.size))
                J[:, self.i_a] = -g_a
                J[:, self.i_t] = -g_t[:, 1:]
                m = x[self.i_m[k]]
                J[np.arange(g_a.shape[0]), self.i_m[k].start + self.owner] = 2 * m[self.owner]
                rows.append(J)
            return np.vstack(rows)

        cons.append({"type": "ineq", "fun": bounds_fun, "jac": bounds_jac})

        # z >= (1 - s) m1 + s m2 for each position and share end (or z >= m1)
        if len(self.modes) == 1:
            def top(x: np.ndarray) -> np.ndarray:
                return x[-1] - x[self.i_m[0]]

            J = np.zeros((P, self.size))
            J[:, -1] = 1.0
            J[np.arange(P), self.i_m[0].start + np.arange(P)] = -1.0
        else:
            s = self.shares  # (P, 2)

            def top(x: np.ndarray) -> np.ndarray:
                m1, m2 = x[self.i_m[0]], x[self.i_m[1]]
                return (x[-1] - ((1 - s) * m1[:, None] + s * m2[:, None])).ravel()

            J = np.zeros((2 * P, self.size))
            J[:, -1] = 1.0
            rows = np.arange(2 * P)
            pos = rows // 2
            J[rows, self.i_m[0].start + pos] = -(1 - s).ravel()
            J[rows, self.i_m[1].start + pos] = -s.ravel()
        J_top = J
        cons.append({"type": "ineq", "fun": top, "jac": lambda x: J_top})

        # ordering theta_i - theta_{i-1} >= 0 (theta_0 = 0) and the sum of amplitudes
        D = np.zeros((n - 1, self.size))
        for i in range(n - 1):
            D[i, n + i] = 1.0
            if i > 0:
                D[i, n + i - 1] = -1.0
        cons.append({"type": "ineq", "fun": lambda x: D @ x, "jac": lambda x: D})
        E = np.zeros((1, self.size))
        E[0, self.i_a] = 1.0
        cons.append({"type": "eq", "fun": lambda x: np.array([x[self.i_a].sum() - 1.0]), "jac": lambda x: E})
        return cons

    def start_vector(self, a: np.ndarray, th: np.ndarray) -> np.ndarray:
        x = np.zeros(self.size)
        x[self.i_a] = a
        x[self.i_t] = th[1:]
        vals = []
        for k in range(len(self.modes)):
            v = np.sqrt(self.vib2(a, th, k)[0]).reshape(self.P, 9).max(axis=1)
            x[self.i_m[k]] = v + 1e-9
            vals.append(v)
        x[-1] = self.objective_exact(a, th) + 1e-9
        return x


def _pad(shaper: Shaper, n: int, scale: float, cap: float) -> tuple[np.ndarray, np.ndarray] | None:
    """A start of ``n`` impulses from a shaper (times compressed to the cap if it is longer)."""
    if len(shaper) > n or np.any(shaper.amplitudes < 0):
        return None
    t = shaper.times * scale
    if t[-1] > cap:
        t = t * (cap / t[-1])
    a = shaper.amplitudes.copy()
    extra = n - a.size
    if extra:  # split the last impulse
        a = np.concatenate([a[:-1], np.full(extra + 1, a[-1] / (extra + 1))])
        t = np.concatenate([t[:-1], np.full(extra + 1, t[-1])])
    return a, t


def _starts(problem: _Problem, b: Band) -> list[tuple[str, np.ndarray, np.ndarray]]:
    n, scale, cap = problem.n, problem.scale, problem.cap
    omega_n, zeta = b.centre()
    second = None if b.centre2() is None else FAMILIES["ZV"](*b.centre2())  # type: ignore[misc]
    starts = []
    for name, fam in FAMILIES.items():
        if fam.zeta_range[0] <= zeta <= fam.zeta_range[1]:
            shaper = fam(omega_n, zeta)
            padded = _pad(shaper, n, scale, cap)
            if padded is not None:
                starts.append((f"{name} at the band centre", *padded))
            padded = None if second is None else _pad(shaper.convolve(second), n, scale, cap)
            if padded is not None:
                starts.append((f"{name} * ZV (second mode) at the band centres", *padded))
    lo, hi = b.omega_n_range
    for w in (lo, hi):
        padded = _pad(FAMILIES["ZV"](w, zeta), n, scale, cap)
        if padded is not None:
            starts.append((f"ZV at {w:.4g} rad/s", *padded))
    for k in range(2, n + 1):
        a = np.array([math.comb(k - 1, i) for i in range(k)], dtype=float)
        a = np.concatenate([a / a.sum(), np.zeros(n - k)])
        t = np.concatenate([np.linspace(0.0, cap, k), np.full(n - k, cap)])
        a[k - 1 :] = a[k - 1] / (n - k + 1)
        starts.append((f"{k} binomial impulses over the cap", a, t))
    return starts


def _clean(a: np.ndarray, th: np.ndarray, scale: float, name: str) -> Shaper:
    a = np.clip(a, 0.0, None)
    th = np.maximum.accumulate(np.clip(th, 0.0, None))
    keep = a > AMPLITUDE_FLOOR
    a, th = a[keep], th[keep]
    t = th / scale
    t -= t[0]
    merged_a, merged_t = [a[0]], [t[0]]
    for ai, ti in zip(a[1:], t[1:], strict=True):
        if ti - merged_t[-1] <= 1e-12:
            merged_a[-1] += ai
        else:
            merged_a.append(ai)
            merged_t.append(ti)
    return normalised(merged_a, merged_t, name)


def minimax(
    mode_map: ModeMap,
    x_f_mm: float,
    duration_cap_s: float,
    n_impulses: int | None = None,
    start_mm: float = 0.0,
    coverage: float = DEFAULT_COVERAGE,
    n_between: int = DEFAULT_N_BETWEEN,
    max_iter: int = 100,
) -> Design:
    """The minimax shaper of a move: the smallest worst predicted residual within a duration cap.

    Parameters
    ----------
    mode_map : ModeMap
        The measured map.
    x_f_mm, start_mm : float
        The move (mm).
    duration_cap_s : float
        The longest the shaper may last (s).
    n_impulses : int, optional
        Impulses to place (2-12; default :data:`MINIMAX_IMPULSES`, or :data:`MINIMAX_IMPULSES_TWO_MODES`
        with a second mode); unused ones end with zero amplitude and are dropped.
    coverage, n_between
        The band (:func:`helpers.research.design.predict.band`).
    max_iter : int
        SLSQP iterations per start.

    Returns
    -------
    Design
        System ``"minimax"``: one shaper for both moves; the provenance holds the objective's value
        (``predicted_worst_pct``), the start it came from and the optimiser's message.
    """
    cap = check_positive(duration_cap_s, "duration_cap_s")
    if n_impulses is None:
        n_impulses = MINIMAX_IMPULSES_TWO_MODES if mode_map.has_second_mode else MINIMAX_IMPULSES
    n = check_int(n_impulses, "n_impulses", 2)
    if n > 12:
        raise ValueError(f"n_impulses must be at most 12, got {n}")
    b = _band_of(mode_map, x_f_mm, start_mm, coverage, n_between)
    problem = _Problem(b, n, cap)
    bounds = [(0.0, 1.0)] * n + [(0.0, problem.cap)] * (n - 1) + [(0.0, None)] * (problem.size - 2 * n + 1)
    cons = problem.constraints()
    scored = [(problem.objective_exact(a0, th0), i, label, a0, th0) for i, (label, a0, th0) in
              enumerate(_starts(problem, b))]  # fmt: skip
    scored.sort(key=lambda row: (row[0], row[1]))
    best: tuple[float, np.ndarray, np.ndarray, str, str] | None = None
    for value, _, label, a0, th0 in scored[:MINIMAX_STARTS]:
        candidates = [(value, a0, th0, label, "start")]
        x0 = problem.start_vector(a0, th0)
        res = minimize(
            lambda x: x[-1],
            x0,
            jac=lambda x: np.eye(1, problem.size, problem.size - 1).ravel(),
            method="SLSQP",
            bounds=bounds,
            constraints=cons,
            options={"maxiter": int(max_iter), "ftol": 1e-10},
        )
        a, th = problem.unpack(res.x)
        a = np.clip(a, 0.0, None)
        if a.sum() > 0:
            a = a / a.sum()
            th = np.minimum(np.maximum.accumulate(np.clip(th, 0.0, None)), problem.cap)
            candidates.append((problem.objective_exact(a, th), a, th, label, str(res.message)))
        for cand in candidates:
            if best is None or cand[0] < best[0] - 1e-12:
                best = cand
    assert best is not None
    value, a, th, label, message = best
    shaper = _clean(a, th, problem.scale, f"minimax {b.low_mm:g}-{b.high_mm:g} mm")
    provenance = {
        "design": "minimax",
        "objective": "max over positions and share ends of (1 - s) max V1 + s max V2 over the uncertainty "
        "corners (percent)",
        "predicted_worst_pct": worst_residual_pct(shaper, b),
        "duration_cap_s": cap,
        "n_impulses": n,
        "start": label,
        "optimiser": message,
        "move": _move_info(x_f_mm, start_mm),
        "band": b.as_dict(),
        "mode_map": _map_info(mode_map),
    }
    return Design("minimax", shaper, provenance)
