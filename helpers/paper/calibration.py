"""The load-cell calibration: the fit of counts against known loads, and its file, owned here alone.

``counts = offset_counts + gain * load`` is fitted by least squares through the per-load mean counts,
weighted by each mean's standard error (the scatter of its samples / sqrt(n)), with the standard errors of
slope and intercept; ``newtons_per_count = 1 / gain`` with the error propagated to first order. The result is
written to ``data/calibration/calibration.json`` (:data:`helpers.base.paths.LOADCELL_CALIBRATION`), which
every run
reads through :func:`load_calibration`. Recording the known loads is :mod:`helpers.rig.loadcell`'s job.

(Not to be confused with the virtual rig's *tuning*, :mod:`helpers.virtual.tuning`, or the linear model's
*fit*,
:func:`helpers.paper.model.fit_to_mode`.)
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from helpers.base.jsonfile import DataFileError, read_json, write_json
from helpers.base.paths import LOADCELL_CALIBRATION, repo_path
from helpers.paper.hardware import ADC_MAX, MM_PER_STEP

if TYPE_CHECKING:  # the recordings are read by their owner; here they are only a type
    from helpers.recordings import Recording

__all__ = [
    "LoadCellCalibration",
    "UNCALIBRATED",
    "CalibrationFit",
    "fit_calibration",
    "save_calibration",
    "load_calibration",
]

MISSING_HINT = "record it with `python -m helpers record calibration` (add --ports for hardware)"


@dataclass(frozen=True)
class LoadCellCalibration:
    """What turns a recording's counts and steps into newtons and millimetres (a recording's ``calibration``).

    Attributes
    ----------
    newtons_per_count : float
        Slope, N per ADC count (> 0).
    offset_counts : float
        ADC counts at zero tension.
    mm_per_step : float
        Cable travel per motor step, mm.
    origin : str
        Where it came from (a file under ``data/`` or a note such as ``uncalibrated``).
    source : str or None
        ``"hardware"`` or ``"virtual-rig"``: the kind of rig the calibration was recorded on.
    """

    newtons_per_count: float
    offset_counts: float
    mm_per_step: float = MM_PER_STEP
    origin: str = ""
    source: str | None = None

    def __post_init__(self) -> None:
        for name in ("newtons_per_count", "offset_counts", "mm_per_step"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise ValueError(f"load-cell calibration: {name} must be a finite number, got {value!r}")
        if self.newtons_per_count <= 0 or self.mm_per_step <= 0:
            raise ValueError("load-cell calibration: newtons_per_count and mm_per_step must be > 0")

    def to_dict(self) -> dict[str, Any]:
        """The ``calibration`` entry of a recording's metadata."""
        out: dict[str, Any] = {
            "newtons_per_count": float(self.newtons_per_count),
            "offset_counts": float(self.offset_counts),
            "mm_per_step": float(self.mm_per_step),
            "origin": self.origin,
        }
        if self.source is not None:
            out["source"] = self.source
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> LoadCellCalibration:
        """Read a recording's ``calibration`` entry (the keys of :meth:`to_dict`)."""
        return cls(
            newtons_per_count=data["newtons_per_count"],
            offset_counts=data["offset_counts"],
            mm_per_step=data.get("mm_per_step", MM_PER_STEP),
            origin=str(data.get("origin", "")),
            source=data.get("source"),
        )


UNCALIBRATED = LoadCellCalibration(1.0, 0.0, MM_PER_STEP, "uncalibrated: tension_n equals adc counts")
"""Explicitly no calibration (recording the calibration itself, benchmarks): tension in counts."""


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
        if adc.max() >= ADC_MAX:
            raise ValueError(f"{r.name}: the ADC saturates ({ADC_MAX} counts) at {sc['load_n']:.2f} N")
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
        coef, cov = np.polyfit(x, y, 1, cov=True)
        slope, intercept = float(coef[0]), float(coef[1])
        slope_se, intercept_se = (float(v) for v in np.sqrt(np.clip(np.diag(cov), 0.0, None)))
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
    fit: CalibrationFit, recs: Sequence[Recording], path: str | os.PathLike = LOADCELL_CALIBRATION
) -> Path:
    """Write the calibration that every run reads (:func:`load_calibration`), with its provenance.

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
    return write_json(path, data)


def load_calibration(path: str | os.PathLike = LOADCELL_CALIBRATION) -> LoadCellCalibration:
    """Read the load-cell calibration (``data/calibration/calibration.json`` by default).

    Raises
    ------
    helpers.base.jsonfile.MissingDataError
        If there is none yet (the message says how to record it).
    helpers.base.jsonfile.DataFileError
        If the file is malformed (a key missing, a value of the wrong type or range).
    """
    p = Path(path)
    data = read_json(p, "load-cell calibration", MISSING_HINT)
    source = data.get("source")
    try:
        return LoadCellCalibration(
            newtons_per_count=data["newtons_per_count"],
            offset_counts=data["offset_counts"],
            mm_per_step=data.get("mm_per_step", MM_PER_STEP),
            origin=repo_path(p),
            source=(source.get("kind", "unknown") if isinstance(source, dict) else "unknown"),
        )
    except KeyError as exc:
        raise DataFileError(f"{p}: the load-cell calibration lacks {exc.args[0]!r}") from None
    except ValueError as exc:
        raise DataFileError(f"{p}: {exc}") from None
