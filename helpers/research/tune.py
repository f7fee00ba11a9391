"""``python -m helpers tune``: measure the arm's modes across its configurations, design shapers, verify them.

One command for what the paper does once at rest, done where the arm actually is (``docs/shaper_design.md``):

1. **identify** the mode map (:mod:`helpers.research.survey`: hold the cable at 0-40 mm, kick it, identify
two modes
   from each ring-down), saved as ``<data>/tuning/mode_map.json`` with the recordings in
   ``<data>/tuning/survey/``;
2. **design** the candidates of :data:`CANDIDATES` for each condition of the grid from that map (and the
   paper's two TDFs from the identified mode at rest), saved in ``<data>/tuning/designs/``;
3. **verify** each by running it on the rig (:data:`REPETITIONS` runs per condition by default), recordings in
   ``<data>/tuning/verify/`` (Table I grid) or ``<data>/tuning/wide/`` (the wider grid; regenerated, not
   committed), and measure each move's residual vibration, its noise floor, its duration and the Table II
   metrics (:func:`helpers.research.residuals.move_residuals`);
4. **report**: ``<data>/tuning/tuning_report.{md,csv,png}`` (notebook 07 alone writes ``figures/``'s) and
   ``<data>/tuning/<grid>_verification.json`` (every run's rows, so that notebook 07 needs no recordings),
   and **choose**: the candidate whose worst measured residual over every move of the grid is lowest among
   those whose moves are no longer than the paper's non-robust TDF's, written to
   ``<data>/tuning/chosen.json``.

The same code runs on the in-process virtual rig (``--ports virtual``, the default), the pseudo-terminal
server and hardware (``--ports auto``).
"""

from __future__ import annotations

import argparse
import contextlib
import itertools
import json
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from tqdm.auto import tqdm

from helpers import recordings
from helpers.base.cli import DefaultsHelp, arg_number, needs
from helpers.base.jsonfile import write_json
from helpers.base.locks import folder_lock
from helpers.base.paths import figure_path, repo_path, user_data_dir
from helpers.base.style import SYSTEM_COLOURS
from helpers.paper import numbers as paper
from helpers.paper import scaling_notes, scenarios
from helpers.paper.identify import load_identification
from helpers.paper.shapers import design_tdfs
from helpers.paper.tension import load_calibration
from helpers.recordings import RecordingExists
from helpers.research import design, residuals, tune_tendons
from helpers.research.lane_runs import in_lanes, record_in_lanes
from helpers.research.modemap import ModeMap, load_map, refuse_map_of_other_rig
from helpers.research.survey import POSITIONS_MM, survey
from helpers.rig import Rig
from helpers.rigfile import RigFile
from helpers.virtual import ArmPlant
from helpers.virtual.plant import LANE_WIDTHS
from helpers.virtual.rig_file_tuning import refuse_other_rig

CANDIDATES = ("zv", "zvd", "ei", "multi-mode", "scheduled", "map-following", "auto")
"""What ``tune`` designs and verifies, by ``scenario.system`` name (``docs/shaper_design.md``): the paper's
non-robust (zv) and robust (zvd) TDFs from the mode at rest; EI centred on the band a move sweeps; the
dominant mode's ZVD convolved with a ZV on the second mode; a ZV pair scheduled on the configuration of each
move's residual (Up: destination, Down: rest); a ZV whose impulse spacing follows the map during the move; the
automatic choice (the shortest candidate whose predicted residual stays within the tolerance)."""

GRIDS = {
    "table-i": tuple(paper.TABLE_I_CONDITIONS),
    "wide": tuple((v, x) for x in (10.0, 20.0, 30.0, 39.0) for v in (100.0, 200.0, 300.0, 400.0)),
}
"""(v_in mm/s, x_f mm) of each grid. The wide grid stops at 39 mm: 40 mm is 157 whole steps, one past the
travel limit."""


def rig_grid(name: str, rig: RigFile) -> tuple[tuple[float, float], ...]:
    """The grid ``name`` on ``rig``: :data:`GRIDS`, scaled where it does not fit."""
    return scenarios.scaled(GRIDS[name], rig)


def rig_positions(rig: RigFile) -> tuple[float, ...]:
    """The survey positions on ``rig``: ``POSITIONS_MM``, spread over a shorter travel."""
    return scenarios.survey_positions(POSITIONS_MM, rig)

