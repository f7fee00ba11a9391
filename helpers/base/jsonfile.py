"""Writing files so that a crash never leaves half a file, and reading JSON files with one clear error.

The one atomic writer of the package: every JSON result, calibration and recording goes through
:func:`write_temp` (a unique temporary file in the same folder, flushed and fsynced) and then a rename
(:func:`atomic_write`: ``os.replace``; the recordings' store adds no-clobber and replace-safely).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import tempfile
from pathlib import Path
from typing import Any

import numpy as np


class DataFileError(ValueError):
    """A data file is missing, unreadable or malformed; the message names the file and the problem."""


class MissingDataError(DataFileError, FileNotFoundError):
    """A data file that an analysis needs does not exist yet; the message says how to make it."""


def write_temp(folder: str | os.PathLike, name: str, data: bytes) -> Path:
    """Write ``data`` to a new hidden temporary file in ``folder`` (flushed and fsynced) and return its path.

    The file gets the mode an ordinary new file would (0666 minus the umask), not ``mkstemp``'s 0600. On any
    error (a full disk, a signal) the temporary file is removed and the error re-raised: nothing else changed.
    """
    folder = Path(folder)
    tmp: str | None = None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{name}.{os.getpid()}-", suffix=".tmp")
        umask = os.umask(0)
        os.umask(umask)
        os.fchmod(fd, 0o666 & ~umask)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
    except BaseException as exc:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError):  # a read-only or full file system: name the file it was for
            raise type(exc)(exc.errno, exc.strerror, str(folder / name)) from None
        raise
    return Path(tmp)


TEMP_PATTERN = re.compile(r"\.(?P<name>.+)\.(?P<pid>\d+)-[A-Za-z0-9_]+\.tmp\Z")
"""A temporary file of :func:`write_temp`: ``.<name>.<pid of its writer>-<random>.tmp``."""


def process_alive(pid: int) -> bool:
    """True if a process ``pid`` exists (it may be another program that got a dead writer's pid)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_stale_temporaries(folder: str | os.PathLike) -> None:
    """Remove the temporary files of :func:`write_temp` in ``folder`` whose writer has died.

    A live writer's file is never touched (its pid is in the name and the process exists). Callers hold the
    folder's lock, so that no writer of theirs can be starting meanwhile.
    """
    try:
        entries = list(Path(folder).iterdir())
    except OSError:
        return
    for path in entries:
        m = TEMP_PATTERN.match(path.name)
        if m is not None and not process_alive(int(m["pid"])):
            with contextlib.suppress(OSError):
                path.unlink()


def atomic_write(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically: readers see the old file or the new one, never a part.

    Parameters
    ----------
    path : path-like
        Destination; its folder is created if needed.
    data : bytes
        The whole content.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path = Path(path)
    tmp = write_temp(path.parent, path.name, data)
    try:
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def json_safe(value: Any) -> Any:
    """Make ``value`` JSON-safe: numpy to Python, tuples to lists, paths to text, NaN to None."""
    if isinstance(value, np.ndarray | np.generic):
        value = value.tolist()  # Python lists and scalars
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def dumps(data: dict[str, Any], sort_keys: bool = True) -> str:
    """The project's JSON text: indented, keys sorted, NaN refused, a final newline."""
    return json.dumps(json_safe(data), indent=2, sort_keys=sort_keys, allow_nan=False) + "\n"


def write_json(path: str | os.PathLike, data: dict[str, Any], sort_keys: bool = True) -> Path:
    """Write ``data`` as JSON atomically (see :func:`dumps`) and return the path."""
    return atomic_write(path, dumps(data, sort_keys).encode("utf-8"))


def read_json(path: str | os.PathLike, what: str, missing_hint: str = "") -> dict[str, Any]:
    """Read a JSON object, raising one clear error for a missing or malformed file.

    Parameters
    ----------
    path : path-like
        The file.
    what : str
        What the file holds, for the messages (e.g. ``"identification result"``).
    missing_hint : str
        How to make the file, appended to the message when it is missing.

    Returns
    -------
    dict
        The JSON object.

    Raises
    ------
    MissingDataError
        If the file does not exist.
    DataFileError
        If it is not valid JSON or not an object.
    """
    path = Path(path)
    if not path.exists():
        hint = f": {missing_hint}" if missing_hint else ""
        raise MissingDataError(f"{path}: no {what} yet{hint}")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DataFileError(f"{path}: the {what} is not valid JSON ({exc})") from None
    except RecursionError:
        raise DataFileError(f"{path}: the {what} is nested too deeply to be what it should be") from None
    if not isinstance(data, dict):
        raise DataFileError(f"{path}: the {what} is not a JSON object")
    return data
