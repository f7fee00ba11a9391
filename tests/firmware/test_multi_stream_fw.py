"""Streams of several axes: the stepper firmware built for the four-tendon rig config in simavr, fed ``MV``
set-points (different per axis, one axis driven into its travel clamp), every axis's STEP edges against
the reference (``helpers.board.stream_reference.AxesRun`` through ``tests/stream_run.py``'s
``simulate_axes``) step for step (within one timer tick); the multi-axis streaming replies and refusals
(``MV``, the shorter longest delay, the programme table the stream takes).
Every stream is also sent to the emulated four-tendon stepper (``helpers.virtual.emulator.boards``):
the same lines in the same order, and every emulated step on the tick of the firmware's STEP edge.
"""

from __future__ import annotations

import random
import re
from pathlib import Path

import fwsim
import numpy as np
import pytest
import streamsim
from stream_run import PeriodCommands, StreamResult, simulate_axes

from helpers.board import stream_reference as hs

pytestmark = [pytest.mark.firmware, pytest.mark.streaming]

F = fwsim.F_CPU
TICK_CYCLES = 8
AXES = [("D5", "D6"), ("D2", "B2"), ("D3", "B3"), ("D4", "B4")]  # (STEP, DIR) of axes 0-3 on the Uno
TRAVEL = 156
RELEASE = 78  # rigs/four-tendon.toml: 20 mm below rest, floor(20 / 0.2552544) = 78 steps
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


def stream_commands(
    shaper: hs.StreamShaper, sps: list[tuple[int, ...]]
) -> tuple[list[tuple[float, str]], float]:
    """The commands (send time, body) of a stream of ``sps`` and the time by which it is over (s).

    ``EN 1``, the shaper, ``STREAM``, the first three set-points at once (a lead of about three periods),
    then one per period (sent 5 ms into each period), ``END``.
    """
    t_stream = 0.05 + 0.004 * (len(shaper.commands()) + 1)
    cmds = [(0.05 + 0.004 * i, body) for i, body in enumerate(["EN 1", *shaper.commands()])]
    cmds.append((t_stream, "STREAM"))
    times = [0.001 + 0.002 * i if i < 3 else 0.005 + 0.01 * (i - 2) for i in range(len(sps))]
    cmds += [(t_stream + t, "MV " + " ".join(map(str, v))) for t, v in zip(times, sps, strict=True)]
    cmds.append((t_stream + times[-1] + 0.003, "END"))
    return cmds, t_stream + times[-1] + 0.09 + shaper.duration_s + 0.1


def run_stream(
    build: Path, shaper: hs.StreamShaper, sps: list[tuple[int, ...]]
) -> tuple[list[StreamResult], list[np.ndarray], int, float, tuple[int, int]]:
    """Stream ``sps`` (one set-point per axis and period, from position 0) into the four-tendon build.

    Returns the reference (from the periods the board named), every axis's edge-minus-tick residuals (CPU
    cycles), the least free stack (``MEM``) and the busiest period's interrupt load (the control tick and the
    step interrupt, share of a period), and the emulated stepper's steps and spread (:func:`emulated_alike`).
    Asserts the replies, the step counts, the DIR levels, the notices and ``DONE`` against the reference, and
    the emulated four-tendon stepper's lines and steps against the firmware's.
    """
    cmds, duration = stream_commands(shaper, sps)
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
    ref = simulate_axes(
        shaper, PeriodCommands(assigned, n + 1), [0] * 4, [TRAVEL] * 4, releases=[RELEASE] * 4
    )
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
    emulated = emulated_alike(run, cmds, duration)  # the emulated four-tendon stepper too
    return ref, residuals, int(mem[1]), streamsim.isr_cycles_per_period(run).max() / (F / 100), emulated


