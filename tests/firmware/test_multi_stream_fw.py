"""Streams of several axes: the stepper firmware built for the four-tendon rig config in simavr, fed ``MV``
set-points (different per axis, one axis driven into its travel clamp), every axis's STEP edges against
``helpers.board.stream_reference.simulate_axes`` step for step (within one timer tick); the multi-axis
streaming replies and refusals (``MV``, the shorter longest delay, the programme table the stream takes).
"""

from __future__ import annotations

import random
import re
from pathlib import Path

import fwsim
import numpy as np
import pytest
import streamsim

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


def _level_at(edges: list[tuple[int, int]], cycle: int) -> int:
    level = 0
    for c, lv in edges:
        if c > cycle:
            break
        level = lv
    return level


def run_stream(
    build: Path, shaper: hs.StreamShaper, sps: list[tuple[int, ...]]
) -> tuple[list[hs.StreamResult], list[np.ndarray], int, float]:
    """Stream ``sps`` (one set-point per axis and period, from position 0) into the four-tendon build.

    Returns the reference (from the periods the board named), every axis's edge-minus-tick residuals (CPU
    cycles), the least free stack (``MEM``) and the busiest period's interrupt load (the control tick and the
    step interrupt, share of a period). Asserts the replies, the step counts, the DIR levels, the notices and
    ``DONE`` against the reference.
    """
    t_stream = 0.05 + 0.004 * (len(shaper.commands()) + 1)
    cmds = [(0.05 + 0.004 * i, body) for i, body in enumerate(["EN 1", *shaper.commands()])]
    cmds.append((t_stream, "STREAM"))
    # the first three set-points at once (a lead of about three periods), then one per period
    times = [0.001 + 0.002 * i if i < 3 else 0.005 + 0.01 * (i - 2) for i in range(len(sps))]
    cmds += [(t_stream + t, "MV " + " ".join(map(str, v))) for t, v in zip(times, sps, strict=True)]
    cmds.append((t_stream + times[-1] + 0.003, "END"))
    duration = t_stream + times[-1] + 0.09 + shaper.duration_s + 0.1
    cmds.append((duration, "MEM"))  # the least free stack over the stream
    duration += 0.01
    watch = [p for pair in AXES for p in pair] + ["B0", "B1"]
    run = fwsim.run("stepper", _script(cmds), duration, watch=watch, elf=build / "stepper_uno.elf")
    assert all(ln.checksum_ok for ln in run.lines)
    stream_cycle = next(ln.cycle for ln in run.lines if ln.body == "OK STREAM 0")
    after = [ln.body for ln in run.lines if ln.cycle >= stream_cycle]
    mem = re.fullmatch(r"OK MEM (\d+)", after.pop())
    assert mem and int(mem[1]) >= 256, mem  # the stack margin the RAM budget keeps (PROTOCOL.md)
    replies = [b for b in after if not b.startswith(("N,", "DONE"))]
    n = len(sps)
    assert len(replies) == n + 2, replies
    assigned: dict[int, tuple[int, ...]] = {}
    for v, reply in zip(sps, replies[1 : n + 1], strict=True):
        m = re.fullmatch(r"OK MV (\d+)", reply)
        assert m, reply
        assigned[int(m[1])] = v
    assert sorted(assigned) == list(range(1, n + 1))  # no underrun: one set-point per period 1..n
    assert replies[n + 1] == f"OK END {n + 1}"
    ref = hs.simulate_axes(shaper, hs.PeriodCommands(assigned, n + 1), [0] * 4, [TRAVEL] * 4)
    assert after[-1] == "DONE " + " ".join(str(r.position) for r in ref)
    assert sorted(b for b in after if b.startswith("N,")) == sorted(n.line for r in ref for n in r.notices)
    residuals = []
    for a, ((step, dir_pin), r) in enumerate(zip(AXES, ref, strict=True)):
        edges = np.array(
            [c for c, p, lv in run.pins if p == step and lv == 1 and c >= stream_cycle], dtype=np.int64
        )
        assert len(edges) == len(r.ticks), f"axis {a}: {len(edges)} steps, reference {len(r.ticks)}"
        dir_edges = [(c, lv) for c, p, lv in run.pins if p == dir_pin]
        for c, d in zip(edges, r.directions, strict=True):
            assert _level_at(dir_edges, int(c)) == (d > 0), f"axis {a}: DIR wrong at cycle {c}"
            assert _level_at(dir_edges, int(c) - 5 * 16) == (d > 0), f"axis {a}: DIR set late at {c}"
        residuals.append(edges - TICK_CYCLES * r.ticks)
    return ref, residuals, int(mem[1]), streamsim.isr_cycles_per_period(run).max() / (F / 100)


