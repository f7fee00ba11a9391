"""What a recording is: the raw columns, the metadata (checked field by field), the derived columns.

The CSV holds the raw columns exactly as the DAQ board reports them: ``seq``, ``t_us`` (device microseconds,
unwrapped), ``adc`` (0-1023 counts) and ``steps`` (signed motor position counted by the DAQ board). The
derived columns are computed on load from the metadata and never stored:

- ``t_s``: seconds from the first sample;
- ``tension_n``: ``(adc - offset_counts) * newtons_per_count`` (calibration in the metadata);
- ``cable_mm``: ``steps * mm_per_step``.

The JSON metadata (``SCHEMA_VERSION`` 2; 1 is read too) is described key by key in
``docs/recording_format.md``;
:func:`validate_meta` checks each key's type and range and :func:`validate` the samples against it, raising
one :class:`RecordingError` that names the file, the field and the problem.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from helpers import rigfile
from helpers.base.validate import is_finite_number, is_int
from helpers.paper.hardware import ADC_MAX, DAQ_RATE_MAX_HZ, DAQ_RATE_MIN_HZ, LIMITS
from helpers.paper.hardware import RIG as HW_RIG
from helpers.recordings.tendons import (
    TENDON_SCHEMA_VERSION,
    derive_tendon_columns,
    recorded_columns,
    tendon_count,
    tendon_meta_problem,
)
from helpers.rigfile.recorded import recording_rig, validate_rig_section

SCHEMA_VERSION = 2
"""Version of the metadata layout new recordings get (2: with ``rig``, the rig file)."""

READ_VERSIONS = (1, 2, TENDON_SCHEMA_VERSION)
"""Versions :func:`helpers.recordings.load` reads (1: before rig files, the paper's rig; 3: several tendons,
:mod:`helpers.recordings.tendons`); others refused."""

RAW_COLUMNS = ("seq", "t_us", "adc", "steps")
"""The CSV's columns, in order."""

DERIVED_COLUMNS = ("t_s", "tension_n", "cable_mm")
"""Columns computed on load."""

SOURCES = ("hardware", "virtual-rig")
"""The vocabulary of ``source.kind``."""

STATUSES = ("complete", "aborted", "deviated")
"""The vocabulary of ``status``: ``deviated`` is a run that went to its end but whose motion differed from
its command (a stream whose host fell behind, or whose shaped motion the board clamped; ``deviation`` says
how)."""

REQUIRED_META = (
    "schema_version",
    "source",
    "scenario",
    "calibration",
    "rate_hz",
    "status",
    "counts",
    "csv_sha256",
)

COUNT_KEYS = ("samples", "dropped", "corrupted", "overruns")

STREAM_AMP_ONE = 4096
"""A streamed run's impulse amplitudes are in units of 1/4096 and sum to exactly this (the board's 1.0)."""

_SHA256 = re.compile(r"[0-9a-f]{64}\Z")


class RecordingError(ValueError):
    """A recording could not be loaded or saved; the message names the file, the field and the problem."""


@dataclass
class Recording:
    """One run: the samples (raw + derived columns) and the metadata.

    Attributes
    ----------
    frame : pandas.DataFrame
        Columns ``seq``, ``t_us``, ``adc``, ``steps`` (int64) and, after :meth:`derive`, ``t_s``,
        ``tension_n``, ``cable_mm``.
    meta : dict
        The JSON metadata (see the module docstring).
    path : pathlib.Path or None
        The CSV's path once saved or loaded.
    """

    frame: pd.DataFrame
    meta: dict[str, Any]
    path: Path | None = None

    @property
    def name(self) -> str:
        """The file stem, or ``"<unsaved>"``."""
        return self.path.stem if self.path is not None else "<unsaved>"

    @property
    def status(self) -> str:
        """``"complete"``, ``"aborted"`` or ``"deviated"``."""
        return str(self.meta.get("status"))

    @property
    def is_virtual(self) -> bool:
        """True when the data come from the virtual rig (simulation, not a measurement)."""
        return self.meta.get("source", {}).get("kind") == "virtual-rig"

    @property
    def tendons(self) -> int:
        """Number of tendons recorded (1 for versions 1 and 2)."""
        return tendon_count(self.meta)

    def derive(self) -> Recording:
        """Add the derived columns from the metadata's calibration; return ``self``."""
        if self.tendons > 1:
            self.frame = derive_tendon_columns(self.frame, self.meta)
        else:
            self.frame = derive_columns(self.frame, self.meta["calibration"])
        return self

    def __repr__(self) -> str:
        return f"Recording({self.name!r}, {len(self.frame)} samples, {self.status})"


