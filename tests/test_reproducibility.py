"""Stored outputs reproduce on any machine: the numbers the notebooks print do not depend on the BLAS thread
count or the CPU, and the figure writers produce the same bytes on every run.

The notebooks print only digits that survive round-off. The numbers that are most sensitive to it (the
linearisation of very fine chains, the frequency map, the identification fit) are computed here in fresh
processes under different settings and must agree far beyond the printed precision. The slow tests execute
every notebook under nbval with one BLAS thread, and on a generic x86-64 target (numba compiled for a generic
CPU, numpy's wide SIMD paths switched off), as stand-ins for other machines.
"""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import nbformat
import numpy as np
import pytest

from helpers.base.paths import REPO_ROOT
from helpers.commands import reproduce
from helpers.commands.reproduce import NOTEBOOKS_DIR

SENSITIVE = r"""
import json
import numpy as np
from helpers import recordings
from helpers.paper.identify import identify_recording
from helpers.base.paths import DATA_DIR
from helpers.virtual import RigParameters, linearise, statics

p = RigParameters()
out = {}
for m in (1, 2, 4, 8):
    lin = linearise(p.replace(elements_per_disc=m), 0.0)
    out[f"omega_d_{m}_per_disc"] = lin.omega_d
    out[f"zeta_{m}_per_disc"] = lin.zeta
fm = statics.frequency_map(p, np.array([0.0, 10.0, 20.0, 30.0, 40.0]))
for col in ("static_tension_n", "omega_d_rad_s", "zeta", "dominant_omega_d_rad_s", "dominant_zeta"):
    out[f"map_{col}"] = fm[col].tolist()
rec = recordings.load(DATA_DIR / "identification" / "pulse_v100_x10")
res = identify_recording(rec, window=(9.0, 10.0), column="adc")
out.update(fit_zeta=res.fit.zeta, fit_omega_d=res.fit.omega_d, logdec_zeta=res.logdec.zeta,
           fft_omega_d=res.fft.omega_d)
print(json.dumps(out))
"""

GENERIC_CPU = {
    # numba compiles for a generic x86-64 target into a cache of its own ...
    "NUMBA_CPU_NAME": "generic",
    # ... and numpy keeps to its baseline (no AVX2/AVX-512 dispatch of its ufuncs)
    "NPY_DISABLE_CPU_FEATURES": "X86_V3,X86_V4,AVX512_ICL,AVX512_SPR",
}
ONE_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def _env(extra: dict[str, str], tmp_path: Path) -> dict[str, str]:
    env = dict(os.environ)
    for key in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_CPU_NAME"):
        env.pop(key, None)
    env.update(extra)
    if "NUMBA_CPU_NAME" in extra:
        env["NUMBA_CACHE_DIR"] = str(tmp_path / "numba-generic")
    return env


def _sensitive(extra: dict[str, str], tmp_path: Path) -> dict:
    env = _env(extra, tmp_path)
    cmd = [sys.executable, "-c", SENSITIVE]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _assert_close(a: dict, b: dict, rtol: float) -> None:
    assert a.keys() == b.keys()
    for key in a:
        x, y = np.asarray(a[key], float), np.asarray(b[key], float)
        np.testing.assert_allclose(x, y, rtol=rtol, err_msg=key)


@pytest.mark.slow  # 14-18 s; the slow suite also runs every notebook under one BLAS thread
def test_sensitive_numbers_do_not_depend_on_blas_threads(tmp_path):
    """One BLAS thread against the default: agreement to 1e-7, 1000 times finer than the printed digits."""
    _assert_close(_sensitive({}, tmp_path), _sensitive(ONE_THREAD, tmp_path), rtol=1e-7)


@pytest.mark.slow
def test_sensitive_numbers_do_not_depend_on_the_cpu(tmp_path):
    _assert_close(_sensitive({}, tmp_path), _sensitive(GENERIC_CPU, tmp_path), rtol=1e-7)


