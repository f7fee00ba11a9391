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
import reprlib
from collections.abc import Callable
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
    TIP_COLUMNS,
    TIP_MM_COLUMNS,
    recorded_columns,
    tendon_count,
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
    def tendons(self) -> int:
        """Number of tendons recorded (1 for versions 1 and 2)."""
        return tendon_count(self.meta)

    def derive(self) -> Recording:
        """Add the derived columns from the metadata's calibration; return ``self``."""
        self.frame = derive_columns(self.frame, self.meta)
        return self

    def __repr__(self) -> str:
        return f"Recording({self.name!r}, {len(self.frame)} samples, {self.status})"


def derive_columns(frame: pd.DataFrame, meta: dict[str, Any]) -> pd.DataFrame:
    """Return the raw columns of ``frame`` with the derived ones, computed from ``meta``'s calibration.

    ``t_s``; every tendon's ``tension_n`` and ``cable_mm`` (``tension_n_i`` and ``cable_mm_i`` for several
    tendons, whose calibration holds one number per tendon); the tip's ``tip_x_mm`` .. where it was recorded.
    """
    out = frame.loc[:, list(raw_columns(meta))].copy()
    t = out["t_us"].to_numpy(dtype=np.int64)
    out["t_s"] = (t - t[0]) * 1e-6 if len(t) else np.zeros(0)
    n = tendon_count(meta)
    suffixes = [""] if n == 1 else [f"_{i}" for i in range(n)]
    cal = meta["calibration"]
    npc, offset, mm = (np.atleast_1d(cal[k]) for k in ("newtons_per_count", "offset_counts", "mm_per_step"))
    for i, s in enumerate(suffixes):
        out[f"tension_n{s}"] = counts_to_newtons(out[f"adc{s}"].to_numpy(), npc[i], offset[i])
    for i, s in enumerate(suffixes):
        out[f"cable_mm{s}"] = out[f"steps{s}"].to_numpy(float) * float(mm[i])
    for um, tip_mm in zip(TIP_COLUMNS, TIP_MM_COLUMNS, strict=True):
        if um in out:
            out[tip_mm] = out[um].to_numpy(float) * 1e-3
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


Kind = tuple[Callable[[Any], bool], str]
"""A check of one value and what it expects (for the message: ``<key>: expected <what>, got <value>``)."""

OBJECT: Kind = (lambda v: isinstance(v, dict), "an object")
TEXT: Kind = (lambda v: isinstance(v, str), "text")
INTEGER: Kind = (is_int, "an integer")
COUNT: Kind = (lambda v: is_int(v) and v >= 0, "an integer >= 0")
NUMBER: Kind = (is_finite_number, "a finite number")
POSITIVE: Kind = (lambda v: is_finite_number(v) and v > 0, "a finite number > 0")
INTEGERS: Kind = (lambda v: isinstance(v, list) and all(is_int(x) for x in v), "a list of integers")
SHA256: Kind = (lambda v: isinstance(v, str) and _SHA256.match(v) is not None, "64 lower-case hex digits")
LINES: Kind = (lambda v: isinstance(v, list) and all(isinstance(x, str) for x in v), "a list of notice lines")
TENDONS: Kind = (lambda v: is_int(v) and 2 <= v <= rigfile.MAX_TENDONS, f"an integer 2-{rigfile.MAX_TENDONS}")
DAQ_RATES = f"{DAQ_RATE_MIN_HZ}-{DAQ_RATE_MAX_HZ}"
RATE: Kind = (lambda v: is_int(v) and DAQ_RATE_MIN_HZ <= v <= DAQ_RATE_MAX_HZ, f"an integer in {DAQ_RATES}")


def _one_of(names: tuple[str, ...]) -> Kind:
    return (lambda v: v in names, f"one of {', '.join(names)}")


def _per_tendon(n: int, number: Kind) -> Kind:
    return (
        lambda v: isinstance(v, list) and len(v) == n and all(number[0](x) for x in v),
        f"a list of {n} {'positive ' if number is POSITIVE else ''}finite numbers (one per tendon)",
    )


def _flat_object(value: Any) -> bool:
    return isinstance(value, dict) and not any(isinstance(v, dict | list) for v in value.values())


METADATA: tuple[tuple[str, Kind], ...] = (
    ("status", _one_of(STATUSES)),
    ("abort_reason?", (lambda v: v is None or isinstance(v, str), "text or null")),
    ("csv_sha256", SHA256),
    ("calibration", OBJECT),
    ("rate_hz", RATE),
    ("counts", OBJECT),
    *((f"counts.{key}?", COUNT) for key in ("dropped", "corrupted", "overruns")),
    ("counts.samples", COUNT),
    ("source", OBJECT),
    ("source.kind", _one_of(SOURCES)),
    ("source.parameters?", (_flat_object, "an object of flat values")),
    ("scenario", OBJECT),
    ("scenario.kind", TEXT),
    ("scenario.repetition?", INTEGER),
)
"""The keys every recording's metadata is checked for, in order: ``(dotted key, kind)``; a key ending in
``?`` may be absent, and a key's parent is an object checked by an earlier row."""

REQUIRED_META = ("schema_version", *(key for key, _ in METADATA if "." not in key and not key.endswith("?")))
"""The top-level keys every recording's metadata holds: the version and the rows of :data:`METADATA` that
may not be absent."""

