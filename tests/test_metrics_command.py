"""``python -m helpers metrics``: finds recordings, skips what it cannot analyse (saying why), writes tables.

The metric values themselves are checked against closed forms in ``test_metrics.py``; here the per-run rows
must equal :func:`helpers.paper.metrics.recording_metrics` of each file, and the means the plain average of
those.
Everything is written into a temporary folder (recordings copied from ``data/``).
"""

import json
import shutil

import numpy as np
import pandas as pd
import pytest

from helpers import recordings
from helpers.__main__ import main
from helpers.base.paths import DATA_DIR
from helpers.commands import metrics_report as table2
from helpers.paper import metrics

SOURCE = DATA_DIR / "experiments"
ZV30 = [f"zv_v200_x30_r{k}" for k in (1, 2, 3)]


@pytest.fixture
def folder(tmp_path, monkeypatch):
    """tmp/mine: three ZV repetitions and one ZVD run; tmp/other: a calibration run; cwd = tmp."""
    mine = tmp_path / "mine"
    mine.mkdir()
    for stem in [*ZV30, "zvd_v200_x30_r1"]:
        for ext in (".csv", ".json"):
            shutil.copy(SOURCE / f"{stem}{ext}", mine / f"{stem}{ext}")
    other = tmp_path / "other"
    other.mkdir()
    for ext in (".csv", ".json"):
        shutil.copy(DATA_DIR / "calibration" / f"load_0500g{ext}", other / f"load_0500g{ext}")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _abort(path):
    meta = json.loads(path.read_text())
    meta["status"], meta["abort_reason"] = "aborted", "interrupted by Ctrl-C"
    path.write_text(json.dumps(meta))


def test_runs_and_means_match_the_metrics_of_each_file(folder, capsys):
    assert main(["metrics", "mine", "--csv", "out/t"]) == 0
    runs = pd.read_csv(folder / "out" / "t_runs.csv")
    means = pd.read_csv(folder / "out" / "t_scenarios.csv")
    assert len(runs) == 8 and set(runs["source"]) == {"virtual-rig"}
    for stem in ZV30:
        expected = metrics.recording_metrics(recordings.load(folder / "mine" / f"{stem}.csv").frame)
        got = runs[runs["recording"] == f"mine/{stem}"].set_index("motion")
        for row in expected.itertuples():
            assert got.loc[row.motion, "peak_n"] == pytest.approx(row.peak_n, rel=1e-5)
            assert got.loc[row.motion, "settling_ms"] == pytest.approx(row.settling_ms, rel=1e-5)
    zv = means[(means["system"] == "zv") & (means["motion"] == "Up")].iloc[0]
    # from each file's metrics at full precision (the CSV keeps six significant digits of every number)
    per_run = np.array([
        metrics.recording_metrics(recordings.load(folder / "mine" / f"{stem}.csv").frame)
        .set_index("motion").loc["Up", "overshoot_pct"]
        for stem in ZV30
    ])  # fmt: skip
    assert zv["n_runs"] == 3
    assert zv["overshoot_pct_mean"] == pytest.approx(per_run.mean(), rel=1e-5)
    assert zv["overshoot_pct_std"] == pytest.approx(per_run.std(ddof=1), rel=1e-5)
    out = capsys.readouterr().out
    assert "Per scenario" in out and "zv (Non-robust)" in out and "zvd (Robust)" in out
    assert "simulated recordings, not hardware measurements" in out
    assert "Skipped: none." in out


def test_folders_files_and_quoted_globs_are_found_once_each(folder):
    stems = table2.expand(["mine", "mine/zv_v200_x30_r1.csv", "mine/zv_*_r2.json", "mine/zvd_v200_x30_r1"])
    assert [s.name for s in stems] == [*ZV30, "zvd_v200_x30_r1"]
    assert [s.name for s in table2.expand(["**/*_r3.csv"])] == ["zv_v200_x30_r3"]


