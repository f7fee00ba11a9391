"""DROPBEAR Dataset-8 trials, data made elsewhere, read from their own files as recordings (``external``).

The project's recordings are written by its own drivers (``docs/recording_format.md``). Data made by others
keep their own format and licence in ``data/external/`` and are read here into the same type,
:class:`~helpers.recordings.format.Recording`, with ``source.kind`` :data:`EXTERNAL_SOURCE` (``"external"``):
never saved as a CSV/JSON pair here, never validated as one (their columns are the instrument's, not the DAQ
board's), and never presented as a recording of this project's rig.

A DROPBEAR trial (:func:`read_dropbear`; ``data/external/dropbear/README.md``) is tab-separated text: header
lines (the instrument's path, ``Sampling Frequency - 5000``, a date), the channel line (``Low G Accel  Accel
PinLoc  Time``, or six columns with two strain gauges), a units line, a zero line, a blank line, then one row
of numbers per sample. Its frame keeps every channel in its unit (volts, unscaled: ``low_g_accel_v``,
``accel_v``, ``pinloc_v``, ``sg_300_a_v``, ...), the time ``t_s`` as the file gives it, and the sampling rate
in ``meta["rate_hz"]``; ``meta["scenario"]["configuration"]`` names the configuration signal's column
(``pinloc_v``, the roller position sensor's voltage). A file that is not a trial, or a truncated or malformed
one, raises one :class:`~helpers.recordings.format.RecordingError` naming the file and the line (exit status 5
on the command line).
"""

from __future__ import annotations

import hashlib
import math
import os
import re
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from helpers.recordings.format import Recording, RecordingError

__all__ = ["EXTERNAL_SOURCE", "DROPBEAR_DATASET", "DROPBEAR_LICENCE", "read_dropbear", "configuration_column"]

EXTERNAL_SOURCE = "external"
"""``source.kind`` of a recording made elsewhere (beside ``hardware`` and ``virtual-rig``)."""

DROPBEAR_DATASET = "DROPBEAR Dataset-8: Acceleration vs Roller Displacement"
"""The dataset's name as its authors give it."""

DROPBEAR_CITATION = (
    "A. Vereen, A. Downey, J. Dodson, A. G. Moura, 'Dataset-8 DROPBEAR Acceleration vs Roller Displacement', "
    "Aug. 2023, High-Rate-SHM-Working-Group on GitHub"
)
"""How to cite it (``CITATION.cff``)."""

DROPBEAR_LICENCE = "CC BY-SA 4.0"
"""The dataset's licence: the data and everything derived from them stay under it."""

CONFIGURATION = "pinloc_v"
"""The configuration signal of a DROPBEAR trial: the roller position sensor's voltage."""

_RATE = re.compile(r"Sampling Frequency\s*-\s*([0-9.eE+-]+)\s*\Z")
TIME_TOLERANCE = 0.01
"""Largest deviation of a sample's time from ``t_0 + k / rate_hz``, in sample periods (a missing or repeated
sample is refused)."""

MIN_SAMPLES = 2
"""Fewest samples a trial may hold."""


def _column(name: str) -> str:
    """A channel's name as a column (``Low G Accel`` -> ``low_g_accel_v``)."""
    return re.sub(r"[^a-z0-9]+", "_", name.strip().lower()).strip("_") + "_v"


def _fail(path: Path, line: int | None, problem: str) -> RecordingError:
    where = f"{path}" if line is None else f"{path}: line {line}"
    return RecordingError(f"{where}: {problem}")


def configuration_column(recording: Recording) -> str:
    """The column of ``recording``'s configuration signal (``meta["scenario"]["configuration"]``)."""
    scenario = recording.meta.get("scenario", {})
    column = scenario.get("configuration") if isinstance(scenario, dict) else None
    if not isinstance(column, str) or column not in recording.frame.columns:
        raise ValueError(f"{recording.name}: the recording names no configuration signal among its columns")
    return column


