"""Every key of the recording format is checked on load against the recording's own rig, in every version.

The keys are the tables of ``docs/recording_format.md``: the loader's schema lists the same keys, a wrong
value of each is refused naming it, and the cases the format was attacked with (lists of the wrong length,
set-points beyond the board's limit, an absurd calibration, a wrong ``setpoints_sha256``, a tip stream without
its path) are each refused in one line naming the file and the key, in version 3 (the recordings of
``data/tip_streams``, which loaded before) and in version 4 (written by
:func:`helpers.recordings.from_samples`).
"""

from __future__ import annotations

import copy
import hashlib
import json
import re
import shutil
import struct
from pathlib import Path

import numpy as np
import pytest

from helpers import recordings, rigfile
from helpers.base.paths import REPO_ROOT
from helpers.recordings import RecordingError
from helpers.recordings.checks import SCHEMA, validate_meta
from helpers.recordings.shaping import SYSTEMS

DOC = REPO_ROOT / "docs" / "recording_format.md"
PAPER = rigfile.default_rig()
FOUR = rigfile.load(rigfile.resolve("four-tendon"))
UTC = "2026-12-01T18:26:44Z"
FIRMWARE = {"daq": "test", "stepper": "test"}
OLD = REPO_ROOT / "tests" / "fixtures" / "recordings"  # versions 1 and 3, as data/ had them before version 4
V1_PULSE = OLD / "experiments" / "zvd_v200_x20_r1"
V1_STREAM = OLD / "streams" / "teleop_zv"
V3_TIP = OLD / "tip_streams" / "tip_random_zv_b10"
UNIT = 2.0**-16 / 16e-6  # steps/s of one set-point unit: 2^-16 step per 16 us (firmware/PROTOCOL.md)


def _json(stem: Path) -> dict:
    return json.loads(stem.with_suffix(".json").read_text())


def _documented_keys() -> list[str]:
    """The keys of the JSON table (first cell of each row, in backticks)."""
    text = DOC.read_text().split("## JSON: the keys", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"^\| `([a-z_0-9.]+)` \|", text, flags=re.M)


def _schema_keys() -> set[str]:
    """Every object key the schema checks (following references, conditions and versions)."""
    definitions = json.loads(SCHEMA.read_text())["definitions"]
    out: set[str] = set()

    def walk(node: dict, prefix: str) -> None:
        if "$ref" in node:
            walk(definitions[node["$ref"].rsplit("/", 1)[1]], prefix)
        for sub in [*node.get("allOf", []), *(node[k] for k in ("then", "else") if k in node)]:
            walk(sub, prefix)
        for key in node.get("required", []):
            out.add(f"{prefix}{key}")
        for key, sub in node.get("properties", {}).items():
            out.add(f"{prefix}{key}")
            walk(sub, f"{prefix}{key}.")

    for version in (1, 2, 3, 4):
        walk(definitions[f"version_{version}"], "")
    return out | {"schema_version", "tendons"}  # checked before the schema: they choose it


# -- fixtures: recordings of every version and kind ---------------------------------------------------------
def _sha(rows: list[list[int]]) -> str:
    """The set-points' sha256 as the format defines it, computed here by hand: period by period, tendon by
    tendon, 16-bit little-endian signed."""
    data = b"".join(struct.pack("<h", v) for period in zip(*rows, strict=True) for v in period)
    return hashlib.sha256(data).hexdigest()


def _stream(rig, setpoints: list[list[int]]) -> dict:
    n = len(setpoints[0])
    return {
        "rate_hz": 100,
        "impulses": {"amplitudes": [2048, 2048], "delays_us": [0, 48_000], "allow_negative": False,
                     "amplitude_unit": 1 / 4096},
        "setpoints": list(setpoints[0]), "tendon_setpoints": [list(s) for s in setpoints],
        "periods": list(range(1, n + 1)), "n_setpoints": n, "setpoints_sha256": _sha(setpoints),
        "setpoint_unit_mm_s": [m * UNIT for m in rigfile.derived(rig).mm_per_step], "source": "array",
        "end_period": n + 1, "lead_periods": 4, "lead_in_s": 0.2, "tail_s": 0.5, "fifo_full": 0,
        "underruns": 0, "late_start_periods": 0, "notices": [], "clamps": {"speed": 0, "travel": 0},
        "watchdog": False,
    }  # fmt: skip


