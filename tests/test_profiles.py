"""Tests of helpers.paper.profiles: the pulse, exact shaped profiles and stepper programmes."""

import json
import math
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers import rigfile
from helpers.board import programmes
from helpers.board.programmes import Dwell, Limits, Move, Programme, Segment
from helpers.paper import modes, profiles, shapers
from helpers.paper import numbers as paper
from helpers.paper.profiles import VelocityProfile
from helpers.research import families
from rigs import SHIPPED

ZV, ZVD = shapers.design_tdfs()
OMEGA_N = modes.omega_n_from_damped(paper.OMEGA_D, paper.ZETA)
SYSTEMS = {"unshaped": None, "zv": ZV, "zvd": ZVD}


PAPER = SHIPPED["paper"]
MM_PER_STEP = PAPER.mm_per_step  # the paper's 0.25525 mm, by hand (tests/rigs.py)
LIMITS = Limits.of(PAPER.load())  # the paper's board limits (checked against the keys below)


def test_mm_per_step_from_spool_and_steps():  # paper-only: the paper's published spool and steps
    assert MM_PER_STEP == pytest.approx(math.pi * paper.SPOOL_DIAMETER_M * 1e3 / paper.STEPS_PER_REV)
    assert f"{MM_PER_STEP:.5f}" == "0.25525"


# -- the pulse -------------------------------------------------------------------------------------
@pytest.mark.parametrize(("v", "x"), paper.TABLE_I_CONDITIONS)
def test_pulse_integral_equals_x_f(v, x):
    dt = 1e-5
    t = np.arange(0.0, 10.0, dt)
    vel = profiles.pulse_profile(v, x).sample(t)
    up = np.sum(vel[t < 5.0]) * dt
    down = np.sum(vel[t >= 5.0]) * dt
    assert up == pytest.approx(x, abs=v * dt)
    assert down == pytest.approx(-x, abs=v * dt)


def test_pulse_shape_matches_eq_14():
    t_p = 20.0 / 200.0
    t = np.array([0.99, 1.0, 1.0 + t_p / 2, 1.0 + t_p + 1e-9, 7.99, 8.0, 8.0 + t_p / 2, 8.0 + t_p + 1e-9])
    np.testing.assert_array_equal(
        profiles.pulse_profile(200.0, 20.0).sample(t), [0, 200, 200, 0, 0, -200, -200, 0]
    )


def test_pulse_refuses_bad_arguments():
    with pytest.raises(ValueError, match="v_in"):
        profiles.pulse_profile(-1.0, 10.0)
    with pytest.raises(ValueError, match="x_f"):
        profiles.pulse_profile(100.0, float("nan"))
    with pytest.raises(ValueError, match="down move"):
        profiles.pulse_profile(1.0, 10.0, t_up=1.0, t_down=8.0)


def test_table_i():
    table = profiles.table_i()
    assert len(table) == 12
    assert set(table["system"]) == set(paper.SYSTEMS)
    assert list(table.columns) == ["profile", "system", "v_in_mm_s", "x_f_mm", "t_p_s"]
    printed = {(200.0, 10.0): 0.05, (200.0, 20.0): 0.10, (200.0, 30.0): 0.15, (300.0, 20.0): 0.067}
    for row in table.itertuples():
        assert round(row.t_p_s, 3) == printed[(row.v_in_mm_s, row.x_f_mm)]
    assert set(table["profile"]) == {"Pulse", "Non-robust TDF", "Robust TDF"}


# -- exact piecewise-constant profiles -------------------------------------------------------------
@pytest.mark.parametrize("family", list(families.FAMILIES))
def test_shaped_profile_keeps_displacement(family):
    prof = profiles.single_pulse(200.0, 20.0, 1.0)
    shaped = prof.shaped(families.FAMILIES[family](OMEGA_N, paper.ZETA))
    assert shaped.piece_displacements.sum() == pytest.approx(20.0, rel=1e-12)
    assert shaped.end == pytest.approx(prof.end + families.FAMILIES[family](OMEGA_N, paper.ZETA).duration)


def test_shaped_profile_is_sum_of_delayed_copies():
    prof = profiles.pulse_profile(300.0, 20.0)
    shaped = prof.shaped(ZVD)
    t = np.linspace(0.5, 9.0, 4001)
    expected = sum(a * prof.sample(t - ti) for a, ti in zip(ZVD.amplitudes, ZVD.times, strict=True))
    np.testing.assert_allclose(shaped.sample(t), expected, atol=1e-9)


