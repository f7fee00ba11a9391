"""Designs in programmes, runs and the record command (a pair, a map-following schedule, a design file)."""

from __future__ import annotations

import argparse
import json
import math
import shutil

import numpy as np
import pytest
from rig_fakes import MM_PER_STEP, make_world

from helpers import recordings, rigfile
from helpers.__main__ import main
from helpers.base.jsonfile import DataFileError
from helpers.base.paths import DATA_DIR
from helpers.board.programmes import experiment_programme
from helpers.commands import record
from helpers.paper.shapers import Shaper
from helpers.research.design import SYSTEMS, Design, ShaperPair, map_following, save_design
from helpers.research.modemap import ModeMap

POS = np.arange(0.0, 40.1, 5.0)
MAP = ModeMap(
    POS,
    [25.1, 25.4, 26.3, 27.8, 30.0, 33.3, 37.7, 43.6, 51.5],
    np.full(POS.size, 0.04),
    source={"kind": "virtual-rig", "method": "test map"},
)
UP = Shaper(np.array([0.5, 0.5]), np.array([0.0, 0.1]), "up")
DOWN = Shaper(np.array([0.25, 0.5, 0.25]), np.array([0.0, 0.125, 0.25]), "down")


def test_a_pair_shapes_each_move_with_its_own_shaper():
    up, down = ShaperPair(UP, DOWN).moves(200.0, 30.0, t_up=1.0, t_down=8.0)
    t_p = 30.0 / 200.0
    np.testing.assert_allclose(up.breakpoints, 1.0 + np.array([0.0, 0.1, t_p, t_p + 0.1]), atol=1e-12)
    np.testing.assert_allclose(up.velocities, [100.0, 200.0, 100.0])
    expected = 8.0 + np.array([0, 0.125, t_p, 0.25, t_p + 0.125, t_p + 0.25])
    np.testing.assert_allclose(down.breakpoints, expected)
    np.testing.assert_allclose(down.velocities, [-50.0, -150.0, -100.0, -150.0, -50.0])
    programme, report = experiment_programme(200.0, 30.0, ShaperPair(UP, DOWN))
    assert programme.net_steps == 0 and report.n_steps == round(30.0 / MM_PER_STEP)
    moved = report.pieces.groupby("move")["steps"].sum()
    assert moved["up"] == report.n_steps and moved["down"] == -report.n_steps


def test_a_schedule_runs_its_sub_moves_and_only_for_its_move():
    d = map_following(MAP, 20.0, 200.0, "ZVD")
    up, down = d.moves(200.0, 20.0, t_up=1.0, t_down=8.0)
    subs = d.shaping.up.sub_moves
    ends = {1.0 + s.start_s for s in subs} | {1.0 + s.end_s for s in subs}
    assert set(np.round(up.breakpoints, 12)) <= set(np.round(sorted(ends), 12))
    assert up.piece_displacements.sum() == pytest.approx(20.0, rel=1e-12)
    assert down.piece_displacements.sum() == pytest.approx(-20.0, rel=1e-12)
    programme, report = experiment_programme(200.0, 20.0, d)
    assert programme.net_steps == 0
    with pytest.raises(ValueError, match="computed for 20 mm at 200 mm/s"):
        experiment_programme(200.0, 30.0, d)


def _args(*argv, rig: str = "paper"):
    p = argparse.ArgumentParser()
    record.add_arguments(p)
    args = p.parse_args(list(argv))
    args.rig = rigfile.load(rigfile.resolve(rig))  # as python -m helpers passes it: the rig as a value
    return args


def _with_calibration(tmp_path):
    (tmp_path / "calibration").mkdir()
    shutil.copy(DATA_DIR / "calibration" / "calibration.json", tmp_path / "calibration")


def test_record_runs_a_saved_schedule_and_writes_the_design_into_the_scenario(tmp_path):
    world = make_world()
    _with_calibration(tmp_path)
    design = map_following(MAP, 20.0, 200.0, "ZV")
    path = save_design(design, tmp_path / "following.json")
    argv = ["pulse", "--rig-name", world.name, "--data-dir", str(tmp_path), "--group", "runs",
            "--design", str(path), "--t-end", "9", "--quiet"]  # fmt: skip
    assert record.run(_args(*argv)) == 0  # --v-in and --x-f come from the schedule
    rec = recordings.load(tmp_path / "runs" / "map-following_v200_x20.csv")
    sc = rec.meta["scenario"]
    assert sc["system"] == "map-following" and sc["shaper"] is None and sc["shaper_down"] is None
    assert Design.from_dict(sc["shaping"]).to_dict() == design.to_dict()
    assert sc["design"]["origin"].endswith("following.json")
    assert rec.frame["steps"].max() == round(20.0 / MM_PER_STEP)