def test_four_axis_stream_matches_the_reference_per_axis(
    four_build: tuple[Path, str], firmware_build: None
) -> None:
    sps = setpoints()
    ref, residuals, free, load, (_, emu_spread) = run_stream(four_build[0], SHAPER, sps)
    # the reference itself: axis 1 reaches its travel and is held there (by hand: 391 steps commanded)
    assert ref[1].position == TRAVEL and [n.line for n in ref[1].notices] == [f"N,LIMIT,TRAVEL,{TRAVEL},1"]
    assert all(len(r.ticks) > 20 for r in ref)
    allres = np.concatenate(residuals)
    spread = int(allres.max() - allres.min())
    print(
        f"four-axis stream: {[len(r.ticks) for r in ref]} steps; edge minus reference tick spread "
        f"{spread} cycles ({spread / 16:.3f} us) over all axes; interrupts at most {100 * load:.1f} % of a "
        f"period; least free stack {free} bytes; the emulated stepper's steps within {emu_spread} cycles of "
        "the firmware's edges (less the lead)"
    )
    assert spread <= TICK_CYCLES  # every step of every axis within one tick of the reference's


def test_four_axis_stream_pays_out_down_to_the_release(
    four_build: tuple[Path, str], firmware_build: None
) -> None:
    """Axis 2 driven down at the top speed for 10 periods (by hand: 10 x 1640 x 625 / 65536 = 156.4 steps
    commanded) is paid out below rest down to its release, -78, and held there; axis 0 goes up meanwhile."""
    sps = [(600 if i < 10 else 0, 0, -hs.V_MAX if i < 10 else 0, 0) for i in range(12)]
    ref, residuals, _, _, (emu_steps, emu_spread) = run_stream(four_build[0], SHAPER, sps)
    assert ref[2].position == -RELEASE
    assert [n.line for n in ref[2].notices] == [f"N,LIMIT,TRAVEL,-{RELEASE},2"]
    assert len(ref[2].ticks) == RELEASE and set(ref[2].directions.tolist()) == {-1}
    assert ref[0].position == 57  # 10 x 600 x 625 / 65536 = 57.2 steps
    allres = np.concatenate(residuals)
    spread = int(allres.max() - allres.min())
    print(
        f"paid-out four-axis stream: axis 2 down to {ref[2].position}, firmware edges within {spread} cycles "
        f"of the reference's ticks; the emulated stepper's {emu_steps} steps within {emu_spread} cycles"
    )
    assert spread <= TICK_CYCLES


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
    ref, residuals, free, load, (_, emu_spread) = run_stream(build, shaper, sps)
    allres = np.concatenate(residuals)
    spread = int(allres.max() - allres.min())
    assert spread <= TICK_CYCLES, f"seed {seed}: spread {spread} cycles"
    return sum(len(r.ticks) for r in ref), spread, load, free, emu_spread


def test_random_four_axis_stream(four_build: tuple[Path, str], firmware_build: None) -> None:
    steps, spread, load, free, emu_spread = _check_random(four_build[0], 7)
    print(
        f"random four-axis stream: {steps} steps, spread {spread} cycles, load {100 * load:.1f} %, "
        f"least free stack {free} bytes; emulated stepper alike, its steps within {emu_spread} cycles"
    )


