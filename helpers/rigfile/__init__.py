"""The rig file: one TOML file describes a rig's hardware, arm, boards and tendons (``docs/rig_file.md``).

Standard library and numpy only (no pydantic, no numba, no twin): :func:`load` reads and checks a file,
:func:`resolve` finds one by path or by a shipped rig's name, :func:`default_rig` is the paper's
(``rigs/paper.toml``), :func:`derived` what follows from a rig. Nothing here reads a rig or the environment
at import: a rig is a value, loaded where the user names it and passed down.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

from helpers.rigfile.derived import Derived, check, derived, hold_tension_n, loop_counts
from helpers.rigfile.errors import RigFileError
from helpers.rigfile.model import Arm, Boards, Hardware, RigFile, Tendon, load, loads, rig_hash
from helpers.rigfile.schema import MAX_TENDONS, RIG_SCHEMA_VERSION

__all__ = [
    "RigFile", "RigFileError", "Tendon", "Hardware", "Arm", "Boards", "Derived", "load", "loads", "rig_hash",
    "derived", "check", "hold_tension_n", "loop_counts", "MAX_TENDONS", "RIG_SCHEMA_VERSION", "RIGS_DIR",
    "DEFAULT_RIG", "resolve", "default_rig",
]  # fmt: skip

RIGS_DIR: Path = Path(__file__).resolve().parents[2] / "rigs"
"""The rig files shipped with the project (the repository's top-level ``rigs/``)."""

DEFAULT_RIG: Path = RIGS_DIR / "paper.toml"
"""The paper's rig, the default."""


def resolve(name_or_path: str | os.PathLike[str]) -> Path:
    """A rig file's path: a path as given, else a shipped rig's name (``paper``: rigs/paper.toml)."""
    p = Path(name_or_path)
    if p.exists() or p.suffix == ".toml" or len(p.parts) > 1:
        return p
    shipped_path = RIGS_DIR / f"{p}.toml"
    return shipped_path if shipped_path.exists() else p


@functools.lru_cache(maxsize=1)
def _paper(mtime_ns: int) -> RigFile:
    return load(DEFAULT_RIG)


def default_rig() -> RigFile:
    """The paper's rig (``rigs/paper.toml``), read when first asked for (and again if the file changes)."""
    return _paper(DEFAULT_RIG.stat().st_mtime_ns)
