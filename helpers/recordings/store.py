"""Where recordings live, and how they are written and read without ever losing one.

- **Names** are validated (:func:`check_name`): letters, digits, ``_``, ``-``, ``.``; no path separators in
  a name, no ``..``; the stems of the project's own files (``calibration``, ``result``) are reserved. (The
  record commands check the group, a folder under ``data/``: :mod:`helpers.commands.recording_paths`.)
- **No silent overwrite**: :func:`save` refuses a name that exists unless asked to replace it, and then keeps
  the old pair until the new one is complete.
- **Pairs are never torn**: the CSV goes first, the JSON (holding the CSV's sha256) last, each written to a
  temporary file and renamed into place. A CSV without its JSON is an incomplete run; :func:`load` and
  :func:`catalogue` call it that.
- **One writer per folder**: saving holds the folder's lock (:mod:`helpers.base.locks`); a reader holds it
shared,
  so it never sees a pair in the middle of a replacement. The kernel releases the lock when a process dies.
- **Aborted runs never take a complete run's name**: :func:`aborted_path` gives them their own.
- **A full disk** (or any error while writing) removes the temporary files and raises one
  :class:`RecordingError`; nothing already on disk changes.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import io
import json
import math
import os
import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from helpers.base.jsonfile import dumps, process_alive, remove_stale_temporaries, write_temp
from helpers.base.locks import LOCK_NAME, FolderBusy, folder_lock, take_lock
from helpers.base.paths import DATA_DIR, EXTERNAL_DATA_DIR
from helpers.base.signals import signals_held
from helpers.recordings.checks import required_keys, validate, validate_meta
from helpers.recordings.format import Recording, RecordingError, raw_columns

NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,99}\Z")
"""A recording's name, or one component of a group."""

RESERVED_NAMES = frozenset({"calibration", "result"})
"""Stems of the project's own JSON files (``calibration.json``, ``result.json``): never a recording's name."""

SAVE_WAIT_S = 10.0
"""How long a save waits for another process's save in the same folder."""


class RecordingExists(RecordingError):
    """A recording of that name exists and replacing it was not asked for."""


# -- names -------------------------------------------------------------------------------------------------
def check_name(name: str) -> str:
    """Return ``name`` if it is a valid recording name, else raise :class:`RecordingError` saying why."""
    if not isinstance(name, str) or not NAME_PATTERN.match(name) or ".." in name:
        raise RecordingError(
            f"invalid recording name {name!r}: use letters, digits, '_', '-', '.' (no '/', no '..', "
            "at most 100 characters)"
        )
    if name.lower() in RESERVED_NAMES or name.lower().endswith(".tmp"):
        raise RecordingError(f"invalid recording name {name!r}: reserved for the project's own files")
    return name


def refuse_existing(target: str | os.PathLike, replace: bool = False) -> None:
    """Refuse, before anything moves, a run whose recording would overwrite one (unless replacing).

    Raises
    ------
    RecordingExists
        The CSV or the JSON of ``target`` exists and ``replace`` is False.
    """
    csv = _csv_path(target)
    if not replace and (csv.exists() or csv.with_suffix(".json").exists()):
        raise RecordingExists(f"{csv}: a recording of that name exists; choose another name or replace it")


def aborted_path(path: str | os.PathLike, started_utc: str, status: str = "aborted") -> Path:
    """The name a run that is not ``complete`` is saved under: ``<name>_<status>_<UTC start>.csv``."""
    p = _csv_path(path)
    stamp = re.sub(r"[^0-9TZ]", "", started_utc) or time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    return p.with_name(f"{p.stem}_{status}_{stamp}.csv")


@contextlib.contextmanager
def reserve(target: str | os.PathLike, replace: bool = False) -> Iterator[Path]:
    """Check the name, refuse an existing recording (unless replacing), hold the name for the ``with`` block.

    A second run asking for the same name meanwhile, in another process or this one, is refused at once,
    before it starts, instead of learning of the conflict only when its finished run is saved. The hold is a
    ``flock`` on ``.<name>.reserved.lock`` beside the recording (released by the kernel if the process dies),
    removed when the block ends. The block gets the recording's CSV path (``target``, ``.csv`` added where it
    has no suffix or ``.json``).

    Raises
    ------
    RecordingError
        An invalid name (:func:`check_name`).
    RecordingExists
        The recording exists (and ``replace`` is False), or another run holds the name.
    """
    csv = _csv_path(target)
    check_name(csv.stem)
    refuse_existing(csv, replace)
    csv.parent.mkdir(parents=True, exist_ok=True)
    lock = csv.with_name(f".{csv.stem}.reserved.lock")

    def busy(who: str) -> RecordingExists:
        return RecordingExists(f"{csv}: {who} is recording under this name right now; choose another name")

    fd = None
    try:
        with signals_held():  # an interrupt cannot leave the name held by a lost file descriptor
            fd = take_lock(lock, busy)
        yield csv
    finally:
        if fd is not None:
            with signals_held():
                with contextlib.suppress(OSError):
                    lock.unlink()  # still holding the lock: nobody can have taken this file meanwhile
                os.close(fd)