def test_what_cannot_be_analysed_is_skipped_with_the_reason(folder, capsys):
    _abort(folder / "mine" / "zv_v200_x30_r3.json")
    (folder / "mine" / "zv_v200_x30_r2.csv").write_bytes(b"t_us,adc\n1,2\n")  # torn: sha256 mismatch
    (folder / "mine" / "half.csv").write_text("t_us,steps,adc,seq\n")  # an incomplete run: no JSON
    assert main(["metrics", "mine", "other"]) == 0
    out = capsys.readouterr().out
    skipped = out[out.index("Skipped 4:"):]
    assert "mine/zv_v200_x30_r3: aborted run (interrupted by Ctrl-C); --include-aborted" in skipped
    assert "mine/zv_v200_x30_r2:" in skipped and "sha256" in skipped
    assert "mine/half:" in skipped
    assert "other/load_0500g: a load-cell calibration run" in skipped
    assert main(["metrics", "mine", "--include-aborted"]) == 0
    assert "zv_v200_x30_r3" in capsys.readouterr().out.split("Per scenario")[0]


def test_nothing_to_analyse_and_missing_paths_are_one_line_errors(folder, capsys):
    assert main(["metrics", "other"]) == 5
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no recording could be analysed" in err and "calibration run" in err
    assert main(["metrics", "nowhere"]) == 2
    assert "nowhere: no such recording, folder or file" in capsys.readouterr().err
    assert main(["metrics", "mine/zz_*"]) == 2
    assert "no file matches" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        main(["metrics", "mine", "--band", "0"])
    assert exit_.value.code == 2 and "outside (0, 0.5]" in capsys.readouterr().err


def test_outputs_are_never_overwritten_without_replace(folder, capsys):
    assert main(["metrics", "mine", "--markdown", "t.md"]) == 0
    first = (folder / "t.md").read_text()
    assert first.startswith("## Per scenario") and "| zv (Non-robust) |" in first
    (folder / "t.md").write_text("mine")
    assert main(["metrics", "mine", "--markdown", "t.md", "--csv", "t"]) == 5
    assert "t.md exists; pass --replace" in capsys.readouterr().err
    assert (folder / "t.md").read_text() == "mine" and not (folder / "t_runs.csv").exists()
    assert main(["metrics", "mine", "--markdown", "t.md", "--replace"]) == 0
    assert (folder / "t.md").read_text() == first
    capsys.readouterr()
    assert main(["metrics", "mine", "--markdown", "-"]) == 0
    assert capsys.readouterr().out == first


def test_display_rounds_once_from_full_precision():
    runs = pd.DataFrame(
        {
            "recording": ["a"], "source": ["hardware"], "v_in_mm_s": [200.0], "x_f_mm": [10.0],
            "system": ["zv"], "repetition": [1], "motion": ["Down"],
            "peak_n": [-0.0449], "overshoot_pct": [35.449], "settling_ms": [483.5001], "reason": [""],
        }
    )  # fmt: skip
    means = pd.DataFrame(
        {
            "source": ["hardware"], "x_f_mm": [10.0], "v_in_mm_s": [200.0], "system": ["zv"],
            "motion": ["Down"], "n_runs": [2],
            "peak_n_mean": [-0.0449], "peak_n_std": [0.00449], "overshoot_pct_mean": [35.449],
            "overshoot_pct_std": [np.nan], "settling_ms_mean": [483.5001], "settling_ms_std": [2.5],
        }
    )  # fmt: skip
    r, m = table2.displayed(runs, means)
    assert r.loc[0, "overshoot %"] == "35.4"  # not 35.5 (35.449 -> 35.45 -> 35.5 when rounded twice)
    assert r.loc[0, "peak N"] == "-0.04"
    assert r.loc[0, "settling ms"] == "484"
    assert m.loc[0, "overshoot %"] == "35.4"  # no spread with a NaN std
    assert m.loc[0, "peak N"] == "-0.04 ± 0.00"
    assert m.loc[0, "settling ms"] == "484 ± 2"
