"""Which suite runs which notebook: the paper's notebooks 00-05 by default, the wings' in the slow suite.

The expectation is the notebooks' file names in ``notebooks/`` (00-05 the paper's steps, 06 onwards the twin
and the research), listed here by hand rather than from the code that marks them (``conftest.py``).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
PAPER = {"00", "01", "02", "03", "04", "05"}


def _collected(*marker: str) -> set[str]:
    """The two-digit numbers of the notebooks whose nbval cells ``pytest --collect-only`` selects."""
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-n", "0", *marker, "notebooks"],
        cwd=REPO_ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    return {line.split("/")[1][:2] for line in proc.stdout.splitlines() if line.startswith("notebooks/")}


def test_the_default_run_takes_the_paper_notebooks_and_the_slow_run_the_others() -> None:
    every = {p.name[:2] for p in (REPO_ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb")}
    assert PAPER < every  # the wings have notebooks too
    # the default run deselects the slow marker (pyproject's addopts), so this is its complement too
    assert _collected("-m", "slow") == every - PAPER