def _csv_path(path: str | os.PathLike) -> Path:
    p = Path(path)
    return p.with_suffix(".csv") if p.suffix in ("", ".json") else p


# -- writing -----------------------------------------------------------------------------------------------
def _csv_bytes(frame: pd.DataFrame, columns: tuple[str, ...]) -> bytes:
    buf = io.StringIO()
    frame.loc[:, list(columns)].astype(np.int64).to_csv(buf, index=False, lineterminator="\n")
    return buf.getvalue().encode("ascii")


def _write_error(target: Path, exc: OSError) -> RecordingError:
    why = "no space left on device" if exc.errno == errno.ENOSPC else (exc.strerror or str(exc))
    return RecordingError(f"{target}: could not save ({why}); nothing already on disk was changed")


def save(recording: Recording, path: str | os.PathLike | None = None, *, replace: bool = False) -> Path:
    """Write ``recording`` as ``<path>.csv`` and ``<path>.json`` (the JSON last); return the CSV path.

    Parameters
    ----------
    recording : Recording
        Its ``meta`` must hold the keys of the contract except ``csv_sha256`` (filled in here).
    path : path-like, optional
        ``data/<group>/<name>.csv`` (the suffix may be omitted); defaults to ``recording.path``.
    replace : bool
        Replace an existing recording of that name (the old pair stays until the new one is complete).

    Returns
    -------
    pathlib.Path
        The CSV's path; ``recording.path`` is set to it.

    Raises
    ------
    RecordingExists
        The name exists and ``replace`` is False.
    RecordingError
        An invalid name, incomplete metadata, or the files could not be written (e.g. a full disk).
    helpers.base.locks.FolderBusy
        Another process kept saving into the folder for longer than :data:`SAVE_WAIT_S`.
    """
    target = _csv_path(path if path is not None else recording.path or "")
    if target.name in ("", ".csv"):
        raise RecordingError("save: no path given for the recording")
    check_name(target.stem)
    meta = dict(recording.meta)
    missing = [k for k in required_keys() if k not in meta and k != "csv_sha256"]
    if missing:
        raise RecordingError(f"{target}: metadata lacks {', '.join(missing)}")
    data = _csv_bytes(recording.frame, raw_columns(meta))
    meta["csv_sha256"] = hashlib.sha256(data).hexdigest()
    meta["counts"] = dict(meta["counts"], samples=int(len(recording.frame)))
    text = dumps(meta)
    json_target = target.with_suffix(".json")
    try:
        with folder_lock(target.parent, wait_s=SAVE_WAIT_S, what="saving a recording"):
            tidy_folder(target.parent)
            refuse_existing(target, replace)
            _write_pair(target, json_target, data, text.encode("utf-8"))
    except OSError as exc:
        raise _write_error(target, exc) from None
    recording.meta = json.loads(text)
    recording.path = target
    return target


_BACKUP = re.compile(r"\.(?P<name>.+)\.replaced-(?P<pid>\d+)\.tmp\Z")
"""A recording file set aside during a replacement: ``.<file name>.replaced-<pid of its writer>.tmp``."""


def tidy_folder(folder: Path) -> None:
    """What writers that died left in ``folder``: called by a writer holding the folder's lock.

    Their temporary files go (:func:`helpers.base.jsonfile.remove_stale_temporaries`). A pair a dead writer
    was
    replacing is made whole again: if the new pair is complete, the old one's set-aside files go; if not,
    the new part goes and the old pair is put back. A live writer's files are never touched.
    """
    remove_stale_temporaries(folder)
    aside: dict[str, dict[str, Path]] = {}
    for path in folder.iterdir():
        m = _BACKUP.match(path.name)
        if m is None or process_alive(int(m["pid"])):
            continue
        dest = folder / m["name"]
        aside.setdefault(dest.stem, {})[dest.suffix] = path
    for stem, files in aside.items():
        csv, js = folder / f"{stem}.csv", folder / f"{stem}.json"
        if csv.exists() and js.exists():  # the replacement was complete: the old pair is obsolete
            for p in files.values():
                p.unlink(missing_ok=True)
            continue
        for new in (js, csv):  # half a new pair: the old pair comes back
            if new.suffix in files:
                new.unlink(missing_ok=True)
        if ".json" not in files and js.exists():  # the new JSON alone, old JSON gone: keep the new pair's
            continue
        for suffix, p in files.items():
            os.replace(p, folder / f"{stem}{suffix}")


