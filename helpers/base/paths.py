"""Where the project's folders are, so that no notebook or module hard-codes a relative path."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

REPO_ROOT: Path = Path(__file__).resolve().parents[2]
"""The repository's top folder (the package is installed editable from it)."""

DATA_DIR: Path = REPO_ROOT / "data"
"""Recordings, calibration and identification results."""

FIGURES_ENV = "HELPERS_FIGURES_DIR"
"""Environment variable that sends figures and tables elsewhere (the test suite points it at a temporary
folder, so that running the tests writes nothing into the working tree)."""

FIGURES_DIR: Path = Path(os.environ.get(FIGURES_ENV) or REPO_ROOT / "figures")
"""Regenerated figures and tables: ``figures/``, or the folder named by ``HELPERS_FIGURES_DIR``."""

STORED_TABLES_DIR: Path = REPO_ROOT / "figures"
"""The repository's own ``figures/`` folder, never redirected: the tables that commands store there for the
notebooks to *read* (the previous virtual rig's Table II, the virtual rig's study tables). Notebooks write
through :func:`figure_path`; they read these through :func:`stored_table`."""

USER_DATA_ENV = "HELPERS_USER_DATA_DIR"
"""Environment variable that moves the user's data folder (:func:`user_data_dir`) elsewhere (the test suite
points it at a temporary folder, so that a command run without ``--data-dir`` writes nothing into the working
tree)."""

EXTERNAL_DATA_DIR: Path = DATA_DIR / "external"
"""Data made elsewhere, in their own formats and with their licences (``docs/external_data.md``): read only,
never recordings of this project (``helpers.recordings.catalogue`` leaves the folder out)."""

IDENTIFICATION_RESULT: Path = DATA_DIR / "identification" / "result.json"
"""The shipped identified dominant mode: written by ``helpers.paper.identify.save_identification`` through
``python -m helpers record all --data-dir data`` (without ``--data-dir``, and in notebook 02's live cell, into
:func:`user_data_dir` instead), read by ``helpers.paper.identify.load_identification`` (notebooks 03 on)."""

LOADCELL_CALIBRATION: Path = DATA_DIR / "calibration" / "calibration.json"
"""The load-cell calibration: written by ``helpers.paper.calibration.save_calibration`` (``python -m helpers
record
calibration``), read by ``helpers.paper.tension.load_calibration`` (every recording run)."""

VIRTUAL_RIG_REGISTRY: Path = Path(tempfile.gettempdir()) / "helpers-virtual-rigs"
"""Where ``python -m helpers serve-virtual-rig`` announces its pseudo-terminals, so that recordings made
through them are labelled ``virtual-rig``, never ``hardware`` (read by
``helpers.rig.ports.virtual_source_for``)."""


def user_data_dir(rig: object) -> Path:
    """Where a user's recordings and results go by default: ``my_data/<rig name>/`` (gitignored).

    ``data/`` holds the project's shipped recordings (the notebooks analyse them); commands write there only
    when told to (``--data-dir data``). Every command that records or reads a previous step's result
    (calibration, identification, tuning) uses this folder unless ``--data-dir`` is given: the same layout as
    ``data/`` (``calibration/``, ``identification/``, ``experiments/``, ``tuning/``, one's own groups), one
    folder per rig, so that two rigs never mix. ``HELPERS_USER_DATA_DIR`` (read when called) replaces
    ``my_data``.

    Parameters
    ----------
    rig : RigFile or str
        The rig (its ``name``) or a rig's name.

    Returns
    -------
    pathlib.Path
        ``<repository>/my_data/<rig name>`` (not created).

    Raises
    ------
    ValueError
        If the name is not a single folder name.
    """
    name = str(getattr(rig, "name", rig))
    if name in ("", ".", "..") or "/" in name or "\\" in name:
        raise ValueError(f"rig name {name!r} cannot name a folder under my_data/")
    return user_data_root() / name


def user_data_root() -> Path:
    """The folder of every rig's :func:`user_data_dir`: ``my_data/`` (or ``HELPERS_USER_DATA_DIR``)."""
    return Path(os.environ.get(USER_DATA_ENV) or REPO_ROOT / "my_data")


def figure_path(name: str) -> Path:
    """Return ``figures/<name>``, creating the folder if needed.

    Parameters
    ----------
    name : str
        File name, e.g. ``"fig12_model_shaping.png"``.

    Returns
    -------
    pathlib.Path
        The full path.
    """
    FIGURES_DIR.mkdir(parents=True, exist_ok=True)
    return FIGURES_DIR / name


def stored_table(name: str) -> Path:
    """Return ``figures/<name>`` in the repository (not redirected by ``HELPERS_FIGURES_DIR``), for reading.

    Raises
    ------
    FileNotFoundError
        If the table is not there, naming the command that makes it.
    """
    path = STORED_TABLES_DIR / name
    if not path.exists():
        raise FileNotFoundError(
            f"{path} is missing: the virtual rig's study tables are written by "
            "`python -m helpers virtual-rig studies`; table2_previous_rig.csv is kept in the repository"
        )
    return path


def shown(path: str | os.PathLike | None, root: Path | None = None) -> str:
    """A path as a message shows it (``"?"`` for None).

    Relative to ``root`` when it lies inside it, else as given; without a ``root``, relative to the working
    directory where it can be.
    """
    if path is None:
        return "?"
    p = Path(path)
    if root is not None:
        return p.relative_to(root).as_posix() if p.is_relative_to(root) else str(p)
    try:
        return os.path.relpath(p)
    except ValueError:
        return str(p)


def repo_path(path: str | os.PathLike) -> str:
    """A path as a message shows it: relative to the repository (e.g. ``data/...``) when it lies inside it."""
    return shown(path, REPO_ROOT)
