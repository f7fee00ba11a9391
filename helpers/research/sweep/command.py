"""``python -m helpers sweep``: run sweeps, design the robust shapers, regenerate the robustness atlas.

Actions (``docs/sweeps.md``):

- ``run DEF.json [DEF.json ...]``: run each definition (or finish it where it stopped) and write its
  dataset, by default beside the definition with the suffix ``.nc``;
- ``design``: tune the families and optimise the robust shapers on the linear model, write the design set;
- ``atlas``: ``design``, the atlas's definitions (:mod:`helpers.research.sweep.presets`) and their ``run``, in
  ``data/sweeps/`` (``--full``: the full atlas, in ``data/sweeps/full/``);
- ``info FILE.nc``: what a stored sweep holds.

Chunks run on a local Dask cluster of one worker per core, on ``--scheduler ADDRESS``, or with ``--serial``
in this process. Ctrl-C (or SIGTERM) keeps the finished chunks; the same command resumes.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from helpers.base.cli import DefaultsHelp, arg_number
from helpers.base.jsonfile import DataFileError, write_json
from helpers.base.paths import DATA_DIR
from helpers.research.robustness import robust_designs, save_designs, uncertainty_model
from helpers.research.sweep.definition import SweepDefinition, load_definition
from helpers.research.sweep.execute import SweepReport, run_sweep
from helpers.research.sweep.files import load_sweep
from helpers.research.sweep.presets import DESIGNS_FILE, atlas_definitions

SWEEPS_DIR = DATA_DIR / "sweeps"
"""Where the atlas's definitions, design set and stored datasets live."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``sweep`` command's actions and options."""
    parser.formatter_class = DefaultsHelp
    sub = parser.add_subparsers(dest="action", required=True, metavar="action")
    run = sub.add_parser("run", help="run sweep definitions (JSON) and write their datasets (.nc)",
                         formatter_class=DefaultsHelp)  # fmt: skip
    run.add_argument("definitions", nargs="+", type=Path, help="definition files")
    run.add_argument("--output", type=Path, help="the dataset file (one definition only; default: DEF.nc)")
    atlas = sub.add_parser("atlas", help="design, write and run the robustness atlas's sweeps (notebook 09)",
                           formatter_class=DefaultsHelp)  # fmt: skip
    atlas.add_argument("--full", action="store_true", help="the full atlas (hours), in data/sweeps/full/")
    atlas.add_argument("--out-dir", type=Path, help="folder (default data/sweeps, or data/sweeps/full)")
    for p in (run, atlas):
        p.add_argument("--scheduler", help="address of a running Dask scheduler (default: a local cluster)")
        p.add_argument(
            "--workers", type=arg_number(1, 1024, int), help="local cluster's workers (default: cores)"
        )
        p.add_argument("--threads", type=arg_number(1, 256, int), default=1, help="batch threads per task")
        p.add_argument("--serial", action="store_true", help="no Dask: run the chunks in this process")
        p.add_argument("--overwrite", action="store_true", help="replace existing dataset files")
        p.add_argument("--keep-parts", action="store_true", help="keep the finished chunks' folder")
        p.add_argument("--no-progress", action="store_true", help="no progress bar")
    design = sub.add_parser("design", help="tune the families and optimise the robust shapers (linear model)",
                            formatter_class=DefaultsHelp)  # fmt: skip
    design.add_argument("--output", type=Path, default=SWEEPS_DIR / DESIGNS_FILE, help="the design set")
    design.add_argument("--draws", type=arg_number(16, 100_000, int), default=1024, help="draws of the model")
    design.add_argument("--seed", type=arg_number(0, 2**31 - 1, int), default=0, help="the draws' seed")
    info = sub.add_parser("info", help="what a stored sweep holds")
    info.add_argument("dataset", type=Path, help="a sweep's .nc file")


def _summary(report: SweepReport, name: str) -> str:
    return (
        f"{name}: {report.runs} runs in {report.chunks} chunks ({report.resumed} found on disk, "
        f"{report.computed} computed on {report.where}) in {report.wall_s:.1f} s; {report.refused} refused "
        f"-> {os.path.relpath(report.output)}"
    )


def _run(definitions: list[tuple[SweepDefinition, Path]], args: argparse.Namespace) -> None:
    existing = [out for _, out in definitions if out.exists()]
    if existing and not args.overwrite:
        raise DataFileError(f"{existing[0]} exists already: pass --overwrite to replace it")
    for d, out in definitions:
        _, report = run_sweep(
            d, out, scheduler=args.scheduler, workers=args.workers, threads=args.threads, serial=args.serial,
            progress=not args.no_progress, overwrite=args.overwrite, keep_parts=args.keep_parts,
        )  # fmt: skip
        for line in report.rejected:
            print(f"note: {line}", file=sys.stderr)
        print(_summary(report, d.name), flush=True)


def _design(output: Path, draws: int, seed: int) -> None:
    t0 = time.perf_counter()
    designs = robust_designs(uncertainty_model(), n_draws=draws, seed=seed)
    save_designs(designs, output)
    table = designs.table()
    print(f"robust shapers on the linear model ({draws} draws, {time.perf_counter() - t0:.0f} s) "
          f"-> {os.path.relpath(output)}")  # fmt: skip
    for row in table.itertuples():
        ms, pct = 1e3 * row.duration_s, row.objective_pct
        print(f"  {row.name:16s} {row.family:14s} {ms:6.1f} ms  p95 {pct:6.2f} %")


def run(args: argparse.Namespace) -> int:
    """Run the ``sweep`` command."""
    if args.action == "run":
        if args.output is not None and len(args.definitions) != 1:
            raise ValueError("--output needs exactly one definition")
        defs = []
        for path in args.definitions:
            out = args.output if args.output is not None else path.with_suffix(".nc")
            defs.append((load_definition(path), out))
        _run(defs, args)
    elif args.action == "design":
        _design(args.output, args.draws, args.seed)
    elif args.action == "atlas":
        folder = args.out_dir or (SWEEPS_DIR / "full" if args.full else SWEEPS_DIR)
        folder.mkdir(parents=True, exist_ok=True)
        _design(folder / DESIGNS_FILE, 1024, 0)
        defs = []
        for d in atlas_definitions(uncertainty_model(), full=args.full):
            path = write_json(folder / f"{d.name}.json", d.to_dict())
            defs.append((load_definition(path), path.with_suffix(".nc")))
        _run(defs, args)
    else:
        ds = load_sweep(args.dataset)
        definition = json.loads(ds.attrs["definition"])
        print(f"{args.dataset}: sweep {definition['name']!r}, {ds.attrs['code_version']}, physics "
              f"{ds.attrs['physics_fingerprint']}")  # fmt: skip
        print("  dimensions: " + ", ".join(f"{k} {v}" for k, v in ds.sizes.items()))
        print(f"  runs: {int(ds['status'].size)}, refused or failed: {int((ds['status'] > 0).sum())}")
        print("  variables: " + ", ".join(ds.data_vars))
    return 0
