"""Notebooks with live cells name their rig in the parameters cell, select it before anything reads it, and
pass it to the command lines they run; a kernel that already runs one rig refuses another."""

from __future__ import annotations

import ast
import importlib.util
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from helpers import rigfile
from helpers.base.paths import REPO_ROOT
from helpers.paper import hardware  # the host's constants, read on import (the paper's rig in the tests)

NOTEBOOKS = sorted((REPO_ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))
USE_LINE = "RIG_FILE = rigfile.use(RIG)"


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
def test_the_parameters_cell_names_the_rig_and_the_next_cell_selects_it(path: Path) -> None:
    before, params, after = _parts(path)
    assert any(line.startswith("RIG = ") for line in params.splitlines()), "no RIG in the parameters cell"
    assert after[0].startswith(USE_LINE), "the cell after the parameters does not select the rig first"
    assert not any(USE_LINE in s for s in after[1:]), "the rig is selected twice"


def _helpers_imports(code: str) -> set[str]:
    mods = set()
    for node in ast.walk(ast.parse(code)):
        if isinstance(node, ast.Import):
            mods |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            mods |= {node.module} | {f"{node.module}.{a.name}" for a in node.names}
    return {m for m in mods if m.split(".")[0] == "helpers"}


def test_nothing_reads_the_rig_before_the_notebooks_select_it() -> None:
    # everything of helpers the cells before the selection import, imported in a fresh process as a kernel
    # would: the host's constants (helpers.paper.hardware) must not have been read yet
    imported: set[str] = set()
    for path in LIVE_NOTEBOOKS:
        before, params, _ = _parts(path)
        imported |= _helpers_imports("\n".join([*before, params]))
    assert "helpers.rigfile" in imported
    code = "import importlib, sys\n"
    code += "".join(f"importlib.import_module({m!r})\n" for m in sorted(imported) if _is_module(m))
    code += "print('helpers.paper.hardware' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"


def _is_module(name: str) -> bool:
    # "helpers.base.paths.DATA_DIR" (a name imported from a module) is not a module
    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:
        return False


@pytest.mark.parametrize("path", LIVE_NOTEBOOKS, ids=lambda p: p.name[:2])
def test_live_command_lines_are_given_the_rig(path: Path) -> None:
    for src in _code_cells(path):
        s = _source(src)
        if '"-m", "helpers"' in s:
            assert '"--rig", str(RIG)' in s, s


def test_a_rig_named_in_the_parameters_cell_is_the_rig_the_cells_use() -> None:
    # notebook 04's cells up to its programmes, with RIG given as papermill injects it: the host's constants
    # follow the long arm (40 mm spool, 1600 steps/rev: pi * 40 / 1600 mm per step, by hand)
    before, params, after = _parts(REPO_ROOT / "notebooks" / "04_experiments.ipynb")
    code = "\n".join([*before, params, 'RIG = "long-arm"', after[0],
                      "from helpers.paper import hardware",
                      "print(hardware.RIG.name, repr(hardware.MM_PER_STEP))"])  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env={**os.environ, "MPLBACKEND": "Agg"}, timeout=120)  # fmt: skip
    assert out.returncode == 0, out.stderr
    lines = out.stdout.strip().splitlines()
    assert lines[0].startswith("rig: long-arm (")
    name, mm = lines[-1].split()
    assert name == "long-arm"
    assert math.isclose(float(mm), math.pi * 40.0 / 1600, rel_tol=1e-12)


def test_a_process_that_runs_one_rig_refuses_another(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(rigfile.ENV_VAR, raising=False)
    assert rigfile.in_use().hash == hardware.RIG.hash == rigfile.default_rig().hash
    with pytest.raises(rigfile.RigFileError, match=r"long-arm\.toml: this process already runs rig 'paper'"):
        rigfile.use("long-arm")
    assert rigfile.ENV_VAR not in os.environ  # nothing selected by the refused call
    assert rigfile.use("paper").hash == hardware.RIG.hash  # the same rig again is fine
