"""Rig tuning: choosing the virtual rig's unknown parameters so that it reproduces the paper's numbers.

(Not to be confused with the *load-cell calibration*, :mod:`helpers.loadcell`, or the linear model's *fit*,
:func:`helpers.model.fit_to_mode`.)

The paper states the backbone (A228 wire, d = 0.82 mm, L = 0.24 m, 12 discs) and the stepper, not the disc
mass, the cable offset r, the cable/load-cell stiffness k, the pretension, the mounting orientation or the
damping. They are chosen here, in two layers:

1. *assumed* from the paper's hints (reasons in ``docs/virtual_rig.md`` and on
   :class:`~helpers.virtual.parameters.RigParameters`): r, the base orientation;
2. *tuned* against simulated experiments analysed by the project's own code: the disc mass and the
   damping so that the identification run (100 mm/s, 10 mm, analysed on 9-10 s by
   :func:`helpers.identify.identify`) gives omega_d = 25.085 rad/s and zeta = 0.044; k and the pretension
   so that the unshaped pulse runs of Table I land near the paper's Up peaks and Down overshoots.

The result is stored as literals in :data:`helpers.virtual.parameters.TUNED` (so that nothing slow runs on
import; ``RigParameters()`` is the tuned rig); :func:`tune` re-derives them and notebook 06 shows the check.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pandas as pd

from helpers import paper
from helpers.identify import IdentificationResult, identify
from helpers.metrics import MOTIONS, recording_metrics
from helpers.programmes import experiment_programme
from helpers.shapers import paper_tdfs
from helpers.virtual import ArmPlant, RigParameters, SimResult, linearise, simulate

__all__ = [
    "identification_run",
    "identified_mode",
    "pulse_runs",
    "pulse_table",
    "rayleigh_for",
    "tune",
]


def identification_run(params: RigParameters, seed: int | None = 0, rate_hz: float = 1000.0) -> SimResult:
    """Simulate the paper's identification experiment (100 mm/s, 10 mm, up at 1 s, down at 8 s, 12 s).

    Returns
    -------
    helpers.virtual.SimResult
    """
    prog, _ = experiment_programme(
        paper.IDENTIFICATION_RUN["v_in_mm_s"], paper.IDENTIFICATION_RUN["x_f_mm"]
    )
    return simulate(prog, rate_hz=rate_hz, params=params, seed=seed)


def identified_mode(params: RigParameters, seed: int | None = 0, signal: str = "adc") -> IdentificationResult:
    """Identify the dominant mode of a simulated identification run with :func:`helpers.identify.identify`.

    Parameters
    ----------
    params : RigParameters
        The rig.
    seed : int, optional
        Load-cell noise seed.
    signal : {"adc", "tension"}
        Analyse the ADC counts (as the paper did) or the noise-free tension.

    Returns
    -------
    helpers.identify.IdentificationResult
    """
    if signal not in ("adc", "tension"):
        raise ValueError(f"signal must be 'adc' or 'tension', got {signal!r}")
    run = identification_run(params, seed=seed)
    y = run.adc.astype(float) if signal == "adc" else run.tension
    return identify(run.t, y, window=paper.IDENTIFICATION_RUN["window_s"])


def pulse_runs(params: RigParameters, systems: tuple[str, ...] = ("unshaped",), seed: int | None = 0) -> dict:
    """Simulate the Table I conditions for ``systems`` (``unshaped``, ``zv``, ``zvd``).

    Returns
    -------
    dict
        ``(v_in, x_f, system) -> SimResult``.
    """
    zv, zvd = paper_tdfs()
    shapers: dict[str, Any] = {"unshaped": None, "zv": zv, "zvd": zvd}
    plant = ArmPlant(params)
    out = {}
    for v_in, x_f in paper.TABLE_I_CONDITIONS:
        for system in systems:
            prog, _ = experiment_programme(v_in, x_f, shaper=shapers[system])
            out[(v_in, x_f, system)] = simulate(prog, params=params, seed=seed, plant=plant)
    return out


def pulse_table(runs: dict, signal: str = "tension") -> pd.DataFrame:
    """Table II metrics of simulated runs (:func:`helpers.metrics.recording_metrics`) beside the paper's.

    Parameters
    ----------
    runs : dict
        ``(v_in, x_f, system) -> SimResult`` (:func:`pulse_runs`).
    signal : {"tension", "adc"}
        The noise-free tension, or the ADC counts converted with the load cell's true calibration.

    Returns
    -------
    pandas.DataFrame
        One row per condition, system and motion: ``y0_n``, ``yf_n``, ``peak_n``, ``overshoot_pct``,
        ``settling_ms`` and the paper's ``paper_peak_n``, ``paper_overshoot_pct``, ``paper_settling_ms``.
    """
    ref = paper.table_ii().set_index(["v_in_mm_s", "x_f_mm", "system", "motion"])
    rows = []
    for (v_in, x_f, system), run in runs.items():
        metrics = recording_metrics(run.frame(signal)).set_index("motion")
        for motion in MOTIONS:
            m = metrics.loc[motion]
            p = ref.loc[(float(v_in), float(x_f), system, motion)]
            rows.append(
                {
                    "v_in_mm_s": v_in,
                    "x_f_mm": x_f,
                    "system": system,
                    "motion": motion,
                    "y0_n": m["y0_n"],
                    "yf_n": m["yf_n"],
                    "peak_n": m["peak_n"],
                    "overshoot_pct": m["overshoot_pct"],
                    "settling_ms": m["settling_ms"],
                    "paper_peak_n": p["peak_n"],
                    "paper_overshoot_pct": p["overshoot_pct"],
                    "paper_settling_ms": p["settling_ms"],
                }
            )
    return pd.DataFrame(rows)


def rayleigh_for(params: RigParameters, zeta: float) -> RigParameters:
    """Rayleigh coefficients giving damping ratio ``zeta`` to the two lowest oscillatory modes at rest.

    As the paper does for its modal model (eqs. 8-10): ``alpha = 2 zeta w1 w2 / (w1 + w2)``,
    ``beta = 2 zeta / (w1 + w2)`` with w1, w2 the two lowest undamped frequencies of the rig linearised about
    its rest state (the cable makes the damping non-proportional, so the realised ratios differ slightly;
    :func:`tune` corrects ``zeta`` against the identification).
    """
    if not (math.isfinite(zeta) and 0 <= zeta < 1):
        raise ValueError(f"zeta must be in [0, 1), got {zeta!r}")
    lin = linearise(params.replace(alpha=0.0, beta=0.0), 0.0)
    w = np.sort(np.abs(lin.poles[lin.poles.imag > 1e-9]))
    w1, w2 = float(w[0]), float(w[1])
    return params.replace(alpha=2 * zeta * w1 * w2 / (w1 + w2), beta=2 * zeta / (w1 + w2))


def tune(
    base: RigParameters | None = None,
    omega_d: float = paper.OMEGA_D,
    zeta: float = paper.ZETA,
    n_iter: int = 6,
    verbose: bool = False,
) -> tuple[RigParameters, pd.DataFrame]:
    """Re-derive the disc mass and the damping from simulated identification runs (the rig tuning).

    Holds ``r``, ``k``, the pretension and the orientation of ``base`` fixed and iterates: disc mass by a
    secant step on ``log omega_d`` against ``log disc_mass`` (omega ~ m^-1/2), damping by scaling the Rayleigh
    target ``zeta`` with the ratio of target to identified damping. Each iteration is one 12 s simulation.

    Returns
    -------
    (RigParameters, pandas.DataFrame)
        The tuned parameters and the iteration history.
    """
    base = RigParameters() if base is None else base
    z_target = zeta
    p = rayleigh_for(base, z_target)
    history = []
    for it in range(n_iter):
        res = identified_mode(p)
        history.append(
            {"iteration": it, "disc_mass_g": p.disc_mass * 1e3, "alpha": p.alpha, "beta": p.beta,
             "omega_d": res.omega_d, "zeta": res.zeta}
        )  # fmt: skip
        if verbose:
            print(history[-1])
        if abs(res.omega_d / omega_d - 1) < 1e-3 and abs(res.zeta / zeta - 1) < 0.02:
            break
        # omega^2 ~ 1/(m_discs + m_eff): scale the disc mass by the discs' share of the inertia
        share = p.n_discs * p.disc_mass / (p.n_discs * p.disc_mass + p.rod_mass / 3)
        mass = p.disc_mass * (1 + ((res.omega_d / omega_d) ** 2 - 1) / share)
        z_target *= zeta / res.zeta
        p = rayleigh_for(dataclasses.replace(p, disc_mass=mass), z_target)
    return p, pd.DataFrame(history)