def read_dropbear(path: str | os.PathLike) -> Recording:
    """Read a DROPBEAR Dataset-8 trial file as a recording.

    Parameters
    ----------
    path : path-like
        The trial's text file (``data/external/dropbear/*.txt``).

    Returns
    -------
    Recording
        ``frame``: ``t_s`` (s, the file's ``Time``) and one column per channel in volts (unscaled),
        ``pinloc_v`` the configuration signal; ``meta``: ``source`` (``kind`` ``"external"``, ``dataset``,
        ``file``, ``sha256``, ``licence``, ``citation``), ``rate_hz``, ``units`` and ``channels`` (the file's
        own names) per column, ``scenario`` (``kind`` ``"external"``, ``configuration``, the file's header
        lines), ``counts.samples``, ``status`` ``"complete"``; ``path``: the file.

    Raises
    ------
    RecordingError
        One line naming the file (and the line) for a missing or unreadable file, a file that is not a
        DROPBEAR trial, a malformed or truncated row, or samples not evenly spaced at the stated rate.
    """
    p = Path(path)
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise _fail(p, None, "no such file") from None
    except OSError as exc:
        raise _fail(p, None, f"cannot be read ({exc.strerror})") from None
    try:
        text = data.decode("ascii")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise _fail(p, line, "not a DROPBEAR trial (not plain text)") from None
    lines = text.split("\n")
    rate, head = None, None
    for i, line in enumerate(lines[:20]):
        fields = [f.strip() for f in line.rstrip("\r").split("\t")]
        match = _RATE.match(line.strip())
        if match:
            try:
                rate = float(match.group(1))
            except ValueError:
                raise _fail(p, i + 1, f"sampling frequency {match.group(1)!r} is not a number") from None
        if "PinLoc" in fields and fields[-1] == "Time":
            head = i
            break
    if head is None:
        raise _fail(p, None, "not a DROPBEAR trial: no channel line naming PinLoc and Time in the first 20")
    if rate is None or not (math.isfinite(rate) and rate > 0):
        raise _fail(p, None, "not a DROPBEAR trial: no 'Sampling Frequency - N' line before the channel line")
    names = [f.strip() for f in lines[head].rstrip("\r").split("\t")]
    if len(names) < 2 or len(set(names)) != len(names) or any(not n for n in names):
        raise _fail(p, head + 1, f"channel line {lines[head]!r}: expected distinct names, the last 'Time'")
    units = [f.strip() for f in lines[head + 1].rstrip("\r").split("\t")] if head + 1 < len(lines) else []
    if len(units) != len(names):
        raise _fail(p, head + 2, f"units line has {len(units)} fields for {len(names)} channels (truncated?)")
    first = head + 2  # the zero line, then a blank line, then the samples
    while first < len(lines) and lines[first].strip() and not _numeric_row(lines[first], len(names)):
        first += 1
    while first < len(lines) and not lines[first].strip():
        first += 1
    rows = lines[first:]
    while rows and not rows[-1].strip():  # the final newline
        rows.pop()
    values = np.empty((len(rows), len(names)))
    for k, row in enumerate(rows):
        fields = row.rstrip("\r").split("\t")
        if len(fields) != len(names):
            what = "truncated" if k == len(rows) - 1 else "malformed"
            raise _fail(p, first + k + 1, f"{what} row: {len(fields)} fields, expected {len(names)}")
        try:
            values[k] = [float(f) for f in fields]
        except ValueError:
            problem = f"malformed row: {row.strip()[:60]!r} is not {len(names)} numbers"
            raise _fail(p, first + k + 1, problem) from None
    if len(rows) < MIN_SAMPLES:
        raise _fail(p, None, f"{len(rows)} samples: truncated (a trial holds at least {MIN_SAMPLES})")
    bad = ~np.isfinite(values).all(axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        raise _fail(p, first + k + 1, "a value is not finite")
    t = values[:, -1]
    drift = np.abs((t - t[0]) * rate - np.arange(t.size))
    if drift.max() > TIME_TOLERANCE:
        k = int(np.argmax(drift > TIME_TOLERANCE))
        raise _fail(p, first + k + 1, f"time {t[k]:.6g} s is not sample {k} at {rate:g} per second "
                                      "(a missing, repeated or reordered sample?)")  # fmt: skip
    columns = ["t_s"] + [_column(n) for n in names[:-1]]
    if len(set(columns)) != len(columns):
        raise _fail(p, head + 1, f"channel names {names} give the same column twice")
    frame = pd.DataFrame({"t_s": t, **{c: values[:, i] for i, c in enumerate(columns[1:])}})
    if CONFIGURATION not in frame.columns:
        raise _fail(p, head + 1, "no PinLoc channel (the configuration signal)")
    meta: dict[str, Any] = {
        "status": "complete",
        "rate_hz": int(rate) if rate.is_integer() else rate,
        "counts": {"samples": int(len(frame))},
        "source": {
            "kind": EXTERNAL_SOURCE,
            "dataset": DROPBEAR_DATASET,
            "file": p.name,
            "sha256": hashlib.sha256(data).hexdigest(),
            "licence": DROPBEAR_LICENCE,
            "citation": DROPBEAR_CITATION,
            "measured": "real hardware, recorded by the dataset's authors",
        },
        "scenario": {
            "kind": EXTERNAL_SOURCE,
            "configuration": CONFIGURATION,
            "header": [line.rstrip("\r") for line in lines[:head]],
        },
        "units": {"t_s": "s", **{c: "V" for c in columns[1:]}},
        "channels": {"t_s": names[-1], **dict(zip(columns[1:], names[:-1], strict=True))},
        "file_units": {"t_s": units[-1], **dict(zip(columns[1:], units[:-1], strict=True))},
    }
    return Recording(frame=frame, meta=meta, path=p)


def _numeric_row(line: str, n: int) -> bool:
    """Whether ``line`` is ``n`` tab-separated numbers (a sample row)."""
    fields = line.rstrip("\r").split("\t")
    if len(fields) != n:
        return False
    try:
        [float(f) for f in fields]
    except ValueError:
        return False
    return True
