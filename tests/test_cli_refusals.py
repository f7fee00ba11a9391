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
from helpers.base.paths import DATA_DIR, REPO_ROOT
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


# sub-commands, the rig's ranges, zero steps, speeds that fit, ports, output folders, the data folder


def _help(argv, capsys) -> str:
    with pytest.raises(SystemExit) as done:
        main([*argv, "--help"])
    assert done.value.code == 0
    return capsys.readouterr().out


def test_each_record_sub_command_shows_only_its_own_options(capsys):
    pulse = _help(["record", "pulse"], capsys)
    assert "--v-in" in pulse and "--x-f" in pulse and "--system" in pulse and "--data-dir" in pulse
    for other in ("--direction-deg", "--bend-mm", "--path-seed", "--margin-n", "--mode-grid", "--duration"):
        assert other not in pulse, other
    calibration = _help(["record", "calibration"], capsys)
    assert "--duration" in calibration and "--v-in" not in calibration and "--system" not in calibration
    move = _help(["record", "move"], capsys)
    assert "--bend-mm" in move and "--mode-grid" in move and "--x-f" not in move and "--path-seed" not in move
    assert "my_data/<rig name>/" in pulse  # where the recordings go, said by every recorder's help


def test_another_sub_commands_option_is_a_usage_error(capsys):
    assert _status(["record", "pulse", "--v-in", "100", "--x-f", "10", "--direction-deg", "4"]) == 2
    assert "unrecognized arguments: --direction-deg 4" in _one_line(capsys)


def test_the_rig_option_goes_after_the_sub_command_too(data, tmp_path, capsys):
    argv = ["record", "pulse", "--v-in", "100", "--x-f", "10", "--dry-run", "--rig", "long-arm"]
    assert _status([*argv, "--data-dir", str(data)]) == 0
    steps = round(10 / rigfile.derived(rigfile.load(rigfile.resolve("long-arm"))).mm_per_step[0])
    assert steps != 39 and f", {steps} steps per move" in capsys.readouterr().out  # the paper's rig: 39
    assert _status([*argv, "--data-dir", str(tmp_path / "none")]) == 5  # and the missing step names the rig
    assert "`python -m helpers --rig long-arm record calibration --data-dir" in _one_line(capsys)


def test_a_missing_previous_step_names_the_command_that_makes_it(tmp_path, capsys):
    own = ["--data-dir", str(tmp_path)]
    assert _status(["record", "pulse", "--v-in", "100", "--x-f", "10", "--dry-run", *own]) == 5
    line = _one_line(capsys)
    assert "no load-cell calibration yet" in line
    assert f"`python -m helpers record calibration --data-dir {tmp_path}`" in line
    (tmp_path / "calibration").mkdir()
    shutil.copy(DATA_DIR / "calibration" / "calibration.json", tmp_path / "calibration")
    assert _status(["record", "table-i", "--dry-run", *own]) == 5
    line = _one_line(capsys)
    assert "no identification result yet" in line and "record identification --data-dir" in line
    assert _status(["tune", "--repetitions", "1", *own]) == 5
    assert "record identification" in _one_line(capsys)
    assert not list(tmp_path.rglob("*.csv"))


def test_the_default_data_folder_is_my_data_per_rig(monkeypatch, tmp_path, capsys):
    from helpers.base.paths import USER_DATA_ENV, user_data_dir

    monkeypatch.setenv(USER_DATA_ENV, str(tmp_path))
    assert user_data_dir(rigfile.load(rigfile.resolve("long-arm"))) == tmp_path / "long-arm"
    assert user_data_dir("paper") == tmp_path / "paper"
    for bad in ("..", ".", "a/b", ""):
        with pytest.raises(ValueError):
            user_data_dir(bad)
    assert _status(["record", "calibration", "--dry-run"]) == 0
    assert str(tmp_path / "paper" / "calibration" / "load_0000g.csv") in capsys.readouterr().out
    monkeypatch.delenv(USER_DATA_ENV)
    assert user_data_dir("paper") == REPO_ROOT / "my_data" / "paper"
    assert "my_data/" in (REPO_ROOT / ".gitignore").read_text().splitlines()


