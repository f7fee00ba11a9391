"""Recordings of a rig with several tendons: ``schema_version`` 3 (``docs/recording_format.md``).

The CSV holds ``seq``, ``t_us``, then one ADC column per tendon (``adc_0`` .. ``adc_{n-1}``, the DAQ's
channels) and one step column per tendon (``steps_0`` .. ``steps_{n-1}``, each axis's position from zero).
The metadata is version 2's with ``tendons`` (n >= 2) and the calibration per tendon: ``calibration.
newtons_per_count``, ``offset_counts`` and ``mm_per_step`` are lists of n numbers; ``rig`` (the rig file,
whose tendon count must be n) is required. Derived on load: ``t_s``, and per tendon ``tension_n_i =
(adc_i - offset_counts[i]) * newtons_per_count[i]`` and ``cable_mm_i = steps_i * mm_per_step[i]``.

Optional, from the virtual rig only: the tip's position where the twin provides it, ``tip_x_um``,
``tip_y_um``, ``tip_z_um`` (integer micrometres, the spatial twin's tip node in the clamp frame at channel 0's
instant of each sample), present exactly when the metadata has ``tip`` (an object naming its origin); derived
on load: ``tip_x_mm``, ``tip_y_mm``, ``tip_z_mm``. Recordings from hardware have neither and load unchanged.

A one-tendon recording stays version 2 (``seq,t_us,adc,steps``), written and read exactly as before.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from helpers.base.validate import is_finite_number, is_int

TENDON_SCHEMA_VERSION = 3
"""The metadata version of a recording with several tendons."""

MAX_TENDONS = 4

TIP_COLUMNS = ("tip_x_um", "tip_y_um", "tip_z_um")
"""The optional twin-provided tip columns (integer micrometres), written when the metadata has ``tip``."""

TIP_MM_COLUMNS = ("tip_x_mm", "tip_y_mm", "tip_z_mm")
"""The tip's position in millimetres, derived on load from :data:`TIP_COLUMNS`."""


def tendon_columns(n: int) -> tuple[str, ...]:
    """The CSV's columns of a recording of ``n`` tendons, in order."""
    return ("seq", "t_us") + tuple(f"adc_{i}" for i in range(n)) + tuple(f"steps_{i}" for i in range(n))


def recorded_columns(meta: dict[str, Any]) -> tuple[str, ...]:
    """The CSV's columns of a version-3 recording with this metadata (the tip's when ``meta`` has ``tip``)."""
    return tendon_columns(tendon_count(meta)) + (TIP_COLUMNS if "tip" in meta else ())


def tendon_count(meta: dict[str, Any]) -> int:
    """``meta["tendons"]`` (1 for a recording of version 1 or 2)."""
    return int(meta.get("tendons", 1)) if meta.get("schema_version") == TENDON_SCHEMA_VERSION else 1


def _numbers(value: Any, n: int, positive: bool) -> bool:
    return (
        isinstance(value, list)
        and len(value) == n
        and all(is_finite_number(x) for x in value)
        and (not positive or all(x > 0 for x in value))
    )


def tendon_meta_problem(meta: dict[str, Any]) -> str | None:
    """What is wrong with the version-3 keys of ``meta`` (``tendons``, the calibration's lists), or None."""
    n = meta.get("tendons")
    if not (is_int(n) and 2 <= n <= MAX_TENDONS):
        return f"tendons: expected an integer 2-{MAX_TENDONS}, got {n!r}"
    cal = meta.get("calibration")
    if not isinstance(cal, dict):
        return "calibration: expected an object"
    for key, positive in (("newtons_per_count", True), ("offset_counts", False), ("mm_per_step", True)):
        if key not in cal:
            return f"calibration.{key}: missing"
        if not _numbers(cal[key], n, positive):
            need = "positive " if positive else ""
            return f"calibration.{key}: expected a list of {n} {need}finite numbers (one per tendon)"
    if "rig" not in meta:
        return "rig: missing (a recording of several tendons keeps its rig file)"
    if "tip" in meta and not isinstance(meta["tip"], dict):
        return "tip: expected an object (the twin-provided tip columns' origin)"
    return None


def derive_tendon_columns(frame: pd.DataFrame, meta: dict[str, Any]) -> pd.DataFrame:
    """The raw columns of ``frame`` with ``t_s`` and every tendon's ``tension_n_i`` and ``cable_mm_i``."""
    n = tendon_count(meta)
    cal = meta["calibration"]
    out = frame.loc[:, list(recorded_columns(meta))].copy()
    t = out["t_us"].to_numpy(dtype=np.int64)
    out["t_s"] = (t - t[0]) * 1e-6 if len(t) else np.zeros(0)
    for i in range(n):
        adc = out[f"adc_{i}"].to_numpy(dtype=float)
        out[f"tension_n_{i}"] = (adc - float(cal["offset_counts"][i])) * float(cal["newtons_per_count"][i])
    for i in range(n):
        out[f"cable_mm_{i}"] = out[f"steps_{i}"].to_numpy(float) * float(cal["mm_per_step"][i])
    if "tip" in meta:
        for um, mm in zip(TIP_COLUMNS, TIP_MM_COLUMNS, strict=True):
            out[mm] = out[um].to_numpy(float) * 1e-3
    return out