def _rows(rig, n_rows: int = 60, tip: bool = False) -> np.ndarray:
    """Plausible samples at 1 kHz: tendon 1 pulled one step every 5 ms, the others still."""
    n = rig.n_tendons
    s = np.arange(n_rows)
    cols = [
        s,
        5_000 + 1_000 * s,
        *(123 + (s + i) % 7 for i in range(n)),
        s // 5,
        *(0 * s for _ in range(n - 1)),
    ]
    if tip:
        cols += [-20_000 + s, 0 * s, 230_000 + 0 * s]
    return np.column_stack(cols)


def _v4(rig, scenario: dict, calibration=None, tip: bool = False, **more) -> dict:
    rec = recordings.from_samples(
        _rows(rig, tip=tip), rig, calibration, source={"kind": "virtual-rig", "version": "test"},
        scenario=scenario, rate_hz=1000, started_utc=UTC, firmware=FIRMWARE, t_go_us=9_000,
        counts={"dropped": 0, "corrupted": 0, "overruns": 0, "implausible": 0}, **more,
    )  # fmt: skip
    return {**rec.meta, "csv_sha256": "0" * 64}


def _move(rig) -> dict:
    n = rig.n_tendons
    return {
        "kind": "move", "direction_deg": 45.0, "bend_mm": 10.0, "shaper": "zvd", "design": {"mode": "test"},
        "speed_mm_s": 50.0, "steps": [5] + [0] * (n - 1), "planned_tension_n": [2.5] * n,
        "tension_floor_n": 1.0, "trimmed_steps": [0] * n, "items": ["MSEG 40000 5" + " 0" * (n - 1)],
        "noise_seed": 3, "prepull_steps": 0, "floor_check": {"simulated": True},
        "measured_trim": {"steps": [1] + [0] * (n - 1), "moves": 1, "targets_n": [2.3554] * n,
                          "before_n": [0.4] + [2.36] * (n - 1), "after_n": [2.9] + [2.4] * (n - 1),
                          "tolerance_n": 0.1},
    }  # fmt: skip


def _as_v3(meta: dict) -> dict:
    out = copy.deepcopy(meta)
    out["schema_version"] = 3
    out["calibration"]["origin"] = out["calibration"]["origin"][0]
    out["calibration"].pop("source", None)
    return out


def _as_v2(meta: dict) -> dict:
    return {**copy.deepcopy(meta), "schema_version": 2, "rig": recordings.rig_section(PAPER)}


PREPULL = {"prepull_steps": 1, "prepull_periods": 51, "release_periods": 104}
"""A tip stream's pre-pull as ``record tip-stream --prepull 1`` writes it on four tendons: the pull's
period and its 0.5 s at rest before the path's period 0, then each tendon's let-out and its 0.25 s at rest
after the path's last."""


def _fixtures() -> dict[str, dict]:
    """Metadata of every version and kind (checksums aside): together they hold every documented key."""
    pulse = _json(V1_PULSE)
    tip_stream = _json(V3_TIP)
    v4_stream = {
        "kind": "stream",
        "tendons": 4,
        "start_positions_steps": [0, 0, 0, 0],
        "t_stream_us": 8_000,
        "shaper": None,
        "stream": {**_stream(FOUR, [[0, 8, 8, 0], [0, -8, -8, 0], [0] * 4, [1, 0, 0, -1]]),
                   "rest_trims": [{"setpoint": 2, "targets_n": [2.0] * 4, "measured_n": [1.5, 2.0, 2.1, 2.2],
                                   "steps": [1, 0, 0, 0]}]},
    }
    v4 = {
        "v4 pulse (paper)": _v4(PAPER, dict(pulse["scenario"]), [pulse["calibration"]], done_position=0,
                                done_positions=[0]),
        "v4 stream (paper)": _v4(PAPER, {"kind": "stream", "start_position_steps": 0,
                                         "stream": _stream(PAPER, [[0, 10, -10, 0]])},
                                 status="deviated", deviation="late"),
        "v4 stream (four)": _v4(FOUR, v4_stream, tip=True, done_positions=[0, 0, 0, 0]),
        "v4 move (four)": _v4(FOUR, _move(FOUR), status="aborted", reason="test"),
        "v4 tip stream (four)": _v4(FOUR, {**tip_stream["scenario"], **PREPULL}, tip=True),
        "v4 programme (four)": _v4(FOUR, {"kind": "programme", "items": ["WAIT 10"]}),
    }  # fmt: skip
    return {
        "v1 pulse": pulse, "v1 stream": _json(V1_STREAM), "v2 pulse": _as_v2(pulse),
        "v3 tip stream": tip_stream, **v4, "v3 move (four)": _as_v3(v4["v4 move (four)"]),
        "v3 stream (four)": _as_v3(v4["v4 stream (four)"]),
    }  # fmt: skip


