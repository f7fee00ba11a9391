"""A recording checked against its own rig: every key of its metadata, then its samples.

Each key's type and range is in ``metadata.schema.json`` beside this module (a JSON Schema, draft 7, one
definition per ``schema_version``; ``docs/recording_format.md`` lists the same keys for people), whose limits
``$name`` are the recording's rig's (:func:`limits`): its tendons, ADC, DAQ rates, travel, speed and stream
set-point limit. What no schema can say is checked here (:func:`validate_meta`): the rig file kept in the
recording and its tendon count, the cable per step against the rig's, the stream's impulses, set-point counts
and their sha256. :func:`validate` checks the samples. Each problem is one :class:`RecordingError` line naming
the file and the key.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import re
import reprlib
from pathlib import Path
from typing import Any

import fastjsonschema
import numpy as np
import pandas as pd

from helpers import rigfile
from helpers.base.validate import is_int
from helpers.recordings.format import READ_VERSIONS, RecordingError, raw_columns
from helpers.rigfile.recorded import recording_rig

SCHEMA = Path(__file__).with_name("metadata.schema.json")
"""The metadata's JSON Schema (its ``$name`` values filled in by :func:`limits`)."""

TENDONS = {1: (1, 1), 2: (1, 1), 3: (2, rigfile.MAX_TENDONS), 4: (1, rigfile.MAX_TENDONS)}
"""The tendon counts each version holds (1 and 2: one tendon, the columns ``adc`` and ``steps``)."""

STREAM_AMP_ONE = 4096
"""A streamed run's impulse amplitudes are in units of 1/4096 and sum to exactly this (the board's 1.0)."""

STEPS_PER_S_PER_UNIT = 2.0**-16 / 16e-6
"""Steps per second of one stream set-point unit (2^-16 step per 16 us, ``firmware/PROTOCOL.md``)."""

RIG_TOLERANCE = 1e-4
"""A recording's cable per step (and a stream's set-point unit) is its rig's within this relative amount."""

SAMPLE_TIME_TOLERANCE = 0.1
"""Samples are one period of ``rate_hz`` apart or more (the board's timer; lost lines and overruns only add
periods): closer than this fraction of a period less is impossible."""


@functools.cache
def required_keys() -> tuple[str, ...]:
    """The top-level keys every recording's metadata holds (the schema's ``common`` ones)."""
    return tuple(json.loads(SCHEMA.read_text())["definitions"]["common"]["required"])


def _fail(path: Path, problem: str) -> RecordingError:
    return RecordingError(f"{path}: {problem}")


def limits(rig: rigfile.RigFile, n: int) -> dict[str, float]:
    """The schema's ``$name`` values for a recording of ``n`` tendons made on ``rig``.

    The ADC offset may lie a quarter of the ADC's range beyond either end (a fit's zero extrapolated outside
    the readable counts); a stream set-point is at most ``floor(2^20 / min_interval_us)`` board units (the
    firmware's limit: the fastest step interval, 1640 for the paper's 639 us); an impulse's delay at most 1 s
    on a board of one axis, 0.62 s on one of several.
    """
    d, hw = rigfile.derived(rig), rig.hardware
    margin = (d.adc_max + 1) / 4
    v_max = math.floor(2**20 / d.min_interval_us)
    return {
        "n": n, "offset_min": -margin, "offset_max": d.adc_max + margin, "setpoint_min": -v_max,
        "setpoint_max": v_max, "delay_max": 1_000_000 if n == 1 else 620_000, "rate_min": hw.daq_rate_min_hz,
        "rate_max": hw.daq_rate_max_hz, "position_min": -max(d.release_steps),
        "position_max": max(d.travel_steps), "speed_max": hw.speed_limit_mm_s, "travel_mm": hw.travel_mm,
    }  # fmt: skip


@functools.lru_cache(maxsize=32)
def _validator(version: int, values: tuple[tuple[str, float], ...]) -> Any:
    """The compiled schema of ``version``, ``values`` filled in (a quoted ``"$name"`` becomes the number)."""
    named = dict(values)

    def fill(m: re.Match) -> str:
        if m[2] not in named:
            return m[0]
        value = named[m[2]]
        return json.dumps(value) if m[1] else f"{value:g}" if isinstance(value, float) else str(value)

    text = re.sub(r'(")?\$([a-z_]+)\b(?(1)")', fill, SCHEMA.read_text())
    schema = {**json.loads(text), "$ref": f"#/definitions/version_{version}"}
    return fastjsonschema.compile(schema)


