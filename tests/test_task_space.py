"""Moves in task space (helpers.research.task_space): a bend turned into every tendon's steps, the floor.

Expected values by hand from the rig files: a step is pi 65 / 800 = 0.255254 mm of cable, the travel 156
steps (39.82 mm), the release below rest floor(20 / 0.255254) = floor(78.35) = 78 steps (19.91 mm). A
bend of ``b`` mm towards ``beta`` pulls tendon ``i`` at ``a_i`` by ``b cos(beta - a_i)`` (equal offsets),
so 10 mm towards 45 deg is 7.0711 mm = 27.70 steps on tendons 1 and 2, towards 30 deg 8.660 mm = 33.93
steps on tendon 1 and 5.0 mm = 19.59 steps on tendon 2 (the stepper's command adds its rotor's lag, under
half a step here). The opposite tendon pays out about the same cable as the pulled one takes in.
The hanging rig (gravity along the backbone) is symmetric about the plane between two neighbours, so its
plan for 45 deg is mirrored and 30 deg mirrors 60 deg.
"""

from __future__ import annotations

import math

import pytest

from helpers import recordings, rigfile
from helpers.__main__ import main
from helpers.paper.shapers import Shaper
from helpers.research.task_space import MovePlan, check_travel, move_design, move_programme, plan_move
from helpers.rig.safety import SafetyError, check_programme
from helpers.virtual.emulator.world import forget_world

MM = math.pi * 65 / 800


@pytest.fixture(scope="module")
def hanging() -> rigfile.RigFile:
    return rigfile.load(rigfile.resolve("hanging"))


@pytest.fixture(scope="module")
def four() -> rigfile.RigFile:
    return rigfile.load(rigfile.resolve("four-tendon"))


def test_the_floor_is_the_rig_files(hanging, four) -> None:
    assert hanging.arm.tension_floor_n == 1.0  # stated in hanging.toml
    assert four.arm.tension_floor_n == 1.0  # the documented default


def test_a_bend_between_two_tendons_of_the_symmetric_rig_is_mirrored(hanging) -> None:
    p = plan_move(hanging, 45.0, 10.0)
    assert p.pulled == (True, True, False, False)
    assert p.steps[0] == p.steps[1] == round(10 * math.cos(math.pi / 4) / MM)  # 27.70 -> 28
    assert p.steps[2] == p.steps[3] < 0  # both antagonists pay out
    assert abs(p.steps[2] + 28) <= 2
    assert p.tension_n[0] == pytest.approx(p.tension_n[1], rel=1e-6)
    assert p.tension_n[2] == pytest.approx(p.tension_n[3], rel=1e-6)
    assert min(p.tension_n) >= 1.0
    assert p.displacement_mm[0] == pytest.approx(28 * MM)


def test_mirrored_directions_give_mirrored_plans(hanging) -> None:
    a, b = plan_move(hanging, 30.0, 10.0), plan_move(hanging, 60.0, 10.0)
    assert a.steps[0] == 34 and a.steps[1] == 20  # 33.93 and 19.59 steps, the lag under half a step
    assert (b.steps[1], b.steps[0], b.steps[3], b.steps[2]) == a.steps
    assert b.tension_n[1] == pytest.approx(a.tension_n[0], rel=1e-6)


def test_the_opposite_tendon_pays_out_and_every_tendon_keeps_the_floor(four) -> None:
    p = plan_move(four, 0.0, 10.0)
    assert abs(p.steps[0] - 10 / MM) <= 1  # 39.18 steps and the rotor's lag
    assert -41 <= p.steps[2] <= -37  # tendon 3 (180 deg) pays out about 39 steps
    assert abs(p.steps[1]) <= 1 and abs(p.steps[3]) <= 1  # the side tendons barely move
    assert p.tension_n[0] > 2.3554  # the pulled tendon loads up from its pretension
    assert min(p.tension_n) >= p.floor_n == 1.0
    assert "tendon 3: -" in "\n".join(p.lines()) and "floor 1.00 N" in p.lines()[0]


