"""The firmware built for the second shipped rig (``rigs/long-arm.toml``: a 40 mm spool, 1600 microsteps/rev,
150 mm/s, 20 mm of travel) with ``make -C firmware RIG=FILE`` and the real header generator, in simavr: the
boards report that rig's hash, and the stepper's limits are that rig's, not the paper's."""

from __future__ import annotations

import hashlib
import math
import subprocess
import sys
from pathlib import Path

import fwsim
import pytest

pytestmark = pytest.mark.firmware

RIG = fwsim.REPO / "rigs" / "long-arm.toml"
# the rig file's numbers, worked by hand: 0.0785 mm/step; 150 mm/s = 1909.9 steps/s (under the 2000 cap), so
# the fastest step is ceil(523.6) = 524 us; 20 mm of travel = floor(254.6) = 254 steps
MM_PER_STEP = math.pi * 40.0 / 1600
MIN_INTERVAL_US = math.ceil(1e6 * MM_PER_STEP / 150.0)
TRAVEL_STEPS = math.floor(20.0 / MM_PER_STEP)


@pytest.fixture(scope="module")
def long_arm_build(tmp_path_factory: pytest.TempPathFactory) -> Path:
    build = tmp_path_factory.mktemp("long_arm")
    proc = subprocess.run(
        ["make", "-C", str(fwsim.FIRMWARE), "-j2", f"RIG={RIG}", f"PYTHON={sys.executable}", f"BUILD={build}",
         "firmware", "size"],
        capture_output=True, text=True, check=False, timeout=600,
    )  # fmt: skip
    if proc.returncode != 0:
        pytest.fail(f"long-arm build failed:\n{proc.stdout[-3000:]}{proc.stderr[-3000:]}", pytrace=False)
    assert "stepper_uno:" in proc.stdout and "B RAM" in proc.stdout  # the RAM budget is printed
    return build


def test_the_second_rigs_build_reports_its_hash_and_its_limits(long_arm_build: Path) -> None:
    assert (MIN_INTERVAL_US, TRAVEL_STEPS) == (524, 254)
    digest = hashlib.sha256(RIG.read_bytes()).hexdigest()[:8]
    cmds = [
        "PING",
        "CONFIG",
        f"SEG 1 {TRAVEL_STEPS} {MIN_INTERVAL_US}",  # the whole travel at the top speed: accepted
        f"SEG 1 10 {MIN_INTERVAL_US - 1}",  # faster than 150 mm/s on this spool
        f"SEG 1 {TRAVEL_STEPS + 1} 1000",  # past the travel
        "SEG 1 10 638",  # the paper's fastest step is legal here (0.0785 mm/step)
    ]
    times = [0.05 + 0.02 * i for i in range(len(cmds))]
    run = fwsim.run(
        "stepper", list(zip(times, map(fwsim.command, cmds), strict=True)), 0.3,
        elf=long_arm_build / "stepper_uno.elf",
    )  # fmt: skip
    bodies = [ln.body for ln in run.lines]
    assert all(ln.checksum_ok for ln in run.lines)
    assert bodies[0] == bodies[1].replace("PONG", "HELLO") == f"HELLO stepper 2.3.0+{digest}"
    assert bodies[2] == f"OK CONFIG 1 64 {MIN_INTERVAL_US} 1000000 {TRAVEL_STEPS}"
    assert bodies[3] == "OK SEG 1"
    assert bodies[4].startswith("ERR RANGE") and bodies[5].startswith("ERR RANGE")
    assert bodies[6] == "OK SEG 2"
    daq = fwsim.run("daq", [(0.05, fwsim.command("PING"))], 0.2, elf=long_arm_build / "daq_mega.elf")
    assert [ln.body for ln in daq.lines][:2] == [f"HELLO daq 2.3.0+{digest}", f"PONG daq 2.3.0+{digest}"]
