"""A hardware user's day, in the README's order, over ``serve-virtual-rig``'s pseudo-terminals (slow).

``record calibration`` (on the in-process rig: :data:`CALIBRATION`), then ``record identification``,
``record table-i`` (one repetition), a reduced ``tune`` (one repetition), a scenario of one's own (``record
pulse --group mine``) and ``home``, each with ``--ports DAQ,STEPPER`` as on hardware; none with
``--data-dir``: everything goes to the user's data folder, ``my_data/<rig name>/``. Run twice:

- from this working tree with ``HELPERS_USER_DATA_DIR`` pointing into ``tmp_path``: every file lands there,
  none elsewhere (the suite's own check of ``git status`` covers the tree);
- in a fresh ``git clone`` of the committed state, with that clone's code (``PYTHONPATH``) and its default
  ``my_data/``: afterwards ``git status --porcelain`` in the clone is empty (``my_data/`` is gitignored and no
  tracked file is rewritten).

Waits are on readiness (the server's two device paths, each command's exit); the timeouts only bound a
failure.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from helpers.base.paths import REPO_ROOT, USER_DATA_ENV

pytestmark = pytest.mark.slow

BOUND_S = 3600.0
"""Bound on one command of the day: only a failure reaches it."""

CALIBRATION = ("record", "calibration", "--quiet", "--ports", "virtual")
"""The load cell's calibration, on the in-process virtual rig: its fixture hangs the known loads. Over the
pseudo-terminals, as on hardware, the command asks a person to hang each mass and press Enter, which the
server's rig cannot be given (the rest of the day runs there)."""

DAY = (
    ("record", "identification", "--quiet"),
    ("record", "table-i", "--repetitions", "1", "--quiet"),
    ("tune", "--repetitions", "1", "--quiet"),
    ("record", "pulse", "--v-in", "250", "--x-f", "25", "--system", "zvd", "--group", "mine", "--quiet"),
    ("home",),
)
"""The README's hardware day, each command run with ``--ports DAQ,STEPPER`` appended."""


def _serve(env: dict[str, str], cwd: Path) -> tuple[subprocess.Popen, str]:
    """``serve-virtual-rig --speed 0`` (as fast as the reader drains it) and its ``DAQ,STEPPER`` ports."""
    server = subprocess.Popen(
        [sys.executable, "-m", "helpers", "serve-virtual-rig", "--speed", "0", "--virtual-instance", "day"],
        cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    ports: dict[str, str] = {}
    while len(ports) < 2:
        line = server.stdout.readline()  # readiness: the server prints its two device paths
        if not line:
            server.kill()
            raise AssertionError(f"serve-virtual-rig ended before printing its ports: {server.stderr.read()}")
        words = line.split()
        if len(words) == 2 and words[0] in ("daq", "stepper"):
            ports[words[0]] = words[1]
    return server, f"{ports['daq']},{ports['stepper']}"


def _day(env: dict[str, str], cwd: Path) -> None:
    """Run :data:`DAY` over a fresh server; every command must exit 0."""
    done = subprocess.run([sys.executable, "-m", "helpers", *CALIBRATION], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=BOUND_S)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    server, ports = _serve(env, cwd)
    try:
        for argv in DAY:
            done = subprocess.run(
                [sys.executable, "-m", "helpers", *argv, "--ports", ports], cwd=cwd, env=env,
                capture_output=True, text=True, timeout=BOUND_S,
            )  # fmt: skip
            assert done.returncode == 0, (argv, done.stdout[-2000:], done.stderr[-2000:])
    finally:
        server.terminate()
        try:
            server.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            server.kill()
            server.communicate()


def _check_the_days_files(mine: Path) -> None:
    """What the day wrote, each step where the next one reads it."""
    assert (mine / "calibration" / "calibration.json").exists()
    assert len(list((mine / "calibration").glob("load_*g.csv"))) == 6
    assert (mine / "identification" / "result.json").exists()
    assert len(list((mine / "experiments").glob("*.csv"))) == 12  # Table I, one repetition
    tuning = mine / "tuning"
    assert (tuning / "mode_map.json").exists() and (tuning / "chosen.json").exists()
    assert (tuning / "tuning_report.png").exists()  # beside its data, not in figures/
    assert [p.name for p in (mine / "mine").glob("*.csv")] == ["zvd_v250_x25.csv"]


def test_a_hardware_users_day_writes_only_into_the_user_data_folder(tmp_path):
    my_data = tmp_path / "my_data"
    env = {**os.environ, USER_DATA_ENV: str(my_data), "PYTHONPATH": str(REPO_ROOT)}
    _day(env, REPO_ROOT)
    _check_the_days_files(my_data / "paper")
    assert sorted(p.name for p in my_data.iterdir()) == ["paper"]


def test_a_fresh_clone_runs_the_day_and_stays_clean(tmp_path):
    clone = tmp_path / "clone"
    subprocess.run(["git", "clone", "--quiet", str(REPO_ROOT), str(clone)], check=True, timeout=600)
    env = {k: v for k, v in os.environ.items() if k not in (USER_DATA_ENV, "HELPERS_FIGURES_DIR")}
    env["PYTHONPATH"] = str(clone)
    _day(env, clone)
    _check_the_days_files(clone / "my_data" / "paper")
    status = subprocess.run(["git", "status", "--porcelain"], cwd=clone, capture_output=True, text=True,
                            check=True, timeout=120).stdout  # fmt: skip
    assert status == "", status
