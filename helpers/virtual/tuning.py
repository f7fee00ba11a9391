"""Rig tuning: choosing the virtual rig's unknown parameters so that it reproduces the paper's numbers.

(Not to be confused with the *load-cell calibration*, :mod:`helpers.paper.calibration`, or the linear model's
*fit*,
:func:`helpers.research.model_fit.fit_to_mode`.)

The paper states the backbone, the spool, the step count and the motor, not the disc mass, the cable offset
``r``, the series stiffness ``k`` of the cable path, the pretension or the damping. They are chosen here in
two layers, and only on data the paper's shaped rows do not enter:

1. *the identified mode*: for any candidate, the disc mass and the damping level (``alpha`` and
   ``beta_chord`` in the paper's Rayleigh ratio through modes 1 and 2) are solved so that the rig as it runs
   (rotor free on its microstep spring), linearised at rest, has its lowest mode at omega_d = 25.085 rad/s
   with zeta = 0.044 (:func:`calibrate_mode`). The simulated identification run (100 mm/s, 10 mm; ADC counts
   on 9-10 s through :func:`helpers.paper.identify.identify`, the code notebook 02 uses) checks this in the
   time
   domain (:func:`identified_mode`);
2. *the unshaped rows of Table II*: ``r``, ``k`` and the pretension minimise :func:`objective`, the mean
   square of the relative Up-peak errors and of the Up and Down overshoot errors (in units of 100 points) of
   the four unshaped conditions (:func:`tune`, a Nelder-Mead search in log coordinates, each candidate
   re-calibrated by step 1). The settling times are left out: the viscous damping fixed by the identified
   zeta cannot reach them (``docs/virtual_rig.md``), and fitting them would spoil the identified mode.

The 16 shaped rows are never used: they are the held-out predictions of notebook 05. The result is stored as
literals in :data:`helpers.virtual.parameters.TUNED` (so nothing slow runs on import; ``RigParameters()`` is
the tuned rig); ``python -m helpers virtual-rig tune`` (:mod:`helpers.virtual.studies`) re-derives them and
notebook 06 shows the check.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd
from scipy import linalg, optimize

from helpers.board.programmes import experiment_programme
from helpers.paper import numbers as paper
from helpers.paper.identify import IdentificationResult, identify
from helpers.paper.metrics import MOTIONS, recording_metrics
from helpers.paper.shapers import design_tdfs
from helpers.virtual import ArcChain, ArmPlant, RigParameters, SimResult, linearise, simulate
from helpers.virtual.statics import model_arrays, stable_max_step

__all__ = [
    "identification_run",
    "identified_mode",
    "pulse_runs",
    "pulse_table",
    "rayleigh_pair",
    "LAYOUTS",
    "layout_damping",
    "lowest_mode",
    "calibrate_mode",
    "objective",
    "tune",
    "TUNED_KEYS",
]

TUNED_KEYS = ("r", "k", "pretension")
"""The unknowns tuned on the unshaped rows of Table II."""


def identification_run(params: RigParameters, seed: int | None = 0, rate_hz: float = 1000.0) -> SimResult:
    """Simulate the paper's identification experiment (100 mm/s, 10 mm, up at 1 s, down at 8 s, 12 s)."""
    prog, _ = experiment_programme(paper.IDENTIFICATION_RUN["v_in_mm_s"], paper.IDENTIFICATION_RUN["x_f_mm"])
    return simulate(prog, rate_hz=rate_hz, params=params, seed=seed)


def identified_mode(params: RigParameters, seed: int | None = 0, signal: str = "adc") -> IdentificationResult:
    """Identify the dominant mode of a simulated identification run with :func:`~identify.identify`.

    Parameters
    ----------
    params : RigParameters
        The rig.
    seed : int, optional
        Load-cell noise seed.
    signal : {"adc", "output"}
        Analyse the ADC counts (as the paper did) or the amplifier's noise-free output.
    """
    if signal not in ("adc", "output"):
        raise ValueError(f"signal must be 'adc' or 'output', got {signal!r}")
    run = identification_run(params, seed=seed)
    y = run.adc.astype(float) if signal == "adc" else run.output
    return identify(run.t, y, window=paper.IDENTIFICATION_RUN["window_s"])


