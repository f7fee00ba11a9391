"""``python -m helpers reproduce``: execute every numbered notebook in place and summarise.

Each notebook runs top to bottom in a fresh kernel (nbclient), from its own folder, with the live cells
inactive (``LIVE = False`` in every parameters cell), and is written back in the stored form
(:func:`normalise`: what a JupyterLab autosave changed in its metadata is undone). Independent notebooks
run two at a time (``--jobs``); a notebook that reads another's output declares it in its metadata.
Figures and tables land in ``figures/``. On the first error the run stops and names the notebook and the
cell.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path

import nbformat
from nbclient import NotebookClient
from nbclient.exceptions import CellExecutionError

from helpers.base.cli import DefaultsHelp, arg_number
from helpers.base.notebook import BATCH_ENV
from helpers.base.paths import FIGURES_DIR, REPO_ROOT
from helpers.commands.summary import print_summary

NOTEBOOKS_DIR: Path = REPO_ROOT / "notebooks"
"""The numbered notebooks."""


class NotebookFailed(RuntimeError):
    """A notebook cell raised; the message names the notebook, the cell index and the error."""


@dataclass(frozen=True)
class NotebookRun:
    """The outcome of executing one notebook."""

    path: Path
    seconds: float
    n_cells: int


def numbered_notebooks(folder: Path = NOTEBOOKS_DIR) -> list[Path]:
    """Return the notebooks named ``NN_topic.ipynb`` in order.

    Parameters
    ----------
    folder : pathlib.Path
        Where to look.

    Returns
    -------
    list of pathlib.Path
        Sorted by name, so by number.
    """
    return sorted(p for p in folder.glob("[0-9][0-9]_*.ipynb"))


def _failing_cell(nb: nbformat.NotebookNode) -> tuple[int, str]:
    """Find the code cell whose stored output is an error (nbclient stores it before raising)."""
    code_index = 0
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        code_index += 1
        for out in cell.get("outputs", []):
            if out.get("output_type") == "error":
                first_line = cell.source.strip().splitlines()[0] if cell.source.strip() else ""
                return code_index, first_line
    return -1, ""


def coalesce_streams(nb: nbformat.NotebookNode) -> None:
    """Merge consecutive ``stdout``/``stderr`` outputs of each cell into one (in place).

    How a kernel splits printed text into stream messages depends on timing; merged, the stored notebook is
    the same on every run (nbval merges them the same way before it compares).
    """
    for cell in nb.cells:
        merged: list = []
        for out in cell.get("outputs", []):
            prev = merged[-1] if merged else None
            if (
                out.get("output_type") == "stream"
                and prev is not None
                and prev.get("output_type") == "stream"
                and prev.get("name") == out.get("name")
            ):
                prev["text"] = prev["text"] + out["text"]
            else:
                merged.append(out)
        if "outputs" in cell:
            cell["outputs"] = merged


KERNELSPEC = {"display_name": "Python 3 (ipykernel)", "language": "python", "name": "python3"}
"""The stored notebooks' kernel: ipykernel's own spec, as JupyterLab writes it when it opens a notebook."""

NOTEBOOK_METADATA = ("kernelspec", "language_info", "helpers")
"""Notebook metadata kept in the stored form (``helpers``: the notebook's dependencies and priority)."""

CELL_METADATA = ("tags",)
"""Cell metadata kept in the stored form; what JupyterLab adds (``collapsed``, ``scrolled``, ``jupyter``,
``execution`` timings, ...) is dropped."""


def normalise(nb: nbformat.NotebookNode) -> nbformat.NotebookNode:
    """Bring a notebook to the stored form (in place), whatever JupyterLab's autosave left in it.

    The kernelspec is :data:`KERNELSPEC`; notebook metadata other than :data:`NOTEBOOK_METADATA` (widget
    state, a kernel name of another environment) and cell metadata other than :data:`CELL_METADATA` are
    dropped. ``language_info`` is what the executing kernel reported. Outputs are left to the execution.

    Returns
    -------
    nbformat.NotebookNode
        ``nb`` itself.
    """
    meta = nb.metadata
    for key in [k for k in meta if k not in NOTEBOOK_METADATA]:
        del meta[key]
    meta["kernelspec"] = nbformat.from_dict(dict(KERNELSPEC))
    for cell in nb.cells:
        for key in [k for k in cell.metadata if k not in CELL_METADATA]:
            del cell.metadata[key]
    return nb


def execute_notebook(path: Path, timeout: int = 600) -> NotebookRun:
    """Execute ``path`` in place in a fresh kernel and write the outputs back.

    Parameters
    ----------
    path : pathlib.Path
        The notebook.
    timeout : int
        Seconds any one cell may take.

    Returns
    -------
    NotebookRun
        Wall time and number of cells.

    Raises
    ------
    NotebookFailed
        If a cell raises; the notebook is still written so the error can be inspected.
    """
    nb = nbformat.read(path, as_version=4)
    os.environ.pop("MPLBACKEND", None)  # an inherited backend would hide inline figures
    os.environ[BATCH_ENV] = "1"  # unattended: interactive cells show their static figure, store no widgets
    client = NotebookClient(
        nb,
        timeout=timeout,
        kernel_name="python3",
        resources={"metadata": {"path": str(path.parent)}},
        # the kernel's start-up notice about its local TCP transport is noise on this one-screen job
        extra_arguments=["--IPKernelApp.log_level=ERROR"],
        record_timing=False,  # no wall-clock timestamps in the committed notebooks
    )
    start = time.perf_counter()
    try:
        client.execute()
    except CellExecutionError as exc:
        coalesce_streams(nb)
        nbformat.write(normalise(nb), path)
        index, first = _failing_cell(nb)
        text = re.sub(r"\x1b\[[0-9;]*m", "", str(exc)).strip()  # no terminal colour codes in the message
        last = text.splitlines()[-1] if text else type(exc).__name__
        raise NotebookFailed(f"{path.name}: code cell {index} ({first!r}) failed: {last}") from exc
    coalesce_streams(nb)
    nbformat.write(normalise(nb), path)
    return NotebookRun(path=path, seconds=time.perf_counter() - start, n_cells=len(nb.cells))


def dependencies(path: Path) -> list[str]:
    """Names of the notebooks that must finish before ``path`` starts.

    A notebook declares them in its metadata when it reads a file that another notebook writes; notebook 03
    (which reads the identification result that notebook 02 saves) has
    ``{"helpers": {"depends_on": ["02_pulse_identification.ipynb"]}}``. Notebooks that only read ``data/``
    declare nothing and may run in parallel.
    """
    meta = nbformat.read(path, as_version=4).metadata.get("helpers", {})
    return list(meta.get("depends_on", []))


def priority(path: Path) -> int:
    """Scheduling priority of ``path``: higher starts first among notebooks that are ready.

    A long notebook declares ``{"helpers": {"priority": 1}}`` so that it runs beside the others instead of
    after them (notebook 06 simulates the virtual rig and, in a fresh environment, compiles it first).
    """
    return int(nbformat.read(path, as_version=4).metadata.get("helpers", {}).get("priority", 0))


def reproduce(notebooks: list[Path] | None = None, timeout: int = 600, jobs: int = 2) -> list[NotebookRun]:
    """Execute the numbered notebooks (in parallel where they are independent) and print a summary.

    Notebooks start in numeric order (higher :func:`priority` first) as soon as a worker is free and their
    declared dependencies (see :func:`dependencies`) have finished. On the first failure no further notebook
    starts, the running ones finish, and :class:`NotebookFailed` names the notebook and the cell.

    Parameters
    ----------
    notebooks : list of pathlib.Path, optional
        Which notebooks; all numbered ones by default.
    timeout : int
        Seconds any one cell may take.
    jobs : int
        Notebooks executed at once (each in its own kernel process).

    Returns
    -------
    list of NotebookRun
        One entry per executed notebook, in numeric order.
    """
    notebooks = numbered_notebooks() if notebooks is None else list(notebooks)
    selected = {p.name for p in notebooks}
    needs = {p.name: [d for d in dependencies(p) if d in selected] for p in notebooks}
    pending = sorted(notebooks, key=lambda p: -priority(p))  # stable: numeric order within a priority
    done: dict[str, NotebookRun] = {}
    failure: NotebookFailed | None = None
    total_start = time.perf_counter()
    with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        running: dict[Future, Path] = {}
        while pending or running:
            if failure is None:
                for path in list(pending):
                    if len(running) >= max(1, jobs):
                        break
                    if all(d in done for d in needs[path.name]):
                        print(f"executing {path.name} ...", flush=True)
                        running[pool.submit(execute_notebook, path, timeout)] = path
                        pending.remove(path)
            else:
                pending.clear()
            if not running:
                break
            finished, _ = wait(running, return_when=FIRST_COMPLETED)
            for fut in finished:
                path = running.pop(fut)
                try:
                    result = fut.result()
                except NotebookFailed as exc:
                    failure = failure or exc
                    continue
                done[path.name] = result
                print(f"  {path.name} done in {result.seconds:.1f} s", flush=True)
    if failure is not None:
        raise failure
    runs = [done[p.name] for p in notebooks]
    total = time.perf_counter() - total_start
    print()
    print(f"{len(runs)} notebooks executed in {total:.1f} s ({max(1, jobs)} at a time)")
    print_summary()
    n_figs = len(list(FIGURES_DIR.glob("*"))) if FIGURES_DIR.exists() else 0
    print(f"{n_figs} files in figures/")
    return runs


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``reproduce`` command's options to ``parser``."""
    parser.formatter_class = DefaultsHelp
    parser.add_argument(
        "--timeout", type=arg_number(1, 86_400, int), default=600, help="seconds any one cell may take"
    )
    parser.add_argument(
        "--jobs", type=arg_number(1, 64, int), default=min(2, os.cpu_count() or 1), help="notebooks at once"
    )
    parser.add_argument(
        "notebooks",
        nargs="*",
        help="only these notebooks: paths, or names such as 05_metric_tables.ipynb or 05 (default: all)",
    )


def resolve_notebook(name: str) -> Path:
    """A notebook given on the command line: a path (from here), a name in ``notebooks/``, or its number."""
    for candidate in (Path(name), NOTEBOOKS_DIR / name, REPO_ROOT / name):
        if candidate.is_file():
            return candidate.resolve()
    matches = sorted(NOTEBOOKS_DIR.glob(f"{name}*.ipynb")) if name else []
    if len(matches) == 1:
        return matches[0].resolve()
    choices = ", ".join(p.name for p in numbered_notebooks())
    raise SystemExit(f"no notebook {name!r} (here, in notebooks/ or by number); the notebooks are: {choices}")


def run(args: argparse.Namespace) -> int:
    """Run ``python -m helpers reproduce``; exit status 1 names the failing notebook and cell."""
    notebooks = [resolve_notebook(n) for n in args.notebooks] or None
    try:
        reproduce(notebooks, timeout=args.timeout, jobs=args.jobs)
    except NotebookFailed as exc:
        print(f"\nERROR: {exc}", file=sys.stderr)
        return 1
    return 0