REPETITIONS = {"table-i": 3, "wide": 1}
"""Default runs per condition and candidate."""
RATE_HZ = 500
"""DAQ rate of the verification runs, Hz (4 Hz to 12 Hz vibrations; halves what is stored)."""
T_END_S = 10.0
"""Length of a verification run, s (up at 1 s, down at 8 s, 2 s after the down move for its residual)."""
TOLERANCE_PCT = 5.0
"""Default tolerance of the automatic choice, % predicted residual."""


@dataclass
class Candidates:
    """The designs of one grid: ``designs[(v_in, x_f)][system]`` (None where none could be made) and why."""

    designs: dict[tuple[float, float], dict[str, design.Design | None]]
    notes: dict[tuple[float, float], dict[str, str]]


def condition_name(v: float, x: float) -> str:
    """The file-name part of a move, e.g. ``v200_x20`` (design files, verification runs)."""
    return f"v{v:g}_x{x:g}".replace(".", "p")


def design_candidates(
    mode_map: ModeMap,
    rest_mode: tuple[float, float],
    grid: tuple[tuple[float, float], ...],
    tolerance_pct: float = TOLERANCE_PCT,
    include_minimax: bool = False,
) -> Candidates:
    """Every candidate of :data:`CANDIDATES` for every condition of ``grid``.

    Parameters
    ----------
    mode_map : helpers.research.modemap.ModeMap
        The measured map.
    rest_mode : (float, float)
        ``(omega_d, zeta)`` identified at rest: the paper's two TDFs are designed from it.
    grid : tuple of (v_in, x_f)
        The conditions.
    tolerance_pct : float
        Tolerance of the automatic choice.
    include_minimax : bool
        Let the automatic choice consider minimax designs too (slower: seconds per condition).

    Returns
    -------
    Candidates
    """
    zv, zvd = design_tdfs(*rest_mode)
    out: dict[tuple[float, float], dict[str, design.Design | None]] = {}
    notes: dict[tuple[float, float], dict[str, str]] = {}
    for v, x in grid:
        fixed_zv_duration = float(zv.duration)
        made: dict[str, design.Design | None] = {
            "zv": design.as_design(zv, "zv", origin="identified mode at rest"),
            "zvd": design.as_design(zvd, "zvd", origin="identified mode at rest"),
            "ei": design.band_centred(mode_map, x, "EI"),
            "multi-mode": design.multi_mode_design(mode_map, x) if mode_map.has_second_mode else None,
            "scheduled": design.scheduled_pair(mode_map, x, "ZV"),
            "map-following": design.map_following(mode_map, x, v, "ZV"),
        }
        note: dict[str, str] = {}
        if made["multi-mode"] is None:
            note["multi-mode"] = "the map has no second mode"
        choice = design.auto_choice(
            mode_map, x, tolerance_pct=tolerance_pct, include_minimax=include_minimax
        )
        capped = design.auto_choice(
            mode_map, x, tolerance_pct=tolerance_pct, max_duration_s=fixed_zv_duration,
            include_minimax=include_minimax,
        )  # fmt: skip
        note["auto (no longer than zv)"] = capped.message
        made["auto"] = choice.design
        for d in made.values():  # the map's prediction travels with each convolution design
            if d is not None and d.kind != "schedule":
                d.provenance["worst_predicted_pct"] = design.worst_predicted_pct(d, mode_map, x)
        note["auto"] = choice.message
        out[(v, x)] = made
        notes[(v, x)] = note
    return Candidates(out, notes)


