"""Stepper firmware (Arduino Uno + TB6600) in simavr: Table I programmes on the STEP/DIR/ENA pins, limits."""

from __future__ import annotations

import math

import fwsim
import numpy as np
import pytest

pytestmark = pytest.mark.firmware

F = fwsim.F_CPU
MM_PER_STEP = math.pi * 65.0 / 800.0  # 65 mm spool, 800 steps/rev (paper)
STEP, DIR, ENA = "D5", "D6", "D7"


def unshaped_programme(v_mm_s: float, x_mm: float) -> list[tuple]:
    """Table I pulse from first principles: 1 s lead-in, up at v, hold until 8 s, down at v, 0.5 s tail."""
    n = round(x_mm / MM_PER_STEP)
    interval = round(MM_PER_STEP / v_mm_s * 1e6)
    hold_ms = round(8000 - 1000 - n * interval / 1000)
    return [
        ("WAIT", 1000),
        ("SEG", 1, n, interval),
        ("WAIT", hold_ms),
        ("SEG", -1, n, interval),
        ("WAIT", 500),
    ]


def zvd_programme(v_mm_s: float, x_mm: float) -> list[tuple]:
    """The robust-TDF version of the same move, as the project's helpers.board.programmes builds it."""
    programmes = pytest.importorskip("helpers.board.programmes")
    shapers = pytest.importorskip("helpers.paper.shapers")
    _, robust = shapers.design_tdfs()
    prog, _ = programmes.experiment_programme(v_mm_s, x_mm, robust, t_end=8.8)
    out: list[tuple] = []
    for item in prog.items:
        if isinstance(item, programmes.Segment):
            out.append(("SEG", item.direction, item.n_steps, item.interval_us))
        else:
            out.append(("WAIT", item.ms))
    return out


def commands(items: list[tuple]) -> list[str]:
    return [" ".join(str(x) for x in it) for it in items]


def expected_steps(items: list[tuple]) -> tuple[np.ndarray, np.ndarray, int]:
    """Step instants (us from GO) and directions by the PROTOCOL.md rule, and the programme's duration."""
    times, dirs, t0 = [], [], 0
    for it in items:
        if it[0] == "SEG":
            _, d, n, iv = it
            times += [t0 + k * iv for k in range(1, n + 1)]
            dirs += [d] * n
            t0 += n * iv
        else:
            t0 += it[1] * 1000
    return np.array(times, dtype=float), np.array(dirs), t0


def run_programme(items: list[tuple]):
    cmds = ["EN 1", "CLEAR", *commands(items), "GO"]
    t = [0.05 + 0.02 * i for i in range(len(cmds))]
    t_go = t[-1]
    _, _, dur_us = expected_steps(items)
    t_after = t_go + dur_us * 1e-6 + 0.05
    script = [(ti, fwsim.command(c)) for ti, c in zip(t, cmds, strict=True)]
    script += [(t_after, fwsim.command("POS")), (t_after + 0.02, fwsim.command("ABORT"))]
    return fwsim.run("stepper", script, t_after + 0.05, watch=(STEP, DIR, ENA))


def pin_trace(run, pin: str) -> list[tuple[int, int]]:
    return [(c, lv) for c, p, lv in run.pins if p == pin]


def level_at(trace: list[tuple[int, int]], cycle: int, initial: int = 0) -> int:
    level = initial
    for c, lv in trace:
        if c > cycle:
            break
        level = lv
    return level


@pytest.fixture(scope="module", params=["unshaped", "zvd"])
def table_i_run(request, firmware_build):
    items = unshaped_programme(200.0, 20.0) if request.param == "unshaped" else zvd_programme(200.0, 20.0)
    return request.param, items, run_programme(items)


def test_programme_accepted_and_done(table_i_run):
    _, items, run = table_i_run
    bodies = [ln.body for ln in run.lines]
    assert bodies[0] == "HELLO stepper 2.3.0+481e87e3"
    assert f"OK GO {len(items)}" in bodies
    net = sum(it[1] * it[2] for it in items if it[0] == "SEG")
    assert f"DONE {net}" in bodies and f"OK POS {net}" in bodies
    assert all(ln.checksum_ok for ln in run.lines)


def test_exact_number_of_steps_in_each_direction(table_i_run):
    _, items, run = table_i_run
    rises = [c for c, lv in pin_trace(run, STEP) if lv == 1]
    _, dirs, _ = expected_steps(items)
    assert len(rises) == len(dirs)
    dir_trace = pin_trace(run, DIR)
    measured = np.array([1 if level_at(dir_trace, c) else -1 for c in rises])
    np.testing.assert_array_equal(measured, dirs)  # DIR HIGH = pull
    n_up = sum(it[2] for it in items if it[0] == "SEG" and it[1] == 1)
    assert np.sum(dirs == 1) == n_up == round(20.0 / MM_PER_STEP)