def test_the_lead_on_three_tendons_is_the_one_that_pulls_not_the_one_that_pays_out_most() -> None:
    """rigs/three-tendon.toml, 10 mm towards 45 deg: tendon 1 (at 0 deg, cos 45 = 0.71) pulls 28 steps, tendon
    3 (at 240 deg) pays out 36. The lead is tendon 1, and its cable sets the window: 28 x 0.25525 mm at 200
    mm/s = 35 736 us (tendon 3's 36 steps would have made it 45 946 us)."""
    three = rigfile.load(rigfile.resolve("three-tendon"))
    plan = plan_move(three, 45.0, 10.0)
    assert plan.steps == (28, 10, -36) and plan.lead == 0
    prog = move_programme(plan, three, 200.0)
    first = next(it for it in prog.items if it.command(3).startswith("MSEG"))
    assert first.command(3) == "MSEG 35736 28 10 -36"
    assert round(1e6 * 28 * MM / 200) == 35736


def _no_release(four: rigfile.RigFile) -> rigfile.RigFile:
    """The four-tendon rig without a release: position 0 (the rest) is the end of every tendon's travel."""
    text = four.text.replace("release_mm = 20.0", "release_mm = 0.0")
    assert text != four.text
    return rigfile.loads(text, "no-release.toml")


def _steps_plan(steps: tuple[int, ...]) -> MovePlan:
    return MovePlan(45.0, 10.0, steps, (0.0,) * 4, (0.0,) * 4, (3.0,) * 4, 1.0, (True, True, False, False),
                    (0, 0, 0, 0), 0)  # fmt: skip


def test_paying_out_within_the_release_is_inside_the_travel(four) -> None:
    # 10 mm towards 45 deg: tendons 3 and 4 pay out 27 steps, inside the 78 below rest
    assert check_travel(_steps_plan((28, 28, -27, -27)), four) == (28, 28, -27, -27)
    assert check_travel(_steps_plan((28, 28, -78, -27)), four) == (28, 28, -78, -27)  # the end of the release
    with pytest.raises(SafetyError) as exc:
        check_travel(_steps_plan((28, 28, -27, -79)), four)
    assert str(exc.value) == (
        "tendon 4: the move 10 mm towards 45 deg needs -79 steps (-20.17 mm) from position 0, past its "
        "travel of -78-156 steps: it pays out at most 78 steps (19.91 mm, [hardware] release_mm) below its "
        "rest"
    )
    p = plan_move(four, 90.0, 10.0)  # tendon 4 (270 deg) is opposite: about 39 steps out
    assert check_travel(p, four) == p.steps
    with pytest.raises(SafetyError, match=r"^tendon 4: the move 10 mm towards 90 deg needs -3\d steps"):
        check_travel(p, four, start=(0, 0, 0, -45))  # -45 - 39 is past -78


def test_paying_out_from_rest_on_a_rig_without_a_release_names_the_tendon(four) -> None:
    rig = _no_release(four)
    with pytest.raises(SafetyError, match=r"^tendon 3: the move 10 mm towards 45 deg needs -27 steps") as exc:
        check_travel(_steps_plan((28, 28, -27, -27)), rig)
    assert "past its travel of 0-156 steps: the rig's position 0 is its rest" in str(exc.value)
    assert "\n" not in str(exc.value)
    assert check_travel(_steps_plan((28, 28, -27, -27)), rig, start=(40, 0, 40, 40)) == (68, 28, 13, 13)


def test_a_bend_beyond_the_travel_is_refused_before_the_statics(four) -> None:
    with pytest.raises(SafetyError, match=r"^tendon 2: the move 45 mm towards 90 deg pulls it 45.00 mm, past "
                                          r"its travel of 39.82 mm \(156 steps\)$"):  # fmt: skip
        plan_move(four, 90.0, 45.0)


