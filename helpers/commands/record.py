"""``python -m helpers record``: record experiments into the data folder through :class:`helpers.rig.Rig`.

A procedure on top of the rig: it combines the drivers (:mod:`helpers.rig`), the identification
(:mod:`helpers.paper.identify`), the shaper design (:mod:`helpers.paper.shapers`) and the load-cell
calibration (:mod:`helpers.paper.calibration`).

The same code path serves the hardware (``--ports auto`` or ``--ports DAQ,STEPPER``) and the virtual rig
(``--ports virtual``, the default: in-process; or the device paths printed by ``serve-virtual-rig``).

The data folder is ``my_data/<rig name>/`` (:func:`helpers.base.paths.user_data_dir`, gitignored) unless
``--data-dir`` is given; ``--data-dir data`` regenerates the project's shipped recordings. Each sub-command
has its own options (``record pulse --help``)::

    python -m helpers record calibration                     # known loads -> calibration/, fit, save
    python -m helpers record identification                  # the identification run -> result.json
    python -m helpers record table-i --repetitions 3         # 12 scenarios x 3
    python -m helpers record pulse --v-in 250 --x-f 25 --system zvd --repetitions 3 --group mine
    python -m helpers record pulse --v-in 200 --x-f 20 --design my_design.json   # a saved design
    python -m helpers record all                             # identification, then Table I x 3
    python -m helpers --rig four-tendon record move --direction-deg 45 --bend-mm 10 --shaper zvd --dry-run

``table-i`` and pulses with ``--system zv``, ``zvd`` or ``ei`` design the shapers from
``identification/result.json`` in the data folder (written by ``record identification``, ``record all`` or
notebook 02's live cell) unless ``--zeta`` and ``--omega-d`` are given; a missing calibration or
identification is named in one line with the command that makes it (exit status 5). A pulse with
``--design FILE`` runs a design saved by :func:`helpers.research.design.save_design` (a shaper, an Up/Down
pair or a map-following schedule; the designs of a mode map, ``docs/shaper_design.md``) under the design's
system. A recording that exists is never overwritten unless ``--replace`` is given; two recorders cannot
write into one group at once.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

from helpers.base.cli import DefaultsHelp, arg_number, needs, rig_option, step_command
from helpers.base.jsonfile import MissingDataError
from helpers.base.paths import DATA_DIR, repo_path, user_data_dir
from helpers.board.programmes import experiment_programme
from helpers.commands.recording_paths import check_group, recording_path
from helpers.commands.session import recording_session, tension_guard
from helpers.commands.tip_stream import TIP_SPEED_MM_S, record_tip_stream
from helpers.paper import numbers as paper
from helpers.paper import scaling_notes, scenarios
from helpers.paper.calibration import (
    LoadCellCalibration,
    fit_calibration,
    load_calibration,
    save_calibration,
    uncalibrated,
)
from helpers.paper.identify import identify_recording, load_identification, save_identification
from helpers.paper.modes import omega_n_from_damped
from helpers.paper.shapers import Shaper, design_tdfs
from helpers.recordings import RecordingExists, check_name, refuse_existing
from helpers.research.design import SYSTEMS, Design, Schedule, load_design, up_down
from helpers.research.families import ei
from helpers.research.modemap import load_map
from helpers.research.task_shaping import MAX_PREPULL_STEPS, ModeGrid, shaped_move
from helpers.research.task_shaping import SHAPERS as MOVE_SHAPERS
from helpers.research.task_space import check_travel
from helpers.research.teleop import record_streams
from helpers.research.tip_stream import FIGURES as TIP_FIGURES
from helpers.research.tip_stream import SHAPERS as TIP_SHAPERS
from helpers.rig import Rig, SafetyError, check_programme, check_request
from helpers.rig.static import calibration_masses_kg, record_calibration
from helpers.rig.table_i import NoiseSeeds, record_table_i, scenario_name
from helpers.rigfile import RigFile, derived

IDENTIFIED_SYSTEMS = ("zv", "zvd", "ei")
"""Systems ``record`` designs itself from one identified mode (the others come from a --design file)."""

DESIGN_SYSTEMS = tuple(s for s in SYSTEMS if s not in ("unshaped", *IDENTIFIED_SYSTEMS))
"""Systems that need a saved design (``--design FILE``)."""

SYSTEM_HELP = (
    "unshaped = the paper's pulse; zv = the paper's non-robust TDF (ZV shaper); "
    "zvd = the paper's robust TDF (ZVD shaper); ei = an EI shaper (these three are designed from the "
    "identified mode, or taken from --design); " + ", ".join(DESIGN_SYSTEMS) + " = designs from a mode map, "
    "run with --design FILE (docs/shaper_design.md). Default: unshaped, or the design file's system"
)
DEFAULT_GROUPS = {
    "calibration": "calibration", "pulse": "runs", "table-i": "experiments", "all": "experiments",
    "streams": "streams", "move": "moves", "tip-stream": "tip_streams", "identification": "identification",
}  # fmt: skip
"""The lock a recorder holds on its group for the whole session (another recorder is refused)."""


def _name(text: str) -> str:
    try:
        return check_name(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _group(text: str) -> str:
    try:
        return check_group(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


WHAT: dict[str, str] = {
    "calibration": "known loads hung on the load cell; the fit saved as calibration/calibration.json",
    "identification": "the identification run (100 mm/s, 10 mm, scaled to the rig) and its analysis, saved "
    "as identification/result.json (what table-i, pulse and tune design from)",
    "table-i": "the paper's 12 scenarios (Table I), the TDFs designed from identification/result.json",
    "all": "identification, then table-i with the TDFs designed from it",
    "pulse": "one up-hold-down move (a scenario of your own), unshaped or shaped",
    "streams": "notebook 08's two arbitrary motions, unshaped, zv, zvd and scheduled (needs "
    "tuning/mode_map.json from `tune`)",
    "move": "a bend of a rig with several tendons (docs/task_space.md)",
    "tip-stream": "a figure of bends streamed to a rig with several tendons, one shaper for all",
}
"""``record``'s sub-commands -> their one-line help."""

