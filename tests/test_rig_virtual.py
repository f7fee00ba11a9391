"""Rig.run on the in-process virtual rig (test-double plant): one board-timed programme -> one recording."""

from __future__ import annotations

import numpy as np
import pytest
from rig_fakes import (
    CALIBRATION,
    GAIN,
    K_N_PER_MM,
    MM_PER_STEP,  # the paper's cable per step, by hand
    OFFSET,
    PRETENSION_N,
    make_rig,
    make_world,
)

from helpers import recordings, rigfile
from helpers.board.programmes import Dwell, Programme, Segment, experiment_programme
from helpers.board.protocol import frame
from helpers.rig import Rig
from helpers.rig.ports import KNOWN_BOARDS, find_rig_ports
from helpers.rig.static import record_static

PROG = Programme((Dwell(100), Segment(1, 20, 1000), Dwell(200), Segment(-1, 20, 1000), Dwell(100)))


def test_run_records_the_whole_programme(tmp_path):
    rig, world = make_rig()
    rec = rig.run(PROG, scenario={"kind": "test"}, path=tmp_path / "g" / "r1", progress=False, tail_s=0.05)
    assert rec.status == "complete"
    back = recordings.load(tmp_path / "g" / "r1")
    f = back.frame
    assert back.meta["source"]["kind"] == "virtual-rig"
    assert back.meta["counts"] == {
        "samples": len(f), "dropped": 0, "corrupted": 0, "overruns": 0, "implausible": 0,
    }  # fmt: skip
    assert back.meta["firmware"] == {"daq": "2.3.0+481e87e3", "stepper": "2.3.0+481e87e3"}
    assert back.meta["scenario"]["programme"]["items"][1] == {
        "kind": "SEG",
        "direction": 1,
        "n_steps": 20,
        "interval_us": 1000,
    }
    # it recorded past the programme's end (0.44 s) plus the tail, and DONE arrived
    t_go = back.meta["t_go_us"]
    assert f["t_us"].iloc[-1] - t_go >= PROG.duration_us + 50_000
    assert back.meta["done_position"] == 0
    assert np.all(np.diff(f["seq"]) == 1) and np.all(np.diff(f["t_us"]) == 1000)
    # the steps column follows the programme's own step times (s from GO)
    st, sg = PROG.step_times()
    t_rel = (f["t_us"].to_numpy() - t_go) / 1e6
    expected = np.array([sg[st <= t + 1e-9].sum() for t in t_rel])
    np.testing.assert_array_equal(f["steps"].to_numpy(), expected)
    assert f["steps"].max() == 20
    # tension derived with the metadata's calibration equals the double's physics
    np.testing.assert_allclose(
        back.frame["tension_n"],
        np.rint(OFFSET + GAIN * (PRETENSION_N + K_N_PER_MM * MM_PER_STEP * expected)) / GAIN - OFFSET / GAIN,
    )
    # the stepper's driver was enabled for the run and disabled after it
    assert world.stepper.received[-1] == "EN 0" and not world.stepper.enabled
    assert not world.daq.streaming


def test_run_pulse_uses_the_paper_profile(tmp_path):
    rig, world = make_rig()
    rec = rig.run_pulse(200, 10, path=tmp_path / "p", progress=False, t_end_s=9.0)
    sc = rec.meta["scenario"]
    assert sc["kind"] == "pulse" and sc["system"] == "unshaped" and sc["x_f_mm"] == 10.0
    prog, _ = experiment_programme(200, 10, None, t_end=9.0)
    assert rec.frame["steps"].max() == prog.n_steps // 2
    t = rec.frame["t_s"].to_numpy() - rec.meta["t_go_s"]
    first_step = t[np.argmax(rec.frame["steps"].to_numpy() > 0)]
    assert first_step == pytest.approx(1.0 + 0.00128, abs=2e-3)  # the up move starts at 1 s from GO


def test_consecutive_runs_on_one_rig(tmp_path):
    rig, world = make_rig()
    for i in range(2):
        rec = rig.run(PROG, path=tmp_path / f"r{i}", progress=False)
        assert rec.status == "complete" and rec.frame["seq"].iloc[0] == 0