def test_a_move_of_zero_whole_steps_is_refused_and_nothing_written(tmp_path, capsys):
    argv = ["--rig", "four-tendon", "record", "move", "--direction-deg", "0", "--bend-mm", "1e-300",
            "--data-dir", str(tmp_path)]  # fmt: skip
    assert _status(argv) == 2
    assert "a move of zero steps" in _one_line(capsys)
    assert not list(tmp_path.rglob("*.csv")) and not list(tmp_path.rglob("*.json"))


def test_a_tip_stream_of_zero_whole_steps_is_refused(tmp_path, capsys):
    argv = ["--rig", "four-tendon", "record", "tip-stream", "--bend-mm", "1e-300",
            "--data-dir", str(tmp_path)]  # fmt: skip
    assert _status(argv) == 2
    assert "a stream of zero steps" in _one_line(capsys)
    assert not list(tmp_path.rglob("*.csv"))


def test_a_move_at_the_rigs_speed_limit_and_length_is_accepted(tmp_path, capsys):
    base = ["--rig", "four-tendon", "record", "move", "--direction-deg", "0", "--bend-mm", "10", "--dry-run",
            "--data-dir", str(tmp_path)]  # fmt: skip
    rig = rigfile.load(rigfile.resolve("four-tendon"))
    limit, longest = rig.hardware.speed_limit_mm_s, rig.hardware.max_programme_s
    assert _status([*base, "--v-in", f"{limit:g}"]) == 0  # was refused by a rounding of the step interval
    out = capsys.readouterr().out
    assert "would be made" in out
    # its dwells split at the board's longest (the dynamic floor check, minutes of the twin, is not the point)
    assert _status([*base, "--t-end", f"{longest:g}", "--no-floor-check"]) == 0
    assert f"{longest:.2f} s)" in capsys.readouterr().out


def test_a_move_too_fast_says_the_limit(tmp_path, capsys):
    argv = ["--rig", "four-tendon", "record", "move", "--direction-deg", "0", "--bend-mm", "10",
            "--v-in", "500", "--dry-run", "--data-dir", str(tmp_path)]  # fmt: skip
    assert _status(argv) == 3
    assert "at most 400 mm/s (speed_limit_mm_s)" in _one_line(capsys)


@pytest.mark.slow  # the refusal plans the figure at several speeds to find what fits, then it runs: 12 s
def test_a_three_tendon_tip_stream_too_fast_says_what_speed_fits(tmp_path, capsys):
    import re

    # pulled one step in: without, the line's whole steps leave a tendon below the floor (test_whole_steps)
    argv = ["--rig", "three-tendon", "record", "tip-stream", "--path", "line", "--bend-mm", "10", "--dry-run",
            "--prepull", "1", "--data-dir", str(tmp_path)]  # fmt: skip
    assert _status([*argv, "--v-in", "400"]) == 3
    line = _one_line(capsys)
    assert "over the stream's speed limit" in line
    fits = re.search(r"--v-in ([\d.]+) fits \(planned; ([\d.]+) is refused\)", line)
    assert fits, line
    assert _status([*argv, "--v-in", fits.group(1)]) == 0  # what the refusal says fits, fits
    assert "would be made" in capsys.readouterr().out
    assert _status([*argv, "--v-in", fits.group(2)]) == 3


def test_home_refuses_extra_ports_in_one_line(capsys):
    for ports in ("a,b,c", "a,"):
        assert _status(["home", "--ports", ports]) == 2
        assert "home takes 'virtual', 'auto', 'DAQ,STEPPER' or the stepper's port alone" in _one_line(capsys)


def test_metrics_creates_missing_folders_only_under_the_working_directory_or_my_data(tmp_path, monkeypatch,
                                                                                     capsys):  # fmt: skip
    monkeypatch.chdir(tmp_path)
    outside = tmp_path.parent / f"{tmp_path.name}-absent" / "deeper"
    argv = ["metrics", str(DATA_DIR / "experiments" / "unshaped_v200_x10_r1.csv")]
    assert _status([*argv, "--csv", str(outside / "x")]) == 2
    assert "does not exist; outputs create folders only inside" in capsys.readouterr().err
    assert not outside.parent.exists()
    assert _status([*argv, "--csv", "sub/dir/x"]) == 0  # inside the working directory: created
    assert (tmp_path / "sub" / "dir" / "x_runs.csv").exists()
    existing = tmp_path.parent / f"{tmp_path.name}-there"
    existing.mkdir()
    try:
        assert _status([*argv, "--csv", str(existing / "x")]) == 0  # a folder that exists: anywhere
    finally:
        shutil.rmtree(existing)
