"""Selecting the rig (``--rig FILE``, ``HELPERS_RIG``); recordings carry their rig (docs/rig_file.md)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from rig_fakes import make_rig

from helpers import recordings, rigfile
from helpers.board.programmes import Dwell, Programme, Segment
from helpers.rigfile.option import take_rig_option

_PROBE = (
    "from helpers.paper import hardware as h; "
    "print(h.RIG.name, h.LIMITS.min_interval_us, h.LIMITS.max_position_steps, round(h.MM_PER_STEP, 6))"
)


def _python(code: str, env_rig: str | None) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env.pop(rigfile.ENV_VAR, None)
    if env_rig is not None:
        env[rigfile.ENV_VAR] = env_rig
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)


def test_hardware_follows_the_environment():
    assert _python(_PROBE, None).stdout.split() == ["paper", "639", "156", "0.255254"]
    assert _python(_PROBE, "long-arm").stdout.split() == ["long-arm", "524", "254", "0.07854"]


def test_a_bad_rig_in_the_environment_is_one_line():
    proc = _python(_PROBE, "no-such-rig.toml")
    assert proc.returncode != 0 and "no-such-rig.toml: no such rig file" in proc.stderr


def test_rig_option_sets_the_rig_before_the_command_loads():
    code = (
        "from helpers.__main__ import main; "
        "status = main(['rig', 'check', '--rig', 'long-arm', 'paper', '--json', '--points', '2']); "
        "from helpers.paper import hardware; print(status, hardware.RIG.name)"
    )
    proc = _python(code, None)
    assert proc.returncode == 0, proc.stderr
    last = proc.stdout.strip().splitlines()[-1]
    assert last == "0 long-arm"


def test_take_rig_option():
    assert take_rig_option(["record", "--rig", "a.toml", "pulse"]) == (["record", "pulse"], "a.toml")
    assert take_rig_option(["--rig=b", "metrics"]) == (["metrics"], "b")
    assert take_rig_option(["metrics", "--", "--rig", "x"]) == (["metrics", "--", "--rig", "x"], None)
    for bad in (["metrics", "--rig"], ["--rig", "--json"], ["--rig="]):
        with pytest.raises(ValueError, match="--rig needs a rig file"):
            take_rig_option(bad)


def test_the_old_rig_name_option_is_the_virtual_instance():
    import argparse

    from helpers.commands import home

    parser = argparse.ArgumentParser()
    home.add_arguments(parser)
    assert parser.parse_args(["--rig-name", "a"]).rig_name == "a"
    assert parser.parse_args(["--virtual-instance", "b"]).rig_name == "b"


# --- recordings carry their rig -------------------------------------------------------------------------
def _run(tmp_path):
    rig, _ = make_rig()
    try:
        return rig.run(
            Programme((Dwell(20), Segment(1, 5, 1000), Dwell(20))), path=tmp_path / "a", progress=False
        )
    finally:
        rig.close()


def test_old_recordings_load_as_the_paper_rig():
    meta = {"schema_version": 1}
    assert recordings.recording_rig(meta).hash == rigfile.default_rig().hash


def test_a_recordings_rig_section_round_trips(rig_file):  # rig-parametrised (tests/conftest.py)
    rig = rigfile.load(rig_file.path)
    section = recordings.rig_section(rig)
    assert json.loads(json.dumps(section)) == section
    back = recordings.recording_rig({"rig": section})
    assert (back.name, back.hash) == (rig_file.data["name"], rig_file.hash)
    assert back.text == rig_file.path.read_text()
    assert rigfile.derived(back).min_interval_us == rig_file.min_interval_us


def test_a_recording_from_the_virtual_rig_keeps_its_rig(tmp_path, shipped_rig):  # rig-parametrised
    rec = _run(tmp_path)
    assert rec.meta["schema_version"] == 2
    assert (rec.meta["rig"]["name"], rec.meta["rig"]["hash"]) == (shipped_rig.data["name"], shipped_rig.hash)
    loaded = recordings.load(rec.path)
    assert recordings.recording_rig(loaded.meta).text == shipped_rig.path.read_text()
    assert loaded.meta["calibration"]["mm_per_step"] == pytest.approx(shipped_rig.mm_per_step, rel=1e-12)


def test_a_tampered_rig_section_is_refused(tmp_path):
    rec = _run(tmp_path)
    json_path = rec.path.with_suffix(".json")
    meta = json.loads(json_path.read_text())
    meta["rig"]["text"] = meta["rig"]["text"].replace("travel_mm = 40.0", "travel_mm = 80.0")
    json_path.write_text(json.dumps(meta))
    with pytest.raises(recordings.RecordingError, match="rig.hash"):
        recordings.load(rec.path)