def pulse_runs(
    params: RigParameters, systems: tuple[str, ...] = ("unshaped",), seed: int | None = 0,
    conditions: tuple[tuple[float, float], ...] = paper.TABLE_I_CONDITIONS,
) -> dict[tuple[float, float, str], SimResult]:  # fmt: skip
    """Simulate Table I conditions for ``systems`` (``unshaped``, ``zv``, ``zvd``; the paper's shapers).

    Returns
    -------
    dict
        ``(v_in, x_f, system) -> SimResult``.
    """
    zv, zvd = design_tdfs()
    shapers: dict[str, Any] = {"unshaped": None, "zv": zv, "zvd": zvd}
    plant = ArmPlant(params)
    out = {}
    for v_in, x_f in conditions:
        for system in systems:
            prog, _ = experiment_programme(v_in, x_f, shaper=shapers[system])
            out[(v_in, x_f, system)] = simulate(prog, params=params, seed=seed, plant=plant)
    return out


def pulse_table(runs: dict, signal: str = "output") -> pd.DataFrame:
    """Table II metrics of simulated runs (:func:`~metrics.recording_metrics`) beside the paper's.

    Parameters
    ----------
    runs : dict
        ``(v_in, x_f, system) -> SimResult`` (:func:`pulse_runs`).
    signal : {"output", "tension", "adc"}
        The amplifier's noise-free output, the true tension, or the ADC counts converted with the load cell's
        true calibration.

    Returns
    -------
    pandas.DataFrame
        One row per condition, system and motion: ``y0_n``, ``yf_n``, ``peak_n``, ``overshoot_pct``,
        ``settling_ms``, ``peak_is_bound``, ``max_rotor_lag_steps`` and the paper's ``paper_peak_n``,
        ``paper_overshoot_pct``, ``paper_settling_ms``.
    """
    ref = paper.table_ii().set_index(["v_in_mm_s", "x_f_mm", "system", "motion"])
    rows = []
    for (v_in, x_f, system), run in runs.items():
        metrics = recording_metrics(run.frame(signal)).set_index("motion")
        for motion in MOTIONS:
            m = metrics.loc[motion]
            p = ref.loc[(float(v_in), float(x_f), system, motion)]
            rows.append({
                "v_in_mm_s": v_in, "x_f_mm": x_f, "system": system, "motion": motion,
                "y0_n": m["y0_n"], "yf_n": m["yf_n"], "peak_n": m["peak_n"],
                "overshoot_pct": m["overshoot_pct"], "settling_ms": m["settling_ms"],
                "peak_is_bound": bool(m["peak_is_bound"]), "max_rotor_lag_steps": run.max_rotor_lag_steps,
                "paper_peak_n": p["peak_n"], "paper_overshoot_pct": p["overshoot_pct"],
                "paper_settling_ms": p["settling_ms"],
            })  # fmt: skip
    return pd.DataFrame(rows)


# --- layer 1: the identified mode -------------------------------------------------------------------------
LAYOUTS: dict[str, str] = {
    "chord+floor": "air drag (alpha M) + dashpots between disc chords + high-mode floor (the rig)",
    "chord": "air drag + dashpots between disc chords, no high-mode floor",
    "rayleigh-discs": "air drag + stiffness-proportional dashpots between consecutive discs (previous rig)",
    "mass": "air drag alone (mass-proportional) + high-mode floor",
    "stiffness-discs": "dashpots between consecutive discs alone (stiffness-proportional) + high-mode floor",
}
"""Damping layouts: each is calibrated to the identified mode by :func:`calibrate_mode` (notebook 06)."""