DATA_DIR_HELP = (
    "the data folder (default: my_data/<rig name>/, gitignored; `--data-dir data` writes the project's "
    "shipped recordings)"
)

_ABSENT: dict[str, Any] = {
    "v_in": None, "x_f": None, "system": None, "design": None, "zeta": None, "omega_d": None,
    "identification": None, "repetitions": None, "t_end": 12.0, "duration": 1.0, "name": None,
    "direction_deg": None, "bend_mm": None, "path": "square", "path_seed": 0, "margin_n": 0.0,
    "shaper": "none", "mode_grid": None, "no_floor_check": False, "group": None,
}  # fmt: skip
"""The options a sub-command does not have, as the code that serves several reads them."""


def _parent() -> argparse.ArgumentParser:
    return argparse.ArgumentParser(add_help=False)


def _session_options() -> argparse.ArgumentParser:
    """Every recorder's options: where it records, into which data folder, and how."""
    p = _parent()
    p.add_argument(
        "--ports", default="virtual",
        help="'virtual' (in-process virtual rig), 'auto' (find the boards by USB id) or 'DAQ,STEPPER' "
        "(device paths, e.g. those serve-virtual-rig prints)",
    )  # fmt: skip
    p.add_argument("--virtual-instance", "--rig-name", dest="rig_name", default="record", type=_name,
                   help="name of the in-process virtual rig instance (old spelling: --rig-name)")  # fmt: skip
    p.add_argument(
        "--seed", type=arg_number(0, 2**32 - 1 - 10_000, int), default=0,
        help="in-process virtual rig: noise seed of the first run; run k gets seed + k (recorded)",
    )  # fmt: skip
    p.add_argument(
        "--rate", type=arg_number(1, 1_000_000, int), default=None,
        help="DAQ sample rate, Hz, within the rig's daq_rate_min_hz-daq_rate_max_hz, checked against the rig "
        "(paper: 100-2000; default: the rig's daq_rate_default_hz, 1000)",
    )  # fmt: skip
    p.add_argument("--data-dir", type=Path, default=None, help=DATA_DIR_HELP)
    p.add_argument(
        "--replace", action="store_true",
        help="replace recordings of the same names (each kept until the new one is whole)",
    )  # fmt: skip
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument(
        "--dry-run", action="store_true",
        help="check everything and print the recordings that would be made, without opening a port",
    )  # fmt: skip
    return p


def _group_option(default: str) -> argparse.ArgumentParser:
    p = _parent()
    p.add_argument("--group", type=_group, default=None,
                   help=f"folder under the data folder (default: {default})")  # fmt: skip
    return p


def _t_end_option() -> argparse.ArgumentParser:
    p = _parent()
    p.add_argument(
        "--t-end", type=arg_number(0, 1e6, lo_open=True), default=12.0,
        help="programme (and recording) length, s, in (0, the rig's max_programme_s], checked against the "
        "rig (paper: 600)",
    )  # fmt: skip
    return p


def _repetitions_option(default: int) -> argparse.ArgumentParser:
    p = _parent()
    p.add_argument("--repetitions", type=arg_number(1, 100, int), default=None,
                   help=f"runs per scenario, 1-100 (default: {default})")  # fmt: skip
    return p


def _identified_options() -> argparse.ArgumentParser:
    p = _parent()
    p.add_argument(
        "--zeta", type=arg_number(0, 1, lo_open=True),
        help="design the shapers from this damping ratio (default: the identification result's)",
    )  # fmt: skip
    p.add_argument(
        "--omega-d", type=arg_number(0, 1e4, lo_open=True),
        help="... and this damped frequency, rad/s (default: the identification result's)",
    )  # fmt: skip
    p.add_argument("--identification", default=None,
                   help="identification result JSON (default: identification/result.json in the data folder, "
                   "made by `record identification`)")  # fmt: skip
    return p


