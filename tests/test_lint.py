"""The code style gate: ruff over the package, the tests and the notebooks (part of the test command)."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from helpers.base.paths import REPO_ROOT


def test_ruff_clean():
    beside = Path(sys.executable).with_name("ruff")  # the environment's own ruff, even if not on PATH
    ruff = str(beside) if beside.exists() else shutil.which("ruff")
    if ruff is None:
        pytest.skip("ruff is not installed: pip install -r environment.txt")
    result = subprocess.run(
        [ruff, "check", "."], cwd=REPO_ROOT, capture_output=True, text=True
    )
    assert result.returncode == 0, result.stdout + result.stderr


def test_cli_help_lists_reproduce():
    result = subprocess.run(
        [sys.executable, "-m", "helpers", "--help"], cwd=REPO_ROOT, capture_output=True, text=True
    )
    assert result.returncode == 0
    assert "reproduce" in result.stdout