def _schema_problem(exc: fastjsonschema.JsonSchemaValueException) -> str:
    """One line naming the key: what is missing, or what was expected and what the file holds."""
    key = exc.name.removeprefix("data").removeprefix(".")
    if exc.rule == "required":
        missing = next(k for k in exc.rule_definition if k not in exc.value)
        return f"{key + '.' if key else ''}{missing}: missing"
    what = exc.definition.get("description") or f"{exc.rule} {exc.rule_definition!r}"
    return f"{key}: expected {what}, got {reprlib.repr(exc.value)}"


def validate_meta(meta: Any, path: Path) -> None:
    """Check every key of the contract for its type and range; raise :class:`RecordingError` naming it.

    In order: the version; the rig file kept in the recording (version 1: the paper's) and the tendon count;
    every key against the schema with this rig's limits; what ties keys together (:func:`_check_together`).
    """
    if not isinstance(meta, dict):
        raise _fail(path, f"metadata is not a JSON object (got {type(meta).__name__})")
    version = meta.get("schema_version")
    if not is_int(version) or version not in READ_VERSIONS:
        raise _fail(path, f"schema_version: unknown {version!r} (this code reads {READ_VERSIONS})")
    if version >= 2 and "rig" not in meta:
        raise _fail(path, f"rig: missing (a recording of schema_version {version} keeps its rig file)")
    try:
        rig = recording_rig(meta)
    except rigfile.RigFileError as exc:
        raise _fail(path, str(exc).splitlines()[0].removeprefix("recording: ")) from None
    low, high = TENDONS[version]
    if version >= 3 and "tendons" not in meta:
        raise _fail(path, "tendons: missing")
    n = meta["tendons"] if version >= 3 else 1
    if not is_int(n) or not low <= n <= high:
        raise _fail(path, f"tendons: expected an integer {low}-{high}, got {reprlib.repr(n)}")
    if rig.n_tendons != n:
        raise _fail(path, f"tendons: {n}, but the rig file has {rig.n_tendons}")
    try:
        _validator(version, tuple(limits(rig, n).items()))(meta)
    except fastjsonschema.JsonSchemaValueException as exc:
        raise _fail(path, _schema_problem(exc)) from None
    _check_together(meta, rig, n, path)


def _increasing(values: list[int]) -> bool:
    return bool(np.all(np.diff(values) > 0))


def _check_together(meta: dict[str, Any], rig: rigfile.RigFile, n: int, path: Path) -> None:
    """What ties keys together: the cable per step is the rig's; a stream's impulses, counts and sha256."""
    rig_mm = rigfile.derived(rig).mm_per_step
    sc = meta["scenario"]
    per_tendon = [("calibration.mm_per_step", meta["calibration"]["mm_per_step"], 1.0)]
    stream = sc.get("stream") if sc["kind"] == "stream" else None
    if stream is not None and "setpoint_unit_mm_s" in stream:
        per_tendon.append(
            ("scenario.stream.setpoint_unit_mm_s", stream["setpoint_unit_mm_s"], STEPS_PER_S_PER_UNIT)
        )
    for key, values, scale in per_tendon:
        for i, (got, mm) in enumerate(zip(np.atleast_1d(values), rig_mm, strict=True)):
            if abs(got / (mm * scale) - 1) > RIG_TOLERANCE:
                raise _fail(
                    path, f"{key}: {got:g} for tendon {i + 1}, but its rig file makes it {mm * scale:g}"
                )
    for key in ("shaper", "shaper_down"):
        if isinstance(sc.get(key), dict) and len(sc[key]["amplitudes"]) != len(sc[key]["times"]):
            raise _fail(path, f"scenario.{key}: amplitudes and times must pair up")
    if stream is not None:
        _check_stream(stream, n if meta["schema_version"] >= 3 else 0, path)


