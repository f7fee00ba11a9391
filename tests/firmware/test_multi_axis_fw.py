"""Several tendons: the firmware built for a four-tendon rig config
(``firmware/common/rig_config_four_tendon.h``) in simavr: RAM budgets, compile-time refusal of configs that do
not fit, coordinated four-axis programmes on the pins (every step within one timer tick of the programme, per
axis), per-axis limits, the one-axis commands on axis 0, and four-channel DAQ frames with each tendon's step
count; the link budget at 1 Mbaud through the harness's pseudo-terminal (``-m slow``: 60 s of device time);
a short four-tendon firmware-in-the-loop run (``fil4.py``: both sketches driving the spatial twin, sample by
sample).
"""

from __future__ import annotations

import math
import random
import re
import subprocess
import time
from pathlib import Path

import fwsim
import pytest

from helpers.rigfile import capacity

pytestmark = pytest.mark.firmware

F = fwsim.F_CPU
TICK_CYCLES = 8  # Timer1 /8: one tick is 0.5 us = 8 cycles
FOUR = fwsim.FIRMWARE / "common" / "rig_config_four_tendon.h"
TRAVEL = 156
RELEASE = 78  # rigs/four-tendon.toml: 20 mm below rest, floor(20 / 0.2552544) = 78 steps
# (STEP, DIR) pins of the four axes on the Uno, and their inputs on the Mega (firmware/PROTOCOL.md)
UNO_AXES = [("D5", "D6"), ("D2", "B2"), ("D3", "B3"), ("D4", "B4")]
MEGA_AXES = [("E4", "G5"), ("E5", "E3"), ("D2", "A1"), ("D3", "A3")]
_RAM = re.compile(
    r"^(daq_mega|stepper_uno): .* (\d+) B RAM \(data \+ bss\) of (\d+) B "
    r"\(([\d.]+)%, goal <= 80%: (\w+)\) \[(.+)\]$",
    re.M,
)


def _make(*args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run(
        ["make", "-C", str(fwsim.FIRMWARE), "-j2", *args],
        capture_output=True,
        text=True,
        check=False,
        timeout=timeout,
    )


def ram_lines(output: str) -> dict[str, tuple[int, int, float, str, str]]:
    return {m[0]: (int(m[1]), int(m[2]), float(m[3]), m[4], m[5]) for m in _RAM.findall(output)}


def test_ram_budgets_printed_and_within_goal(four_build: tuple[Path, str], firmware_build: None) -> None:
    _, out = four_build
    four = ram_lines(out)
    paper = ram_lines(_make("size").stdout)
    for name, lines in (("four-tendon", four), ("paper", paper)):
        assert set(lines) == {"daq_mega", "stepper_uno"}, f"{name}: RAM budget lines missing"
        for board, (used, ram, pct, verdict, _) in lines.items():
            assert ram == {"daq_mega": 8192, "stepper_uno": 2048}[board]
            assert abs(pct - 100.0 * used / ram) < 0.06
            assert pct <= 80.0 and verdict == "met", f"{name} {board}: {used} B of {ram} B"
        print(
            f"{name}: " + ", ".join(f"{b} {u} B ({p:.1f} %)" for b, (u, _, p, _, _) in sorted(lines.items()))
        )
    assert (
        four["stepper_uno"][4] == "rig_config_four_tendon.h"
        and paper["stepper_uno"][4] == "rig_config_paper.h"
    )
    # the host's model of the stepper's static RAM (helpers.rigfile.capacity) is the build's, to the byte
    assert four["stepper_uno"][0] == capacity.stepper_ram(4, 639, 64).static_bytes
    assert paper["stepper_uno"][0] == capacity.stepper_ram(1, 639, 64).static_bytes
    # four axes and four channels cost RAM: the tables grow with the config
    assert four["stepper_uno"][0] > paper["stepper_uno"][0] and four["daq_mega"][0] > paper["daq_mega"][0]


def _header(**changes: str) -> str:
    text = FOUR.read_text()
    for name, value in changes.items():
        if value == "":
            text = re.sub(rf"^#define {name} .*$", "", text, flags=re.M)
        else:
            text, n = re.subn(rf"^#define {name} .*$", f"#define {name} {value}", text, flags=re.M)
            assert n == 1, name
    return text


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"RIG_PROGRAMME_MAX": "200"}, "does not fit the Uno's RAM"),
        ({"RIG_AXES": "5"}, "RIG_AXES must be 1-4"),
        ({"RIG_HASH": ""}, "RIG_HASH, RIG_NAME, RIG_AXES and RIG_CHANNELS are required"),
        ({"RIG_AXIS_TRAVEL_STEPS": "{156, 156}"}, "RIG_AXIS_TRAVEL_STEPS needs RIG_AXES values"),
        ({"RIG_AXIS_RELEASE_STEPS": "{78, 78}"}, "RIG_AXIS_RELEASE_STEPS needs RIG_AXES values"),
        ({"RIG_AXIS_RELEASE_STEPS": "{78, 78, 100, 78}"}, "must be <= 255 per axis"),  # 100 + 156 = 256
        ({"RIG_MIN_INTERVAL_US": "100"}, "step intervals must satisfy"),
    ],
)
def test_config_refused_at_compile_time(tmp_path: Path, changes: dict, message: str) -> None:
    header = tmp_path / "bad_rig.h"
    header.write_text(_header(**changes))
    build = tmp_path / "build"
    proc = _make(f"RIG_CONFIG={header}", f"BUILD={build}", f"{build}/stepper_uno/stepper_uno.o", timeout=120)
    assert proc.returncode != 0
    assert message in proc.stderr, proc.stderr[-2000:]


