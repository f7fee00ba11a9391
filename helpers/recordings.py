"""The recording format of ``data/`` (``docs/recording_format.md``): ``<name>.csv`` + ``<name>.json``.

The CSV holds the raw columns exactly as the DAQ board reports them: ``seq``, ``t_us`` (device microseconds,
unwrapped), ``adc`` (0-1023 counts) and ``steps`` (signed motor position counted by the DAQ board). The
derived columns are computed on load from the metadata and never stored:

- ``t_s``: seconds from the first sample;
- ``tension_n``: ``(adc - offset_counts) * newtons_per_count`` (calibration in the metadata);
- ``cable_mm``: ``steps * mm_per_step``.

The JSON metadata (``SCHEMA_VERSION`` 1) holds ``schema_version``, ``source`` (``{"kind": "hardware"}`` or
``{"kind": "virtual-rig", "version": ..., "parameters": {...}}``), ``scenario``, ``calibration``, ``rate_hz``,
``firmware``, ``started_utc``, ``status`` (``"complete"`` or ``"aborted"``) and ``abort_reason``, ``counts``
(``samples``, ``dropped``, ``corrupted``, ``overruns``) and ``csv_sha256``.

Saving is atomic (temporary file in the same folder, then ``os.replace``; CSV first, then JSON, so a JSON file
never points at a CSV that is not there). Loading validates and raises :class:`RecordingError`, one error type
whose message names the file and the problem.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from helpers.paths import DATA_DIR

SCHEMA_VERSION = 1
"""Version of the metadata layout; :func:`load` refuses any other."""

RAW_COLUMNS = ("seq", "t_us", "adc", "steps")
"""The CSV's columns, in order."""

DERIVED_COLUMNS = ("t_s", "tension_n", "cable_mm")
"""Columns computed on load."""

SOURCES = ("hardware", "virtual-rig")
STATUSES = ("complete", "aborted")
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


class RecordingError(ValueError):
    """A recording could not be loaded or saved; the message names the file and the problem."""


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
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def name(self) -> str:
        """The file stem, or ``"<unsaved>"``."""
        return self.path.stem if self.path is not None else "<unsaved>"

    @property
    def status(self) -> str:
        """``"complete"`` or ``"aborted"``."""
        return str(self.meta.get("status"))

    @property
    def is_virtual(self) -> bool:
        """True when the data come from the virtual rig (simulation, not a measurement)."""
        return self.meta.get("source", {}).get("kind") == "virtual-rig"

    def derive(self) -> Recording:
        """Add the derived columns from the metadata's calibration; return ``self``."""
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


def empty_frame() -> pd.DataFrame:
    """Return a frame with the raw columns and no rows."""
    return pd.DataFrame({c: np.zeros(0, dtype=np.int64) for c in RAW_COLUMNS})


def frame_from_rows(rows: list[tuple[int, int, int, int]] | np.ndarray) -> pd.DataFrame:
    """Return the raw frame of ``(seq, t_us, adc, steps)`` rows."""
    arr = np.asarray(rows, dtype=np.int64).reshape(-1, 4)
    return pd.DataFrame({c: arr[:, i] for i, c in enumerate(RAW_COLUMNS)})


def _csv_bytes(frame: pd.DataFrame) -> bytes:
    buf = io.StringIO()
    frame.loc[:, list(RAW_COLUMNS)].astype(np.int64).to_csv(buf, index=False, lineterminator="\n")
    return buf.getvalue().encode("ascii")


