"""``python -m helpers record``: record experiments into ``data/`` through :class:`helpers.rig.Rig`.

A procedure on top of the rig: it combines the drivers (:mod:`helpers.rig`), the identification
(:mod:`helpers.identify`), the shaper design (:mod:`helpers.shapers`) and the load-cell calibration
(:mod:`helpers.loadcell`).

The same code path serves the hardware (``--ports auto`` or ``--ports DAQ,STEPPER``) and the virtual rig
(``--ports virtual``, the default: in-process; or the device paths printed by ``serve-virtual-rig``).

Commands::

    python -m helpers record calibration                     # known loads -> data/calibration/, fit, save
    python -m helpers record pulse --v-in 100 --x-f 10 --group identification --name pulse_v100_x10
    python -m helpers record pulse --v-in 200 --x-f 20 --system zvd --zeta 0.044 --omega-d 25.085
    python -m helpers record table-i --repetitions 3         # 12 scenarios x 3
    python -m helpers record all                             # identification + result.json + Table I x 3

``table-i`` and shaped pulses design the shapers from ``data/identification/result.json`` (written by
``record all`` or notebook 02's live cell) unless ``--zeta`` and ``--omega-d`` are given.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from helpers import paper
from helpers.identify import identify_recording, load_identification, save_identification
from helpers.jsonfile import MissingDataError
from helpers.loadcell import (
    UNCALIBRATED,
    LoadCellCalibration,
    fit_calibration,
    load_calibration,
    save_calibration,
)
from helpers.paths import DATA_DIR
from helpers.rig import Rig
from helpers.rig.loadcell import record_calibration
from helpers.shapers import design_tdfs


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``record`` options."""
    parser.add_argument(
        "what",
        choices=["calibration", "pulse", "table-i", "all"],  # the keys of RECORDERS
        help="what to record ('all': identification run, its analysis, then Table I)",
    )
    parser.add_argument(
        "--ports",
        default="virtual",
        help="'virtual' (in-process virtual rig), 'auto' (find boards by USB id) or 'DAQ,STEPPER'",
    )
    parser.add_argument("--rig-name", default="record", help="name of the in-process virtual rig")
    parser.add_argument("--seed", type=int, default=0, help="virtual rig: sensor-noise seed")
    parser.add_argument("--v-in", type=float, help="pulse speed, mm/s")
    parser.add_argument("--x-f", type=float, help="pulse displacement, mm")
    parser.add_argument("--system", choices=["unshaped", "zv", "zvd"], default="unshaped")
    parser.add_argument("--zeta", type=float, help="identified damping ratio (shaper design)")
    parser.add_argument("--omega-d", type=float, help="identified damped frequency, rad/s (shaper design)")
    parser.add_argument(
        "--identification",
        default=None,
        help="identification result JSON (default data/identification/result.json)",
    )
    parser.add_argument("--repetitions", type=int, default=3)
    parser.add_argument("--t-end", type=float, default=12.0, help="programme (and recording) length, s")
    parser.add_argument("--rate", type=int, default=1000, help="DAQ sample rate, Hz")
    parser.add_argument("--group", default=None, help="folder under data/")
    parser.add_argument("--name", default=None, help="file name (pulse only)")
    parser.add_argument("--duration", type=float, default=1.0, help="calibration: seconds per load")
    parser.add_argument("--quiet", action="store_true", help="no progress bars")


def _shapers(args: argparse.Namespace) -> tuple[dict[str, Any], dict[str, Any]]:
    if args.zeta is not None and args.omega_d is not None:
        zeta, omega_d, origin = args.zeta, args.omega_d, "command line"
    else:
        try:
            found = load_identification(args.identification) if args.identification else load_identification()
        except MissingDataError as exc:
            raise SystemExit(f"{exc} (or pass --zeta and --omega-d)") from None
        zeta, omega_d = found.zeta, found.omega_d
        origin = args.identification or "data/identification/result.json"
    zv, zvd = design_tdfs(omega_d, zeta)
    print(f"shapers designed from zeta = {zeta:.4f}, omega_d = {omega_d:.3f} rad/s ({origin})")
    return {"unshaped": None, "zv": zv, "zvd": zvd}, {"zeta": zeta, "omega_d": omega_d, "origin": origin}


def _shown(path: Path) -> str:
    """``path`` relative to the repository when it is inside it."""
    p = Path(path)
    return p.relative_to(DATA_DIR.parent).as_posix() if p.is_relative_to(DATA_DIR.parent) else str(p)


def scenario_name(system: str, v_in: float, x_f: float, repetition: int | None = None) -> str:
    """File name of a pulse scenario, e.g. ``zvd_v200_x20_r1``."""
    base = f"{system}_v{v_in:g}_x{x_f:g}"
    return base if repetition is None else f"{base}_r{repetition}"


def record_table_i(
    rig: Any,
    shapers: dict[str, Any],
    design: dict[str, Any] | None,
    repetitions: int = 3,
    group: Path = DATA_DIR / "experiments",
    t_end_s: float = 12.0,
    rate_hz: int = 1000,
) -> list[Path]:
    """Record the twelve scenarios of Table I, ``repetitions`` times each, into ``group``.

    Parameters
    ----------
    rig : helpers.rig.Rig
        A connected rig (hardware or virtual).
    shapers : dict
        ``{"unshaped": None, "zv": Shaper, "zvd": Shaper}``.
    design : dict, optional
        Where the shapers came from (``zeta``, ``omega_d``, ``origin``), written into every scenario.
    repetitions : int
        Runs per scenario.
    group : pathlib.Path
        Destination folder.
    t_end_s : float
        Programme (and recording) length, s.
    rate_hz : int
        DAQ sample rate.

    Returns
    -------
    list of pathlib.Path
        The CSV files written, in recording order.
    """
    paths = []
    for system in paper.SYSTEMS:
        for v, x in paper.TABLE_I_CONDITIONS:
            for rep in range(1, repetitions + 1):
                path = Path(group) / scenario_name(system, v, x, rep)
                rec = rig.run_pulse(
                    v,
                    x,
                    shapers[system],
                    system=system,
                    path=path,
                    repetition=rep,
                    t_end_s=t_end_s,
                    rate_hz=rate_hz,
                    progress=False,
                    scenario_extra={"design": design},
                )
                print(f"{path.name}: {rec.status}, {len(rec.frame)} samples", flush=True)
                paths.append(rec.path)
    return paths