def derive_columns(frame: pd.DataFrame, calibration: dict[str, Any]) -> pd.DataFrame:
    """Return ``frame`` with ``t_s``, ``tension_n`` and ``cable_mm`` computed from ``calibration``.

    Parameters
    ----------
    frame : pandas.DataFrame
        The raw columns.
    calibration : dict
        ``newtons_per_count``, ``offset_counts``, ``mm_per_step``.

    Returns
    -------
    pandas.DataFrame
        A copy with the derived columns.
    """
    out = frame.loc[:, list(RAW_COLUMNS)].copy()
    t = out["t_us"].to_numpy(dtype=np.int64)
    out["t_s"] = (t - t[0]) * 1e-6 if len(t) else np.zeros(0)
    out["tension_n"] = counts_to_newtons(
        out["adc"].to_numpy(), calibration["newtons_per_count"], calibration["offset_counts"]
    )
    out["cable_mm"] = out["steps"].to_numpy(float) * float(calibration["mm_per_step"])
    return out


def counts_to_newtons(adc: np.ndarray, newtons_per_count: float, offset_counts: float) -> np.ndarray:
    """Tension in N from ADC counts, ``(adc - offset_counts) * newtons_per_count`` (load-cell calibration)."""
    return (np.asarray(adc, dtype=float) - float(offset_counts)) * float(newtons_per_count)


def raw_columns(meta: dict[str, Any]) -> tuple[str, ...]:
    """The CSV's columns of a recording with this metadata (several tendons: ``adc_i``, ``steps_i``)."""
    n = tendon_count(meta)
    return RAW_COLUMNS if n == 1 else recorded_columns(meta)


def empty_frame() -> pd.DataFrame:
    """Return a frame with the raw columns and no rows."""
    return pd.DataFrame({c: np.zeros(0, dtype=np.int64) for c in RAW_COLUMNS})


def frame_from_rows(rows: list[tuple[int, int, int, int]] | np.ndarray) -> pd.DataFrame:
    """Return the raw frame of ``(seq, t_us, adc, steps)`` rows."""
    arr = np.asarray(rows, dtype=np.int64).reshape(-1, 4)
    return pd.DataFrame({c: arr[:, i] for i, c in enumerate(RAW_COLUMNS)})


# -- metadata, field by field ------------------------------------------------------------------------------
def _fail(path: Path, problem: str) -> RecordingError:
    return RecordingError(f"{path}: {problem}")


def _section(meta: dict[str, Any], key: str, path: Path, where: str = "") -> dict[str, Any]:
    if key not in meta:
        raise _fail(path, f"{where}{key}: missing")
    value = meta[key]
    if not isinstance(value, dict):
        raise _fail(path, f"{key}: expected an object, got {type(value).__name__}")
    return value


def _number(section: dict[str, Any], key: str, where: str, path: Path, positive: bool = False) -> float:
    if key not in section:
        raise _fail(path, f"{where}.{key}: missing")
    value = section[key]
    if not is_finite_number(value):
        raise _fail(path, f"{where}.{key}: expected a finite number, got {value!r}")
    if positive and value <= 0:
        raise _fail(path, f"{where}.{key}: must be > 0, got {value!r}")
    return float(value)


