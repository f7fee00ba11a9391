"""``python -m helpers record tip-stream``: a figure of bends streamed to a rig with several tendons.

::

    python -m helpers --rig four-tendon record tip-stream --path square --bend-mm 10 --shaper zvd --dry-run

The path (:func:`helpers.research.tip_stream.figure_path`) is planned and checked before any port opens: every
tendon's set-points by the statics, the static tensions at every period against the rig file's floor, and the
stream's own checks (travel, speed, the board's shaped motion). The dry run prints each tendon's range of
set-points and least planned tension against the floor, the shaper and the modes it was designed from, then
names the recording it would make. Without it the stream is recorded (``helpers.rig.stream``; the tendons
must stand at rest) into ``data/<group>/tip_<path>_<shaper>_b<bend>``.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from helpers.base.paths import repo_path
from helpers.commands.recording_paths import recording_path
from helpers.commands.session import recording_session
from helpers.recordings import refuse_existing
from helpers.research.tip_stream import (
    TooFast,
    board_counts,
    board_tensions,
    check_plan,
    figure_path,
    interpolation_error,
    plan_stream,
    stream_design,
)
from helpers.rig import SafetyError
from helpers.rig.stream import stream

__all__ = ["record_tip_stream", "TIP_SPEED_MM_S", "TIP_TAIL_S"]

TIP_SPEED_MM_S = 100.0
"""The figure's speed (mm of bend per second) when ``--v-in`` is not given."""

TIP_TAIL_S = 1.5
"""Device time recorded after the board's ``DONE``, s."""


def _name(args: argparse.Namespace) -> str:
    text = f"tip_{args.path}_{args.shaper}_b{args.bend_mm:g}" + (
        f"_m{args.margin_n:g}" if args.margin_n else ""
    ) + (f"_d{args.direction_deg:g}" if args.direction_deg else "")
    return args.name or text.replace(".", "p").replace("-", "m")


def _plan(args: argparse.Namespace, rig: Any) -> tuple[Any, Any, Any]:
    if args.bend_mm is None:
        raise SystemExit("record tip-stream needs --bend-mm (the figure's size)")
    if rig.n_tendons < 2:
        raise ValueError(
            f"record tip-stream needs a rig file with several tendons; the selected rig '{rig.name}' has one "
            "(--rig four-tendon)"
        )
    speed = args.v_in if args.v_in is not None else TIP_SPEED_MM_S
    limit = rig.hardware.speed_limit_mm_s
    if speed > limit:
        raise SafetyError(f"tip stream at --v-in {speed:g} mm/s refused: rig {rig.name!r} moves a cable at "
                          f"most {limit:g} mm/s (speed_limit_mm_s)")  # fmt: skip

    def figure(v: float) -> Any:
        return figure_path(args.path, args.bend_mm, speed_mm_s=v, seed=args.path_seed,
                           turn_deg=args.direction_deg or 0.0)  # fmt: skip

    path = figure(speed)
    try:
        plan = plan_stream(rig, path, margin_n=args.margin_n)  # the floor at every period: before any port
    except TooFast as exc:
        raise TooFast(f"{exc}: {_fitting(rig, figure, speed, args.margin_n)}") from None
    if not np.abs(plan.units).any():
        raise ValueError(f"--bend-mm {args.bend_mm:g}: the {args.path} path moves no tendon a whole step "
                         "(a stream of zero steps); nothing recorded")  # fmt: skip
    design = stream_design(rig, path, args.shaper)
    return path, plan, design


FIT_TRIES = 6
"""Halvings of the figure's speed, then as many bisections, that :func:`_fitting` plans at most."""