def _write_pair(csv_path: Path, json_path: Path, data: bytes, text: bytes) -> None:
    """Temporary files first; then (old JSON and CSV aside), the new CSV, then the new JSON; then tidy up."""
    temps: list[Path] = []
    backups: list[tuple[Path, Path]] = []
    placed: list[Path] = []
    try:
        for dest, content in ((csv_path, data), (json_path, text)):
            temps.append(write_temp(dest.parent, dest.name, content))
        # an old pair goes aside, the JSON first: meanwhile the pair reads as incomplete, never as torn
        for p in (json_path, csv_path):
            if p.exists():
                aside = p.with_name(f".{p.name}.replaced-{os.getpid()}.tmp")
                os.replace(p, aside)
                backups.append((aside, p))
        for tmp, dest in zip(temps, (csv_path, json_path), strict=True):
            os.link(tmp, dest)  # a hard link fails rather than overwrite
            placed.append(dest)
    except BaseException:
        for p in placed:  # the new files that made it
            p.unlink(missing_ok=True)
        for aside, dest in reversed(backups):  # the old pair back
            os.replace(aside, dest)
        raise
    finally:
        for tmp in temps:
            tmp.unlink(missing_ok=True)
    for aside, _ in backups:
        aside.unlink(missing_ok=True)


# -- reading -----------------------------------------------------------------------------------------------
@contextlib.contextmanager
def _shared_lock(folder: Path) -> Iterator[None]:
    """Hold the folder's lock shared (readers do not block each other; a writer waits for them)."""

    def busy(who: str) -> FolderBusy:
        return FolderBusy(f"{folder} is busy: {who} is saving a recording there")

    try:
        fd = take_lock(folder / LOCK_NAME, busy, SAVE_WAIT_S, shared=True)
    except OSError:  # a read-only folder: nobody can be writing into it
        yield
        return
    try:
        yield
    finally:
        os.close(fd)


def _read_pair(csv_path: Path) -> tuple[bytes, Any]:
    json_path = csv_path.with_suffix(".json")
    with _shared_lock(csv_path.parent):
        has_json, has_csv = json_path.exists(), csv_path.exists()
        if has_csv and not has_json:
            raise RecordingError(
                f"{csv_path}: incomplete run: the CSV has no metadata (the save did not finish)"
            )
        if not has_json:
            raise RecordingError(f"{json_path}: missing JSON metadata file")
        if not has_csv:
            raise RecordingError(f"{csv_path}: missing CSV file")
        meta = _read_json(json_path)
        data = csv_path.read_bytes()
    return data, meta


def _finite(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"{text} is not a finite number")
    return value


def _read_json(json_path: Path) -> Any:
    """The parsed JSON file, or one :class:`RecordingError`: unreadable JSON and why.

    NaN and infinities are unreadable too: JSON has neither.
    """
    try:
        return json.loads(json_path.read_bytes().decode("utf-8"), parse_float=_finite, parse_constant=_finite)
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
        why = f"{type(exc).__name__}: {str(exc)[:80]}"
        raise RecordingError(f"{json_path}: unreadable JSON ({why})") from None


