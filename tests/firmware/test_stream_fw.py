"""The stepper firmware's streaming input shaper in simavr: commands and errors, the watchdog, the limits on
the shaped output, and random streams whose STEP/DIR edges must match ``helpers.board.stream_reference`` to
one tick."""

from __future__ import annotations

import random
import re

import fw_cases
import fwsim
import numpy as np
import pytest
import streamsim
from crc_reference import link_hex

from helpers.board import stream_reference as hs

pytestmark = [pytest.mark.firmware, pytest.mark.streaming]

F = fwsim.F_CPU
T_CYCLES = hs.PERIOD_TICKS * streamsim.CYCLES_PER_TICK  # one control period in CPU cycles


def _k(body: str) -> bytes:
    return f"{body}*{link_hex(body)}\n".encode()


# --- commands and errors ---------------------------------------------------------------------------------
STREAM_CASES = fw_cases.stream_cases()


@pytest.fixture(scope="module")
def command_session(firmware_build):
    cmds = [c for c, _, _ in STREAM_CASES]
    return fwsim.command_session("stepper", cmds, [p for _, _, p in STREAM_CASES])


def test_streaming_commands_and_error_replies(command_session):
    run, groups = command_session
    failures = []
    dones = []
    for (cmd, expected, _), group in zip(STREAM_CASES, groups, strict=True):
        replies = [ln.body for ln in group if not ln.body.startswith(("DONE", "N,"))]
        dones += [ln.body for ln in group if ln.body.startswith("DONE")]
        if len(replies) != 1 or not re.fullmatch(expected, replies[0]):
            failures.append(f"{cmd!r}: expected {expected!r}, got {replies!r}")
    assert not failures, "\n".join(failures)
    assert dones == ["DONE 0"]  # END's stream ran out; ABORT's sends ABORTED, no DONE
    assert all(ln.checksum_ok for ln in run.lines)
    assert not [ln for ln in run.lines if "J" in ln.body]
    assert not [ln.raw for ln in run.lines if len(ln.raw) > 63], "a line longer than the protocol allows"


def test_setpoints_faster_than_the_board_fill_the_fifo(firmware_build):
    """Eight set-points queue; the ninth is refused with ERR FULL; each reply names the period it drives."""
    burst = b"".join(_k(f"V {10 * i}") for i in range(10))
    script = [(0.05, _k("EN 1")), (0.06, _k("SHAPER 1 0")), (0.07, _k("IMP 0 4096 0")), (0.08, _k("STREAM"))]
    script += [(0.0805, burst), (0.2, _k("END"))]
    run = fwsim.run("stepper", script, 0.4)
    replies = [ln.body for ln in run.lines if ln.body.startswith(("OK V", "ERR"))]
    periods = [int(r.split()[2]) for r in replies if r.startswith("OK V")]
    assert len(periods) >= 8 and periods == list(range(periods[0], periods[0] + len(periods)))
    assert "ERR FULL" in " ".join(replies)  # ten set-points within 9 ms: at least one waits for room


