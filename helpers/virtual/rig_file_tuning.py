"""Tuning the twin of a rig file on that rig's own data, written back as a new rig file with provenance.

``python -m helpers virtual-rig tune --rig FILE --data-dir DIR`` runs the procedure that tuned the paper's
rig (:mod:`helpers.virtual.tuning`) with the user's data in place of the paper's numbers:

1. *the identified mode*: ``DIR/identification/result.json`` (``record all``, or ``record pulse`` and the
   identification of notebook 02); the disc mass and the damping level (``alpha``, ``beta_chord``) are
   solved so that the twin's lowest mode at rest (rotor free) is that mode
   (:func:`helpers.virtual.tuning.calibrate_mode`);
2. *the unshaped recordings* of ``DIR/experiments`` (``record table-i``): the cable offset, the cable's
   stiffness and the pretension minimise the mean square of the relative Up-peak errors and of the Up and
   Down overshoot errors (in units of 100 points) against the recordings' means, each candidate
   re-calibrated by step 1 (Nelder-Mead in log coordinates, as the paper's rig).

Every recording used must carry the rig file's hash (a recording of another rig is refused). The result is
the input file's text with the six tuned keys of ``[arm]`` rewritten (``disc_mass_g``, ``cable_offset_mm``,
``cable_stiffness_n_m``, ``pretension_n``, ``damping_alpha_per_s``, ``damping_beta_chord_s``) and a header
of provenance comments (source recordings, code version, date, objective); it is written to a new file and
never over the input or any existing file.
"""

from __future__ import annotations

import datetime as _dt
import math
import re
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy import optimize

from helpers import __version__, recordings, rigfile
from helpers.base.jsonfile import DataFileError
from helpers.base.paths import REPO_ROOT
from helpers.board.programmes import experiment_programme
from helpers.paper.identify import load_identification
from helpers.paper.metrics import MOTIONS, recording_metrics, scenario_table
from helpers.rigfile import RigFile
from helpers.rigfile.recorded import recording_rig
from helpers.virtual import ArmPlant, RigParameters, simulate
from helpers.virtual.from_rig import ROTOR_TEETH, rig_parameters
from helpers.virtual.statics import stable_max_step
from helpers.virtual.tuning import calibrate_mode

TUNED_ARM_KEYS = (
    "disc_mass_g", "cable_offset_mm", "cable_stiffness_n_m", "pretension_n", "damping_alpha_per_s",
    "damping_beta_chord_s",
)  # fmt: skip
"""The ``[arm]`` keys a tuning writes (the parameters the paper's rig is tuned on)."""


@dataclass(frozen=True)
class Targets:
    """What the twin is tuned to: the identified mode and the unshaped recordings' Table II means."""

    omega_d: float
    zeta: float
    table: pd.DataFrame
    """``v_in_mm_s``, ``x_f_mm``, ``motion``, ``peak_n``, ``overshoot_pct`` (unshaped means)."""
    sources: tuple[str, ...]
    """The recordings (and the identification result) used, as given."""


def load_targets(rig: RigFile, data_dir: Path) -> Targets:
    """The tuning targets in ``data_dir``, each recording checked to be of ``rig``.

    Raises
    ------
    helpers.base.jsonfile.MissingDataError
        No identification result.
    helpers.base.jsonfile.DataFileError
        No unshaped recording, or a recording of another rig (one line naming it).
    """
    data_dir = Path(data_dir)
    ident_path = data_dir / "identification" / "result.json"
    mode = load_identification(ident_path)
    sources = [str(ident_path)]
    if mode.recording:
        rec_path = data_dir / "identification" / f"{mode.recording}.csv"
        if rec_path.exists():
            _check_rig(recordings.load(rec_path, derive=False).meta, rig, rec_path)
            sources.append(str(rec_path))
    recs = []
    for path in sorted((data_dir / "experiments").glob("unshaped_*.csv")):
        rec = recordings.load(path)
        _check_rig(rec.meta, rig, path)
        recs.append(rec)
        sources.append(str(path))
    if not recs:
        folder = data_dir / "experiments"
        raise DataFileError(f"{folder}: no unshaped recording (record them with `record table-i`)")
    table = scenario_table(recs)
    cols = {"peak_n_mean": "peak_n", "overshoot_pct_mean": "overshoot_pct"}
    table = table.rename(columns=cols)[["v_in_mm_s", "x_f_mm", "motion", *cols.values()]]
    return Targets(mode.omega_d, mode.zeta, table.reset_index(drop=True), tuple(sources))