def verify(
    rig: Rig,
    candidates: Candidates,
    folder: Path,
    repetitions: int,
    *,
    rate_hz: int = RATE_HZ,
    replace: bool = False,
    seeds: Callable[[], int | None] = lambda: None,
    progress: bool = True,
    lanes: int = 0,
) -> pd.DataFrame:
    """Run every candidate on every condition ``repetitions`` times; one row per run and move.

    ``lanes`` (0, the default: every run in ``rig``'s world, one after the other, each starting where the one
    before left the arm and the device clock; what made ``data/tuning``): on the in-process virtual rig of one
    tendon, each run in a fresh world of its own (at rest, ``t = 0``, named ``<world>.<run>``), up to
    ``lanes`` of them at once with their plants in the lanes of one kernel call
    (:mod:`helpers.virtual.emulator.lockstep`). Its recordings do not depend on ``lanes`` (1 to 8), and differ
    from the chained runs' (``docs/shaper_design.md``). Hardware, the pseudo-terminal server and the spatial
    twin (several tendons) ignore it.

    Returns
    -------
    pandas.DataFrame
        ``system``, ``v_in_mm_s``, ``x_f_mm``, ``repetition``, ``recording`` and the columns of
        :func:`helpers.research.residuals.move_residuals`.
    """
    if type(lanes) is not int or not 0 <= lanes <= max(LANE_WIDTHS):
        raise ValueError(f"lanes must be an integer in 0-{max(LANE_WIDTHS)}, got {lanes!r}")
    jobs = [
        (cond, system, d, k)
        for cond, systems in candidates.designs.items()
        for system, d in systems.items()
        if d is not None
        for k in range(1, repetitions + 1)
    ]
    names = [f"{system}_{condition_name(v, x)}_r{k}".replace("-", "_") for (v, x), system, _, k in jobs]

    def record(r: Rig, job: tuple, name: str, seed: int | None) -> recordings.Recording:
        (v, x), system, d, k = job
        return r.run_pulse(v, x, d, system=system, path=folder / name, repetition=k, t_end_s=T_END_S,
                           rate_hz=rate_hz, progress=False, replace=replace, noise_seed=seed)  # fmt: skip

    if lanes and in_lanes(rig) and isinstance(rig.world.plant, ArmPlant):
        bar = tqdm(total=len(jobs), desc="verify", unit="run", disable=not progress)
        recs = record_in_lanes(rig, jobs, names, [seeds() for _ in jobs], record, lanes, done=bar.update)
        bar.close()
    else:
        recs = (record(rig, job, name, seeds()) for job, name in zip(jobs, names, strict=True))
        recs = tqdm(recs, total=len(jobs), desc="verify", unit="run", disable=not progress)
    rows = []
    for ((v, x), system, _, k), name, rec in zip(jobs, names, recs, strict=True):
        table = residuals.move_residuals(rec.frame)
        table.insert(0, "recording", name)
        table.insert(0, "repetition", k)
        table.insert(0, "x_f_mm", x)
        table.insert(0, "v_in_mm_s", v)
        table.insert(0, "system", system)
        rows.append(table)
    return pd.concat(rows, ignore_index=True)


def summarise(rows: pd.DataFrame) -> pd.DataFrame:
    """Mean (and spread) over repetitions per system, condition and motion."""
    keys = ["system", "v_in_mm_s", "x_f_mm", "motion"]
    agg = rows.groupby(keys, sort=False).agg(
        runs=("residual_pct", "size"),
        residual_pct=("residual_pct", "mean"),
        residual_sd=("residual_pct", "std"),
        noise_floor_pct=("noise_floor_pct", "mean"),
        move_duration_s=("move_duration_s", "mean"),
        peak_n=("peak_n", "mean"),
        overshoot_pct=("overshoot_pct", "mean"),
        settling_ms=("settling_ms", "mean"),
        slack=("slack", "any"),
    )
    return agg.reset_index()


def choose(summary: pd.DataFrame, reference: str = "zv") -> dict[str, Any]:
    """The candidate with the lowest worst residual of those whose moves are no longer than ``reference``'s.

    Parameters
    ----------
    summary : pandas.DataFrame
        Output of :func:`summarise`.
    reference : str
        The system whose move durations cap the others (the paper's non-robust TDF).

    Returns
    -------
    dict
        ``system``, ``worst_residual_pct``, ``criterion`` and ``table`` (every system's worst residual and
        whether it keeps within the duration cap).
    """
    ref = summary[summary["system"] == reference].set_index(["v_in_mm_s", "x_f_mm", "motion"])[
        "move_duration_s"
    ]
    rows = []
    for system, g in summary.groupby("system", sort=False):
        g = g.set_index(["v_in_mm_s", "x_f_mm", "motion"])
        cap = ref.reindex(g.index)
        within = bool(np.all(g["move_duration_s"] <= cap + 0.0015))  # a 500 Hz sample of slack
        rows.append(
            {
                "system": system,
                "worst_residual_pct": float(g["residual_pct"].max()),
                "mean_residual_pct": float(g["residual_pct"].mean()),
                "within_duration_cap": within,
            }
        )
    table = pd.DataFrame(rows)
    eligible = table[table["within_duration_cap"]]
    criterion = f"lowest worst residual among the systems whose moves are no longer than {reference}'s"
    if eligible.empty:
        eligible, criterion = table, "lowest worst residual (no system kept within the duration cap)"
    best = eligible.sort_values(["worst_residual_pct", "mean_residual_pct"]).iloc[0]
    return {
        "system": str(best["system"]),
        "worst_residual_pct": float(best["worst_residual_pct"]),
        "criterion": criterion,
        "table": table,
    }