def validate_meta(meta: Any, path: Path) -> None:
    """Check every key of the contract for its type and range; raise :class:`RecordingError` naming it.

    Parameters
    ----------
    meta : object
        The parsed JSON.
    path : pathlib.Path
        For the messages.
    """
    if not isinstance(meta, dict):
        raise _fail(path, f"metadata is not a JSON object (got {type(meta).__name__})")
    version = meta.get("schema_version")
    if version not in READ_VERSIONS or not is_int(version):
        raise _fail(path, f"schema_version: unknown {version!r} (this code reads {READ_VERSIONS})")
    missing = [k for k in REQUIRED_META if k not in meta]
    if missing:
        raise _fail(path, f"metadata lacks {', '.join(missing)}")
    if meta["status"] not in STATUSES:
        raise _fail(path, f"status: {meta['status']!r} is not one of {', '.join(STATUSES)}")
    reason = meta.get("abort_reason")
    if reason is not None and not isinstance(reason, str):
        raise _fail(path, f"abort_reason: expected text or null, got {type(reason).__name__}")
    sha = meta["csv_sha256"]
    if not (isinstance(sha, str) and _SHA256.match(sha)):
        raise _fail(path, f"csv_sha256: expected 64 lower-case hex digits, got {str(sha)[:20]!r}")
    cal = _section(meta, "calibration", path)
    if version == TENDON_SCHEMA_VERSION:
        problem = tendon_meta_problem(meta)
        if problem is not None:
            raise _fail(path, problem)
    else:
        _number(cal, "newtons_per_count", "calibration", path, positive=True)
        _number(cal, "offset_counts", "calibration", path)
        _number(cal, "mm_per_step", "calibration", path, positive=True)
    rate = meta["rate_hz"]
    if not (is_int(rate) and DAQ_RATE_MIN_HZ <= rate <= DAQ_RATE_MAX_HZ):
        span = f"{DAQ_RATE_MIN_HZ}-{DAQ_RATE_MAX_HZ}"
        raise _fail(path, f"rate_hz: expected an integer in {span}, got {rate!r}")
    counts = _section(meta, "counts", path)
    for key in COUNT_KEYS:
        if key in counts and not (is_int(counts[key]) and counts[key] >= 0):
            raise _fail(path, f"counts.{key}: expected an integer >= 0, got {counts[key]!r}")
    if "samples" not in counts:
        raise _fail(path, "counts.samples: missing")
    source = _section(meta, "source", path)
    if source.get("kind") not in SOURCES:
        raise _fail(path, f"source.kind: {source.get('kind')!r} is not one of {', '.join(SOURCES)}")
    if "parameters" in source:
        params = source["parameters"]
        if not isinstance(params, dict) or any(isinstance(v, dict | list) for v in params.values()):
            raise _fail(path, "source.parameters: expected an object of flat values")
    problem = validate_rig_section(meta, path)
    if problem is not None:
        raise _fail(path, problem)
    if version == TENDON_SCHEMA_VERSION and recording_rig(meta).n_tendons != meta["tendons"]:
        raise _fail(path, f"tendons: {meta['tendons']}, but the rig file has {recording_rig(meta).n_tendons}")
    scenario = _section(meta, "scenario", path)
    if not isinstance(scenario.get("kind"), str):
        raise _fail(path, f"scenario.kind: expected text, got {scenario.get('kind')!r}")
    if scenario["kind"] == "pulse":
        if not isinstance(scenario.get("system"), str):
            raise _fail(path, f"scenario.system: expected text, got {scenario.get('system')!r}")
        _number(scenario, "v_in_mm_s", "scenario", path, positive=True)
        _number(scenario, "x_f_mm", "scenario", path, positive=True)
    if "repetition" in scenario and not is_int(scenario["repetition"]):
        raise _fail(path, f"scenario.repetition: expected an integer, got {scenario['repetition']!r}")
    if scenario["kind"] == "stream":
        _validate_stream(scenario, path)


def _int_list(section: dict[str, Any], key: str, where: str, path: Path) -> list[int]:
    value = section.get(key)
    if not isinstance(value, list) or not all(is_int(x) for x in value):
        raise _fail(path, f"{where}.{key}: expected a list of integers")
    return value


