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
def long_arm_build(tmp_path_factory: pytest.TempPathFactory, firmware_build: None) -> Path:
    """The long-arm build (after the default one, which makes the simavr harness the tests run it in)."""
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


@pytest.mark.streaming
def test_the_second_rigs_stream_takes_its_own_set_point_limit(long_arm_build: Path) -> None:
    """A set-point v steps every 2^20 / v us, so this build's fastest step (524 us) allows floor(2^20 / 524) =
    2001 units, not the paper's 1640 (639 us): V 2001 is taken, V 2002 refused naming 2001. The emulated
    board built for this rig file answers the same (``tests/test_rig_stream.py``), and so does the host."""
    assert (1 << 20) // MIN_INTERVAL_US == 2001 and (1 << 20) // 639 == 1640
    cmds = ["SHAPER 1 0", "IMP 0 4096 0", "EN 1", "STREAM", "V 2001", "V 1641", "V 2002", "V -2002", "ABORT"]
    times = [0.05 + 0.002 * i for i in range(len(cmds))]
    run = fwsim.run(
        "stepper", list(zip(times, map(fwsim.command, cmds), strict=True)), 0.08,
        elf=long_arm_build / "stepper_uno.elf",
    )  # fmt: skip
    bodies = [ln.body for ln in run.lines if not ln.body.startswith(("HELLO", "N,", "DONE"))]
    assert all(ln.checksum_ok for ln in run.lines)
    assert bodies[:4] == ["OK SHAPER 1", "OK IMP 0", "OK EN 1", "OK STREAM 0"]
    assert bodies[4].startswith("OK V ") and bodies[5].startswith("OK V ")  # 2001 and 1641: both taken
    assert bodies[6:8] == ["ERR RANGE set-point -2001..2001"] * 2
