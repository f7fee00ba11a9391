"""Recording the load-cell calibration: the ADC counts under known loads, with the motor idle.

Procedure (hardware): detach the cable from the load cell, hang each known mass from it in turn, and record
``duration_s`` seconds of samples per mass. On the virtual rig the same code path runs, and the loads are hung
by the VIRTUAL calibration fixture (``VirtualWorld.hang_load`` of :mod:`helpers.virtual.emulator.world`); such
recordings say ``virtual-rig`` in their metadata. The fit and the file are :mod:`helpers.paper.calibration`'s.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from helpers import recordings
from helpers.base.paths import LOADCELL_CALIBRATION
from helpers.paper import hardware
from helpers.recordings import Recording
from helpers.rig.static import record_static

G_STANDARD = 9.80665
"""Standard gravity, m/s^2 (weight of a hung mass)."""

PAPER_MASSES_KG = (0.0, 0.2, 0.5, 1.0, 1.5, 1.9)
"""The paper's rig's masses (kg): 0 to 18.6 N, the range of Table II's tensions (up to 17.7 N), on 20 N."""

PAPER_SPAN_N = 20.0
"""The load-cell span the paper's masses were chosen for (``rigs/paper.toml``'s ``load_cell_range_n``)."""


def calibration_masses_kg(load_cell_range_n: float) -> tuple[float, ...]:
    """Masses to hang on a load cell of this span (kg): the paper's, scaled down to a smaller span (to 1 g).

    A cell of 20 N or more gets the paper's masses; a smaller one the same fractions of its span (a 10 N
    cell: 0 to 0.95 kg, 9.3 N), so no load drives the loop into saturation.
    """
    if load_cell_range_n >= PAPER_SPAN_N:
        return PAPER_MASSES_KG
    scale = load_cell_range_n / PAPER_SPAN_N
    return tuple(round(m * scale, 3) for m in PAPER_MASSES_KG)


CALIBRATION_MASSES_KG = calibration_masses_kg(hardware.RIG.tendons[0].load_cell_range_n)
"""Masses hung on the load cell (kg) of the rig the host runs: the paper's 0 to 18.6 N on its rig."""

CALIBRATION_DIR = LOADCELL_CALIBRATION.parent
"""Where the calibration recordings go (``load_<grams>g``), beside the calibration file."""


def record_calibration(
    rig: Any,
    masses_kg: Sequence[float] = CALIBRATION_MASSES_KG,
    duration_s: float = 1.0,
    folder: str | os.PathLike = CALIBRATION_DIR,
    prompt: Callable[[str], object] | None = input,
    rate_hz: int = 1000,
    replace: bool = False,
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
    replace : bool
        Replace earlier calibration recordings of the same loads.

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
            out.append(record_static(rig, duration_s, scenario, path=path, rate_hz=rate_hz, replace=replace))
    finally:
        if world is not None:
            world.hang_load(None)
    return out


def load_calibration_recordings(folder: str | os.PathLike = CALIBRATION_DIR) -> list[Recording]:
    """Load every calibration recording in ``folder`` (sorted by load)."""
    recs = [recordings.load(p) for p in sorted(Path(folder).glob("load_*.csv"))]
    return sorted(recs, key=lambda r: r.meta["scenario"]["load_n"])