def _validate_stream(scenario: dict[str, Any], path: Path) -> None:
    """``scenario.stream`` of a streamed run (``docs/recording_format.md``)."""
    stream = _section(scenario, "stream", path, "scenario.")
    _number(stream, "rate_hz", "scenario.stream", path, positive=True)
    impulses = stream.get("impulses")
    if not isinstance(impulses, dict):
        raise _fail(path, "scenario.stream.impulses: expected an object")
    amps = _int_list(impulses, "amplitudes", "scenario.stream.impulses", path)
    delays = _int_list(impulses, "delays_us", "scenario.stream.impulses", path)
    if not amps or len(amps) != len(delays):
        raise _fail(path, "scenario.stream.impulses: amplitudes and delays_us must pair up (at least one)")
    if sum(amps) != STREAM_AMP_ONE:
        raise _fail(path, f"scenario.stream.impulses.amplitudes: sum to {sum(amps)}, not {STREAM_AMP_ONE}")
    if delays[0] != 0 or any(b <= a for a, b in zip(delays, delays[1:], strict=False)):
        raise _fail(path, "scenario.stream.impulses.delays_us: expected 0 first, then increasing")
    setpoints = _int_list(stream, "setpoints", "scenario.stream", path)
    periods = _int_list(stream, "periods", "scenario.stream", path)
    n = stream.get("n_setpoints")
    if not (is_int(n) and n == len(setpoints) == len(periods)):
        raise _fail(
            path, f"scenario.stream.n_setpoints: {n!r} does not match the set-points and periods listed"
        )
    if any(b <= a for a, b in zip(periods, periods[1:], strict=False)):
        raise _fail(path, "scenario.stream.periods: expected increasing periods")
    sha = stream.get("setpoints_sha256")
    if not (isinstance(sha, str) and _SHA256.match(sha)):
        raise _fail(path, "scenario.stream.setpoints_sha256: expected 64 lower-case hex digits")
    for key in ("fifo_full", "underruns"):
        if not (is_int(stream.get(key)) and stream[key] >= 0):
            raise _fail(path, f"scenario.stream.{key}: expected an integer >= 0, got {stream.get(key)!r}")
    clamps = stream.get("clamps")
    if not (
        isinstance(clamps, dict)
        and all(is_int(clamps.get(k)) and clamps[k] >= 0 for k in ("speed", "travel"))
    ):
        raise _fail(path, "scenario.stream.clamps: expected integers >= 0 for speed and travel")
    notices = stream.get("notices")
    if not (isinstance(notices, list) and all(isinstance(x, str) for x in notices)):
        raise _fail(path, "scenario.stream.notices: expected a list of notice lines")


def validate(frame: pd.DataFrame, meta: dict[str, Any], path: Path) -> None:
    """Check the samples against the metadata; raise :class:`RecordingError` naming the problem.

    Checks: the raw columns are present and integer; ``counts.samples`` rows; ``seq`` strictly increases and
    its gaps add up to no more than the metadata's ``counts.dropped``; ``t_us`` strictly increases; ``adc`` is
    within 0-1023; and nothing a rig cannot produce (:func:`_check_physics`), whatever the checksum: samples
    closer than the stated rate, a step count beyond the travel or changing faster than the step rate.
    """
    columns = raw_columns(meta)
    for col in columns:
        if col not in frame.columns:
            raise _fail(path, f"missing column {col!r}")
        if len(frame) and not pd.api.types.is_integer_dtype(frame[col]):
            raise _fail(path, f"column {col!r} is not integer")
    expected = meta.get("counts", {}).get("samples")
    if expected is not None and expected != len(frame):
        raise _fail(path, f"counts.samples says {expected} rows, the CSV has {len(frame)}")
    seq = frame["seq"].to_numpy(np.int64)
    t_us = frame["t_us"].to_numpy(np.int64)
    if len(seq) > 1:
        dseq = np.diff(seq)
        if np.any(dseq <= 0):
            i = int(np.argmax(dseq <= 0))
            raise _fail(path, f"seq does not increase at row {i + 1} ({seq[i]} then {seq[i + 1]})")
        gaps = int(np.sum(dseq - 1))
        admitted = int(meta.get("counts", {}).get("dropped", 0))
        if gaps > admitted:
            raise _fail(
                path, f"gap in seq: {gaps} samples missing but the metadata admits {admitted} dropped"
            )
        dt = np.diff(t_us)
        if np.any(dt <= 0):
            i = int(np.argmax(dt <= 0))
            raise _fail(path, f"non-monotonic time at row {i + 1} (t_us {t_us[i]} then {t_us[i + 1]})")
    for col in (c for c in columns if c.startswith("adc")):
        adc = frame[col].to_numpy(np.int64)
        if len(adc) and (adc.min() < 0 or adc.max() > ADC_MAX):
            raise _fail(path, f"{col} outside 0-{ADC_MAX}")
    for col in (c for c in columns if c.startswith("steps")):
        _check_physics(frame, meta, path, col)