def layout_damping(params: RigParameters, layout: str, zeta: float) -> RigParameters:
    """``params`` with the damping fields of ``layout`` at damping level ``zeta`` (see :data:`LAYOUTS`)."""
    if layout not in LAYOUTS:
        raise ValueError(f"unknown damping layout {layout!r}; choose from {list(LAYOUTS)}")
    a, b = rayleigh_pair(params, zeta)
    floor = 0.0 if layout in ("chord", "rayleigh-discs") else RigParameters().floor_zeta
    zero = {"alpha": 0.0, "beta_chord": 0.0, "beta_disc": 0.0, "floor_zeta": floor}
    w_1, _ = _two_lowest(params)
    if layout in ("chord+floor", "chord"):
        return params.replace(**{**zero, "alpha": a, "beta_chord": b})
    if layout == "rayleigh-discs":
        return params.replace(**{**zero, "alpha": a, "beta_disc": b})
    if layout == "mass":
        return params.replace(**{**zero, "alpha": 2 * zeta * w_1})
    return params.replace(**{**zero, "beta_disc": 2 * zeta / w_1})


def _two_lowest(params: RigParameters) -> tuple[float, float]:
    chain = ArcChain(params)
    q = model_arrays(params).q_rest
    kap, g = chain.cable_tangent(q, params.pretension, params.k)
    K = chain.hessian(q, lam=params.pretension) + kap * np.outer(g, g)
    w = np.sqrt(np.abs(linalg.eigh(K, chain.mass_matrix(q), eigvals_only=True)))
    return float(w[0]), float(w[1])


def rayleigh_pair(params: RigParameters, zeta: float) -> tuple[float, float]:
    """``(alpha, beta_chord)`` of the paper's Rayleigh rule (eqs. 8-10) for damping ratio ``zeta``.

    ``alpha = 2 zeta w1 w2 / (w1 + w2)``, ``beta = 2 zeta / (w1 + w2)``, with ``w1, w2`` the two lowest
    undamped frequencies of the arm at rest with the cable as a spring of the series stiffness ``k``. The
    chord dashpots are not exactly stiffness-proportional and the rotor adds its own coupling, so the realised
    ratio differs a little; :func:`calibrate_mode` scales ``zeta`` to hit the target.
    """
    if not (math.isfinite(zeta) and 0 <= zeta < 1):
        raise ValueError(f"zeta must be in [0, 1), got {zeta!r}")
    w1, w2 = _two_lowest(params)
    return 2 * zeta * w1 * w2 / (w1 + w2), 2 * zeta / (w1 + w2)


def lowest_mode(params: RigParameters) -> tuple[float, float]:
    """``(omega_d, zeta)`` of the lowest mode of the rig as it runs (rotor free), linearised at rest."""
    m = linearise(params, 0.0, rotor="free").modes()
    return float(m.omega_d.iloc[0]), float(m.zeta.iloc[0])


def calibrate_mode(
    params: RigParameters,
    omega_d: float = paper.OMEGA_D,
    zeta: float = paper.ZETA,
    layout: str = "chord+floor",
    n_iter: int = 12,
) -> RigParameters:
    """Disc mass and damping level giving the lowest mode at rest ``(omega_d, zeta)`` (rotor free).

    A secant-like update of the disc mass (``omega^2 ~ 1 / (discs + a third of the wire)``) and a scaling of
    the damping level of ``layout`` (:data:`LAYOUTS`) on the realised ``zeta``, until both agree to 1e-7.
    """
    p = params
    z_target = zeta
    for _ in range(n_iter):
        p = layout_damping(p, layout, z_target)
        wd, z = lowest_mode(p)
        if abs(wd / omega_d - 1) < 1e-7 and abs(z / zeta - 1) < 1e-7:
            return p
        share = p.n_discs * p.disc_mass / (p.n_discs * p.disc_mass + p.rod_mass / 3)
        p = p.replace(disc_mass=p.disc_mass * (1 + ((wd / omega_d) ** 2 - 1) / share))
        z_target *= zeta / z
    raise RuntimeError(f"the mode calibration did not converge: omega_d {wd:.5f}, zeta {z:.5f}")


