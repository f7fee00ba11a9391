"""The host driver of helpers.rig talks to the firmware (in simavr) through the harness's pseudo-terminals.

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

rig = pytest.importorskip("helpers.rig", reason="helpers.rig (the host driver) is not importable")
link = pytest.importorskip("helpers.rig.link")
rigfile = pytest.importorskip("helpers.rigfile")
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


def _link(path: str, kind: str):
    paper = rigfile.default_rig()
    return link.Link.open(path, kind, paper, getattr(paper.hardware, f"{kind}_baud"), READY_S, READY_S)


def test_the_link_streams_the_daq_firmwares_samples(rig_paths):
    daq = _link(rig_paths[0], "daq")
    try:
        assert daq.version == "2.3.0+481e87e3"
        assert daq.command("RATE 500") == "OK RATE 500"
        daq.command("ZERO")
        daq.parser.restart()  # the stream's counts start at START, as the driver's do
        assert daq.command("START") == "OK START 500"
        deadline = time.monotonic() + 30.0  # the simulation may run slower than real time on a busy machine
        while len(daq.rows) < 200 and time.monotonic() < deadline:  # 0.4 s of device time
            daq.read()
        n = link.ints(daq.command("STOP"))[0]
        rows = daq.rows
        assert n == len(rows) >= 200
        seq = np.array([r[0] for r in rows])
        np.testing.assert_array_equal(seq, np.arange(n))
        t_us = np.array([r[1] for r in rows])
        assert np.all(np.abs(np.diff(t_us) - 2000) <= 4)  # 500 Hz on the board's clock
        stats = daq.parser.stats
        assert (stats.dropped, stats.overruns, stats.corrupted) == (0, 0, 0)
        with pytest.raises(rig.CommandRefused) as err:
            daq.command("RATE 5")  # the firmware refuses
        assert err.value.code == "RANGE"
        assert daq.command("PING") == "PONG daq 2.3.0+481e87e3"
    finally:
        daq.close()


def test_the_link_runs_a_programme_on_the_stepper_firmware(rig_paths):
    stepper = _link(rig_paths[1], "stepper")
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
        start = link.ints(stepper.command("POS"))[0]
        assert stepper.send_all(prog.commands())[-1] == "OK SEG 4"
        stepper.command("EN 1")
        assert stepper.command("GO") == "OK GO 4"
        deadline = time.monotonic() + 30.0
        while stepper.done is None and time.monotonic() < deadline:
            stepper.read()
        assert stepper.done == (start + 25,)
        assert link.ints(stepper.command("POS")) == (start + 25,)
        with pytest.raises(rig.CommandRefused) as err:
            stepper.command("SEG 1 10 100")  # 2.5 m/s: refused by the firmware itself
        assert err.value.code == "RANGE"
        assert stepper.command("ABORT") == f"ABORTED {start + 25}"
        with pytest.raises(rig.CommandRefused) as err:
            stepper.command("GO")  # ABORT disabled the driver
        assert err.value.code == "STATE"
    finally:
        stepper.close()


def test_rig_records_the_steps_the_stepper_firmware_issues(rig_paths, tmp_path):
    calibration = {"newtons_per_count": 0.01, "offset_counts": 0.0, "mm_per_step": 0.25525, "origin": "test"}
    the_rig = rig.Rig(rig_paths, rigfile.default_rig(), calibration, timeout=READY_S, hello_timeout=READY_S,
                      silence_s=READY_S)  # fmt: skip  # simavr on a busy host may stall for seconds
    assert the_rig.source["kind"] == "hardware"  # pseudo-terminals that no serve-virtual-rig announced
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
        (start,) = the_rig.positions()  # where an earlier test left the stepper: the recording counts from it
        rec = the_rig.run(prog, path=tmp_path / "run", rate_hz=1000, progress=False)
        meta = rec.meta
        assert meta["status"] == "complete"
        assert meta["firmware"] == {"daq": "2.3.0+481e87e3", "stepper": "2.3.0+481e87e3"}
        assert meta["counts"]["dropped"] == 0 and meta["counts"]["overruns"] == 0
        frame = rec.frame
        assert len(frame) >= prog.duration_s * 1000 * 0.95
        steps = frame["steps"].to_numpy() - start
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
        assert meta["done_position"] == start
    finally:
        the_rig.close()
