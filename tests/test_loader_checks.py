"""The loader refuses contents no rig can produce even when the checksum was recomputed to match them, and a
malformed stream recording is one named problem among good files, never a crash of the whole folder."""

from __future__ import annotations

import hashlib
import json
import shutil

import pandas as pd
import pytest

from helpers import recordings
from helpers.__main__ import main
from helpers.base.paths import DATA_DIR, REPO_ROOT
from helpers.recordings import RecordingError

STREAM = DATA_DIR / "streams"


def _copy(src_stem, folder, name):
    folder.mkdir(parents=True, exist_ok=True)
    for ext in (".csv", ".json"):
        shutil.copy(src_stem.with_suffix(ext), folder / f"{name}{ext}")
    return folder / f"{name}.csv"


def _a_stream():
    return sorted(p for p in STREAM.glob("*.csv") if "aborted" not in p.name)[0]


def _edit_csv(csv, change):
    frame = pd.read_csv(csv)
    change(frame)
    csv.write_text(frame.to_csv(index=False, lineterminator="\n"))
    meta = json.loads(csv.with_suffix(".json").read_text())
    meta["csv_sha256"] = hashlib.sha256(csv.read_bytes()).hexdigest()  # the checksum made to match
    csv.with_suffix(".json").write_text(json.dumps(meta))


def _jump(frame):
    frame.loc[len(frame) // 2, "steps"] = 100_000


def _twice_the_rate(frame):
    frame["t_us"] = frame["t_us"].iloc[0] + (frame["t_us"] - frame["t_us"].iloc[0]) // 2


def _teleport(frame):  # within the travel, but 40 steps between two samples 1 ms apart
    frame.loc[len(frame) // 2 :, "steps"] += 40


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (_jump, "beyond the travel"),
        (_twice_the_rate, "less than the period of rate_hz"),
        (_teleport, "faster than the stepper's 2000 steps/s"),
    ],
)
def test_impossible_contents_are_refused_whatever_the_checksum(tmp_path, change, message):
    old = REPO_ROOT / "tests" / "fixtures" / "recordings"  # a version-1 pulse: the damage edits its columns
    csv = _copy(old / "experiments" / "zvd_v200_x20_r1.csv", tmp_path / "g", "run")
    recordings.load(csv)  # sound as stored
    _edit_csv(csv, change)
    with pytest.raises(RecordingError, match=message) as info:
        recordings.load(csv)
    assert str(csv) in str(info.value)


def test_a_stream_recording_without_its_stream_section_is_one_named_problem(tmp_path, capsys, monkeypatch):
    folder = tmp_path / "mine"
    good = _copy(DATA_DIR / "experiments" / "zvd_v200_x20_r1.csv", folder, "good")  # a pulse: analysed
    bad = _copy(_a_stream(), folder, "bad")
    meta = json.loads(bad.with_suffix(".json").read_text())
    del meta["scenario"]["stream"]
    bad.with_suffix(".json").write_text(json.dumps(meta))
    with pytest.raises(RecordingError, match="scenario.stream: missing"):
        recordings.load(bad)
    cat = recordings.catalogue(tmp_path).set_index("name")
    assert cat.loc["bad", "problem"] == "scenario.stream: missing" and cat.loc["good", "problem"] == ""
    monkeypatch.chdir(tmp_path)
    assert main(["metrics", "mine", "--include-aborted"]) == 0
    out, err = capsys.readouterr()
    assert "bad" in out + err and "scenario.stream: missing" in out + err
    assert "good" in out and recordings.load(good).status == "complete"