def _fitting(rig: Any, figure: Callable[[float], Any], speed: float, margin_n: float) -> str:
    """What figure speed fits, found by planning the figure (halving, then bisecting; every answer planned).

    A speed fits when the whole plan passes (the speed limit, the floor, the statics); the set-points of a
    line scale with the figure's speed, at a corner the statics make them scale less, so the speed is found
    by planning, not by proportion.
    """

    def fits(v: float) -> bool:
        try:
            plan_stream(rig, figure(v), margin_n=margin_n)
        except (SafetyError, ValueError, RuntimeError):  # too fast, or refused otherwise
            return False
        return True

    hi, lo = speed, None
    for _ in range(FIT_TRIES):
        if fits(hi / 2):
            lo = hi / 2
            break
        hi /= 2
    if lo is None:
        return f"still too fast at {hi:g} mm/s: a smaller --bend-mm or another --path"
    for _ in range(FIT_TRIES):
        mid = math.floor((lo + hi) / 2 * 10) / 10
        if mid <= lo:
            break
        lo, hi = (mid, hi) if fits(mid) else (lo, mid)
    return f"--v-in {lo:g} fits (planned; {hi:g} is refused)"


def _print(rig: Any, path: Any, plan: Any, design: Any) -> None:
    print(
        f"tip stream on rig '{rig.name}' ({rig.n_tendons} tendons): {path.summary()}; set-points by the "
        "spatial twin's statics (simulated), static tensions at every period (rotors free):"
    )
    for line in plan.lines(rig):
        print(f"  {line}")
    away = [(path.polar(a), s) for (a, _), s in zip(path.stops, plan.stop_steps, strict=True)]
    stops = "; ".join(f"{m:g} mm towards {d:g} deg: {', '.join(f'{n:+d}' for n in s)}" for (d, m), s in away)
    print(f"  whole steps at the stops: {stops}")
    if plan.interpolated:
        error = interpolation_error(rig, path, plan.knot_mm)
        print(
            f"  the statics solved at knots every {plan.knot_mm:g} mm of bend, {plan.interpolated} periods "
            f"interpolated between them: at most {error:.4f} step off the statics at the knots' midpoints"
        )
    else:
        print(f"  the statics solved at every period in motion (knots every {plan.knot_mm:g} mm of bend)")
    print(f"  shaper: {design.describe()}")


def record_tip_stream(args: argparse.Namespace) -> int:
    """``record tip-stream``: plan, check, print (dry run) or record one figure of bends (several tendons)."""
    rig = args.rig
    path, plan, design = _plan(args, rig)
    target = recording_path(args.group, _name(args), args.data_dir)
    if not args.replace:
        refuse_existing(target)
    if args.dry_run:
        _print(rig, path, plan, design)
    checked = check_plan(plan, rig, design.shaper)  # travel, speed, the shaped motion: from rest
    counts = board_counts(plan, rig, design.shaper)
    if [tuple(c) for c in counts] != list(plan.stop_steps):
        raise SafetyError(
            f"the {path.name} path: the board's planner stands at {counts} at the stops, not at the plan's "
            f"{list(plan.stop_steps)}"
        )
    forecast = board_tensions(plan, rig, design.shaper).min(axis=0)
    if args.dry_run:
        figures = ", ".join(f"{t:.2f}" for t in forecast)
        print(
            f"  forecast (not a check): the least static tensions at the board's whole-step counts as it "
            f"moves (its planner, one-step hysteresis): {figures} N for tendons 1-{rig.n_tendons}"
        )
        print(
            f"  the board's shaped motion (its planner) reaches {list(checked.reach)} steps and stands at "
            "the plan's whole steps at every stop"
        )
        print(f"dry run: 1 recording would be made on --ports {args.ports}: {repo_path(target)}; "
              "nothing was sent")  # fmt: skip
        return 0
    scenario = {
        "stream_of": "tip path", "path": path.metadata(), "shaper_name": design.name,
        "design": design.metadata(), **plan.metadata(), "speed_mm_s": path.speed_mm_s,
        "board_count_min_static_tension_n": [round(float(t), 6) for t in forecast],
    }  # fmt: skip
    with recording_session(args, from_rest="a tip stream") as (trig, noise_seed):
        print(f"  {path.summary()}; shaper: {design.describe()}")
        rec = stream(trig, plan.setpoints_mm_s, design.shaper, path=target, scenario=scenario, lead_in_s=0.2,
                     rate_hz=args.rate, replace=args.replace, tail_s=TIP_TAIL_S, noise_seed=noise_seed,
                     progress=False)  # fmt: skip
    print(f"{rec.meta['status']}: {len(rec.frame)} samples -> {repo_path(rec.path)}")
    return 0
