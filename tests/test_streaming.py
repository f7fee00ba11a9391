"""``helpers.board.stream_reference``, the reference of the stepper board's streaming shaper: its steps
follow the exact
shaped trajectory within one step at every instant, each step at the first tick after its exact crossing;
the fixed-point representation and the board's rules for set-points, the watchdog and END."""

from __future__ import annotations

import random

import numpy as np
import pytest
from stream_exact import exact_position
from stream_run import PeriodCommands, StreamResult, simulate, simulate_axes, velocity_units

from helpers.board import stream_reference as hs

pytestmark = pytest.mark.streaming


def random_stream(r: random.Random) -> tuple[hs.StreamShaper, PeriodCommands, int]:
    n = r.randint(1, 8)
    negative = r.random() < 0.3
    d_max = r.choice([0.0, 0.005, 0.05, 0.3, 1.0]) if n > 1 else 0.0
    delays = sorted({0.0, *(r.uniform(0.0, d_max) for _ in range(n - 1))})
    amps = [r.uniform(0.1, 1.0) for _ in delays]
    if negative and len(amps) > 1:  # one negative impulse, small enough that the sum stays well above 0
        i = r.randrange(1, len(amps))
        amps[i] = -r.uniform(0.1, 0.5) * (sum(amps) - amps[i])
    shaper = hs.StreamShaper.quantise(amps, delays, allow_negative=negative)
    top = r.choice([30, 300, hs.V_MAX])
    assigned, v, k = {}, 0, 1
    for _ in range(r.randint(1, 80)):
        v = int(np.clip(v + r.gauss(0, top / 4), -top, top)) if r.random() < 0.8 else r.randint(-top, top)
        assigned[k] = v
        k += 1 if r.random() < 0.9 else r.randint(2, 14)  # gaps: underruns, now and then the watchdog
    end = None if r.random() < 0.2 else k + r.randint(0, 3)
    return shaper, PeriodCommands(assigned, end), r.randint(0, hs.TRAVEL_MAX)


def count_at(result: StreamResult, start: int, t: np.ndarray) -> np.ndarray:
    """The step count at times ``t`` (ticks): steps issued at or before ``t``."""
    csum = np.concatenate([[start], start + np.cumsum(result.directions)])
    return csum[np.searchsorted(result.ticks, t, side="right")]


@pytest.mark.parametrize("seed", range(40))
def test_steps_follow_the_exact_shaped_trajectory_within_one_step(seed):
    r = random.Random(seed)
    shaper, commands, start = random_stream(r)
    result = simulate(shaper, commands, position=start)
    assert result.finish_tick is not None
    t_end = result.finish_tick * hs.PERIOD_TICKS
    # every instant: a dense grid, every breakpoint of the shaped velocity, and both sides of every step
    grid = np.arange(0, t_end, 97.0)
    breaks = np.array(
        [
            (k + 1) * hs.PERIOD_TICKS + d * hs.DELTA // 16
            for k in range(result.finish_tick)
            for d in shaper.delays_us
        ],
        dtype=float,
    )
    t = np.unique(np.concatenate([grid, breaks, result.ticks - 1.0, result.ticks, result.ticks + 1.0]))
    t = t[(t >= 0) & (t <= t_end)]
    x = exact_position(shaper, result.v_by_period, t, position=start)
    c = count_at(result, start, t)
    v_tick = hs.S_MAX / hs.ONE / hs.DELTA  # the fastest motion in one tick (steps)
    assert np.max(np.abs(x - c)) < 1.0 + v_tick + 1e-9
    # each step is issued at the first tick at or after the exact crossing of c +- 1
    before = count_at(result, start, result.ticks.astype(float) - 1)
    xs = exact_position(shaper, result.v_by_period, result.ticks.astype(float), position=start)
    xs_prev = exact_position(shaper, result.v_by_period, result.ticks - 1.0, position=start)
    up = result.directions > 0
    eps = 1e-9
    assert np.all(np.where(up, xs >= before + 1 - eps, xs <= before - 1 + eps))
    assert np.all(np.where(up, xs_prev < before + 1 + eps, xs_prev > before - 1 - eps))
    # where the stream ends, the count is within one step of where the exact trajectory rests
    x_end = exact_position(shaper, result.v_by_period, np.array([float(t_end)]), position=start)[0]
    assert abs(x_end - result.position) < 1.0
    assert 0 <= result.position <= hs.TRAVEL_MAX


