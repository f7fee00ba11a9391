"""Evidence for the virtual rig's modelling choices: damping layouts, eyelet friction, actuator and sensor.

Each study simulates the rig (:mod:`helpers.virtual`) under alternatives and measures what the paper's
analysis would see (:mod:`helpers.paper.identify`, :mod:`helpers.paper.metrics`). They take from seconds to a
minute,
so notebook 06 reads their results from CSV files that ``python -m helpers virtual-rig studies`` writes into
``figures/`` (:func:`write_studies`); the numbers are simulated, never measured.

- :func:`damping_layouts`: each layout of :data:`helpers.virtual.tuning.LAYOUTS` calibrated to the identified
  mode, then its modes at rest, the identification run through ``helpers.paper.identify``, the unshaped rows
  of
  Table II (the tuning objective) and, shown but never used to choose, the ZV-shaped 200 mm/s 20 mm run.
- :func:`eyelet_friction`: capstan friction in the guide and the eyelets, with the viscous damping re-scaled
  so that the identification window still gives zeta = 0.044: does it shorten the unshaped settling?
- :func:`actuator_effects`: ideal actuator against stepper and stepper + carriage, and the amplifier: the
  tension right after one step, the ripple during a ramp, per-sample differences, Table II peaks.
- :func:`rotor_lag`: the rotor's largest lag behind its commanded angle in every Table I run (health).
- :func:`actuator_sensitivity`: every Table I scenario with the motor's torque at the paper's 4.3 kg cm and
  at 0.8x, 1.0x and 1.5x the assumed value, a 100 g carriage and a 3x stiffer cable (nothing re-tuned): the
  steps lost, the rotor's lag and how far each Table II row moves; :func:`sensitivity_summary` condenses it.
- the ``virtual-rig`` command (``check``, ``tune``, ``studies``, and ``frequency-map``: the spatial twin's
  modes over bend direction and magnitude, :func:`helpers.virtual.spatial.direction_map.frequency_map`).
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd

from helpers import rigfile
from helpers.base.paths import DATA_DIR, STORED_TABLES_DIR
from helpers.board.programmes import experiment_programme
from helpers.paper import numbers as paper
from helpers.paper.identify import identify
from helpers.paper.metrics import recording_metrics
from helpers.paper.shapers import design_tdfs
from helpers.virtual import (
    ArmPlant,
    RigParameters,
    SimResult,
    frequency_map,
    linearise,
    rig_file_tuning,
    simulate,
)
from helpers.virtual.parameters import KG_CM
from helpers.virtual.sorosim import run_command as sorosim_command
from helpers.virtual.spatial.direction_map import frequency_map as spatial_frequency_map
from helpers.virtual.spatial.direction_map import frequency_map_csv
from helpers.virtual.spatial.from_rig import spatial_rig
from helpers.virtual.spatial.rig import PRESETS, preset
from helpers.virtual.statics import stable_max_step
from helpers.virtual.tuning import (
    LAYOUTS,
    calibrate_mode,
    identification_run,
    objective,
    pulse_runs,
    pulse_table,
    tune,
    tuned_literals,
)

__all__ = [
    "damping_layouts",
    "eyelet_friction",
    "actuator_effects",
    "rotor_lag",
    "actuator_sensitivity",
    "sensitivity_summary",
    "SENSITIVITY_VARIANTS",
    "spatial_map",
    "pulse_study",
    "write_studies",
    "STUDY_FILES",
    "reference_parameters",
    "RETUNED",
]

def reference_parameters() -> RigParameters:
    """The tuned rig integrated by RK4 at its step, the reference every study here runs on by default.

    The studies compare physical alternatives (damping layouts, friction, the actuator, the motor): on the
    reference integrator the implicit step's own error (its convergence band, ``docs/virtual_rig.md``, section
    2) does not mix into those comparisons, and a layout whose damping is large on the stiff modes (which the
    implicit step keeps explicit) stays stable. The recordings in ``data/`` are made with the default, the
    implicit step.
    """
    return RigParameters().with_integrator("rk4")


STUDY_FILES = {
    "layouts": "virtual_damping_layouts.csv",
    "friction": "virtual_eyelet_friction.csv",
    "actuator": "virtual_actuator_effects.csv",
    "lag": "virtual_rotor_lag.csv",
    "sensitivity": "virtual_actuator_sensitivity.csv",
    "convergence": "virtual_convergence.csv",
    "spatial": "virtual_spatial_map.csv",
    "pulses": "virtual_pulse_table.csv",
}
"""Study name -> the CSV in ``figures/`` that :func:`write_studies` writes and notebook 06 reads."""

RETUNED: dict[str, dict[str, float]] = {
    "mass": {"r": 7.943e-3, "k": 18629.0, "pretension": 2.534},
}
"""Layouts whose tuned unknowns were searched again (``rig_tuning.tune(layout=...)``, started from the
previous values: objective 0.0369 for ``mass`` against 0.0590 for the rig's layout); :func:`damping_layouts`
adds a re-tuned row for each."""


def _identified(params: RigParameters) -> tuple[float, float]:
    run = identification_run(params)
    res = identify(run.t, run.adc.astype(float), window=paper.IDENTIFICATION_RUN["window_s"])
    return float(res.omega_d), float(res.zeta)


def _second_mode_fraction(params: RigParameters) -> float:
    """The strongest spectral peak above 60 rad/s in the identification window, relative to the one below.

    The window is 9-10 s of the amplifier's noise-free output (mean removed, Hann, zero-padded 16x).
    """
    run = identification_run(params)
    sel = (run.t >= 9.0) & (run.t <= 10.0)
    y = run.output[sel] - np.mean(run.output[sel])
    n = 16 * y.size
    w = 2 * np.pi * np.fft.rfftfreq(n, float(np.median(np.diff(run.t))))
    spec = np.abs(np.fft.rfft(y * np.hanning(y.size), n))
    low, high = (w > 10) & (w < 60), (w >= 60) & (w < 1000)
    return float(spec[high].max() / spec[low].max())


def _metrics(run: SimResult, motion: str) -> pd.Series:
    return recording_metrics(run.frame("output")).set_index("motion").loc[motion]


def damping_layouts(params: RigParameters | None = None) -> pd.DataFrame:
    """Every damping layout calibrated to the identified mode, and what it does to the data.

    Every layout first with the rig's tuned ``r``, ``k`` and pretension, then the layouts of :data:`RETUNED`
    with their own (a fairer comparison on the unshaped rows, which those three were tuned on).

    Returns
    -------
    pandas.DataFrame
        Per layout: ``mode2_omega_d``, ``mode2_zeta``, ``mode3_zeta`` (rest, rotor free),
        ``dominant_40mm_omega_d`` (the tension-dominant mode at 40 mm), ``max_step_ms`` (the stable step),
        ``ident_omega_d``, ``ident_zeta`` (identification run through helpers.paper.identify),
        ``ident_mode2_fraction`` (strongest peak above 60 rad/s in the identification window's spectrum,
        relative to the dominant one), ``unshaped_objective`` (the tuning objective on the four unshaped
        conditions), ``unshaped_settling_ratio`` (mean of simulated / paper settling over the eight unshaped
        rows), the unshaped 200/20 ``up_peak_n``, ``up_overshoot_pct``, ``up_settling_ms``,
        ``down_settling_ms``, and the ZV-shaped 200/20 ``zv_up_overshoot_pct``, ``zv_up_settling_ms`` (shown,
        not used to choose).
    """
    params = reference_parameters() if params is None else params
    zv, _ = design_tdfs()
    prog_zv, _ = experiment_programme(200.0, 20.0, shaper=zv)
    cases = [(layout, layout, description, params) for layout, description in LAYOUTS.items()]
    cases += [
        (
            f"{layout} (re-tuned)",
            layout,
            LAYOUTS[layout] + "; r, k, pretension re-tuned",
            params.replace(**changes),
        )
        for layout, changes in RETUNED.items()
    ]
    rows = []
    for name, layout, description, base in cases:
        p = calibrate_mode(base, layout=layout)
        p = p.replace(max_step=stable_max_step(p))
        modes = linearise(p, 0.0, rotor="free").modes()
        dom40 = linearise(p, 0.040, rotor="free")
        ident = _identified(p)
        table = pulse_table(pulse_runs(p))
        row20 = table[(table.v_in_mm_s == 200.0) & (table.x_f_mm == 20.0)].set_index("motion")
        zv_up = _metrics(simulate(prog_zv, params=p), "Up")
        rows.append({
            "layout": name, "description": description, "disc_mass_g": p.disc_mass * 1e3,
            "r_mm": p.r * 1e3, "k_n_m": p.k, "pretension_n": p.pretension,
            "alpha": p.alpha, "beta_chord": p.beta_chord, "beta_disc": p.beta_disc,
            "floor_zeta": p.floor_zeta, "mode2_omega_d": modes.omega_d.iloc[1],
            "mode2_zeta": modes.zeta.iloc[1],
            "mode3_zeta": modes.zeta.iloc[2], "dominant_40mm_omega_d": dom40.omega_d,
            "max_step_ms": p.max_step * 1e3, "ident_omega_d": ident[0], "ident_zeta": ident[1],
            "ident_mode2_fraction": _second_mode_fraction(p), "unshaped_objective": objective(table),
            "unshaped_settling_ratio": float(np.mean(table.settling_ms / table.paper_settling_ms)),
            "up_peak_n": row20.loc["Up", "peak_n"], "up_overshoot_pct": row20.loc["Up", "overshoot_pct"],
            "up_settling_ms": row20.loc["Up", "settling_ms"],
            "down_settling_ms": row20.loc["Down", "settling_ms"],
            "zv_up_overshoot_pct": zv_up["overshoot_pct"], "zv_up_settling_ms": zv_up["settling_ms"],
        })  # fmt: skip
    return pd.DataFrame(rows)


def _viscous_scaled(params: RigParameters, scale: float) -> RigParameters:
    return params.replace(alpha=params.alpha * scale, beta_chord=params.beta_chord * scale)


def eyelet_friction(
    params: RigParameters | None = None, mus: tuple[float, ...] = (0.0, 0.02, 0.05, 0.1), v0: float = 1e-3
) -> pd.DataFrame:
    """Capstan friction in the eyelets: identified zeta kept at 0.044, settling of the unshaped 200/20 run.

    For each ``mu`` the viscous damping (``alpha`` and ``beta_chord`` together) is scaled by a secant
    search until the identification run's damped-sine fit on 9-10 s gives zeta = 0.044 again (at most five
    runs); ``mu = 0`` is the rig. Friction is regularised with ``tanh(v / v0)``, which is stiff: every run of
    this study (``mu = 0`` included, for a like-with-like comparison) steps at 25 us. At the rig's 0.25 ms the
    friction law is integrated wrongly and the final tensions drift by newtons; 50 us and 25 us agree to
    0.2 N in the peak and 0.03 N in the final tension.

    Friction is added only if it makes the rig better at predicting what it was not tuned on: so the study
    also runs every Table I scenario (the shaped ones with the paper's shapers) and reports mean absolute
    errors against the paper: the unshaped settling times (not fitted by the tuning) and the 16 shaped rows.

    Returns
    -------
    pandas.DataFrame
        ``mu``, ``viscous_scale``, ``ident_omega_d``, ``ident_zeta``; for the unshaped 200 mm/s 20 mm run
        ``up_peak_n``, ``up_final_n``, ``up_overshoot_pct``, ``up_settling_ms``, ``down_settling_ms``; and
        ``unshaped_settling_mae_ms``, ``shaped_peak_mae_n``, ``shaped_overshoot_mae_pp``,
        ``shaped_settling_mae_ms`` over Table I.
    """
    params = reference_parameters() if params is None else params
    h = 2.5e-5
    prog, _ = experiment_programme(200.0, 20.0)
    rows = []
    for mu in mus:
        base = params.replace(eyelet_mu=mu, eyelet_v0=v0, max_step=h)
        scales, zetas = [1.0], []
        for it in range(5):
            wd, z = _identified(_viscous_scaled(base, scales[-1]))
            zetas.append(z)
            if mu == 0.0 or abs(z / paper.ZETA - 1) < 0.01:
                break
            if it == 0:
                nxt = scales[-1] * paper.ZETA / z if z > 0 else 0.5
            else:
                slope = (zetas[-1] - zetas[-2]) / (scales[-1] - scales[-2])
                nxt = scales[-1] + (paper.ZETA - zetas[-1]) / slope if slope != 0 else scales[-1]
            scales.append(float(np.clip(nxt, 0.0, 2.0)))
        p = _viscous_scaled(base, scales[len(zetas) - 1])
        run = simulate(prog, params=p)
        up, down = _metrics(run, "Up"), _metrics(run, "Down")
        table = pulse_table(pulse_runs(p, systems=paper.SYSTEMS))
        un, sh = table[table.system == "unshaped"], table[table.system != "unshaped"]
        rows.append({
            "mu": mu, "viscous_scale": scales[len(zetas) - 1], "ident_omega_d": wd, "ident_zeta": zetas[-1],
            "up_peak_n": up["peak_n"], "up_final_n": up["yf_n"], "up_overshoot_pct": up["overshoot_pct"],
            "up_settling_ms": up["settling_ms"], "down_settling_ms": down["settling_ms"],
            "unshaped_settling_mae_ms": float((un.settling_ms - un.paper_settling_ms).abs().mean()),
            "shaped_peak_mae_n": float((sh.peak_n - sh.paper_peak_n).abs().mean()),
            "shaped_overshoot_mae_pp": float((sh.overshoot_pct - sh.paper_overshoot_pct).abs().mean()),
            "shaped_settling_mae_ms": float((sh.settling_ms - sh.paper_settling_ms).abs().mean()),
        })  # fmt: skip
    return pd.DataFrame(rows)


def _one_step(params: RigParameters) -> np.ndarray:
    """True tension at the 1 kHz samples after one pull step at 2.0005 s, less the last sample before it."""
    plant = ArmPlant(params)
    before = plant.advance(np.arange(1, 2001) / 1000.0, raw=True)[-1]
    after = plant.advance(2.0 + np.arange(1, 11) / 1000.0, [2.0005], [1.0], raw=True)
    return after - before


def actuator_effects(params: RigParameters | None = None) -> pd.DataFrame:
    """What the stepper, the carriage and the amplifier change in the recordings.

    Each actuator model (``ideal``, ``stepper``, ``stepper+carriage``) is calibrated to the identified mode.
    Measured on the true tension of the measured cable unless a column says ``output`` (the amplifier's).

    Returns
    -------
    pandas.DataFrame
        Per actuator: ``step_dT_1ms`` .. ``step_dT_6ms`` (tension change at the samples after one pull step
        at rest), ``step_peak_n`` (their largest), ``ramp_ripple_n`` (largest |signal - 5-sample mean| during
        the 200 mm/s ramp), ``max_sample_diff_vs_ideal_n`` and ``rms_diff_vs_ideal_n`` over the unshaped
        200/20 run, its ``up_peak_n`` and ``up_overshoot_pct`` (amplifier output), ``amp_max_diff_n`` (largest
        |output - true tension|) and ``max_rotor_lag_steps``.
    """
    params = reference_parameters() if params is None else params
    prog, _ = experiment_programme(200.0, 20.0)
    rows = []
    ideal_raw = None
    for actuator in ("ideal", "stepper", "stepper+carriage"):
        p = calibrate_mode(params.replace(actuator=actuator))
        p = p.replace(max_step=stable_max_step(p))
        d = _one_step(p)
        run = simulate(prog, params=p)
        raw = run.tension
        ideal_raw = raw if ideal_raw is None else ideal_raw
        smooth = np.convolve(raw, np.ones(5) / 5, mode="same")
        ramp = (run.t > 1.005) & (run.t < 1.095)
        up = _metrics(run, "Up")
        row = {"actuator": actuator, "disc_mass_g": p.disc_mass * 1e3, "max_step_ms": p.max_step * 1e3}
        row.update({f"step_dT_{i + 1}ms": float(d[i]) for i in range(6)})
        row.update({
            "step_peak_n": float(np.max(d)), "ramp_ripple_n": float(np.max(np.abs(raw - smooth)[ramp])),
            "max_sample_diff_vs_ideal_n": float(np.max(np.abs(raw - ideal_raw))),
            "rms_diff_vs_ideal_n": float(np.sqrt(np.mean((raw - ideal_raw) ** 2))),
            "up_peak_n": float(up["peak_n"]), "up_overshoot_pct": float(up["overshoot_pct"]),
            "amp_max_diff_n": float(np.max(np.abs(run.output - raw))),
            "max_rotor_lag_steps": run.max_rotor_lag_steps,
        })  # fmt: skip
        rows.append(row)
    return pd.DataFrame(rows)


def rotor_lag(params: RigParameters | None = None) -> pd.DataFrame:
    """The rotor's largest lag (microsteps) in every Table I run, and whether it returned to rest.

    Returns
    -------
    pandas.DataFrame
        ``v_in_mm_s``, ``x_f_mm``, ``system``, ``max_rotor_lag_steps``, ``torque_peak_lag_steps`` (a quarter
        of a tooth pitch: beyond it the sinusoidal law's torque falls), ``slip_lag_steps`` (half a tooth
        pitch: beyond it the rotor slips a tooth), ``end_tension_n`` (mean of the last 0.3 s; the pretension
        if no step was lost).
    """
    params = reference_parameters() if params is None else params
    runs = pulse_runs(params, systems=paper.SYSTEMS)
    quarter = (math.pi / 2 / params.rotor_teeth) / params.step_angle
    return pd.DataFrame([
        {"v_in_mm_s": v, "x_f_mm": x, "system": s, "max_rotor_lag_steps": run.max_rotor_lag_steps,
         "torque_peak_lag_steps": quarter, "slip_lag_steps": 2 * quarter,
         "end_tension_n": float(np.mean(run.output[-300:]))}
        for (v, x, s), run in runs.items()
    ])  # fmt: skip


SENSITIVITY_VARIANTS: dict[str, dict[str, float]] = {
    "rig": {},
    "paper torque": {"holding_torque": paper.HOLDING_TORQUE_KG_CM * KG_CM},
    "0.8x torque": {"holding_torque_scale": 0.8},
    "1.5x torque": {"holding_torque_scale": 1.5},
    "100 g carriage": {"carriage_mass": 0.100},
    "3x stiffer cable": {"k_scale": 3.0},
}
"""The assumptions whose effect :func:`actuator_sensitivity` measures, each alone on the tuned rig: the
motor's torque amplitude (the rig assumes 1.5 x the paper's 4.3 kg cm; ``paper torque`` is 4.3 kg cm, the
others scale the assumed value), the load-cell carriage's mass (30 g assumed) and the cable's stiffness
(tuned)."""


def _variant(params: RigParameters, changes: dict[str, float]) -> RigParameters:
    """The rig with one assumption changed; the cable itself (``k_cable``) kept unless ``k_scale`` scales it.

    ``k`` is the whole path's stiffness, the cable in series with the motor's microstep spring, so a weaker
    motor with the same cable has a lower ``k``: ``1/k = 1/k_cable + R^2 / (T_h N_r)``.
    """
    kw = dict(changes)
    if "holding_torque_scale" in kw:
        kw["holding_torque"] = params.holding_torque * kw.pop("holding_torque_scale")
    k_cable = params.k_cable * kw.pop("k_scale", 1.0)
    torque = kw.get("holding_torque", params.holding_torque)
    kw["k"] = 1.0 / (1.0 / k_cable + params.spool_radius**2 / (torque * params.rotor_teeth))
    p = params.replace(**kw)
    if p.integrator != "rk4":  # the implicit step holds the cable's stiffness
        return p
    return p.replace(max_step=min(params.max_step, stable_max_step(p)))  # a stiffer cable needs a finer step


def actuator_sensitivity(
    params: RigParameters | None = None,
    variants: dict[str, dict[str, float]] | None = None,
    conditions: tuple[tuple[float, float], ...] = paper.TABLE_I_CONDITIONS,
    systems: tuple[str, ...] = paper.SYSTEMS,
) -> pd.DataFrame:
    """Every Table I scenario (unshaped and the paper's two shapers) under each variant of the actuator.

    Each variant (:data:`SENSITIVITY_VARIANTS`) changes one assumption of the tuned rig and nothing else
    (the cable stays the same cable when the motor changes; nothing is re-tuned: this is the sensitivity of
    the predictions to that assumption). The steps lost are
    read from the rotor's lag behind its command when the run has ended at rest (a tooth slipped is 16
    microsteps; what remains below one is the static lag that holds the tension). ``conditions`` and
    ``systems`` default to all of Table I; the first variant is the reference of the ``d_`` columns.

    Returns
    -------
    pandas.DataFrame
        One row per variant, condition, system and motion: ``variant``, ``holding_torque_kg_cm``,
        ``carriage_g``, ``k_n_m``, ``v_in_mm_s``, ``x_f_mm``, ``system``, ``motion``, ``peak_n``,
        ``overshoot_pct``, ``settling_ms``, ``max_rotor_lag_steps`` (the run's largest lag, microsteps),
        ``end_lag_steps`` (at the end), ``lost_steps`` (microsteps lost: 16 per tooth), ``end_tension_n``
        (mean of the last 0.3 s: the pretension when nothing was lost, about 0 for a slack cable), and
        ``d_peak_n``, ``d_overshoot_pp``, ``d_settling_ms``: the change from the ``rig`` variant's row.
    """
    params = reference_parameters() if params is None else params
    variants = SENSITIVITY_VARIANTS if variants is None else variants
    zv, zvd = design_tdfs()
    shapers = {"unshaped": None, "zv": zv, "zvd": zvd}
    tooth = 4 * round((math.pi / 2 / params.rotor_teeth) / params.step_angle)  # microsteps per tooth
    rows = []
    for name, changes in variants.items():
        p = _variant(params, changes)
        plant = ArmPlant(p)
        for v_in, x_f in conditions:
            for system in systems:
                prog, _ = experiment_programme(v_in, x_f, shaper=shapers[system])
                run = simulate(prog, params=p, seed=0, plant=plant)
                lag = plant.rotor_lag_steps
                metrics = recording_metrics(run.frame("output")).set_index("motion")
                for motion in ("Up", "Down"):
                    m = metrics.loc[motion]
                    rows.append({
                        "variant": name, "holding_torque_kg_cm": p.holding_torque / KG_CM,
                        "carriage_g": p.carriage_mass * 1e3, "k_n_m": p.k, "v_in_mm_s": v_in, "x_f_mm": x_f,
                        "system": system, "motion": motion, "peak_n": float(m["peak_n"]),
                        "overshoot_pct": float(m["overshoot_pct"]), "settling_ms": float(m["settling_ms"]),
                        "max_rotor_lag_steps": run.max_rotor_lag_steps, "end_lag_steps": lag,
                        "lost_steps": int(tooth * round(lag / tooth)),
                        "end_tension_n": float(np.mean(run.output[-300:])),
                    })  # fmt: skip
    df = pd.DataFrame(rows)
    key = ["v_in_mm_s", "x_f_mm", "system", "motion"]
    ref = df[df.variant == next(iter(variants))].set_index(key)[["peak_n", "overshoot_pct", "settling_ms"]]
    base = ref.reindex(pd.MultiIndex.from_frame(df[key])).to_numpy()
    df["d_peak_n"] = df.peak_n.to_numpy() - base[:, 0]
    df["d_overshoot_pp"] = df.overshoot_pct.to_numpy() - base[:, 1]
    df["d_settling_ms"] = df.settling_ms.to_numpy() - base[:, 2]
    return df


def sensitivity_summary(df: pd.DataFrame) -> pd.DataFrame:
    """Per variant of :func:`actuator_sensitivity`: runs that lost steps, the largest lag, how far rows moved.

    Returns
    -------
    pandas.DataFrame
        Index ``variant``; ``holding_torque_kg_cm``, ``carriage_g``, ``k_n_m``; ``unshaped_runs_losing_steps``
        and ``shaped_runs_losing_steps`` (of 4 and 8 runs), ``max_lag_unshaped_steps`` and
        ``max_lag_shaped_steps`` (microsteps), and the largest change of an unshaped and of a shaped Table II
        row from the rig's: ``unshaped_max_d_peak_n``, ``unshaped_max_d_overshoot_pp``,
        ``unshaped_max_d_settling_ms``, ``shaped_max_d_peak_n``, ``shaped_max_d_overshoot_pp``,
        ``shaped_max_d_settling_ms``.
    """
    rows = []
    for name, g in df.groupby("variant", sort=False):
        runs = g.drop_duplicates(["v_in_mm_s", "x_f_mm", "system"])
        row = {"variant": name, **g.iloc[0][["holding_torque_kg_cm", "carriage_g", "k_n_m"]].to_dict()}
        for label, sel in (("unshaped", g.system == "unshaped"), ("shaped", g.system != "unshaped")):
            r = runs[runs.system == "unshaped"] if label == "unshaped" else runs[runs.system != "unshaped"]
            row[f"{label}_runs_losing_steps"] = int((r.lost_steps != 0).sum())
            row[f"max_lag_{label}_steps"] = float(r.max_rotor_lag_steps.max())
            for col in ("d_peak_n", "d_overshoot_pp", "d_settling_ms"):
                row[f"{label}_max_{col}"] = float(g.loc[sel, col].abs().max())
        rows.append(row)
    return pd.DataFrame(rows).set_index("variant")


CONVERGENCE_U_MM = (0.0, 10.0, 20.0, 30.0, 40.0)
"""Cable displacements of the convergence study, mm."""


def _pct(a: pd.Series, b: pd.Series) -> pd.Series:
    # rounded to the printed digits (+ 0.0 turns -0.0 into 0.0): no sign of a round-off zero in the output
    return (100 * (a / b - 1)).round(3) + 0.0


def convergence(params: RigParameters | None = None) -> pd.DataFrame:
    """The arc chain against finer rods: static tension and frequencies over the cable displacement.

    The tuned rig (one element per disc interval, with the rod's bowing) against 4 and 8 elements per
    interval, and the plain arc chain (no bowing) against its 4x finer rod: the static tension, the dominant
    and the second damped frequency at :data:`CONVERGENCE_U_MM`, and their differences in % (three decimals).
    """
    params = reference_parameters() if params is None else params
    u = np.array(CONVERGENCE_U_MM)
    maps = {m: frequency_map(params.replace(elements_per_disc=m), u) for m in (1, 4, 8)}
    plain = {m: frequency_map(params.replace(elements_per_disc=m, bowing=False), u) for m in (1, 4)}
    return pd.DataFrame({
        "u_mm": u,
        "bend_deg": maps[4].tip_angle_deg,
        "tension_m1": maps[1].static_tension_n, "tension_m4": maps[4].static_tension_n,
        "tension_pct": _pct(maps[1].static_tension_n, maps[4].static_tension_n),
        "omega_d_m1": maps[1].omega_d_rad_s, "omega_d_m4": maps[4].omega_d_rad_s,
        "omega_d_pct": _pct(maps[1].omega_d_rad_s, maps[4].omega_d_rad_s),
        "omega_d_pct_m8": _pct(maps[1].omega_d_rad_s, maps[8].omega_d_rad_s),
        "omega_d2_pct": _pct(maps[1].omega_d2_rad_s, maps[4].omega_d2_rad_s),
        "plain_tension_pct": _pct(plain[1].static_tension_n, plain[4].static_tension_n),
        "plain_omega_d_pct": _pct(plain[1].omega_d_rad_s, plain[4].omega_d_rad_s),
    })  # fmt: skip


def pulse_study() -> pd.DataFrame:
    """The tuned rig's unshaped pulses beside Table II's rows (:func:`helpers.virtual.tuning.pulse_table`).

    The twelve unshaped Table I runs on the tuned rig (noise seed 0, :func:`reference_parameters`): what the
    rig was tuned on (notebook 06,
    section 2, reads it; about 10 s to compute).
    """
    return pulse_table(pulse_runs(reference_parameters()))


SPATIAL_MAP_RIGS = ("four-tendon", "hanging")
"""The shipped rig files of the spatial study: the four-tendon arm horizontal (as the paper's) and hanging."""
SPATIAL_MAP_DIRECTIONS_DEG = tuple(float(d) for d in np.arange(0.0, 360.0, 22.5))
SPATIAL_MAP_BENDS_MM = (0.0, 10.0, 20.0)


def spatial_map() -> pd.DataFrame:
    """The spatial twin's modes over bend direction and magnitude, for the two four-tendon rig files.

    :func:`helpers.virtual.spatial.direction_map.frequency_map` of ``rigs/four-tendon.toml`` and
    ``rigs/hanging.toml`` (16 directions, every 22.5 degrees from tendon 1, bends of 0, 10 and 20 mm, four
    modes with the spools held), with a ``rig`` column: notebook 06 shows how the modes split when the arm
    bends and how gravity breaks the horizontal arm's symmetry (``docs/spatial_twin.md``, section 5).
    """
    frames = []
    for name in SPATIAL_MAP_RIGS:
        rig = spatial_rig(rigfile.load(rigfile.resolve(name)))
        df = spatial_frequency_map(rig, SPATIAL_MAP_DIRECTIONS_DEG, SPATIAL_MAP_BENDS_MM, n_modes=4)
        frames.append(df.assign(rig=name))
    out = pd.concat(frames, ignore_index=True)
    return out[["rig", *[c for c in out.columns if c != "rig"]]]


def write_studies(names: tuple[str, ...] = tuple(STUDY_FILES), verbose: bool = True) -> list[Path]:
    """Run the studies and write their CSVs into the repository's ``figures/`` (6 significant digits).

    They go to :data:`helpers.base.paths.STORED_TABLES_DIR` even when ``HELPERS_FIGURES_DIR`` redirects the
    notebooks' output: notebook 06 reads them from there.
    """
    funcs = {"layouts": damping_layouts, "friction": eyelet_friction, "actuator": actuator_effects,
             "lag": rotor_lag, "sensitivity": actuator_sensitivity, "convergence": convergence,
             "spatial": spatial_map, "pulses": pulse_study}  # fmt: skip
    paths = []
    for name in names:
        t0 = time.perf_counter()
        df = funcs[name]()
        STORED_TABLES_DIR.mkdir(parents=True, exist_ok=True)
        path = STORED_TABLES_DIR / STUDY_FILES[name]
        df.to_csv(path, index=False, float_format="%.6g")
        paths.append(path)
        if verbose:
            print(f"{name}: {path} ({time.perf_counter() - t0:.0f} s)")
            print(df.to_string(index=False, max_colwidth=40), flush=True)
    return paths


# --- command line: python -m helpers virtual-rig ... -------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``virtual-rig`` command's options."""
    parser.add_argument(
        "action", choices=["check", "tune", "studies", "frequency-map", "sorosim"],
        help="check: the tuned rig's identified mode and unshaped rows (seconds); tune: re-derive the tuned "
             "literals (minutes); studies: rewrite figures/virtual_*.csv for notebook 06 (a few minutes); "
             "frequency-map: print the spatial twin's modes against bend direction and magnitude as CSV "
             "(docs/spatial_twin.md; about a second per row); sorosim FILE: the twin as a bare rod against a "
             "SoroSim tip-release test (docs/external_data.md; about 30 s)",
    )  # fmt: skip
    parser.add_argument("file", nargs="?", type=Path, help="'sorosim': the SoroSim test's file")
    parser.add_argument("--segments", type=int, default=20, help="'sorosim': the twin's elements (even)")
    parser.add_argument("--print-rod-file", action="store_true",
                        help="'sorosim': print the bare rod's file the twin is built from")  # fmt: skip
    parser.add_argument("--max-evaluations", type=int, default=100, help="Nelder-Mead budget of 'tune'")
    parser.add_argument("--data-dir", type=Path, default=None,
                        help="'tune': tune the --rig file's twin on this data folder's identification "
                             "result and unshaped recordings, written as a new rig file (docs/rig_file.md); "
                             "default for a rig other than the paper's: data/")  # fmt: skip
    parser.add_argument("--out", type=Path, default=None,
                        help="'tune' with a rig file: the new rig file (default NAME-tuned.toml here)")
    parser.add_argument("--only", nargs="*", choices=list(STUDY_FILES), help="'studies': run only these")
    parser.add_argument("--preset", choices=list(PRESETS), default=None,
                        help="'frequency-map': a built-in spatial rig (default: the rig file)")  # fmt: skip
    parser.add_argument("--directions", default="0:360:15",
                        help="'frequency-map': bend directions, deg from tendon 1 (0,45,90 or a:b:step)")
    parser.add_argument("--bends", default="0:35:5", help="'frequency-map': bend magnitudes, mm of cable")
    parser.add_argument("--modes", type=int, default=4, help="'frequency-map': modes per row (default 4)")


def run(args: argparse.Namespace) -> int:
    """Run the ``virtual-rig`` command."""
    t0 = time.perf_counter()
    if args.action == "sorosim":
        if args.file is None:
            raise ValueError("virtual-rig sorosim needs the SoroSim test's FILE")
        return sorosim_command(args.file, args.segments, args.print_rod_file)
    if args.file is not None:
        raise ValueError(f"virtual-rig {args.action} takes no FILE (only 'sorosim' does)")
    if args.action == "frequency-map":
        if args.modes < 1:
            raise ValueError(f"--modes must be >= 1, got {args.modes}")
        rig = preset(args.preset) if args.preset is not None else spatial_rig(args.rig)
        directions = "0" if rig.n_tendons == 1 and args.directions == "0:360:15" else args.directions
        print(frequency_map_csv(rig, directions, args.bends, n_modes=args.modes), end="")
        return 0
    if args.action == "studies":
        write_studies(tuple(args.only) if args.only else tuple(STUDY_FILES))
        return 0
    own_rig = args.rig.hash != rigfile.default_rig().hash
    if args.action == "tune" and (args.data_dir is not None or own_rig):
        data_dir = args.data_dir if args.data_dir is not None else DATA_DIR
        return rig_file_tuning.run_tune(args.rig, data_dir, args.out, args.max_evaluations)
    if args.action == "tune":
        params, history = tune(max_evaluations=args.max_evaluations, verbose=True)
        print(
            f"\nbest objective {history.objective.min():.5f} after {len(history)} evaluations "
            f"({time.perf_counter() - t0:.0f} s); TUNED literals for helpers/virtual/parameters.py "
            f"(max_step {params.max_step * 1e3:.4f} ms):"
        )
        print(tuned_literals(params))
    else:
        params = RigParameters()
    run_id = identification_run(params)
    ident = identify(run_id.t, run_id.adc.astype(float), window=paper.IDENTIFICATION_RUN["window_s"])
    dw, dz = 100 * (ident.omega_d / paper.OMEGA_D - 1), 100 * (ident.zeta / paper.ZETA - 1)
    print(
        f"\nidentification run: omega_d {ident.omega_d:.3f} rad/s ({dw:+.2f} %), "
        f"zeta {ident.zeta:.4f} ({dz:+.1f} %)"
    )
    table = pulse_table(pulse_runs(params))
    print(f"objective on the unshaped rows: {objective(table):.5f}")
    cols = ["v_in_mm_s", "x_f_mm", "motion", "peak_n", "paper_peak_n", "overshoot_pct", "paper_overshoot_pct",
            "settling_ms", "paper_settling_ms", "max_rotor_lag_steps"]  # fmt: skip
    print(table[cols].round(2).to_string(index=False))
    return 0