FIXTURES = _fixtures()


def _get(meta: dict, key: str):
    for part in key.split("."):
        if not isinstance(meta, dict) or part not in meta:
            return KeyError
        meta = meta[part]
    return meta


def _set(meta: dict, key: str, value) -> dict:
    out = copy.deepcopy(meta)
    *parents, last = key.split(".")
    section = out
    for part in parents:
        section = section[part]
    section[last] = value
    return out


def _refusal(meta: dict) -> str:
    with pytest.raises(RecordingError) as info:
        validate_meta(meta, Path("g/run.json"))
    message = str(info.value)
    assert message.startswith("g/run.json: ") and "\n" not in message
    return message.removeprefix("g/run.json: ")


# -- the tables and the schema ------------------------------------------------------------------------------
def test_the_documented_keys_and_the_loaders_schema_are_the_same():
    documented = _documented_keys()
    assert len(documented) == len(set(documented)) > 100  # one row per key
    assert set(documented) == _schema_keys()


def test_the_pulse_systems_of_the_schema_are_the_vocabulary():
    text = SCHEMA.read_text()
    assert json.dumps(list(SYSTEMS)) in text.replace('",\n', '", ')  # the enum, in the vocabulary's order


@pytest.mark.parametrize("name", list(FIXTURES))
def test_every_fixture_is_a_sound_recording(name):
    validate_meta(FIXTURES[name], Path("g/run.json"))


@pytest.mark.parametrize("key", _documented_keys())
def test_every_documented_key_is_checked_in_every_recording_that_holds_it(key):
    holding = [name for name, meta in FIXTURES.items() if _get(meta, key) is not KeyError]
    assert holding, f"no fixture holds {key}"
    for name in holding:
        message = _refusal(_set(FIXTURES[name], key, [[["not a value"]]]))  # of no documented type
        assert message.startswith(key), (name, message)


# -- the cases the format was attacked with, each in version 3 (as loaded before) and 4 ----------------------
def test_a_per_tendon_list_of_the_wrong_length_is_refused():
    for name in ("v3 tip stream", "v4 tip stream (four)", "v3 stream (four)", "v4 move (four)"):
        meta = FIXTURES[name]
        for key in ("calibration.newtons_per_count", "calibration.offset_counts", "calibration.mm_per_step"):
            values = _get(meta, key)
            assert _refusal(_set(meta, key, values[:-1])).startswith(f"{key}: expected a list of 4 ")
            assert _refusal(_set(meta, key, values + values[:1])).startswith(f"{key}: expected a list of 4 ")
    stream = FIXTURES["v4 stream (four)"]
    for key in ("scenario.stream.setpoint_unit_mm_s", "scenario.stream.tendon_setpoints",
                "scenario.start_positions_steps", "done_positions"):  # fmt: skip
        assert _refusal(_set(stream, key, _get(stream, key)[:3])).startswith(f"{key}: expected a list of 4 ")
    move = FIXTURES["v4 move (four)"]
    for key in ("scenario.steps", "scenario.planned_tension_n", "scenario.trimmed_steps"):
        assert _refusal(_set(move, key, [1, 2])).startswith(f"{key}: expected a list of 4 ")
    paper = FIXTURES["v4 pulse (paper)"]
    assert _refusal(_set(paper, "calibration.offset_counts", [122.9, 122.9])).startswith(
        "calibration.offset_counts: expected a list of 1 "
    )


