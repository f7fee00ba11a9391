"""Recording with the motor idle: the load cell under known loads, the noise floor, the serial link's rate.

:func:`record_static` records ``duration_s`` of device time from the DAQ while the stepper is not touched, in
the same guard as every run of a :class:`helpers.rig.Rig` (an interrupt or an error saves what was recorded,
marked ``aborted``). The load-cell calibration (:mod:`helpers.rig.loadcell`) and the serial benchmark use it;
the paper's experiments do not.
"""

from __future__ import annotations

import math
import os
from typing import Any

from helpers.paper.hardware import MAX_PROGRAMME_S
from helpers.recordings import Recording, reserve
from helpers.rig.boards import BoardTimeout
from helpers.rig.experiment import Rig, _check_rate, _DeviceTimeBar, _RunState
from helpers.rig.safety import SafetyError


def record_static(
    rig: Rig,
    duration_s: float,
    scenario: dict[str, Any],
    path: str | os.PathLike | None = None,
    rate_hz: int = 1000,
    silence_timeout: float = 2.0,
    progress: bool = False,
    replace: bool = False,
) -> Recording:
    """Record ``duration_s`` of device time with the motor idle (load-cell calibration, noise floor).

    Parameters
    ----------
    rig : helpers.rig.Rig
        A connected rig (hardware or virtual).
    duration_s : float
        Device seconds to record (0 < duration <= ``MAX_PROGRAMME_S``).
    scenario : dict
        Scenario metadata (e.g. ``{"kind": "calibration", "load_n": 4.9}``).
    path : path-like, optional
        Where to save.
    rate_hz : int
        DAQ sample rate.
    silence_timeout : float
        Seconds without a sample after which the DAQ counts as not answering.
    progress : bool
        Show a tqdm bar.
    replace : bool
        Replace a recording of the same name.
    """
    if (
        not isinstance(duration_s, int | float)
        or not math.isfinite(duration_s)
        or not 0 < duration_s <= MAX_PROGRAMME_S
    ):
        raise SafetyError(f"duration must be within (0, {MAX_PROGRAMME_S:.0f}] s, got {duration_s!r}")
    _check_rate(rate_hz)
    daq = rig.daq

    def body(state: _RunState) -> None:
        daq.check_reset()
        daq.stop()  # a stream left running by an earlier session stops (OK STOP 0 when idle)
        daq.set_rate(rate_hz)
        daq.start()
        daq.expect_steps(0, 0)  # the motor is idle
        bar = _DeviceTimeBar(duration_s, progress, desc=None)
        silence = daq.waiter(silence_timeout)
        try:
            while True:
                before = len(daq.rows)
                daq.pump()
                daq.check_reset()
                rows = daq.rows
                if len(rows) == before:
                    silence.idle(daq.port.timeout or 0.0)
                    if silence.expired:
                        raise BoardTimeout(
                            f"the daq board sent no sample for {silence_timeout:.1f} s (it stopped answering)"
                        )
                    continue
                silence = daq.waiter(silence_timeout)
                if state.t_go_us is None:
                    state.t_go_us = rows[0][1] - round(1e6 / rate_hz)
                bar.show((rows[-1][1] - state.t_go_us) / 1e6)
                if rows[-1][1] - state.t_go_us >= duration_s * 1e6:
                    break
        finally:
            bar.close()
        state.finished = True
        daq.stop()

    target = rig._target(path)
    with reserve(target, replace):  # a second run to this name is refused now, not after this one
        return rig._guarded(body, dict(scenario), target, rate_hz, stepper_used=False, replace=replace)
