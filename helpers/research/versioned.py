"""The research's versioned JSON documents (designs, mode maps): one check of their format and version."""

from __future__ import annotations

from typing import Any


def check_versioned(doc: Any, where: str, tag: str, version: int) -> dict[str, Any]:
    """Return ``doc`` if it is a JSON object with ``format`` = ``tag`` and ``version`` = ``version``.

    One ``ValueError`` naming ``where`` and the field otherwise (the loaders of the versioned files: design
    files, mode maps).
    """
    if not isinstance(doc, dict):
        raise ValueError(f"{where}: expected a JSON object, got {type(doc).__name__}")
    if doc.get("format") != tag:
        raise ValueError(f"{where}: format: expected {tag!r}, got {doc.get('format')!r}")
    if doc.get("version") != version:
        raise ValueError(f"{where}: version: unknown {doc.get('version')!r} (this code reads {version})")
    return doc
