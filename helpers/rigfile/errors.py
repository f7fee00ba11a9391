"""The rig file's one error (standard library only)."""

from __future__ import annotations


class RigFileError(ValueError):
    """A rig file that cannot be used: one line naming the file, the key and the problem."""
