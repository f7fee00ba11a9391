"""The recording format: round trip, derived columns, atomic save, one clear error per problem, catalogue."""

from __future__ import annotations

import json
import os

import numpy as np
import pandas as pd
import pytest

from helpers import recordings
from helpers.recordings import Recording, RecordingError

CAL = {"newtons_per_count": 0.025, "offset_counts": 60.0, "mm_per_step": 0.25525, "origin": "test"}


def _meta(dropped: int = 0, status: str = "complete") -> dict:
    return {
        "schema_version": recordings.SCHEMA_VERSION,
        "source": {"kind": "virtual-rig", "version": "test"},
        "scenario": {
            "kind": "pulse",
            "v_in_mm_s": 200.0,
            "x_f_mm": 10.0,
            "system": "unshaped",
            "repetition": 1,
        },
        "calibration": CAL,
        "rate_hz": 1000,
        "status": status,
        "abort_reason": None if status == "complete" else "test abort",
        "counts": {"dropped": dropped, "corrupted": 0, "overruns": 0},
    }


def _rows(n: int = 50, skip: tuple[int, ...] = ()) -> list[tuple[int, int, int, int]]:
    return [(s, 5_000 + 1000 * s, 100 + s, s // 5) for s in range(n) if s not in skip]


def _save(tmp_path, name="run", rows=None, meta=None):
    rec = Recording(
        frame=recordings.frame_from_rows(rows if rows is not None else _rows()), meta=meta or _meta()
    )
    return recordings.save(rec, tmp_path / "group" / name)


def test_round_trip_and_derived_columns(tmp_path):
    path = _save(tmp_path)
    assert path.suffix == ".csv" and path.with_suffix(".json").exists()
    rec = recordings.load(path)
    f = rec.frame
    assert list(f.columns[:4]) == ["seq", "t_us", "adc", "steps"]
    raw = pd.read_csv(path)
    assert list(raw.columns) == ["seq", "t_us", "adc", "steps"]  # derived columns are never stored
    np.testing.assert_allclose(f["t_s"], (raw["t_us"] - raw["t_us"][0]) / 1e6)
    np.testing.assert_allclose(f["tension_n"], (raw["adc"] - 60.0) * 0.025)
    np.testing.assert_allclose(f["cable_mm"], raw["steps"] * 0.25525)
    assert rec.meta["counts"]["samples"] == 50
    assert rec.is_virtual and rec.status == "complete"


def test_save_leaves_no_temporary_files_and_writes_csv_before_json(tmp_path, monkeypatch):
    order = []
    real = os.replace

    def spy(src, dst):
        order.append(os.path.basename(dst))
        return real(src, dst)

    monkeypatch.setattr(os, "replace", spy)
    _save(tmp_path)
    assert order == ["run.csv", "run.json"]
    assert sorted(p.name for p in (tmp_path / "group").iterdir()) == ["run.csv", "run.json"]


def test_aborted_recording_round_trips(tmp_path):
    path = _save(tmp_path, rows=_rows(10), meta=_meta(status="aborted"))
    rec = recordings.load(path)
    assert rec.status == "aborted" and rec.meta["abort_reason"] == "test abort" and len(rec.frame) == 10


def test_gap_within_the_dropped_count_is_accepted(tmp_path):
    path = _save(tmp_path, rows=_rows(20, skip=(5, 6)), meta=_meta(dropped=2))
    assert len(recordings.load(path).frame) == 18


def _rewrite_csv(path, text):
    path.write_text(text)
    meta = json.loads(path.with_suffix(".json").read_text())
    import hashlib

    meta["csv_sha256"] = hashlib.sha256(path.read_bytes()).hexdigest()
    path.with_suffix(".json").write_text(json.dumps(meta))


@pytest.mark.parametrize(
    "damage, message",
    [
        ("missing_json", "missing JSON"),
        ("checksum", "checksum mismatch"),
        ("schema", "unknown schema version"),
        ("column", "missing column 'adc'"),
        ("gap", "gap in seq"),
        ("time", "non-monotonic time"),
        ("bad_json", "unreadable JSON"),
    ],
)
def test_each_problem_raises_one_error_naming_file_and_problem(tmp_path, damage, message):
    path = _save(tmp_path, rows=_rows(20))
    jp = path.with_suffix(".json")
    if damage == "missing_json":
        jp.unlink()
    elif damage == "checksum":
        path.write_text(path.read_text().replace("\n5,", "\n6,", 1))
    elif damage == "schema":
        meta = json.loads(jp.read_text())
        meta["schema_version"] = 99
        jp.write_text(json.dumps(meta))
    elif damage == "column":
        _rewrite_csv(path, pd.read_csv(path).drop(columns="adc").to_csv(index=False))
    elif damage == "gap":
        _rewrite_csv(path, pd.read_csv(path).drop(index=[4, 5]).to_csv(index=False))
    elif damage == "time":
        df = pd.read_csv(path)
        df.loc[7, "t_us"] = df.loc[6, "t_us"]
        _rewrite_csv(path, df.to_csv(index=False))
    elif damage == "bad_json":
        jp.write_text("{not json")
    with pytest.raises(RecordingError) as info:
        recordings.load(path)
    assert message in str(info.value)
    assert "run." in str(info.value)  # names the file


def test_save_refuses_incomplete_metadata(tmp_path):
    meta = _meta()
    del meta["calibration"]
    with pytest.raises(RecordingError, match="calibration"):
        recordings.save(Recording(recordings.frame_from_rows(_rows(3)), meta), tmp_path / "x")


def test_catalogue_lists_recordings(tmp_path):
    _save(tmp_path, "a")
    _save(tmp_path, "b", meta=_meta(status="aborted"))
    (tmp_path / "group" / "notes.json").write_text("{}")  # not a recording: no CSV beside it
    cat = recordings.catalogue(tmp_path)
    assert list(cat["name"]) == ["a", "b"]
    assert list(cat["status"]) == ["complete", "aborted"]
    assert set(cat["source"]) == {"virtual-rig"}
    assert list(cat["samples"]) == [50, 50]