def test_the_residual_is_exact():
    """Integer arithmetic loses nothing: after a stream with no clamp, c + r / 2^28 is the exact position."""
    shaper = hs.StreamShaper.quantise([0.3, 0.4, 0.3], [0.0, 0.013, 0.137])
    v = {k: (37 * k) % 201 - 100 for k in range(1, 200)}
    result = simulate(shaper, PeriodCommands(v, 200), position=78)
    assert not result.notices
    total = sum(v.values()) * hs.PERIOD  # set-point units times DELTA: 2^-16 step each
    assert result.position * hs.ONE + result.residual == 78 * hs.ONE + total * (hs.ONE >> 16)


def test_speed_and_travel_clamps():
    fast = hs.StreamShaper((6144, -2048), (0, 50_000), allow_negative=True)
    result = simulate(fast, PeriodCommands({k: 1500 for k in range(1, 11)}, 11), position=0)
    assert np.diff(result.ticks).min() >= 1278  # 639 us: the shaped 1.5 x 1500 is clamped to 1640
    assert [n.kind for n in result.notices] == ["LIMIT,SPEED"]
    push = simulate(
        hs.UNIT_SHAPER, PeriodCommands({k: hs.V_MAX for k in range(1, 40)}, 40), position=150
    )
    assert push.position == hs.TRAVEL_MAX and len(push.ticks) == 6
    assert [(n.kind, n.value) for n in push.notices] == [("LIMIT,TRAVEL", 156)]


def test_setpoint_rules():
    c = PeriodCommands({1: 5, 2: 6, 5: 7}, end_period=9)
    got = [(k, v, s) for k, v, s in _take(c, 11)]
    assert [v for _, v, _ in got] == [5, 6, 0, 0, 7, 0, 0, 0, 0, 0, 0]  # underruns and END: zero
    assert [s for _, _, s in got][-3:] == ["end"] * 3
    w = PeriodCommands({1: 9})
    got = list(_take(w, 14))
    assert [v for _, v, _ in got[:11]] == [9] + [0] * 10  # 10 underruns move nothing ...
    assert got[11] == (12, 0, "watchdog")  # ... the 11th fires the watchdog


def _take(commands: PeriodCommands, n: int):
    for item, _ in zip(commands, range(n), strict=False):
        yield item


def test_quantised_shaper():
    s = hs.StreamShaper.quantise([0.25, 0.5, 0.25], [0.1, 0.3, 0.5])
    assert s.amplitudes == (1024, 2048, 1024) and s.delays_us == (0, 200_000, 400_000)
    s = hs.StreamShaper.quantise([1 / 3, 1 / 3, 1 / 3], [0.0, 0.123456, 0.123460])  # the last two merge
    assert sum(s.amplitudes) == hs.AMP_ONE and len(s.amplitudes) == 2 and s.delays_us == (0, 123456)
    assert s.commands() == ["SHAPER 2 0", f"IMP 0 {s.amplitudes[0]} 0", f"IMP 1 {s.amplitudes[1]} 123456"]
    assert velocity_units(400.0, 0.25525) == 1643  # 400 mm/s needs more than the board's 1640
    assert hs.STEPS_PER_S_PER_UNIT == 0.95367431640625


@pytest.mark.parametrize(
    "amps, delays, negative, message",
    [
        ((4096,) * 9, tuple(range(0, 144, 16)), False, "1 to 8"),
        ((4097, -1), (0, 16), True, None),
        ((4097, -1), (0, 16), False, "amplitude"),
        ((16385, -12289), (0, 16), True, "amplitude"),
        ((2048, 2048), (16, 32), False, "delay"),
        ((2048, 2048), (0, 0), False, "delay"),
        ((2048, 2048), (0, 8), False, "delay"),
        ((2048, 2048), (0, 1_000_016), False, "delay"),
        ((2048, 2047), (0, 16), False, "sum"),
    ],
)
def test_shaper_checks(amps, delays, negative, message):
    error = hs.shaper_error(amps, delays, negative)
    if message is None:
        assert error is None
    else:
        assert message in error
        with pytest.raises(ValueError):
            hs.StreamShaper(amps, delays, negative)