def test_make_rig_generates_the_header_then_builds_with_it(tmp_path: Path) -> None:
    """``make RIG=rigfile`` runs ``$(PYTHON) -m helpers.rigfile.firmware_header RIG -o $(BUILD)/rig_config.h``
    from the repository root before any rule (a stand-in interpreter here records its arguments and writes the
    header); a generator that fails stops make with its line, before anything compiles."""
    rig = tmp_path / "rig.json"
    rig.write_text("{}")
    log = tmp_path / "args.txt"
    fake = tmp_path / "fakepython"
    fake.write_text(
        f'#!/bin/sh\necho "$PWD $@" > {log}\nwhile [ "$1" != "-o" ]; do shift; done\ncp {FOUR} "$2"\n'
    )
    fake.chmod(0o755)
    build = tmp_path / "build"
    target = f"{build}/stepper_uno/stepper_uno.o"
    proc = _make(f"RIG={rig}", f"PYTHON={fake}", f"BUILD={build}", target, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    cwd, *args = log.read_text().split()
    assert Path(cwd) == fwsim.REPO
    assert args == ["-m", "helpers.rigfile.firmware_header", str(rig), "-o", f"{build}/rig_config.h"]
    assert (build / "rig_config.h").read_text() == FOUR.read_text()
    assert (build / "rig_config.path").read_text().strip() == str(build / "rig_config.h")
    assert Path(target).stat().st_size > 0
    # a generator that fails stops the build
    fake.write_text("#!/bin/sh\necho 'rig file: bad tendon count' >&2\nexit 2\n")
    proc = _make(f"RIG={rig}", f"PYTHON={fake}", f"BUILD={tmp_path / 'b2'}", "firmware", timeout=120)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "bad tendon count" in proc.stderr
    assert not list((tmp_path / "b2").rglob("*.o"))


def _stepper(build: Path, cmds: list[str], duration: float, spacing: float = 0.02) -> fwsim.SimRun:
    times = [0.05 + spacing * i for i in range(len(cmds))]
    watch = [p for pair in UNO_AXES for p in pair] + ["D7"]
    script = list(zip(times, (fwsim.command(c) for c in cmds), strict=True))
    return fwsim.run("stepper", script, duration, watch=watch, elf=build / "stepper_uno.elf")


def _rising(run: fwsim.SimRun, pin: str) -> list[int]:
    return [c for c, p, lv in run.pins if p == pin and lv == 1]


def _level_at(run: fwsim.SimRun, pin: str, cycle: int) -> int:
    level = 0
    for c, p, lv in run.pins:
        if p == pin and c <= cycle:
            level = lv
    return level


PROGRAMME = [  # (window_us, steps of axes 0-3): coincident steps, one idle axis, a lone axis, returns
    (100_000, (10, 7, 3, 0)),
    (40_000, (20, 20, 1, 40)),
    (156_000, (-30, -27, -4, -40)),
]


def test_four_axis_programme_steps_within_one_tick(
    four_build: tuple[Path, str], firmware_build: None
) -> None:
    build, _ = four_build
    cmds = ["PING", "CONFIG", "EN 1"] + [f"MSEG {w} " + " ".join(map(str, n)) for w, n in PROGRAMME] + ["GO"]
    run = _stepper(build, cmds, 0.2 + sum(w for w, _ in PROGRAMME) / 1e6 + 0.1)
    bodies = [ln.body for ln in run.lines]
    assert all(ln.checksum_ok for ln in run.lines)
    assert bodies[:8] == [
        "HELLO stepper 2.3.0+d09e5115",
        "PONG stepper 2.3.0+d09e5115",
        "OK CONFIG 4 64 639 1000000 156 156 156 156 78 78 78 78",
        "OK EN 1",
        "OK MSEG 1",
        "OK MSEG 2",
        "OK MSEG 3",
        "OK GO 3",
    ]
    assert bodies[8:] == ["DONE 0 0 0 0"]
    # PROTOCOL.md: step k of n in a window of W ticks falls on the first tick at or after k * W / n from the
    # window's start (the exact time); its STEP edge follows the tick by a constant lead (16 us, four axes)
    expected: list[list[tuple[int, float, int]]] = [[] for _ in UNO_AXES]  # (tick, exact tick, pull)
    t0 = 0
    for window, steps in PROGRAMME:
        w = 2 * window
        for a, n in enumerate(steps):
            m = abs(n)
            expected[a] += [(t0 - (-k * w // m), t0 + k * w / m, int(n > 0)) for k in range(1, m + 1)]
        t0 += w
    edges = [_rising(run, step) for step, _ in UNO_AXES]
    for a, (exp, got) in enumerate(zip(expected, edges, strict=True)):
        assert len(got) == len(exp), f"axis {a}: {len(got)} steps, expected {len(exp)}"
    # GO on the simulated clock, from the median offset of the edges from their ticks (the edges jitter by
    # the busy-wait's granularity on TCNT1, up to one tick)
    offsets = sorted(
        c - 128 - t * TICK_CYCLES
        for exp, got in zip(expected, edges, strict=True)
        for (t, _, _), c in zip(exp, got, strict=True)
    )
    origin = offsets[len(offsets) // 2]
    worst = 0.0
    for a, (exp, got) in enumerate(zip(expected, edges, strict=True)):
        for (tick, exact, pull), cycle in zip(exp, got, strict=True):
            at = cycle - 128 - origin  # cycles from GO, less the lead
            assert abs(at - tick * TICK_CYCLES) <= TICK_CYCLES, (
                f"axis {a}: step at tick {at / 8:.2f}, not {tick}"
            )
            worst = max(worst, abs(at - exact * TICK_CYCLES))
            assert _level_at(run, UNO_AXES[a][1], cycle) == pull, f"axis {a}: DIR wrong at tick {tick}"
            assert _level_at(run, UNO_AXES[a][1], cycle - 600 * 16) == pull  # DIR set up early enough
    spread = offsets[-1] - offsets[0]
    assert spread <= TICK_CYCLES  # every step on its tick within one tick (as the streaming tests measure)
    print(
        f"four axes, {len(offsets)} steps: edge-minus-tick spread {spread} cycles ({spread / 16:.3f} us), "
        f"|edge - exact programme| <= {worst / 16:.3f} us"
    )
    assert _level_at(run, "D7", edges[0][0]) == 0  # ENA LOW (enabled) while stepping


DENSE = [  # nearly equal step counts at the top speed: steps of different axes 8 ticks (4 us) apart
    (99_684, (156, 155, 154, 153)),
    (99_684, (-156, -155, -154, -153)),
]


def test_dense_four_axis_programme(four_build: tuple[Path, str], firmware_build: None) -> None:
    """Steps of different axes a few ticks apart are each raised at their own tick (one interrupt serves a
    cluster); only the third of three steps within about 10 ticks can be up to 3 ticks late."""
    build, _ = four_build
    cmds = ["EN 1"] + [f"MSEG {w} " + " ".join(map(str, n)) for w, n in DENSE] + ["GO"]
    run = _stepper(build, cmds, 0.1 + sum(w for w, _ in DENSE) / 1e6 + 0.1)
    assert [ln.body for ln in run.lines][-1] == "DONE 0 0 0 0"
    ticks: list[list[int]] = [[] for _ in UNO_AXES]
    t0 = 0
    for window, steps in DENSE:
        w = 2 * window
        for a, n in enumerate(steps):
            ticks[a] += [t0 - (-k * w // abs(n)) for k in range(1, abs(n) + 1)]
        t0 += w
    edges = [_rising(run, step) for step, _ in UNO_AXES]
    assert [len(e) for e in edges] == [len(t) for t in ticks] == [312, 310, 308, 306]
    offsets = sorted(
        c - 128 - t * TICK_CYCLES
        for ts, es in zip(ticks, edges, strict=True)
        for t, c in zip(ts, es, strict=True)
    )
    origin = offsets[len(offsets) // 2]
    late = [o - origin for o in offsets]
    within_one = sum(1 for o in late if abs(o) <= TICK_CYCLES)
    print(
        f"dense: {len(late)} steps, {within_one} within one tick of their tick, the others at most "
        f"{max(late) / 16:.3f} us late"
    )
    assert min(late) >= -TICK_CYCLES and max(late) <= 4 * TICK_CYCLES
    assert within_one >= 0.98 * len(late)


def random_programme(rnd: random.Random) -> tuple[list[str], list[list[int]], list[int], float]:
    """A random four-axis programme within the limits: commands, each axis's step ticks (PROTOCOL.md's rule,
    from GO), the final positions and the duration (s)."""
    pos = [0, 0, 0, 0]
    cmds, ticks, t0 = ["EN 1"], [[] for _ in UNO_AXES], 0
    for _ in range(rnd.randint(2, 6)):
        if rnd.random() < 0.2 and any(ticks):  # a dwell (after some motion)
            ms = rnd.randint(0, 30)
            cmds.append(f"WAIT {ms}")
            t0 += 2000 * ms
            continue
        steps = [
            0 if rnd.random() < 0.2 else rnd.randint(max(-RELEASE - p, -60), min(TRAVEL - p, 60)) for p in pos
        ]
        if not any(steps):
            steps[0] = 1 if pos[0] < TRAVEL else -1
        fastest, slowest = max(map(abs, steps)), min(abs(n) for n in steps if n)
        window = rnd.randint(fastest * 639, min(slowest * 1_000_000, fastest * 639 * 3 + 5000))
        cmds.append(f"MSEG {window} " + " ".join(map(str, steps)))
        for a, n in enumerate(steps):
            ticks[a] += [t0 - (-k * 2 * window // abs(n)) for k in range(1, abs(n) + 1)]
            pos[a] += n
        t0 += 2 * window
    return cmds + ["GO"], ticks, pos, t0 / 2e6


def _check_random(build: Path, seed: int) -> tuple[int, int]:
    cmds, ticks, pos, duration = random_programme(random.Random(seed))
    run = _stepper(build, cmds, 0.07 + 0.02 * len(cmds) + duration)
    assert [ln.body for ln in run.lines][-1] == "DONE " + " ".join(map(str, pos)), seed
    edges = [_rising(run, step) for step, _ in UNO_AXES]
    assert [len(e) for e in edges] == [len(t) for t in ticks], seed
    offsets = sorted(
        c - 128 - t * TICK_CYCLES
        for ts, es in zip(ticks, edges, strict=True)
        for t, c in zip(ts, es, strict=True)
    )
    spread = offsets[-1] - offsets[0]
    assert spread <= TICK_CYCLES, f"seed {seed}: edge-minus-tick spread {spread} cycles"
    return len(offsets), spread


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_four_axis_programmes(four_build: tuple[Path, str], firmware_build: None, seed: int) -> None:
    """Random programmes (2-6 items, dwells, 0-60 steps per axis and item, windows from the top speed up):
    every step issued, each on its tick within one tick, the positions in DONE."""
    _check_random(four_build[0], seed)


@pytest.mark.slow
def test_many_random_four_axis_programmes(four_build: tuple[Path, str], firmware_build: None) -> None:
    results = [_check_random(four_build[0], seed) for seed in range(100, 160)]
    print(
        f"60 random four-axis programmes, {sum(n for n, _ in results)} steps: edge-minus-tick spread at most "
        f"{max(s for _, s in results)} cycles"
    )


def test_per_axis_limits_refused_before_moving(four_build: tuple[Path, str], firmware_build: None) -> None:
    build, _ = four_build
    cmds = [
        "EN 1",
        "MSEG 200000 10 7 235 0",  # axis 2 past its release and travel (78 + 156) in one item
        "MSEG 10000 0 16 0 0",  # axis 1 faster than 639 us per step
        "MSEG 10000000 0 0 0 5",  # axis 3 slower than one step per second
        "MSEG 100000 0 0 0",  # one number short
        "MSEG 100000 0 0 0 0",  # nothing moves
        "MSEG 200000 100 100 100 100",
        "MSEG 200000 50 50 50 57",  # axis 3 would reach 157
        "GO",
        "POS",
        "SEG 1 235 1000",  # the one-axis command: axis 0's release and travel, as MSEG
    ]
    run = _stepper(build, cmds, 0.05 + 0.02 * len(cmds) + 0.05)
    assert [ln.body for ln in run.lines][1:] == [
        "OK EN 1",
        "ERR RANGE axis 2 steps -234..234",
        "ERR RANGE axis 1 interval 639-1000000 us",
        "ERR RANGE axis 3 interval 639-1000000 us",
        "ERR ARG MSEG needs 5 integers",
        "ERR RANGE no axis moves (a dwell is WAIT)",
        "OK MSEG 1",
        "OK MSEG 2",
        "ERR RANGE axis 3 travel -78-156 steps",
        "OK POS 0 0 0 0",
        "ERR RANGE n_steps 1-234",
    ]
    for step, _ in UNO_AXES:
        assert _rising(run, step) == [], f"{step} moved"


PAID_OUT = [  # below rest: axis 2 to the end of its release, axis 3 a little, axis 0 up; then back
    (100_000, (20, 0, -78, -5)),
    (100_000, (-20, 0, 78, 5)),
]


def test_paid_out_axes_go_down_to_the_release_like_the_emulated_board(
    four_build: tuple[Path, str], firmware_build: None
) -> None:
    """GO accepts a programme down to -78 (the release) and refuses one step further, naming the axis and
    the travel -78-156; the emulated four-tendon stepper replies alike and steps on the firmware's ticks."""
    build, _ = four_build
    cmds = ["EN 1", f"MSEG {PAID_OUT[0][0]} " + " ".join(map(str, PAID_OUT[0][1])), "GO"]
    cmds += ["CLEAR", "MSEG 10000 0 0 -1 0", "GO", "POS", "CLEAR"]
    cmds += [f"MSEG {PAID_OUT[1][0]} " + " ".join(map(str, PAID_OUT[1][1])), "GO"]
    duration = 0.05 + 0.11 * len(cmds) + 0.15  # 110 ms apart: each programme (100 ms) is done before the next
    run = _stepper(build, cmds, duration, spacing=0.11)
    fw = [ln.body for ln in run.lines]
    emu, emu_steps = _emulated("stepper", cmds, duration, spacing=0.11)
    assert fw == emu
    assert fw[1:] == [
        "OK EN 1", "OK MSEG 1", "OK GO 1", "DONE 20 0 -78 -5", "OK CLEAR", "OK MSEG 1",
        "ERR RANGE axis 2 travel -78-156 steps", "OK POS 20 0 -78 -5", "OK CLEAR", "OK MSEG 1", "OK GO 1",
        "DONE 0 0 0 0",
    ]  # fmt: skip
    edges = [_rising(run, step) for step, _ in UNO_AXES]
    assert [len(e) for e in edges] == [len(s) for s in emu_steps] == [40, 0, 156, 10]
    for c in edges[2][:78]:  # the pay-out: DIR low (release) at each of axis 2's first 78 edges
        assert _level_at(run, UNO_AXES[2][1], c) == 0
    # each GO's steps (the emulated ones from that GO) share one origin: GO on the simulated clock
    second_go = [ln.cycle for ln in run.lines if ln.body == "OK GO 1"][1]
    groups: tuple[list[int], list[int]] = ([], [])
    for got, want in zip(edges, emu_steps, strict=True):
        for c, t in zip(got, want, strict=True):
            groups[c > second_go].append(c - 128 - 8 * round(t * 2e6))
    for group in groups:
        origin = sorted(group)[len(group) // 2]
        assert max(abs(o - origin) for o in group) <= TICK_CYCLES


def test_one_axis_commands_drive_axis_zero(four_build: tuple[Path, str], firmware_build: None) -> None:
    build, _ = four_build
    run = _stepper(build, ["EN 1", "SEG 1 5 1000", "WAIT 10", "SEG -1 2 700", "GO", "POS", "ABORT"], 0.25)
    assert [ln.body for ln in run.lines][1:] == [
        "OK EN 1",
        "OK SEG 1",
        "OK WAIT 2",
        "OK SEG 3",
        "OK GO 3",
        "DONE 3 0 0 0",
        "OK POS 3 0 0 0",
        "ABORTED 3 0 0 0",
    ]
    got = _rising(run, "D5")
    assert len(got) == 7 and [len(_rising(run, s)) for s, _ in UNO_AXES[1:]] == [0, 0, 0]
    gaps_us = [(b - a) / 16 for a, b in zip(got, got[1:], strict=False)]
    expected = [1000.0] * 4 + [10_000 + 700.0, 700.0]
    assert all(abs(g - e) <= 0.5 for g, e in zip(gaps_us, expected, strict=True)), gaps_us


def test_stream_drives_axis_zero_of_four(four_build: tuple[Path, str], firmware_build: None) -> None:
    build, _ = four_build
    cmds = ["SHAPER 1 0", "IMP 0 4096 0", "EN 1", "STREAM"] + ["V 1000"] * 10 + ["END"]
    run = _stepper(build, cmds, 0.5, spacing=0.01)
    assert [ln.body for ln in run.lines][-1] == "DONE 95 0 0 0"
    # ten 10 ms periods at 1000 x 2^-16 step per 16 us: 95.37 steps, of which the count issues the whole ones
    assert len(_rising(run, "D5")) == math.floor(10 * 1000 * 625 / 2**16) == 95
    assert [len(_rising(run, s)) for s, _ in UNO_AXES[1:]] == [0, 0, 0]


def _mv(t: float, ch: int) -> float:
    """Four distinct waveforms (mV): ramps and a triangle, within 0-5 V."""
    return [500 + 4000 * t, 4500 - 3000 * t, 2500 + 2000 * abs(((4 * t) % 2) - 1) - 1000, 300 + 4200 * t * t][
        ch
    ]


def test_four_channel_daq_frames(four_build: tuple[Path, str], firmware_build: None) -> None:
    build, _ = four_build
    wave = [(k / 200, *(_mv(k / 200, c) for c in range(4))) for k in range(201)]
    # each axis: a DIR level, then pulses 0.5 ms after every other sample instant (away from them)
    edges: list[tuple[float, str, int]] = []
    pulses: list[list[tuple[float, int]]] = [[] for _ in MEGA_AXES]
    for a, (step, dirpin) in enumerate(MEGA_AXES):
        sign = 1 if a % 2 == 0 else -1
        edges.append((0.06, dirpin, 1 if sign > 0 else 0))
        for k in range(5 * (a + 1)):
            t = 0.1005 + 0.002 * k + 0.03 * a
            edges += [(t, step, 1), (t + 10e-6, step, 0)]
            pulses[a].append((t, sign))
    edges.sort(key=lambda e: e[0])
    cmds = [(0.02, fwsim.command("CONFIG")), (0.03, fwsim.command("START")), (0.6, fwsim.command("STOP"))]
    run = fwsim.run("daq", cmds, 0.7, wave=wave, edges=edges, elf=build / "daq_mega.elf")
    assert all(ln.checksum_ok for ln in run.lines)
    replies = [ln.body for ln in run.replies()]
    data = [ln.body.split(",")[1:] for ln in run.lines if ln.body.startswith("D,")]
    assert replies[1:3] == ["OK CONFIG 4 4 100 2000", "OK START 1000"]
    assert replies[3:] == [f"OK STOP {len(data)}"]  # no W,OVERRUN: every period a data line
    assert len(data) >= 560 and all(len(f) == 10 for f in data)
    rows = [[int(x) for x in f] for f in data]
    assert [r[0] for r in rows] == list(range(len(rows)))
    assert all(b[1] - a[1] == 1000 for a, b in zip(rows, rows[1:], strict=False))  # t_us 1 ms apart
    # the ADC log: one conversion start per channel, channel c the c-th of each sample
    convs = run.adc[-4 * len(rows) :] if len(run.adc) >= 4 * len(rows) else run.adc
    starts = [c for c, _ in convs[::4]]
    assert len(starts) == len(rows)
    for i, row in enumerate(rows):
        for c in range(4):
            mv = convs[4 * i + c][1][c]
            assert abs(row[2 + c] - math.floor(mv * 1023 / 5000)) <= 1, (i, c, row)
        for a in range(4):
            t_sample = starts[i] / F
            count = sum(s for t, s in pulses[a] if t < t_sample)
            assert row[6 + a] == count, f"sample {i} axis {a}: {row[6 + a]} steps, expected {count}"
    assert rows[-1][6:] == [5, -10, 15, -20]
    longest = max(len(ln.raw) + 1 for ln in run.lines if ln.body.startswith("D,"))
    print(f"four channels at 1 kHz: {len(rows)} frames, 0 overruns, longest {longest} bytes")


@pytest.mark.slow
def test_link_budget_four_channels_through_pty(four_build: tuple[Path, str], firmware_build: None) -> None:
    """60 s of device time at 1 kHz, four channels, 1 Mbaud, read through the harness's pseudo-terminal."""
    serial = pytest.importorskip("serial")
    build, _ = four_build
    proc = subprocess.Popen(
        [str(fwsim.HARNESS), "-m", "atmega2560", "-p", "-s", "0", str(build / "daq_mega.elf")],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
    )
    try:
        assert proc.stdout is not None
        port = proc.stdout.readline().decode().split()[1]
        link = serial.Serial(port, 1_000_000, timeout=0.2)
        buf = b""
        while b"PONG daq" not in buf:  # synchronise (the boot banner may be gone)
            link.write(fwsim.command("PING"))
            buf += link.read(200)
        link.write(fwsim.command("START"))
        seq = last = None
        frames = drops = bad = overruns = 0
        t_first = t_last = None
        buf = b""
        deadline = time.monotonic() + 600  # a guard against a hung harness only: nothing is timed
        while (t_last is None or t_last - t_first < 60_000_000) and time.monotonic() < deadline:
            buf += link.read(4096)
            *lines, buf = buf.split(b"\n")
            for raw in lines:
                body, star, given = raw.decode("ascii", "replace").rpartition("*")
                if not star or given != fwsim.checksum(body.encode("ascii", "replace")):
                    bad += 1
                    continue
                if body.startswith("W,OVERRUN"):
                    overruns += int(body.split(",")[2])
                if not body.startswith("D,"):
                    continue
                f = [int(x) for x in body.split(",")[1:]]
                seq = f[0]
                drops += 0 if last is None else seq - last - 1
                last = seq
                frames += 1
                t_first = f[1] if t_first is None else t_first
                t_last = f[1]
        link.write(fwsim.command("STOP"))
        link.close()
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    print(
        f"pty link, 4 channels at 1 kHz, 1 Mbaud: {frames} frames over {(t_last - t_first) / 1e6:.3f} s "
        f"of device time, {drops} dropped, {bad} corrupted, {overruns} overruns"
    )
    assert t_last - t_first >= 60_000_000
    assert (drops, bad, overruns) == (0, 0, 0)
    assert frames >= 60_000


class _Clock:
    """What an emulated board reads of its world: the device clock, a seed and the GO instants."""

    def __init__(self) -> None:
        self.t = 0.0
        self.seed = 0
        self.t0_us = 0
        self.go_times: list[float] = []


def _emulated(board: str, cmds: list[str], duration: float, spacing: float = 0.02):
    """The emulated four-tendon board (``helpers.virtual.emulator.boards``) sent the same commands at
    the same device times as ``_stepper``: its reply bodies, and each axis's step times from GO (s)."""
    tb = pytest.importorskip("helpers.virtual.emulator.boards")
    rigfile = pytest.importorskip("helpers.rigfile")
    limits = tb.build_limits(rigfile.load(fwsim.REPO / "rigs" / "four-tendon.toml"))
    clock = _Clock()
    dev = (tb.StepperEmulator if board == "stepper" else tb.DaqEmulator)(clock, limits)
    dev.reset()
    steps: list[list[float]] = [[] for _ in range(limits.axes)]
    bodies = []
    for i, c in enumerate([*cmds, None]):
        t = 0.05 + spacing * i if c is not None else duration
        if board == "stepper":
            times, axes, _ = dev.steps_until(t)
            for ti, a in zip(times.tolist(), axes.tolist(), strict=True):
                steps[a].append(ti - clock.go_times[-1])
            dev.finish_if_due(t)
        clock.t = t
        if c is not None:
            dev.receive(fwsim.command(c))
        bodies += [line.decode().rstrip("\n").rpartition("*")[0] for line in dev.out]
        dev.out.clear()
    return bodies, steps


def test_emulated_four_axis_stepper_follows_the_firmware_tick_for_tick(
    four_build: tuple[Path, str], firmware_build: None
) -> None:
    """The same four-axis programme (coincident, lone and idle axes, a dwell, SEG on axis 0, a refusal) in
    simavr and on the emulated board: the same replies (DONE and POS with every axis), and every emulated
    step on the tick of the firmware's STEP edge (the edge less its constant lead, rounded to the tick)."""
    build, _ = four_build
    cmds = ["PING", "CONFIG", "EN 1"] + [f"MSEG {w} " + " ".join(map(str, n)) for w, n in PROGRAMME]
    cmds += ["WAIT 5", "SEG 1 3 700", "MSEG 10000 0 16 0 0", "GO"]  # axis 1 too fast: refused
    duration = 0.2 + sum(w for w, _ in PROGRAMME) / 1e6 + 0.1
    run = _stepper(build, cmds, duration)
    fw = [ln.body for ln in run.lines]
    emu, emu_steps = _emulated("stepper", cmds, duration)
    assert fw == emu
    assert fw[-3:] == ["ERR RANGE axis 1 interval 639-1000000 us", "OK GO 5", "DONE 3 0 0 0"]
    edges = [_rising(run, step) for step, _ in UNO_AXES]
    # by hand from PROGRAMME: 10 + 20 + 30 + 3 (SEG), 7 + 20 + 27, 3 + 1 + 4, 0 + 40 + 40 steps
    assert [len(e) for e in edges] == [len(s) for s in emu_steps] == [63, 54, 8, 80]
    offsets = [
        c - 128 - 8 * round(t * 2e6)
        for got, want in zip(edges, emu_steps, strict=True)
        for c, t in zip(got, want, strict=True)
    ]
    origin = sorted(offsets)[len(offsets) // 2]  # GO on the simulated clock (as in the tests above)
    worst = max(abs(o - origin) for o in offsets)
    print(f"emulated four-axis stepper: {len(offsets)} steps, each within {worst} cycles of the firmware's")
    assert worst <= TICK_CYCLES


def test_emulated_four_channel_daq_replies_as_the_firmware(
    four_build: tuple[Path, str], firmware_build: None
) -> None:
    build, _ = four_build
    cmds = ["PING", "CONFIG", "RATE 50", "RATE 500", "ZERO", "CONFIG 1"]
    script = [(0.02 + 0.01 * i, fwsim.command(c)) for i, c in enumerate(cmds)]
    run = fwsim.run("daq", script, 0.1 + 0.01 * len(cmds), elf=build / "daq_mega.elf")
    fw = [ln.body for ln in run.lines]
    emu, _ = _emulated("daq", cmds, 0.2, spacing=0.01)
    assert [b if not b.startswith("ERR") else b.split()[:2] for b in fw] == [
        b if not b.startswith("ERR") else b.split()[:2] for b in emu
    ]
    assert fw[2] == "OK CONFIG 4 4 100 2000"


def test_four_tendon_firmware_in_the_loop_short(
    four_build: tuple[Path, str], firmware_build: None, tmp_path: Path
) -> None:
    """A short four-tendon programme through both four-tendon sketches in simavr driving the spatial twin
    (``fil4.py``, whose full move and per-tendon metrics are ``test_fil4.py``'s, ``-m slow``): every recorded
    step count of every axis is the stepper sketch's edges at channel 0's conversion, every ADC count simavr's
    conversion of the twin's millivolts at that channel's own conversion (channel c, c x 104 us later)."""
    fil4 = pytest.importorskip("fil4")
    build, _ = four_build
    elfs = {"daq": build / "daq_mega.elf", "stepper": build / "stepper_uno.elf"}
    programme = fil4.Programme((fil4.Move(50_000, (6, 4, 2, 3)), fil4.Move(30_000, (-6, -4, -2, -3))))
    edges = fil4.programme_edges(programme, elfs["stepper"])
    # by hand: 6 + 6, 4 + 4, 2 + 2, 3 + 3 steps; axis 0's first at 50 ms / 6 = 8.33 ms after GO, first of all
    assert [int((edges.axes == a).sum()) for a in range(4)] == [12, 8, 4, 6] and edges.axes[0] == 0
    assert [int(edges.signs[edges.axes == a].sum()) for a in range(4)] == [0, 0, 0, 0]
    wave = fil4.tension_waveform(edges, programme.duration_s + 0.5, fil4.four_rig())
    run = fil4.record(wave, programme, elfs, tmp_path, tail_s=0.1)
    a = fil4.check_alignment(run, edges, wave)
    assert a.samples >= 100 and a.adc_mismatches == 0
    assert a.harness_error <= 0.5 / fil4.SIMAVR_MV_PER_COUNT + 1e-4  # whole millivolts
    assert a.step_mismatches == a.near_edge <= 0.01 * 4 * a.samples
    # the twin moved: tendon 0 (6 steps, 1.5 mm) rose above its pretension during the move
    assert run.frame["tension_n_0"].max() > run.frame["tension_n_0"].iloc[0] + 1.0
