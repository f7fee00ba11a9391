"""Every tendon taut at the whole steps the board executes (``record tip-stream``).

A tip stream is checked, before any port opens, on the static tensions at the board's whole-step counts at
every period (:func:`helpers.research.tip_stream.check_whole_steps`), and pre-pulled on request
(``--prepull K``: every tendon pulled ``K`` steps in before the path and let out after it, as a move's).

By hand (``rigs/four-tendon.toml``): a step is pi 65 / 800 = 0.255254 mm of cable, one set-point unit held
for a 10 ms period 625 / 65536 step (104.8576 unit-periods a step), the rest pretension 2.3554 N and the
floor 1 N. One step of a tendon against its antagonist is about 2.7 N of static tension, more than the
pretension: where the board's count of the pulled tendon is a step behind its cable (its count follows the
cable with a one-step hysteresis, ``firmware/PROTOCOL.md``) while the antagonist's is not, the statics leave
the antagonist slack at those whole steps, though at the planned (fractional) positions it keeps about its
pretension. Every tendon one step in raises every tension to about 7.5 N, so that a step's lag leaves it
near 4.8 N.

The whole-step counts of an unshaped stream are found here without the board's planner: with the unit
shaper the board's exact position at the end of period ``k + 2`` is the plan's integrated set-points at
boundary ``k``, and the count moves when the position is a whole step away from it.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from helpers import rigfile
from helpers.__main__ import error_line, main
from helpers.base.paths import DATA_DIR, REPO_ROOT
from helpers.research import tip_stream as ts
from helpers.research.task_shaping import pretensioned
from helpers.research.task_space import plan_move
from helpers.rig.safety import SafetyError
from helpers.rigfile.derived import derived
from helpers.virtual.spatial.from_rig import spatial_rig
from helpers.virtual.spatial.statics import equilibrium

SHIPPED = REPO_ROOT / "tests" / "fixtures" / "recordings" / "tip_streams" / "tip_random_zv_b10.json"
"""A tip stream once shipped, recorded before the check (its forecast at the whole steps: tendon 2 at 0 N);
kept as a fixture of the format's version 3, ``data/tip_streams/`` holds it recorded again with a pre-pull."""


@pytest.fixture(scope="module")
def four() -> rigfile.RigFile:
    return rigfile.load(rigfile.resolve("four-tendon"))


@pytest.fixture(scope="module")
def line() -> ts.TipPath:
    """5 mm towards tendon 1 (0 deg) and back at 50 mm/s: 2 mm of bend a period (0.3 s at rest first)."""
    return ts.figure_path("line", 5.0, speed_mm_s=50.0)


def _counts(positions: np.ndarray, tol: float = 1e-4) -> np.ndarray:
    """Whole-step counts following ``positions`` (steps) with a one-step hysteresis, boundary by boundary.

    A count moves once its cable is a whole step away from it; at a boundary, only if it was more than
    ``tol`` (under a timer tick of motion) beyond it (a step falling on the boundary's tick counts after it).
    """
    c = np.zeros(positions.shape[1], dtype=int)

    def follow(x: np.ndarray, tol: float) -> None:
        for i, v in enumerate(x):
            if v >= c[i] + 1 + tol:
                c[i] = math.floor(v - tol)
            elif v <= c[i] - 1 - tol:
                c[i] = math.ceil(v + tol)

    out = []
    for k, x in enumerate(positions):
        if k:
            follow(positions[k - 1], 0.0)
        follow(x, tol)
        out.append(c.copy())
    return np.array(out)


def _statics(rig: rigfile.RigFile, counts: np.ndarray) -> np.ndarray:
    """The static tensions (rotors free) at every row of whole-step counts."""
    twin = spatial_rig(rig)
    mm = np.array(derived(rig).mm_per_step) * 1e-3
    eq, solved = None, {}
    for c in map(tuple, counts):
        if c not in solved:
            eq = equilibrium(twin, np.array(c) * mm, rotor="free", start=eq)
            solved[c] = eq.tension
    return np.array([solved[tuple(c)] for c in counts])