# --- layer 2: the unshaped rows of Table II ---------------------------------------------------------------
def objective(table: pd.DataFrame) -> float:
    """The tuning's objective on the unshaped rows of a :func:`pulse_table`.

    Mean of the squares of: the relative error of each Up peak, and the error of each Up and Down overshoot in
    units of 100 percentage points (12 terms for the four conditions). The Down peaks (0 N in the paper: a
    slack cable) and the settling times are not used.
    """
    un = table[table.system == "unshaped"]
    up = un[un.motion == "Up"]
    terms = list((up.peak_n / up.paper_peak_n - 1).to_numpy())
    terms += list(((un.overshoot_pct - un.paper_overshoot_pct) / 100.0).to_numpy())
    terms = np.asarray(terms, dtype=float)
    if not np.all(np.isfinite(terms)):
        return math.inf
    return float(np.mean(terms**2))


def evaluate(params: RigParameters, layout: str = "chord+floor") -> tuple[float, pd.DataFrame, RigParameters]:
    """Calibrate ``params`` to the mode, choose its step and run the four unshaped conditions.

    The step is :func:`~helpers.virtual.statics.stable_max_step`. Returns ``(objective, table, params)``.
    """
    p = calibrate_mode(params, layout=layout)
    p = p.replace(max_step=stable_max_step(p))
    table = pulse_table(pulse_runs(p))
    return objective(table), table, p


def tune(
    start: RigParameters | None = None,
    max_evaluations: int = 80,
    verbose: bool = False,
    layout: str = "chord+floor",
) -> tuple[RigParameters, pd.DataFrame]:
    """Search ``r``, ``k`` and the pretension on the unshaped rows of Table II (see the module docstring).

    Nelder-Mead on ``log r``, ``log k``, ``log pretension``, starting from ``start`` (default the tuned
    rig); every candidate is re-calibrated to the identified mode first, with the damping ``layout``. Each
    evaluation is four 12 s simulations and a few linearisations (about 1-2 s).

    Returns
    -------
    (RigParameters, pandas.DataFrame)
        The best parameters and the history (one row per evaluation).
    """
    start = RigParameters() if start is None else start
    x0 = np.log([start.r, start.k, start.pretension])
    history: list[dict[str, float]] = []
    best: dict[str, Any] = {"f": math.inf, "params": start}

    def f(x: np.ndarray) -> float:
        r, k, pre = np.exp(x)
        try:
            value, _, p = evaluate(start.replace(r=float(r), k=float(k), pretension=float(pre)), layout)
        except (ValueError, RuntimeError, FloatingPointError):
            value, p = math.inf, None
        history.append({"r_mm": r * 1e3, "k_n_m": k, "pretension_n": pre, "objective": value})
        if verbose:
            print(
                f"r {r * 1e3:.3f} mm  k {k:.0f} N/m  pretension {pre:.3f} N  objective {value:.5f}",
                flush=True,
            )
        if value < best["f"]:
            best.update(f=value, params=p)
        return value

    simplex = x0 + np.vstack([np.zeros(3), np.diag([0.06, 0.15, 0.12])])
    options = {"maxfev": max_evaluations, "xatol": 2e-3, "fatol": 1e-5, "initial_simplex": simplex}
    optimize.minimize(f, x0, method="Nelder-Mead", options=options)
    return best["params"], pd.DataFrame(history)


def tuned_literals(params: RigParameters) -> str:
    """The :data:`helpers.virtual.parameters.TUNED` literals for ``params`` (to paste into parameters.py)."""
    keys = ("disc_mass", "r", "k", "pretension", "alpha", "beta_chord")
    fmt = {"disc_mass": "{:.6e}", "r": "{:.5e}", "k": "{:.1f}", "pretension": "{:.4f}", "alpha": "{:.6f}",
           "beta_chord": "{:.6e}"}  # fmt: skip
    return "\n".join(f'    "{k}": {fmt[k].format(getattr(params, k))},' for k in keys)