# --- the watchdog ----------------------------------------------------------------------------------------
def test_watchdog_brings_the_cable_to_rest_and_disables_the_driver(firmware_build):
    shaper = hs.StreamShaper.quantise([0.25, 0.5, 0.25], [0.0, 0.2, 0.4])  # a 400 ms shaper
    setpoints = [(0.005 + 0.01 * i, 300) for i in range(30)]  # then the host falls silent
    result, (out,) = streamsim.run([streamsim.StreamSpec(shaper, setpoints, None)])
    ref = out.reference
    assert [n.kind for n in ref.notices] == ["WATCHDOG"]
    assert out.notices == [f"N,WATCHDOG,{ref.notices[0].value}"]
    assert [d.body for d in out.done] == [f"DONE {ref.position}"]
    assert len(out.step_cycles) == len(ref.ticks) > 0
    origin = streamsim.stream_origin(out)
    last_period = max(out.commands.assigned)
    stopped_at = origin + (last_period + 1) * T_CYCLES  # the next set-point was due here
    ena = [(c, lv) for c, p, lv in result.pins if p == "D7"]
    off = [c for c, lv in ena if lv == 1 and c > stopped_at]
    assert off, "the watchdog disabled the driver"
    # PROTOCOL.md's bound: 100 ms + the shaper's duration + 4 control periods (+ the tick's entry, < 0.1 ms)
    bound = stopped_at + (0.100 + shaper.duration_s + 0.040 + 0.0001) * F
    assert out.step_cycles[-1] < off[0] <= bound, "off within 100 ms + the shaper + 40 ms"
    # the steps go on for the shaper's duration after the set-points stop, and no longer
    assert out.step_cycles[-1] > stopped_at + (0.100 + 0.2) * F
    print(
        f"\nwatchdog: driver off {(off[0] - stopped_at) / F * 1e3:.1f} ms after the first missing set-point "
        f"(bound {(bound - stopped_at) / F * 1e3:.0f} ms); last step "
        f"{(out.step_cycles[-1] - stopped_at) / F * 1e3:.1f} ms after it"
    )


# --- limits on the shaped output ------------------------------------------------------------------------
def test_travel_is_clamped_on_the_shaped_output(firmware_build):
    shaper = hs.StreamShaper.quantise([0.5, 0.5], [0.0, 0.1])
    up = [(0.005 + 0.01 * i, 1640) for i in range(30)]  # 0.3 s at full speed: 469 steps asked, 156 allowed
    down = [(0.305 + 0.01 * i, -1640) for i in range(40)]  # and back past zero
    spec = streamsim.StreamSpec(shaper, up + down, 0.71)
    result, (out,) = streamsim.run([spec])
    position = np.cumsum(out.step_dirs)
    assert position.max() == hs.TRAVEL_MAX and position.min() == 0 and position[-1] == 0
    assert sorted(out.notices) == ["N,LIMIT,TRAVEL,0", "N,LIMIT,TRAVEL,156"]
    assert [d.body for d in out.done] == ["DONE 0"]
    assert len(out.step_cycles) == len(out.reference.ticks) == 2 * hs.TRAVEL_MAX


def test_speed_is_clamped_on_the_shaped_output(firmware_build):
    """A shaper with a negative impulse overshoots: 1.5 v, clamped to the 400 mm/s (639 us per step) limit."""
    shaper = hs.StreamShaper((6144, -2048), (0, 50_000), allow_negative=True)
    setpoints = [(0.005 + 0.01 * i, 1500) for i in range(10)]
    result, (out,) = streamsim.run([streamsim.StreamSpec(shaper, setpoints, 0.105)])
    intervals = np.diff(out.step_cycles) / 16.0  # us
    assert intervals.min() >= 639.0 - 0.6  # one tick of edge jitter at most
    assert out.notices == [f"N,LIMIT,SPEED,{out.reference.notices[0].value}"]
    assert len(out.step_cycles) == len(out.reference.ticks)
    assert np.isclose(np.median(intervals[:20]), 639.375, atol=0.6), "the clamped stretch runs at the limit"