def report_figure(summary: pd.DataFrame, grid_name: str, source: str) -> plt.Figure:
    """Residual vibration of every candidate, per condition and motion, with the measure's noise floor."""
    conditions = list(dict.fromkeys(zip(summary["v_in_mm_s"], summary["x_f_mm"], strict=True)))
    systems = list(dict.fromkeys(summary["system"]))
    fig, axes = plt.subplots(
        2, len(conditions), figsize=(2.6 * len(conditions) + 1.0, 5.2), sharey="row", squeeze=False
    )
    colours = {s: SYSTEM_COLOURS.get(s, f"C{i + 2}") for i, s in enumerate(systems)}
    for j, (v, x) in enumerate(conditions):
        for i, motion in enumerate(("Up", "Down")):
            ax = axes[i][j]
            g = summary[
                (summary["v_in_mm_s"] == v) & (summary["x_f_mm"] == x) & (summary["motion"] == motion)
            ]
            g = g.set_index("system").reindex(systems)
            ax.bar(
                range(len(systems)),
                g["residual_pct"],
                color=[colours[s] for s in systems],
                yerr=g["residual_sd"].fillna(0.0),
                capsize=2,
            )
            ax.axhline(float(np.nanmean(g["noise_floor_pct"])), color="k", lw=0.8, ls=":")
            ax.set_xticks(range(len(systems)), systems, rotation=60, fontsize=7)
            ax.set_title(f"{x:g} mm at {v:g} mm/s, {motion}", fontsize=8)
        axes[0][j].tick_params(labelbottom=False)
    axes[0][0].set_ylabel("Up residual (% of step)")
    axes[1][0].set_ylabel("Down residual (% of step)")
    fig.suptitle(
        f"Residual vibration 0.1-1.1 s after each move ({source}; {grid_name} grid); "
        "dotted: the measure's noise floor",
        fontsize=9,
    )
    fig.tight_layout()
    return fig


def rows_of(document: dict[str, Any]) -> pd.DataFrame:
    """The per-run rows of a verification document (``<data>/tuning/<grid>_verification.json``)."""
    return pd.DataFrame(document["rows"])


def report_markdown(document: dict[str, Any]) -> str:
    """The report's Markdown: every system's worst and mean residual, the duration check, the choice."""
    chosen = choose(summarise(rows_of(document)))
    src = document["source"]
    lines = [
        f"# Tuning report ({src['kind']}, {document['grid']} grid, {src['repetitions']} run(s) each)",
        "",
        "| system | worst residual % | mean residual % | moves no longer than zv's |",
        "|---|---|---|---|",
    ]
    lines += [
        f"| {r.system} | {r.worst_residual_pct:.1f} | {r.mean_residual_pct:.1f} | {r.within_duration_cap} |"
        for r in chosen["table"].itertuples()
    ]
    lines += ["", f"Chosen: **{chosen['system']}** ({chosen['criterion']}).", ""]
    return "\n".join(lines) + "\n"


