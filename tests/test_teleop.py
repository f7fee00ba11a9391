"""Arbitrary motion: the host-side scheduled shaper, the commands, and the analysis of a recorded stream."""

import numpy as np
import pandas as pd
import pytest

from helpers.board.stream_reference import STEPS_PER_S_PER_UNIT
from helpers.research import teleop
from helpers.research.modemap import ModeMap
from rigs import SHIPPED

MM_PER_STEP = SHIPPED["paper"].mm_per_step  # the paper's rig, by hand (tests/rigs.py)
UNIT = MM_PER_STEP * STEPS_PER_S_PER_UNIT
SOURCE = {"kind": "virtual-rig", "method": "test"}


def test_on_a_constant_map_the_host_shaper_is_the_zv_convolution():
    # a ZV whose delay is a whole number of periods: 25.1327 rad/s damped -> T = 0.125 s = 12.5 periods;
    # pick omega_d so that T = 0.12 s exactly (12 periods) to compare without fractional delays
    omega_d = np.pi / 0.12
    flat = ModeMap.constant(omega_d, 0.0, (0.0, 40.0), source=SOURCE)
    v = np.r_[np.zeros(5), np.full(10, 100.0), np.zeros(30)]
    shaped = teleop.schedule_setpoints(v, flat, "ZV", mm_per_step=MM_PER_STEP)
    expected = np.zeros(v.size + 12)
    expected[: v.size] += 0.5 * v  # zeta = 0: two equal impulses 0.12 s apart
    expected[12 : 12 + v.size] += 0.5 * v
    n = max(shaped.size, expected.size)
    np.testing.assert_allclose(np.r_[shaped, np.zeros(n - shaped.size)],
                               np.r_[expected, np.zeros(n - expected.size)], atol=UNIT)  # fmt: skip


def test_the_scheduled_stream_moves_the_cable_exactly_as_far_in_whole_board_units():
    rising = ModeMap([0.0, 20.0, 40.0], [25.0, 29.0, 41.0], [0.044, 0.04, 0.035], source=SOURCE)
    v = teleop.teleop_command(MM_PER_STEP, seed=5)
    shaped = teleop.schedule_setpoints(v, rising, "ZVD", mm_per_step=MM_PER_STEP)
    assert np.sum(shaped / UNIT) == pytest.approx(np.sum(v / UNIT), abs=1e-9)  # the same displacement
    assert np.allclose(shaped / UNIT, np.rint(shaped / UNIT), atol=1e-9)  # whole board units
    # the delay follows the configuration: a move near 40 mm is spread over a shorter ZVD than one near 0
    t_short = 2 * np.pi / rising.at(40.0).omega_d
    t_long = 2 * np.pi / rising.at(0.0).omega_d
    assert t_short < t_long
    with pytest.raises(ValueError, match="unknown shaper family"):
        teleop.schedule_setpoints(v, rising, "XYZ", mm_per_step=MM_PER_STEP)


def test_commands_come_back_to_zero_and_stay_inside_the_travel():
    for v in (teleop.teleop_command(MM_PER_STEP, seed=3), teleop.pick_and_place(MM_PER_STEP)):
        position = np.cumsum(v) * teleop.PERIOD_S
        assert np.sum(v / UNIT) == pytest.approx(0.0, abs=1e-9)
        assert position.min() > -1e-9 and position.max() < 40.0
        assert np.abs(v).max() <= 400.0


def test_stops_and_residuals_of_a_synthetic_recording():
    t = np.arange(0.0, 8.0, 0.001)
    steps = np.zeros(t.size)
    steps[(t >= 1.0)] = np.minimum((t[t >= 1.0] - 1.0) / 0.1 * 40, 40).round()  # a 0.1 s move of 40 steps
    tension = 2.0 + 4.0 * (t >= 1.1) + 0.4 * np.exp(-(t - 1.1) * 1.0) * np.sin(25.0 * (t - 1.1)) * (t >= 1.1)
    frame = pd.DataFrame({"t_s": t, "steps": steps, "cable_mm": steps * MM_PER_STEP, "tension_n": tension})
    (start, end, stop_end), = teleop.stops(frame)
    assert start == pytest.approx(1.0, abs=3e-3) and end == pytest.approx(1.1, abs=2e-3) and stop_end == t[-1]
    res = teleop.stop_residuals(frame).iloc[0]
    w = (t >= end + 0.1) & (t <= end + 1.1)
    expected = 100 * np.ptp(tension[w]) / 2 / (tension[w].mean() - 2.0)
    assert res["residual_pct"] == pytest.approx(expected, rel=1e-9)
    assert res["position_mm"] == pytest.approx(40 * MM_PER_STEP)
