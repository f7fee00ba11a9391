"""The rig is a value: ``--rig`` an ordinary option, nothing read at import; recordings carry their rig."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from rig_fakes import make_rig

from helpers import recordings, rigfile
from helpers.board.programmes import Dwell, Programme, Segment

PACKAGE_IMPORT = (
    "import importlib, json, pkgutil, helpers\n"
    "names = [m.name for m in pkgutil.walk_packages(helpers.__path__, 'helpers.')]\n"
    "optional = {}\n"
    "for n in names:\n"
    "    try:\n"
    "        importlib.import_module(n)\n"
    "    except ModuleNotFoundError as exc:\n"
    "        optional[n] = str(exc)\n"
    "print(json.dumps({'imported': len(names) - len(optional), 'optional': optional}))"
)
"""Imports every module of the package; one of an extra not installed is listed with its message."""
NEEDS_COSSERATBENCH = (
    'the cosseratbench solver needs the [cosseratbench] extra: pip install -e ".[cosseratbench]"'
)


def _python(code: str, env: dict[str, str] | None = None, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *(["-c", code] if code else []), *args], capture_output=True,
                          text=True, env=dict(os.environ, **(env or {})), timeout=300)  # fmt: skip


def test_importing_any_module_reads_no_rig_and_no_environment():
    # the rig is a value passed down: a bad rig named in the environment changes nothing
    proc = _python(PACKAGE_IMPORT, {"HELPERS_RIG": "/nonexistent"})
    assert proc.returncode == 0, proc.stderr[-2000:]
    result = json.loads(proc.stdout.splitlines()[-1])
    assert result["imported"] > 100  # every module of the package was imported
    # only a module of an optional extra may be missing its packages, and it says which extra to install
    for name, message in result["optional"].items():
        assert name == "helpers.virtual.spatial.cosseratbench_solver", (name, message)
        assert message == NEEDS_COSSERATBENCH


@pytest.mark.parametrize("where", ["before", "after"])
def test_the_rig_option_is_an_ordinary_option_anywhere(where):
    argv = ["--rig", "no-such-rig.toml", "frame", "PING"] if where == "before" else \
        ["frame", "PING", "--rig", "no-such-rig.toml"]  # fmt: skip
    proc = _python("", None, "-m", "helpers", *argv)
    assert proc.returncode == 2 and proc.stderr.strip() == "error: no-such-rig.toml: no such rig file"
    ok = _python("", None, "-m", "helpers", "frame", "--rig", "long-arm", "PING")
    assert ok.returncode == 0 and ok.stdout.strip() == "PING*79"


def test_the_old_rig_name_option_is_the_virtual_instance():
    import argparse

    from helpers.commands import home

    parser = argparse.ArgumentParser()
    home.add_arguments(parser)
    assert parser.parse_args(["--rig-name", "a"]).rig_name == "a"
    assert parser.parse_args(["--virtual-instance", "b"]).rig_name == "b"


# --- recordings carry their rig -------------------------------------------------------------------------
def _run(tmp_path, rig=None):
    rig, _ = make_rig(rig=rig)
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
    rec = _run(tmp_path, shipped_rig.load())
    assert rec.meta["schema_version"] == 4
    assert (rec.meta["rig"]["name"], rec.meta["rig"]["hash"]) == (shipped_rig.data["name"], shipped_rig.hash)
    loaded = recordings.load(rec.path)
    assert recordings.recording_rig(loaded.meta).text == shipped_rig.path.read_text()
    assert loaded.meta["calibration"]["mm_per_step"] == pytest.approx([shipped_rig.mm_per_step], rel=1e-12)


def test_a_tampered_rig_section_is_refused(tmp_path):
    rec = _run(tmp_path)
    json_path = rec.path.with_suffix(".json")
    meta = json.loads(json_path.read_text())
    meta["rig"]["text"] = meta["rig"]["text"].replace("travel_mm = 40.0", "travel_mm = 80.0")
    json_path.write_text(json.dumps(meta))
    with pytest.raises(recordings.RecordingError, match="rig.hash"):
        recordings.load(rec.path)