def refuse_other_rig(meta: dict[str, Any], rig: RigFile, path: Path, what: str = "use") -> None:
    """Refuse (``DataFileError``, one line) a recording made on a rig other than ``rig``."""
    kept = recording_rig(meta, source=str(path))
    if kept.hash != rig.hash:
        raise DataFileError(
            f"{path}: recorded on rig {kept.name!r} (hash {kept.hash}), not on the rig {rig.name!r} "
            f"({rig.hash}); {what} a rig's own recordings (select its rig file with --rig)"
        )


def _check_rig(meta: dict[str, Any], rig: RigFile, path: Path) -> None:
    refuse_other_rig(meta, rig, path, what="tune a rig on")


def simulated_table(
    params: RigParameters, conditions: list[tuple[float, float]], seed: int = 0
) -> pd.DataFrame:
    """Table II metrics (amplifier output) of the twin's unshaped runs at ``conditions``."""
    plant = ArmPlant(params)
    rows = []
    for v, x in conditions:
        prog, _ = experiment_programme(v, x)
        run = simulate(prog, params=params, seed=seed, plant=plant)
        m = recording_metrics(run.frame("output")).set_index("motion")
        for motion in MOTIONS:
            rows.append({"v_in_mm_s": v, "x_f_mm": x, "motion": motion, "peak_n": m.loc[motion, "peak_n"],
                         "overshoot_pct": m.loc[motion, "overshoot_pct"]})  # fmt: skip
    return pd.DataFrame(rows)


def objective(sim: pd.DataFrame, targets: pd.DataFrame) -> float:
    """The paper rig's objective against the user's table: relative Up peaks, Up and Down overshoots / 100."""
    keys = ["v_in_mm_s", "x_f_mm", "motion"]
    both = sim.merge(targets, on=keys, suffixes=("", "_target"))
    up = both[both.motion == "Up"]
    terms = list((up.peak_n / up.peak_n_target - 1).to_numpy())
    terms += list(((both.overshoot_pct - both.overshoot_pct_target) / 100.0).to_numpy())
    arr = np.asarray(terms, dtype=float)
    return float(np.mean(arr**2)) if arr.size and np.all(np.isfinite(arr)) else math.inf


def tune_rig(
    rig: RigFile, targets: Targets, max_evaluations: int = 60, verbose: bool = False
) -> tuple[RigParameters, float, pd.DataFrame]:
    """Tune ``rig``'s planar twin on ``targets`` (the module's procedure).

    Returns
    -------
    (RigParameters, float, pandas.DataFrame)
        The best twin, its objective and the history (one row per evaluation).
    """
    start = rig_parameters(rig)
    conditions = sorted({(float(v), float(x)) for v, x in zip(targets.table.v_in_mm_s, targets.table.x_f_mm,
                                                                strict=True)})  # fmt: skip
    history: list[dict[str, float]] = []
    best: dict[str, Any] = {"f": math.inf, "params": None}

    def f(x: np.ndarray) -> float:
        r, k, pre = (float(v) for v in np.exp(x))
        try:
            p = calibrate_mode(start.replace(r=r, k=k, pretension=pre), targets.omega_d, targets.zeta)
            p = p.replace(max_step=stable_max_step(p))
            value = objective(simulated_table(p, conditions), targets.table)
        except (ValueError, RuntimeError, FloatingPointError):
            value, p = math.inf, None
        history.append({"r_mm": r * 1e3, "k_n_m": k, "pretension_n": pre, "objective": value})
        if verbose:
            print(f"r {r * 1e3:.3f} mm  k {k:.0f} N/m  pretension {pre:.3f} N  objective {value:.5f}")
        if value < best["f"]:
            best.update(f=value, params=p)
        return value

    x0 = np.log([start.r, start.k, max(start.pretension, 1e-3)])
    simplex = x0 + np.vstack([np.zeros(3), np.diag([0.06, 0.15, 0.12])])
    options = {"maxfev": max_evaluations, "xatol": 2e-3, "fatol": 1e-5, "initial_simplex": simplex}
    optimize.minimize(f, x0, method="Nelder-Mead", options=options)
    if best["params"] is None:
        raise RuntimeError("no candidate twin could be evaluated (every one failed its mode calibration)")
    return best["params"], best["f"], pd.DataFrame(history)


def arm_values(rig: RigFile, params: RigParameters) -> dict[str, float]:
    """The ``[arm]`` values of a tuned twin (the series stiffness less the stepper's microstep spring)."""
    t = rig.tendons[0]
    R = 0.5e-3 * t.spool_diameter_mm
    cable = 1.0 / (1.0 / params.k - R**2 / (t.holding_torque_n_m * ROTOR_TEETH))
    return {
        "disc_mass_g": params.disc_mass * 1e3, "cable_offset_mm": params.r * 1e3,
        "cable_stiffness_n_m": cable, "pretension_n": params.pretension, "damping_alpha_per_s": params.alpha,
        "damping_beta_chord_s": params.beta_chord,
    }  # fmt: skip