def test_a_set_point_beyond_the_boards_limit_is_refused():
    """1640 board units on the paper's rig (its 639 us step: floor(2^20 / 639)); 10^9 in a version-3 file."""
    v1 = FIXTURES["v1 stream"]
    values = _get(v1, "scenario.stream.setpoints")
    assert "got 1641" in _refusal(_set(v1, "scenario.stream.setpoints", [1641, *values[1:]]))
    tip = FIXTURES["v3 tip stream"]
    rows = copy.deepcopy(tip["scenario"]["stream"]["tendon_setpoints"])
    rows[2][100] = 10**9
    message = _refusal(_set(tip, "scenario.stream.tendon_setpoints", rows))
    assert message.startswith("scenario.stream.tendon_setpoints[2][100]: expected a set-point of -1640..1640")
    four = FIXTURES["v4 stream (four)"]
    message = _refusal(_set(four, "scenario.stream.setpoints", [-1641, 8, 8, 0]))
    assert message.startswith("scenario.stream.setpoints[0]: expected a set-point of -1640..1640 board units")


def test_the_set_point_limit_is_the_recordings_rig():
    """A rig whose fastest step is 1001 us streams at most floor(2^20 / 1001) = 1047 units: 1048 is refused
    in its recording, 1047 not; the paper's limit (1640) has nothing to do with it."""
    text = PAPER.text.replace("speed_limit_mm_s = 400.0", "speed_limit_mm_s = 255.0")
    assert text != PAPER.text
    slow = rigfile.loads(text, source="slow.toml")
    assert rigfile.derived(slow).min_interval_us == 1001
    limit = 2**20 // 1001
    for v, refused in ((limit, False), (limit + 1, True)):
        meta = _v4(slow, {"kind": "stream", "stream": _stream(slow, [[0] * 3])})
        meta = _set(meta, "scenario.stream.setpoints", [v, 0, 0])
        meta = _set(meta, "scenario.stream.tendon_setpoints", [[v, 0, 0]])
        meta = _set(meta, "scenario.stream.setpoints_sha256", _sha([[v, 0, 0]]))
        if refused:
            assert _refusal(meta).startswith(
                f"scenario.stream.setpoints[0]: expected a set-point of -{limit}..{limit}"
            )
        else:
            validate_meta(meta, Path("g/run.json"))


@pytest.mark.parametrize(
    "name", ["v1 pulse", "v2 pulse", "v3 tip stream", "v4 pulse (paper)", "v4 move (four)"]
)
def test_an_absurd_calibration_is_refused(name):
    meta = FIXTURES[name]
    several = isinstance(meta["calibration"]["offset_counts"], list)
    at = "[0]" if several else ""

    def put(key, value):
        return _set(meta, f"calibration.{key}", [value] + meta["calibration"][key][1:] if several else value)

    refused = [("offset_counts", 1e300), ("offset_counts", -257.0), ("offset_counts", 1280.0),
               ("newtons_per_count", 1e308), ("newtons_per_count", 1e-5), ("newtons_per_count", 0.0)]
    for key, value in refused:
        assert _refusal(put(key, value)).startswith(f"calibration.{key}{at}: expected ")
    for key, value in (("offset_counts", -256.0), ("offset_counts", 1279.0), ("newtons_per_count", 100.0),
                       ("newtons_per_count", 1.0)):  # fmt: skip
        validate_meta(put(key, value), Path("g/run.json"))  # the edges of the stated ranges
    message = _refusal(put("mm_per_step", 0.3))
    assert message.startswith("calibration.mm_per_step: 0.3 for tendon 1, but its rig file makes it 0.255254")