def _bend_options(what: str) -> argparse.ArgumentParser:
    p = _parent()
    move = what == "move"
    p.add_argument(
        "--direction-deg", type=arg_number(-360, 360),
        help="the bend's direction, deg around the backbone (0 = towards tendon 1, counter-clockwise)" if move
        else "the figure turned by this angle, deg (the line's direction, the square's first corner; "
        "default 0)",
    )  # fmt: skip
    p.add_argument(
        "--bend-mm", type=arg_number(0, 1000, lo_open=True),
        help=("the bend's magnitude, mm of cable (as the direction map's bend_mm)" if move else
              "the figure's size, mm of bend") + "; required; within every tendon's travel and at least one "
        "whole step on some tendon (else refused: exit 3 for the travel, 2 for a move of zero steps)",
    )  # fmt: skip
    limit = "the rig's speed_limit_mm_s (faster: refused, exit 3, naming the limit)"
    p.add_argument(
        "--v-in", type=arg_number(0, 1e6, lo_open=True),
        help=f"the lead tendon's cable speed, mm/s, in (0, {limit}] (default {MOVE_SPEED_MM_S:g})"
        if move else
        f"the figure's speed, mm of bend per second, in (0, {limit}], and every tendon's set-points within "
        f"the stream's limit (else refused, saying what speed fits) (default {TIP_SPEED_MM_S:g})",
    )  # fmt: skip
    p.add_argument("--name", type=_name, default=None,
                   help="file name (default: from the options)")  # fmt: skip
    return p


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``record``'s sub-commands, each with its own options (``record pulse --help``: the pulse's)."""
    parser.formatter_class = DefaultsHelp
    parser.description = (
        "Record experiments through the rig's boards (hardware or virtual rig) into the data folder: "
        "my_data/<rig name>/ unless --data-dir is given."
    )
    session, t_end = _session_options(), _t_end_option()
    sub = parser.add_subparsers(dest="what", required=True, metavar="what")

    def add(name: str, *parents: argparse.ArgumentParser) -> argparse.ArgumentParser:
        return sub.add_parser(name, help=WHAT[name], description=WHAT[name], formatter_class=DefaultsHelp,
                              parents=[rig_option(), session, *parents])  # fmt: skip

    cal = add("calibration", _group_option("calibration"))
    cal.add_argument(
        "--duration", type=arg_number(0, 1e6, lo_open=True), default=1.0,
        help="seconds per load, in (0, the rig's max_programme_s], checked against the rig",
    )  # fmt: skip
    add("identification", t_end)
    add("table-i", _group_option("experiments"), _identified_options(), _repetitions_option(3), t_end)
    add("all", _group_option("experiments"), _repetitions_option(3), t_end)
    pulse = add("pulse", _group_option("runs"), _identified_options(), _repetitions_option(1), t_end)
    pulse.add_argument(
        "--v-in", type=arg_number(0, 1e6, lo_open=True),
        help="pulse speed, mm/s, in (0, the rig's speed_limit_mm_s] (faster: refused, exit 3, naming the "
        "limit; paper: 400); required unless --design holds a schedule",
    )  # fmt: skip
    pulse.add_argument(
        "--x-f", type=arg_number(0, 1e6, lo_open=True),
        help="pulse displacement, mm, from half a step to the rig's travel in whole steps (else refused, "
        "exit 3; paper: 39.82 mm, 156 steps); required unless --design holds a schedule",
    )  # fmt: skip
    pulse.add_argument("--system", choices=list(SYSTEMS), default=None, help=SYSTEM_HELP)
    pulse.add_argument(
        "--design", type=Path, default=None,
        help="run this saved design (JSON of helpers.research.design.save_design: a shaper, an Up/Down pair "
        "or a map-following schedule, which also sets --v-in and --x-f); default: none, design from --system",
    )  # fmt: skip
    pulse.add_argument(
        "--name", type=_name, default=None,
        help="file name; repetitions add _r<k> (default: <system>_v<v-in>_x<x-f>)",
    )  # fmt: skip
    add("streams", _group_option("streams"))
    move = add("move", _group_option("moves"), _bend_options("move"), t_end)
    move.add_argument(
        "--shaper", choices=list(MOVE_SHAPERS), default="none",
        help="none; a family (zv, zvd, zvdd, mzv, ei, ei2, ei3, umzv) at the dominant mode at the bend; "
        "scheduled (ZVD on the mode grid), multimode (two split modes) or auto (docs/task_space.md)",
    )  # fmt: skip
    move.add_argument(
        "--mode-grid", type=Path, default=None,
        help="a mode grid (CSV of helpers.research.task_shaping.ModeGrid.write_csv) that scheduled, "
        "multimode and auto read the modes off (default: the modes at the move itself)",
    )  # fmt: skip
    move.add_argument(
        "--no-floor-check", action="store_true",
        help="do not simulate the shaped move's tensions in the spatial twin (nor change the pretension or "
        "the design when a tendon would dip below the floor)",
    )  # fmt: skip
    _tension_options(move, "move")
    tip = add("tip-stream", _group_option("tip_streams"), _bend_options("tip-stream"))
    tip.add_argument("--path", choices=list(TIP_FIGURES), default="square",
                     help="the figure of bends (docs/task_space.md, arbitrary motion)")  # fmt: skip
    tip.add_argument("--path-seed", type=arg_number(0, 2**32 - 1, int), default=0,
                     help="the seed of the random path")  # fmt: skip
    tip.add_argument(
        "--margin-n", type=arg_number(0, 10), default=0.0,
        help="trim the stops' whole steps to the tension floor plus this margin, N (0: record move's policy)",
    )  # fmt: skip
    tip.add_argument(
        "--prepull", type=arg_number(0, MAX_PREPULL_STEPS, int), default=0,
        help="pull every tendon this many whole steps in before the path and let it out after (one tendon at "
        "a time), as record move's pre-pull; the path planned from there (a path whose static tensions at "
        "the board's whole steps leave a tendon below the floor is refused, saying which --prepull passes)",
    )  # fmt: skip
    tip.add_argument("--shaper", choices=list(TIP_SHAPERS), default="none",
                     help="none, zv or zvd from the map's mode at the path's stops, one shaper for every "
                     "tendon")  # fmt: skip
    _tension_options(tip, "stream")


def _tension_options(parser: argparse.ArgumentParser, what: str) -> None:
    """``--trim`` and ``--no-floor-watch``: a motion of several tendons (``record move``, ``tip-stream``)."""
    parser.add_argument(
        "--trim", action="store_true",
        help=f"before the {what}, trim every tendon by whole steps until its measured tension at rest is at "
        "its planned rest tension (the fewest steps at which it is >= it; helpers.rig.trim, docs/safety.md)"
        + (", and at every stop long enough, by one measurement, to the planner's tension at the board's "
           "whole steps there" if what == "stream" else ""),
    )  # fmt: skip
    parser.add_argument(
        "--no-floor-watch", action="store_true",
        help=f"record the whole {what} even where a tendon's measured tension stays below [arm] "
        "tension_floor_n for longer than [arm] floor_watch_ms (by default that stops it, saved aborted)",
    )  # fmt: skip


def _shapers(args: argparse.Namespace, quiet: bool = False) -> tuple[dict[str, Any], dict[str, Any]]:
    if (args.zeta is None) != (args.omega_d is None):
        raise SystemExit("give both --zeta and --omega-d, or neither (then result.json is used)")
    if args.zeta is not None:
        zeta, omega_d, origin = args.zeta, args.omega_d, "command line"
    else:
        path = Path(args.identification or args.data_dir / "identification" / "result.json")
        try:
            found = load_identification(path)
        except MissingDataError:  # a data file is missing: status 5, not a usage error
            raise MissingDataError(
                f"{repo_path(path)}: no identification result yet: make it with `"
                f"{step_command(args, 'record identification')}` (add --ports for hardware), or pass --zeta "
                "and --omega-d"
            ) from None
        zeta, omega_d = found.zeta, found.omega_d
        origin = repo_path(path)
    zv, zvd = design_tdfs(omega_d, zeta)
    extra = ei(omega_n_from_damped(omega_d, zeta), zeta)
    if not quiet:
        print(f"shapers designed from zeta = {zeta:.4f}, omega_d = {omega_d:.3f} rad/s ({origin})")
    shapers = {"unshaped": None, "zv": zv, "zvd": zvd, "ei": Shaper(extra.amplitudes, extra.times, "ei")}
    return shapers, {"zeta": zeta, "omega_d": omega_d, "origin": origin}


def _pulse_request(args: argparse.Namespace) -> tuple[str, Any, dict[str, Any] | None, float, float]:
    """What ``record pulse`` runs: ``(system, shaping, design info, v_in, x_f)``.

    The shaping is None (unshaped), a shaper designed from the identified mode (zv, zvd, ei), or the design
    of ``--design``; a map-following schedule supplies the move if ``--v-in``/``--x-f`` are not given.
    """
    if args.design is not None:
        if args.zeta is not None or args.omega_d is not None:
            raise ValueError("--design and --zeta/--omega-d exclude each other: a design file is complete")
        design = load_design(args.design)
        if args.system is not None and args.system != design.system:
            raise ValueError(
                f"--system {args.system}, but {repo_path(args.design)} holds a {design.system!r} design "
                "(drop --system, or give the design's own)"
            )
        v, x = args.v_in, args.x_f
        if isinstance(design.shaping, Schedule):
            v = design.shaping.v_in_mm_s if v is None else v
            x = design.shaping.x_f_mm if x is None else x
        if v is None or x is None:
            raise SystemExit("record pulse needs --v-in and --x-f")
        if isinstance(design.shaping, Schedule):
            design.shaping.check_move(v, x)
        info = {"origin": repo_path(args.design), "system": design.system, "kind": design.kind}
        return design.system, design, info, v, x
    if args.v_in is None or args.x_f is None:
        raise SystemExit("record pulse needs --v-in and --x-f")
    system = args.system or "unshaped"
    if system == "unshaped":
        return system, None, None, args.v_in, args.x_f
    if system in DESIGN_SYSTEMS:
        raise ValueError(
            f"--system {system} needs --design FILE: a design saved with helpers.research.design.save_design "
            "from a mode map (docs/shaper_design.md)"
        )
    shapers, design_info = _shapers(args)
    return system, shapers[system], design_info, args.v_in, args.x_f


def _describe(system: str, shaping: Any) -> str:
    """A short description of a pulse's shaping for the dry run."""
    if shaping is None:
        return "unshaped"
    inner = shaping.shaping if isinstance(shaping, Design) else shaping
    if isinstance(inner, Schedule):
        return f"{system} (schedule: {len(inner.up.sub_moves)} + {len(inner.down.sub_moves)} sub-moves)"
    up, down = up_down(inner)
    if up is down:
        return f"{up.name} ({len(up.amplitudes)} impulses)"
    return f"{system} (Up {up.name}: {len(up)} impulses; Down {down.name}: {len(down)} impulses)"