def test_shaped_profile_agrees_with_shaper_apply_on_grid():
    dt = 1e-4
    s = shapers.Shaper(np.array([0.3, 0.7]), np.array([0.0, 0.1]), "grid")
    t = np.arange(0.0, 2.0, dt)
    prof = profiles.single_pulse(200.0, 10.0, 0.5)
    np.testing.assert_allclose(prof.shaped(s).sample(t), s.apply(t, prof.sample(t)), atol=1e-9)


def test_displacement_is_integral_of_velocity():
    prof = profiles.pulse_profile(200.0, 30.0).shaped(ZV)
    dt = 1e-5
    t = np.arange(0.0, 10.0, dt)
    numeric = np.cumsum(prof.sample(t)) * dt
    np.testing.assert_allclose(prof.displacement(t), numeric, atol=200 * dt * 2)
    assert prof.displacement(12.0) == pytest.approx(0.0, abs=1e-12)


def test_velocity_profile_validation():
    with pytest.raises(ValueError, match="n\\+1"):
        VelocityProfile(np.array([0.0, 1.0]), np.array([1.0, 2.0]))
    with pytest.raises(ValueError, match="increasing"):
        VelocityProfile(np.array([0.0, 0.0]), np.array([1.0]))


# -- programme items and limits --------------------------------------------------------------------
def test_segment_and_dwell_timing():
    prog = Programme((Dwell(2), Segment(1, 3, 1000), Dwell(1), Segment(-1, 2, 700)))
    t, s = prog.step_times()
    np.testing.assert_allclose(t, [0.003, 0.004, 0.005, 0.0067, 0.0074], atol=1e-12)
    np.testing.assert_array_equal(s, [1, 1, 1, -1, -1])
    assert prog.duration_us == 2000 + 3000 + 1000 + 1400
    assert prog.net_steps == 1
    assert prog.commands() == ["CLEAR", "WAIT 2", "SEG 1 3 1000", "WAIT 1", "SEG -1 2 700"]
    np.testing.assert_array_equal(prog.position_steps([0.0029, 0.003, 0.0051, 0.0075]), [0, 1, 3, 1])


@pytest.mark.parametrize(
    "bad",
    [
        lambda: Segment(1, 1.5, 1000),
        lambda: Segment(1, 5, float("nan")),
        lambda: Segment(1, 0, 1000),
        lambda: Segment(0, 5, 1000),
        lambda: Segment(True, 5, 1000),
        lambda: Segment(1, 5, -700),
        lambda: Dwell(-1),
        lambda: Dwell(2.5),
        lambda: Dwell(float("nan")),
        lambda: Programme(("WAIT 5",)),
    ],
)
def test_bad_items_refused(bad):
    with pytest.raises(ValueError):
        bad()


def test_host_limits_follow_the_rig_file(shipped_rig):  # rig-parametrised (tests/conftest.py)
    r = shipped_rig
    rig = r.load()
    limits, d = Limits.of(rig), rigfile.derived(rig)
    assert limits.mm_per_step == pytest.approx((r.mm_per_step,), rel=1e-12)
    assert (limits.min_interval_us, limits.max_interval_us) == (r.min_interval_us, r.hw("max_interval_us"))
    assert (limits.travel_steps, limits.max_items) == ((r.travel_steps,), r.hw("programme_max_items"))
    assert (limits.max_dwell_ms, limits.max_speed_mm_s) == (r.hw("max_dwell_ms"), r.hw("speed_limit_mm_s"))
    assert (d.clip_low_counts, d.clip_high_counts) == r.clip_counts
    # the fastest step never exceeds the speed limit or the step-rate cap, and one microsecond less would
    assert r.mm_per_step / r.min_interval_us * 1e6 <= r.hw("speed_limit_mm_s") + 1e-9
    assert 1e6 / r.min_interval_us <= r.hw("step_rate_cap_hz")
    assert (r.mm_per_step / (r.min_interval_us - 1) * 1e6 > r.hw("speed_limit_mm_s")
            or 1e6 / (r.min_interval_us - 1) > r.hw("step_rate_cap_hz"))  # fmt: skip
    assert r.travel_steps * r.mm_per_step <= r.hw("travel_mm") < (r.travel_steps + 1) * r.mm_per_step