def _check_stream(stream: dict[str, Any], n: int, path: Path) -> None:
    """The stream's impulses, set-point counts and sha256 (``n`` tendons of ``tendon_setpoints``, 0: none)."""
    amps, delays = stream["impulses"]["amplitudes"], stream["impulses"]["delays_us"]
    if len(amps) != len(delays):
        raise _fail(path, "scenario.stream.impulses: amplitudes and delays_us must pair up")
    if sum(amps) != STREAM_AMP_ONE:
        raise _fail(path, f"scenario.stream.impulses.amplitudes: sum to {sum(amps)}, not {STREAM_AMP_ONE}")
    if min(amps) < 0 and not stream["impulses"].get("allow_negative", False):
        raise _fail(path, "scenario.stream.impulses.amplitudes: negative, but allow_negative is not true")
    if delays[0] != 0 or not _increasing(delays):
        raise _fail(path, "scenario.stream.impulses.delays_us: expected 0 first, then increasing")
    rows = stream["tendon_setpoints"] if n else [stream["setpoints"]]
    count = stream["n_setpoints"]
    if any(len(x) != count for x in (stream["setpoints"], stream["periods"], *rows)):
        raise _fail(path, f"scenario.stream.n_setpoints: {count} does not match the set-points and periods")
    if rows[0] != stream["setpoints"]:
        raise _fail(path, "scenario.stream.setpoints: not tendon 1's tendon_setpoints")
    if not _increasing(stream["periods"]):
        raise _fail(path, "scenario.stream.periods: expected increasing periods")
    digest = hashlib.sha256(np.asarray(rows, dtype="<i2").T.tobytes()).hexdigest()
    if digest != stream["setpoints_sha256"]:
        raise _fail(
            path, f"scenario.stream.setpoints_sha256: not the set-points' (theirs is {digest[:12]}...)"
        )


def _first(bad: np.ndarray) -> int | None:
    """The index of the first true value, or None."""
    return int(np.argmax(bad)) if np.any(bad) else None


def validate(frame: pd.DataFrame, meta: dict[str, Any], path: Path) -> None:
    """Check the samples against the metadata and the rig; raise :class:`RecordingError` naming the problem.

    The frame is the reader's (:func:`helpers.recordings.load`): its columns are the header's, checked there
    to be exactly the raw columns, and int64 (anything else is an unreadable CSV). Checks: ``counts.samples``
    rows; ``seq`` strictly increases and its gaps add up to no more than the metadata's ``counts.dropped``;
    ``t_us`` strictly increases; and, whatever the checksum, nothing the rig cannot produce: samples closer
    than the stated rate, an ADC reading outside the ADC's range, a step count beyond its axis's travel (its
    release below position 0 and its travel above it together: the most a count can change from the
    recording's start) or changing faster than the rig's step-rate cap.
    """
    if meta["counts"]["samples"] != len(frame):
        raise _fail(path, f"counts.samples says {meta['counts']['samples']} rows, the CSV has {len(frame)}")
    seq, t_us = frame["seq"].to_numpy(np.int64), frame["t_us"].to_numpy(np.int64)
    dseq, dt = np.diff(seq), np.diff(t_us)
    if (i := _first(dseq <= 0)) is not None:
        raise _fail(path, f"seq does not increase at row {i + 1} ({seq[i]} then {seq[i + 1]})")
    gaps, admitted = int(np.sum(dseq - 1)), int(meta["counts"].get("dropped", 0))
    if gaps > admitted:
        raise _fail(path, f"gap in seq: {gaps} samples missing but the metadata admits {admitted} dropped")
    if (i := _first(dt <= 0)) is not None:
        raise _fail(path, f"non-monotonic time at row {i + 1} (t_us {t_us[i]} then {t_us[i + 1]})")
    period_us = 1e6 / float(meta["rate_hz"])
    if (i := _first(dt < (1.0 - SAMPLE_TIME_TOLERANCE) * period_us)) is not None:
        raise _fail(
            path,
            f"t_us: samples {dt[i]} us apart at row {i + 1}, less than the period of rate_hz "
            f"{meta['rate_hz']} ({period_us:g} us): not what the board records",
        )
    rig = recording_rig(meta)
    d, max_rate = rigfile.derived(rig), float(rig.hardware.step_rate_cap_hz)
    for col in raw_columns(meta):
        values = frame[col].to_numpy(np.int64)
        if col.startswith("adc") and len(values) and (values.min() < 0 or values.max() > d.adc_max):
            raise _fail(path, f"{col} outside 0-{d.adc_max}")
        if not col.startswith("steps") or len(values) < 2:
            continue
        axis = int(col[len("steps_") :] or 0)  # versions 1-2: steps, axis 0
        travel = d.travel_steps[axis] + d.release_steps[axis]
        if (i := _first(np.abs(values) > travel)) is not None:
            raise _fail(path, f"{col}: {values[i]} at row {i} is beyond the travel of {travel} steps")
        if (i := _first(np.abs(np.diff(values)) > np.floor(max_rate * dt * 1e-6) + 1)) is not None:
            step = values[i + 1] - values[i]
            raise _fail(path, f"{col}: changes by {step} in {dt[i]} us at row {i + 1}, faster than the "
                              f"stepper's {max_rate:g} steps/s")  # fmt: skip