def record_all(
    rig: Any,
    repetitions: int = 3,
    t_end_s: float = 12.0,
    rate_hz: int = 1000,
    data_dir: Path = DATA_DIR,
    group: str = "experiments",
    replace: bool = False,
    seeds: NoiseSeeds | None = None,
) -> None:
    """Regenerate every recording of the paper's experiment, in the order the analysis needs them.

    1. the identification run (100 mm/s, 10 mm; :mod:`helpers.paper.scenarios` scales it on a rig it does not
       fit) into ``identification/pulse_v100_x10``;
    2. its identification on the 9-10 s window with :func:`helpers.paper.identify.identify_recording`, saved
    to
       ``identification/result.json`` (what notebook 02's live cell does too);
    3. the twelve Table I scenarios x ``repetitions``, with the TDFs designed from that result, into
       ``group``.

    Parameters
    ----------
    rig : helpers.rig.Rig
        A connected rig.
    repetitions, t_end_s, rate_hz, replace, seeds
        As :func:`record_table_i`.
    data_dir : pathlib.Path
        The data folder.
    group : str
        Folder of the Table I recordings under ``data_dir``.
    """
    seeds = seeds or NoiseSeeds(None)
    result, path = record_identification(rig, t_end_s, rate_hz, data_dir, replace, seeds)
    zv, zvd = design_tdfs(result.omega_d, result.zeta)
    design = {"zeta": result.zeta, "omega_d": result.omega_d, "origin": repo_path(path)}
    record_table_i(
        rig,
        {"unshaped": None, "zv": zv, "zvd": zvd},
        design,
        repetitions=repetitions,
        group=Path(data_dir) / group,
        t_end_s=t_end_s,
        rate_hz=rate_hz,
        replace=replace,
        seeds=seeds,
    )


