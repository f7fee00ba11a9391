"""The host drivers of helpers.rig talk to the firmware (in simavr) through the harness's pseudo-terminals.

Both boards run in one harness process, in lockstep, paced to real time as the hardware would be, and wired as
on the bench: the Uno's STEP (D5) and DIR (D6) go to the Mega's D2 and D4, so the DAQ counts the steps the
stepper firmware really issues. No physics is simulated: the ADC input is 0 V.
"""

from __future__ import annotations

import time

import fwsim
import numpy as np
import pytest

pytestmark = pytest.mark.firmware

rig = pytest.importorskip("helpers.rig", reason="helpers.rig (the host drivers) is not importable")
programmes = pytest.importorskip("helpers.board.programmes")

READY_S = 60.0
"""Deadline (s) for a board's greeting or reply: the waits end on readiness, so only a failure takes it
(simavr runs slower than real time on a busy machine)."""


@pytest.fixture(scope="module")
def rig_paths(firmware_build):
    proc, daq_path, stepper_path = fwsim.rig_process(pace=1.0)
    try:
        yield daq_path, stepper_path
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=5)
        except Exception:  # noqa: BLE001 - make sure it is gone
            proc.kill()
            proc.wait()


def test_daq_driver_streams_from_the_firmware(rig_paths):
    daq = rig.DaqBoard.open(rig_paths[0], timeout=READY_S, hello_timeout=READY_S)
    try:
        assert daq.version == "2.3.0+481e87e3"
        assert daq.set_rate(500) == 500
        daq.zero()
        assert daq.start() == 500
        rows = []
        deadline = time.monotonic() + 30.0  # the simulation may run slower than real time on a busy machine
        while len(rows) < 200 and time.monotonic() < deadline:  # 0.4 s of device time
            rows += daq.read_rows()
        n = daq.stop()
        rows += daq.take_rows()
        assert n == len(rows) >= 200
        seq = np.array([r[0] for r in rows])
        np.testing.assert_array_equal(seq, np.arange(n))
        t_us = np.array([r[1] for r in rows])
        assert np.all(np.abs(np.diff(t_us) - 2000) <= 4)  # 500 Hz on the board's clock
        stats = daq.stats
        assert (stats.dropped, stats.overruns, stats.corrupted) == (0, 0, 0)
        with pytest.raises(rig.CommandRefused) as err:
            daq.command("RATE 5")  # bypasses the driver's own range check: the firmware refuses
        assert err.value.code == "RANGE"
        assert daq.ping() == "2.3.0+481e87e3"
    finally:
        daq.close()


def test_stepper_driver_runs_a_programme_on_the_firmware(rig_paths):
    stepper = rig.StepperBoard.open(rig_paths[1], timeout=READY_S, hello_timeout=READY_S)
    try:
        assert stepper.version == "2.3.0+481e87e3"
        prog = programmes.Programme(
            (
                programmes.Dwell(50),
                programmes.Segment(1, 40, 1276),
                programmes.Dwell(100),
                programmes.Segment(-1, 15, 851),
            )
        )
        start = stepper.position()
        assert stepper.load(prog, start_position=start) == 4
        stepper.enable(True)
        assert stepper.go() == 4
        deadline = time.monotonic() + 30.0
        while stepper.done_position is None and time.monotonic() < deadline:
            stepper.pump()
        assert stepper.done_position == start + 25
        assert stepper.position() == start + 25
        with pytest.raises(rig.CommandRefused) as err:
            stepper.command("SEG 1 10 100")  # 2.5 m/s: refused by the firmware itself
        assert err.value.code == "RANGE"
        assert stepper.abort() == start + 25
        with pytest.raises(rig.CommandRefused) as err:
            stepper.go()  # ABORT disabled the driver
        assert err.value.code == "STATE"
    finally:
        stepper.close()


def test_rig_records_the_steps_the_stepper_firmware_issues(rig_paths, tmp_path):
    daq = rig.DaqBoard.open(rig_paths[0], timeout=READY_S, hello_timeout=READY_S)
    stepper = rig.StepperBoard.open(rig_paths[1], timeout=READY_S, hello_timeout=READY_S)
    the_rig = rig.Rig(
        daq,
        stepper,
        calibration={
            "newtons_per_count": 0.01,
            "offset_counts": 0.0,
            "mm_per_step": 0.25525,
            "origin": "test",
        },
        source={"kind": "simavr-firmware", "note": "both firmwares in simavr, no physics"},
    )
    try:
        n_up, iv, hold_ms = 10, 1276, 200
        prog = programmes.Programme(
            (
                programmes.Dwell(100),
                programmes.Segment(1, n_up, iv),
                programmes.Dwell(hold_ms),
                programmes.Segment(-1, n_up, iv),
                programmes.Dwell(100),
            )
        )
        rec = the_rig.run(prog, path=tmp_path / "run", rate_hz=1000, progress=False)
        meta = rec.meta
        assert meta["status"] == "complete"
        assert meta["firmware"] == {"daq": "2.3.0+481e87e3", "stepper": "2.3.0+481e87e3"}
        assert meta["counts"]["dropped"] == 0 and meta["counts"]["overruns"] == 0
        frame = rec.frame
        assert len(frame) >= prog.duration_s * 1000 * 0.95
        steps = frame["steps"].to_numpy()
        t_us = frame["t_us"].to_numpy()
        assert steps.min() == 0 and steps.max() == n_up and steps[-1] == 0
        assert np.all(np.abs(np.diff(steps)) <= 1), "at most one step per 1 ms sample at 1276 us per step"
        # the motion as the DAQ saw it, on its own clock: up move, hold, down move
        t_first_up = t_us[np.argmax(steps >= 1)]
        t_top = t_us[np.argmax(steps >= n_up)]
        t_first_down = t_us[np.argmax((steps < n_up) & (t_us > t_top))]
        up_us, hold_us = (n_up - 1) * iv, hold_ms * 1000 + iv
        assert abs((t_top - t_first_up) - up_us) <= 1000 + 8
        assert abs((t_first_down - t_top) - hold_us) <= 1000 + 8
        assert meta["done_position"] is not None
    finally:
        the_rig.close()