# --- random streams against the reference --------------------------------------------------------------
def random_spec(r: random.Random) -> streamsim.StreamSpec:
    """A random stream: shaper (1-8 impulses, some negative), set-points, host timing; some hit limits."""
    n = r.randint(1, 8)
    negative = r.random() < 0.25
    d_max = r.choice([0.0, 0.01, 0.05, 0.15, 0.3, 0.3, 0.6, 1.0]) if n > 1 else 0.0
    delays = sorted({0.0, *(r.uniform(0.0, d_max) for _ in range(n - 1))})
    amps = [r.uniform(0.2, 1.0) for _ in delays]
    if negative and len(amps) > 1:  # one negative impulse, small enough that the sum stays well above 0
        i = r.randrange(1, len(amps))
        amps[i] = -r.uniform(0.1, 0.5) * (sum(amps) - amps[i])
    shaper = hs.StreamShaper.quantise(amps, delays, allow_negative=negative)
    setpoints = []
    t, v = r.uniform(0.002, 0.02), 0
    style = r.choice(["walk", "walk", "steps", "steps", "zigzag", "push"])
    top = r.choice([120, 400, 800, hs.V_MAX])  # the stream's largest set-point
    for _ in range(r.randint(5, 60)):
        if style == "walk":
            v = int(np.clip(v + r.gauss(0, top / 5), -top, top))
        elif style == "steps" and r.random() < 0.2:
            v = r.randint(-top, top)
        elif style == "push":  # towards a travel limit, at full speed
            v = hs.V_MAX if r.random() < 0.9 else -hs.V_MAX
        elif style == "zigzag":
            v = r.choice([-1, 1]) * r.randint(0, top)
        setpoints.append((t, v))
        # the host's rate: 100 Hz +- 30 %, jitter, now and then a burst (FIFO full) or a pause (underruns)
        u = r.random()
        t += 0.003 if u < 0.05 else r.uniform(0.04, 0.16) if u < 0.07 else r.uniform(0.007, 0.013)
    end_at = None if r.random() < 0.1 else t + r.uniform(0.0, 0.02)
    return streamsim.StreamSpec(shaper, setpoints, end_at)


def check_outcome(out: streamsim.StreamOutcome) -> list[str]:
    """What differs between a stream on the firmware and its reference (empty when they agree)."""
    ref = out.reference
    problems = []
    if not all(r.startswith("OK") for r in out.replies[: len(out.replies) - len(out.commands.assigned)]):
        setup = [r for r in out.replies if not r.startswith(("OK", "ERR FULL", "ERR STATE"))]
        if setup:
            problems.append(f"unexpected replies {setup[:3]}")
    if len(out.step_cycles) != len(ref.ticks):
        problems.append(f"{len(out.step_cycles)} steps, reference {len(ref.ticks)}")
        return problems
    if not np.array_equal(out.step_dirs, ref.directions):
        problems.append("directions differ")
    if len(out.dir_setup) and out.dir_setup.min() < 5 * 16:
        problems.append(f"DIR changed {out.dir_setup.min() / 16:.1f} us before a step (TB6600: >= 5 us)")
    res = streamsim.residuals(out)
    if len(res) and res.max() - res.min() > streamsim.CYCLES_PER_TICK:
        problems.append(f"step times spread {res.max() - res.min()} cycles (> 1 tick)")
    expected_notices = sorted(f"N,{n.kind},{n.value}" for n in ref.notices)
    if sorted(out.notices) != expected_notices:
        problems.append(f"notices {sorted(out.notices)}, reference {expected_notices}")
    if [d.body for d in out.done] != [f"DONE {ref.position}"]:
        problems.append(f"done {[d.body for d in out.done]}, reference DONE {ref.position}")
    elif ref.finish_tick is not None and len(out.tick_rises):
        origin = streamsim.stream_origin(out)
        late = (out.done[0].cycle - origin) / T_CYCLES - ref.finish_tick
        if not 0 <= late <= 0.6:  # sent at the finishing tick, after any lines queued (1.2 ms each)
            problems.append(f"DONE {late:.2f} periods after the reference's finishing tick")
    return problems