def test_four_axis_stream_matches_the_reference_per_axis(
    four_build: tuple[Path, str], firmware_build: None
) -> None:
    sps = setpoints()
    ref, residuals, free, load = run_stream(four_build[0], SHAPER, sps)
    # the reference itself: axis 1 reaches its travel and is held there (by hand: 391 steps commanded)
    assert ref[1].position == TRAVEL and [n.line for n in ref[1].notices] == [f"N,LIMIT,TRAVEL,{TRAVEL},1"]
    assert all(len(r.ticks) > 20 for r in ref)
    allres = np.concatenate(residuals)
    spread = int(allres.max() - allres.min())
    print(
        f"four-axis stream: {[len(r.ticks) for r in ref]} steps; edge minus reference tick spread "
        f"{spread} cycles ({spread / 16:.3f} us) over all axes; interrupts at most {100 * load:.1f} % of a "
        f"period; least free stack {free} bytes"
    )
    assert spread <= TICK_CYCLES  # every step of every axis within one tick of the reference's


def random_stream(rnd: random.Random) -> tuple[hs.StreamShaper, list[tuple[int, ...]]]:
    """A random shaper (1-8 impulses, delays up to 0.62 s) and 20-40 periods of set-points per axis."""
    n = rnd.randint(1, 8)
    delays = sorted(rnd.sample(range(1, hs.MAX_DELAY_US_AXES // 16 + 1), n - 1))
    cuts = sorted(rnd.randint(0, 4096) for _ in range(n - 1))
    amps = [b - a for a, b in zip([0, *cuts], [*cuts, 4096], strict=True)]
    shaper = hs.StreamShaper(tuple(amps), (0, *(16 * d for d in delays)))
    periods = rnd.randint(20, 40)
    sps = []
    levels = [rnd.randint(-hs.V_MAX, hs.V_MAX) for _ in AXES]
    for _ in range(periods):
        levels = [v if rnd.random() < 0.8 else rnd.randint(-hs.V_MAX, hs.V_MAX) for v in levels]
        sps.append(tuple(levels))
    return shaper, sps


def _check_random(build: Path, seed: int) -> tuple[int, int, float, int]:
    shaper, sps = random_stream(random.Random(seed))
    ref, residuals, free, load = run_stream(build, shaper, sps)
    allres = np.concatenate(residuals)
    spread = int(allres.max() - allres.min())
    assert spread <= TICK_CYCLES, f"seed {seed}: spread {spread} cycles"
    return sum(len(r.ticks) for r in ref), spread, load, free


def test_random_four_axis_stream(four_build: tuple[Path, str], firmware_build: None) -> None:
    steps, spread, load, free = _check_random(four_build[0], 7)
    print(
        f"random four-axis stream: {steps} steps, spread {spread} cycles, load {100 * load:.1f} %, "
        f"least free stack {free} bytes"
    )


@pytest.mark.slow
def test_many_random_four_axis_streams(four_build: tuple[Path, str], firmware_build: None) -> None:
    results = [_check_random(four_build[0], seed) for seed in range(100, 140)]
    print(
        f"40 random four-axis streams: {sum(r[0] for r in results)} steps, every edge within "
        f"{max(r[1] for r in results)} cycles of the reference's tick (spread), interrupts at most "
        f"{100 * max(r[2] for r in results):.1f} % of a period, least free stack "
        f"{min(r[3] for r in results)} bytes"
    )


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
    script += [(t_end + 0.82, fwsim.command("MEM"))]
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
    assert bodies[16:19] == ["DONE 0 0 0 0", "ERR STATE programme empty", "OK POS 0 0 0 0"]
    free = int(re.fullmatch(r"OK MEM (\d+)", bodies[19])[1])
    print(f"least free stack after a four-axis stream: {free} bytes")
    assert free >= 256  # the margin the RAM budget keeps (firmware/PROTOCOL.md)