def _reproduce_into(folder: Path, names: list[str], monkeypatch) -> Path:
    """Execute copies of ``names`` in ``folder`` with figures going to ``folder/figures``."""
    folder.mkdir()
    (folder / "figures").mkdir()
    monkeypatch.setenv("HELPERS_FIGURES_DIR", str(folder / "figures"))
    copies = []
    for name in names:
        shutil.copy(NOTEBOOKS_DIR / name, folder / name)
        copies.append(folder / name)
    reproduce.reproduce(copies, timeout=300, jobs=1)
    return folder


def test_figure_writers_produce_identical_bytes_twice(tmp_path, monkeypatch):
    """The figure writers of the notebooks, called twice into two folders: the same PNG bytes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import helpers.base.paths
    from helpers import recordings
    from helpers.base.paths import DATA_DIR
    from helpers.paper.identify import identify_recording
    from helpers.paper.shapers import design_tdfs
    from helpers.plotting import identification
    from helpers.plotting import shapers as shaper_plots

    rec = recordings.load(DATA_DIR / "identification" / "pulse_v100_x10")
    result = identify_recording(rec, window=(9.0, 10.0), column="adc")
    out = {}
    for run in ("a", "b"):
        folder = tmp_path / run
        folder.mkdir()
        monkeypatch.setattr(helpers.base.paths, "FIGURES_DIR", folder)
        identification.fig5_force_response(rec.frame["t_s"], rec.frame["adc"], (9.0, 10.0), save=True)
        identification.fig6_logdec_fft(result, rec.frame["t_s"], rec.frame["adc"], save=True)
        zv, zvd = design_tdfs()
        shaper_plots.sensitivity_curves([zv, zvd], 25.1, 0.044)
        plt.close("all")
        out[run] = {p.name: p.read_bytes() for p in sorted(folder.iterdir())}
    assert len(out["a"]) == 3 and out["a"].keys() == out["b"].keys()
    for name, data in out["a"].items():
        assert data[:8] == b"\x89PNG\r\n\x1a\n"
        assert data == out["b"][name], f"{name} differs between two runs"


@pytest.mark.slow
def test_reproduce_writes_identical_figures_and_notebooks_twice(tmp_path, monkeypatch):
    """Notebook 03 (three figures) executed twice: the same figure bytes and the same notebook bytes."""
    names = ["03_shaper_design.ipynb"]
    first = _reproduce_into(tmp_path / "a", names, monkeypatch)
    second = _reproduce_into(tmp_path / "b", names, monkeypatch)
    figures = sorted(p.name for p in (first / "figures").iterdir())
    assert len(figures) >= 3 and all(name.endswith(".png") for name in figures)
    for name in figures:
        data = (first / "figures" / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n", name
        assert data == (second / "figures" / name).read_bytes(), f"{name} differs between two runs"
    assert (first / names[0]).read_bytes() == (second / names[0]).read_bytes()
    # what reproduce stores carries no timestamps
    nb = nbformat.read(first / names[0], as_version=4)
    assert all("execution" not in cell.get("metadata", {}) for cell in nb.cells)


NBVAL_EVERY_NOTEBOOK = (sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider")
NBVAL_EVERY_NOTEBOOK += ("-m", "slow or not slow")
"""nbval over every notebook: the wings' notebooks carry the ``slow`` marker (``conftest.py``), so ``-m``
selects both."""


@pytest.mark.slow
@pytest.mark.parametrize("setting", ["one-blas-thread", "generic-cpu"])
def test_every_notebook_output_is_identical_under_other_settings(setting, tmp_path):
    """nbval over every notebook with one BLAS thread, or on a generic CPU target: every output matches."""
    extra = ONE_THREAD if setting == "one-blas-thread" else GENERIC_CPU
    env = _env(extra, tmp_path)
    env["HELPERS_FIGURES_DIR"] = str(tmp_path / "figures")
    proc = subprocess.run(
        [*NBVAL_EVERY_NOTEBOOK, str(REPO_ROOT / "notebooks")],
        cwd=REPO_ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=1800,
    )
    assert proc.returncode == 0, proc.stdout[-4000:]
