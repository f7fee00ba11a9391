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
    "DEFAULT_RIG", "ENV_VAR", "resolve", "selected_path", "selected", "in_use", "default_rig", "use",
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


_IN_USE: list[RigFile] = []  # the rig the host's constants were read from, once read


def in_use() -> RigFile:
    """The rig this process runs: :func:`selected` the first time, the same rig ever after.

    ``helpers.paper.hardware`` reads its constants through this on import; from then on :func:`use` refuses
    another rig, since the constants already loaded would not follow it.
    """
    if not _IN_USE:
        _IN_USE.append(selected())
    return _IN_USE[0]


def default_rig() -> RigFile:
    """The paper's rig (``rigs/paper.toml``)."""
    return _load_cached(DEFAULT_RIG)


def use(name_or_path: str | os.PathLike[str]) -> RigFile:
    """Select a rig for this process and the processes it starts: check it, then set ``$HELPERS_RIG``.

    Call before the modules that read the rig load (``helpers.paper.hardware`` reads it once, on import, via
    :func:`in_use`); once they have, naming another rig raises :class:`RigFileError` (restart the process, or
    the notebook's kernel, with the new rig).
    """
    path = resolve(name_or_path)
    rig = load(path)
    if _IN_USE and _IN_USE[0].hash != rig.hash:
        running = _IN_USE[0]
        raise RigFileError(
            f"{path}: this process already runs rig {running.name!r} (hash {running.hash}), read when "
            f"helpers loaded; restart it (a notebook: restart the kernel) with the new rig selected first"
        )
    os.environ[ENV_VAR] = str(path.resolve())
    return rig