LIMIT_CASES = {
    "too fast": (lambda r: (Segment(1, 10, r.min_interval_us - 1),), "interval"),
    "too slow": (lambda r: (Segment(1, 1, r.hw("max_interval_us") + 1),), "interval"),
    "beyond the travel": (lambda r: (Segment(1, r.travel_steps + 1, 1000),), "travel"),
    "below zero": (lambda r: (Segment(1, 5, 1000), Segment(-1, 6, 1000)), "travel"),
    "long dwell": (lambda r: (Dwell(r.hw("max_dwell_ms") + 1),), "dwell"),
    "too many items": (
        lambda r: tuple(Dwell(1) for _ in range(r.hw("programme_max_items") + 1)),
        "programme length",
    ),
    "empty": (lambda r: (), "programme length"),
}


def _limits(r):
    return Limits.of(rigfile.load(r.path))


@pytest.mark.parametrize("case", list(LIMIT_CASES))
def test_limits_refused_with_named_limit(rig_file, case):  # every shipped rig, as a value
    items, limit = LIMIT_CASES[case]
    with pytest.raises(ValueError, match=limit):
        Programme(items(rig_file)).check_limits(_limits(rig_file))


def test_limits_accept_the_extremes(rig_file):  # every shipped rig, as a value
    r = rig_file
    Programme(
        (Segment(1, r.travel_steps, r.min_interval_us), Dwell(r.hw("max_dwell_ms")),
         Segment(-1, r.travel_steps, r.hw("max_interval_us")))
        + tuple(Dwell(0) for _ in range(r.hw("programme_max_items") - 3))
    ).check_limits(_limits(r))  # fmt: skip


def test_travel_checked_from_start_position(rig_file):  # every shipped rig, as a value
    prog = Programme((Segment(1, 10, 1000),))
    prog.check_limits(_limits(rig_file), start_position=rig_file.travel_steps - 10)
    with pytest.raises(ValueError, match="travel"):
        prog.check_limits(_limits(rig_file), start_position=rig_file.travel_steps - 9)


def test_the_quantiser_lands_on_whole_steps_of_the_rig(rig_file):  # every shipped rig, as a value
    r = rig_file
    moves = ((100.0, 10.0, ZV), (r.fastest_mm_s, r.longest_mm, None), (50.0, 0.6 * r.mm_per_step, None))
    for v, x, shaper in moves:
        prog, rep = programmes.experiment_programme(v, x, shaper, rig=rigfile.load(r.path))
        n = round(x / r.mm_per_step)
        assert rep.n_steps == n and rep.realised_mm == pytest.approx(n * r.mm_per_step, rel=1e-12)
        t, signs = prog.step_times()
        pos = np.cumsum(signs.astype(int))
        assert pos.max() == n <= r.travel_steps and pos[-1] == 0
        assert min(it.interval_us for it in prog.items if isinstance(it, Segment)) >= r.min_interval_us


def test_a_request_faster_than_the_rig_is_refused(rig_file):  # every shipped rig, as a value
    r = rig_file
    with pytest.raises(ValueError, match=f"interval limit.*{r.min_interval_us} us"):
        programmes.experiment_programme(r.hw("speed_limit_mm_s") + 1.0, 5.0, rig=rigfile.load(r.path))
    with pytest.raises(ValueError, match="travel"):
        programmes.experiment_programme(50.0, r.longest_mm + r.mm_per_step, rig=rigfile.load(r.path))


def test_to_dict_states_every_item_as_json():
    prog, _ = programmes.experiment_programme(200.0, 20.0, ZVD)
    data = json.loads(json.dumps(prog.to_dict()))
    assert [d["kind"] for d in data["items"]] == [it.command().split()[0] for it in prog.items]
    assert data["items"][1] == {"kind": "SEG", **{k: getattr(prog.items[1], k) for k in
                                                  ("direction", "n_steps", "interval_us")}}  # fmt: skip
    assert data["net_steps"] == 0 and data["duration_s"] == prog.duration_s
    moved = Programme((Move(7001, (3, 0, -1, 2)), Dwell(5))).to_dict()
    assert json.loads(json.dumps(moved))["items"] == [
        {"kind": "MSEG", "window_us": 7001, "steps": [3, 0, -1, 2]}, {"kind": "WAIT", "ms": 5},
    ]  # fmt: skip


