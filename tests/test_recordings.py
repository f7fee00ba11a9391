"""The recording format and its store: round trip, no silent overwrite, no torn pair, one clear error each."""

from __future__ import annotations

import errno
import hashlib
import json
import multiprocessing as mp
import os
import stat

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from helpers import recordings, rigfile
from helpers.base.paths import REPO_ROOT
from helpers.commands.recording_paths import recording_path
from helpers.paper import metrics
from helpers.recordings import Recording, RecordingError, RecordingExists

PAPER = rigfile.default_rig()
MM_PER_STEP = 3.141592653589793 * 65 / 800  # the paper's spool (65 mm) and 800 steps per revolution
CAL = {"newtons_per_count": 0.025, "offset_counts": 60.0, "mm_per_step": MM_PER_STEP, "origin": "test"}
FIRMWARE = {"daq": "test", "stepper": "test"}
PULSE = {"kind": "pulse", "v_in_mm_s": 200.0, "x_f_mm": 10.0, "system": "unshaped", "repetition": 1}


def _rows(n: int = 50, skip: tuple[int, ...] = (), adc0: int = 100) -> list[tuple[int, int, int, int]]:
    return [(s, 5_000 + 1000 * s, adc0 + s % 400, s // 5) for s in range(n) if s not in skip]


def _rec(rows=None, dropped: int = 0, status: str = "complete") -> Recording:
    """A run of the paper's rig as the one writer makes it (version 4, one tendon)."""
    return recordings.from_samples(
        rows if rows is not None else _rows(), PAPER, [CAL], source={"kind": "virtual-rig"},
        scenario=PULSE, rate_hz=1000, started_utc="2026-12-01T15:00:00Z", firmware=FIRMWARE,
        status=status, reason=None if status == "complete" else "test abort",
        counts={"dropped": dropped, "corrupted": 0, "overruns": 0},
    )  # fmt: skip


def _save(tmp_path, name="run", rows=None, replace=False, **kwargs):
    return recordings.save(_rec(rows, **kwargs), tmp_path / "group" / name, replace=replace)


def _visible(folder) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if not p.name.startswith("."))


def test_round_trip_and_derived_columns(tmp_path):
    path = _save(tmp_path)
    assert path.suffix == ".csv" and path.with_suffix(".json").exists()
    rec = recordings.load(path)
    f = rec.frame
    assert list(f.columns) == ["seq", "t_us", "adc_0", "steps_0", "t_s", "tension_n_0", "cable_mm_0", "adc",
                               "steps", "tension_n", "cable_mm"]  # fmt: skip
    raw = pd.read_csv(path)
    assert list(raw.columns) == ["seq", "t_us", "adc_0", "steps_0"]  # derived columns are never stored
    np.testing.assert_allclose(f["t_s"], (raw["t_us"] - raw["t_us"][0]) / 1e6)
    np.testing.assert_allclose(f["tension_n"], (raw["adc_0"] - 60.0) * 0.025)
    np.testing.assert_allclose(f["tension_n_0"], (raw["adc_0"] - 60.0) * 0.025)
    np.testing.assert_allclose(f["cable_mm"], raw["steps_0"] * 0.2552544031)
    assert (f["adc"] == raw["adc_0"]).all() and (f["steps"] == raw["steps_0"]).all()
    assert rec.meta["counts"]["samples"] == 50 and (rec.meta["schema_version"], rec.meta["tendons"]) == (4, 1)
    assert rec.meta["source"]["kind"] == "virtual-rig" and rec.status == "complete"
    assert rec.meta["calibration"]["offset_counts"] == [60.0] and rec.meta["rig"]["name"] == "paper"


def test_csv_is_placed_before_json_and_no_temporary_file_is_left(tmp_path, monkeypatch):
    order = []
    real = os.link

    def spy(src, dst):
        order.append(os.path.basename(dst))
        return real(src, dst)

    monkeypatch.setattr(os, "link", spy)
    _save(tmp_path)
    assert order == ["run.csv", "run.json"]
    assert _visible(tmp_path / "group") == ["run.csv", "run.json"]
    assert not [p for p in (tmp_path / "group").iterdir() if p.name.endswith(".tmp")]


def test_saved_files_are_readable_by_others(tmp_path):
    path = _save(tmp_path)
    umask = os.umask(0)
    os.umask(umask)
    for p in (path, path.with_suffix(".json")):
        assert stat.S_IMODE(p.stat().st_mode) == 0o666 & ~umask


def test_an_existing_name_is_refused_and_kept(tmp_path):
    path = _save(tmp_path, rows=_rows(30))
    with pytest.raises(RecordingExists, match="exists"):
        _save(tmp_path, rows=_rows(5))
    assert len(recordings.load(path).frame) == 30


def test_replace_keeps_the_old_pair_until_the_new_one_is_complete(tmp_path, monkeypatch):
    path = _save(tmp_path, rows=_rows(30))
    real = os.link

    def fail_on_json(src, dst):
        if str(dst).endswith(".json"):
            raise OSError(errno.EIO, "simulated failure")
        return real(src, dst)

    monkeypatch.setattr(os, "link", fail_on_json)
    with pytest.raises(RecordingError, match="could not save"):
        _save(tmp_path, rows=_rows(5), replace=True)
    monkeypatch.undo()
    assert len(recordings.load(path).frame) == 30  # the old pair, whole
    assert _visible(tmp_path / "group") == ["run.csv", "run.json"]
    _save(tmp_path, rows=_rows(5), replace=True)
    assert len(recordings.load(path).frame) == 5


def test_a_full_disk_is_one_error_and_loses_nothing(tmp_path, monkeypatch):
    kept = _save(tmp_path, "kept")
    before = {p.name: p.read_bytes() for p in (tmp_path / "group").iterdir() if not p.name.startswith(".")}

    def no_space(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", no_space)
    with pytest.raises(RecordingError, match="no space left on device") as info:
        _save(tmp_path, "new")
    assert "\n" not in str(info.value)
    monkeypatch.undo()
    after = {p.name: p.read_bytes() for p in (tmp_path / "group").iterdir() if not p.name.startswith(".")}
    assert after == before
    assert not [p for p in (tmp_path / "group").iterdir() if p.name.endswith(".tmp")]
    assert len(recordings.load(kept).frame) == 50


@pytest.mark.parametrize(
    "name", ["../x", "a/b", "..", "", "calibration", "result", "Result", "x" * 101, "-x", "x.tmp", "a b"]
)
def test_bad_or_reserved_names_are_refused(tmp_path, name):
    with pytest.raises(RecordingError, match="invalid recording name"):
        recording_path("group", name, root=tmp_path)
    if "/" not in name:  # save itself checks the file's own name too
        with pytest.raises(RecordingError, match="invalid recording name"):
            recordings.save(_rec(), tmp_path / "group" / f"{name}.csv")
    assert not (tmp_path / "group").exists() or _visible(tmp_path / "group") == []


@pytest.mark.parametrize("group", ["../x", "/etc", "a/../b", "", "a//b"])
def test_bad_groups_are_refused(group):
    with pytest.raises(RecordingError, match="invalid group"):
        recording_path(group, "run")


def test_an_aborted_run_gets_its_own_name(tmp_path):
    target = tmp_path / "group" / "zv_v200_x20_r1.csv"
    p = recordings.aborted_path(target, "2026-12-01T15:00:00Z")
    assert p.parent == target.parent and p.name == "zv_v200_x20_r1_aborted_20261201T150000Z.csv"
    recordings.check_name(p.stem)


def test_zero_samples_round_trip(tmp_path):
    path = _save(tmp_path, rows=[], status="aborted")
    rec = recordings.load(path)
    assert len(rec.frame) == 0 and list(rec.frame.columns[:4]) == ["seq", "t_us", "adc_0", "steps_0"]
    assert "tension_n" in rec.frame and rec.meta["abort_reason"] == "test abort"


def test_gap_within_the_dropped_count_is_accepted(tmp_path):
    path = _save(tmp_path, rows=_rows(20, skip=(5, 6)), dropped=2)
    assert len(recordings.load(path).frame) == 18


def _rewrite_csv(path, text):
    path.write_text(text)
    meta = json.loads(path.with_suffix(".json").read_text())
    meta["csv_sha256"] = hashlib.sha256(path.read_bytes()).hexdigest()
    path.with_suffix(".json").write_text(json.dumps(meta))


def _rewrite_meta(path, change):
    jp = path.with_suffix(".json")
    meta = json.loads(jp.read_text())
    change(meta)
    jp.write_text(json.dumps(meta))


@pytest.mark.parametrize(
    "damage, message",
    [
        ("missing_json", "incomplete run"),
        ("checksum", "checksum mismatch"),
        ("schema", "unknown"),
        ("column", "header"),
        ("order", "header"),
        ("cut", "counts.samples"),
        ("gap", "counts.samples"),
        ("time", "non-monotonic time"),
        ("bad_json", "unreadable JSON"),
        ("status", "status"),
        ("source", "source.kind"),
        ("npc", "calibration.newtons_per_count"),
        ("npc_type", "calibration.newtons_per_count"),
        ("counts", "counts.dropped"),
        ("rate", "rate_hz"),
        ("scenario", "scenario"),
        ("list", "metadata is not a JSON object"),
        ("deep", "unreadable JSON"),
        ("text_in_csv", "unreadable CSV"),
    ],
)
def test_each_problem_raises_one_error_naming_file_and_field(tmp_path, damage, message):
    path = _save(tmp_path, rows=_rows(20))
    jp = path.with_suffix(".json")
    if damage == "missing_json":
        jp.unlink()
    elif damage == "checksum":
        path.write_text(path.read_text().replace("\n5,", "\n6,", 1))
    elif damage == "schema":
        _rewrite_meta(path, lambda m: m.update(schema_version=99))
    elif damage == "column":
        _rewrite_csv(path, pd.read_csv(path).drop(columns="adc_0").to_csv(index=False))
    elif damage == "order":
        _rewrite_csv(path, pd.read_csv(path)[["seq", "adc_0", "t_us", "steps_0"]].to_csv(index=False))
    elif damage == "cut":  # cut at a row boundary: still parses, but has fewer rows than recorded
        _rewrite_csv(path, "\n".join(path.read_text().splitlines()[:15]) + "\n")
    elif damage == "gap":
        _rewrite_csv(path, pd.read_csv(path).drop(index=[4, 5]).to_csv(index=False))
    elif damage == "time":
        df = pd.read_csv(path)
        df.loc[7, "t_us"] = df.loc[6, "t_us"]
        _rewrite_csv(path, df.to_csv(index=False))
    elif damage == "bad_json":
        jp.write_text("{not json")
    elif damage == "status":
        _rewrite_meta(path, lambda m: m.update(status="finished"))
    elif damage == "source":
        _rewrite_meta(path, lambda m: m["source"].update(kind="simulation"))
    elif damage == "npc":
        _rewrite_meta(path, lambda m: m["calibration"].update(newtons_per_count=-1.0))
    elif damage == "npc_type":
        _rewrite_meta(path, lambda m: m["calibration"].update(newtons_per_count="0.02"))
    elif damage == "counts":
        _rewrite_meta(path, lambda m: m["counts"].update(dropped=-3))
    elif damage == "rate":
        _rewrite_meta(path, lambda m: m.update(rate_hz=True))
    elif damage == "scenario":
        _rewrite_meta(path, lambda m: m.update(scenario=[1, 2]))
    elif damage == "list":
        jp.write_text("[1, 2, 3]")
    elif damage == "deep":
        jp.write_text("[" * 100_000 + "]" * 100_000)
    elif damage == "text_in_csv":
        _rewrite_csv(path, path.read_text().replace("\n5,", "\nfive,", 1))
    with pytest.raises(RecordingError) as info:
        recordings.load(path)
    assert message in str(info.value)
    assert "run." in str(info.value)  # names the file
    assert "\n" not in str(info.value)


def test_save_refuses_incomplete_metadata(tmp_path):
    rec = _rec(_rows(3))
    del rec.meta["calibration"]
    with pytest.raises(RecordingError, match="metadata lacks calibration"):
        recordings.save(rec, tmp_path / "x")
    assert not (tmp_path / "x.csv").exists()


def test_catalogue_lists_recordings_and_reports_bad_files(tmp_path):
    _save(tmp_path, "a")
    _save(tmp_path, "b", status="aborted")
    _save(tmp_path, "c")
    (tmp_path / "group" / "c.json").write_text("{broken")
    _save(tmp_path, "d")
    (tmp_path / "group" / "d.json").unlink()  # an incomplete run: CSV only
    (tmp_path / "group" / "calibration.json").write_text("{}")  # reserved: not a recording
    cat = recordings.catalogue(tmp_path)
    assert list(cat["name"]) == ["a", "b", "c", "d"]
    assert list(cat["status"][:2]) == ["complete", "aborted"] and cat["status"][3] == "incomplete"
    assert list(cat["problem"][:2]) == ["", ""]
    assert "unreadable JSON" in cat["problem"][2]
    assert "incomplete" in cat["problem"][3]


# -- fuzzing the loader: whatever the files hold, one RecordingError (or a good load) ------------------------
SCALARS = st.none() | st.booleans() | st.integers(-(10**6), 10**6) | st.floats(allow_nan=False)
JSON_VALUES = st.recursive(
    SCALARS | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner, max_size=3),
    max_leaves=8,
)
KEYS = [
    "schema_version", "status", "abort_reason", "csv_sha256", "calibration", "rate_hz", "counts", "source",
    "scenario", "tendons", "rig", "host", "firmware", "started_utc",
]  # fmt: skip


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(key=st.sampled_from(KEYS), sub=st.sampled_from([None, "newtons_per_count", "samples", "kind"]),
       value=JSON_VALUES)  # fmt: skip
def test_fuzzed_metadata_gives_a_recording_error(tmp_path_factory, key, sub, value):
    folder = tmp_path_factory.mktemp("fuzz")
    path = recordings.save(_rec(_rows(10)), folder / "run")
    meta = json.loads(path.with_suffix(".json").read_text())
    if sub and isinstance(meta.get(key), dict):
        meta[key][sub] = value
    else:
        meta[key] = value
    path.with_suffix(".json").write_text(json.dumps(meta))
    try:
        recordings.load(path)
    except RecordingError:
        pass


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(blob=st.binary(max_size=300), keep_header=st.booleans())
def test_fuzzed_csv_gives_a_recording_error(tmp_path_factory, blob, keep_header):
    folder = tmp_path_factory.mktemp("fuzz")
    path = recordings.save(_rec(_rows(10)), folder / "run")
    data = (b"seq,t_us,adc_0,steps_0\n" if keep_header else b"") + blob
    path.write_bytes(data)
    meta = json.loads(path.with_suffix(".json").read_text())
    meta["csv_sha256"] = hashlib.sha256(data).hexdigest()
    path.with_suffix(".json").write_text(json.dumps(meta))
    try:
        recordings.load(path)
    except RecordingError:
        pass


# -- concurrency: two writers and a reader on one folder ----------------------------------------------------
def _writer(folder: str, n: int, seed: int, replace: bool, results) -> None:
    rng = np.random.default_rng(seed)
    for i in range(n):
        rows = _rows(int(rng.integers(5, 400)), adc0=seed)
        try:
            recordings.save(_rec(rows), os.path.join(folder, "shared"), replace=replace)
            results.put(("saved", seed, i))
        except RecordingExists:
            results.put(("refused", seed, i))
    results.put(("end", seed, n))


def _reader(folder: str, stop, results) -> None:
    ok = bad = 0
    path = os.path.join(folder, "shared.csv")
    while not stop.is_set():
        try:
            recordings.load(path)
            ok += 1
        except RecordingError as exc:
            bad += 1
            results.put(("reader-error", str(exc)[:120], 0))
    results.put(("reader", ok, bad))


def _drain(queue, processes: int) -> list:
    """Every result the processes put, up to the ``("end", ...)`` each one puts last (the reader's summary
    is its end): readiness, not a quiet period."""
    out, ended = [], 0
    while ended < processes:
        item = queue.get(timeout=300)
        ended += item[0] in ("end", "reader")
        out.append(item)
    return out


def test_concurrent_writers_and_a_reader_never_see_a_torn_pair(tmp_path):
    ctx = mp.get_context("fork")
    folder = tmp_path / "group"
    recordings.save(_rec(_rows(20)), folder / "shared")
    results, stop = ctx.Queue(), ctx.Event()
    reader = ctx.Process(target=_reader, args=(str(folder), stop, results))
    writers = [ctx.Process(target=_writer, args=(str(folder), 15, seed, True, results)) for seed in (1, 2)]
    reader.start()
    for w in writers:
        w.start()
    for w in writers:
        w.join(120)
    stop.set()
    reader.join(60)
    out = _drain(results, 1 + len(writers))
    saved = [r for r in out if r[0] == "saved"]
    summary = [r for r in out if r[0] == "reader"]
    errors = [r for r in out if r[0] == "reader-error"]
    assert len(saved) == 30 and not errors
    assert summary and summary[0][1] > 0
    rec = recordings.load(folder / "shared")  # the survivor is whole
    assert int(rec.frame["adc"].iloc[0]) in (1, 2)
    assert _visible(folder) == ["shared.csv", "shared.json"]


def test_two_writers_of_one_new_name_one_wins_the_other_is_refused(tmp_path):
    ctx = mp.get_context("fork")
    results = ctx.Queue()
    writers = [ctx.Process(target=_writer, args=(str(tmp_path), 1, seed, False, results)) for seed in (1, 2)]
    for w in writers:
        w.start()
    for w in writers:
        w.join(60)
    outcomes = sorted(r[0] for r in _drain(results, len(writers)) if r[0] != "end")
    assert outcomes == ["refused", "saved"]
    assert len(recordings.load(tmp_path / "shared").frame) >= 5


# -- one writer, one frame shape for every version ----------------------------------------------------------
def test_every_version_of_one_tendon_loads_into_one_frame_and_the_same_metrics(tmp_path):
    """A version-1 recording of data/, its samples written as version 2 (by hand) and as version 4 (by the one
    writer): the same frame on load, and the paper's metrics read the same numbers from each."""
    v1 = recordings.load(REPO_ROOT / "tests" / "fixtures" / "recordings" / "experiments" / "zvd_v200_x20_r1")
    m = v1.meta
    v4 = recordings.from_samples(
        v1.frame[["seq", "t_us", "adc", "steps"]].to_numpy(), PAPER, [m["calibration"]], source=m["source"],
        scenario=m["scenario"], rate_hz=m["rate_hz"], started_utc=m["started_utc"], firmware=m["firmware"],
        counts=m["counts"], t_go_us=m["t_go_us"], done_position=m["done_position"],
    )  # fmt: skip
    v4 = recordings.load(recordings.save(v4, tmp_path / "g" / "v4"))
    assert v4.path.read_text().startswith("seq,t_us,adc_0,steps_0\n")
    v2_meta = {k: v for k, v in m.items() if k != "csv_sha256"}
    v2_meta |= {"schema_version": 2, "rig": recordings.rig_section(PAPER)}
    v2 = recordings.load(recordings.save(Recording(v1.frame, v2_meta), tmp_path / "g" / "v2"))
    assert v2.path.read_text().startswith("seq,t_us,adc,steps\n")
    expected = metrics.metrics_by_run([v1])
    assert np.isfinite(expected["peak_n"]).all()
    for rec in (v2, v4):
        pd.testing.assert_frame_equal(rec.frame, v1.frame)
        pd.testing.assert_frame_equal(metrics.metrics_by_run([rec]), expected)
    assert recordings.calibration_of(v4.meta) == recordings.calibration_of(v1.meta) == m["calibration"]


def test_a_recording_of_several_tendons_has_no_one_tendon_names(tmp_path):
    four = rigfile.load(rigfile.resolve("four-tendon"))
    rows = [(s, 1000 * s, 120, 121, 122, 123 + s % 3, s // 4, 0, 0, -(s // 4)) for s in range(40)]
    rec = recordings.from_samples(rows, four, source={"kind": "hardware"}, scenario={"kind": "programme"},
                                  rate_hz=1000, started_utc="2026-12-01T15:00:00Z", firmware=FIRMWARE)
    back = recordings.load(recordings.save(rec, tmp_path / "g" / "four"))
    assert back.path.read_text().splitlines()[:2] == [
        "seq,t_us,adc_0,adc_1,adc_2,adc_3,steps_0,steps_1,steps_2,steps_3", "0,0,120,121,122,123,0,0,0,0"
    ]
    assert not {"adc", "steps", "tension_n", "cable_mm"} & set(back.frame.columns) and back.tendons == 4
    np.testing.assert_allclose(back.frame["tension_n_3"], (back.frame["adc_3"] - 122.88) / 24.576)
    np.testing.assert_allclose(back.frame["cable_mm_3"], -(np.arange(40) // 4) * MM_PER_STEP)
    origin = f"nominal: rig file four-tendon ({four.hash}), [hardware] loop and load_cell_range_n"
    assert back.meta["calibration"]["origin"] == [origin] * 4


def test_the_writer_takes_the_tip_with_the_samples_and_nothing_else():
    four = rigfile.load(rigfile.resolve("four-tendon"))
    meta = {"source": {"kind": "virtual-rig"}, "scenario": {"kind": "programme"}, "rate_hz": 1000,
            "started_utc": "2026-12-01T15:00:00Z", "firmware": {"daq": "d", "stepper": "s"}}  # fmt: skip
    rows = np.array([(s, 1000 * s, 120, 121, 122, 123, 0, 0, 0, 0, -1000, 5, 230_000 + s) for s in range(5)])
    rec = recordings.from_samples(rows, four, **meta)
    assert rec.meta["tip"] == {"origin": recordings.writer.TWIN_TIP, "unit": "um"}
    tip_z = [230.0, 230.001, 230.002, 230.003, 230.004]
    np.testing.assert_allclose(rec.frame["tip_z_mm"], tip_z, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match=r"rows: shape \(5, 12\); a rig of 4 tendons records 10 columns"):
        recordings.from_samples(rows[:, :12], four, **meta)
    with pytest.raises(ValueError, match=r"rows: shape \(5, 5\); a rig of 1 tendons records 4 columns"):
        recordings.from_samples(rows[:, :5], PAPER, **meta)
    with pytest.raises(ValueError, match="calibration: 1 given for a rig of 4 tendons"):
        recordings.from_samples(rows, four, [CAL], **meta)
    with pytest.raises(RecordingError, match=r"<unsaved recording>: scenario.system: missing"):
        recordings.from_samples(rows[:, :4], PAPER, **{**meta, "scenario": {"kind": "pulse"}})