def test_a_pair_is_recorded_as_up_and_down_shapers(tmp_path):
    world = make_world()
    _with_calibration(tmp_path)
    path = save_design(Design("scheduled", ShaperPair(UP, DOWN)), tmp_path / "pair.json")
    argv = ["pulse", "--rig-name", world.name, "--data-dir", str(tmp_path), "--group", "runs",
            "--v-in", "200", "--x-f", "10", "--design", str(path), "--system", "scheduled",
            "--t-end", "9", "--quiet"]  # fmt: skip
    assert record.run(_args(*argv)) == 0
    sc = json.loads((tmp_path / "runs" / "scheduled_v200_x10.json").read_text())["scenario"]
    assert sc["shaper"]["times"] == [0.0, 0.1] and sc["shaper_down"]["times"] == [0.0, 0.125, 0.25]
    assert sc["shaping"]["kind"] == "pair" and sc["system"] == "scheduled"


@pytest.mark.parametrize(
    ("extra", "error", "message"),
    [
        (["--system", "scheduled"], ValueError, "--system scheduled needs --design FILE"),
        (["--system", "auto"], ValueError, "--system auto needs --design FILE"),
        (["--system", "zv", "--design", "{pair}"], ValueError, "holds a 'scheduled' design"),
        (["--design", "{pair}", "--zeta", "0.04", "--omega-d", "25"], ValueError, "exclude each other"),
        (["--design", "{bad}"], DataFileError, r"bad.json: up.times: missing"),
    ],
)
def test_record_refuses_what_it_cannot_run_in_one_line(tmp_path, extra, error, message):
    _with_calibration(tmp_path)
    save_design(Design("scheduled", ShaperPair(UP, DOWN)), tmp_path / "pair.json")
    doc = Design("scheduled", ShaperPair(UP, DOWN)).to_dict()
    del doc["up"]["times"]
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    extra = [e.format(pair=tmp_path / "pair.json", bad=tmp_path / "bad.json") for e in extra]
    argv = ["pulse", "--v-in", "200", "--x-f", "10", "--data-dir", str(tmp_path), "--dry-run", *extra]
    with pytest.raises(error, match=message) as info:
        record.run(_args(*argv))
    assert "\n" not in str(info.value)


def test_dry_run_describes_a_pair(tmp_path, capsys):
    _with_calibration(tmp_path)
    path = save_design(Design("scheduled", ShaperPair(UP, DOWN)), tmp_path / "pair.json")
    argv = ["pulse", "--v-in", "200", "--x-f", "10", "--data-dir", str(tmp_path), "--dry-run",
            "--design", str(path)]  # fmt: skip
    assert record.run(_args(*argv)) == 0
    out = capsys.readouterr().out
    assert "runs/scheduled_v200_x10.csv: 10 mm at 200 mm/s, scheduled (Up up: 2 impulses; Down down: 3" in out


def test_record_help_names_the_vocabulary_and_the_papers_filters(monkeypatch, capsys):
    monkeypatch.setenv("COLUMNS", "1000")  # no wrapping inside the phrases
    with pytest.raises(SystemExit) as done:
        main(["record", "pulse", "--help"])  # the pulse's own options
    assert done.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "zv = the paper's non-robust TDF (ZV shaper)" in text
    assert "zvd = the paper's robust TDF (ZVD shaper)" in text
    assert "Default: unshaped, or the design file's system" in text
    for name in SYSTEMS:
        assert name in text


def test_the_time_of_a_schedule_follows_the_map():
    # a stiffer arm further out: the Up move's stops come closer together than its starts
    d = map_following(MAP, 30.0, 200.0, "ZV")
    starts = [s.start_s for s in d.shaping.up.sub_moves]
    stops = [s.end_s for s in d.shaping.up.sub_moves]
    assert stops[1] - stops[0] < starts[1] - starts[0] < math.pi / 25.1 + 1e-12


def test_a_bad_request_is_refused_before_any_port_is_opened(tmp_path):
    _with_calibration(tmp_path)
    argv = ["pulse", "--v-in", "200", "--x-f", "10", "--system", "map-following", "--data-dir", str(tmp_path),
            "--ports", "/dev/nonexistent-daq,/dev/nonexistent-stepper"]  # fmt: skip
    with pytest.raises(ValueError, match="needs --design FILE"):  # not a BoardError from opening the port
        record.run(_args(*argv))