def test_sync_by_ping_when_the_board_does_not_reset_on_open():
    world = make_world()
    world.daq.take_output()
    world.stepper.take_output()
    rig = Rig(
        "virtual",
        rigfile.default_rig(),
        world=world.name,
        calibration=CALIBRATION,
        daq_options="&reset_on_open=0",
        stepper_options="&reset_on_open=0",
        timeout=0.5,
        hello_timeout=1.0,
    )
    assert rig.daq.version == "2.3.0+481e87e3" and world.daq.received[0] == "PING"
    assert world.daq.resets == 1  # only the reset at power-up


def test_static_recording_for_calibration(tmp_path):
    rig, world = make_rig()
    world.hang_load(2.5)
    rec = record_static(rig, 0.3, {"kind": "calibration", "load_n": 2.5}, path=tmp_path / "c", rate_hz=500)
    assert len(rec.frame) >= 150 and set(rec.frame["adc"]) == {round(OFFSET + GAIN * 2.5)}
    assert rec.meta["rate_hz"] == 500 and set(world.stepper.received) == {"PING", "CONFIG"}  # not touched


def test_discovery_by_vid_pid(monkeypatch):
    class Port:
        def __init__(self, device, vid, pid):
            self.device, self.vid, self.pid = device, vid, pid

    ports = [
        Port("/dev/ttyACM1", 0x2341, 0x0043),
        Port("/dev/ttyACM0", 0x2341, 0x0042),
        Port("/dev/ttyS0", None, None),
        Port("/dev/ttyUSB9", 0x0403, 0x6001),
    ]
    monkeypatch.setattr("serial.tools.list_ports.comports", lambda: ports)
    rig = rigfile.default_rig()
    assert find_rig_ports(rig) == ("/dev/ttyACM0", "/dev/ttyACM1")  # genuine boards: by their PIDs, unopened
    monkeypatch.setattr("serial.tools.list_ports.comports", lambda: ports[:1])
    with pytest.raises(RuntimeError, match=r"expected one DAQ board .* /dev/ttyACM1 \(2341:0043 Arduino Uno"):
        find_rig_ports(rig)
    assert KNOWN_BOARDS[(0x1A86, 0x7523)][0] == "either"


def test_a_late_reply_is_not_taken_for_the_next_command():
    rig, world = make_rig()
    world.stepper.receive(frame("ABORT"))  # a reply the host never read (its command timed out earlier)
    assert rig.stepper.command("POS") == "OK POS 0"
    assert rig.stepper.unexpected == ["ABORTED 0"]


@pytest.mark.parametrize("version", ["2.3.0+deadbeef", "2.3.0+00000000"])
def test_boards_built_for_another_rig_are_refused_with_the_rebuild_command(monkeypatch, version, shipped_rig):
    # rig-parametrised (tests/conftest.py): the host's rig is named by its hash and file
    import helpers.virtual.emulator.boards as emulated
    from helpers.rig import WrongRig

    monkeypatch.setattr(emulated, "board_version", lambda rig_hash: version)
    rig = shipped_rig.load()
    world = make_world(rig)
    with pytest.raises(WrongRig) as info:
        Rig("virtual", rig, CALIBRATION, world=world.name, timeout=0.5, hello_timeout=1.0)
    message = str(info.value)
    assert version.split("+")[1] in message and shipped_rig.hash in message
    assert "make -C firmware RIG=" in message and shipped_rig.path.name in message
    assert not [c for c in world.stepper.received if not c.startswith("PING")]  # nothing but PING was sent


def test_a_board_without_a_rig_hash_is_the_paper_rigs(monkeypatch):
    import helpers.virtual.emulator.boards as emulated

    monkeypatch.setattr(emulated, "board_version", lambda rig_hash: "2.1.0")
    world = make_world()
    rig = Rig("virtual", rigfile.default_rig(), CALIBRATION, world=world.name, timeout=0.5, hello_timeout=1.0)
    try:
        assert rig.daq.version == rig.stepper.version == "2.1.0"
    finally:
        rig.close()
