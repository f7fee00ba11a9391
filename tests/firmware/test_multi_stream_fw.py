"""Streams of several axes: the stepper firmware built for the four-tendon rig config in simavr, fed ``MV``
set-points (different per axis, one axis driven into its travel clamp), every axis's STEP edges against
``helpers.board.stream_reference.simulate_axes`` step for step (within one timer tick); the multi-axis
streaming replies and refusals (``MV``, the shorter longest delay, the programme table the stream takes).
"""

from __future__ import annotations

import re
from pathlib import Path

import fwsim
import numpy as np
import pytest

from helpers.board import stream_reference as hs

pytestmark = [pytest.mark.firmware, pytest.mark.streaming]

F = fwsim.F_CPU
TICK_CYCLES = 8
AXES = [("D5", "D6"), ("D2", "B2"), ("D3", "B3"), ("D4", "B4")]  # (STEP, DIR) of axes 0-3 on the Uno
TRAVEL = 156
# ZVD-like: three impulses, the delays off the period grid (77.008 ms = 7 periods + 438.5 DELTA ...)
SHAPER = hs.StreamShaper((1024, 2048, 1024), (0, 77_008, 154_016))


def setpoints() -> list[tuple[int, int, int, int]]:
    """30 periods of set-points, different per axis; axis 1 runs at the top speed into its travel (156)."""
    out = []
    for i in range(30):
        v0 = 1200 if i < 10 else (-800 if i < 20 else 0)
        v1 = hs.V_MAX if i < 25 else 0  # 1564 steps/s for 250 ms: 391 steps, clamped at 156
        v2 = 100 * (i + 1) if i < 15 else max(0, 1500 - 100 * (i - 15))
        v3 = 500 if i % 2 == 0 else -300
        out.append((v0, v1, v2, v3))
    return out


def _script(cmds: list[tuple[float, str]]) -> list[tuple[float, bytes]]:
    return [(t, fwsim.command(body)) for t, body in cmds]


def _rising(run: fwsim.SimRun, pin: str, after: float) -> np.ndarray:
    return np.array([c for c, p, lv in run.pins if p == pin and lv == 1 and c >= after], dtype=np.int64)


def _level_at(run: fwsim.SimRun, pin: str, cycle: int) -> int:
    level = 0
    for c, p, lv in run.pins:
        if p == pin and c <= cycle:
            level = lv
    return level


