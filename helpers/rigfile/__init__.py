"""The rig file: one TOML file describes a rig's hardware, arm, boards and tendons (``docs/rig_file.md``).

Standard library and numpy only (no pydantic, no numba, no twin): :func:`load` reads and checks a file,
:func:`selected` gives the rig the host uses (``HELPERS_RIG`` in the environment, else the paper's
``rigs/paper.toml``), :func:`derived` what follows from it.
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
    "DEFAULT_RIG", "ENV_VAR", "resolve", "selected_path", "selected", "default_rig", "shipped",
]  # fmt: skip

RIGS_DIR: Path = Path(__file__).resolve().parents[2] / "rigs"
"""The rig files shipped with the project (the repository's top-level ``rigs/``)."""

DEFAULT_RIG: Path = RIGS_DIR / "paper.toml"
"""The paper's rig, the default."""

ENV_VAR = "HELPERS_RIG"
"""Environment variable naming the rig file the host uses (a path, or a shipped rig's name)."""


def resolve(name_or_path: str | os.PathLike[str]) -> Path:
    """A rig file's path: a path as given, else a shipped rig's name (``paper``: rigs/paper.toml)."""
    p = Path(name_or_path)
    if p.exists() or p.suffix == ".toml" or len(p.parts) > 1:
        return p
    shipped_path = RIGS_DIR / f"{p}.toml"
    return shipped_path if shipped_path.exists() else p


def selected_path() -> Path:
    """The rig file the host uses: ``$HELPERS_RIG`` if set (and not empty), else :data:`DEFAULT_RIG`."""
    value = os.environ.get(ENV_VAR, "").strip()
    return resolve(value) if value else DEFAULT_RIG


@functools.lru_cache(maxsize=8)
def _cached(path: str, mtime_ns: int) -> RigFile:
    return load(path)


def _load_cached(path: Path) -> RigFile:
    try:
        mtime = path.stat().st_mtime_ns
    except OSError:
        return load(path)  # raises the one-line error
    return _cached(str(path), mtime)


def selected() -> RigFile:
    """The checked rig file the host uses (:func:`selected_path`)."""
    return _load_cached(selected_path())


def default_rig() -> RigFile:
    """The paper's rig (``rigs/paper.toml``)."""
    return _load_cached(DEFAULT_RIG)


def shipped() -> dict[str, Path]:
    """The rig files shipped in ``rigs/``: name -> path."""
    return {p.stem: p for p in sorted(RIGS_DIR.glob("*.toml"))}
