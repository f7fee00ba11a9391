"""Recording with the motor idle: the load cell under known loads (its calibration), the noise floor.

:func:`record_static` records ``duration_s`` of device time from the DAQ while the stepper is not touched, in
the same guard as every run of a :class:`helpers.rig.Rig` (an interrupt or an error saves what was recorded,
marked ``aborted``). :func:`record_calibration` is the load-cell calibration's procedure (hardware: detach the
cable from the load cell, hang each known mass from it in turn; the virtual rig: its VIRTUAL calibration
fixture hangs them, ``VirtualWorld.hang_load``, and the recordings say ``virtual-rig``). The fit and its file
are :mod:`helpers.paper.calibration`'s.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from helpers import recordings
from helpers.base.paths import LOADCELL_CALIBRATION
from helpers.recordings import Recording
from helpers.rig.driver import Rig, RunState
from helpers.rig.safety import SafetyError

G_STANDARD = 9.80665
"""Standard gravity, m/s^2 (weight of a hung mass)."""

PAPER_MASSES_KG = (0.0, 0.2, 0.5, 1.0, 1.5, 1.9)
"""The paper's rig's masses (kg): 0 to 18.6 N, the range of Table II's tensions (up to 17.7 N), on 20 N."""

PAPER_SPAN_N = 20.0
"""The load-cell span the paper's masses were chosen for (``rigs/paper.toml``'s ``load_cell_range_n``)."""

CALIBRATION_DIR = LOADCELL_CALIBRATION.parent
"""Where the calibration recordings go (``load_<grams>g``), beside the calibration file."""


def calibration_masses_kg(load_cell_range_n: float) -> tuple[float, ...]:
    """Masses to hang on a load cell of this span (kg): the paper's, scaled down to a smaller span (to 1 g).

    A cell of 20 N or more gets the paper's masses; a smaller one the same fractions of its span (a 10 N
    cell: 0 to 0.95 kg, 9.3 N), so no load drives the loop into saturation.
    """
    if load_cell_range_n >= PAPER_SPAN_N:
        return PAPER_MASSES_KG
    return tuple(round(m * load_cell_range_n / PAPER_SPAN_N, 3) for m in PAPER_MASSES_KG)


def record_static(
    rig: Rig, duration_s: float, scenario: dict[str, Any], *, path: str | os.PathLike, rate_hz: int = 1000,
    replace: bool = False,
) -> Recording:  # fmt: skip
    """Record ``duration_s`` of device time with the motor idle (load-cell calibration, noise floor).

    Parameters
    ----------
    rig : helpers.rig.Rig
        A connected rig (hardware or virtual).
    duration_s : float
        Device seconds to record (0 < duration <= the rig's ``max_programme_s``).
    scenario : dict
        Scenario metadata (e.g. ``{"kind": "calibration", "load_n": 4.9}``).
    path : path-like
        Where to save.
    rate_hz, replace
        As :meth:`Rig.run`'s.
    """
    longest = rig.rig.hardware.max_programme_s
    if type(duration_s) not in (int, float) or not math.isfinite(duration_s) or not 0 < duration_s <= longest:
        raise SafetyError(f"duration must be within (0, {longest:.0f}] s, got {duration_s!r}")
    rig._check_run(rate_hz, None, 0.0)

    def body(state: RunState) -> None:
        rig.daq.check_reset()
        rig.daq.command("STOP")  # a stream left running by an earlier session stops (OK STOP 0 when idle)
        rig._start(rate_hz, [(0, 0)] * rig.n)  # the motor is idle: no step count may change
        # samples from the first one on (its device time less a period: the run's start) for duration_s
        rig._until_done(state, lambda now: (0, ()), rate_hz, duration_s, duration_s, False, stepper=False)
        state.finished = True
        rig.daq.command("STOP")

    with recordings.reserve(path, replace) as target:  # a second run to this name is refused now
        return rig._guarded(body, dict(scenario), target, rate_hz, replace, (0,) * rig.n, stepper_used=False)


def record_calibration(
    rig: Rig, masses_kg: Sequence[float] | None = None, duration_s: float = 1.0,
    folder: str | os.PathLike = CALIBRATION_DIR, rate_hz: int = 1000, replace: bool = False,
) -> list[Recording]:  # fmt: skip
    """Record ``duration_s`` of counts under each known mass (tendon 1's load cell).

    Parameters
    ----------
    rig : helpers.rig.Rig
        Connected rig (the stepper is not used).
    masses_kg : sequence of float, optional
        The masses, kg (default :func:`calibration_masses_kg` of the rig's load cell).
    duration_s : float
        Device seconds per mass.
    folder : path-like
        Where the recordings go (``load_<grams>g.csv/json``).
    rate_hz : int
        DAQ sample rate.
    replace : bool
        Replace earlier calibration recordings of the same loads.
    """
    if masses_kg is None:
        masses_kg = calibration_masses_kg(rig.rig.tendons[0].load_cell_range_n)
    world, virtual = rig.world, rig.source["kind"] == "virtual-rig"  # in-process, or the pty server's
    out = []
    try:
        for m in masses_kg:
            if not np.isfinite(m) or m < 0:
                raise ValueError(f"masses must be finite and >= 0 kg, got {m}")
            load = float(m) * G_STANDARD
            if world is not None:
                world.hang_load(load)
            else:  # hardware: the user hangs it, and says so with Enter
                input(f"Hang {m:.3f} kg ({load:.3f} N) from the load cell, then press Enter")
            scenario = {
                "kind": "calibration", "mass_kg": float(m), "load_n": load, "g_m_s2": G_STANDARD,
                "fixture": "VIRTUAL known load (simulated)" if virtual else "hung mass",
            }  # fmt: skip
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
