"""What a writer that died leaves is cleaned up by the next writer holding the folder's lock (never a live
writer's files), and a group's session lock survives the group's folder being deleted."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from helpers import recordings, rigfile
from helpers.__main__ import main
from helpers.base.jsonfile import write_temp
from helpers.base.locks import FolderBusy, folder_lock
from helpers.base.paths import REPO_ROOT
from helpers.recordings import Recording


def _rec(adc0: int = 100) -> Recording:
    rows = [(s, 5_000 + 1000 * s, adc0 + s % 400, s // 5) for s in range(50)]
    return recordings.from_samples(
        rows, rigfile.default_rig(), source={"kind": "virtual-rig", "version": "test"},
        scenario={"kind": "programme"}, rate_hz=1000, started_utc="2026-12-01T15:00:00Z",
        firmware={"daq": "test", "stepper": "test"}, counts={"dropped": 0, "corrupted": 0, "overruns": 0},
    )


CHILD = """
import os, sys, time
from helpers import recordings
from helpers.recordings import store
sys.path.insert(0, "tests")
from test_stale_files import _rec

real_link = os.link
def link(src, dst):  # the old pair is set aside and the new CSV's temporary file written: die here
    if {stage!r} == "after the new CSV":
        real_link(src, dst)
    print("READY", flush=True)
    time.sleep(600)
store.os.link = link
recordings.save(_rec(adc0=300), sys.argv[1], replace=True)
"""


@pytest.mark.parametrize("stage", ["before the new CSV", "after the new CSV"])
def test_a_replacement_killed_midway_is_undone_by_the_next_writer(tmp_path, stage):
    folder = tmp_path / "g"
    old = recordings.save(_rec(adc0=100), folder / "p")
    before = (old.read_bytes(), old.with_suffix(".json").read_bytes())
    child = subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(CHILD.format(stage=stage)), str(folder / "p")],
        cwd=REPO_ROOT, stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    assert child.stdout.readline().strip() == "READY"  # it holds the folder's lock, mid-replacement
    child.kill()
    child.wait(timeout=60)
    assert any(p.name.endswith(".tmp") for p in folder.iterdir())  # what it left behind
    assert not (folder / "p.json").exists()  # the old pair is aside: p does not load now
    live = write_temp(folder, "live.csv", b"a live writer's file")  # this process is alive
    recordings.save(_rec(adc0=200), folder / "other")  # the next writer
    assert (old.read_bytes(), old.with_suffix(".json").read_bytes()) == before  # the old pair is back
    assert recordings.load(folder / "p").frame["adc"].iloc[0] == 100
    left = sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))
    assert left == [live.name]  # only the live writer's temporary file is there


def test_temporary_files_of_a_dead_writer_go_and_a_live_ones_stay(tmp_path):
    folder = tmp_path / "g"
    folder.mkdir()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True, check=True)  # fmt: skip
    stale = folder / f".run.csv.{int(dead.stdout)}-abcd1234.tmp"  # a writer killed while writing
    stale.write_bytes(b"half a file")
    live = write_temp(folder, "run.json", b"{}")
    recordings.save(_rec(), folder / "run")
    assert not stale.exists() and live.exists()


def test_deleting_a_group_while_a_recorder_holds_it_does_not_let_a_second_in(tmp_path, capsys):
    group = tmp_path / "data" / "g"
    (tmp_path / "data" / "calibration").mkdir(parents=True)
    src = REPO_ROOT / "data" / "calibration" / "calibration.json"
    (tmp_path / "data" / "calibration" / "calibration.json").write_bytes(src.read_bytes())
    with folder_lock(group, what="recording", name=".recording.lock", beside=True):
        for p in sorted(group.rglob("*"), reverse=True):
            p.unlink() if p.is_file() else p.rmdir()
        group.rmdir()  # somebody deletes the group's folder mid-run
        with pytest.raises(FolderBusy, match="is busy"):
            with folder_lock(group, what="recording", name=".recording.lock", beside=True):
                pass
        status = main(["record", "pulse", "--v-in", "100", "--x-f", "10", "--group", "g",
                       "--data-dir", str(tmp_path / "data")])  # fmt: skip
        assert status == 5 and "g is busy: process" in capsys.readouterr().err