@pytest.mark.slow
def test_many_random_four_axis_streams(four_build: tuple[Path, str], firmware_build: None) -> None:
    results = [_check_random(four_build[0], seed) for seed in range(100, 140)]
    print(
        f"40 random four-axis streams: {sum(r[0] for r in results)} steps, every edge within "
        f"{max(r[1] for r in results)} cycles of the reference's tick (spread), interrupts at most "
        f"{100 * max(r[2] for r in results):.1f} % of a period, least free stack "
        f"{min(r[3] for r in results)} bytes; the emulated stepper alike on every stream (spread at most "
        f"{max(r[4] for r in results)} cycles)"
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
    timed = [(0.05 + 0.008 * i, c) for i, c in enumerate(cmds)]
    t_end = 0.05 + 0.008 * len(cmds)
    timed += [(t_end + 0.8, "GO"), (t_end + 0.81, "POS"), (t_end + 0.82, "MEM")]
    run = fwsim.run("stepper", _script(timed), t_end + 0.85, elf=build / "stepper_uno.elf")
    bodies = [ln.body for ln in run.lines if not ln.body.startswith(("HELLO", "N,"))]
    # the emulated four-tendon stepper: every line alike (MEM by its form: it has no stack to measure)
    emulated, _ = emulated_stepper(timed, t_end + 0.85)
    assert _no_mem([ln.body for ln in run.lines]) == _no_mem(emulated)
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


# --- the emulated four-tendon stepper against the firmware ------------------------------------------------
STEPPER_BYTE_S = 10 / 115_200
"""One byte on the stepper's wire (RIG_STEPPER_BAUD): a command reaches the board with its last byte."""


class _Clock:
    """What an emulated board reads of its world: the device clock, a seed and the GO instants."""

    def __init__(self) -> None:
        self.t = 0.0
        self.seed = 0
        self.t0_us = 0
        self.go_times: list[float] = []


def emulated_stepper(cmds: list[tuple[float, str]], duration: float) -> tuple[list[str], list[list[float]]]:
    """The emulated four-tendon stepper (``helpers.virtual.emulator.boards``) sent ``cmds`` as the
    harness sends them (each when its last byte arrives): every line it sent, and each axis's step times
    from ``STREAM`` (s; the STEP edges)."""
    tb = pytest.importorskip("helpers.virtual.emulator.boards")
    rigfile = pytest.importorskip("helpers.rigfile")
    limits = tb.build_limits(rigfile.load(fwsim.REPO / "rigs" / "four-tendon.toml"))
    clock = _Clock()
    dev = tb.StepperEmulator(clock, limits)
    dev.reset()
    events = sorted((t + len(fwsim.command(body)) * STEPPER_BYTE_S, body) for t, body in cmds)
    steps: list[list[float]] = [[] for _ in range(limits.axes)]
    bodies: list[str] = []
    t_stream = 0.0
    for t, body in [*events, (duration, None)]:
        times, axes, _ = dev.steps_until(t)  # the control ticks, their notices and DONE come first
        for ti, a in zip(times.tolist(), axes.tolist(), strict=True):
            steps[a].append(ti - t_stream)
        clock.t = t
        if body is not None:
            dev.receive(fwsim.command(body))
        lines = [line.decode().rstrip("\n").rpartition("*")[0] for line in dev.out]
        t_stream = t if any(b.startswith("OK STREAM") for b in lines) else t_stream
        bodies += lines
        dev.out.clear()
    return bodies, steps


def _no_mem(bodies: list[str]) -> list[str]:
    return [re.sub(r"^OK MEM \d+$", "OK MEM", b) for b in bodies]


def emulated_alike(run: fwsim.SimRun, cmds: list[tuple[float, str]], duration: float) -> tuple[int, int]:
    """Send ``cmds`` to the emulated four-tendon stepper too: assert the same lines as the firmware's ``run``
    (``MEM`` by its form), the same steps per axis, each on the tick of the firmware's STEP edge (the edge
    less its constant lead) within one tick. Returns the steps and the edge-minus-tick spread (cycles)."""
    fw = [ln.body for ln in run.lines]
    emu, emu_steps = emulated_stepper(cmds, duration)
    assert _no_mem(fw) == _no_mem(emu)
    stream_cycle = next(ln.cycle for ln in run.lines if ln.body.startswith("OK STREAM"))
    edges = [[c for c, p, lv in run.pins if p == step and lv == 1 and c >= stream_cycle] for step, _ in AXES]
    assert [len(e) for e in edges] == [len(s) for s in emu_steps]
    lead = 24e-6  # the emulated steps are the STEP edges, 24 us after their ticks
    offsets = [
        c - TICK_CYCLES * round((t - lead) / hs.TICK_S)
        for got, want in zip(edges, emu_steps, strict=True)
        for c, t in zip(got, want, strict=True)
    ]
    spread = max(offsets) - min(offsets) if offsets else 0
    assert spread <= TICK_CYCLES, f"emulated steps off the firmware's ticks: spread {spread} cycles"
    return len(offsets), spread


def test_emulated_four_axis_stream_follows_the_firmware_tick_for_tick(
    four_build: tuple[Path, str], firmware_build: None
) -> None:
    """The 30-period four-axis MV stream above, with refusals in mid-stream (an MV short of an axis, one out
    of range, programme edits, a shaper while streaming), in simavr and on the emulated board: the same lines
    in the same order (replies, per-axis notices, DONE with every axis), and every emulated step on the tick
    of the firmware's STEP edge (the edge less its constant lead)."""
    build, _ = four_build
    cmds, duration = stream_commands(SHAPER, setpoints())
    t_stream = next(t for t, b in cmds if b == "STREAM")
    refusals = ["MV 1 2 3", "MV 0 0 1641 0", "SEG 1 1 1000", "MSEG 10000 1 1 1 1", "WAIT 5", "CLEAR",
                "SHAPER 1 0", "IMP 0 4096 0", "STREAM", "GO"]  # fmt: skip
    # 8 ms into periods 3, 5, ...: after that period's MV has been answered, well before the next tick
    cmds += [(t_stream + 0.028 + 0.02 * j, body) for j, body in enumerate(refusals)]
    cmds += [(duration, "POS"), (duration + 0.01, "GO"), (duration + 0.02, "V 5")]
    cmds.sort()
    duration += 0.05
    watch = [step for step, _ in AXES]
    run = fwsim.run("stepper", _script(cmds), duration, watch=watch, elf=build / "stepper_uno.elf")
    assert all(ln.checksum_ok for ln in run.lines)
    steps, spread = emulated_alike(run, cmds, duration)
    fw = [ln.body for ln in run.lines]
    # what the script is about (by hand): the ten refusals in order, axis 1 held at its travel, the end
    errors = [b for b in fw if b.startswith("ERR")]
    assert (
        errors[:10]
        == ["ERR ARG MV needs 4 integers", "ERR RANGE axis 2 set-point -1640..1640"]
        + ["ERR STATE streaming"] * 8
    )
    assert "N,LIMIT,TRAVEL,156,1" in fw
    assert fw[-4].startswith("DONE ") and fw[-3] == fw[-4].replace("DONE", "OK POS")
    assert int(fw[-4].split()[2]) == 156  # axis 1: up to its travel and held there
    assert fw[-2:] == ["ERR STATE programme empty", "ERR STATE not streaming"]
    print(
        f"emulated four-axis stream: {steps} steps, {len(fw)} lines alike; firmware edge minus emulated tick "
        f"spread {spread} cycles ({spread / 16:.3f} us)"
    )


def test_emulated_four_axis_watchdog_like_the_firmware(
    four_build: tuple[Path, str], firmware_build: None
) -> None:
    """Five MV periods then silence: the watchdog fires after 10 periods without one (period 16), feeds zero,
    stops (DONE with every axis) and disables the driver, on both; then MV and STREAM are refused."""
    build, _ = four_build
    shaper = hs.StreamShaper((2048, 2048), (0, 50_000))
    cmds = [(0.05, "EN 1")] + [(0.054 + 0.004 * i, b) for i, b in enumerate(shaper.commands())]
    t_stream = 0.07
    cmds.append((t_stream, "STREAM"))
    cmds += [(t_stream + 0.005 + 0.01 * i, f"MV 900 0 -300 {300 * i}") for i in range(5)]
    cmds += [(t_stream + 0.5, "MV 1 1 1 1"), (t_stream + 0.51, "POS"), (t_stream + 0.52, "STREAM")]
    duration = t_stream + 0.55
    watch = [step for step, _ in AXES]
    run = fwsim.run("stepper", _script(cmds), duration, watch=watch, elf=build / "stepper_uno.elf")
    steps, spread = emulated_alike(run, cmds, duration)
    fw = [ln.body for ln in run.lines]
    # by hand: set-points for periods 1-5; periods 6-15 underrun, the 11th in a row (period 16) is the
    # watchdog's; axis 2 is driven down from 0 and pays out below rest: 5 x 300 x 625 / 65536 = 14.3 steps,
    # the count within one step of it (-14), inside its release (78)
    assert "N,WATCHDOG,16" in fw and not any(b.startswith("N,LIMIT,TRAVEL") for b in fw)
    assert fw[-3:] == ["ERR STATE not streaming", fw[-2], "ERR STATE driver disabled"]
    assert fw[-2].startswith("OK POS ") and fw[-2].split()[2 + 2] == "-14"  # axis 2
    print(f"emulated four-axis watchdog: {steps} steps alike (spread {spread} cycles), {len(fw)} lines alike")
