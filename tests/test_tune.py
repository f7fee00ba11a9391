"""``python -m helpers tune``: candidates, the choice, the report; end to end on the virtual rig (slow)."""

import json
import shutil

import pandas as pd
import pytest

import helpers.base.paths
from helpers.__main__ import main
from helpers.base.paths import DATA_DIR
from helpers.paper.shapers import design_tdfs
from helpers.research import tune
from helpers.research.modemap import ModeMap


def summary(rows):
    return pd.DataFrame(rows, columns=["system", "v_in_mm_s", "x_f_mm", "motion", "residual_pct",
                                       "move_duration_s"])  # fmt: skip


def test_the_choice_is_the_lowest_worst_residual_within_the_reference_duration():
    rows = []
    for motion in ("Up", "Down"):
        rows += [("zv", 200, 20, motion, 20.0, 0.222), ("zvd", 200, 20, motion, 9.0, 0.346),
                 ("a", 200, 20, motion, 12.0 if motion == "Up" else 18.0, 0.220),
                 ("b", 200, 20, motion, 15.0, 0.222)]  # fmt: skip
    chosen = tune.choose(summary(rows))
    assert chosen["system"] == "b"  # a's worst (18) is above b's (15); zvd is better but longer than zv
    table = chosen["table"].set_index("system")
    assert not table.loc["zvd", "within_duration_cap"] and table.loc["a", "within_duration_cap"]
    too_long = summary([(s, 200, 20, "Up", r, 0.5 if s != "zv" else 0.2) for s, r in (("zv", 20), ("c", 5))])
    assert tune.choose(too_long, reference="zv")["system"] == "zv"  # only zv keeps within its own length


def test_on_a_constant_map_the_map_designs_reduce_to_the_paper_s_zv():
    rest = (25.085, 0.044)
    flat = ModeMap.constant(rest[0], rest[1], (0.0, 40.0), source={"kind": "virtual-rig", "method": "test"})
    found = tune.design_candidates(flat, rest, ((200.0, 20.0),))
    made = found.designs[(200.0, 20.0)]
    zv, _ = design_tdfs(*rest)
    assert set(made) == set(tune.CANDIDATES)
    up, down = made["scheduled"].up_shaper, made["scheduled"].down_shaper
    for s in (up, down):
        assert s.amplitudes.tolist() == pytest.approx(zv.amplitudes.tolist())
        assert s.times.tolist() == pytest.approx(zv.times.tolist())
    assert made["multi-mode"] is None and "no second mode" in found.notes[(200.0, 20.0)]["multi-mode"]


@pytest.mark.slow
def test_tune_runs_end_to_end_on_the_virtual_rig(tmp_path, monkeypatch):
    for group, name in (("calibration", "calibration.json"), ("identification", "result.json")):
        (tmp_path / group).mkdir()
        shutil.copy(DATA_DIR / group / name, tmp_path / group / name)
    monkeypatch.setattr(helpers.base.paths, "FIGURES_DIR", tmp_path / "figures")

    assert main(["tune", "--data-dir", str(tmp_path), "--repetitions", "1", "--quiet"]) == 0
    tuning = tmp_path / "tuning"
    document = json.loads((tuning / "table-i_verification.json").read_text())
    rows = pd.DataFrame(document["rows"])
    assert set(rows["system"]) >= {"zv", "zvd", "map-following", "scheduled"}
    assert len(rows) == 2 * 4 * rows["system"].nunique()  # Up and Down of 4 conditions, 1 run each
    chosen = json.loads((tuning / "chosen.json").read_text())
    for path in chosen["designs"].values():
        assert (tuning / path).exists()
    # data elsewhere: the report stays beside its data, and no figure of the repository is written
    report = {"tuning_report.csv", "tuning_report.md", "tuning_report.png"}
    assert report <= {p.name for p in tuning.iterdir()}
    assert not (tmp_path / "figures").exists()
    assert main(["tune", "--data-dir", str(tmp_path), "--quiet"]) == 5  # the map exists: refused, kept
