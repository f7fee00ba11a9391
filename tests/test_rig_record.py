"""The ``record`` command and the calibration path, on a test-double virtual rig."""

from __future__ import annotations

import argparse
import json
import shutil

import pytest
from rig_fakes import GAIN, OFFSET, make_world

from helpers import recordings, rigfile
from helpers.base.paths import DATA_DIR
from helpers.commands import record
from helpers.paper import calibration as loadcell
from helpers.rig import static as loadcell_recording


def _args(*argv, rig: str = "paper"):
    p = argparse.ArgumentParser()
    record.add_arguments(p)
    args = p.parse_args(list(argv))
    args.rig = rigfile.load(rigfile.resolve(rig))  # as python -m helpers passes it: the rig as a value
    return args


def test_record_calibration_recovers_the_sensor_line(tmp_path):
    world = make_world()
    argv = ("calibration", "--rig-name", world.name, "--data-dir", str(tmp_path), "--quiet")
    assert record.run(_args(*argv)) == 0
    data = json.loads((tmp_path / "calibration" / "calibration.json").read_text())
    assert data["gain_counts_per_n"] == pytest.approx(GAIN, rel=2e-3)  # 0.5-count rounding of each load
    assert data["offset_counts"] == pytest.approx(OFFSET, abs=0.5)
    assert data["source"] == {"kind": "virtual-rig"}
    recs = loadcell_recording.load_calibration_recordings(tmp_path / "calibration")
    assert [r.meta["scenario"]["mass_kg"] for r in recs] == [0.0, 0.2, 0.5, 1.0, 1.5, 1.9]  # 20 N cell
    assert all(r.meta["scenario"]["fixture"].startswith("VIRTUAL") for r in recs)
    assert world.load_n is None  # the fixture is removed afterwards


def test_record_pulse_with_a_shaper(tmp_path):
    world = make_world()
    argv = [
        "pulse",
        "--rig-name",
        world.name,
        "--data-dir",
        str(tmp_path),
        "--group",
        "runs",
        "--v-in",
        "200",
        "--x-f",
        "10",
        "--system",
        "zvd",
        "--zeta",
        "0.044",
        "--omega-d",
        "25.085",
        "--t-end",
        "9",
        "--quiet",
    ]
    (tmp_path / "calibration").mkdir()
    shutil.copy(DATA_DIR / "calibration" / "calibration.json", tmp_path / "calibration")
    assert record.run(_args(*argv)) == 0
    rec = recordings.load(tmp_path / "runs" / "zvd_v200_x10.csv")
    sc = rec.meta["scenario"]
    assert sc["system"] == "zvd" and sc["design"]["zeta"] == 0.044 and len(sc["shaper"]["amplitudes"]) == 3
    assert rec.frame["steps"].max() == round(10 / 0.2552544031041707)


def test_fit_needs_three_loads():
    with pytest.raises(ValueError, match="three distinct loads"):
        loadcell.fit_calibration([])


def _with_calibration(tmp_path):
    """A data folder as a fresh clone has it: the load-cell calibration and the identified mode."""
    for group, name in (("calibration", "calibration.json"), ("identification", "result.json")):
        (tmp_path / group).mkdir()
        shutil.copy(DATA_DIR / group / name, tmp_path / group / name)


def test_dry_run_checks_everything_and_opens_no_port(tmp_path, capsys):
    _with_calibration(tmp_path)
    argv = ["pulse", "--v-in", "250", "--x-f", "25", "--system", "zvd", "--repetitions", "3",
            "--group", "mine", "--ports", "/dev/nonexistent-daq,/dev/nonexistent-stepper",
            "--data-dir", str(tmp_path), "--dry-run"]  # fmt: skip
    assert record.run(_args(*argv)) == 0
    out = capsys.readouterr().out
    assert "3 recording(s) would be made" in out and "nothing was sent" in out
    for k in (1, 2, 3):
        assert f"mine/zvd_v250_x25_r{k}.csv: 25 mm at 250 mm/s, zvd (3 impulses), 98 steps per move" in out
    assert not (tmp_path / "mine").exists()  # nothing written, not even the group folder


def test_dry_run_refuses_what_the_real_run_would_refuse(tmp_path):
    _with_calibration(tmp_path)
    common = ["--data-dir", str(tmp_path), "--dry-run", "--group", "mine"]
    with pytest.raises(record.SafetyError, match="157 steps, beyond the travel of 156 steps"):  # the rig's
        record.run(_args("pulse", "--v-in", "400", "--x-f", "40", *common))  # travel, checked before a port
    assert record.run(_args("pulse", "--v-in", "400", "--x-f", "39.82", *common)) == 0  # 156 steps: the top
    with pytest.raises(record.SafetyError, match="beyond the travel of 156 steps"):  # and the API says why
        record.check_request(400, 40, rigfile.default_rig())
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "unshaped_v200_x10.json").write_text("{}")
    with pytest.raises(recordings.RecordingExists, match="exists"):
        record.run(_args("pulse", "--v-in", "200", "--x-f", "10", *common))
    assert record.run(_args("pulse", "--v-in", "200", "--x-f", "10", "--replace", *common)) == 0
    shutil.rmtree(tmp_path / "calibration")
    with pytest.raises(record.MissingDataError):
        record.run(_args("pulse", "--v-in", "200", "--x-f", "10", *common))