def code_version() -> str:
    """The package version and, in a git checkout, the commit (``0.1.0+abc1234``)."""
    try:
        cmd = ["git", "-C", str(REPO_ROOT), "rev-parse", "--short", "HEAD"]
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=10, check=True).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return __version__
    return f"{__version__}+{out}" if out else __version__


def tuned_text(rig: RigFile, values: dict[str, float], provenance: list[str]) -> str:
    """``rig``'s text with the ``[arm]`` keys of ``values`` rewritten and provenance comments on top."""
    lines = rig.text.splitlines()
    section, seen, out = "", set(), []
    arm_end = None
    for line in lines:
        head = re.match(r"\s*\[+\s*([A-Za-z_]+)", line)
        if head and not line.strip().startswith("#"):
            if section == "arm":
                arm_end = len(out)
            section = head.group(1)
        key = re.match(r"\s*([A-Za-z_]+)\s*=", line)
        if section == "arm" and key and key.group(1) in values:
            name = key.group(1)
            seen.add(name)
            line = f"{name} = {values[name]:.10g}  # tuned (header)"
        out.append(line)
    if section == "arm":
        arm_end = len(out)
    missing = [f"{k} = {values[k]:.10g}  # tuned (header)" for k in values if k not in seen]
    if missing:
        if arm_end is None:
            raise ValueError(f"{rig.source}: no [arm] table to write the tuned values into")
        while arm_end > 0 and not out[arm_end - 1].strip():
            arm_end -= 1
        out[arm_end:arm_end] = missing
    header = [f"# {p}" for p in provenance]
    return "\n".join(header + out) + "\n"


def write_tuned(rig: RigFile, params: RigParameters, value: float, targets: Targets, out: Path) -> Path:
    """Write the tuned rig file to ``out`` (refused if it exists or is the input); check it loads.

    Raises
    ------
    helpers.base.jsonfile.DataFileError
        ``out`` exists (the input included).
    """
    out = Path(out)
    if out.exists():
        raise DataFileError(f"{out}: exists already; the tuned rig goes to a new file (choose another --out)")
    when = _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    provenance = [
        f"TUNED by `python -m helpers virtual-rig tune` from {rig.source} (hash {rig.hash}) on {when}",
        f"code version {code_version()}; objective {value:.6f} (docs/rig_file.md, 'Tuning a rig file')",
        f"identified mode: omega_d {targets.omega_d:.4f} rad/s, zeta {targets.zeta:.5f}",
        "source recordings:",
        *(f"  {s}" for s in targets.sources),
        "",
    ]
    text = tuned_text(rig, arm_values(rig, params), provenance)
    rigfile.loads(text, source=str(out))  # a tuned file that does not load is not written
    out.parent.mkdir(parents=True, exist_ok=True)
    with open(out, "x", encoding="utf-8") as fh:
        fh.write(text)
    return out


def default_out(rig: RigFile) -> Path:
    """The default new file: ``NAME-tuned.toml`` in the working directory (``-tuned-2`` ... if it exists)."""
    out, n = Path.cwd() / f"{rig.name}-tuned.toml", 2
    while out.exists():
        out, n = Path.cwd() / f"{rig.name}-tuned-{n}.toml", n + 1
    return out


def run_tune(rig: RigFile, data_dir: Path, out: Path | None, max_evaluations: int) -> int:
    """``python -m helpers virtual-rig tune --rig FILE --data-dir DIR [--out NEW]``: tune, write anew."""
    out = out if out is not None else default_out(rig)
    if Path(out).exists():  # before minutes of tuning
        raise DataFileError(f"{out}: exists already; the tuned rig goes to a new file (choose another --out)")
    targets = load_targets(rig, data_dir)
    n_runs = len(targets.sources) - 1
    print(f"tuning the twin of {rig.source} on {n_runs} recording(s) of {data_dir}, budget {max_evaluations}")
    params, value, history = tune_rig(rig, targets, max_evaluations=max_evaluations, verbose=True)
    path = write_tuned(rig, params, value, targets, out)
    values = arm_values(rig, params)
    print(f"best objective {value:.6f} after {len(history)} evaluations; tuned [arm] values:")
    for key in TUNED_ARM_KEYS:
        print(f"  {key} = {values[key]:.6g}")
    print(f"tuned rig file -> {path} (the input {rig.source} is unchanged)")
    return 0