def test_a_tendon_below_the_floor_by_statics_is_refused_naming_it(four) -> None:
    text = four.text.replace("angle_deg = 180.0", "angle_deg = 180.0\npretension_n = 0.8")
    low = rigfile.loads(text, "low.toml")
    with pytest.raises(SafetyError, match=r"^tendon 3: its rest pretension 0.80 N is below the tension floor "
                                          r"1.00 N \(\[arm\] tension_floor_n\)"):  # fmt: skip
        plan_move(low, 0.0, 10.0)


@pytest.mark.parametrize("bad", [(math.nan, 10.0), (0.0, 0.0), (0.0, -1.0)])
def test_a_bad_bend_is_one_clear_error(four, bad) -> None:
    with pytest.raises(ValueError, match="direction and bend must be finite|bend_mm must be > 0"):
        plan_move(four, *bad)


def test_a_shaped_programme_convolves_every_tendon_with_the_same_impulses(four) -> None:
    plan = MovePlan(45.0, 10.0, (28, 28, -27, -27), (0.0,) * 4, (0.0,) * 4, (3.0,) * 4, 1.0,
                    (True, True, False, False), (0, 0, 0, 0), 0)  # fmt: skip
    shaper = Shaper((0.5, 0.5), (0.0, 0.1), "test")
    prog = move_programme(plan, four, 200.0, shaper, t_up_s=1.0, t_down_s=3.0, t_end_s=5.0)
    w = round(1e6 * 28 * MM / 200)  # the lead tendon's window: 35 736 us
    assert w == 35736
    cmds = [it.command(4) for it in prog.items]
    # half of every tendon's move in each impulse's window (round half to even: -13.5 -> -14), the pause
    # between them in whole ms (64.264 ms: 64 ms, the 264 us carried into the next window)
    assert cmds[:4] == ["WAIT 1000", f"MSEG {w} 14 14 -14 -14", "WAIT 64", f"MSEG {w + 264} 14 14 -13 -13"]
    assert cmds[5:8] == [f"MSEG {w} -14 -14 14 14", "WAIT 64", f"MSEG {w + 264} -14 -14 13 13"]
    assert tuple(prog.positions((30, 30, 30, 30), 4)[-1]) == (30, 30, 30, 30)
    assert prog.duration_s == pytest.approx(5.0, abs=2e-3)
    check_programme(prog, four, start=(30, 0, 30, 30))


def test_a_piece_too_short_for_its_rounded_step_goes_into_the_next_one(four) -> None:
    """The second impulse 35.5 ms after the first, 236 us before the first ramp ends (35 736 us): in those
    236 us both ramps run and the paying-out tendons' rounded counts step once (-13.41 -> -13 at 35 500 us,
    -13.59 -> -14 at 35 736 us), a step every 236 us, faster than the board's 639 us; merged into the next
    piece (35 500 us on: 35 736 us of the second ramp), every tendon's steps kept."""
    plan = _steps_plan((28, 28, -27, -27))
    shaper = Shaper((0.5, 0.5), (0.0, 0.0355), "test")
    prog = move_programme(plan, four, 200.0, shaper, t_up_s=1.0, t_down_s=3.0, t_end_s=5.0)
    cmds = [it.command(4) for it in prog.items]
    assert cmds[:3] == ["WAIT 1000", "MSEG 35500 14 14 -13 -13", "MSEG 35736 14 14 -14 -14"]
    assert cmds[4:6] == ["MSEG 35500 -14 -14 13 13", "MSEG 35736 -14 -14 14 14"]
    check_programme(prog, four, start=(30, 30, 30, 30))
    assert tuple(prog.positions((30, 30, 30, 30), 4)[-1]) == (30, 30, 30, 30)