def write_report(document: dict[str, Any], folder: Path | None = None) -> list[Path]:
    """Write ``tuning_report[_<grid>].{csv,md,png}`` from a verification document into ``figures/``.

    ``python -m helpers tune`` calls it after a run, and notebook 07 calls it again from the stored
    document (its figures and tables are what ``reproduce`` regenerates).

    Parameters
    ----------
    document : dict
        The verification document.
    folder : pathlib.Path, optional
        Write there instead of ``figures/`` (``tune --data-dir`` elsewhere: the report stays beside its data
        and the repository's figures are left alone).

    Returns
    -------
    list of pathlib.Path
        The three files.
    """
    grid = document["grid"]
    stem = "tuning_report" if grid == "table-i" else f"tuning_report_{grid}"
    summary = summarise(rows_of(document))
    source = str(document["source"]["kind"])
    if folder is not None:
        folder.mkdir(parents=True, exist_ok=True)
    where = figure_path if folder is None else (lambda name: folder / name)
    csv, md, png = (where(f"{stem}.{ext}") for ext in ("csv", "md", "png"))
    summary.assign(source=source).to_csv(csv, index=False, float_format="%.6g")
    md.write_text(report_markdown(document))
    fig = report_figure(summary, grid, source)
    fig.savefig(png)
    plt.close(fig)
    return [csv, md, png]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``python -m helpers tune``."""
    parser.formatter_class = DefaultsHelp
    parser.description = (
        "Measure the arm's modes at 0-40 mm of cable, design shapers from that map, verify each by running "
        "it on the rig, and write the report and the chosen design (docs/shaper_design.md)."
    )
    parser.add_argument(
        "--ports",
        default="virtual",
        help="'virtual' (in-process virtual rig), 'auto' (boards by USB id) or 'DAQ,STEPPER' device paths",
    )
    parser.add_argument(
        "--grid",
        choices=sorted(GRIDS),
        default="table-i",
        help="table-i: the paper's four conditions; wide: 10-39 mm x 100-400 mm/s",
    )
    parser.add_argument(
        "--repetitions",
        type=arg_number(1, 20, int),
        default=None,
        help="verification runs per condition and candidate (default: 3 for table-i, 1 for wide)",
    )
    parser.add_argument(
        "--survey-repetitions", type=arg_number(1, 10, int), default=1, help="runs per survey position"
    )
    parser.add_argument(
        "--reuse-map",
        action="store_true",
        help="design from the saved mode_map.json instead of surveying again",
    )
    parser.add_argument(
        "--tolerance",
        type=arg_number(0, 100, lo_open=True),
        default=TOLERANCE_PCT,
        help="tolerance of the automatic choice, %% predicted residual",
    )
    parser.add_argument(
        "--minimax",
        action="store_true",
        help="let the automatic choice consider minimax designs (seconds per condition)",
    )
    parser.add_argument(
        "--rate",
        type=arg_number(1, 100_000, int),
        default=RATE_HZ,
        help="DAQ rate of the runs, Hz (within the rig file's daq_rate_min_hz-daq_rate_max_hz)",
    )
    parser.add_argument(
        "--seed",
        type=arg_number(0, 2**31, int),
        default=1000,
        help="in-process virtual rig: noise seed of the first run (run k: seed + k)",
    )
    parser.add_argument(
        "--directions", metavar="LIST", default=None,
        help="a rig with several tendons: the bend directions, deg (0,45,90 or start:stop:step; default "
        "0:360:45, those a tendon faces)",
    )  # fmt: skip
    parser.add_argument(
        "--bends", metavar="LIST", default=None,
        help="a rig with several tendons: the bend magnitudes, mm of cable (default 10,20)",
    )  # fmt: skip
    parser.add_argument(
        "--data-dir", type=Path, default=None,
        help="the data folder: reads calibration/ and identification/, writes tuning/ (default: "
        "my_data/<rig name>/, gitignored; `--data-dir data` rewrites the project's shipped tuning)",
    )  # fmt: skip
    parser.add_argument(
        "--lanes", type=arg_number(0, 8, int), default=0,
        help="in-process virtual rig (one tendon or several): each verification run in a fresh world of its "
        "own, up to LANES at once with their plants in one kernel call (the recordings differ from the "
        "default's by the state the chain carried; 0: every run in the one world, in turn, as data/tuning "
        "was made)",
    )  # fmt: skip
    parser.add_argument("--replace", action="store_true", help="replace earlier tuning recordings and files")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    """Run ``python -m helpers tune`` (a rig with several tendons: :mod:`helpers.research.tune_tendons`)."""
    selected: RigFile = args.rig
    if args.data_dir is None:
        args.data_dir = user_data_dir(selected)
    lo, hi = selected.hardware.daq_rate_min_hz, selected.hardware.daq_rate_max_hz
    if not lo <= args.rate <= hi:
        raise ValueError(f"--rate {args.rate} Hz: rig {selected.name!r} samples at {lo}-{hi} Hz")
    if selected.n_tendons > 1:
        return tune_tendons.run_tendons(args, selected)
    if args.directions is not None or args.bends is not None:
        raise ValueError("--directions and --bends apply to a rig with several tendons (a bend's direction); "
                         f"rig {selected.name!r} has one: --grid chooses its conditions")
    grid = rig_grid(args.grid, selected)
    positions = rig_positions(selected)
    scaling_notes.announce(selected, {f"tune {args.grid} grid": GRIDS[args.grid]}, POSITIONS_MM)
    repetitions = args.repetitions or REPETITIONS[args.grid]
    tuning = args.data_dir / "tuning"
    map_path = tuning / "mode_map.json"
    rest = needs(load_identification, args.data_dir / "identification" / "result.json",
                 "identification result", args, "record identification")  # fmt: skip
    rest_run = args.data_dir / "identification" / f"{rest.recording}.csv"
    if rest.recording and rest_run.exists():  # the mode at rest must be this rig's
        refuse_other_rig(recordings.load(rest_run, derive=False).meta, selected, rest_run, what="tune on")
    calibration = needs(load_calibration, args.data_dir / "calibration" / "calibration.json",
                        "load-cell calibration", args, "record calibration")  # fmt: skip
    reused = load_map(map_path) if args.reuse_map else None
    if reused is not None:  # before any port is opened: the map must be this rig's
        refuse_map_of_other_rig(reused, selected, repo_path(map_path))
    say = (lambda _line: None) if args.quiet else (lambda line: print(line, file=sys.stderr))
    with contextlib.ExitStack() as stack:
        stack.enter_context(folder_lock(tuning, what="tuning", name=".tuning.lock"))
        rig = stack.enter_context(Rig(args.ports, selected, calibration=calibration, world="tune"))
        counter = itertools.count(args.seed)
        seeds = (lambda: next(counter)) if rig.world is not None else (lambda: None)
        if not args.reuse_map and map_path.exists() and not args.replace:
            raise RecordingExists(
                f"{repo_path(map_path)} exists; pass --replace to survey again, or --reuse-map"
            )
        if reused is not None:
            mode_map = reused
            say(f"mode map from {repo_path(map_path)} ({len(mode_map)} positions)")
        else:
            say(f"survey: {len(positions)} positions x {args.survey_repetitions} on {rig.source['kind']}")
            mode_map, _ = survey(
                rig,
                tuning / "survey",
                positions,
                args.survey_repetitions,
                rate_hz=args.rate,
                replace=args.replace,
                seeds=seeds,
                progress=None if args.quiet else say,
            )
            mode_map.save(map_path)
            say(f"mode map -> {repo_path(map_path)}")
        candidates = design_candidates(
            mode_map, (rest.omega_d, rest.zeta), grid, args.tolerance, args.minimax
        )
        for (v, x), systems in candidates.designs.items():
            for system, d in systems.items():
                if d is not None:
                    target = tuning / "designs" / f"{system}_{condition_name(v, x)}.json"
                    target.parent.mkdir(parents=True, exist_ok=True)
                    design.save_design(d, target)
            for system, note in candidates.notes[(v, x)].items():
                say(f"{x:g} mm at {v:g} mm/s, {system}: {note}")
        folder = tuning / ("verify" if args.grid == "table-i" else "wide")
        rows = verify(
            rig,
            candidates,
            folder,
            repetitions,
            rate_hz=args.rate,
            replace=args.replace,
            seeds=seeds,
            progress=not args.quiet,
            lanes=args.lanes,
        )
    source = str(rig.source.get("kind", "hardware"))
    rows.insert(0, "source", source)
    summary = summarise(rows)
    chosen = choose(summary)
    document = {
        "format": "continuum-arm-verification",
        "version": 1,
        "grid": args.grid,
        "source": {
            "kind": source,
            "map": repo_path(map_path),
            "repetitions": repetitions,
            "rate_hz": args.rate,
            "t_end_s": T_END_S,
            "seed": args.seed if rig.world is not None else None,
        },
        "notes": {condition_name(v, x): n for (v, x), n in candidates.notes.items()},
        "chosen": {k: v for k, v in chosen.items() if k != "table"},
        "rows": json.loads(rows.to_json(orient="records", double_precision=10)),
    }
    write_json(tuning / f"{args.grid}_verification.json", document)
    if args.grid == "table-i":
        write_json(
            tuning / "chosen.json",
            {
                "format": "continuum-arm-chosen-design",
                "version": 1,
                "system": chosen["system"],
                "criterion": chosen["criterion"],
                "worst_residual_pct": chosen["worst_residual_pct"],
                "designs": {
                    condition_name(v, x): f"designs/{chosen['system']}_{condition_name(v, x)}.json"
                    for v, x in grid
                },
            },
        )
    # a command writes its report beside its data: figures/tuning_report.* are notebook 07's alone
    for path in write_report(document, tuning):
        say(f"wrote {repo_path(path)}")
    print(report_markdown(document), end="")
    return 0