@pytest.mark.slow  # plans the line and solves the statics at its whole steps: about 5 s on two shared cores
def test_a_stream_whose_whole_steps_leave_a_tendon_short_is_refused_naming_it(four, line) -> None:
    plan = ts.plan_stream(four, line)
    assert plan.tension_n.min() >= 1.0  # the plan's own check, at the fractional positions, passes
    tension = _statics(four, _counts(plan.positions))
    k = int(np.argwhere(tension < 1.0)[0, 0])
    i = int(np.argmin(tension[k]))
    assert i == 2 and 29 < k < 40  # tendon 3, the antagonist, as the line goes out
    with pytest.raises(SafetyError) as info:
        ts.check_whole_steps(plan, four, None)
    text = str(info.value)
    assert text.startswith(
        f"tendon 3: the line path (5 mm) leaves it at {tension[k, i]:.2f} N by statics at the board's whole "
        f"steps at period {k} (t = {k / 100:.2f} s, bend "
    )  # fmt: skip
    assert "below the tension floor 1.00 N ([arm] tension_floor_n)" in text and "\n" not in text
    assert tension[k, i] < 0.5  # slack: a step of about 2.7 N against a pretension of 2.36 N
    assert error_line(info.value)[1] == 3


@pytest.mark.slow  # plans the pre-pulled line and checks its whole steps: about 5 s
def test_the_same_stream_pulled_one_step_in_keeps_every_tendon_taut_at_the_whole_steps(four, line) -> None:
    plan = ts.plan_stream(four, line, prepull=1)
    units, n = plan.board_units, line.periods
    # the pull: ceil(104.8576) = 105 units on every tendon in one period, then 0.5 s at rest
    assert plan.offset == 51 and units[0].tolist() == [105] * 4 and not units[1:51].any()
    assert np.array_equal(units[51 : 51 + n], plan.units)
    # the let-out: tendons 1, 3, 2, 4 one at a time, 0.25 s apart; every tendon back to rest exactly
    release = units[51 + n :]
    assert len(release) == 4 * 26
    for j, tendon in enumerate((0, 2, 1, 3)):
        block = release[26 * j : 26 * (j + 1)]
        assert np.flatnonzero(block[0]).tolist() == [tendon] and not block[1:].any()
    assert units.sum(axis=0).tolist() == [0, 0, 0, 0]
    # the stops are the move's from the pre-pulled rest, and the board stands one step above them
    pre = pretensioned(four, spatial_rig(four), 1)
    assert plan.stop_steps[1] == plan_move(four, 0.0, 5.0, spatial=pre).steps
    assert ts.board_counts(plan, four, None) == [tuple(v + 1 for v in s) for s in plan.stop_steps]
    tension = ts.check_whole_steps(plan, four, None)  # no refusal
    assert tension.min() >= 1.0
    # pulled in and settled: every tendon at the statics of one step in (about 7.5 N)
    one = equilibrium(spatial_rig(four), np.array(derived(four).mm_per_step) * 1e-3, rotor="free").tension
    assert tension[50] == pytest.approx(one) and one.min() > 7.0
    assert ts.board_path(plan, four, None)[-1].tolist() == [0, 0, 0, 0]


@pytest.mark.slow  # three dry runs of the command line, one planning each pre-pull: about 5 s
def test_record_tip_stream_refuses_at_the_whole_steps_saying_which_prepull_passes(tmp_path, capsys) -> None:
    base = ["--rig", "four-tendon", "record", "tip-stream", "--path", "line", "--bend-mm", "2", "--dry-run",
            "--data-dir", str(tmp_path / "data")]  # fmt: skip
    assert main([*base, "--v-in", "50"]) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: tendon 3: the line path (2 mm) leaves it at ")
    assert "by statics at the board's whole steps at period " in err
    assert err.rstrip().endswith("N at the board's whole steps)") and "; --prepull 1 passes (" in err
    # a line fast enough that the counts keep up passes without a pre-pull
    assert main([*base, "--v-in", "200"]) == 0
    out = capsys.readouterr().out
    assert "checked: the least static tensions at the board's whole-step counts at every period" in out
    assert "at or above the floor 1.00 N" in out and "tip_line_none_b2.csv; nothing was sent" in out
    assert not (tmp_path / "data").exists()