def record_identification(
    rig: Any, t_end_s: float, rate_hz: int, data_dir: Path, replace: bool, seeds: NoiseSeeds
) -> tuple[Any, Path]:
    """The identification run into ``identification/`` and its analysis, saved as ``result.json`` there.

    Returns
    -------
    tuple
        The :class:`~helpers.paper.identify.IdentificationResult` and the path of ``result.json``.
    """
    run = scenarios.identification_run(rig.rig)
    rec = rig.run_pulse(
        run["v_in_mm_s"],
        run["x_f_mm"],
        None,
        system="unshaped",
        path=Path(data_dir) / "identification" / scenarios.identification_name(rig.rig),
        t_end_s=t_end_s,
        rate_hz=rate_hz,
        progress=False,
        replace=replace,
        noise_seed=seeds.take(),
    )
    print(f"identification run: {rec.status}, {len(rec.frame)} samples -> {repo_path(rec.path)}")
    result = identify_recording(rec, window=run["window_s"], column="adc")
    path = save_identification(result, Path(data_dir) / "identification" / "result.json")
    print(f"identified zeta = {result.zeta:.4f}, omega_d = {result.omega_d:.3f} rad/s -> {repo_path(path)}")
    return result, path


def _record_calibration(rig: Rig, args: argparse.Namespace, seeds: NoiseSeeds) -> None:
    folder = args.data_dir / args.group
    recs = record_calibration(
        rig, duration_s=args.duration, folder=folder, rate_hz=args.rate, replace=args.replace
    )
    fit = fit_calibration(recs)
    path = save_calibration(fit, recs, folder / "calibration.json")
    print(
        f"{len(recs)} loads recorded; gain {fit.gain_counts_per_n:.4f} +- {fit.gain_stderr:.4f} "
        f"counts/N, offset {fit.offset_counts:.3f} +- {fit.offset_stderr:.3f} counts -> {repo_path(path)}"
    )


def _record_pulse(rig: Rig, args: argparse.Namespace, seeds: NoiseSeeds) -> None:
    request = getattr(args, "pulse_request", None)
    system, shaping, design, v_in, x_f = request if request is not None else _pulse_request(args)
    base = args.name or scenario_name(system, v_in, x_f)
    reps = args.repetitions or 1
    for rep in range(1, reps + 1):
        name = base if reps == 1 else f"{base}_r{rep}"
        rec = rig.run_pulse(
            v_in,
            x_f,
            shaping,
            system=system,
            path=args.data_dir / args.group / name,
            repetition=rep,
            t_end_s=args.t_end,
            rate_hz=args.rate,
            progress=not args.quiet,
            scenario_extra=None if design is None else {"design": design},
            replace=args.replace,
            noise_seed=seeds.take(),
        )
        print(f"{rec.status}: {len(rec.frame)} samples -> {repo_path(rec.path)}")


