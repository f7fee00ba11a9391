"""The recording format as a public contract (docs/recording_format.md), checked on every file in data/.

The reader here is written independently of ``helpers.recordings`` (plain csv, json and hashlib), as a tool
outside the project would read the files: versions 1 and 2 (one tendon) and 3 and 4 (per-tendon columns).
``data/`` holds versions 1 (the calibration) and 4, ``tests/fixtures/recordings/`` a version-1 pulse and
stream and a version-3 tip stream as ``data/`` held them before; a version-4 recording of each layout (one
tendon, four with the tip) is also written by :func:`helpers.recordings.from_samples` into a temporary folder
and read the same way.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import re
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from helpers import recordings, rigfile
from helpers.base.paths import DATA_DIR, REPO_ROOT

OLD = REPO_ROOT / "tests" / "fixtures" / "recordings"
"""Recordings of versions 1 and 3 as ``data/`` held them before it was recorded again in version 4."""

NOT_RECORDINGS = {"calibration.json", "result.json"}


def _tracked_json() -> list[Path]:
    """The JSON files the repository holds under data/ (git ls-files; every file outside a checkout)."""
    try:
        out = subprocess.run(["git", "ls-files", "-z", "--", "*.json"], cwd=DATA_DIR, capture_output=True,
                             check=True, timeout=60).stdout.decode()  # fmt: skip
        return [DATA_DIR / name for name in out.split("\0") if name]
    except (OSError, subprocess.SubprocessError):
        return list(DATA_DIR.rglob("*.json"))


def _is_recording(path: Path) -> bool:
    """A recording's JSON, not another document: those (designs, mode maps, results) declare a ``format``.

    ``data/external/`` holds data made elsewhere in their own formats (docs/external_data.md), not recordings.
    """
    if path.name in NOT_RECORDINGS or path.relative_to(DATA_DIR).parts[0] == "external":
        return False
    doc = json.loads(path.read_text())
    return not (isinstance(doc, dict) and "format" in doc and "schema_version" not in doc)


RECORDINGS = sorted(p for p in _tracked_json() if _is_recording(p)) + sorted(OLD.rglob("*.json"))


def _root(path: Path) -> Path:
    """The folder a recording's group is relative to: ``data/``, or the old versions' fixtures."""
    return OLD if path.is_relative_to(OLD) else DATA_DIR
VIRTUAL_PARAMETER_KEYS = (
    "E", "rho", "d", "L", "n_discs", "disc_mass", "r", "k", "pretension", "g", "base_angle_deg",
)  # fmt: skip
NAME = re.compile(r"[A-Za-z0-9_.-]+\Z")


def _number(x: object) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def test_there_are_recordings_to_check():
    assert len(RECORDINGS) >= 40


@pytest.mark.parametrize("path", RECORDINGS, ids=lambda p: str(p.relative_to(_root(p).parent)))
def test_recording_follows_the_contract(path: Path):
    meta = json.loads(path.read_text())
    group = path.parent.relative_to(_root(path))
    assert all(NAME.match(part) for part in (*group.parts, path.stem))
    data = path.with_suffix(".csv").read_bytes()
    if meta["schema_version"] in (3, 4):
        return _check_several_tendons(path, meta, data)
    assert meta["schema_version"] in (1, 2)
    assert meta["status"] in ("complete", "aborted", "deviated")
    assert meta["csv_sha256"] == hashlib.sha256(data).hexdigest()
    cal = meta["calibration"]
    assert _number(cal["newtons_per_count"]) and cal["newtons_per_count"] > 0
    assert _number(cal["offset_counts"])
    assert _number(cal["mm_per_step"]) and cal["mm_per_step"] > 0
    assert isinstance(cal["origin"], str)
    source = meta["source"]
    assert source["kind"] in ("hardware", "virtual-rig")
    if source["kind"] == "virtual-rig":
        params = source["parameters"]
        for key in VIRTUAL_PARAMETER_KEYS:
            assert _number(params[key]), key
        assert all(not isinstance(v, dict | list) for v in params.values())  # flat values
    scenario = meta["scenario"]
    assert isinstance(scenario["kind"], str)
    if scenario["kind"] == "pulse":
        assert isinstance(scenario["system"], str)
        assert _number(scenario["v_in_mm_s"]) and _number(scenario["x_f_mm"])
    if meta["schema_version"] == 2:
        assert hashlib.sha256(meta["rig"]["text"].encode()).hexdigest()[:8] == meta["rig"]["hash"]
    if scenario["kind"] == "stream":
        _check_stream(scenario["stream"], [scenario["stream"]["setpoints"]])
    rows = list(csv.reader(io.StringIO(data.decode("ascii"))))
    assert rows[0] == ["seq", "t_us", "adc", "steps"]
    body = np.array(rows[1:], dtype=np.int64)
    assert len(body) == meta["counts"]["samples"]
    assert np.all(np.diff(body[:, 0]) > 0) and np.all(np.diff(body[:, 1]) > 0)
    assert body[:, 2].min() >= 0 and body[:, 2].max() <= 1023
    # the package's loader derives the same tension from the same two keys
    rec = recordings.load(path)
    expected = (body[:, 2] - cal["offset_counts"]) * cal["newtons_per_count"]
    np.testing.assert_allclose(rec.frame["tension_n"].to_numpy(), expected, rtol=0, atol=1e-12)


def _check_stream(stream: dict, rows: list[list[int]]) -> None:
    """A stream's set-points: within the paper's board limit (|v| <= 1640 units for its 639 us step; every
    rig in data/ has it), counted, and their sha256 period by period, tendon by tendon, int16 little-endian.
    """
    assert stream["n_setpoints"] == len(stream["periods"]) == len(stream["setpoints"])
    assert all(len(r) == stream["n_setpoints"] and all(abs(v) <= 1640 for v in r) for r in rows)
    assert rows[0] == stream["setpoints"] and sum(stream["impulses"]["amplitudes"]) == 4096
    data = b"".join(struct.pack("<h", v) for period in zip(*rows, strict=True) for v in period)
    assert hashlib.sha256(data).hexdigest() == stream["setpoints_sha256"]


def _check_several_tendons(path: Path, meta: dict, data: bytes) -> None:
    """A recording of per-tendon columns (``schema_version`` 3, 2-4 tendons, and 4, 1-4 tendons,
    docs/recording_format.md), read independently."""
    n = meta["tendons"]
    assert (2 if meta["schema_version"] == 3 else 1) <= n <= 4
    assert meta["status"] in ("complete", "aborted", "deviated")
    assert meta["csv_sha256"] == hashlib.sha256(data).hexdigest()
    rig = meta["rig"]
    assert isinstance(rig["name"], str) and isinstance(rig["text"], str)
    assert hashlib.sha256(rig["text"].encode()).hexdigest()[:8] == rig["hash"]
    assert rig["text"].count("[[tendon]]") in ((n,) if n > 1 else (0, 1))  # one tendon: may be implicit
    cal = meta["calibration"]
    for key in ("newtons_per_count", "offset_counts", "mm_per_step"):
        assert len(cal[key]) == n and all(_number(v) for v in cal[key]), key
    assert all(1e-4 <= v <= 100 for v in cal["newtons_per_count"]) and all(v > 0 for v in cal["mm_per_step"])
    assert all(-256 <= v <= 1279 for v in cal["offset_counts"])  # the 10-bit ADC's range, a quarter beyond
    if meta["schema_version"] == 4:
        assert len(cal["origin"]) == n and all(isinstance(o, str) for o in cal["origin"])
        assert isinstance(meta["started_utc"], str)
    else:
        assert isinstance(cal["origin"], str)
    if meta["scenario"]["kind"] == "stream":
        _check_stream(meta["scenario"]["stream"], meta["scenario"]["stream"]["tendon_setpoints"])
    if meta["scenario"].get("stream_of") == "tip path":
        assert isinstance(meta["scenario"]["path"]["stops"], list)
    assert meta["source"]["kind"] in ("hardware", "virtual-rig")
    assert isinstance(meta["host"]["helpers"], str)  # provenance: the code that recorded it
    assert isinstance(meta["firmware"]["daq"], str) and isinstance(meta["firmware"]["stepper"], str)
    rows = list(csv.reader(io.StringIO(data.decode("ascii"))))
    header = ["seq", "t_us", *(f"adc_{i}" for i in range(n)), *(f"steps_{i}" for i in range(n))]
    tip = ["tip_x_um", "tip_y_um", "tip_z_um"]
    assert rows[0] == (header + tip if "tip" in meta else header)
    if "tip" in meta:
        assert meta["source"]["kind"] == "virtual-rig" and meta["tip"]["unit"] == "um"
    body = np.array(rows[1:], dtype=np.int64)
    assert len(body) == meta["counts"]["samples"]
    assert np.all(np.diff(body[:, 0]) > 0) and np.all(np.diff(body[:, 1]) > 0)
    adc = body[:, 2 : 2 + n]
    assert adc.min() >= 0 and adc.max() <= 1023
    rec = recordings.load(path)
    for i in range(n):
        expected = (adc[:, i] - cal["offset_counts"][i]) * cal["newtons_per_count"][i]
        np.testing.assert_allclose(rec.frame[f"tension_n_{i}"].to_numpy(), expected, rtol=0, atol=1e-12)


def test_a_version_4_recording_of_each_layout_follows_the_contract(tmp_path):
    """Versions 4 of the paper's one tendon (its pulse's samples and scenario from data/) and of four tendons
    with the twin's tip and a stream, read by the independent reader above."""
    pulse = recordings.load(OLD / "experiments" / "zvd_v200_x20_r1.csv")
    m = pulse.meta
    one = recordings.from_samples(
        pulse.frame[["seq", "t_us", "adc", "steps"]].to_numpy(), rigfile.default_rig(), [m["calibration"]],
        source=m["source"], scenario=m["scenario"], rate_hz=1000, started_utc=m["started_utc"],
        firmware=m["firmware"], counts=m["counts"],
    )  # fmt: skip
    tip = json.loads((OLD / "tip_streams" / "tip_random_zv_b10.json").read_text())
    four = rigfile.load(rigfile.resolve("four-tendon"))
    rows = [(s, 1000 * s, 120, 121, 122, 123, s // 8, 0, 0, -(s // 8), -5000, 3, 230_000) for s in range(200)]
    several = recordings.from_samples(
        rows, four, source={"kind": "virtual-rig"}, scenario=tip["scenario"], rate_hz=1000,
        started_utc=tip["started_utc"], firmware=tip["firmware"],
    )  # fmt: skip
    for rec, name in ((one, "one"), (several, "four")):
        path = recordings.save(rec, tmp_path / "g" / name)
        meta = json.loads(path.with_suffix(".json").read_text())
        assert meta["schema_version"] == 4
        _check_several_tendons(path.with_suffix(".json"), meta, path.read_bytes())
    assert path.read_text().splitlines()[0].endswith("steps_3,tip_x_um,tip_y_um,tip_z_um")