@pytest.mark.slow  # two dry runs of the command line: over 1 s
def test_a_prepull_is_not_offered_on_an_arm_it_would_bend(four, tmp_path, capsys) -> None:
    """Tendon 4 turned from 270 to 260 deg: the four do not balance, pulling them all in bends the arm."""
    text = four.text.replace("[[tendon]]\nangle_deg = 270.0\n", "[[tendon]]\nangle_deg = 260.0\n")
    path = tmp_path / "turned.toml"
    path.write_text(text.replace('name = "four-tendon"', 'name = "turned"'))
    argv = ["--rig", str(path), "record", "tip-stream", "--path", "line", "--bend-mm", "2", "--v-in", "50",
            "--dry-run", "--data-dir", str(tmp_path / "data")]  # fmt: skip
    assert main(argv) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "at the board's whole steps at period " in err
    assert err.rstrip().endswith(
        "; no --prepull can lift it on this rig: pulling every tendon in would bend this arm (tendons at 0, "
        "90, 180, 260 deg do not balance)"
    )  # fmt: skip
    assert main([*argv, "--prepull", "1"]) == 2
    assert "--prepull 1: pulling every tendon in would bend this arm" in capsys.readouterr().err


@pytest.mark.slow  # plans the 12 s random path three times (not pre-pulled, then pre-pulled): about a minute
def test_the_shipped_random_stream_is_refused_and_pulled_one_step_in_passes(tmp_path, capsys) -> None:
    """The once shipped ``tip_random_zv_b10`` was recorded before the check: its scenario forecasts tendon 2
    at 0 N at the board's whole steps. Its command, from its scenario (the random figure of 10 mm, seed 0,
    at 100 mm/s, ZV), on its rig (four-tendon), is refused now, naming tendon 2 and its least."""
    meta = json.loads(SHIPPED.read_text())
    sc = meta["scenario"]
    assert meta["rig"]["name"] == "four-tendon" and sc["board_count_min_static_tension_n"][1] == 0.0
    path = sc["path"]
    assert (path["figure"], path["bend_mm"], path["speed_mm_s"]) == ("random", 10.0, 100.0)
    assert sc["shaper_name"] == "zv"
    four = rigfile.load(rigfile.resolve("four-tendon"))
    plan = ts.plan_stream(four, ts.figure_path("random", 10.0, speed_mm_s=100.0, seed=0))
    assert plan.units.T.tolist() == sc["stream"]["tendon_setpoints"]  # the command reproduced
    argv = ["--rig", "four-tendon", "record", "tip-stream", "--path", "random", "--bend-mm", "10", "--v-in",
            "100", "--shaper", "zv", "--dry-run", "--data-dir", str(tmp_path / "data")]  # fmt: skip
    assert main(argv) == 3
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: tendon 2: the random path (10 mm) leaves it at ")
    assert "by statics at the board's whole steps at period " in err
    assert "(the least: 0.00 N, tendon 2 at period " in err and "; --prepull 1 passes (" in err
    assert main([*argv, "--prepull", "1"]) == 0
    out = capsys.readouterr().out
    figures = out.split("one-step hysteresis, the pre-pull and its let-out): ")[1]
    least = [float(v) for v in figures.split(" N for tendons")[0].split(", ")]
    assert len(least) == 4 and min(least) >= 1.0
    assert "tip_random_zv_b10_pre1.csv; nothing was sent" in out


def test_the_shipped_tip_streams_were_recorded_pre_pulled_with_every_tendon_above_the_floor_at_whole_steps():
    shipped = sorted((DATA_DIR / "tip_streams").glob("tip_random_*_b10*.json"))
    assert [p.name for p in shipped] == [f"tip_random_{s}_b10_pre1.json" for s in ("none", "zv", "zvd")]
    floor = rigfile.load(rigfile.resolve("four-tendon")).arm.tension_floor_n
    for path in shipped:
        meta = json.loads(path.read_text())
        sc = meta["scenario"]
        assert meta["status"] == "complete" and sc["prepull_periods"] > 0, path.name
        assert min(sc["board_count_min_static_tension_n"]) >= floor, path.name