def _atomic_write(path: Path, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _clean(value: Any) -> Any:
    """Make metadata JSON-safe: numpy scalars to Python, tuples to lists, NaN refused."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, np.ndarray):
        return [_clean(v) for v in value.tolist()]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _csv_path(path: str | os.PathLike) -> Path:
    p = Path(path)
    return p.with_suffix(".csv") if p.suffix in ("", ".json") else p


def save(recording: Recording, path: str | os.PathLike | None = None) -> Path:
    """Write ``recording`` atomically as ``<path>.csv`` and ``<path>.json``; return the CSV path.

    Parameters
    ----------
    recording : Recording
        Its ``meta`` must hold the keys of ``REQUIRED_META`` except ``csv_sha256`` (filled in here).
    path : path-like, optional
        ``data/<group>/<name>.csv`` (the suffix may be omitted); defaults to ``recording.path``.

    Returns
    -------
    pathlib.Path
        The CSV's path; ``recording.path`` is set to it.
    """
    target = _csv_path(path if path is not None else recording.path or "")
    if target.name in ("", ".csv"):
        raise RecordingError("save: no path given for the recording")
    meta = dict(recording.meta)
    meta.setdefault("schema_version", SCHEMA_VERSION)
    missing = [k for k in REQUIRED_META if k not in meta and k != "csv_sha256"]
    if missing:
        raise RecordingError(f"{target}: metadata lacks {', '.join(missing)}")
    target.parent.mkdir(parents=True, exist_ok=True)
    data = _csv_bytes(recording.frame)
    meta["csv_sha256"] = hashlib.sha256(data).hexdigest()
    meta["counts"] = dict(meta["counts"], samples=int(len(recording.frame)))
    text = json.dumps(_clean(meta), indent=2, sort_keys=True, allow_nan=False) + "\n"
    _atomic_write(target, data)
    _atomic_write(target.with_suffix(".json"), text.encode("utf-8"))
    recording.meta = json.loads(text)
    recording.path = target
    return target


def _fail(path: Path, problem: str) -> RecordingError:
    return RecordingError(f"{path}: {problem}")


def validate(frame: pd.DataFrame, meta: dict[str, Any], path: Path) -> None:
    """Check the samples against the metadata; raise :class:`RecordingError` naming the problem.

    Checks: the raw columns are present and integer; ``seq`` strictly increases and its gaps add up to no
    more than the metadata's ``counts.dropped``; ``t_us`` strictly increases; ``adc`` is within 0-1023.
    """
    for col in RAW_COLUMNS:
        if col not in frame.columns:
            raise _fail(path, f"missing column {col!r}")
        if not pd.api.types.is_integer_dtype(frame[col]):
            raise _fail(path, f"column {col!r} is not integer")
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
    adc = frame["adc"].to_numpy(np.int64)
    if len(adc) and (adc.min() < 0 or adc.max() > 1023):
        raise _fail(path, "adc outside 0-1023")


def load(path: str | os.PathLike, derive: bool = True) -> Recording:
    """Load and validate one recording.

    Parameters
    ----------
    path : path-like
        The CSV or JSON file, or the path without suffix.
    derive : bool
        Add ``t_s``, ``tension_n``, ``cable_mm``.

    Returns
    -------
    Recording

    Raises
    ------
    RecordingError
        Missing JSON or CSV, unreadable JSON, unknown schema version, missing metadata keys, checksum
        mismatch, missing column, gap in ``seq`` beyond the dropped count, non-monotonic time.
    """
    csv_path = _csv_path(path)
    json_path = csv_path.with_suffix(".json")
    if not json_path.exists():
        raise _fail(json_path, "missing JSON metadata file")
    if not csv_path.exists():
        raise _fail(csv_path, "missing CSV file")
    try:
        meta = json.loads(json_path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise _fail(json_path, f"unreadable JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise _fail(json_path, "metadata is not a JSON object")
    version = meta.get("schema_version")
    if version != SCHEMA_VERSION:
        raise _fail(json_path, f"unknown schema version {version!r} (this code reads {SCHEMA_VERSION})")
    missing = [k for k in REQUIRED_META if k not in meta]
    if missing:
        raise _fail(json_path, f"metadata lacks {', '.join(missing)}")
    data = csv_path.read_bytes()
    digest = hashlib.sha256(data).hexdigest()
    if digest != meta["csv_sha256"]:
        raise _fail(
            csv_path,
            f"checksum mismatch: sha256 {digest[:12]}... but the metadata says "
            f"{str(meta['csv_sha256'])[:12]}...",
        )
    try:
        frame = pd.read_csv(io.BytesIO(data))
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise _fail(csv_path, f"unreadable CSV ({exc})") from None
    validate(frame, meta, csv_path)
    frame = frame.loc[:, list(RAW_COLUMNS)].astype(np.int64)
    rec = Recording(frame=frame, meta=meta, path=csv_path)
    return rec.derive() if derive else rec


def catalogue(root: str | os.PathLike = DATA_DIR) -> pd.DataFrame:
    """List every recording under ``root`` with its key metadata (without loading the samples).

    Parameters
    ----------
    root : path-like
        Folder searched recursively for ``*.json`` files that have a ``.csv`` beside them.

    Returns
    -------
    pandas.DataFrame
        One row per recording: ``group``, ``name``, ``source``, ``kind``, ``system``, ``v_in_mm_s``,
        ``x_f_mm``, ``repetition``, ``status``, ``samples``, ``dropped``, ``corrupted``, ``overruns``,
        ``rate_hz``, ``started_utc``, ``path`` (relative to ``root``), sorted by group and name.
    """
    root = Path(root)
    rows = []
    for jp in sorted(root.rglob("*.json")):
        if not jp.with_suffix(".csv").exists():
            continue
        try:
            meta = json.loads(jp.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError):
            continue
        if not isinstance(meta, dict) or "schema_version" not in meta:
            continue
        sc = meta.get("scenario", {}) or {}
        counts = meta.get("counts", {}) or {}
        rows.append(
            {
                "group": jp.parent.relative_to(root).as_posix(),
                "name": jp.stem,
                "source": (meta.get("source") or {}).get("kind"),
                "kind": sc.get("kind"),
                "system": sc.get("system"),
                "v_in_mm_s": sc.get("v_in_mm_s"),
                "x_f_mm": sc.get("x_f_mm"),
                "repetition": sc.get("repetition"),
                "status": meta.get("status"),
                "samples": counts.get("samples"),
                "dropped": counts.get("dropped"),
                "corrupted": counts.get("corrupted"),
                "overruns": counts.get("overruns"),
                "rate_hz": meta.get("rate_hz"),
                "started_utc": meta.get("started_utc"),
                "path": jp.with_suffix(".csv").relative_to(root).as_posix(),
            }
        )
    columns = [
        "group",
        "name",
        "source",
        "kind",
        "system",
        "v_in_mm_s",
        "x_f_mm",
        "repetition",
        "status",
        "samples",
        "dropped",
        "corrupted",
        "overruns",
        "rate_hz",
        "started_utc",
        "path",
    ]
    return pd.DataFrame(rows, columns=columns).sort_values(["group", "name"], ignore_index=True)