# --- several axes ------------------------------------------------------------------------------------------
def test_axes_with_v_setpoints_move_axis_zero_as_one_axis_does() -> None:
    """``V`` on a build with several axes: axis 0 as the one-axis board, the others never step."""
    for seed in range(20):
        shaper, commands, start = random_stream(random.Random(seed))
        if max(shaper.delays_us) > hs.MAX_DELAY_US_AXES:
            continue
        one = simulate(shaper, commands, position=start)
        axes = simulate_axes(shaper, commands, [start, 5, 0, 156])
        assert np.array_equal(axes[0].ticks, one.ticks) and np.array_equal(axes[0].directions, one.directions)
        assert axes[0].finish_tick == one.finish_tick and axes[0].notices == one.notices
        assert [len(r.ticks) for r in axes[1:]] == [0, 0, 0] and [r.position for r in axes[1:]] == [5, 0, 156]


def test_each_axis_is_clamped_at_its_own_travel() -> None:
    """Top speed for 30 periods (1640 * 625 * 30 / 2^16 = 469.2 steps): up on axes 0 and 2 (travels 100
    and 40), down on axis 3 (from 40 to 0); axis 1 holds."""
    unit = hs.StreamShaper((4096,), (0,))
    commands = PeriodCommands({k: (hs.V_MAX, 0, hs.V_MAX, -hs.V_MAX) for k in range(1, 31)}, 31)
    res = simulate_axes(unit, commands, [0, 7, 0, 40], [100, 156, 40, 156])
    assert [r.position for r in res] == [100, 7, 40, 0]
    assert [n.line for r in res for n in r.notices] == [
        "N,LIMIT,TRAVEL,100",
        "N,LIMIT,TRAVEL,40,2",
        "N,LIMIT,TRAVEL,0,3",
    ]
    assert res[1].finish_tick == res[0].finish_tick == 30 + 2 + 3  # last non-zero 30, + q_max + 2, + 3


def test_an_axis_with_a_release_pays_out_down_to_it() -> None:
    """The same top speed down for 30 periods (469.2 steps) on axes with a release below zero
    (``RIG_AXIS_RELEASE_STEPS``): axis 0 (release 78) from 0 to -78, axis 1 (none) held at 0, axis 2 (release
    78) from 100 to -78; the exact trajectory with the same limits ends there too."""
    unit = hs.StreamShaper((4096,), (0,))
    commands = PeriodCommands({k: (-hs.V_MAX, -hs.V_MAX, -hs.V_MAX) for k in range(1, 31)}, 31)
    res = simulate_axes(unit, commands, [0, 0, 100], [156, 156, 156], releases=[78, 0, 78])
    assert [r.position for r in res] == [-78, 0, -78]
    assert [n.line for r in res for n in r.notices] == [
        "N,LIMIT,TRAVEL,-78",
        "N,LIMIT,TRAVEL,0,1",
        "N,LIMIT,TRAVEL,-78,2",
    ]
    assert len(res[2].ticks) == 178 and set(res[2].directions.tolist()) == {-1}
    t = np.array([40.0 * hs.PERIOD_TICKS])
    assert exact_position(unit, res[2].v_by_period, t, position=100, release=78)[0] == -78.0
    assert exact_position(unit, res[2].v_by_period, t, position=100)[0] == 0.0  # no release: at 0


def test_impulse_delays_of_a_build_with_several_axes() -> None:
    assert hs.impulse_problem(1, 2048, 620_000, 0, False, hs.MAX_DELAY_US_AXES) is None
    assert hs.impulse_problem(1, 2048, 620_016, 0, False, hs.MAX_DELAY_US_AXES) == "delay"
    assert hs.impulse_problem(1, 2048, 620_016, 0, False) is None  # one axis: up to 1 s
