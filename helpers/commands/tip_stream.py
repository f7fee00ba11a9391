"""``python -m helpers record tip-stream``: a figure of bends streamed to a rig with several tendons.

::

    python -m helpers --rig four-tendon record tip-stream --path square --bend-mm 10 --prepull 1 --dry-run

The path (:func:`helpers.research.tip_stream.figure_path`) is planned and checked before any port opens: every
tendon's set-points by the statics, the static tensions at every period against the rig file's floor, the
stream's own checks (travel, speed, the board's shaped motion), and the static tensions at the board's
whole-step counts at every period (:func:`~helpers.research.tip_stream.check_whole_steps`): a tendon below the
floor there is refused in one line naming the tendon, the period and the figure, and saying which
``--prepull K`` (every tendon pulled ``K`` steps in before the path and let out after it, as a move's
pre-pull) passes, if one up to :data:`~helpers.research.task_shaping.MAX_PREPULL_STEPS` does; nothing is
pre-pulled unless asked. The dry run prints each tendon's range of set-points and least planned tension
against the floor, the shaper and the modes it was designed from, the least tensions at the board's whole
steps, then names the recording it would make. Without it the stream is recorded (``helpers.rig.stream``; the
tendons must stand at rest) into ``data/<group>/tip_<path>_<shaper>_b<bend>`` (``_pre<K>`` with a pre-pull),
the floor watched (``--no-floor-watch``: not); with ``--trim`` every tendon is trimmed by measurement before
the stream and at every stop long enough for it (:func:`~helpers.research.tip_stream.rest_trims`,
``docs/safety.md``).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from helpers.base.paths import repo_path
from helpers.commands.recording_paths import recording_path
from helpers.commands.session import recording_session, tension_guard
from helpers.recordings import refuse_existing
from helpers.research.task_shaping import MAX_PREPULL_STEPS, pretensioned, release_order
from helpers.research.tip_stream import (
    PERIOD_S,
    PREPULL_SETTLE_PERIODS,
    RELEASE_GAP_PERIODS,
    TooFast,
    board_counts,
    check_plan,
    check_whole_steps,
    figure_path,
    interpolation_error,
    plan_stream,
    rest_trims,
    stream_design,
)
from helpers.rig import SafetyError
from helpers.rig.stream import stream
from helpers.rig.trim import REST_WINDOW_S
from helpers.virtual.spatial.from_rig import spatial_rig

__all__ = ["record_tip_stream", "TIP_SPEED_MM_S", "TIP_TAIL_S"]

TIP_SPEED_MM_S = 100.0
"""The figure's speed (mm of bend per second) when ``--v-in`` is not given."""

TIP_TAIL_S = 1.5
"""Device time recorded after the board's ``DONE``, s."""


def _name(args: argparse.Namespace) -> str:
    text = f"tip_{args.path}_{args.shaper}_b{args.bend_mm:g}" + (
        f"_m{args.margin_n:g}" if args.margin_n else ""
    ) + (f"_d{args.direction_deg:g}" if args.direction_deg else "") + (
        f"_pre{args.prepull}" if args.prepull else ""
    )
    return args.name or text.replace(".", "p").replace("-", "m")


def _plan(args: argparse.Namespace, rig: Any, prepull: int) -> tuple[Any, Any, Any, Any]:
    """The path, its plan pre-pulled ``prepull`` steps, its design and the twin they were made on."""
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
    twin = base = spatial_rig(rig)
    if prepull:  # the design's modes and the interpolation's statics from the pre-pulled rest
        try:
            twin = pretensioned(rig, base, prepull)
        except ValueError as exc:
            raise ValueError(f"--prepull {prepull}: {exc}") from None
    try:  # the floor at every period: before any port
        plan = plan_stream(rig, path, spatial=base, margin_n=args.margin_n, prepull=prepull)
    except TooFast as exc:
        raise TooFast(f"{exc}: {_fitting(rig, figure, speed, args.margin_n, prepull)}") from None
    if not np.abs(plan.units).any():
        raise ValueError(f"--bend-mm {args.bend_mm:g}: the {args.path} path moves no tendon a whole step "
                         "(a stream of zero steps); nothing recorded")  # fmt: skip
    design = stream_design(rig, path, args.shaper, spatial=twin)
    return path, plan, design, twin


FIT_TRIES = 6
"""Halvings of the figure's speed, then as many bisections, that :func:`_fitting` plans at most."""


def _fitting(rig: Any, figure: Callable[[float], Any], speed: float, margin_n: float, prepull: int) -> str:
    """What figure speed fits, found by planning the figure (halving, then bisecting; every answer planned).

    A speed fits when the whole plan passes (the speed limit, the floor, the statics); the set-points of a
    line scale with the figure's speed, at a corner the statics make them scale less, so the speed is found
    by planning, not by proportion.
    """

    def fits(v: float) -> bool:
        try:
            plan_stream(rig, figure(v), margin_n=margin_n, prepull=prepull)
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


