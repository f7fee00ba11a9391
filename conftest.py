"""Root pytest configuration shared by the unit tests and nbval.

Running the tests writes nothing into the working tree: figures and tables (which the notebooks save when
nbval executes them) go to a temporary folder named by ``HELPERS_FIGURES_DIR``, set here before any kernel
starts, so every kernel nbval launches inherits it; so does the user's data folder
(``HELPERS_USER_DATA_DIR``), where a command run without ``--data-dir`` records. Caches that ``.gitignore``
lists (numba, hypothesis, the firmware build) are the only files the tests leave behind.
"""

import atexit
import os
import re
import shutil
import tempfile
from pathlib import Path

import pytest

# An inherited backend (e.g. MPLBACKEND=Agg in CI) would stop the kernels nbval starts from producing
# inline figures, and the stored "<Figure ...>" outputs would then not match.
os.environ.pop("MPLBACKEND", None)
# Notebooks run unattended here: interactive cells show their static figure
# (helpers.base.notebook.interactive).
os.environ["HELPERS_BATCH"] = "1"

if not os.environ.get("HELPERS_FIGURES_DIR"):
    _figures = tempfile.mkdtemp(prefix="helpers-test-figures-")
    os.environ["HELPERS_FIGURES_DIR"] = _figures
    atexit.register(shutil.rmtree, _figures, ignore_errors=True)

# A command run without --data-dir writes into the user's data folder (my_data/<rig>/): a temporary one here.
if not os.environ.get("HELPERS_USER_DATA_DIR"):
    _user_data = tempfile.mkdtemp(prefix="helpers-test-my-data-")
    os.environ["HELPERS_USER_DATA_DIR"] = _user_data
    atexit.register(shutil.rmtree, _user_data, ignore_errors=True)


PAPER_NOTEBOOKS = range(0, 6)
"""Notebooks 00-05 (the paper's own steps) run under nbval in the default suite; the wings' notebooks (06
onwards: the twin, the research) carry the ``slow`` marker, so ``python -m pytest -m slow`` runs them."""


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Mark the nbval cells of the notebooks beyond the paper's as ``slow`` (before ``-m`` selects)."""
    for item in items:
        match = re.match(r"(\d+)_", Path(str(item.fspath)).name)
        if item.fspath.ext == ".ipynb" and match and int(match.group(1)) not in PAPER_NOTEBOOKS:
            item.add_marker(pytest.mark.slow)


def _git_status() -> list[str] | None:
    """``git status --porcelain`` of the repository, or None outside a git checkout."""
    import subprocess
    from pathlib import Path

    try:
        proc = subprocess.run(
            ["git", "status", "--porcelain"],
            cwd=Path(__file__).resolve().parent,
            capture_output=True,
            text=True,
            timeout=60,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return proc.stdout.splitlines() if proc.returncode == 0 else None


def _is_worker(config) -> bool:
    """True in a pytest-xdist worker (the controller alone checks the working tree)."""
    return hasattr(config, "workerinput")


_KERNELS = (
    # the planar plant, one scenario and four in lanes
    "import numpy as np; from helpers.virtual.plant import ArmLanes, ArmPlant; "
    "from helpers.virtual.parameters import RigParameters as R; t = np.array([1e-3]); e = np.empty(0); "
    "ArmPlant(R()).advance(t, e, e); ArmLanes([R()] * 4).advance_all(t, [e] * 4, [e] * 4)",
    # the spatial twin, one scenario
    "import numpy as np; from helpers.virtual.spatial.plant import SpatialPlant; "
    "from helpers.virtual.spatial.rig import four_tendon_rig as four; "
    "SpatialPlant(four()).advance(np.array([1e-3]))",
)
"""What :func:`_compile_kernels_once` runs, each in a process of its own: the first call of each kernel."""


def _compile_kernels_once(config) -> None:
    """Compile the twins' kernels into numba's cache before the workers start (a parallel run only).

    Two workers that first call the same kernel at once both compile it (about 11-20 s of CPU each, on a
    fresh clone); compiled here, two kernels at a time, each is compiled once and every worker loads it
    from the cache. With the cache warm this costs each process its imports (about 2 s of CPU).
    """
    if not (getattr(config.option, "numprocesses", 0) or 0) >= 2 or config.option.collectonly:
        return
    import subprocess
    import sys

    root = str(Path(__file__).resolve().parent)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")]))}
    procs = [subprocess.Popen([sys.executable, "-c", code], cwd=root, env=env, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL) for code in _KERNELS]  # fmt: skip
    for proc in procs:  # a failure here is the tests' to find, each where its own call fails
        proc.wait()


def pytest_sessionstart(session):
    """Note what ``git status`` shows before the tests run; compile the kernels once (a parallel run)."""
    if not _is_worker(session.config):
        session.config.stash_git_status = _git_status()
        _compile_kernels_once(session.config)


def pytest_sessionfinish(session, exitstatus):
    """Fail the run if the tests changed anything ``git status`` can see (they must write only to temp)."""
    before = getattr(session.config, "stash_git_status", None)
    after = _git_status()
    if before is None or after is None:
        return
    changed = sorted(set(after) - set(before))
    if changed:
        reporter = session.config.pluginmanager.get_plugin("terminalreporter")
        if reporter is not None:
            reporter.write_line("")
            reporter.write_line(
                "the test run changed the working tree (tests must write to temporary folders only):",
                red=True,
            )
            for line in changed:
                reporter.write_line(f"  {line}", red=True)
        session.exitstatus = 1
