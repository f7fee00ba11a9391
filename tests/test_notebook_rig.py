"""Notebooks with live cells name their rig in the parameters cell and load it, once, as a value the cells
pass on (to the drivers and to the command lines they run); one kernel may hold several rigs."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from helpers.base.paths import REPO_ROOT

NOTEBOOKS = sorted((REPO_ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))
LOAD_LINE = "RIG_FILE = rigfile.load(rigfile.resolve(RIG))"


def _code_cells(path: Path) -> list[dict]:
    return [c for c in json.loads(path.read_text())["cells"] if c["cell_type"] == "code"]


def _source(cell: dict) -> str:
    return "".join(cell["source"])


def _live(path: Path) -> bool:
    return any(_source(c).startswith("# NBVAL_SKIP") and "LIVE" in _source(c) for c in _code_cells(path))


LIVE_NOTEBOOKS = [p for p in NOTEBOOKS if _live(p)]


def _parts(path: Path) -> tuple[list[str], str, list[str]]:
    """(code before the parameters cell, the parameters cell, code from the cell after it on)."""
    cells = _code_cells(path)
    i = next(k for k, c in enumerate(cells) if "parameters" in c["metadata"].get("tags", []))
    return [_source(c) for c in cells[:i]], _source(cells[i]), [_source(c) for c in cells[i + 1 :]]


def test_the_notebooks_with_live_cells_are_the_expected_ones() -> None:
    # the calibration, the identification, the experiments, tune and the streams record; the others analyse
    assert [p.name[:2] for p in LIVE_NOTEBOOKS] == ["00", "02", "04", "07", "08", "10"]


@pytest.mark.parametrize("path", LIVE_NOTEBOOKS, ids=lambda p: p.name[:2])
def test_the_parameters_cell_names_the_rig_and_the_next_cell_loads_it(path: Path) -> None:
    before, params, after = _parts(path)
    assert any(line.startswith("RIG = ") for line in params.splitlines()), "no RIG in the parameters cell"
    assert after[0].startswith(LOAD_LINE), "the cell after the parameters does not load the rig first"
    assert not any(LOAD_LINE in s for s in after[1:]), "the rig is loaded twice"


@pytest.mark.parametrize("path", LIVE_NOTEBOOKS, ids=lambda p: p.name[:2])
def test_live_command_lines_are_given_the_rig(path: Path) -> None:
    for src in _code_cells(path):
        s = _source(src)
        if '"-m", "helpers"' in s:
            assert '"--rig", str(RIG)' in s, s


def test_a_rig_named_in_the_parameters_cell_is_the_rig_the_cells_use() -> None:
    # notebook 04's cells up to its first analysis, with RIG given as papermill injects it, then the paper's
    # rig in the same kernel: each value keeps its own numbers (the long arm's 40 mm spool and 1600 steps/rev:
    # pi * 40 / 1600 mm per step, by hand), nothing is selected for the process
    before, params, after = _parts(REPO_ROOT / "notebooks" / "04_experiments.ipynb")
    code = "\n".join([*before, params, 'RIG = "long-arm"', after[0],
                      "other = rigfile.load(rigfile.resolve('paper'))",
                      "print(RIG_FILE.name, repr(rigfile.derived(RIG_FILE).mm_per_step[0]), other.name, "
                      "repr(rigfile.derived(other).mm_per_step[0]))"])  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={**os.environ, "MPLBACKEND": "Agg"}, timeout=120)  # fmt: skip
    assert out.returncode == 0, out.stderr
    lines = out.stdout.strip().splitlines()
    assert lines[0].startswith("rig: long-arm (")
    name, mm, other, other_mm = lines[-1].split()
    assert (name, other) == ("long-arm", "paper")
    assert math.isclose(float(mm), math.pi * 40.0 / 1600, rel_tol=1e-12)
    assert math.isclose(float(other_mm), math.pi * 65.0 / 800, rel_tol=1e-12)
