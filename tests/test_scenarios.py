"""The paper's scenarios on a rig they do not fit are scaled by a stated rule, never clamped."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from helpers import rigfile
from helpers.paper import numbers as paper
from helpers.paper import scenarios
from helpers.research import survey, tune


def _python(code: str, env_rig: str | None) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env.pop(rigfile.ENV_VAR, None)
    if env_rig is not None:
        env[rigfile.ENV_VAR] = env_rig
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)


_PROBE = (
    "import json; from helpers.paper import scenarios as s; from helpers.research import survey, tune; "
    "print(json.dumps({'table_i': s.table_i_conditions(), 'ident': s.identification_name(), "
    "'survey': s.survey_positions(survey.POSITIONS_MM), 'wide': tune.rig_grid('wide'), "
    "'notes': s.scaling_notes({'wide': tune.GRIDS['wide']}, survey.POSITIONS_MM)}))"
)


def test_the_paper_rig_keeps_the_paper_scenarios():
    # in this process the selected rig is the paper's
    assert scenarios.table_i_conditions() == paper.TABLE_I_CONDITIONS
    assert scenarios.identification_name() == "pulse_v100_x10"
    assert scenarios.survey_positions(survey.POSITIONS_MM) == (0, 5, 10, 15, 20, 25, 30, 35, 40)
    assert tune.rig_grid("wide") == tune.GRIDS["wide"] and (400.0, 39.0) in tune.rig_grid("wide")
    assert scenarios.scaling_notes({"wide": tune.GRIDS["wide"]}, survey.POSITIONS_MM) == []


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


def test_scenarios_follow_the_selected_rig():
    proc = _python(_PROBE, "long-arm")
    assert proc.returncode == 0, proc.stderr
    got = json.loads(proc.stdout)
    # long-arm: 150 mm/s, 254 steps of 0.07854 mm (19.95 mm)
    assert [tuple(c) for c in got["table_i"]] == [(100, 6.6), (100, 13.2), (100, 19.9), (150, 13.2)]
    assert got["ident"] == "pulse_v100_x10"  # 100 mm/s, 10 mm fit: unscaled
    assert got["survey"] == [0, 2.5, 5, 7.5, 10, 12.5, 15, 17.5, 20]
    assert max(v for v, _ in got["wide"]) <= 150 and max(x for _, x in got["wide"]) <= 19.95
    text = "\n".join(got["notes"])
    assert "Table I: speeds 200, 300 -> 100, 150 mm/s; distances 10, 20, 30 -> 6.6, 13.2, 19.9 mm" in text
    assert "survey positions" in text and "identification" not in text
