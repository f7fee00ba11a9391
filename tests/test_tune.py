"""``python -m helpers tune``: candidates, the choice, the report; end to end on the virtual rig (slow)."""

import hashlib
import json
import shutil
import tomllib
from pathlib import Path

import pandas as pd
import pytest

import helpers.base.paths
from helpers import rigfile
from helpers.__main__ import main
from helpers.base.paths import DATA_DIR
from helpers.paper.shapers import design_tdfs
from helpers.research import tune
from helpers.research.modemap import ModeMap, load_map, map_rig
from helpers.rigfile import RIGS_DIR


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


def _rig_of(path):
    """(name, hash) of a rig file; the hash as docs/rig_file.md defines it (SHA-256 of the file, 8 digits)."""
    text = Path(path).read_bytes()
    return tomllib.loads(text.decode())["name"], hashlib.sha256(text).hexdigest()[:8]


def test_reuse_map_refuses_a_map_of_another_rig_before_any_port_opens(tmp_path, capsys, monkeypatch):
    for group, name in (("calibration", "calibration.json"), ("identification", "result.json")):
        (tmp_path / group).mkdir()
        shutil.copy(DATA_DIR / group / name, tmp_path / group / name)
    monkeypatch.setattr(tune, "Rig", lambda *a, **k: pytest.fail("a port was opened"))  # the one driver
    this_name, this_hash = _rig_of(rigfile.DEFAULT_RIG)  # the rig `tune` runs without --rig: the paper's
    other = next(p for p in sorted(RIGS_DIR.glob("*.toml")) if _rig_of(p)[1] != this_hash)
    other_name, other_hash = _rig_of(other)
    source = {"kind": "virtual-rig", "method": "test", "rig": {"name": other_name, "hash": other_hash}}
    (tmp_path / "tuning").mkdir()
    ModeMap.constant(25.0, 0.04, (0.0, 40.0), source=source).save(tmp_path / "tuning" / "mode_map.json")
    capsys.readouterr()
    assert main(["tune", "--data-dir", str(tmp_path), "--reuse-map", "--quiet"]) == 5  # docs/faults.md
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert other_hash in err[0] and this_hash in err[0] and "mode_map.json" in err[0]
    assert repr(other_name) in err[0] and repr(this_name) in err[0]


def test_a_map_without_its_rig_is_the_paper_rigs_and_a_survey_map_names_its_rig():
    legacy = ModeMap.constant(25.0, 0.04, (0.0, 40.0), source={"kind": "virtual-rig", "method": "test"})
    assert map_rig(legacy) == _rig_of(RIGS_DIR / "paper.toml")
    with pytest.raises(ValueError, match="source.rig"):
        ModeMap.constant(25.0, 0.04, (0.0, 40.0), source={"kind": "hardware", "method": "m", "rig": "paper"})
    stored = load_map(DATA_DIR / "tuning" / "mode_map.json")  # surveyed before rig files: the paper's
    assert map_rig(stored)[0] == "paper"