def test_step_times_follow_the_programme(table_i_run):
    name, items, run = table_i_run
    rises = np.array([c for c, lv in pin_trace(run, STEP) if lv == 1], dtype=float)
    t_exp, _, dur_us = expected_steps(items)
    # measured step instants relative to the first step, against the programme's (us)
    t_meas = (rises - rises[0]) / 16.0
    t_rel = t_exp - t_exp[0]
    drift = np.abs(t_meas - t_rel)
    assert drift.max() <= 1.0, f"step instants off by up to {drift.max():.3f} us"
    # every step interval within 0.1 % of the programmed one
    iv_meas, iv_exp = np.diff(t_meas), np.diff(t_rel)
    rel = np.abs(iv_meas - iv_exp) / iv_exp
    assert rel.max() <= 1e-3
    done = next(ln for ln in run.lines if ln.body.startswith("DONE"))
    t_end_meas = done.cycle / 16.0 - (rises[0] / 16.0 - t_exp[0])
    assert dur_us <= t_end_meas <= dur_us + 3000, "DONE comes right after the last item"
    print(
        f"\n{name}: {len(rises)} steps, worst interval error {rel.max() * 100:.4f} %, "
        f"worst step-time error {drift.max():.3f} us"
    )


def test_direction_enable_order_and_pulse_shape(table_i_run):
    _, _, run = table_i_run
    ena, dirt, step = pin_trace(run, ENA), pin_trace(run, DIR), pin_trace(run, STEP)
    rises = [c for c, lv in step if lv == 1]
    falls = [c for c, lv in step if lv == 0 and c > rises[0]]
    # driver disabled from reset (ENA HIGH within the first microseconds), enabled before the first step
    assert ena[0][1] == 1 and ena[0][0] < 16 * 10
    enable_at = next(c for c, lv in ena if lv == 0)
    assert enable_at < rises[0]
    assert all(level_at(ena, c, 1) == 0 for c in rises), "ENA stays LOW (enabled) while stepping"
    # DIR set up at least 5 us before each step edge (TB6600), never changed during a pulse
    for c in rises:
        last_dir_change = max((cd for cd, _ in dirt if cd <= c), default=-(10**9))
        assert c - last_dir_change >= 5 * 16
    widths = np.array(falls[: len(rises)]) - np.array(rises)
    assert widths.min() >= 2.5 * 16, "STEP high for at least 2.5 us (TB6600)"
    assert widths.max() <= 20 * 16
    # ABORT at the end disables the driver again
    assert ena[-1][1] == 1 and ena[-1][0] > rises[-1]


def test_limits_refused_whatever_the_host_asks(firmware_build):
    """Requests beyond the compiled-in limits never move the motor."""
    cmds = [
        "EN 1",
        "SEG 1 10 638",  # 400.2 mm/s
        "SEG 1 157 1000",  # > 40 mm in one segment
        "SEG 1 100 639",
        "SEG 1 57 639",  # 157 steps in total: refused at GO
        "GO",
        "CLEAR",
        "SEG -1 1 1000",  # below zero: refused at GO
        "GO",
        "CLEAR",
        "WAIT 60001",
        "SEG 1 1 1000001",
    ]
    script = [(0.05 + 0.02 * i, fwsim.command(c)) for i, c in enumerate(cmds)]
    run = fwsim.run("stepper", script, 0.05 + 0.02 * len(cmds) + 0.1, watch=(STEP, DIR, ENA))
    replies = [ln.body for ln in run.lines][1:]
    assert [r.split()[0:2] for r in replies] == [
        ["OK", "EN"],
        ["ERR", "RANGE"],
        ["ERR", "RANGE"],
        ["OK", "SEG"],
        ["OK", "SEG"],
        ["ERR", "RANGE"],
        ["OK", "CLEAR"],
        ["OK", "SEG"],
        ["ERR", "RANGE"],
        ["OK", "CLEAR"],
        ["ERR", "RANGE"],
        ["ERR", "RANGE"],
    ]
    assert not [1 for _, p, lv in run.pins if p == STEP and lv == 1], "no step was issued"


def test_long_intervals_split_into_timer_chunks_stay_exact(firmware_build):
    """Intervals beyond Timer1's 16-bit range (32.768 ms) are chunked; the step times must not drift."""
    items = [
        ("SEG", 1, 3, 100000),
        ("SEG", -1, 3, 33000),
        ("SEG", 1, 2, 32768),
        ("WAIT", 40),
        ("SEG", 1, 1, 639),
    ]
    run = run_programme(items)
    rises = np.array([c for c, lv in pin_trace(run, STEP) if lv == 1], dtype=float)
    t_exp, dirs, _ = expected_steps(items)
    assert len(rises) == len(t_exp) == 9
    drift = np.abs((rises - rises[0]) / 16.0 - (t_exp - t_exp[0]))
    assert drift.max() <= 1.0
    assert [ln.body for ln in run.lines if ln.body.startswith("DONE")] == [f"DONE {int(dirs.sum())}"]
