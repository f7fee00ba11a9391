"""Where the record commands write a recording: ``<data dir>/<group>/<name>.csv``, the group and name checked.

A group is a folder under ``data/`` (``a`` or ``a/b``) whose parts are named as a recording is
(:data:`helpers.recordings.store.NAME_PATTERN`); the store checks the recording's own name
(:func:`helpers.recordings.check_name`) whatever folder it is saved in.
"""

from __future__ import annotations

import os
from pathlib import Path

from helpers.base.paths import DATA_DIR
from helpers.recordings import RecordingError, check_name
from helpers.recordings.store import NAME_PATTERN


def check_group(group: str) -> str:
    """Return ``group`` (a folder under ``data/``, ``a`` or ``a/b``) if valid, else raise saying why."""
    parts = str(group).split("/")
    if not group or any(not NAME_PATTERN.match(p) or ".." in p for p in parts):
        raise RecordingError(
            f"invalid group {group!r}: a folder under data/ named with letters, digits, '_', '-', '.' "
            "(sub-folders with '/'; no '..', not an absolute path)"
        )
    return str(group)


def recording_path(group: str, name: str, root: str | os.PathLike = DATA_DIR) -> Path:
    """``<root>/<group>/<name>.csv`` after checking both names."""
    return Path(root) / check_group(group) / f"{check_name(name)}.csv"
