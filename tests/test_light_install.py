"""The paper runs with the paper's packages: without the twin's and the sweeps' extras (pyproject.toml).

The extras' packages are blocked in a fresh interpreter (``sys.modules[name] = None`` makes their import fail
as if they were not installed). The core then imports, the metrics command works, and a command that needs an
extra says so in one line naming it. CI also builds a real light environment (``.ci/run``).
"""

from __future__ import annotations

import subprocess
import sys

import pytest

from helpers.base.paths import REPO_ROOT

EXTRAS = ("numba", "llvmlite", "tqdm", "dask", "distributed", "xarray", "pydantic")
BLOCK = "import sys\nfor m in " + repr(EXTRAS) + ":\n    sys.modules[m] = None\n"


def _run(code: str, tmp_path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", BLOCK + code], capture_output=True, text=True, timeout=300, cwd=tmp_path
    )


def test_the_core_imports_without_the_extras(tmp_path):
    code = (
        "import helpers.base.notebook, helpers.paper.identify, helpers.paper.metrics, helpers.paper.model\n"
        "import helpers.board.programmes, helpers.board.stream_reference, helpers.recordings, helpers.rig\n"
        "import helpers.plotting.experiments, helpers.plotting.identification, helpers.plotting.model\n"
        "import helpers.plotting.playground, helpers.plotting.shapers, helpers.rig.table_i\n"
        "print('ok')\n"
    )
    proc = _run(code, tmp_path)
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr[-1500:]


def test_the_metrics_command_runs_without_the_extras(tmp_path):
    code = (
        "from helpers.__main__ import main\n"
        f"sys.exit(main(['metrics', {str(REPO_ROOT / 'data' / 'experiments')!r}]))\n"
    )
    proc = _run(code, tmp_path)
    assert proc.returncode == 0, proc.stderr[-1500:]
    assert "settling" in proc.stdout and "zvd" in proc.stdout


@pytest.mark.parametrize(
    ("argv", "extra"),
    [
        (["sweep", "run", "none.json"], "sweep"),
        (["virtual-rig", "check"], "virtual"),
    ],
)
def test_a_command_that_needs_an_extra_names_it_in_one_line(tmp_path, argv, extra):
    proc = _run(f"from helpers.__main__ import main\nsys.exit(main({argv!r}))\n", tmp_path)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 1
    assert len(lines) == 1 and f"[{extra}] extra" in lines[0] and f'pip install -e ".[{extra}]"' in lines[0]