def _print(rig: Any, path: Any, plan: Any, design: Any, twin: Any) -> None:
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
        error = interpolation_error(rig, path, plan.knot_mm, spatial=twin)
        print(
            f"  the statics solved at knots every {plan.knot_mm:g} mm of bend, {plan.interpolated} periods "
            f"interpolated between them: at most {error:.4f} step off the statics at the knots' midpoints"
        )
    else:
        print(f"  the statics solved at every period in motion (knots every {plan.knot_mm:g} mm of bend)")
    if plan.prepull:
        order = ", ".join(str(j + 1) for j in release_order(rig.n_tendons))
        print(
            f"  pre-pull: every tendon pulled {plan.prepull} step(s) in before the path (1 period, then "
            f"{PREPULL_SETTLE_PERIODS * PERIOD_S:.2f} s at rest) and let out after it one at a time (tendons "
            f"{order}, {RELEASE_GAP_PERIODS * PERIOD_S:.2f} s apart); planned and designed from that "
            "pre-pulled rest (positions and stops count from it)"
        )
    print(f"  shaper: {design.describe()}")


def _prepull_hint(args: argparse.Namespace, rig: Any) -> str:
    """Which ``--prepull`` above the one asked keeps every tendon at the floor at the board's whole steps.

    Each pre-pull is planned, designed and checked as the command would with it (every check of the stream).
    """
    if args.prepull >= MAX_PREPULL_STEPS:
        return f"no larger pre-pull is allowed (--prepull at most {MAX_PREPULL_STEPS})"
    try:
        pretensioned(rig, spatial_rig(rig), 1)
    except ValueError as exc:
        return f"no --prepull can lift it on this rig: {exc}"
    last = ""
    for k in range(args.prepull + 1, MAX_PREPULL_STEPS + 1):
        try:
            _, plan, design, _ = _plan(args, rig, k)
            check_plan(plan, rig, design.shaper)
            tension = check_whole_steps(plan, rig, design.shaper)
        except (SafetyError, ValueError) as exc:
            last = str(exc)
            continue
        return (f"--prepull {k} passes (every tendon pulled {k} step(s) in before the path and let out after "
                f"it: the least {tension.min():.2f} N at the board's whole steps)")  # fmt: skip
    return f"no --prepull up to {MAX_PREPULL_STEPS} passes ({last})"


def record_tip_stream(args: argparse.Namespace) -> int:
    """``record tip-stream``: plan, check, print (dry run) or record one figure of bends (several tendons)."""
    rig = args.rig
    path, plan, design, twin = _plan(args, rig, args.prepull)
    target = recording_path(args.group, _name(args), args.data_dir)
    if not args.replace:
        refuse_existing(target)
    if args.dry_run:
        _print(rig, path, plan, design, twin)
    checked = check_plan(plan, rig, design.shaper)  # travel, speed, the shaped motion: from rest
    counts = board_counts(plan, rig, design.shaper)
    if counts != plan.stop_counts():
        raise SafetyError(
            f"the {path.name} path: the board's planner stands at {counts} at the stops, not at the plan's "
            f"{plan.stop_counts()}"
        )
    try:  # every tendon at the floor at the board's whole steps, at every period
        least = check_whole_steps(plan, rig, design.shaper).min(axis=0)
    except SafetyError as exc:
        raise SafetyError(f"{exc}; {_prepull_hint(args, rig)}") from None
    guard = tension_guard(args, rig)
    if args.trim:  # and at every rest long enough: to the statics' tension at the board's whole steps there
        guard = replace(guard, rests=rest_trims(plan, rig, design.shaper, REST_WINDOW_S))
    if args.dry_run:
        figures = ", ".join(f"{t:.2f}" for t in least)
        print(
            f"  checked: the least static tensions at the board's whole-step counts at every period (its "
            f"planner, one-step hysteresis{', the pre-pull and its let-out' if plan.prepull else ''}): "
            f"{figures} N for tendons 1-{rig.n_tendons}, at or above the floor {plan.floor_n:.2f} N"
        )
        print(
            f"  the board's shaped motion (its planner) reaches {list(checked.reach)} steps"
            f"{' (from the rest before the pre-pull)' if plan.prepull else ''} and stands at the plan's "
            "whole steps at every stop"
        )
        if guard.rests is not None:
            where, k = ", ".join(str(r.setpoint) for r in guard.rests) or "none long enough", len(guard.rests)
            print(f"  --trim: every tendon trimmed by measurement before the stream and at {k} of its stops "
                  f"(set-points {where}), to the statics' tensions at the board's counts there")
        print(f"dry run: 1 recording would be made on --ports {args.ports}: {repo_path(target)}; "
              "nothing was sent")  # fmt: skip
        return 0
    scenario = {
        "stream_of": "tip path", "path": path.metadata(), "shaper_name": design.name,
        "design": design.metadata(), **plan.metadata(), "speed_mm_s": path.speed_mm_s,
        "board_count_min_static_tension_n": [round(float(t), 6) for t in least],
    }  # fmt: skip
    with recording_session(args, from_rest="a tip stream") as (trig, noise_seed):
        print(f"  {path.summary()}; shaper: {design.describe()}")
        rec = stream(trig, plan.board_setpoints_mm_s, design.shaper, path=target, scenario=scenario,
                     lead_in_s=0.2, rate_hz=args.rate, replace=args.replace, tail_s=TIP_TAIL_S,
                     noise_seed=noise_seed, progress=False, guard=guard)  # fmt: skip
    print(f"{rec.meta['status']}: {len(rec.frame)} samples -> {repo_path(rec.path)}")
    return 0
