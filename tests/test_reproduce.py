"""The reproduce job: order, dependencies and the error that names the notebook and the cell."""

import nbformat
import pytest
from nbformat.v4 import new_code_cell, new_notebook

from helpers.commands import reproduce


def _write(path, sources, depends_on=None):
    nb = new_notebook(cells=[new_code_cell(s) for s in sources])
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    if depends_on:
        nb.metadata["helpers"] = {"depends_on": depends_on}
    nbformat.write(nb, path)
    return path


def test_numbered_notebooks_are_sorted_and_filtered(tmp_path):
    for name in ["10_b.ipynb", "02_a.ipynb", "scratch.ipynb", "1_x.ipynb"]:
        _write(tmp_path / name, ["1"])
    assert [p.name for p in reproduce.numbered_notebooks(tmp_path)] == ["02_a.ipynb", "10_b.ipynb"]


def test_dependency_runs_first_and_outputs_are_written(tmp_path):
    marker = tmp_path / "marker.txt"
    # the reader comes first in the list and both may run at once: only the declared dependency orders them
    reader = _write(
        tmp_path / "02_read.ipynb", [f"print(open({str(marker)!r}).read())"], depends_on=["01_write.ipynb"]
    )
    writer = _write(
        tmp_path / "01_write.ipynb", ["import time; time.sleep(1)", f"open({str(marker)!r}, 'w').write('x')"]
    )
    runs = reproduce.reproduce([reader, writer], timeout=60, jobs=2)
    assert sorted(r.path.name for r in runs) == ["01_write.ipynb", "02_read.ipynb"]
    out = nbformat.read(reader, as_version=4).cells[0].outputs
    assert out[0]["text"] == "x\n"


def test_failure_names_notebook_and_cell(tmp_path):
    bad = _write(tmp_path / "03_bad.ipynb", ["x = 1", "raise ValueError('boom')"])
    with pytest.raises(reproduce.NotebookFailed, match=r"03_bad.ipynb: code cell 2 .*ValueError: boom"):
        reproduce.execute_notebook(bad, timeout=60)


@pytest.mark.slow
def test_priority_starts_a_long_notebook_first(tmp_path, capsys):
    a = _write(tmp_path / "01_a.ipynb", ["1"])
    b = _write(tmp_path / "02_b.ipynb", ["2"])
    long = _write(tmp_path / "03_long.ipynb", ["3"])
    nb = nbformat.read(long, as_version=4)
    nb.metadata["helpers"] = {"priority": 1}
    nbformat.write(nb, long)
    reproduce.reproduce([a, b, long], timeout=60, jobs=1)
    lines = capsys.readouterr().out.splitlines()
    started = [line.split()[1] for line in lines if line.startswith("executing")]
    assert started == ["03_long.ipynb", "01_a.ipynb", "02_b.ipynb"]


def test_stream_outputs_are_merged_so_reruns_store_the_same_bytes(tmp_path):
    # a flush and a pause make the kernel send two stream messages for one cell
    src = "import sys, time\nprint('a'); sys.stdout.flush(); time.sleep(0.3)\nprint('b')"
    nb_path = _write(tmp_path / "01_streams.ipynb", [src])
    reproduce.execute_notebook(nb_path, timeout=60)
    outputs = nbformat.read(nb_path, as_version=4).cells[0].outputs
    assert [(o["output_type"], o["name"], o["text"]) for o in outputs] == [("stream", "stdout", "a\nb\n")]


@pytest.mark.slow
def test_reproduce_undoes_what_a_jupyterlab_autosave_changes(tmp_path):
    """Measured: JupyterLab (4.x, ipykernel) that opens a stored notebook rewrites its kernelspec's display
    name within its 2-minute autosave; one that ran it may add widget state, cell metadata and timings."""
    path = _write(tmp_path / "01_saved.ipynb", ["print(1)"])
    clean = reproduce.normalise(nbformat.read(path, as_version=4))
    nb = nbformat.read(path, as_version=4)
    nb.metadata["kernelspec"] = {"display_name": "Python 3 (my env)", "language": "python", "name": "my-env"}
    nb.metadata["widgets"] = {"application/vnd.jupyter.widget-state+json": {"state": {}, "version_major": 2}}
    timing = {"iopub.status.busy": "2026-01-01T00:00:00Z"}
    nb.cells[0].metadata.update(
        {"scrolled": True, "collapsed": False, "jupyter": {"source_hidden": True}, "execution": timing,
         "tags": ["x"]}
    )  # fmt: skip
    nbformat.write(nb, path)
    reproduce.execute_notebook(path, timeout=60)
    back = nbformat.read(path, as_version=4)
    assert back.metadata["kernelspec"] == reproduce.KERNELSPEC == clean.metadata["kernelspec"]
    assert "widgets" not in back.metadata and back.metadata["language_info"]["name"] == "python"
    assert dict(back.cells[0].metadata) == {"tags": ["x"]}
    assert back.cells[0].outputs[0]["text"] == "1\n"


def test_the_stored_notebooks_are_in_the_stored_form():
    """What reproduce writes: an autosave that only opened a notebook (the measured kernelspec change)
    leaves its bytes as they are."""
    for path in reproduce.numbered_notebooks():
        raw = path.read_text(encoding="utf-8")
        nb = nbformat.reads(raw, as_version=4)
        normal = reproduce.normalise(nbformat.reads(raw, as_version=4))
        assert nbformat.writes(normal) == nbformat.writes(nb), path
        assert nb.metadata["kernelspec"] == reproduce.KERNELSPEC, path