def _run_random(n_streams: int, seed: int, per_session: int = 25):
    r = random.Random(seed)
    specs = [random_spec(r) for _ in range(n_streams)]
    failures, spreads, loads, free, setup = [], [], [], [], []
    n_steps = n_clamped = n_watchdog = 0
    for i in range(0, n_streams, per_session):
        result, outcomes = streamsim.run(specs[i : i + per_session])
        for j, out in enumerate(outcomes):
            problems = check_outcome(out)
            if problems:
                failures.append(f"stream {i + j} ({specs[i + j].shaper}): {'; '.join(problems)}")
            res = streamsim.residuals(out)
            if len(res):
                spreads.append(int(res.max() - res.min()))
                setup.append(int(out.dir_setup.min()))
            n_steps += len(out.step_cycles)
            n_clamped += any(n.startswith("N,LIMIT") for n in out.notices)
            n_watchdog += any(n.startswith("N,WATCHDOG") for n in out.notices)
        loads.append(streamsim.isr_cycles_per_period(result))
        free.append(int(result.lines[-1].body.split()[2]))
    loads_all = np.concatenate(loads)
    figures = (
        f"{n_streams} random streams, {n_steps} steps ({n_clamped} streams clamped at a limit, {n_watchdog} "
        f"ended by the watchdog): step edges match the reference's ticks with a spread of at most "
        f"{max(spreads)} cycles ({max(spreads) / 16:.3f} us; median {int(np.median(spreads))}); DIR set at "
        f"least {min(setup) / 16:.0f} us before each step edge; "
        f"control tick + step interrupt per 10 ms period: "
        f"worst {loads_all.max()} cycles ({loads_all.max() / T_CYCLES * 100:.1f} %), median "
        f"{int(np.median(loads_all))}; least free stack {min(free)} bytes"
    )
    return failures, figures, max(spreads), loads_all.max(), min(free)


@pytest.mark.slow  # 23 s of simavr; the default suite keeps the commands, FIFO, watchdog and clamps
def test_random_streams_match_the_reference(firmware_build):
    failures, figures, spread, load, free = _run_random(50, seed=2024)
    print("\n" + figures)
    assert not failures, "\n".join(failures[:10])
    assert spread <= streamsim.CYCLES_PER_TICK
    assert load < 0.25 * T_CYCLES
    assert free >= 200


def test_worst_case_interrupt_load_jitter_and_stack(firmware_build):
    """8 impulses cutting every period into 8 pieces, full-speed set-points of alternating sign (so the speed
    clamp works and every piece steps), set-points sent every 4 ms (the FIFO overflows: ERR FULL replies keep
    the UART busy): the heaviest load the stream can put on the board."""
    delays = [j * 0.01125 for j in range(8)]  # 11.25 ms apart: 8 different offsets in the period
    shaper = hs.StreamShaper(
        (2048, -1024, 1024, -1024, 2048, -1024, 1024, 1024),
        tuple(round(d * 1e6 / 16) * 16 for d in delays),
        allow_negative=True,
    )
    warm_up = [(0.002 + 0.01 * i, hs.V_MAX // 2) for i in range(10)]  # to mid-travel first
    zigzag = [(0.1 + 0.004 * i, hs.V_MAX if (i // 5) % 2 else -hs.V_MAX) for i in range(150)]
    spec = streamsim.StreamSpec(shaper, warm_up + zigzag, 0.7)
    result, (out,) = streamsim.run([spec])
    assert not check_outcome(out)
    load = streamsim.isr_cycles_per_period(result)
    res = streamsim.residuals(out)
    free = int(result.lines[-1].body.split()[2])
    steps_per_period = np.bincount(out.reference.ticks // hs.PERIOD_TICKS).max()
    print(
        f"\nstress stream: {len(out.step_cycles)} steps (up to {steps_per_period} per period), "
        f"{sum(r.startswith('ERR FULL') for r in out.replies)} set-points refused (FIFO full); "
        f"interrupt load per 10 ms period: worst {load.max()} cycles ({load.max() / T_CYCLES * 100:.1f} %), "
        f"median {int(np.median(load))}; step edge spread {res.max() - res.min()} cycles; "
        f"least free stack {free} bytes"
    )
    assert steps_per_period >= 15
    assert res.max() - res.min() <= streamsim.CYCLES_PER_TICK
    assert load.max() < 0.25 * T_CYCLES
    assert free >= 200


@pytest.mark.slow
def test_a_thousand_random_streams_match_the_reference(firmware_build):
    failures, figures, spread, load, free = _run_random(1000, seed=7)
    print("\n" + figures)
    assert not failures, f"{len(failures)} streams differ:\n" + "\n".join(failures[:10])
    assert spread <= streamsim.CYCLES_PER_TICK
    assert load < 0.25 * T_CYCLES
    assert free >= 200
