"""The load-cell calibration: the fit of counts against known loads, and its file, owned here alone.

``counts = offset_counts + gain * load`` is fitted by least squares through the per-load mean counts,
weighted by each mean's standard error (the scatter of its samples / sqrt(n)), with the standard errors of
slope and intercept; ``newtons_per_count = 1 / gain`` with the error propagated to first order. The result is
written to ``data/calibration/calibration.json`` (:data:`helpers.base.paths.LOADCELL_CALIBRATION`), which
every run reads through :func:`helpers.paper.tension.load_calibration` (the reader and the calibration's
type live there, so that a run does not carry the fit). Recording the known loads is
:mod:`helpers.rig.static`'s job.

(Not to be confused with the virtual rig's *tuning*, :mod:`helpers.virtual.tuning`, or the linear model's
*fit*, :func:`helpers.research.model_fit.fit_to_mode`.)
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from helpers.base.jsonfile import write_json
from helpers.base.paths import LOADCELL_CALIBRATION
from helpers.paper.tension import LoadCellCalibration, load_calibration
from helpers.rigfile import derived
from helpers.rigfile.recorded import recording_rig

if TYPE_CHECKING:  # the recordings are read by their owner; here they are only a type
    from helpers.recordings import Recording

__all__ = [
    "LoadCellCalibration",
    "uncalibrated",
    "CalibrationFit",
    "fit_calibration",
    "save_calibration",
    "load_calibration",
]
"""The calibration's whole interface: the fit and the writer here, the reader and its type from
:mod:`helpers.paper.tension` (which every run imports without the fit)."""


def uncalibrated(mm_per_step: float) -> LoadCellCalibration:
    """Explicitly no calibration (recording the calibration itself, benchmarks): tension in counts."""
    return LoadCellCalibration(1.0, 0.0, mm_per_step, "uncalibrated: tension_n equals adc counts")



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
        adc_max = derived(recording_rig(r.meta)).adc_max  # the ADC of the rig the recording was made on
        if adc.max() >= adc_max:
            raise ValueError(f"{r.name}: the ADC saturates ({adc_max} counts) at {sc['load_n']:.2f} N")
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
    weighted = bool(np.all(sem > 0))  # by each mean's own standard error (the sample scatter is measured)
    if weighted:
        coef, cov = np.polyfit(x, y, 1, w=1.0 / sem, cov="unscaled")
    else:  # noiseless readings: fall back to the residual scatter
        coef, cov = np.polyfit(x, y, 1, cov=True)
    slope, intercept = float(coef[0]), float(coef[1])
    slope_se, intercept_se = (float(v) for v in np.sqrt(np.clip(np.diag(cov), 0.0, None)))
    table["fitted_counts"] = intercept + slope * x
    table["residual_counts"] = y - table["fitted_counts"]
    r2 = 1.0 - float(np.sum(table["residual_counts"] ** 2)) / float(np.sum((y - y.mean()) ** 2))
    chi2 = float(np.sum((table["residual_counts"] / sem) ** 2)) / (len(x) - 2) if weighted else float("nan")
    return CalibrationFit(
        table=table,
        gain_counts_per_n=slope,
        gain_stderr=slope_se,
        offset_counts=intercept,
        offset_stderr=intercept_se,
        r_squared=r2,
        reduced_chi2=chi2,
    )


def save_calibration(
    fit: CalibrationFit, recs: Sequence[Recording], path: str | os.PathLike = LOADCELL_CALIBRATION
) -> Path:
    """Write the calibration that every run reads (:func:`load_calibration`), with its provenance.

    Returns
    -------
    pathlib.Path
    """
    kinds = {r.meta.get("source", {}).get("kind") for r in recs}
    source = {"kind": kinds.pop() if len(kinds) == 1 else "mixed"}
    steps = {derived(recording_rig(r.meta)).mm_per_step[0] for r in recs}
    if len(steps) != 1:
        raise ValueError("the calibration's recordings were made on rigs of different mm per step")
    data = {
        "newtons_per_count": fit.newtons_per_count,
        "newtons_per_count_stderr": fit.newtons_per_count_stderr,
        "offset_counts": fit.offset_counts,
        "offset_counts_stderr": fit.offset_stderr,
        "gain_counts_per_n": fit.gain_counts_per_n,
        "r_squared": fit.r_squared,
        "reduced_chi2": fit.reduced_chi2,
        "mm_per_step": steps.pop(),
        "source": source,
        "recordings": [r.path.name if r.path else r.name for r in recs],
        "started_utc": min(str(r.meta.get("started_utc", "")) for r in recs),
    }
    return write_json(path, data)