def _record_table_i(rig: Rig, args: argparse.Namespace, seeds: NoiseSeeds) -> None:
    shapers, design = _shapers(args)
    record_table_i(
        rig,
        shapers,
        design,
        repetitions=args.repetitions or 3,
        group=args.data_dir / args.group,
        t_end_s=args.t_end,
        rate_hz=args.rate,
        replace=args.replace,
        seeds=seeds,
    )


def _record_all(rig: Rig, args: argparse.Namespace, seeds: NoiseSeeds) -> None:
    record_all(
        rig,
        repetitions=args.repetitions or 3,
        t_end_s=args.t_end,
        rate_hz=args.rate,
        data_dir=args.data_dir,
        group=args.group,
        replace=args.replace,
        seeds=seeds,
    )


def _record_identification(rig: Rig, args: argparse.Namespace, seeds: NoiseSeeds) -> None:
    record_identification(rig, args.t_end, args.rate, args.data_dir, args.replace, seeds)


def _record_streams(rig: Rig, args: argparse.Namespace, seeds: NoiseSeeds) -> None:
    mode_map = needs(load_map, args.data_dir / "tuning" / "mode_map.json", "mode map", args, "tune")
    rest = needs(load_identification, args.data_dir / "identification" / "result.json",
                 "identification result", args, "record identification")  # fmt: skip
    recs = record_streams(rig, args.data_dir / args.group, mode_map, (rest.omega_d, rest.zeta),
                          replace=args.replace, seeds=seeds.take, rate_hz=args.rate)  # fmt: skip
    for rec in recs:
        print(f"{rec.status}: {len(rec.frame)} samples -> {repo_path(rec.path)}")


RECORDERS: dict[str, Callable[[Rig, argparse.Namespace, NoiseSeeds], None]] = {
    "calibration": _record_calibration,
    "pulse": _record_pulse,
    "table-i": _record_table_i,
    "all": _record_all,
    "streams": _record_streams,
    "identification": _record_identification,
}
"""What ``record`` can record -> the function that does it."""


def missing_calibration(path: Path, args: argparse.Namespace) -> str:
    """The one line for a missing load-cell calibration: the command that records it."""
    return (f"{repo_path(path)}: no load-cell calibration yet: record it with "
            f"`{step_command(args, 'record calibration')}` (add --ports for hardware)")  # fmt: skip


def _calibration_for(what: str, args: argparse.Namespace) -> LoadCellCalibration | None:
    """The load-cell calibration a run uses: the saved one; recording a new one may start without any."""
    data_dir, rig = args.data_dir, args.rig
    path = data_dir / "calibration" / "calibration.json"
    try:
        return load_calibration(path)
    except MissingDataError:
        if what == "calibration":
            return uncalibrated(derived(rig).mm_per_step[0])
        raise MissingDataError(missing_calibration(path, args)) from None


def _planned_pulses(
    args: argparse.Namespace, quiet: bool = False
) -> list[tuple[str, str, float, float, str, Any]]:
    """(group, name, v_in, x_f, system, shaping) of every pulse ``args`` asks for, in recording order."""
    if args.what == "pulse":
        system, shaping, _, v_in, x_f = getattr(args, "pulse_request", None) or _pulse_request(args)
        base = args.name or scenario_name(system, v_in, x_f)
        reps = args.repetitions or 1
        return [
            (args.group, base if reps == 1 else f"{base}_r{rep}", v_in, x_f, system, shaping)
            for rep in range(1, reps + 1)
        ]
    planned = []
    scaling_notes.announce(args.rig)
    if args.what in ("all", "identification"):
        run = scenarios.identification_run(args.rig)
        v, x = run["v_in_mm_s"], run["x_f_mm"]
        planned.append(("identification", scenarios.identification_name(args.rig), v, x, "unshaped", None))
        if args.what == "identification":
            return planned
        if not quiet:
            print("dry run: the shapers of Table I are designed from the identification run once recorded;")
            print("         the plan below checks them with the current identification result")
    if args.what == "all" and quiet:  # names only (the existence check): `all` designs its shapers itself
        shapers: dict[str, Any] = dict.fromkeys(paper.SYSTEMS)
    else:
        shapers, _ = _shapers(args, quiet=quiet)
    reps = args.repetitions or 3
    for system in paper.SYSTEMS:
        for v, x in scenarios.table_i_conditions(args.rig):
            for rep in range(1, reps + 1):
                planned.append((args.group, scenario_name(system, v, x, rep), v, x, system, shapers[system]))
    return planned


