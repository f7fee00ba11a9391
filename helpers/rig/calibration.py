"""Load-cell calibration: record the ADC counts under known loads, fit counts = offset + gain * load.

Procedure (hardware): detach the cable from the load cell, hang each known mass from it in turn, and record
``duration_s`` seconds of samples per mass with the motor idle. On the virtual rig the same code path runs,
and the loads are hung by the VIRTUAL calibration fixture
(:meth:`helpers.virtual.boards.VirtualWorld.hang_load`); such recordings say ``virtual-rig`` in their
metadata.

The fit is a least-squares line through the per-load mean counts, weighted by each mean's standard error (the
scatter of its samples / sqrt(n)), with the standard errors of slope and intercept; ``newtons_per_count = 1 /
gain`` with the error propagated to first order. The result is written to
``data/calibration/calibration.json``, which :class:`helpers.rig.Rig` reads.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

from helpers import recordings
from helpers.paths import DATA_DIR
from helpers.profiles import MM_PER_STEP
from helpers.recordings import Recording

G_STANDARD = 9.80665
"""Standard gravity, m/s^2 (weight of a hung mass)."""

CALIBRATION_MASSES_KG = (0.0, 0.2, 0.5, 1.0, 1.5, 1.9)
"""Masses hung on the load cell (kg): 0 to 18.6 N, the range of Table II's tensions (up to 17.7 N)."""

CALIBRATION_DIR = DATA_DIR / "calibration"
CALIBRATION_FILE = CALIBRATION_DIR / "calibration.json"


def record_calibration(
    rig: Any,
    masses_kg: Sequence[float] = CALIBRATION_MASSES_KG,
    duration_s: float = 1.0,
    folder: str | os.PathLike = CALIBRATION_DIR,
    prompt: Callable[[str], object] | None = input,
    rate_hz: int = 1000,
) -> list[Recording]:
    """Record ``duration_s`` of counts under each known mass.

    Parameters
    ----------
    rig : helpers.rig.Rig
        Connected rig (the stepper is not used).
    masses_kg : sequence of float
        The masses, kg.
    duration_s : float
        Device seconds per mass.
    folder : path-like
        Where the recordings go (``load_<grams>g.csv/json``).
    prompt : callable
        On hardware, called with an instruction before each mass (``input`` waits for Enter). Ignored on the
        in-process virtual rig, whose fixture hangs the load itself.
    rate_hz : int
        DAQ sample rate.

    Returns
    -------
    list of Recording
    """
    world = rig.virtual_world
    out = []
    try:
        for m in masses_kg:
            if not np.isfinite(m) or m < 0:
                raise ValueError(f"masses must be finite and >= 0 kg, got {m}")
            load = float(m) * G_STANDARD
            if world is not None:
                world.hang_load(load)
            elif prompt is not None:
                prompt(f"Hang {m:.3f} kg ({load:.3f} N) from the load cell, then press Enter")
            scenario = {
                "kind": "calibration",
                "mass_kg": float(m),
                "load_n": load,
                "g_m_s2": G_STANDARD,
                "fixture": "VIRTUAL known load (simulated)" if rig.is_virtual else "hung mass",
            }
            path = Path(folder) / f"load_{round(m * 1000):04d}g"
            out.append(rig.record_static(duration_s, scenario, path=path, rate_hz=rate_hz))
    finally:
        if world is not None:
            world.hang_load(None)
    return out


@dataclass(frozen=True)
class CalibrationFit:
    """counts = offset_counts + gain_counts_per_n * load, fitted by least squares.

    Attributes
    ----------
    table : pandas.DataFrame
        Per load: ``mass_kg``, ``load_n``, ``mean_counts``, ``std_counts``, ``n_samples``, ``fitted_counts``,
        ``residual_counts``.
    gain_counts_per_n, gain_stderr : float
        Slope and its standard error.
    offset_counts, offset_stderr : float
        Intercept and its standard error.
    r_squared : float
        Coefficient of determination.
    reduced_chi2 : float
        Sum of squared residuals in units of each mean's standard error, per degree of freedom (about 1 when
        the line and the error bars agree).
    """

    table: pd.DataFrame
    gain_counts_per_n: float
    gain_stderr: float
    offset_counts: float
    offset_stderr: float
    r_squared: float
    reduced_chi2: float = float("nan")

    @property
    def newtons_per_count(self) -> float:
        """1 / gain."""
        return 1.0 / self.gain_counts_per_n

    @property
    def newtons_per_count_stderr(self) -> float:
        """Standard error of 1/gain (first-order propagation)."""
        return self.gain_stderr / self.gain_counts_per_n**2


