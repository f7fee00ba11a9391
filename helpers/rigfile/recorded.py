"""A recording's rig: the rig file a run was made with, kept in its metadata (``docs/recording_format.md``).

Recordings of schema version 2 carry ``rig``: the rig file's ``name``, ``hash``, ``schema_version`` and its
whole ``text``; older recordings (schema version 1, made before rig files) were all made on the paper's rig
and load as it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from helpers import rigfile
from helpers.rigfile import RigFile, RigFileError

__all__ = ["rig_section", "recording_rig", "validate_rig_section"]


def rig_section(rig: RigFile) -> dict[str, Any]:
    """The ``rig`` object of a new recording's metadata."""
    return {"name": rig.name, "hash": rig.hash, "schema_version": rig.schema_version, "text": rig.text}


def validate_rig_section(meta: dict[str, Any], path: Path) -> str | None:
    """The problem with ``meta["rig"]`` (None if it is absent or valid): a text whose hash is ``hash``."""
    if "rig" not in meta:
        return None
    section = meta["rig"]
    if not isinstance(section, dict):
        return "rig: expected an object"
    for key in ("name", "hash", "text"):
        if not isinstance(section.get(key), str):
            return f"rig.{key}: expected text"
    if rigfile.rig_hash(section["text"].encode("utf-8")) != section["hash"]:
        return "rig.hash: does not match rig.text"
    return None


def recording_rig(meta: dict[str, Any], source: str = "recording") -> RigFile:
    """The rig a recording was made with: its ``rig.text`` checked, or the paper's rig for older recordings.

    Raises
    ------
    helpers.rigfile.RigFileError
        The kept rig file is not valid (one line naming the recording and the key).
    """
    section = meta.get("rig")
    if section is None:
        return rigfile.default_rig()
    try:
        return rigfile.loads(section["text"], source=f"{source} (rig {section.get('name')!r})")
    except (KeyError, TypeError):
        raise RigFileError(f"{source}: rig.text: missing") from None