def record_all(rig: Any, repetitions: int = 3, t_end_s: float = 12.0, rate_hz: int = 1000) -> None:
    """Regenerate every recording of the paper's experiment, in the order the analysis needs them.

    1. the identification run (100 mm/s, 10 mm) into ``data/identification/pulse_v100_x10``;
    2. its identification on the 9-10 s window with :func:`helpers.identify.identify_recording`, saved to
       ``data/identification/result.json`` (what notebook 02 computes and saves too);
    3. the twelve Table I scenarios x ``repetitions``, with the TDFs designed from that result, into
       ``data/experiments/``.

    Parameters
    ----------
    rig : helpers.rig.Rig
        A connected rig.
    repetitions, t_end_s, rate_hz
        As :func:`record_table_i`.
    """
    run = paper.IDENTIFICATION_RUN
    rec = rig.run_pulse(
        run["v_in_mm_s"],
        run["x_f_mm"],
        None,
        system="unshaped",
        path=DATA_DIR / "identification" / "pulse_v100_x10",
        t_end_s=t_end_s,
        rate_hz=rate_hz,
        progress=False,
    )
    print(f"identification run: {rec.status}, {len(rec.frame)} samples -> {_shown(rec.path)}")
    result = identify_recording(rec, window=run["window_s"], column="adc")
    path = save_identification(result)
    print(f"identified zeta = {result.zeta:.4f}, omega_d = {result.omega_d:.3f} rad/s -> {_shown(path)}")
    zv, zvd = design_tdfs(result.omega_d, result.zeta)
    design = {"zeta": result.zeta, "omega_d": result.omega_d, "origin": _shown(path)}
    record_table_i(
        rig,
        {"unshaped": None, "zv": zv, "zvd": zvd},
        design,
        repetitions=repetitions,
        t_end_s=t_end_s,
        rate_hz=rate_hz,
    )


def _record_calibration(rig: Rig, args: argparse.Namespace) -> None:
    folder = DATA_DIR / (args.group or "calibration")
    recs = record_calibration(rig, duration_s=args.duration, folder=folder, rate_hz=args.rate)
    fit = fit_calibration(recs)
    path = save_calibration(fit, recs, folder / "calibration.json")
    print(
        f"{len(recs)} loads recorded; gain {fit.gain_counts_per_n:.4f} +- {fit.gain_stderr:.4f} "
        f"counts/N, offset {fit.offset_counts:.3f} +- {fit.offset_stderr:.3f} counts -> {path}"
    )


def _record_pulse(rig: Rig, args: argparse.Namespace) -> None:
    if args.v_in is None or args.x_f is None:
        raise SystemExit("record pulse needs --v-in and --x-f")
    shapers, design = _shapers(args) if args.system != "unshaped" else ({"unshaped": None}, None)
    name = args.name or scenario_name(args.system, args.v_in, args.x_f)
    path = DATA_DIR / (args.group or "runs") / name
    rec = rig.run_pulse(
        args.v_in,
        args.x_f,
        shapers[args.system],
        system=args.system,
        path=path,
        t_end_s=args.t_end,
        rate_hz=args.rate,
        progress=not args.quiet,
        scenario_extra=None if design is None else {"design": design},
    )
    print(f"{rec.status}: {len(rec.frame)} samples -> {_shown(rec.path)}")


def _record_table_i(rig: Rig, args: argparse.Namespace) -> None:
    shapers, design = _shapers(args)
    record_table_i(
        rig,
        shapers,
        design,
        repetitions=args.repetitions,
        group=DATA_DIR / (args.group or "experiments"),
        t_end_s=args.t_end,
        rate_hz=args.rate,
    )


def _record_all(rig: Rig, args: argparse.Namespace) -> None:
    record_all(rig, repetitions=args.repetitions, t_end_s=args.t_end, rate_hz=args.rate)


RECORDERS: dict[str, Callable[[Rig, argparse.Namespace], None]] = {
    "calibration": _record_calibration,
    "pulse": _record_pulse,
    "table-i": _record_table_i,
    "all": _record_all,
}
"""What ``record`` can record -> the function that does it."""


def _calibration_for(what: str) -> LoadCellCalibration | None:
    """The load-cell calibration a run uses: the saved one; recording a new one may start without any."""
    if what != "calibration":
        return None  # Rig loads it, or says clearly that there is none yet
    try:
        return load_calibration()
    except MissingDataError:
        return UNCALIBRATED


def run(args: argparse.Namespace) -> int:
    """Run ``python -m helpers record``."""
    rig = Rig.connect(
        args.ports,
        rig_name=args.rig_name,
        calibration=_calibration_for(args.what),
        daq_options=f"&seed={args.seed}" if args.ports == "virtual" else "",
    )
    try:
        print(
            f"connected: daq firmware {rig.daq.version}, stepper firmware {rig.stepper.version}, "
            f"source {rig.source['kind']}"
        )
        RECORDERS[args.what](rig, args)
        return 0
    except KeyboardInterrupt:
        print("interrupted: the driver was disabled and the partial recording saved", file=sys.stderr)
        return 130
    finally:
        rig.close()