def test_moves_step_every_axis_on_the_firmware_ticks():
    """MSEG's step k of n on tick ceil(k 2W / n) of 0.5 us (firmware/PROTOCOL.md); SEG's at k x interval.

    By hand: W = 7001 us = 14002 ticks: 3 steps at 4668, 9335, 14002 ticks (2334, 4667.5, 7001 us); 2 steps at
    7001, 14002 ticks; then a 1 ms dwell and axis 0's SEG of 2 steps, 1000 us apart, from 8001 us.
    """
    prog = Programme((Move(7001, (3, 0, 1, -2)), Dwell(1), Segment(1, 2, 1000)))
    (t0, s0), (t1, s1), (t2, s2), (t3, s3) = prog.step_times_us(4)
    np.testing.assert_array_equal(t0, [2334.0, 4667.5, 7001.0, 9001.0, 10001.0])
    assert len(t1) == 0 and list(t2) == [7001.0] and list(t3) == [3500.5, 7001.0]
    assert list(s0) == [1] * 5 and list(s3) == [-1, -1]
    assert prog.commands(4) == ["CLEAR", "MSEG 7001 3 0 1 -2", "WAIT 1", "SEG 1 2 1000"]
    assert tuple(prog.positions((0, 0, 0, 5), 4)[-1]) == (5, 0, 1, 3) and prog.n_steps == 8


FOUR = {  # four-tendon rig: 156 steps of travel, 78 of release, a step at most every 639 us
    "past the travel": ((Move(200000, (0, 0, 0, 157)),), "tendon 4, item 1 .* travel limit: position 157"),
    "past the release": ((Move(200000, (0, 0, -79, 0)),), r"tendon 3, item 1 .* position -79 .* -78-156"),
    "too fast": ((Move(10000, (0, 16, 0, 0)),), "tendon 2, item 1 .* interval limit: a step every 625 us"),
    "too slow": ((Move(3_000_000, (0, 0, 2, 0)),), "tendon 3, item 1 .* above the maximum interval"),
    "more tendons than the rig": ((Move(100000, (1, 1, 1, 1, 1)),), "5 step counts, but the rig has 4"),
}


@pytest.mark.parametrize("case", list(FOUR))
def test_several_tendons_are_checked_each_against_its_limits(case):
    items, message = FOUR[case]
    limits = Limits.of(rigfile.load(rigfile.resolve("four-tendon")))
    with pytest.raises(ValueError, match=message):
        Programme(items).check_limits(limits, (0, 0, 0, 0))
    Programme((Move(200000, (156, -78, 0, 3)),)).check_limits(limits, (0, 0, 0, 0))  # the extremes pass


def test_a_move_without_motion_is_no_item():
    with pytest.raises(ValueError, match="no tendon moves"):
        Move(1000, (0, 0, 0))


# -- the experiment programme ----------------------------------------------------------------------
COMMAND = re.compile(r"^(CLEAR|SEG (1|-1) [1-9][0-9]* [1-9][0-9]*|WAIT (0|[1-9][0-9]*))$")


@pytest.mark.parametrize("system", list(SYSTEMS))
@pytest.mark.parametrize(("v", "x"), paper.TABLE_I_CONDITIONS)
def test_experiment_programme_table_i(system, v, x):
    shaper = SYSTEMS[system]
    prog, report = programmes.experiment_programme(v, x, shaper)
    n = round(x / MM_PER_STEP)
    assert report.n_steps == n
    t, signs = prog.step_times()
    # exactly N steps up then N steps down, back to zero
    assert len(t) == 2 * n
    assert prog.net_steps == 0
    assert np.all(signs[:n] == 1) and np.all(signs[n:] == -1)
    assert np.all(np.diff(t) > 0)
    # the up move runs from t_up to the end of the shaped move, the down move from t_down
    dur = x / v + (shaper.duration if shaper else 0.0)
    assert 1.0 < t[0] and t[n - 1] <= 1.0 + dur + 1e-3
    starts = prog.item_starts_us()
    first_down = next(
        i for i, it in enumerate(prog.items) if isinstance(it, Segment) and it.direction == -1
    )
    assert abs(starts[first_down] / 1e6 - 8.0) < 1e-3
    assert 8.0 < t[n] and t[-1] <= 8.0 + dur + 1e-3
    assert prog.duration_s == pytest.approx(12.0, abs=1e-3)
    # the stepper follows the exact shaped displacement (scaled to whole steps) to within about one step
    exact = profiles.pulse_profile(v, x).shaped(shaper)
    grid = np.linspace(0.0, 12.0, 24001)
    err = prog.position_steps(grid) * MM_PER_STEP - exact.displacement(grid) * report.realised_mm / x
    # (cumulative rounding +-0.5 step, the staircase trails by up to 1 step, plus the rescaling)
    assert np.max(np.abs(err)) < 2.0 * MM_PER_STEP
    # commands in the protocol's format, short enough for the board's line buffer
    cmds = prog.commands()
    assert cmds[0] == "CLEAR" and "GO" not in cmds
    assert all(COMMAND.match(c) and len(c) <= 63 for c in cmds)
    prog.check_limits(LIMITS)