@pytest.mark.parametrize("name", ["v1 stream", "v3 tip stream", "v4 stream (paper)", "v4 stream (four)"])
def test_a_wrong_setpoints_sha256_is_refused(name):
    meta = FIXTURES[name]
    assert _refusal(_set(meta, "scenario.stream.setpoints_sha256", "0" * 64)).startswith(
        "scenario.stream.setpoints_sha256: not the set-points'"
    )
    stream = meta["scenario"]["stream"]
    rows = copy.deepcopy(stream.get("tendon_setpoints", [stream["setpoints"]]))
    rows[-1][1] += 1  # one set-point changed, the sha256 kept
    changed = _set(meta, "scenario.stream.setpoints", rows[0])
    if "tendon_setpoints" in meta["scenario"]["stream"]:
        changed = _set(changed, "scenario.stream.tendon_setpoints", rows)
    assert _refusal(changed).startswith("scenario.stream.setpoints_sha256: not the set-points'")


def test_tendon_1s_set_points_are_the_setpoints():
    meta = FIXTURES["v4 stream (four)"]
    message = _refusal(_set(meta, "scenario.stream.setpoints", [0, 8, 8, 1]))
    assert message == "scenario.stream.setpoints: not tendon 1's tendon_setpoints"


@pytest.mark.parametrize("name", ["v3 tip stream", "v4 tip stream (four)"])
@pytest.mark.parametrize(
    "key",
    ["path", "shaper_name", "design", "stop_steps", "trimmed_steps", "planned_min_tension_n",
     "tension_floor_n", "knot_mm", "board_count_min_static_tension_n", "speed_mm_s"],
)  # fmt: skip
def test_a_tip_stream_without_a_key_of_its_scenario_is_refused(name, key):
    meta = copy.deepcopy(FIXTURES[name])
    del meta["scenario"][key]
    assert _refusal(meta) == f"scenario.{key}: missing"


@pytest.mark.parametrize("key", ["summary", "figure", "bend_mm", "speed_mm_s", "periods", "period_s", "stops",
                                 "bends_mm"])  # fmt: skip
def test_a_tip_streams_path_without_a_key_is_refused(key):
    meta = copy.deepcopy(FIXTURES["v3 tip stream"])
    del meta["scenario"]["path"][key]
    assert _refusal(meta) == f"scenario.path.{key}: missing"


@pytest.mark.parametrize("name", ["v3 move (four)", "v4 move (four)"])
@pytest.mark.parametrize("key", ["direction_deg", "bend_mm", "shaper", "design", "speed_mm_s", "steps",
                                 "planned_tension_n", "tension_floor_n", "trimmed_steps"])  # fmt: skip
def test_a_move_without_a_key_of_its_scenario_is_refused(name, key):
    meta = copy.deepcopy(FIXTURES[name])
    del meta["scenario"][key]
    assert _refusal(meta) == f"scenario.{key}: missing"


def test_a_stream_beyond_the_rigs_travel_or_timing_is_refused():
    meta = FIXTURES["v4 stream (four)"]
    assert "expected a step position within the rig's travel, -78..156, got 157" in _refusal(
        _set(meta, "scenario.start_positions_steps", [0, 0, 157, 0])
    )
    assert _refusal(_set(meta, "scenario.stream.impulses.delays_us", [0, 620_016])).startswith(
        "scenario.stream.impulses.delays_us[1]: expected a multiple of 16 us within 0..620000 us"
    )  # a board of several axes keeps 0.62 s of set-points; the paper's keeps 1 s
    validate_meta(_set(FIXTURES["v4 stream (paper)"], "scenario.stream.impulses.delays_us", [0, 1_000_000]),
                  Path("g/run.json"))  # fmt: skip
    assert _refusal(_set(meta, "scenario.stream.impulses.amplitudes", [2048, 2047])).startswith(
        "scenario.stream.impulses.amplitudes: sum to 4095"
    )
    assert _refusal(_set(meta, "scenario.stream.periods", [1, 3, 2, 4])).startswith("scenario.stream.periods")
    assert _refusal(_set(meta, "scenario.stream.n_setpoints", 5)).startswith("scenario.stream.n_setpoints")
    unit = meta["scenario"]["stream"]["setpoint_unit_mm_s"]
    assert _refusal(_set(meta, "scenario.stream.setpoint_unit_mm_s", [1.0, *unit[1:]])).startswith(
        "scenario.stream.setpoint_unit_mm_s: 1 for tendon 1, but its rig file makes it 0.24343"
    )


