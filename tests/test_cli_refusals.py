"""Refusals of the command line: one line naming the problem, the documented status, before any port opens;
and ``home``, which stops what an earlier session left running."""

from __future__ import annotations

import errno
import json
import shutil

import pytest
from rig_fakes import make_rig

from helpers import rigfile
from helpers.__main__ import main
from helpers.base.paths import DATA_DIR
from helpers.board.programmes import Dwell, Programme, Segment
from helpers.commands.home import home
from helpers.rig import NotAtZero, SafetyError, check_request, link


@pytest.fixture
def data(tmp_path, monkeypatch):
    """A data folder with the calibration and the identification of a fresh clone; no port may open."""
    for sub in ("calibration", "identification"):
        (tmp_path / sub).mkdir()
    shutil.copy(DATA_DIR / "calibration" / "calibration.json", tmp_path / "calibration")
    shutil.copy(DATA_DIR / "identification" / "result.json", tmp_path / "identification")

    def no_port(*a, **k):
        raise AssertionError("a port was opened")

    monkeypatch.setattr(link, "open_port", no_port)
    return tmp_path


def _status(argv) -> int:
    """``main``'s exit status (argparse's usage errors leave as SystemExit, as from the shell)."""
    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code)


def _one_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err


@pytest.mark.parametrize("system", ["unshaped", "zv", "zvd", "ei"])
def test_the_longest_pulse_the_help_promises_is_accepted_for_every_shaper(data, system, capsys):
    args = ["record", "pulse", "--v-in", "200", "--x-f", "39.82", "--system", system, "--data-dir", str(data)]
    assert main([*args, "--dry-run"]) == 0
    assert "156 steps per move" in capsys.readouterr().out
    assert _status([*args[:5], "40", *args[6:], "--dry-run"]) == 3  # the rig's travel: a safety limit
    assert "displacement 40.0 mm is 157 steps, beyond the travel of 156 steps (39.8 mm)" in _one_line(capsys)
    with pytest.raises(SafetyError, match="157 steps, beyond the travel of 156 steps"):
        check_request(200, 40, rigfile.default_rig())


def test_an_existing_recording_is_refused_before_connecting_naming_the_ways_out(data, capsys):
    (data / "runs").mkdir()
    for ext in (".csv", ".json"):
        (data / "runs" / f"mine{ext}").write_text("{}")
    args = ["record", "pulse", "--v-in", "100", "--x-f", "10", "--name", "mine", "--data-dir", str(data)]
    assert main(args) == 5
    line = _one_line(capsys)
    assert "mine.csv: a recording of that name exists" in line and "--name" in line and "--replace" in line


def test_a_missing_identification_is_a_data_error(data, capsys):
    (data / "identification" / "result.json").unlink()
    args = ["record", "pulse", "--v-in", "100", "--x-f", "10", "--system", "zvd", "--data-dir", str(data)]
    assert main(args) == 5
    assert "no identification result yet" in _one_line(capsys)


def test_no_boards_found_by_usb_is_a_board_fault(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr("serial.tools.list_ports.comports", lambda: [])
    for sub in ("calibration",):
        (tmp_path / sub).mkdir()
        shutil.copy(DATA_DIR / "calibration" / "calibration.json", tmp_path / sub)
    args = ["record", "pulse", "--v-in", "100", "--x-f", "10", "--ports", "auto", "--data-dir", str(tmp_path)]
    assert main(args) == 4
    assert "expected one DAQ board (Mega) and one stepper board (Uno)" in _one_line(capsys)


@pytest.mark.parametrize("what", [errno.ENOSPC, errno.EROFS])
def test_a_full_or_read_only_disk_names_the_file_and_is_a_data_error(tmp_path, monkeypatch, capsys, what):
    from helpers.base import jsonfile

    def refuse(*a, **k):
        raise OSError(what, errno.errorcode[what])

    monkeypatch.setattr(jsonfile.os, "fsync", refuse)
    definition = tmp_path / "d.json"
    definition.write_text(json.dumps({"name": "d", "shapers": ["unshaped"]}))
    assert main(["sweep", "run", str(definition), "--serial", "--no-progress"]) == 5
    line = _one_line(capsys)
    assert "sweep.json" in line or "d.nc" in line
    assert ("no space left" in line) if what == errno.ENOSPC else ("read-only" in line)
    for sub in ("calibration",):
        (tmp_path / sub).mkdir(exist_ok=True)
    args = ["record", "calibration", "--duration", "0.2", "--data-dir", str(tmp_path), "--group", "cal"]
    assert main(args) == 5
    line = _one_line(capsys)
    assert "load_" in line and "could not" in line


def test_home_on_the_in_process_rig_says_there_is_nothing_to_do(capsys):
    assert main(["home"]) == 0
    assert "nothing to home" in capsys.readouterr().out
    assert _status(["home", "--rig-name", "a&daq_options=x"]) == 2
    assert "invalid virtual rig name" in _one_line(capsys)


def test_home_stops_a_programme_an_earlier_session_left_running():
    rig, world = make_rig()
    rig.stepper.send_all(Programme((Segment(1, 40, 1000), Dwell(60_000))).commands())
    rig.stepper.command("EN 1")
    rig.stepper.command("GO")
    world.advance_to(world.t + 0.1)  # 40 steps done, a minute's dwell to go: the programme runs
    assert world.stepper.running and world.stepper.position == 40
    rig.stepper.booted_on_open = False  # as a board that kept running (serve-virtual-rig, no reset-on-open)
    said = home(rig.stepper, rig.rig)
    assert said.startswith("moved 40 steps") and world.stepper.position == 0 and not world.stepper.enabled
    assert world.stepper.received.index("ABORT") > world.stepper.received.index("GO")


def test_a_pulse_away_from_zero_names_the_way_home_for_these_ports(tmp_path):
    rig, world = make_rig()
    rig.run(Programme((Dwell(50), Segment(1, 10, 1000), Dwell(50))), path=tmp_path / "a", progress=False)
    with pytest.raises(NotAtZero, match=r"helpers\.commands\.home\.home\(rig\.stepper, rig\.rig\)"):
        rig.run_pulse(100, 5, path=tmp_path / "b", progress=False)
    rig.source["ports"] = {"daq": "/dev/pts/5", "stepper": "/dev/pts/6"}  # as over serve-virtual-rig
    with pytest.raises(NotAtZero, match="python -m helpers home --ports /dev/pts/5,/dev/pts/6"):
        rig.run_pulse(100, 5, path=tmp_path / "b", progress=False)
