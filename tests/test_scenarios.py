"""The paper's scenarios on a rig they do not fit are scaled by a stated rule, never clamped."""

from __future__ import annotations

import pytest

from helpers.paper import numbers as paper
from helpers.paper import scaling_notes, scenarios
from helpers.research import survey, tune
from rigs import SHIPPED, floor_to


def test_the_paper_rig_keeps_the_paper_scenarios():  # paper-only: the paper's published scenarios
    rig = SHIPPED["paper"].load()
    assert scenarios.table_i_conditions(rig) == paper.TABLE_I_CONDITIONS
    assert scenarios.identification_name(rig) == "pulse_v100_x10"
    assert scenarios.survey_positions(survey.POSITIONS_MM, rig) == (0, 5, 10, 15, 20, 25, 30, 35, 40)
    assert tune.rig_grid("wide", rig) == tune.GRIDS["wide"] and (400.0, 39.0) in tune.rig_grid("wide", rig)
    assert scaling_notes.scaling_notes(rig, {"wide": tune.GRIDS["wide"]}, survey.POSITIONS_MM) == []


def test_the_rule_scales_a_whole_set_and_keeps_what_fits():
    conditions = ((200.0, 10.0), (200.0, 20.0), (200.0, 30.0), (300.0, 20.0))
    # fastest 150 mm/s: speeds x 0.5; longest 15 mm: distances x 0.5
    assert scenarios.scale_conditions(conditions, 150.0, 15.0) == (
        (100.0, 5.0), (100.0, 10.0), (100.0, 15.0), (150.0, 10.0),
    )  # fmt: skip
    assert scenarios.scale_conditions(conditions, 300.0, 30.0) == conditions  # fits: unchanged
    # floored, not rounded: 19.95 / 30 of 10 mm is 6.65 mm -> 6.6 mm (never beyond the limit)
    assert scenarios.scale_conditions([(100.0, 10.0), (100.0, 30.0)], 150.0, 19.95) == (
        (100.0, 6.6), (100.0, 19.9),
    )  # fmt: skip


def test_scenarios_follow_the_rig(rig_file):  # rig-parametrised (tests/conftest.py)
    r, rig = rig_file, rig_file.load()
    table_i = scenarios.table_i_conditions(rig)
    assert table_i == tuple(r.scaled(list(paper.TABLE_I_CONDITIONS)))
    assert all(v <= r.fastest_mm_s and x <= r.longest_mm for v, x in table_i)
    run = paper.IDENTIFICATION_RUN
    ((v, x),) = r.scaled([(run["v_in_mm_s"], run["x_f_mm"])])
    assert scenarios.identification_name(rig) == f"pulse_v{v:g}_x{x:g}".replace(".", "p")
    # the survey's positions: the paper's 0-40 mm every 5, spread over a shorter travel in as many steps
    n = len(survey.POSITIONS_MM) - 1
    top = min(r.hw("travel_mm"), max(survey.POSITIONS_MM))
    expected = tuple(floor_to(top * k / n, 0.1) for k in range(n + 1))
    assert scenarios.survey_positions(survey.POSITIONS_MM, rig) == pytest.approx(expected, abs=1e-9)
    wide = tune.rig_grid("wide", rig)
    assert list(wide) == r.scaled(list(tune.GRIDS["wide"]))
    notes = "\n".join(scaling_notes.scaling_notes(rig, {"wide": tune.GRIDS["wide"]}, survey.POSITIONS_MM))
    fits = table_i == paper.TABLE_I_CONDITIONS
    assert ("Table I:" in notes) == (not fits)  # a scaled set is said, an unscaled one is not
    if not fits:
        speeds = ", ".join(f"{v:g}" for v in sorted({v for v, _ in table_i}))
        assert f"-> {speeds} mm/s" in notes


def test_the_second_rigs_scaled_scenarios_are_the_documented_ones():  # the table in docs/rig_file.md
    r = SHIPPED["long-arm"]
    assert r.scaled(list(paper.TABLE_I_CONDITIONS)) == [(100, 6.6), (100, 13.2), (100, 19.9), (150, 13.2)]
    assert r.scaled([(100.0, 10.0)]) == [(100.0, 10.0)]  # the identification run fits: unscaled
