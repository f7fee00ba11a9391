"""Recordings of a rig with several tendons: ``schema_version`` 3 (``docs/recording_format.md``).

The CSV holds ``seq``, ``t_us``, then one ADC column per tendon (``adc_0`` .. ``adc_{n-1}``, the DAQ's
channels) and one step column per tendon (``steps_0`` .. ``steps_{n-1}``, each axis's position from zero).
The metadata is version 2's with ``tendons`` (n >= 2) and the calibration per tendon: ``calibration.
newtons_per_count``, ``offset_counts`` and ``mm_per_step`` are lists of n numbers; ``rig`` (the rig file,
whose tendon count must be n) is required. Derived on load: ``t_s``, and per tendon ``tension_n_i =
(adc_i - offset_counts[i]) * newtons_per_count[i]`` and ``cable_mm_i = steps_i * mm_per_step[i]``. The keys
are checked and the columns derived by :mod:`helpers.recordings.format` with those of one tendon.

Optional, from the virtual rig only: the tip's position where the twin provides it, ``tip_x_um``,
``tip_y_um``, ``tip_z_um`` (integer micrometres, the spatial twin's tip node in the clamp frame at channel 0's
instant of each sample), present exactly when the metadata has ``tip`` (an object naming its origin); derived
on load: ``tip_x_mm``, ``tip_y_mm``, ``tip_z_mm``. Recordings from hardware have neither and load unchanged.

A one-tendon recording stays version 2 (``seq,t_us,adc,steps``), written and read exactly as before.
"""

from __future__ import annotations

from typing import Any

TENDON_SCHEMA_VERSION = 3
"""The metadata version of a recording with several tendons."""

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
