"""Shapers that minimise a percentile of the residual under an uncertainty model, on the linear model.

- :func:`tune_family`: a classical family (ZVD, EI, MZV, 2-hump EI, ...) with its design frequency (and, for
  EI, its tolerance ``V``) chosen to minimise the objective, at the identified damping ratio, optionally
  no longer than a duration. A grid, then a bounded scalar search around its best point.
- :func:`optimise_shaper`: ``n`` positive impulses summing to 1 within a duration cap that minimise the
  objective. Nelder-Mead in unconstrained coordinates (amplitudes as a softmax, time increments as
  exponentials, scaled into the cap when they exceed it), first on a smooth surrogate (the mean of the worst
  10 %, which bounds the 90th percentile from above), then on the percentile itself, from fixed starts: the
  families compressed to the cap and equally spaced binomial impulses. No random numbers: deterministic.
- :func:`robust_designs`: the families tuned, the optimised shaper at the tuned families' durations, every
  compared family compressed or stretched to each robust design's duration (:func:`at_duration`: the
  comparison at equal duration), and a table of their objective; :func:`save_designs` /
  :func:`load_designs` keep them in a JSON file that the
  sweeps read (``docs/sweeps.md``).

The objective is the ``q``-th percentile (default 95) of
:func:`helpers.research.robustness.model.linear_residual_pct`
over a fixed :class:`~helpers.research.robustness.model.UncertaintySample`.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.optimize import minimize, minimize_scalar

from helpers.base.jsonfile import DataFileError, read_json, write_json
from helpers.paper.modes import omega_n_from_damped
from helpers.paper.shapers import Shaper
from helpers.research.families import FAMILIES, ei
from helpers.research.robustness.model import UncertaintyModel, UncertaintySample, linear_residual_pct

__all__ = [
    "COMPARED_FAMILIES",
    "DESIGNS_FORMAT",
    "TunedShaper",
    "DesignSet",
    "tune_family",
    "at_duration",
    "optimise_shaper",
    "robust_designs",
    "save_designs",
    "load_designs",
]

COMPARED_FAMILIES = ("ZVD", "EI", "MZV", "2-hump EI")
"""The standard families the robust design is judged against."""

DESIGNS_FORMAT = "continuum-arm-robust-shapers"
"""The ``format`` tag of a design-set file."""

ROBUST_IMPULSES = 5
"""Impulses of a robust design over a map with one mode."""

ROBUST_IMPULSES_TWO_MODES = 9
"""Impulses of a robust design over a map with a second mode (on the measured map, 5, 7 and 9 impulses at
355 ms give a 95th percentile of 6.3, 4.0 and 2.6 % on the linear model)."""

EI_VTOL_GRID = (0.005, 0.01, 0.02, 0.03, 0.05, 0.07, 0.1, 0.13, 0.16, 0.2, 0.25)
"""Tolerances ``V`` tried when tuning EI (each with its best design frequency)."""

FREQUENCY_RANGE = (0.7, 1.7)
"""Design frequencies tried, as multiples of the identified one."""


@dataclass(frozen=True)
class TunedShaper:
    """A shaper and how it was obtained.

    Attributes
    ----------
    name : str
        Its name in a sweep (e.g. ``"ei-tuned"``, ``"robust"``).
    shaper : Shaper
        The impulses.
    objective_pct : float
        The objective on the linear model (percentile of the residual, %).
    family : str or None
        The family, for a tuned family (None for free impulses).
    omega_d, zeta, vtol : float or None
        The family's design mode (damped rad/s, damping ratio) and EI tolerance.
    reference_omega_d : float
        The identified frequency the design is relative to (a sweep's frequency error scales it).
    """

    name: str
    shaper: Shaper
    objective_pct: float
    family: str | None
    omega_d: float | None
    zeta: float | None
    vtol: float | None
    reference_omega_d: float

    @property
    def duration(self) -> float:
        """The shaper's duration, s."""
        return self.shaper.duration

    def to_dict(self) -> dict[str, Any]:
        """The sweep's custom-shaper entry (``docs/sweeps.md``) plus the objective."""
        out: dict[str, Any] = {"objective_pct": self.objective_pct, "duration_s": self.duration}
        if self.family is not None:
            out.update(family=self.family, omega_d=self.omega_d, zeta=self.zeta)
            if self.vtol is not None:
                out["vtol"] = self.vtol
        else:
            out.update(
                amplitudes=self.shaper.amplitudes.tolist(),
                times=self.shaper.times.tolist(),
                reference_omega_d=self.reference_omega_d,
            )
        return out


def _objective(shaper: Shaper, sample: UncertaintySample, q: float) -> float:
    return float(np.percentile(linear_residual_pct(shaper, sample), q))


def _family_shaper(family: str, omega_d: float, zeta: float, vtol: float | None) -> Shaper:
    omega_n = omega_n_from_damped(omega_d, zeta)
    if vtol is not None:
        return ei(omega_n, zeta, vtol)
    return FAMILIES[family](omega_n, zeta)


def tune_family(
    family: str,
    sample: UncertaintySample,
    reference_omega_d: float,
    zeta: float,
    q: float = 95.0,
    max_duration_s: float | None = None,
    name: str | None = None,
) -> TunedShaper:
    """The family's design frequency (and EI's tolerance) that minimise the percentile residual.

    Parameters
    ----------
    family : str
        A name of :data:`helpers.research.families.FAMILIES`.
    sample : UncertaintySample
        The fixed draws.
    reference_omega_d : float
        The identified damped frequency (rad/s): the search runs over :data:`FREQUENCY_RANGE` times it.
    zeta : float
        The design damping ratio (the identified one).
    q : float
        The percentile.
    max_duration_s : float, optional
        Longest shaper allowed (s): raises the lowest design frequency tried.
    name : str, optional
        Default ``"<family>-tuned"`` in lower case with dashes.

    Returns
    -------
    TunedShaper
    """
    if family not in FAMILIES:
        raise ValueError(f"unknown family {family!r}; choose from {', '.join(FAMILIES)}")
    lo, hi = (f * reference_omega_d for f in FREQUENCY_RANGE)
    if max_duration_s is not None:
        # the duration falls as 1/omega: the lowest frequency allowed makes it exactly max_duration_s
        d_ref = _family_shaper(family, reference_omega_d, zeta, 0.05 if family == "EI" else None).duration
        lo = max(lo, reference_omega_d * d_ref / float(max_duration_s) * (1 + 1e-9))
        if lo >= hi:
            raise ValueError(f"{family} cannot be as short as {max_duration_s} s in the frequency range")
    vtols: Iterable[float | None] = EI_VTOL_GRID if family == "EI" else (None,)
    best: tuple[float, float, float | None] = (math.inf, lo, None)
    for vtol in vtols:

        def f(w: float, vtol: float | None = vtol) -> float:
            return _objective(_family_shaper(family, w, zeta, vtol), sample, q)

        grid = np.linspace(lo, hi, 121)
        values = [f(w) for w in grid]
        i = int(np.argmin(values))
        a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
        res = minimize_scalar(f, bounds=(a, b), method="bounded", options={"xatol": 1e-6 * reference_omega_d})
        w, val = float(grid[i]), float(values[i])
        if res.fun <= val:
            w, val = float(res.x), float(res.fun)
        if val < best[0]:
            best = (val, w, vtol)
    val, w, vtol = best
    shaper = _family_shaper(family, w, zeta, vtol)
    label = name or f"{family.lower().replace(' ', '-')}-tuned"
    shaper = Shaper(shaper.amplitudes, shaper.times, label)
    return TunedShaper(label, shaper, val, family, w, zeta, vtol, reference_omega_d)


# -- free impulses -----------------------------------------------------------------------------------------
class _Free:
    """Unconstrained coordinates of ``n`` positive impulses within a cap, and the sample's residuals."""

    def __init__(self, sample: UncertaintySample, n: int, cap: float) -> None:
        self.n, self.cap = n, cap
        self.sample = sample
        z = sample.zeta
        self.cases = [(sample.omega_n * z, sample.omega_n * np.sqrt(1 - z**2), 1.0 - _share(sample))]
        if sample.omega_n2 is not None:
            z2 = sample.zeta2
            self.cases.append((sample.omega_n2 * z2, sample.omega_n2 * np.sqrt(1 - z2**2), _share(sample)))

    def unpack(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        a = np.exp(x[: self.n] - np.max(x[: self.n]))
        a /= a.sum()
        t = np.concatenate([[0.0], np.cumsum(np.exp(np.clip(x[self.n :], -50, 50)))])
        if t[-1] > self.cap:
            t *= self.cap / t[-1]
        return a, t

    def pack(self, a: np.ndarray, t: np.ndarray) -> np.ndarray:
        a = np.maximum(np.asarray(a, float), 1e-4)
        gaps = np.maximum(np.diff(np.asarray(t, float)), 1e-4 * self.cap)
        return np.concatenate([np.log(a / a.sum()), np.log(gaps)])

    def residuals(self, x: np.ndarray) -> np.ndarray:
        a, t = self.unpack(x)
        total = 0.0
        for sigma, wd, weight in self.cases:
            decay = np.exp(sigma[:, None] * (t - t[-1]))
            c = (a * decay * np.cos(wd[:, None] * t)).sum(axis=1)
            s = (a * decay * np.sin(wd[:, None] * t)).sum(axis=1)
            total = total + weight * np.hypot(c, s)
        return 100.0 * total


def _share(sample: UncertaintySample) -> np.ndarray | float:
    return 0.0 if sample.share2 is None else sample.share2


def _as_n_impulses(shaper: Shaper, n: int, cap: float) -> tuple[np.ndarray, np.ndarray]:
    """A start of exactly ``n`` impulses: the shaper compressed into the cap, split or merged to ``n``."""
    a, t = shaper.amplitudes.copy(), shaper.times.copy()
    if t[-1] > cap:
        t = t * cap / t[-1]
    while a.size < n:  # split the largest impulse in two, a little apart
        k = int(np.argmax(a))
        a = np.insert(a, k + 1, a[k] / 2)
        a[k] /= 2
        t = np.insert(t, k + 1, t[k] + 1e-3 * cap)
    while a.size > n:  # merge the two closest impulses
        k = int(np.argmin(np.diff(t)))
        t[k] = (a[k] * t[k] + a[k + 1] * t[k + 1]) / (a[k] + a[k + 1])
        a[k] += a[k + 1]
        a, t = np.delete(a, k + 1), np.delete(t, k + 1)
    t[0] = 0.0
    return a, np.maximum.accumulate(t)


def optimise_shaper(
    sample: UncertaintySample,
    duration_s: float,
    reference_omega_d: float,
    zeta: float,
    n_impulses: int = 5,
    q: float = 95.0,
    max_iter: int = 3000,
    name: str = "robust",
    extra_starts: Iterable[Shaper] = (),
) -> TunedShaper:
    """``n_impulses`` positive impulses within ``duration_s`` that minimise the percentile residual.

    Parameters
    ----------
    sample : UncertaintySample
        The fixed draws.
    duration_s : float
        The cap on the shaper's duration, s.
    reference_omega_d, zeta : float
        The identified mode: the starting families are designed from it (compressed to the cap).
    n_impulses : int
        Impulses (>= 2).
    q : float
        The percentile.
    max_iter : int
        Nelder-Mead iterations per stage and start.
    name : str
        The result's name.
    extra_starts : iterable of Shaper
        Further starts (compressed to the cap if longer), e.g. the optimum at a shorter cap.

    Returns
    -------
    TunedShaper
        Never worse on the objective than any of its starts.
    """
    if not (math.isfinite(duration_s) and duration_s > 0):
        raise ValueError(f"duration_s must be a positive number of seconds, got {duration_s!r}")
    if isinstance(n_impulses, bool) or not isinstance(n_impulses, int) or n_impulses < 2:
        raise ValueError(f"n_impulses must be an integer >= 2, got {n_impulses!r}")
    free = _Free(sample, n_impulses, float(duration_s))
    omega_n = omega_n_from_damped(reference_omega_d, zeta)
    starts = []
    for fam in ("ZVD", "EI", "2-hump EI", "ZVDD", "MZV"):
        s = FAMILIES[fam](omega_n, zeta)
        starts.append(_as_n_impulses(s, n_impulses, duration_s))
    binomial = np.array([math.comb(n_impulses - 1, k) for k in range(n_impulses)], float)
    starts.append((binomial / binomial.sum(), np.linspace(0.0, duration_s, n_impulses)))
    starts += [_as_n_impulses(s, n_impulses, duration_s) for s in extra_starts]

    def tail_mean(x: np.ndarray) -> float:
        r = free.residuals(x)
        k = max(1, int(round(0.1 * r.size)))
        return float(np.mean(np.sort(r)[-k:]))  # sorted: the same sum order on every CPU

    def pct(x: np.ndarray) -> float:
        return float(np.percentile(free.residuals(x), q))

    best_x, best_f = None, math.inf
    opts = {"maxiter": max_iter, "maxfev": 2 * max_iter, "xatol": 1e-7, "fatol": 1e-7}
    for a, t in starts:
        x0 = free.pack(a, t)
        candidates = [x0]
        r1 = minimize(tail_mean, x0, method="Nelder-Mead", options=opts)
        r2 = minimize(pct, r1.x, method="Nelder-Mead", options=opts)
        candidates += [r1.x, r2.x]
        for x in candidates:
            f = pct(x)
            if f < best_f:
                best_x, best_f = x, f
    a, t = free.unpack(best_x)
    keep = a > 1e-7
    a, t = a[keep] / a[keep].sum(), t[keep]
    t = t - t[0]
    shaper = Shaper(a, t, name)
    return TunedShaper(name, shaper, _objective(shaper, sample, q), None, None, None, None, reference_omega_d)


# -- the design set ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DesignSet:
    """The tuned families and the robust designs, with the model and sample they were judged on.

    Attributes
    ----------
    designs : dict of str to TunedShaper
        By sweep name.
    model : dict
        :meth:`UncertaintyModel.describe`.
    n_draws, seed : int
        The sample.
    q : float
        The percentile.
    notes : dict of str to str
        How each robust design's cap was chosen.
    compared : tuple of str
        The names of the compared (tuned) families.
    equal_duration : dict of str to tuple of str
        For each robust design, the compared families at its duration (:func:`at_duration`).
    """

    designs: dict[str, TunedShaper]
    model: dict[str, Any]
    n_draws: int
    seed: int
    q: float
    notes: dict[str, str] = field(default_factory=dict)
    compared: tuple[str, ...] = ()
    equal_duration: dict[str, tuple[str, ...]] = field(default_factory=dict)

    def table(self) -> pd.DataFrame:
        """One row per design: ``name``, ``family``, ``duration_s``, ``objective_pct``."""
        rows = [
            {"name": k, "family": d.family or "free impulses", "duration_s": d.duration,
             "objective_pct": d.objective_pct}
            for k, d in self.designs.items()
        ]  # fmt: skip
        return pd.DataFrame(rows)


def robust_designs(
    model: UncertaintyModel,
    n_draws: int = 1024,
    seed: int = 0,
    q: float = 95.0,
    n_impulses: int | None = None,
    families: Iterable[str] = COMPARED_FAMILIES,
    extra_families: Iterable[str] = ("ZVDD",),
    max_iter: int = 3000,
) -> DesignSet:
    """Tune the families, then optimise free impulses at the compared families' durations.

    Two robust designs: ``robust``, capped at the duration of the best compared family (the one with the
    lowest objective), and ``robust-short``, capped at the shortest compared family's duration (what
    robustness costs in time). The optimiser may end below its cap, so each compared family is also
    compressed or stretched to each robust design's actual duration (:func:`at_duration`, named
    ``"<family>-at-robust"``, ``"<family>-at-robust-short"``): the comparison at equal duration.
    ``extra_families`` are tuned for reference only (not compared).

    Parameters
    ----------
    model : UncertaintyModel
        The distribution.
    n_draws, seed : int
        The fixed sample (:meth:`UncertaintyModel.sample`).
    q : float
        The percentile.
    n_impulses : int, optional
        Impulses of the robust designs (default :data:`ROBUST_IMPULSES`, or
        :data:`ROBUST_IMPULSES_TWO_MODES` when the map has a second mode).
    families, extra_families : iterable of str
        Families to tune.
    max_iter : int
        Nelder-Mead iterations per stage and start.

    Returns
    -------
    DesignSet
    """
    sample = model.sample(n_draws, seed)
    if n_impulses is None:
        n_impulses = ROBUST_IMPULSES_TWO_MODES if model.mode_map.has_second_mode else ROBUST_IMPULSES
    w_id, z_id = model.identified.omega_d, model.identified.zeta
    designs: dict[str, TunedShaper] = {}
    compared = list(families)
    for fam in [*compared, *extra_families]:
        tuned = tune_family(fam, sample, w_id, z_id, q)
        designs[tuned.name] = tuned
    ranked = [designs[f"{f.lower().replace(' ', '-')}-tuned"] for f in compared]
    best = min(ranked, key=lambda d: d.objective_pct)
    shortest = min(ranked, key=lambda d: d.duration)
    short = optimise_shaper(sample, shortest.duration, w_id, z_id, n_impulses, q, max_iter, "robust-short")
    # the longer cap also starts from the shorter optimum, so it is never worse
    designs["robust"] = optimise_shaper(sample, best.duration, w_id, z_id, n_impulses, q, max_iter, "robust",
                                        extra_starts=[short.shaper])  # fmt: skip
    designs["robust-short"] = short
    notes = {
        "robust": f"capped at the duration of the best compared family ({best.name})",
        "robust-short": f"capped at the duration of the shortest compared family ({shortest.name})",
    }
    equal: dict[str, tuple[str, ...]] = {}
    for robust in ("robust", "robust-short"):
        matched = [at_duration(t, designs[robust].duration, sample, q, robust) for t in ranked]
        designs.update((m.name, m) for m in matched)
        equal[robust] = tuple(m.name for m in matched)
        notes[f"at-{robust}"] = f"the compared families compressed or stretched to {robust}'s duration"
    compared_names = tuple(d.name for d in ranked)
    return DesignSet(designs, model.describe(), n_draws, seed, q, notes, compared_names, equal_duration=equal)


def at_duration(
    tuned: TunedShaper, duration_s: float, sample: UncertaintySample, q: float, label: str
) -> TunedShaper:
    """A tuned family compressed or stretched in time to ``duration_s``.

    The same shape (damping ratio, EI's tolerance), its design frequency scaled by ``tuned.duration /
    duration_s``. The comparison of designs at equal duration: a family's impulse times scale as one over its
    design frequency, so this is the one member of the family (at the tuned shape) that lasts exactly as
    long.

    Parameters
    ----------
    tuned : TunedShaper
        A tuned family (:func:`tune_family`).
    duration_s : float
        The duration to match (s).
    sample : UncertaintySample
        The draws its objective is evaluated on.
    q : float
        The percentile.
    label : str
        The design it is matched to: the result is named ``"<family>-at-<label>"``.

    Returns
    -------
    TunedShaper
    """
    if tuned.family is None or tuned.omega_d is None or tuned.zeta is None:
        raise ValueError(f"{tuned.name} is not a family: nothing to compress or stretch")
    w = tuned.omega_d * tuned.duration / float(duration_s)
    shaper = _family_shaper(tuned.family, w, tuned.zeta, tuned.vtol)
    name = f"{tuned.family.lower().replace(' ', '-')}-at-{label}"
    shaper = Shaper(shaper.amplitudes, shaper.times, name)
    return TunedShaper(
        name, shaper, _objective(shaper, sample, q), tuned.family, w, tuned.zeta, tuned.vtol,
        tuned.reference_omega_d,
    )  # fmt: skip


def save_designs(designs: DesignSet, path: str | os.PathLike) -> Path:
    """Write a design set as JSON (sorted keys, atomically); :func:`load_designs` reads it back."""
    data = {
        "format": DESIGNS_FORMAT,
        "version": 1,
        "model": designs.model,
        "n_draws": designs.n_draws,
        "seed": designs.seed,
        "q": designs.q,
        "notes": designs.notes,
        "compared": list(designs.compared),
        "equal_duration": {k: list(v) for k, v in designs.equal_duration.items()},
        "shapers": {k: d.to_dict() for k, d in designs.designs.items()},
    }
    return write_json(path, data)


def load_designs(path: str | os.PathLike) -> dict[str, dict[str, Any]]:
    """The custom-shaper entries of a design-set file (name -> entry), checked for their format tag."""
    data = read_json(path, "robust shaper designs", "make it with `python -m helpers sweep design`")
    if data.get("format") != DESIGNS_FORMAT or not isinstance(data.get("shapers"), dict):
        raise DataFileError(f"{path}: not a robust shaper design file (format {data.get('format')!r})")
    return data["shapers"]