def test_the_design_uses_the_direction_maps_mode_at_the_bend(hanging) -> None:
    d = move_design(hanging, 0.0, 10.0, "zv")
    # docs/spatial_twin.md: hanging, towards a tendon, 10 mm: 24.46 and 26.42 rad/s (spools held); the
    # pulled tendon's tension shows the mode in the plane of the bend, the stiffer one
    assert d.omega_d == pytest.approx(26.42, rel=0.02)
    assert d.tendon == 0
    assert d.shaper.times[1] == pytest.approx(math.pi / d.omega_d)  # ZV: half a damped period
    assert "tendon 1's tension" in d.describe() and f"{d.omega_d:.3f} rad/s" in d.describe()
    assert move_design(hanging, 0.0, 10.0, "none").shaper is None


# --- python -m helpers record move ----------------------------------------------------------------------
def _two_tendon_rig(four: rigfile.RigFile, folder) -> str:
    """The four-tendon rig with tendons 1 and 2 only (0 and 90 deg): a bend between them pays nothing out."""
    text = four.text.replace("[[tendon]]\nangle_deg = 180.0\n\n[[tendon]]\nangle_deg = 270.0\n\n", "")
    path = folder / "two.toml"
    path.write_text(text.replace('name = "four-tendon"', 'name = "two-tendon"'))
    assert rigfile.load(path).n_tendons == 2
    return str(path)


def test_record_move_dry_run_pays_the_antagonists_out_below_rest(four, tmp_path, monkeypatch, capsys) -> None:
    rig_args = ["--rig", "four-tendon"]
    data = tmp_path / "data"
    argv = ["record", "move", "--direction-deg", "45", "--bend-mm", "10", "--dry-run", "--data-dir"]
    argv.append(str(data))
    assert main(rig_args + argv) == 0
    out = capsys.readouterr().out
    assert "tendon 1: +28 steps (+7.15 mm, pulled); static tension" in out
    assert "tendon 3: -27 steps (-6.89 mm, paid out below its rest, held at its pretension)" in out
    w = round(1e6 * 28 * MM / 200)  # the lead tendon's window at 200 mm/s
    assert f"MSEG {w} 28 28 -27 -27; WAIT 6964; MSEG {w} -28 -28 27 27" in out
    assert "move_none_d45_b10.csv; nothing was sent" in out and not data.exists()


def test_record_move_dry_run_prints_the_plan_then_refuses_a_pay_out_from_rest(four, tmp_path, monkeypatch,
                                                                             capsys) -> None:  # fmt: skip
    path = tmp_path / "rig" / "no-release.toml"
    path.parent.mkdir()
    path.write_text(_no_release(four).text)
    rig_args = ["--rig", str(path)]
    tmp_path = tmp_path / "data"
    argv = [
        "record",
        "move",
        "--direction-deg",
        "45",
        "--bend-mm",
        "10",
        "--dry-run",
        "--data-dir",
        str(tmp_path),
    ]
    assert main(rig_args + argv) == 3
    out, err = capsys.readouterr()
    assert "tendon 1: +28 steps (+7.15 mm, pulled); static tension" in out
    assert "tendon 4: -27 steps" in out and "floor 1.00 N" in out
    assert err.strip().startswith("error: tendon 3: the move 10 mm towards 45 deg needs -27 steps")
    assert len(err.strip().splitlines()) == 1
    assert not tmp_path.exists()  # nothing written


def test_record_move_dry_run_on_a_rig_that_reaches_it(four, tmp_path, monkeypatch, capsys) -> None:
    rig_args = ["--rig", str(_two_tendon_rig(four, tmp_path))]
    data = tmp_path / "data"
    argv = [
        "record",
        "move",
        "--direction-deg",
        "45",
        "--bend-mm",
        "10",
        "--dry-run",
        "--data-dir",
        str(data),
    ]
    assert main(rig_args + argv) == 0
    out = capsys.readouterr().out
    w = round(1e6 * 28 * MM / 200)
    assert (
        f"programme (5 items, 12.00 s): WAIT 1000; MSEG {w} 28 28; WAIT 6964; MSEG {w} -28 -28; WAIT 3964"
        in out
    )
    assert "move_none_d45_b10.csv; nothing was sent" in out
    assert not data.exists()