def test_four_axis_stream_matches_the_reference_per_axis(
    four_build: tuple[Path, str], firmware_build: None
) -> None:
    build, _ = four_build
    sps = setpoints()
    t_stream = 0.05 + 0.004 * 6
    cmds = [(0.05 + 0.004 * i, body) for i, body in enumerate(["EN 1", *SHAPER.commands()])]
    cmds.append((t_stream, "STREAM"))
    # the first three set-points at once (a lead of about three periods), then one per period
    times = [0.001 + 0.002 * i if i < 3 else 0.005 + 0.01 * (i - 2) for i in range(len(sps))]
    cmds += [(t_stream + t, "MV " + " ".join(map(str, v))) for t, v in zip(times, sps, strict=True)]
    cmds.append((t_stream + times[-1] + 0.003, "END"))
    duration = t_stream + 0.30 + 0.09 + SHAPER.duration_s + 0.1
    watch = [p for pair in AXES for p in pair] + ["B0"]
    run = fwsim.run("stepper", _script(cmds), duration, watch=watch, elf=build / "stepper_uno.elf")
    assert all(ln.checksum_ok for ln in run.lines)
    bodies = [ln.body for ln in run.lines]
    replies = [b for b in bodies if not b.startswith(("N,", "DONE", "HELLO"))]
    assert replies[:6] == ["OK EN 1", "OK SHAPER 3", "OK IMP 0", "OK IMP 1", "OK IMP 2", "OK STREAM 0"]
    assigned: dict[int, tuple[int, ...]] = {}
    for v, reply in zip(sps, replies[6:36], strict=True):
        m = re.fullmatch(r"OK MV (\d+)", reply)
        assert m, reply
        assigned[int(m[1])] = v
    assert sorted(assigned) == list(range(1, 31))  # no underrun: one set-point per period 1..30
    m = re.fullmatch(r"OK END (\d+)", replies[36])
    assert m and int(m[1]) == 31
    ref = hs.simulate_axes(SHAPER, hs.PeriodCommands(assigned, 31), [0, 0, 0, 0], [TRAVEL] * 4)
    # the reference itself: axis 1 reaches its travel and is held there (by hand: 391 steps commanded)
    assert ref[1].position == TRAVEL and [n.line for n in ref[1].notices] == [f"N,LIMIT,TRAVEL,{TRAVEL},1"]
    assert bodies[-1] == "DONE " + " ".join(str(r.position) for r in ref)
    notices = sorted(b for b in bodies if b.startswith("N,"))
    assert notices == sorted(n.line for r in ref for n in r.notices)
    stream_cycle = next(ln.cycle for ln in run.lines if ln.body == "OK STREAM 0")
    residuals = []
    for a, ((step, dir_pin), r) in enumerate(zip(AXES, ref, strict=True)):
        edges = _rising(run, step, stream_cycle - F // 100)
        assert len(edges) == len(r.ticks), f"axis {a}: {len(edges)} steps, reference {len(r.ticks)}"
        assert len(edges) > 20
        for c, d in zip(edges, r.directions, strict=True):
            assert _level_at(run, dir_pin, c) == (d > 0), f"axis {a}: DIR wrong at cycle {c}"
        residuals.append(edges - TICK_CYCLES * r.ticks)
    allres = np.concatenate(residuals)
    spread = int(allres.max() - allres.min())
    print(
        f"four-axis stream: {[len(r.ticks) for r in ref]} steps; edge minus reference tick spread "
        f"{spread} cycles ({spread / 16:.3f} us) over all axes"
    )
    assert spread <= TICK_CYCLES  # every step of every axis within one tick of the reference's


def test_multi_axis_stream_replies_and_refusals(four_build: tuple[Path, str], firmware_build: None) -> None:
    build, _ = four_build
    cmds = [
        "EN 1",
        "SHAPER 2 0",
        "IMP 0 2048 0",
        "IMP 1 2048 620016",  # over the 0.62 s of a multi-axis build: refused, shaper discarded
        "SHAPER 2 0",
        "IMP 0 2048 0",
        "IMP 1 2048 620000",
        "MSEG 10000 1 1 1 1",
        "STREAM",  # empties the programme
        "MV 1 2 3",
        "MV 0 0 1641 0",
        "MSEG 10000 1 1 1 1",
        "CLEAR",
        "V 10",
        "MV 10 0 0 -5",
        "END",
    ]
    script = [(0.05 + 0.008 * i, fwsim.command(c)) for i, c in enumerate(cmds)]
    t_end = 0.05 + 0.008 * len(cmds)
    script += [(t_end + 0.8, fwsim.command("GO")), (t_end + 0.81, fwsim.command("POS"))]
    run = fwsim.run("stepper", script, t_end + 0.85, elf=build / "stepper_uno.elf")
    bodies = [ln.body for ln in run.lines if not ln.body.startswith(("HELLO", "N,"))]
    assert bodies[:9] == [
        "OK EN 1",
        "OK SHAPER 2",
        "OK IMP 0",
        "ERR RANGE delay: 0 first, rising, 16 us units, <= 0.62 s",
        "OK SHAPER 2",
        "OK IMP 0",
        "OK IMP 1",
        "OK MSEG 1",
        "OK STREAM 0",
    ]
    assert bodies[9:13] == [
        "ERR ARG MV needs 4 integers",
        "ERR RANGE axis 2 set-point -1640..1640",
        "ERR STATE streaming",
        "ERR STATE streaming",
    ]
    assert re.fullmatch(r"OK V \d+", bodies[13]) and re.fullmatch(r"OK MV \d+", bodies[14])
    assert int(bodies[14].split()[-1]) == int(bodies[13].split()[-1]) + 1
    assert re.fullmatch(r"OK END \d+", bodies[15])
    # 10 + 10 units for two periods on axis 0 (0.19 steps), -5 on axis 3 at 0: nothing moves; then the
    # programme is empty (STREAM took its table)
    assert bodies[16:] == ["DONE 0 0 0 0", "ERR STATE programme empty", "OK POS 0 0 0 0"]
