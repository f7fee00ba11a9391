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

from helpers.base.paths import DATA_DIR, FIGURES_ENV, REPO_ROOT, USER_DATA_ENV

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


def _files(folder: Path) -> dict[Path, tuple[int, int]]:
    """Every data file's size and time; not the folder locks (``.lock``, gitignored), which any reader of the
    folder creates if it is missing (in a fresh clone the first one, maybe another test's, at any moment)."""
    return {p: (p.stat().st_size, p.stat().st_mtime_ns) for p in folder.rglob("*")
            if p.is_file() and not p.name.endswith(".lock")}  # fmt: skip


def test_live_cells_record_into_my_data_and_the_cells_below_analyse_it_there(tmp_path: Path) -> None:
    # notebooks 00 and 02 with LIVE = True on the in-process virtual rig, injected after the parameters cell
    # as papermill does: the calibration, the identification run and its result go to my_data/<rig>/ (a
    # temporary folder here), the analysis below reads them there, and nothing under data/ changes
    script = []
    for name in ("00_rig_and_calibration.ipynb", "02_pulse_identification.ipynb"):
        before, params, after = _parts(REPO_ROOT / "notebooks" / name)
        script += [*before, params, "LIVE = True", *after]
        if name.startswith("00"):
            script.append("print('analysed', *sorted({str(r.path.parent) for r in cal_recs}))")
    data, my_data = _files(DATA_DIR), (REPO_ROOT / "my_data").exists()
    env = {**os.environ, USER_DATA_ENV: str(tmp_path / "my_data"), FIGURES_ENV: str(tmp_path / "figures"),
           "MPLBACKEND": "Agg"}  # fmt: skip
    out = subprocess.run([sys.executable, "-c", "\n".join(script)], capture_output=True, text=True, env=env,
                         cwd=REPO_ROOT / "notebooks", timeout=600)  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    mine = tmp_path / "my_data" / "paper"
    loads = sorted(p.name for p in (mine / "calibration").glob("load_*g.csv"))
    assert loads == [f"load_{g:04d}g.csv" for g in (0, 200, 500, 1000, 1500, 1900)]  # the notebook's masses
    assert f"analysed {mine / 'calibration'}\n" in out.stdout  # notebook 00's fit: the new recordings
    # notebook 02: the run recorded with the calibration just made, and the result its analysis checks
    run = json.loads((mine / "identification" / "pulse_v100_x10.json").read_text())
    assert run["source"]["kind"] == "virtual-rig" and run["calibration"]["origin"] == [
        str(mine / "calibration" / "calibration.json")
    ]
    assert f"stored {mine / 'identification' / 'result.json'}: zeta = " in out.stdout
    assert "it matches this analysis: yes" in out.stdout
    assert _files(DATA_DIR) == data and (REPO_ROOT / "my_data").exists() == my_data
