"""Arbitrary motion of the tip (helpers.research.tip_stream): a bend stream turned into tendon set-points.

Expected values by hand from the rig files: a step is pi 65 / 800 = 0.255254 mm of cable; one board unit held
for a 10 ms period moves 625 / 65536 step (104.8576 unit-periods per step). A bend of ``b`` towards ``beta``
pulls tendon ``i`` at ``a_i`` by ``b cos(beta - a_i)`` (equal offsets): 10 mm towards 45 deg is 7.0711 mm =
27.70 steps on tendons 1 and 2. The tendon opposite a bend pays out a little less than the pulled tendon takes
in (the statics: 9.85 mm against 10.10 mm for 10 mm towards 0 deg, ``docs/task_space.md``); paying it out the
constant-curvature 8 mm at a bend of 8 mm instead stretches it less by about 0.2 mm, 0.2 / 0.255 x 2.7 N =
2 N below its 2.36 N: under the 1 N floor.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from helpers import recordings, rigfile
from helpers.__main__ import error_line, main
from helpers.board import stream_reference as hs
from helpers.recordings import Recording
from helpers.research import tip_stream as ts
from helpers.research import tip_stream_metrics as tm
from helpers.research.task_shaping import pretensioned
from helpers.research.task_space import plan_move
from helpers.rig.safety import SafetyError
from helpers.rig.stream import StreamLimit, check_stream
from helpers.virtual.emulator.world import forget_world
from helpers.virtual.spatial.from_rig import spatial_rig

MM = math.pi * 65 / 800


@pytest.fixture(scope="module")
def four() -> rigfile.RigFile:
    return rigfile.load(rigfile.resolve("four-tendon"))


@pytest.fixture(scope="module")
def two(four) -> rigfile.RigFile:
    """The four-tendon rig with tendons 1 and 2 only (0 and 90 deg): a bend between them pays nothing out."""
    text = four.text.replace("[[tendon]]\nangle_deg = 180.0\n\n[[tendon]]\nangle_deg = 270.0\n\n", "")
    rig = rigfile.loads(text.replace('name = "four-tendon"', 'name = "two-tendon"'), "two.toml")
    assert rig.n_tendons == 2
    return rig


def _out_and_back(direction_deg: float, bend_mm: float, periods: int = 5, hold: int = 40) -> ts.TipPath:
    """Rest (10 periods), out in ``periods`` to the bend, hold, back in ``periods``, rest (``hold``)."""
    r = math.radians(direction_deg)
    step = np.array([math.cos(r), math.sin(r)]) * bend_mm / (periods * ts.PERIOD_S)
    v = np.vstack([np.zeros((10, 2)), np.repeat(step[None], periods, 0), np.zeros((hold, 2)),
                   np.repeat(-step[None], periods, 0), np.zeros((hold, 2))])  # fmt: skip
    return ts.velocity_path(v, f"out-and-back {direction_deg:g}")


# --- paths -------------------------------------------------------------------------------------------------
def test_a_velocity_command_integrates_to_the_bends_and_its_stops() -> None:
    path = _out_and_back(90.0, 10.0)
    # 10 mm in 5 periods: 200 mm/s of bend along y
    assert path.velocity_mm_s[10].tolist() == pytest.approx([0.0, 200.0], abs=1e-9)
    assert path.polar(15) == pytest.approx((90.0, 10.0))
    assert path.stops == ((0, 10), (15, 55), (60, 100))
    assert path.periods == 100


def test_the_figures_are_deterministic_and_start_and_end_at_rest() -> None:
    for name in ts.FIGURES:
        a, b = ts.figure_path(name, 10.0, seed=4), ts.figure_path(name, 10.0, seed=4)
        assert np.array_equal(a.bends, b.bends)
        assert not a.bends[0].any() and not a.bends[-1].any()
        assert np.max(np.hypot(*a.bends.T)) <= 10.0 + 1e-9
    square = ts.figure_path("square", 10.0, speed_mm_s=100.0, hold_s=1.0, lead_s=0.3)
    corners = [square.polar(a) for a, _ in square.stops]
    assert [tuple(round(v, 6) for v in c) for c in corners] == [
        (0.0, 0.0), (0.0, 10.0), (90.0, 10.0), (180.0, 10.0), (270.0, 10.0), (0.0, 10.0), (0.0, 0.0),
    ]  # fmt: skip
    # an edge of the square: 10 sqrt 2 = 14.14 mm at 100 mm/s, 14 whole periods
    assert square.stops[2][0] - square.stops[1][1] == 14
    assert (
        ts.figure_path("random", 10.0, seed=1).bends.tolist() != ts.figure_path("random", 10.0).bends.tolist()
    )
    with pytest.raises(ValueError, match="path must be one of square, star, circle, random, line"):
        ts.figure_path("spiral", 10.0)


def test_a_figure_turns_about_the_backbone_and_a_line_goes_out_and_back() -> None:
    """``turn_deg`` turns every bend: the square's first corner and the line's one stop at the turn."""
    line = ts.figure_path("line", 5.0, turn_deg=143.4)
    stops = [tuple(round(v, 6) for v in line.polar(a)) for a, _ in line.stops]
    assert stops == [(0.0, 0.0), (143.4, 5.0), (0.0, 0.0)]
    square = ts.figure_path("square", 10.0, turn_deg=90.0)
    assert [round(square.polar(a)[0], 6) for a, _ in square.stops[1:-1]] == [90.0, 180.0, 270.0, 0.0, 90.0]
    plain = ts.figure_path("square", 10.0)
    assert np.array_equal(plain.bends, ts.figure_path("square", 10.0, turn_deg=0.0).bends)
    assert np.allclose(np.hypot(*square.bends.T), np.hypot(*plain.bends.T))  # a turn keeps every magnitude


def test_a_rig_that_faces_no_tendon_towards_0_deg_streams_from_rest(four) -> None:
    """At rest the direction is no matter: a rig whose tendons all face away from 0 deg (at 100-250 deg)
    plans a line towards its tendon 1 (the rest was once solved towards 0 deg and refused)."""
    text = four.text
    for old, new in (("0.0", "160.0"), ("90.0", "100.0"), ("180.0", "200.0"), ("270.0", "250.0")):
        text = text.replace(f"[[tendon]]\nangle_deg = {old}\n", f"[[tendon]]\nangle_deg = {new}\n")
    away = rigfile.loads(text.replace('name = "four-tendon"', 'name = "away"'), "away.toml")
    assert [t.angle_deg for t in away.tendons] == [160.0, 100.0, 200.0, 250.0]
    plan = ts.plan_stream(away, ts.figure_path("line", 3.0, speed_mm_s=50.0, turn_deg=160.0))
    assert plan.stop_steps[0] == (0, 0, 0, 0) and plan.stop_steps[1][0] > 0  # tendon 1 pulled at the stop
    with pytest.raises(SafetyError, match=r"no tendon faces 0 deg"):
        ts.plan_stream(away, ts.figure_path("line", 3.0, speed_mm_s=50.0))


# --- the mapping -------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def twenty(four) -> ts.StreamPlan:
    """20 mm towards 0 deg and back: the stop where rounding leaves tendon 2 short and the policy trims it."""
    return ts.plan_stream(four, _out_and_back(0.0, 20.0, periods=10), knot_mm=2.0)


def test_a_held_bend_stands_at_plan_moves_steps(four, twenty) -> None:
    """Independent: plan_move solves the bend from rest, the stream by continuation along the path."""
    expected = plan_move(four, 0.0, 20.0)
    assert twenty.stop_steps[1] == expected.steps  # (+79, +2, -75, +1): tendon 2 pulled in one step
    assert twenty.trimmed[1] == expected.trimmed
    assert twenty.stop_steps[0] == twenty.stop_steps[2] == (0, 0, 0, 0)
    # the planned positions at the stop are those steps to within one board unit-period (1 / 104.86 step)
    a, b = twenty.path.stops[1]
    assert np.all(np.abs(twenty.positions[a : b + 1] - np.array(expected.steps)) < 1 / ts.UNITS_PER_STEP)
    assert twenty.tension_n[a] == pytest.approx(expected.tension_n, abs=0.05)
    assert twenty.tension_n.min() >= twenty.floor_n == 1.0


def test_the_stream_comes_back_to_rest_exactly(twenty) -> None:
    assert twenty.units.sum(axis=0).tolist() == [0, 0, 0, 0]
    assert np.all(twenty.positions[-1] == 0.0)


def test_a_straight_line_sums_to_its_end_displacement_and_the_board_stands_there(two) -> None:
    """Rest to 10 mm towards 45 deg and hold: each tendon's set-points x 10 ms sum to its 28 steps (27.70
    rounded) x 0.255254 mm, to within one unit-period; the board's planner, shaped by a two-impulse shaper,
    stands at 28 steps."""
    v = np.vstack([np.zeros((5, 2)), np.full((8, 2), 10 * math.cos(math.pi / 4) / 0.08), np.zeros((40, 2))])
    path = ts.velocity_path(v, "line")
    plan = ts.plan_stream(two, path, knot_mm=2.0)
    assert plan.stop_steps[-1] == (28, 28)
    moved = plan.setpoints_mm_s.sum(axis=0) * ts.PERIOD_S
    assert np.all(np.abs(moved - 28 * MM) <= MM / ts.UNITS_PER_STEP + 1e-9)
    shaper = hs.StreamShaper((2048, 2048), (0, 50_000))
    assert ts.board_counts(plan, two, shaper)[-1] == (28, 28)
    assert ts.check_plan(plan, two, shaper).end == (28, 28)


def test_the_statics_between_knots_is_interpolated_within_a_hundredth_of_a_step(two) -> None:
    path = ts.velocity_path(np.vstack([np.zeros((2, 2)), np.tile([[40.0, 30.0]], (20, 1))]), "slow line")
    # 10 mm in 20 periods (0.5 mm each), knots every 2 mm: every fourth boundary, the midpoints solved
    assert ts.interpolation_error(two, path, knot_mm=2.0) < 0.01


# --- the floor, before any byte -----------------------------------------------------------------------
def test_a_path_that_leaves_the_opposite_tendon_short_is_refused_naming_it(four) -> None:
    """Paying every tendon out by the constant-curvature lengths (no statics) leaves the tendon opposite the
    bend (towards 0 deg: tendon 3, at 180 deg) short by about 2 N at 8 mm (module docstring)."""
    star = ts.figure_path("star", 10.0, speed_mm_s=200.0, lead_s=0.3)
    # boundaries 0-29 at rest, then 2 mm of bend per period towards 0 deg: 8 mm at boundary 33
    path = ts.velocity_path(star.velocity_mm_s[:45], "star")
    assert path.polar(33) == pytest.approx((0.0, 8.0))
    with pytest.raises(SafetyError) as info:
        ts.plan_stream(four, path, mapping="kinematic")
    text = str(info.value)
    assert text.startswith("tendon 3: the star path (10 mm) leaves it at 0.")
    assert (
        "by statics at period 33 (t = 0.33 s, bend 8.00 mm towards 0.0 deg), below the tension floor " in text
    )
    assert "1.00 N ([arm] tension_floor_n)" in text and "\n" not in text
    assert error_line(info.value)[1] == 3
    # the statics' own mapping holds it at its pretension: the same path is planned
    plan = ts.plan_stream(four, path, knot_mm=2.0)
    assert plan.tension_n[:, 2].min() >= 2.3


def test_a_rest_pretension_below_the_floor_is_refused(four) -> None:
    low = rigfile.loads(four.text.replace("pretension_n = 2.3554", "pretension_n = 0.8"), "low.toml")
    with pytest.raises(
        SafetyError, match=r"^tendon 1: its rest pretension 0.80 N is below the tension floor"
    ):
        ts.plan_stream(low, _out_and_back(0.0, 5.0))


def test_a_direction_no_tendon_faces_is_refused(two) -> None:
    with pytest.raises(SafetyError, match=r"no tendon faces 180 deg \(tendons at 0, 90 deg\)"):
        ts.plan_stream(two, _out_and_back(180.0, 5.0))


def test_the_stream_checks_a_shaped_motion_after_a_lead_at_rest(four) -> None:
    """The board's shaped motion is checked whatever comes first: 20 periods at rest, then 365 mm/s (1499
    units) through a 1.5 / -0.5 shaper is 2248.5 units in period 21, over the 1640 limit."""
    overshoot = hs.StreamShaper((6144, -2048), (0, 50_000), allow_negative=True)
    sp = np.zeros((23, 4))
    sp[20:, 3] = 365.0
    with pytest.raises(StreamLimit, match=r"^tendon 4, set-point 20: the shaped stream would exceed the "
                                          r"speed limit .* in period 21$"):  # fmt: skip
        check_stream(sp, four, (0, 0, 0, 0), overshoot)


# --- the shaper ---------------------------------------------------------------------------------------------
def test_the_design_is_the_mean_of_the_maps_mode_at_the_stops(two) -> None:
    path = _out_and_back(45.0, 10.0)
    d = ts.stream_design(two, path, "zvd")
    assert len(d.points) == 1 and d.points[0][:2] == (45.0, 10.0)
    # docs/task_space.md: the two-tendon rig, 10 mm towards 45 deg: 26.996 rad/s, zeta 0.0424
    assert d.omega_d == pytest.approx(26.996, abs=0.01) and d.zeta == pytest.approx(0.0424, abs=1e-4)
    assert d.shaper.times[-1] == pytest.approx(2 * math.pi / d.omega_d)  # ZVD: one damped period
    assert "every tendon" in d.describe() and ts.stream_design(two, path, "none").shaper is None


# --- python -m helpers record tip-stream ------------------------------------------------------------------
@pytest.mark.slow  # the whole-step check of the pre-pulled square: 35 s on two loaded cores (main's: 20 s)
def test_record_tip_stream_dry_run_prints_every_tendons_range_and_least_tension(tmp_path, monkeypatch,
                                                                             capsys) -> None:  # fmt: skip
    """A square of 5 mm at 200 mm/s on the four-tendon rig, every tendon pulled one step in first (without,
    its whole steps leave a tendon slack: tests/test_whole_steps.py): its corners are plan_move's bends from
    that pre-pulled rest (5 mm towards a tendon pulls it 5 / 0.255 = 19.6 steps and pays the opposite out
    about as much), within the travel -78..156 steps."""
    rig_args = ["--rig", "four-tendon"]
    argv = ["record", "tip-stream", "--path", "square", "--bend-mm", "5", "--v-in", "200", "--dry-run",
            "--prepull", "1", "--data-dir", str(tmp_path / "data")]  # fmt: skip
    assert main(rig_args + argv) == 0
    out = capsys.readouterr().out
    four = rigfile.load(rigfile.resolve("four-tendon"))
    corner = plan_move(four, 0.0, 5.0, spatial=pretensioned(four, spatial_rig(four), 1)).steps
    assert f"5 mm towards 0 deg: {', '.join(f'{n:+d}' for n in corner)}" in out
    for i in range(1, 5):
        line = next(x for x in out.splitlines() if x.strip().startswith(f"tendon {i}: positions"))
        assert (
            "its travel -78-156 steps" in line and "least static tension" in line and "floor 1.00 N" in line
        )
    assert "shaper: unshaped" in out
    assert "pre-pull: every tendon pulled 1 step(s) in before the path (1 period, then 0.50 s at rest)" in out
    assert "(tendons 1, 3, 2, 4, 0.25 s apart)" in out
    assert "checked: the least static tensions at the board's whole-step counts at every period" in out
    assert "stands at the plan's whole steps at every stop" in out
    assert "tip_streams/tip_square_none_b5_pre1.csv; nothing was sent" in out
    assert not (tmp_path / "data").exists()


@pytest.mark.slow  # the statics at the board's counts, then 5 s of the spatial twin
def test_record_tip_stream_trim_trims_before_and_at_every_long_stop(tmp_path, capsys) -> None:
    """``--trim`` as a user types it: the dry run names the rests, and the recording keeps what each measured.
    On the nominal twin every tendon stands at its planned tension at each rest, so nothing moves there."""
    argv = ["--rig", "four-tendon", "record", "tip-stream", "--path", "line", "--bend-mm", "10", "--prepull",
            "1", "--shaper", "zvd", "--trim", "--data-dir", str(tmp_path / "data")]  # fmt: skip
    assert main([*argv, "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "--trim: every tendon trimmed by measurement before the stream and at 2 of its stops" in out
    assert main([*argv, "--quiet"]) == 0
    rec = recordings.load(tmp_path / "data" / "tip_streams" / "tip_line_zvd_b10_pre1.csv")
    assert rec.meta["status"] == "complete" and rec.meta["scenario"]["measured_trim"]["steps"] == [0] * 4
    rests = rec.meta["scenario"]["stream"]["rest_trims"]
    assert [r["steps"] for r in rests] == [[0] * 4] * 2
    gaps = np.subtract([r["measured_n"] for r in rests], [r["targets_n"] for r in rests])
    assert np.abs(gaps).max() < 0.05  # the twin's tension at the board's counts, measured through its noise


def test_record_tip_stream_refuses_a_figure_the_rig_cannot_reach(two, tmp_path, monkeypatch, capsys) -> None:
    """The star's third direction, 90 deg, faces tendon 2; its fifth, 180 deg, faces no tendon at 0 or 90 deg
    (cos 180 deg < 0, cos 90 deg = 0)."""
    path = tmp_path / "two.toml"
    path.write_text(two.text)
    rig_args = ["--rig", str(path)]
    argv = [
        "record",
        "tip-stream",
        "--path",
        "star",
        "--bend-mm",
        "5",
        "--dry-run",
        "--data-dir",
        str(tmp_path),
    ]
    assert main(rig_args + argv) == 3
    err = capsys.readouterr().err.strip()
    assert (
        err.startswith("error: the star path (5 mm) refused: no tendon faces 180 deg (tendons at 0, 90 deg)")
        and "\n" not in err
    )


# --- end to end on the virtual rig ------------------------------------------------------------------------
@pytest.mark.slow
def test_a_tip_stream_on_the_virtual_rig_stands_at_the_plan_and_records_tip_and_tensions(
    tmp_path, monkeypatch
) -> None:
    """The four-tendon square of 5 mm shaped by ZVD, every tendon pulled one step in first, recorded: every
    stop's step counts are the plan's (one above them), the stream ends at rest, the scenario names the
    stream, the shaper, the path and the pre-pull; the twin's tip and every tension are recorded
    (simulated)."""
    rig_args = ["--rig", "four-tendon"]
    data = tmp_path / "data"
    argv = ["record", "tip-stream", "--path", "square", "--bend-mm", "5", "--v-in", "200", "--shaper", "zvd",
            "--prepull", "1", "--data-dir", str(data), "--virtual-instance", "tip-stream-test",
            "--quiet"]  # fmt: skip
    try:
        assert main(rig_args + argv) == 0
    finally:
        forget_world("tip-stream-test")
    rec = recordings.load(data / "tip_streams" / "tip_square_zvd_b5_pre1.csv")
    scenario = rec.meta["scenario"]
    assert rec.status == "complete" and scenario["kind"] == "stream"
    assert scenario["shaper_name"] == "zvd" and scenario["design"]["shaper"] == "zvd"
    assert scenario["path"]["figure"] == "square" and scenario["path"]["bend_mm"] == 5.0
    assert scenario["path"]["summary"].startswith("square path of 5 mm at 200 mm/s")
    assert [(s["direction_deg"], s["bend_mm"]) for s in scenario["path"]["stops"][1:5]] == [
        (0.0, 5.0), (90.0, 5.0), (180.0, 5.0), (270.0, 5.0),
    ]  # fmt: skip
    four = rigfile.load(rigfile.resolve("four-tendon"))
    plan = ts.plan_stream(four, ts.figure_path("square", 5.0, speed_mm_s=200.0), prepull=1)
    assert scenario["stop_steps"] == [list(s) for s in plan.stop_steps]
    pre = (scenario["prepull_steps"], scenario["prepull_periods"], scenario["release_periods"])
    assert pre == (1, 51, 104)  # the pull and 0.5 s; 4 x (the let-out and 0.25 s)
    assert scenario["stream"]["n_setpoints"] == 51 + plan.path.periods + 104
    t = tm.stream_clock(rec)  # from the path's period 0: 0.51 s after STREAM
    for (_a, b), steps in zip(plan.path.stops, plan.stop_steps, strict=True):
        k = np.searchsorted(t, (b + 2) * ts.PERIOD_S) - 1  # the stop's last boundary, before the next move
        assert [int(rec.frame[f"steps_{i}"].iloc[k]) for i in range(4)] == [v + 1 for v in steps]
    assert [int(rec.frame[f"steps_{i}"].iloc[-1]) for i in range(4)] == [0, 0, 0, 0]
    assert all(c in rec.frame.columns for c in ("tip_x_mm", "tip_y_mm", "tip_z_mm"))
    least = tm.tension_summary(rec, plan.floor_n)
    assert least["tendon"].tolist() == [1, 2, 3, 4] and (least["samples"] == least["samples"][0]).all()
    stops = tm.stop_metrics(rec, plan)
    assert len(stops) == len(plan.path.stops) - 1
    # at the last stop, back at rest, the tip is where the statics puts it to within a millimetre
    assert stops["tip_offset_mm"].iloc[-1] < 1.0
    row = tm.summary(rec, plan)
    assert (
        row["below_floor"] == least["below_floor"].sum() and row["tip_pp_max_mm"] == stops["tip_pp_mm"].max()
    )
    assert 0.0 < row["lag_s"] < 0.6  # ZVD's mean delay is half its 0.25 s


def test_the_tension_summary_separates_step_transients_from_a_slack_tendon() -> None:
    """1 kHz, STREAM at 0.1 s: tendon 1 at 2 N with a 3 ms dip to 0 N every 100 ms from 0.2 s (eight dips, 24
    samples below 1 N; a 20 ms mean over a dip is 2 x 17 / 20 = 1.7 N, none below); tendon 2 at 0.5 N for
    50 ms from 0.5 s (50 samples). A 20 ms mean holding m of those is (2 (20 - m) + 0.5 m) / 20, below 1 N for
    m >= 14: the centred window [k - 10, k + 9] holds 14 or more for k = 504..546, 43 samples."""
    t_us = np.arange(1000) * 1000
    one = np.full(1000, 2.0)
    for start in range(200, 1000, 100):
        one[start : start + 3] = 0.0
    two = np.full(1000, 2.0)
    two[500:550] = 0.5
    frame = pd.DataFrame({"t_us": t_us, "tension_n_0": one, "tension_n_1": two})
    rec = Recording(frame=frame, meta={"scenario": {"t_stream_us": 100_000}, "rate_hz": 1000, "tendons": 2})
    table = tm.tension_summary(rec, 1.0)
    assert table["below_floor"].tolist() == [24, 50]
    assert table["least_n"].tolist() == [0.0, 0.5] and table["at_s"].tolist() == pytest.approx([0.1, 0.4])
    assert table["below_floor_smoothed"].tolist() == [0, 43]
    assert table["least_smoothed_n"][0] == pytest.approx(1.7)


def test_a_margin_trims_the_stops_away_from_rest_and_leaves_rest_at_zero(four) -> None:
    """10 mm towards 0 deg: rounding leaves the side tendons 2 and 4 at 1.18 N (docs/task_space.md), above the
    1 N floor (no trim) but below floor + 0.5 N: with the margin tendon 2 is pulled in (the lower of two equal
    tendons, the first), and rest stays at zero steps on every tendon."""
    path = _out_and_back(0.0, 10.0)
    plain = ts.plan_stream(four, path, knot_mm=2.0)
    assert plain.stop_steps[1] == plan_move(four, 0.0, 10.0).steps == (40, 0, -39, 0)
    assert plain.trimmed[1] == (0, 0, 0, 0)
    margin = ts.plan_stream(four, path, knot_mm=2.0, margin_n=0.5)
    assert margin.trimmed[1][1] == 1 and margin.stop_steps[1][1] == 1
    a, _ = path.stops[1]
    assert margin.tension_n[a].min() >= 1.5
    assert margin.stop_steps[0] == margin.stop_steps[2] == (0, 0, 0, 0) and margin.margin_n == 0.5