def _parse_csv(data: bytes, csv_path: Path, header: bytes) -> pd.DataFrame:
    first, _, _ = data.partition(b"\n")
    if first.rstrip(b"\r") != header:
        raise RecordingError(
            f"{csv_path}: header {first[:60]!r} is not {header.decode()!r} (columns and their order)"
        )
    unreadable = (
        pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, ValueError, OverflowError,
    )  # fmt: skip
    try:
        return pd.read_csv(io.BytesIO(data), dtype=np.int64)
    except unreadable as e:
        raise RecordingError(f"{csv_path}: unreadable CSV ({str(e).splitlines()[0][:100]})") from None


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
        One error naming the file, the field and the problem, for any malformed input: an incomplete run
        (CSV without JSON), a missing file, unreadable JSON, an unknown schema version, a missing or wrongly
        typed key, a checksum mismatch, a wrong header, a row count that contradicts ``counts.samples``, a
        gap in ``seq`` beyond the dropped count, non-monotonic time, ADC counts out of range.
    """
    csv_path = _csv_path(path)
    data, meta = _read_pair(csv_path)
    json_path = csv_path.with_suffix(".json")
    validate_meta(meta, json_path)
    digest = hashlib.sha256(data).hexdigest()
    if digest != meta["csv_sha256"]:
        raise RecordingError(
            f"{csv_path}: checksum mismatch: sha256 {digest[:12]}... but the metadata says "
            f"{str(meta['csv_sha256'])[:12]}..."
        )
    columns = raw_columns(meta)
    frame = _parse_csv(data, csv_path, ",".join(columns).encode("ascii"))
    validate(frame, meta, csv_path)  # its columns are the header's: exactly these, int64
    rec = Recording(frame=frame, meta=meta, path=csv_path)
    return rec.derive() if derive else rec


CATALOGUE_COLUMNS = [
    "group", "name", "source", "kind", "system", "v_in_mm_s", "x_f_mm", "repetition", "status", "samples",
    "dropped", "corrupted", "overruns", "rate_hz", "started_utc", "path", "problem",
]  # fmt: skip


def _catalogue_row(root: Path, csv_path: Path) -> dict[str, Any]:
    row: dict[str, Any] = dict.fromkeys(CATALOGUE_COLUMNS)
    row.update(
        group=csv_path.parent.relative_to(root).as_posix(),
        name=csv_path.stem,
        path=csv_path.relative_to(root).as_posix(),
        problem="",
    )
    json_path = csv_path.with_suffix(".json")
    if not json_path.exists():
        row.update(status="incomplete", problem="incomplete run: the CSV has no metadata")
        return row
    meta: Any = {}
    try:
        meta = _read_json(json_path)
        validate_meta(meta, json_path)
        if not csv_path.exists():
            row["problem"] = "missing CSV file"
    except RecordingError as exc:
        row["problem"] = str(exc).removeprefix(f"{json_path}: ")[:200]
    meta = meta if isinstance(meta, dict) else {}

    def section(key: str) -> dict[str, Any]:
        value = meta.get(key)
        return value if isinstance(value, dict) else {}

    sc, counts, source = section("scenario"), section("counts"), section("source")
    row.update({key: sc.get(key) for key in ("kind", "system", "v_in_mm_s", "x_f_mm", "repetition")})
    row.update({key: counts.get(key) for key in ("samples", "dropped", "corrupted", "overruns")})
    row.update({key: meta.get(key) for key in ("status", "rate_hz", "started_utc")})
    row["source"] = source.get("kind")
    return row


def is_other_document(path: Path) -> bool:
    """True for a JSON file without a CSV beside it that declares another ``format`` (a design, a mode map).

    The project keeps such documents next to recordings (``data/tuning``); they are not recordings, neither
    sound nor broken, so :func:`catalogue` leaves them out.
    """
    if path.suffix != ".json" or path.with_suffix(".csv").exists():
        return False
    try:
        doc = _read_json(path)
    except RecordingError:
        return False
    return isinstance(doc, dict) and isinstance(doc.get("format"), str) and "csv_sha256" not in doc


def catalogue(root: str | os.PathLike = DATA_DIR) -> pd.DataFrame:
    """List every recording under ``root`` with its key metadata (without loading the samples).

    JSON documents of other formats (designs, mode maps: :func:`is_other_document`) are not recordings and
    are left out, as is ``data/external/`` (data made elsewhere, in their own formats). Files that are not
    sound are listed too, never skipped: ``problem`` says what is wrong (malformed metadata, an incomplete run
    whose CSV has no JSON, a missing CSV); it is ``""`` for sound metadata (the samples and their checksum are
    checked by :func:`load`).

    Parameters
    ----------
    root : path-like
        Folder searched recursively.

    Returns
    -------
    pandas.DataFrame
        One row per recording: ``group``, ``name``, ``source``, ``kind``, ``system``, ``v_in_mm_s``,
        ``x_f_mm``, ``repetition``, ``status`` (``complete``, ``aborted`` or ``incomplete``), ``samples``,
        ``dropped``, ``corrupted``, ``overruns``, ``rate_hz``, ``started_utc``, ``path`` (relative to
        ``root``), ``problem``; sorted by group and name.
    """
    root = Path(root)
    stems = set()
    for p in root.rglob("*"):
        if p.resolve().is_relative_to(EXTERNAL_DATA_DIR.resolve()):
            continue
        ours = p.suffix in (".csv", ".json") and not p.name.startswith(".")
        if ours and p.stem.lower() not in RESERVED_NAMES and not is_other_document(p):
            stems.add(p.with_suffix(".csv"))
    rows = [_catalogue_row(root, p) for p in sorted(stems)]
    return pd.DataFrame(rows, columns=CATALOGUE_COLUMNS).sort_values(["group", "name"], ignore_index=True)