def test_quantisation_report_accounts_for_rounding():
    prog, rep = programmes.experiment_programme(200.0, 30.0, ZVD)
    assert rep.realised_mm == pytest.approx(118 * MM_PER_STEP)
    assert rep.realised_mm - rep.requested_mm == pytest.approx(118 * MM_PER_STEP - 30.0)
    seg = rep.pieces[rep.pieces["item"] == "SEG"]
    assert seg.loc[seg["move"] == "up", "steps"].sum() == 118
    assert seg.loc[seg["move"] == "down", "steps"].sum() == -118
    # piece ends on the realised clock are what the programme does
    ends = prog.item_starts_us() + np.array([it.duration_us for it in prog.items])
    seg_ends = [e for e, it in zip(ends, prog.items, strict=True) if isinstance(it, Segment)]
    np.testing.assert_allclose(seg["realised_end_s"], np.array(seg_ends) / 1e6, atol=1e-9)
    assert rep.max_timing_error_us < 1000.0
    assert list(rep.dwells["dwell"]) == ["lead-in", "hold", "trailing"]


def test_zero_velocity_pieces_become_dwells():
    # 10 mm at 200 mm/s lasts 50 ms < T = 125 ms: the ZV-shaped move pauses between its two pieces.
    prog, rep = programmes.experiment_programme(200.0, 10.0, ZV)
    kinds = [type(it).__name__ for it in prog.items]
    assert kinds[:4] == ["Dwell", "Segment", "Dwell", "Segment"]
    assert prog.items[2].ms == round((ZV.times[1] - 0.05) * 1e3)


def test_experiment_refuses_out_of_limits():  # paper-only: the paper rig's 400 mm/s and 40 mm
    with pytest.raises(ValueError, match="interval"):
        programmes.experiment_programme(450.0, 20.0)
    with pytest.raises(ValueError, match="travel"):
        programmes.experiment_programme(200.0, 41.0)
    with pytest.raises(ValueError, match="t_end"):
        programmes.experiment_programme(200.0, 20.0, ZVD, t_end=8.2)


def test_near_limit_speed_stays_within_step_rate():  # paper-only: its 639 us step
    # 12 steps rounded up from 11.6 in 7.6 ms would need 637 us steps: the board's 639 us is used instead
    prog, rep = programmes.experiment_programme(387.8, 2.96, None)
    prog.check_limits(LIMITS)
    assert min(it.interval_us for it in prog.items if isinstance(it, Segment)) >= LIMITS.min_interval_us
    assert 0 < rep.max_timing_error_us < 100.0


def test_long_hold_is_split_into_legal_dwells():
    prog, _ = programmes.experiment_programme(200.0, 10.0, None, t_up=1.0, t_down=130.0, t_end=131.0)
    prog.check_limits(LIMITS)
    assert max(it.ms for it in prog.items if isinstance(it, Dwell)) <= LIMITS.max_dwell_ms


@settings(max_examples=40, deadline=None)
@given(
    v=st.floats(20.0, 380.0),
    x=st.floats(1.0, 39.5),
    family=st.sampled_from([None, *families.FAMILIES]),
    omega=st.floats(10.0, 80.0),
    zeta=st.floats(0.0, 0.2),
)
def test_programme_lands_on_whole_steps(v, x, family, omega, zeta):
    shaper = None if family is None else families.FAMILIES[family](omega, zeta)
    prog, rep = programmes.experiment_programme(v, x, shaper, t_end=12.0)
    n = round(x / MM_PER_STEP)
    assert rep.n_steps == n
    t, signs = prog.step_times()
    pos = np.cumsum(signs.astype(int))
    assert pos[np.searchsorted(t, 8.0, side="left") - 1] == n
    assert prog.net_steps == 0
    assert pos.min() >= 0 and pos.max() <= LIMITS.travel_steps[0]
    prog.check_limits(LIMITS)