def dry_run(args: argparse.Namespace) -> int:
    """Check a ``record`` request completely and print what it would record; no port is opened.

    Every pulse is quantised into its stepper programme and checked against the safety limits, every target
    file against existing recordings (unless ``--replace``), and the load-cell calibration is looked up, as
    the real run does before it moves anything.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed ``record`` arguments (``args.group`` already resolved).

    Returns
    -------
    int
        0 when the run would start; otherwise an exception names the first problem.
    """
    _calibration_for(args.what, args)
    rows = []
    if args.what == "calibration":
        for grams in (round(1000 * m) for m in _masses(args.rig)):
            target = recording_path(args.group, f"load_{grams:04d}g", args.data_dir)
            if not args.replace:
                refuse_existing(target)
            rows.append(f"  {repo_path(target)}: {grams} g hung for {args.duration:g} s at {args.rate} Hz")
    else:
        for group, name, v, x, system, shaper in _planned_pulses(args):
            target = recording_path(group, name, args.data_dir)
            if not args.replace:
                refuse_existing(target)
            v, x = check_request(v, x, args.rig)
            try:
                programme, report = experiment_programme(v, x, shaper, t_end=args.t_end,
                                                         rig=args.rig)  # fmt: skip
            except ValueError as exc:
                raise SafetyError(f"pulse {v} mm/s, {x} mm refused: {exc}") from None
            check_programme(programme, args.rig)
            what = _describe(system, shaper)
            rows.append(
                f"  {repo_path(target)}: {x:g} mm at {v:g} mm/s, {what}, {report.n_steps} steps per move, "
                f"{programme.duration_s:.1f} s at {args.rate} Hz"
            )
    print(f"dry run: {len(rows)} recording(s) would be made on --ports {args.ports}; nothing was sent:")
    print("\n".join(rows))
    return 0


def _masses(rig: RigFile) -> tuple[float, ...]:
    """The calibration's masses for the rig's load cell (tendon 1's)."""
    return calibration_masses_kg(rig.tendons[0].load_cell_range_n)


def _refuse_existing_targets(args: argparse.Namespace) -> None:
    """Refuse a request whose recordings exist already, naming the options that avoid it."""
    if args.what == "calibration":
        names = [(args.group, f"load_{round(1000 * m):04d}g") for m in _masses(args.rig)]
    elif args.what in ("pulse", "table-i", "all", "identification"):
        names = [(g, n) for g, n, *_ in _planned_pulses(args, quiet=True)]
    else:
        return  # streams: each is checked by helpers.rig.stream.stream before anything moves
    how = "choose another --name" if args.what == "pulse" else "choose another --group"
    for group, name in names:
        target = recording_path(group, name, args.data_dir)
        if target.exists() or target.with_suffix(".json").exists():
            raise RecordingExists(
                f"{repo_path(target)}: a recording of that name exists; {how} or pass --replace to replace it"
            )


MOVE_SPEED_MM_S = 200.0
"""The lead tendon's cable speed of a move when --v-in is not given (Table I's slower speed)."""


def _move_name(args: argparse.Namespace) -> str:
    text = f"move_{args.shaper}_d{args.direction_deg:g}_b{args.bend_mm:g}"
    return args.name or text.replace(".", "p").replace("-", "m")


def _plan_move(args: argparse.Namespace, rig: Any) -> Any:
    """``record move``'s plan, design, floor check and programme, every check made before any port opens."""
    if args.direction_deg is None or args.bend_mm is None:
        raise SystemExit("record move needs --direction-deg and --bend-mm")
    if rig.n_tendons < 2:
        raise ValueError(
            f"record move needs a rig file with several tendons; the selected rig '{rig.name}' has one "
            "(--rig four-tendon)"
        )
    grid = None
    if args.mode_grid is not None:
        if args.shaper not in ("scheduled", "multimode", "auto"):
            raise ValueError(
                f"--mode-grid applies to --shaper scheduled, multimode or auto, not {args.shaper}"
            )
        grid = ModeGrid.read_csv(args.mode_grid)
    speed = args.v_in if args.v_in is not None else MOVE_SPEED_MM_S
    times = (paper.PULSE_T_UP_S, paper.PULSE_T_DOWN_S, args.t_end)
    try:
        return shaped_move(rig, args.direction_deg, args.bend_mm, args.shaper, speed, times, grid,
                           check_floor=not args.no_floor_check)  # fmt: skip
    except ValueError as exc:  # the bend itself is checked by the options' ranges
        where = f"{args.bend_mm:g} mm towards {args.direction_deg:g} deg"
        raise SafetyError(f"move {where} refused: {exc}") from None


def _print_move(args: argparse.Namespace, rig: Any, move: Any) -> None:
    speed = args.v_in if args.v_in is not None else MOVE_SPEED_MM_S
    print(
        f"move: {args.bend_mm:g} mm towards {args.direction_deg:g} deg on rig '{rig.name}' "
        f"({rig.n_tendons} tendons), the lead tendon at {speed:g} mm/s; static tensions by the spatial twin "
        "(rotors free):"
    )
    if move.prepull:
        print(
            f"  every tendon pulled in {move.prepull} step(s) before the move (the dynamic floor); the plan "
            "from there:"
        )
    for line in move.plan.lines():
        print(f"  {line}")
    for line in move.lines():
        print(f"  {line}")


