"""Shapers for task-space moves (helpers.research.task_shaping): designs, the grid, the choice, the floor.

Expected values are computed here from closed forms, independently of the code under test:

- ZV / ZVD (Singer and Seering; the paper's TDFs): ``K = exp(-zeta pi / sqrt(1 - zeta^2))``, ZV
  ``[1, K] / (1 + K)`` at ``0, pi/omega_d``, ZVD ``[1, 2K, K^2] / (1 + K)^2`` at ``0, pi/omega_d,
  2 pi/omega_d``;
- the residual of impulses ``A_i`` at ``t_i`` for a mode ``(omega_n, zeta)``:
  ``V = exp(-zeta omega_n t_N) |sum A_i exp(zeta omega_n t_i) exp(j omega_d t_i)|`` (written out below);
- the firmware's step instants: step ``k`` of ``n`` in a window ``W`` at ``ceil(2 k W / n) / 2`` us.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from helpers import rigfile
from helpers.__main__ import main
from helpers.board.programmes import Dwell, Move, Programme
from helpers.paper.shapers import Shaper
from helpers.research import task_shaping as ts
from helpers.research.task_space import MovePlan, move_programme, plan_move
from helpers.rig.safety import SafetyError
from helpers.virtual.spatial.direction_map import frequency_map
from helpers.virtual.spatial.from_rig import spatial_rig

MM = math.pi * 65 / 800  # mm of cable per step


@pytest.fixture(scope="module")
def four() -> rigfile.RigFile:
    return rigfile.load(rigfile.resolve("four-tendon"))


def _v(amps, times, omega_n: float, zeta: float) -> float:
    """The closed-form residual of impulses (module docstring), by hand."""
    wd = omega_n * math.sqrt(1 - zeta * zeta)
    c = sum(a * math.exp(zeta * omega_n * t) * math.cos(wd * t) for a, t in zip(amps, times, strict=True))
    s = sum(a * math.exp(zeta * omega_n * t) * math.sin(wd * t) for a, t in zip(amps, times, strict=True))
    return math.exp(-zeta * omega_n * times[-1]) * math.hypot(c, s)


def _modes(beta: float, bend: float, omega_d, zeta, lead_weights, others=None) -> ts.MoveModes:
    """A hand-made set of modes: the lead tendon (1) with ``lead_weights``, the others ``others``."""
    rows = [tuple(lead_weights)] + [tuple(others or lead_weights)] * 3
    return ts.MoveModes(beta, bend, 0, tuple(omega_d), tuple(zeta), tuple(rows))


def _grid(points: dict[tuple[float, float], ts.MoveModes]) -> ts.ModeGrid:
    dirs = sorted({d for d, _ in points})
    bends = sorted({b for _, b in points})
    return ts.ModeGrid(tuple(dirs), tuple(bends),
                       {(dirs.index(d), bends.index(b)): m for (d, b), m in points.items()})  # fmt: skip


def _plan(beta: float = 0.0, bend: float = 10.0, steps=(40, 0, -39, 0)) -> MovePlan:
    return MovePlan(beta, bend, tuple(steps), tuple(s * MM for s in steps), (0.0,) * 4, (3.0,) * 4, 1.0,
                    (True, False, False, False), (0, 0, 0, 0), 0)  # fmt: skip


def test_the_shaper_names_are_the_families_and_the_designs() -> None:
    assert ts.SHAPERS[:3] == ("none", "zv", "zvd")  # the task-space module's two, first
    assert {"zvdd", "ei", "ei2", "ei3", "mzv", "umzv", "scheduled", "multimode", "auto"} <= set(ts.SHAPERS)


def test_a_ramp_filters_a_mode_as_a_sinc() -> None:
    assert ts.ramp_factor(25.0, 0.0) == 1.0
    assert ts.ramp_factor(25.0, 2 * math.pi / 25.0) == pytest.approx(0.0, abs=1e-15)  # one whole period
    assert ts.ramp_factor(10.0, 0.1) == pytest.approx(math.sin(0.5) / 0.5)


def test_the_scheduled_design_at_a_grid_point_is_that_points_zvd_by_hand(four) -> None:
    wd, z = 24.6, 0.045
    grid = _grid({(0.0, 10.0): _modes(0, 10, (wd, 90.0), (z, 0.03), (1.0, 0.01)),
                  (90.0, 10.0): _modes(90, 10, (26.0, 90.0), (0.04, 0.03), (1.0, 0.01))})  # fmt: skip
    d = ts.design_move(four, _plan(0.0, 10.0), "scheduled", grid=grid)
    k = math.exp(-z * math.pi / math.sqrt(1 - z * z))
    assert d.source == "grid" and d.modes == ((wd, z),)
    np.testing.assert_allclose(d.shaper.times, [0, math.pi / wd, 2 * math.pi / wd], rtol=1e-12)
    np.testing.assert_allclose(d.shaper.amplitudes, np.array([1, 2 * k, k * k]) / (1 + k) ** 2, rtol=1e-12)
    zv = ts.design_move(four, _plan(0.0, 10.0), "zv", grid=grid)
    np.testing.assert_allclose(zv.shaper.amplitudes, [1 / (1 + k), k / (1 + k)], rtol=1e-12)
    assert zv.shaper.times[1] == pytest.approx(math.pi / wd, rel=1e-12)


def test_the_fixed_design_is_the_zvd_of_the_maps_dominant_mode_at_rest_for_every_move(four) -> None:
    row = frequency_map(spatial_rig(four), (0.0,), (0.0,), n_modes=1).iloc[0]
    wd, z = float(row["dominant_omega_d_rad_s"]), float(row["dominant_zeta"])
    k = math.exp(-z * math.pi / math.sqrt(1 - z * z))
    for beta in (0.0, 45.0):
        d = ts.design_move(four, _plan(beta, 10.0), "fixed")
        np.testing.assert_allclose(d.shaper.times, [0, math.pi / wd, 2 * math.pi / wd], rtol=1e-9)
        np.testing.assert_allclose(d.shaper.amplitudes, np.array([1, 2 * k, k * k]) / (1 + k) ** 2, rtol=1e-9)
        assert d.source == "rest" and "at rest" in d.describe()


def test_the_grid_interpolates_bilinearly_and_wraps_the_direction() -> None:
    pts = {(d, b): _modes(d, b, (w,), (0.04,), (1.0,))
           for (d, b), w in {(0.0, 10.0): 24.0, (0.0, 20.0): 26.0, (180.0, 10.0): 25.0,
                             (180.0, 20.0): 27.0}.items()}  # fmt: skip
    grid = _grid(pts)
    assert grid.at(0.0, 15.0).omega_d[0] == pytest.approx(25.0)  # halfway between 24 and 26
    assert grid.at(90.0, 10.0).omega_d[0] == pytest.approx(24.5)  # halfway between 0 and 180 deg
    assert grid.at(270.0, 20.0).omega_d[0] == pytest.approx(26.5)  # between 180 and 360 = 0 deg
    assert grid.at(-90.0, 20.0).omega_d[0] == pytest.approx(26.5)
    with pytest.raises(ValueError, match="outside the mode grid's 10-20 mm"):
        grid.at(0.0, 25.0)


def test_a_grid_survives_its_csv(tmp_path) -> None:
    pts = {(d, 10.0): _modes(d, 10.0, (24.0 + d / 100, 80.0), (0.04, 0.03), (1.0, 0.2), (0.5, 0.1))
           for d in (0.0, 120.0, 240.0)}  # fmt: skip
    grid = _grid(pts)
    back = ts.ModeGrid.read_csv(grid.write_csv(tmp_path / "grid.csv"))
    assert back.directions_deg == (0.0, 120.0, 240.0) and back.bends_mm == (10.0,)
    assert back.at(120.0, 10.0) == pts[(120.0, 10.0)]
    (tmp_path / "bad.csv").write_text("a,b\n1,2\n")
    with pytest.raises(ValueError, match=r"bad.csv: not a mode grid"):
        ts.ModeGrid.read_csv(tmp_path / "bad.csv")


def test_split_needs_a_quarter_of_the_weight_and_five_percent_apart() -> None:
    window = 0.05
    r = [ts.ramp_factor(w, window) for w in (25.0, 21.0, 25.5)]
    m = _modes(0, 20, (25.0, 21.0, 25.5), (0.045, 0.05, 0.045), (1.0, 0.3, 0.9))
    ratio, k = ts.split_ratio(m, window)
    assert k == 1 and ratio == pytest.approx(0.3 * r[1] / r[0])  # 25.5 is within 5 %: not a split
    assert ratio >= ts.SPLIT_WEIGHT
    weak = _modes(0, 20, (25.0, 21.0), (0.045, 0.05), (1.0, 0.2))
    assert ts.split_ratio(weak, window)[0] < ts.SPLIT_WEIGHT


def test_the_multimode_design_cancels_both_split_modes(four) -> None:
    m = _modes(0, 20, (25.5, 21.2), (0.045, 0.05), (1.0, 0.4))
    grid = _grid({(0.0, 20.0): m, (180.0, 20.0): m})
    d = ts.design_move(four, _plan(0.0, 20.0), "multimode", grid=grid)
    assert len(d.modes) == 2 and len(d.shaper) == 4  # ZV * ZV
    for wd, z in d.modes:
        wn = wd / math.sqrt(1 - z * z)
        assert _v(d.shaper.amplitudes, d.shaper.times, wn, z) < 1e-12
    # the scheduled ZVD on the dominant mode alone leaves the second one ringing
    s = ts.design_move(four, _plan(0.0, 20.0), "scheduled", grid=grid)
    assert _v(s.shaper.amplitudes, s.shaper.times, 21.2 / math.sqrt(1 - 0.05**2), 0.05) > 0.05
    one = _modes(0, 20, (25.5, 21.2), (0.045, 0.05), (1.0, 0.1))
    weak = _grid({(0.0, 20.0): one, (180.0, 20.0): one})
    fallback = ts.design_move(four, _plan(0.0, 20.0), "multimode", grid=weak)
    assert len(fallback.shaper) == 3 and "do not split" in fallback.note


def test_the_predicted_residual_weighs_each_mode_by_its_share(four) -> None:
    window = 0.05
    m = _modes(0, 10, (25.0, 60.0), (0.045, 0.03), (1.0, 0.5))
    shaper = Shaper((0.5, 0.5), (0.0, math.pi / 25.0), "half period")
    r = [ts.ramp_factor(w, window) for w in (25.0, 60.0)]
    v = [max(_v(shaper.amplitudes, shaper.times, wd / math.sqrt(1 - z * z) * f, z)
             for f in np.linspace(0.98, 1.02, 9)) for wd, z in ((25.0, 0.045), (60.0, 0.03))]  # fmt: skip
    expected = 100 * (r[0] * v[0] + 0.5 * r[1] * v[1]) / (r[0] + 0.5 * r[1])
    assert ts.predicted_residual_pct(shaper, m, window) == pytest.approx(expected, rel=1e-9)
    assert ts.predicted_residual_pct(None, m, window) == 100.0


def test_auto_picks_the_shortest_candidate_within_the_tolerance(four) -> None:
    m = _modes(0, 10, (24.6,), (0.045,), (1.0,))
    grid = _grid({(0.0, 10.0): m, (180.0, 10.0): m})
    plan = _plan(0.0, 10.0)
    d = ts.design_move(four, plan, "auto", grid=grid)
    # ZV's worst V within +-2 % of the mode, by hand: the candidate every other is longer than
    wn = 24.6 / math.sqrt(1 - 0.045**2)
    zv = ts.design_move(four, plan, "zv", grid=grid).shaper
    worst = max(_v(zv.amplitudes, zv.times, wn * f, 0.045) for f in np.linspace(0.98, 1.02, 9))
    assert 100 * worst < ts.AUTO_TOLERANCE_PCT
    assert d.shaper.name == "ZV" and d.candidates["chosen"].sum() == 1
    tight = ts.design_move(four, plan, "auto", grid=grid, tolerance_pct=0.5)
    table = tight.candidates
    ok = table[table["predicted_pct"] <= 0.5]
    assert tight.shaper.duration == pytest.approx(ok["duration_s"].min())
    assert tight.shaper.duration > zv.duration


def test_the_programme_steps_fall_on_the_firmwares_ticks() -> None:
    prog = Programme((Dwell(2), Move(1000, (3, -1)), Move(500, (0, 1))))
    (t1, s1), (t2, s2) = ts.programme_step_times(prog, 2)
    np.testing.assert_allclose(t1, np.array([2333.5, 2667.0, 3000.0]) * 1e-6)  # ceil(2k 1000/3)/2 + 2 ms
    np.testing.assert_array_equal(s1, [1, 1, 1])
    np.testing.assert_allclose(t2, np.array([3000.0, 3500.0]) * 1e-6)
    np.testing.assert_array_equal(s2, [-1, 1])


def test_a_prepull_pulls_every_tendon_in_first_and_lets_each_out_alone_after(four) -> None:
    prog = move_programme(_plan(), four, 200.0, None, 1.0, 3.0, 5.0)
    pre, start, release = ts.prepull_programme(prog, 2, 4)
    assert pre.items[0] == Move(2000, (2, 2, 2, 2))
    assert start == pytest.approx(2.0e-3 + ts.PREPULL_SETTLE_MS / 1e3)
    assert release == pytest.approx(start + prog.duration_s)
    outs = [it.steps for it in pre.items[len(prog.items) + 2 :] if isinstance(it, Move)]
    assert outs == [(-2, 0, 0, 0), (0, 0, -2, 0), (0, -2, 0, 0), (0, 0, 0, -2)]
    assert tuple(pre.positions((0, 0, 0, 0), 4)[-1]) == (0, 0, 0, 0)
    assert ts.prepull_programme(prog, 0, 4) == (prog, 0.0, prog.duration_s)


# --- the dynamic floor's policy on constructed cases --------------------------------------------------------
def _shaping(name: str, shaper: Shaper | None) -> ts.MoveShaping:
    return ts.MoveShaping(name, shaper, ((25.0, 0.045),))


ZV = Shaper((0.5, 0.5), (0.0, 0.12), "ZV")


def test_a_dip_that_a_prepull_lifts_changes_the_pretension() -> None:
    plan = _plan()
    calls = []

    def simulate(p, shaper, k):
        calls.append(k)
        least = np.array([3.0, 0.4, 2.0, 1.5]) + 3.0 * k  # one step in on every tendon: +3 N
        return least, (least < 1.0).astype(int) * 7

    def planner(k):
        return plan, _shaping("zv", ZV)

    fc = ts.dynamic_floor(plan, _shaping("zv", ZV), simulate, planner, lambda p, f, k: _shaping(f, ZV))
    assert calls == [0, 1]
    assert (fc.changed, fc.prepull, fc.ok) == ("pretension", 1, True)
    assert fc.least_n == (6.0, 3.4, 5.0, 4.5) and fc.below_floor == (0, 0, 0, 0)
    assert "changed the pretension: 1 step(s) pulled in on every tendon" in fc.lines()[-1]
    assert "7 samples below the floor" in fc.attempts[0]


def test_a_dip_no_prepull_lifts_changes_the_design_and_a_refused_prepull_stops_the_raising() -> None:
    plan = _plan()
    longer = {"ZVD": Shaper((0.25, 0.5, 0.25), (0.0, 0.12, 0.24), "ZVD"),
              "ZVDD": Shaper((0.125, 0.375, 0.375, 0.125), (0.0, 0.12, 0.24, 0.36), "ZVDD")}  # fmt: skip

    def simulate(p, shaper, k):
        ok = shaper.name == "ZVDD"
        least = np.full(4, 2.0 if ok else 0.5)
        return least, (least < 1.0).astype(int)

    def planner(k):
        if k == 2:
            raise SafetyError("tendon 1 would carry 19.6 N, at its stepper's pull-out tension")
        return plan, _shaping("zv", ZV)

    def redesign(p, family, k):
        return _shaping(family.lower(), longer[family]) if family in longer else _shaping(family, ZV)

    fc = ts.dynamic_floor(plan, _shaping("zv", ZV), simulate, planner, redesign)
    assert (fc.changed, fc.prepull, fc.ok, fc.shaping.shaper.name) == ("design", 0, True, "ZVDD")
    assert any("+2 step(s) before the move: refused (tendon 1 would carry 19.6 N" in a for a in fc.attempts)
    assert [a.split(":")[0] for a in fc.attempts] == [
        "as planned (zv)", "every tendon +1 step(s) before the move",
        "every tendon +2 step(s) before the move", "the design ZVD", "the design ZVDD",
    ]  # fmt: skip


def test_an_unshaped_move_below_the_floor_is_reported_never_changed() -> None:
    plan = _plan()
    fc = ts.dynamic_floor(plan, _shaping("none", None), lambda p, s, k: (np.zeros(4), np.full(4, 900)),
                          lambda k: pytest.fail("an unshaped move is not changed"),
                          lambda p, f, k: pytest.fail("an unshaped move is not redesigned"))  # fmt: skip
    assert (fc.changed, fc.ok, fc.below_floor) == ("nothing", False, (900,) * 4)
    assert "unshaped: never changed" in fc.lines()[-1]


def test_nothing_helps_returns_the_best_attempt_not_ok() -> None:
    plan = _plan()

    def simulate(p, shaper, k):
        least = np.full(4, 0.2 + 0.1 * k)
        return least, np.ones(4, dtype=int)

    fc = ts.dynamic_floor(plan, _shaping("zv", ZV), simulate, lambda k: (plan, _shaping("zv", ZV)),
                          lambda p, f, k: _shaping(f, Shaper((0.5, 0.5), (0.0, 0.5), f)))  # fmt: skip
    assert not fc.ok and fc.prepull == ts.MAX_PREPULL_STEPS and fc.changed == "pretension"
    assert "still missed" in fc.lines()[-1]


# --- the command line ---------------------------------------------------------------------------------------
def _two_tendon_rig(four: rigfile.RigFile, folder) -> str:
    text = four.text.replace("[[tendon]]\nangle_deg = 180.0\n\n[[tendon]]\nangle_deg = 270.0\n\n", "")
    path = folder / "two.toml"
    path.write_text(text.replace('name = "four-tendon"', 'name = "two-tendon"'))
    return str(path)


def test_record_move_dry_run_names_the_design_and_its_duration(four, tmp_path, monkeypatch, capsys) -> None:
    rig_args = ["--rig", str(_two_tendon_rig(four, tmp_path))]
    argv = ["record", "move", "--direction-deg", "45", "--bend-mm", "10", "--shaper", "ei", "--dry-run",
            "--no-floor-check", "--data-dir", str(tmp_path / "data")]  # fmt: skip
    assert main(rig_args + argv) == 0
    out = capsys.readouterr().out
    assert "shaper: ei: EI, 3 impulses over" in out and "predicted residual" in out
    assert "dynamic floor: not checked (--no-floor-check)" in out
    assert "move_ei_d45_b10.csv; nothing was sent" in out
    assert not (tmp_path / "data").exists()


def test_record_move_refuses_a_bad_mode_grid_in_one_line(four, tmp_path, monkeypatch, capsys) -> None:
    rig_args = ["--rig", str(_two_tendon_rig(four, tmp_path))]
    (tmp_path / "g.csv").write_text("x\n1\n")
    base = ["record", "move", "--direction-deg", "45", "--bend-mm", "10", "--dry-run", "--data-dir",
            str(tmp_path / "data")]  # fmt: skip
    assert main(rig_args + base + ["--shaper", "scheduled", "--mode-grid", str(tmp_path / "g.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "g.csv: not a mode grid" in err and len(err.splitlines()) == 1
    assert main(rig_args + base + ["--shaper", "zv", "--mode-grid", str(tmp_path / "g.csv")]) == 2
    assert "--mode-grid applies to --shaper scheduled, multimode or auto, not zv" in capsys.readouterr().err


# --- the spatial twin (slow) --------------------------------------------------------------------------------
@pytest.mark.slow
def test_a_shaped_four_tendon_move_whose_antagonist_goes_slack_is_prepulled(four) -> None:
    plan = plan_move(four, 0.0, 10.0)
    shaping = ts.design_move(four, plan, "zvd")
    fc = ts.floor_check(four, plan, shaping, times=(0.5, 3.5, 6.0))
    assert fc.attempts[0].startswith("as planned (zvd): least 0.00 N (tendon 3)")  # the paying-out tendon
    assert (fc.changed, fc.prepull, fc.ok) == ("pretension", 1, True)
    assert min(fc.least_n) >= 1.0 and sum(fc.below_floor) == 0
    # the redesign follows the pre-pulled arm: the pretension softens it (docs/spatial_twin.md, section 6)
    assert fc.shaping.modes[0][0] < shaping.modes[0][0]


@pytest.mark.slow
def test_on_the_twin_zvd_leaves_a_fraction_of_the_unshaped_residual(four) -> None:
    df = ts.residual_table(four, points=((45.0, 20.0),), names=("none", "zvd"), floor=False)
    unshaped, zvd = df.iloc[0], df.iloc[1]
    assert unshaped["tip_pct"] == pytest.approx(100.0)
    assert zvd["tip_pct"] < 50.0 and zvd["worst_p2p_pct"] < 100.0
    assert unshaped["below_floor"] > 0  # the measured problem: unshaped, tendons go slack


@pytest.mark.slow
def test_the_simulated_automatic_choice_is_the_shortest_within_its_target(four) -> None:
    move = ts.shaped_move(four, 45.0, 10.0, "auto")
    table = move.shaping.candidates
    assert move.prepull == 1 and move.check.ok  # the floor needed the pre-pull (docs/task_space.md)
    chosen = table[table["chosen"]].iloc[0]
    assert chosen["simulated_pct"] <= ts.AUTO_TARGET_PCT and chosen["below_floor"] == 0
    shorter = table[table["duration_s"] < chosen["duration_s"]]
    assert ((shorter["simulated_pct"] > ts.AUTO_TARGET_PCT) | (shorter["below_floor"] > 0)).all()
    assert (
        move.plan.steps
        == plan_move(four, 45.0, 10.0, spatial=ts.pretensioned(four, spatial_rig(four), 1)).steps
    )
    assert move.shaping.shaper.name == chosen["candidate"]


@pytest.mark.slow
def test_on_two_tendons_that_do_not_balance_the_floor_changes_the_design(four, tmp_path, monkeypatch,
                                                                          capsys) -> None:  # fmt: skip
    rig_args = ["--rig", str(_two_tendon_rig(four, tmp_path))]
    argv = ["record", "move", "--direction-deg", "45", "--bend-mm", "10", "--shaper", "zv", "--dry-run",
            "--data-dir", str(tmp_path / "data")]  # fmt: skip
    assert main(rig_args + argv) == 0
    out = capsys.readouterr().out
    # ZV leaves tendon 2 a few milliseconds below the floor; a pre-pull would bend this arm (tendons at 0
    # and 90 deg pull it towards 45), so the design changes: ZVD, whose three impulses keep the floor
    assert "tried: as planned (zv): least 0." in out and "samples below the floor" in out
    assert "+1 step(s) before the move: refused (pulling every tendon in would bend this arm" in out
    assert "dynamic floor kept: changed the design: the design ZVD" in out
    assert "MSEG 35736 8 8" in out  # ZVD's first impulse, 1 / (1 + K)^2 = 0.29 of 28 steps


# --- the second bending pair (the modes above the dominant pair) -------------------------------------------
@pytest.fixture(scope="module")
def pulled(four):
    """The four-tendon twin one step in on every tendon (the tune's pretension) and its move 20 mm at 180."""
    twin = ts.pretensioned(four, spatial_rig(four), 1)
    return twin, plan_move(four, 180.0, 20.0, twin)


def test_the_second_bending_pair_lies_where_a_zvd_leaves_it_and_a_zv_on_each_cancels_it(four, pulled) -> None:
    twin, plan = pulled
    dom = ts.move_modes(twin, 180.0, 20.0)
    k0 = int(np.argmax(dom.effective(0.1)))
    w1, z1 = dom.omega_d[k0], dom.zeta[k0]
    higher = ts.higher_modes(four, twin, plan)
    assert len(higher) == 2 and higher[0][0] < higher[1][0]
    assert all(2.0 * w1 < w < 5.0 * w1 and 0 < z < 0.1 for w, z in higher)
    # the ZVD at the dominant mode, by hand (module docstring)
    k = math.exp(-z1 * math.pi / math.sqrt(1 - z1**2))
    zvd = Shaper(np.array([1, 2 * k, k * k]) / (1 + k) ** 2, np.array([0, 1, 2]) * math.pi / w1)
    shaped = ts.with_higher_modes(zvd, higher, "ZVD * ZV * ZV")
    assert shaped.name == "ZVD * ZV * ZV"
    assert shaped.duration == pytest.approx(2 * math.pi / w1 + sum(math.pi / w for w, _ in higher))
    for w, z in higher:
        wn = w / math.sqrt(1 - z * z)
        assert _v(list(shaped.amplitudes), list(shaped.times), wn, z) < 1e-9
    # the plain ZVD leaves a share of at least one of them (its zeros: the design frequency's odd multiples)
    left = [_v(list(zvd.amplitudes), list(zvd.times), w / math.sqrt(1 - z * z), z) for w, z in higher]
    assert max(left) > 0.1


@pytest.mark.slow
def test_a_zv_on_the_second_bending_pair_takes_out_what_the_zvd_leaves_after_a_move(four, pulled) -> None:
    """Simulated (the twin, 20 mm towards 180 deg, one step pre-pulled): the ZVD designed at 10 mm towards
    tendon 1 (22.4 rad/s, as the tune's fixed ZVD) leaves 0.37-0.39 N on tendons 1 and 3, tendon 1 ringing
    mostly at the pair's upper mode (75.6 rad/s, 3.4 times the design's); a ZV on each mode of the pair
    takes out over half of it."""
    twin, plan = pulled
    ref = ts.move_modes(twin, 0.0, 10.0)  # the tune's fixed ZVD: the mode at 10 mm towards tendon 1
    k0 = int(np.argmax(ref.effective(0.05)))
    zvd = ts.FAMILIES["ZVD"](ref.omega_n(k0), ref.zeta[k0])
    both = ts.with_higher_modes(zvd, ts.higher_modes(four, twin, plan), "ZVD * ZV * ZV")
    plain = spatial_rig(four)
    worst = []
    for shaper in (zvd, both):
        run = ts.simulate_move(four, plan, shaper, 200.0, 1.5, 4.5, 8.0, twin=plain, prepull=1)
        w = (run.t >= run.end_up_s + 0.1) & (run.t <= run.end_up_s + 1.1)
        worst.append(float(np.max(np.ptp(run.output[w], axis=0)) / 2))
    assert worst[0] > 0.2
    assert worst[1] < 0.5 * worst[0]
