"""Counts to newtons: the load-cell calibration every run records with, and the reader of its file.

A run (:class:`helpers.rig.Rig`) needs only this: :class:`LoadCellCalibration` and :func:`load_calibration`,
which reads ``data/calibration/calibration.json`` (:data:`helpers.base.paths.LOADCELL_CALIBRATION`). The fit
of counts against known loads, the writer of that file, and explicitly no calibration (``uncalibrated``, for
recording the calibration itself) are :mod:`helpers.paper.calibration`'s.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from helpers.base.jsonfile import DataFileError, read_json
from helpers.base.paths import LOADCELL_CALIBRATION, repo_path
from helpers.rigfile import default_rig, derived

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
    mm_per_step: float
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
        """Read a recording's ``calibration`` entry (the keys of :meth:`to_dict`).

        An entry without ``mm_per_step`` predates rig files: the paper's rig made it (its 0.25525 mm).
        """
        mm = data["mm_per_step"] if "mm_per_step" in data else derived(default_rig()).mm_per_step[0]
        return cls(
            newtons_per_count=data["newtons_per_count"],
            offset_counts=data["offset_counts"],
            mm_per_step=mm,
            origin=str(data.get("origin", "")),
            source=data.get("source"),
        )


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
    kind = source.get("kind", "unknown") if isinstance(source, dict) else "unknown"
    try:
        return LoadCellCalibration.from_dict({**data, "origin": repo_path(p), "source": kind})
    except KeyError as exc:
        raise DataFileError(f"{p}: the load-cell calibration lacks {exc.args[0]!r}") from None
    except ValueError as exc:
        raise DataFileError(f"{p}: {exc}") from None
