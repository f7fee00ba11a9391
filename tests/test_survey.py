"""Modes across configurations: the two-mode ring-down fit on signals with known modes, the survey's
programmes, and the map built from its rows."""

import math

import numpy as np
import pandas as pd
import pytest

from helpers.research.ringdown import fit_two_modes
from helpers.research.survey import KICK_MM, map_from_rows, survey_plan
from helpers.rig import check_programme
from rigs import SHIPPED

PAPER = SHIPPED["paper"]  # the paper's rig: its cable per step and travel by hand (tests/rigs.py)
MM_PER_STEP, MAX_TRAVEL_MM = PAPER.mm_per_step, PAPER.hw("travel_mm")

FS = 1000.0


def decay(t, omega_d, zeta, amplitude, phase):
    wn = omega_d / math.sqrt(1 - zeta**2)
    return amplitude * np.exp(-zeta * wn * t) * np.sin(omega_d * t + phase)


@pytest.mark.parametrize("big_second", [False, True])
def test_two_modes_are_recovered_and_ordered_by_frequency(big_second):
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 2.0, 1 / FS)
    a1, a2 = (0.3, 0.5) if big_second else (0.5, 0.25)
    y = 7.0 + decay(t, 28.5, 0.042, a1, 0.4) + decay(t, 78.0, 0.031, a2, 1.3) + rng.normal(0, 0.01, t.size)
    fit = fit_two_modes(t, y)
    assert fit.omega_d == pytest.approx(28.5, rel=2e-3) and fit.zeta == pytest.approx(0.042, rel=0.05)
    assert fit.omega_d2 == pytest.approx(78.0, rel=2e-3) and fit.zeta2 == pytest.approx(0.031, rel=0.08)
    assert fit.share2 == pytest.approx(a2 / (a1 + a2), abs=0.02)
    # the stated standard errors are honest: the truth lies within 4 of them
    assert abs(fit.omega_d - 28.5) < 4 * fit.omega_d_se + 1e-3
    assert abs(fit.share2 - a2 / (a1 + a2)) < 4 * fit.share2_se + 0.01


def test_a_single_mode_leaves_the_second_unreported():
    rng = np.random.default_rng(4)
    t = np.arange(0.0, 2.0, 1 / FS)
    y = 2.3 + decay(t, 25.1, 0.044, 0.4, 0.0) + rng.normal(0, 0.01, t.size)
    fit = fit_two_modes(t, y)
    assert fit.omega_d == pytest.approx(25.1, rel=2e-3)
    assert fit.omega_d2 is None and fit.share2 is None


def test_plans_ring_at_the_position_and_beside_it_within_the_travel():
    kick = round(KICK_MM / MM_PER_STEP) * MM_PER_STEP
    for x in (0.0, 20.0, 40.0):
        plan = survey_plan(x, PAPER.load())
        check_programme(plan.programme, PAPER.load())  # raises if any limit is passed (the paper's rig)
        assert plan.programme.net_steps == 0  # ends where it started
        away, back = plan.rings
        assert back[0] == pytest.approx(plan.position_mm)
        assert abs(away[0] - plan.position_mm) == pytest.approx(kick)
        assert 0.0 <= away[0] <= MAX_TRAVEL_MM and away[2] - away[1] == pytest.approx(2.0)
        assert away[2] < back[1]  # the first ring-down window closes before the kick back
    at_limit = survey_plan(40.0, PAPER.load())
    assert at_limit.rings[0][0] < at_limit.position_mm  # released first at the limit
    with pytest.raises(ValueError, match="outside"):
        survey_plan(41.0, PAPER.load())


def test_the_map_averages_repetitions_and_keeps_the_larger_error():
    rows = pd.DataFrame({
        "position_mm": [0.0, 0.0, 10.0, 10.0],
        "omega_d_rad_s": [25.0, 25.2, 26.0, 26.0], "omega_d_se_rad_s": [0.01, 0.01, 0.3, 0.3],
        "zeta": [0.044, 0.044, 0.043, 0.043], "zeta_se": [0.001] * 4,
        "omega_d2_rad_s": [130.0, 130.0, 99.0, float("nan")], "omega_d2_se_rad_s": [0.1] * 4,
        "zeta2": [0.03] * 4, "zeta2_se": [0.001] * 4, "share2": [0.4, 0.4, 0.5, float("nan")],
        "share2_se": [0.01] * 4,
    })  # fmt: skip
    m = map_from_rows(rows, {"kind": "virtual-rig", "method": "test"})
    assert m.omega_d.tolist() == pytest.approx([25.1, 26.0])
    # spread of (25.0, 25.2) over sqrt(2) = 0.1 beats the fits' 0.01; at 10 mm the fits' 0.3 wins
    assert m.omega_d_se.tolist() == pytest.approx([0.1, 0.3])
    assert not m.has_second_mode and "not resolved at 10.00 mm" in m.source["second_mode"]