def fit_calibration(recs: Sequence[Recording]) -> CalibrationFit:
    """Fit the calibration line to calibration recordings.

    Parameters
    ----------
    recs : sequence of Recording
        Each with ``scenario.kind == "calibration"`` and ``scenario.load_n``; at least three distinct loads.

    Returns
    -------
    CalibrationFit
    """
    rows = []
    for r in recs:
        sc = r.meta.get("scenario", {})
        if sc.get("kind") != "calibration" or "load_n" not in sc:
            raise ValueError(f"{r.name}: not a calibration recording (scenario {sc.get('kind')!r})")
        adc = r.frame["adc"].to_numpy(float)
        if adc.size == 0:
            raise ValueError(f"{r.name}: no samples")
        if adc.max() >= 1023:
            raise ValueError(f"{r.name}: the ADC saturates (1023 counts) at {sc['load_n']:.2f} N")
        rows.append(
            {
                "mass_kg": sc.get("mass_kg", np.nan),
                "load_n": float(sc["load_n"]),
                "mean_counts": adc.mean(),
                "std_counts": adc.std(ddof=1) if adc.size > 1 else 0.0,
                "n_samples": adc.size,
                "recording": r.name,
            }
        )
    table = pd.DataFrame(
        rows, columns=["mass_kg", "load_n", "mean_counts", "std_counts", "n_samples", "recording"]
    )
    table = table.sort_values("load_n", ignore_index=True)
    if table["load_n"].nunique() < 3:
        raise ValueError("a calibration needs at least three distinct loads")
    x, y = table["load_n"].to_numpy(), table["mean_counts"].to_numpy()
    sem = table["std_counts"].to_numpy() / np.sqrt(table["n_samples"].to_numpy())
    table["sem_counts"] = sem
    if np.all(sem > 0):  # weighted by each mean's own standard error (the sample scatter is measured)
        coef, cov = np.polyfit(x, y, 1, w=1.0 / sem, cov="unscaled")
        slope, intercept = float(coef[0]), float(coef[1])
        slope_se, intercept_se = (float(v) for v in np.sqrt(np.diag(cov)))
    else:  # noiseless readings: fall back to the residual scatter
        lr = stats.linregress(x, y)
        slope, intercept, slope_se, intercept_se = lr.slope, lr.intercept, lr.stderr, lr.intercept_stderr
    table["fitted_counts"] = intercept + slope * x
    table["residual_counts"] = y - table["fitted_counts"]
    r2 = 1.0 - float(np.sum(table["residual_counts"] ** 2)) / float(np.sum((y - y.mean()) ** 2))
    chi2 = (
        float(np.sum((table["residual_counts"] / sem) ** 2)) / (len(x) - 2)
        if np.all(sem > 0)
        else float("nan")
    )
    return CalibrationFit(
        table=table,
        gain_counts_per_n=float(slope),
        gain_stderr=float(slope_se),
        offset_counts=float(intercept),
        offset_stderr=float(intercept_se),
        r_squared=r2,
        reduced_chi2=chi2,
    )


def save_calibration(
    fit: CalibrationFit, recs: Sequence[Recording], path: str | os.PathLike = CALIBRATION_FILE
) -> Path:
    """Write the calibration that :class:`helpers.rig.Rig` uses, with its provenance.

    Returns
    -------
    pathlib.Path
    """
    kinds = {r.meta.get("source", {}).get("kind") for r in recs}
    source = {"kind": kinds.pop() if len(kinds) == 1 else "mixed"}
    data = {
        "newtons_per_count": fit.newtons_per_count,
        "newtons_per_count_stderr": fit.newtons_per_count_stderr,
        "offset_counts": fit.offset_counts,
        "offset_counts_stderr": fit.offset_stderr,
        "gain_counts_per_n": fit.gain_counts_per_n,
        "r_squared": fit.r_squared,
        "reduced_chi2": fit.reduced_chi2,
        "mm_per_step": MM_PER_STEP,
        "source": source,
        "recordings": [r.path.name if r.path else r.name for r in recs],
        "started_utc": min(str(r.meta.get("started_utc", "")) for r in recs),
    }
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")
    os.replace(tmp, p)
    return p


def load_calibration_recordings(folder: str | os.PathLike = CALIBRATION_DIR) -> list[Recording]:
    """Load every calibration recording in ``folder`` (sorted by load)."""
    recs = [recordings.load(p) for p in sorted(Path(folder).glob("load_*.csv"))]
    return sorted(recs, key=lambda r: r.meta["scenario"]["load_n"])