@pytest.mark.slow
def test_record_move_records_a_shaped_move_whose_hold_is_the_planned_statics(four, tmp_path, monkeypatch,
                                                                            capsys) -> None:  # fmt: skip
    rig_args = ["--rig", str(_two_tendon_rig(four, tmp_path))]
    argv = ["record", "move", "--direction-deg", "45", "--bend-mm", "10", "--shaper", "zv", "--quiet",
            "--no-floor-check", "--data-dir", str(tmp_path / "data"),
            "--virtual-instance", "task-space-test"]  # fmt: skip
    try:
        assert main(rig_args + argv) == 0
    finally:
        forget_world("task-space-test")
    rec = recordings.load(tmp_path / "data" / "moves" / "move_zv_d45_b10.csv")
    sc = rec.meta["scenario"]
    assert (sc["kind"], sc["direction_deg"], sc["bend_mm"], sc["shaper"]) == ("move", 45.0, 10.0, "zv")
    assert sc["design"]["tendon"] == 1 and len(sc["design"]["times_s"]) == 2
    f = rec.frame
    hold = (f["t_s"] > 6.0) & (f["t_s"] < 8.0)  # the move out ends by 1.2 s; 5 s of ring-down
    for i in range(2):
        assert (f.loc[hold, f"steps_{i}"] == 28).all()
        # the time-domain twin through the emulated boards against the planned statics
        assert f.loc[hold, f"tension_n_{i}"].mean() == pytest.approx(sc["planned_tension_n"][i], abs=0.05)
    assert list(f.iloc[-1][["steps_0", "steps_1"]]) == [0, 0]


@pytest.mark.slow
def test_a_four_tendon_move_pays_out_and_holds_the_planned_statics(tmp_path, monkeypatch, capsys) -> None:
    """10 mm towards 45 deg on the four-tendon virtual rig: tendons 3 and 4 pay out 27 steps below rest.

    The twin starts at rest with every stepper at position 0 (every tendon at its 2.3554 N pretension) and
    holds the plan's static tensions (rotors free) after the move. Tolerance 0.05 N: half an ADC count is
    0.020 N (0.0407 N per count), the noise averages out over the hold's 2000 samples, and 5 s after the move
    the ringing (zeta 0.045 at 24.7 rad/s) has decayed to exp(-0.045 x 24.7 x 5) = 0.4 % of its ~2 N.
    """
    rig_args = ["--rig", "four-tendon"]
    # unshaped, every tendon goes slack while it rings (docs/task_space.md): recorded whole, without the watch
    argv = ["record", "move", "--direction-deg", "45", "--bend-mm", "10", "--quiet", "--data-dir",
            str(tmp_path / "data"), "--virtual-instance", "task-space-four", "--no-floor-watch"]  # fmt: skip
    try:
        assert main(rig_args + argv) == 0
    finally:
        forget_world("task-space-four")
    rec = recordings.load(tmp_path / "data" / "moves" / "move_none_d45_b10.csv")
    sc = rec.meta["scenario"]
    assert sc["steps"] == [28, 28, -27, -27]
    f = rec.frame
    rest = f["t_s"] < 0.9  # the lead-in: the twin at rest, every stepper at 0
    hold = (f["t_s"] > 6.0) & (f["t_s"] < 8.0)
    for i in range(4):
        assert (f.loc[rest, f"steps_{i}"] == 0).all()
        assert f.loc[rest, f"tension_n_{i}"].mean() == pytest.approx(2.3554, abs=0.05)
        assert (f.loc[hold, f"steps_{i}"] == sc["steps"][i]).all()
        assert f.loc[hold, f"tension_n_{i}"].mean() == pytest.approx(sc["planned_tension_n"][i], abs=0.05)
    assert list(f.iloc[-1][[f"steps_{i}" for i in range(4)]]) == [0, 0, 0, 0]  # back at rest
