"""A recording's rig and a tendon's calibration: what the paper's analyses read of a recording's metadata.

Recordings of schema version 2 and later carry ``rig``: the rig file's ``name``, ``hash``, ``schema_version``
and its whole ``text``; older recordings (schema version 1, made before rig files) were all made on the
paper's rig and load as it (``docs/recording_format.md``). A recording's ``calibration`` holds one value per
key (versions 1 and 2) or a list of one per tendon (3 and 4): :func:`calibration_of` gives one tendon's.
"""

from __future__ import annotations

import functools
from typing import Any

from helpers import rigfile
from helpers.rigfile import RigFile, RigFileError


def rig_section(rig: RigFile) -> dict[str, Any]:
    """The ``rig`` object of a new recording's metadata."""
    return {"name": rig.name, "hash": rig.hash, "schema_version": rig.schema_version, "text": rig.text}


def recording_rig(meta: dict[str, Any], source: str = "recording") -> RigFile:
    """The rig a recording was made with: its ``rig.text`` checked, or the paper's rig for older recordings.

    Raises
    ------
    helpers.rigfile.RigFileError
        ``rig`` is not an object of texts whose ``text`` has the ``hash``, or the kept rig file is not valid
        (one line naming the recording and the key).
    """
    section = meta.get("rig")
    if section is None:
        return rigfile.default_rig()
    if not isinstance(section, dict):
        raise RigFileError(f"{source}: rig: expected an object")
    for key in ("name", "hash", "text"):
        if not isinstance(section.get(key), str):
            raise RigFileError(f"{source}: rig.{key}: expected text")
    if rigfile.rig_hash(section["text"].encode("utf-8")) != section["hash"]:
        raise RigFileError(f"{source}: rig.hash: does not match rig.text")
    return _kept(section["text"], f"{source}: rig.text (rig {section['name']!r})")


def calibration_of(meta: dict[str, Any], tendon: int = 0) -> dict[str, Any]:
    """Tendon ``tendon``'s calibration, one value per key, from a recording of any version."""
    n = int(meta.get("tendons", 1)) if meta.get("schema_version") in (3, 4) else 0
    cal = meta["calibration"]
    return {k: v[tendon] if isinstance(v, list) and len(v) == n else v for k, v in cal.items()}


@functools.lru_cache(maxsize=16)
def _kept(text: str, source: str) -> RigFile:
    """A kept rig file, read once per text (a catalogue reads the same rig in every recording)."""
    return rigfile.loads(text, source=source)