PULSE: tuple[tuple[str, Kind], ...] = (
    ("scenario.system", TEXT),
    ("scenario.v_in_mm_s", POSITIVE),
    ("scenario.x_f_mm", POSITIVE),
)
"""The keys of a pulse's ``scenario`` (``kind`` ``"pulse"``)."""

STREAM: tuple[tuple[str, Kind], ...] = (
    ("scenario.stream", OBJECT),
    ("scenario.stream.rate_hz", POSITIVE),
    ("scenario.stream.impulses", OBJECT),
    ("scenario.stream.impulses.amplitudes", INTEGERS),
    ("scenario.stream.impulses.delays_us", INTEGERS),
    ("scenario.stream.setpoints", INTEGERS),
    ("scenario.stream.periods", INTEGERS),
    ("scenario.stream.n_setpoints", INTEGER),
    ("scenario.stream.setpoints_sha256", SHA256),
    ("scenario.stream.fifo_full", COUNT),
    ("scenario.stream.underruns", COUNT),
    ("scenario.stream.clamps", OBJECT),
    ("scenario.stream.clamps.speed", COUNT),
    ("scenario.stream.clamps.travel", COUNT),
    ("scenario.stream.notices", LINES),
)
"""The keys of a streamed run's ``scenario`` (``kind`` ``"stream"``; ``docs/recording_format.md``)."""


CALIBRATION = {"newtons_per_count": POSITIVE, "offset_counts": NUMBER, "mm_per_step": POSITIVE}
"""The calibration's keys, each one number of its kind for one tendon (versions 1 and 2)."""

TIP: Kind = (OBJECT[0], "an object (the twin-provided tip columns' origin)")


def _calibration_keys(n: int) -> tuple[tuple[str, Kind], ...]:
    """The calibration of a recording of ``n`` tendons: a list of ``n`` numbers per key for several."""
    return tuple(
        (f"calibration.{key}", kind if n == 1 else _per_tendon(n, kind)) for key, kind in CALIBRATION.items()
    )


def check_keys(meta: dict[str, Any], keys: tuple[tuple[str, Kind], ...], path: Path) -> None:
    """Check each ``(dotted key, kind)`` of ``keys`` in order; raise :class:`RecordingError` for the first.

    The first key that is missing (unless it ends in ``?``) or not of its kind: one line naming it.
    """
    for key, (accept, what) in keys:
        name = key.removesuffix("?")
        *parents, last = name.split(".")
        section = meta
        for part in parents:  # objects: checked by earlier rows
            section = section[part]
        if last not in section:
            if key.endswith("?"):
                continue
            raise _fail(path, f"{name}: missing")
        if not accept(section[last]):
            raise _fail(path, f"{name}: expected {what}, got {reprlib.repr(section[last])}")


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
    check_keys(meta, METADATA, path)
    if version == TENDON_SCHEMA_VERSION:
        check_keys(meta, (("tendons", TENDONS), ("tip?", TIP)), path)
        if "rig" not in meta:
            raise _fail(path, "rig: missing (a recording of several tendons keeps its rig file)")
    check_keys(meta, _calibration_keys(tendon_count(meta)), path)
    problem = validate_rig_section(meta, path)
    if problem is not None:
        raise _fail(path, problem)
    if version == TENDON_SCHEMA_VERSION and recording_rig(meta).n_tendons != meta["tendons"]:
        raise _fail(path, f"tendons: {meta['tendons']}, but the rig file has {recording_rig(meta).n_tendons}")
    kind = meta["scenario"]["kind"]
    check_keys(meta, PULSE if kind == "pulse" else STREAM if kind == "stream" else (), path)
    if kind == "stream":
        _check_stream(meta["scenario"]["stream"], path)


def _increasing(values: list[int]) -> bool:
    return all(b > a for a, b in zip(values, values[1:], strict=False))


def _check_stream(stream: dict[str, Any], path: Path) -> None:
    """What ties the keys of ``scenario.stream`` together (their kinds checked by :data:`STREAM`)."""
    amps, delays = stream["impulses"]["amplitudes"], stream["impulses"]["delays_us"]
    if not amps or len(amps) != len(delays):
        raise _fail(path, "scenario.stream.impulses: amplitudes and delays_us must pair up (at least one)")
    if sum(amps) != STREAM_AMP_ONE:
        raise _fail(path, f"scenario.stream.impulses.amplitudes: sum to {sum(amps)}, not {STREAM_AMP_ONE}")
    if delays[0] != 0 or not _increasing(delays):
        raise _fail(path, "scenario.stream.impulses.delays_us: expected 0 first, then increasing")
    n = stream["n_setpoints"]
    if not n == len(stream["setpoints"]) == len(stream["periods"]):
        raise _fail(path, f"scenario.stream.n_setpoints: {n} does not match the set-points and periods")
    if not _increasing(stream["periods"]):
        raise _fail(path, "scenario.stream.periods: expected increasing periods")


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
    dseq = np.diff(seq)
    if np.any(dseq <= 0):
        i = int(np.argmax(dseq <= 0))
        raise _fail(path, f"seq does not increase at row {i + 1} ({seq[i]} then {seq[i + 1]})")
    gaps = int(np.sum(dseq - 1))
    admitted = int(meta.get("counts", {}).get("dropped", 0))
    if gaps > admitted:
        raise _fail(path, f"gap in seq: {gaps} samples missing but the metadata admits {admitted} dropped")
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
    made_on = rigfile.default_rig().hash if section is None else section.get("hash")
    if made_on == HW_RIG.hash:
        return LIMITS.max_position_steps, LIMITS.max_step_rate_hz
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