def _record_move(args: argparse.Namespace) -> int:
    """``record move``: plan, check, print (dry run) or record one move on a rig with several tendons."""
    rig = args.rig
    move = _plan_move(args, rig)
    plan, design, programme = move.plan, move.shaping, move.programme
    if not any(plan.steps):
        raise ValueError(f"--bend-mm {args.bend_mm:g}: the move pulls no tendon a whole step (a move of zero "
                         "steps); nothing recorded")  # fmt: skip
    target = recording_path(args.group, _move_name(args), args.data_dir)
    if not args.replace:
        refuse_existing(target)
    if args.dry_run:
        _print_move(args, rig, move)
        check_travel(plan, rig, start=move.start)  # from rest: every tendon at position 0 (or pre-pulled)
        check_programme(programme, rig, (0,) * rig.n_tendons)
        _print_move_programme(args, rig, programme, target)
        return 0
    check_travel(plan, rig, start=move.start)
    check_programme(programme, rig, (0,) * rig.n_tendons)
    with recording_session(args, from_rest="a move") as (trig, noise_seed):
        print(f"  shaper: {design.describe()}")
        if move.check is not None and not move.check.ok and design.shaper is not None:
            print(f"  warning: the twin foresees a tendon below the floor ({move.check.lines()[-1]}); the "
                  "floor watch stops the run if one stays below it longer than [arm] floor_watch_ms")
        scenario = {
            "kind": "move", "direction_deg": plan.direction_deg, "bend_mm": plan.bend_mm,
            "shaper": design.name, **move.metadata(),
            "speed_mm_s": args.v_in if args.v_in is not None else MOVE_SPEED_MM_S,
            "steps": list(plan.steps), "planned_tension_n": list(plan.tension_n),
            "tension_floor_n": plan.floor_n, "trimmed_steps": list(plan.trimmed),
        }  # fmt: skip
        rec = trig.run(programme, path=target, scenario=scenario, rate_hz=args.rate, tail_s=0.5,
                       replace=args.replace, noise_seed=noise_seed, progress=not args.quiet,
                       guard=tension_guard(args, rig))  # several tendons (_plan_move)
    print(f"{rec.meta['status']}: {len(rec.frame)} samples -> {repo_path(rec.path)}")
    return 0


def _print_move_programme(args: argparse.Namespace, rig: Any, programme: Any, target: Path) -> None:
    cmds = [it.command(rig.n_tendons) for it in programme.items]
    print(f"  programme ({len(cmds)} items, {programme.duration_s:.2f} s): " + "; ".join(cmds))
    print(
        f"dry run: 1 recording would be made on --ports {args.ports}: {repo_path(target)}; nothing was sent"
    )


def _within_the_rig(args: argparse.Namespace) -> None:
    """The options whose range is the rig's (``args.rig``): the DAQ rate (default its own) and the lengths."""
    hw = args.rig.hardware
    if args.rate is None:
        args.rate = hw.daq_rate_default_hz
    if not hw.daq_rate_min_hz <= args.rate <= hw.daq_rate_max_hz:
        raise ValueError(f"--rate {args.rate} Hz: rig {args.rig.name!r} samples at "
                         f"{hw.daq_rate_min_hz}-{hw.daq_rate_max_hz} Hz")  # fmt: skip
    for option, value in (("--t-end", args.t_end), ("--duration", args.duration)):
        if value > hw.max_programme_s:
            raise ValueError(f"{option} {value:g} s: rig {args.rig.name!r} runs programmes of at most "
                             f"{hw.max_programme_s:g} s (max_programme_s)")  # fmt: skip


def run(args: argparse.Namespace) -> int:
    """Run ``python -m helpers record`` (errors are turned into one line by ``python -m helpers``)."""
    for key, value in _ABSENT.items():  # the options this sub-command does not have
        if not hasattr(args, key):
            setattr(args, key, value)
    if args.data_dir is None:
        args.data_dir = user_data_dir(args.rig)
    _within_the_rig(args)
    args.group = args.group or DEFAULT_GROUPS[args.what]
    if args.what == "move":
        return _record_move(args)
    if args.what == "tip-stream":
        return record_tip_stream(args)
    if args.what != "pulse" and args.design is not None:
        raise ValueError(f"--design applies to record pulse only, not to record {args.what}")
    if args.what in ("table-i", "all", "identification"):
        scaling_notes.announce(args.rig)  # once: which of the paper's scenarios this rig scales, and to what
    if args.dry_run:
        return dry_run(args)
    if args.what == "pulse":  # refuse a bad request before any port is opened
        args.pulse_request = _pulse_request(args)
    groups = {args.group, "identification"} if args.what == "all" else {args.group}
    calibration = _calibration_for(args.what, args)
    if not args.replace:  # before any port is opened (opening one resets an Arduino)
        _refuse_existing_targets(args)
    with recording_session(args, groups, calibration=calibration) as (rig, seed):
        RECORDERS[args.what](rig, args, NoiseSeeds(seed))
    return 0

