"""What a recording is: the raw columns as stored, the metadata's versions, and one frame shape on load.

The CSV holds the raw columns exactly as the DAQ board reports them (``docs/recording_format.md``):
``seq``, ``t_us`` (device microseconds, unwrapped), then per tendon ``i`` (the boards' 0-based channel and
axis) ``adc_i`` (ADC counts) and ``steps_i`` (the motor's position in steps), and, from the in-process
virtual rig only, the twin's tip (``tip_x_um`` ..). Versions 1 and 2 (one tendon) named the two columns
``adc`` and ``steps``. Whatever the version, a recording loads into one frame shape (:func:`derive_columns`):

- ``seq``, ``t_us``; for every tendon ``adc_i``, ``steps_i`` and, derived from the metadata's calibration,
  ``tension_n_i = (adc_i - offset_counts[i]) * newtons_per_count[i]`` and ``cable_mm_i = steps_i *
  mm_per_step[i]``; ``t_s``, seconds from the first sample; the tip in mm where it was recorded;
- for a recording of one tendon also ``adc``, ``steps``, ``tension_n``, ``cable_mm`` (tendon 0's), the names
  the paper's analyses read.

The metadata is checked key by key by :mod:`helpers.recordings.checks`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from helpers.rigfile.recorded import calibration_of

VERSION = 4
"""The version :func:`helpers.recordings.from_samples` writes: one layout for 1 to 4 tendons."""

READ_VERSIONS = (1, 2, 3, 4)
"""Versions :func:`helpers.recordings.load` reads (1: before rig files, the paper's rig; 2: with the rig
file; 3: several tendons; 4: 1 to 4 tendons); others are refused."""

RAW_COLUMNS = ("seq", "t_us", "adc", "steps")
"""The CSV's columns of versions 1 and 2, in order."""

ONE_TENDON = ("adc", "steps", "tension_n", "cable_mm")
"""A one-tendon recording's frame also has these names for tendon 0's columns (the paper's analyses)."""

TIP_COLUMNS = ("tip_x_um", "tip_y_um", "tip_z_um")
"""The optional twin-provided tip columns (integer micrometres), stored when the metadata has ``tip``."""

TIP_MM_COLUMNS = ("tip_x_mm", "tip_y_mm", "tip_z_mm")
"""The tip's position in millimetres, derived on load from :data:`TIP_COLUMNS`."""


class RecordingError(ValueError):
    """A recording could not be loaded or saved; the message names the file, the field and the problem."""


@dataclass
class Recording:
    """One run: the samples (raw + derived columns) and the metadata.

    Attributes
    ----------
    frame : pandas.DataFrame
        The raw columns (int64) and, after :meth:`derive`, the derived ones (:func:`derive_columns`).
    meta : dict
        The JSON metadata (``docs/recording_format.md``).
    path : pathlib.Path or None
        The CSV's path once saved or loaded.
    """

    frame: pd.DataFrame
    meta: dict[str, Any]
    path: Path | None = None

    @property
    def name(self) -> str:
        """The file stem, or ``"<unsaved>"``."""
        return self.path.stem if self.path is not None else "<unsaved>"

    @property
    def status(self) -> str:
        """``"complete"``, ``"aborted"`` or ``"deviated"``."""
        return str(self.meta.get("status"))

    @property
    def tendons(self) -> int:
        """Number of tendons recorded (1 for versions 1 and 2)."""
        return tendon_count(self.meta)

    def derive(self) -> Recording:
        """Give the frame the one shape of every version (:func:`derive_columns`); return ``self``."""
        self.frame = derive_columns(self.frame, self.meta)
        return self

    def __repr__(self) -> str:
        return f"Recording({self.name!r}, {len(self.frame)} samples, {self.status})"


def tendon_count(meta: dict[str, Any]) -> int:
    """``meta["tendons"]`` (1 for a recording of version 1 or 2)."""
    return int(meta.get("tendons", 1)) if meta.get("schema_version") in (3, 4) else 1


def tendon_columns(n: int) -> tuple[str, ...]:
    """The CSV's columns of ``n`` tendons (versions 3 and 4), in order, without the tip's."""
    return ("seq", "t_us") + tuple(f"adc_{i}" for i in range(n)) + tuple(f"steps_{i}" for i in range(n))


def raw_columns(meta: dict[str, Any]) -> tuple[str, ...]:
    """The CSV's columns of a recording with this metadata (the tip's when ``meta`` has ``tip``)."""
    if meta.get("schema_version") in (1, 2):
        return RAW_COLUMNS
    return tendon_columns(tendon_count(meta)) + (TIP_COLUMNS if "tip" in meta else ())


def counts_to_newtons(adc: np.ndarray, newtons_per_count: float, offset_counts: float) -> np.ndarray:
    """Tension in N from ADC counts, ``(adc - offset_counts) * newtons_per_count`` (load-cell calibration)."""
    return (np.asarray(adc, dtype=float) - float(offset_counts)) * float(newtons_per_count)


def derive_columns(frame: pd.DataFrame, meta: dict[str, Any]) -> pd.DataFrame:
    """The one frame shape of every version, from the raw columns of ``frame`` and ``meta``'s calibration.

    ``seq``, ``t_us``, every tendon's ``adc_i`` and ``steps_i``, the tip's raw columns (where recorded),
    ``t_s``, every tendon's ``tension_n_i`` and ``cable_mm_i``, the tip in mm; for one tendon also ``adc``,
    ``steps``, ``tension_n`` and ``cable_mm``.
    """
    n = tendon_count(meta)
    raw = frame.loc[:, list(raw_columns(meta))].rename(columns={"adc": "adc_0", "steps": "steps_0"})
    cols = {c: raw[c].to_numpy(np.int64) for c in raw.columns}
    t = cols["t_us"]
    cols["t_s"] = (t - t[0]) * 1e-6 if len(t) else np.zeros(0)
    cal = [calibration_of(meta, i) for i in range(n)]
    for i, c in enumerate(cal):
        cols[f"tension_n_{i}"] = counts_to_newtons(
            cols[f"adc_{i}"], c["newtons_per_count"], c["offset_counts"]
        )
    for i, c in enumerate(cal):
        cols[f"cable_mm_{i}"] = cols[f"steps_{i}"] * float(c["mm_per_step"])
    for um, mm in zip(TIP_COLUMNS, TIP_MM_COLUMNS, strict=True):
        if um in cols:
            cols[mm] = cols[um] * 1e-3
    if n == 1:
        cols.update({name: cols[f"{name}_0"] for name in ONE_TENDON})
    return pd.DataFrame(cols, index=raw.index)