SAMPLE_TIME_TOLERANCE = 0.1
"""Samples are one period of ``rate_hz`` apart or more (the board's timer; lost lines and overruns only add
periods): closer than this fraction of a period less is impossible."""


def _rig_limits(meta: dict[str, Any]) -> tuple[int, float]:
    """Travel (steps) and step-rate cap (steps/s) of the rig a recording was made with (its ``rig``).

    The travel is the most a step count (from the recording's start) can change: an axis's release below
    position 0 and its travel above it together.

    The selected rig's limits when the recording carries the selected rig (or none: the paper's rig made
    it, and the paper's is selected); otherwise the kept rig file's, so that a recording made on another rig
    is checked against that rig, not this process's.
    """
    section = meta.get("rig")
    if section is None or section.get("hash") == HW_RIG.hash:
        if section is None and HW_RIG.hash != rigfile.default_rig().hash:
            rig = rigfile.default_rig()
        else:
            return LIMITS.max_position_steps, LIMITS.max_step_rate_hz
    else:
        rig = recording_rig(meta)
    d = rigfile.derived(rig)
    span = max(t + r for t, r in zip(d.travel_steps, d.release_steps, strict=True))
    return span, float(rig.hardware.step_rate_cap_hz)


def _check_physics(frame: pd.DataFrame, meta: dict[str, Any], path: Path, column: str = "steps") -> None:
    """Refuse contents no rig can produce, whatever the checksum says.

    Samples closer than the stated rate, a step count beyond the travel, or one that changes faster than the
    step rate allows.
    """
    if len(frame) < 2:
        return
    t_us = frame["t_us"].to_numpy(np.int64)
    steps = frame[column].to_numpy(np.int64)
    period_us = 1e6 / float(meta["rate_hz"])
    dt = np.diff(t_us)
    short = dt < (1.0 - SAMPLE_TIME_TOLERANCE) * period_us
    if np.any(short):
        i = int(np.argmax(short))
        raise _fail(
            path,
            f"t_us: samples {dt[i]} us apart at row {i + 1}, less than the period of rate_hz "
            f"{meta['rate_hz']} ({period_us:g} us): not what the board records",
        )
    travel, max_rate = _rig_limits(meta)
    if np.abs(steps).max() > travel:
        i = int(np.argmax(np.abs(steps) > travel))
        raise _fail(path, f"{column}: {steps[i]} at row {i} is beyond the travel of {travel} steps")
    allowed = np.floor(max_rate * dt * 1e-6) + 1  # steps possible between two samples
    jump = np.abs(np.diff(steps)) > allowed
    if np.any(jump):
        i = int(np.argmax(jump))
        raise _fail(
            path,
            f"{column}: changes by {steps[i + 1] - steps[i]} in {dt[i]} us at row {i + 1}, faster than the "
            f"stepper's {max_rate:g} steps/s",
        )