def test_the_tendon_count_is_the_rigs_and_the_versions():
    assert _refusal(_set(FIXTURES["v4 move (four)"], "tendons", 3)) == "tendons: 3, but the rig file has 4"
    assert (
        _refusal(_set(FIXTURES["v3 tip stream"], "tendons", 1)) == "tendons: expected an integer 2-4, got 1"
    )
    four = {**copy.deepcopy(FIXTURES["v2 pulse"]), "rig": recordings.rig_section(FOUR)}
    assert _refusal(four) == "tendons: 1, but the rig file has 4"  # a one-tendon layout of a four-tendon rig
    assert _refusal(_set(FIXTURES["v4 pulse (paper)"], "schema_version", 5)) == (
        "schema_version: unknown 5 (this code reads (1, 2, 3, 4))"
    )
    no_rig = copy.deepcopy(FIXTURES["v2 pulse"])
    del no_rig["rig"]
    assert _refusal(no_rig) == "rig: missing (a recording of schema_version 2 keeps its rig file)"
    bad = _set(FIXTURES["v4 pulse (paper)"], "rig.text", PAPER.text.replace("[hardware]", "[hardwar]"))
    bad = _set(bad, "rig.hash", rigfile.rig_hash(bad["rig"]["text"].encode()))
    assert _refusal(bad).startswith("rig.text (rig 'paper'): ")


def test_the_status_says_why():
    assert _refusal(_set(FIXTURES["v4 move (four)"], "abort_reason", None)).startswith(
        "abort_reason: expected text saying why"
    )
    deviated = copy.deepcopy(FIXTURES["v4 stream (paper)"])
    del deviated["deviation"]
    assert _refusal(deviated) == "deviation: missing"


def test_version_4_requires_its_provenance():
    for key in ("host", "firmware", "started_utc", "rig", "tendons"):
        meta = copy.deepcopy(FIXTURES["v4 programme (four)"])
        del meta[key]
        assert _refusal(meta).startswith(f"{key}: missing")


# -- the same checks on load, the file named, among good files ----------------------------------------------
def _copy(stem: Path, folder: Path, name: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for ext in (".csv", ".json"):
        shutil.copy(stem.with_suffix(ext), folder / f"{name}{ext}")
    return folder / f"{name}.csv"


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda m: m["calibration"]["offset_counts"].__setitem__(1, 1e300),
         "calibration.offset_counts[1]: expected"),
        (lambda m: m["calibration"]["newtons_per_count"].pop(),
         "calibration.newtons_per_count: expected a list of 4"),
        (lambda m: m["scenario"]["stream"]["tendon_setpoints"][0].__setitem__(50, 10**9),
         "scenario.stream.tendon_setpoints[0][50]: expected a set-point"),
        (lambda m: m["scenario"].pop("path"), "scenario.path: missing"),
        (lambda m: m["scenario"]["stream"].update(setpoints_sha256="1" * 64),
         "scenario.stream.setpoints_sha256"),
    ],
)  # fmt: skip
def test_version_3_metadata_that_loaded_before_is_refused_on_load(tmp_path, change, message):
    csv = _copy(V3_TIP, tmp_path / "g", "tip")
    recordings.load(csv)  # sound as stored
    meta = _json(csv.with_suffix(""))
    change(meta)
    csv.with_suffix(".json").write_text(json.dumps(meta))
    with pytest.raises(RecordingError) as info:
        recordings.load(csv)
    assert str(info.value).startswith(f"{csv.with_suffix('.json')}: {message}")
    cat = recordings.catalogue(tmp_path).set_index("name")
    assert cat.loc["tip", "problem"].startswith(message)


def test_non_finite_numbers_are_refused_as_json(tmp_path):
    csv = _copy(V1_PULSE, tmp_path / "g", "run")
    text = csv.with_suffix(".json").read_text()
    for bad in ("NaN", "Infinity", "1e999"):
        csv.with_suffix(".json").write_text(text.replace('"t_go_s": -0.001', f'"t_go_s": {bad}'))
        with pytest.raises(RecordingError, match="unreadable JSON .*not a finite number"):
            recordings.load(csv)
