"""``python -m helpers rig check FILE [--json]``, ``rig new FILE`` and ``rig firmware FILE``: the rig file.

``check`` validates a rig file and prints what follows from it: cable per step, the limits in steps and step
intervals, the ADC range in newtons, and the arm's **predicted** modes at rest and across its travel from
its geometry (the twin's statics and linearisation with the file's values: untuned unless the file holds
tuned values, as the paper's does). A rig whose twin cannot hold its travel (static tension at full travel
above the stepper's pull-out tension) is refused, and so is one the boards cannot hold
(``helpers.rigfile.capacity``). ``new`` writes a commented template from the paper's rig and never overwrites
a file. ``firmware`` builds and uploads the boards' firmware for it (``helpers.commands.rig_firmware``).

Exit status: 0; 2 for a bad rig file or argument (one line naming the file, the key and the problem); 5 if
``new`` would overwrite a file; ``firmware``: see its module.
"""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from helpers import rigfile
from helpers.base.jsonfile import DataFileError
from helpers.commands import rig_firmware
from helpers.rigfile import RigFile, RigFileError, capacity
from helpers.rigfile.template import template_text
from helpers.virtual import statics
from helpers.virtual.from_rig import planar_holds, rig_parameters
from helpers.virtual.spatial import statics as spatial_statics
from helpers.virtual.spatial.direction_map import bend_equilibrium
from helpers.virtual.spatial.from_rig import spatial_rig

__all__ = ["add_arguments", "run", "report", "predicted_modes"]

N_MODES = 3
"""Modes listed at rest."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``rig`` command's subcommands."""
    sub = parser.add_subparsers(dest="rig_command", required=True, metavar="subcommand")
    check = sub.add_parser("check", help="validate a rig file and print what follows from it")
    check.add_argument("file", help="the rig file (a path, or a shipped rig's name: paper, long-arm, ...)")
    check.add_argument("--json", action="store_true", help="print one JSON object")
    check.add_argument("--points", type=int, default=5, help="cable positions across the travel (>= 2)")
    new = sub.add_parser("new", help="write a commented rig file template from the paper's rig")
    new.add_argument("file", help="the file to write (refused if it exists)")
    new.add_argument("--name", default=None, help="the rig's name (default: the file's stem)")
    firmware = sub.add_parser(
        "firmware", help="build (and upload) both boards' firmware for a rig file",
        description=rig_firmware.__doc__.split("\n\n")[1].replace("``", ""),
    )  # fmt: skip
    rig_firmware.add_arguments(firmware)


def _mode_rows(df: Any, n: int) -> list[dict[str, float]]:
    return [
        {"omega_d_rad_s": float(r.omega_d), "zeta": float(r.zeta), "omega_n_rad_s": float(r.omega_n)}
        for r in df.iloc[:n].itertuples()
    ]


def predicted_modes(rig: RigFile, points: int = 5) -> dict[str, Any]:
    """The twin's modes of ``rig`` at rest and across its travel (spools held; rotor free for the dominant).

    One tendon with gravity in its plane: the planar twin (``helpers.virtual.statics``); otherwise the
    spatial twin, the travel pulled on tendon 1 alone (a bend towards it).
    """
    travel = rig.hardware.travel_mm
    u_mm = np.linspace(0.0, travel, max(2, points))
    planar = planar_holds(rig)
    out: dict[str, Any] = {"twin": "planar" if planar else "spatial"}
    if planar:
        p = rig_parameters(rig)
        locked = statics.linearise(p, 0.0, rotor="locked")
        free = statics.linearise(p, 0.0, rotor="free")
        out["modes_at_rest"] = _mode_rows(locked.modes(), N_MODES)
        out["dominant_at_rest"] = {"omega_d_rad_s": free.omega_d, "zeta": free.zeta}
        fm = statics.frequency_map(p, u_mm=u_mm)
        cols = ["u_mm", "static_tension_n", "omega_d_rad_s", "zeta", "omega_d2_rad_s", "zeta2",
                "dominant_omega_d_rad_s", "dominant_zeta"]  # fmt: skip
        out["across_travel"] = [{c: float(row[c]) for c in cols} for _, row in fm.iterrows()]
        return out
    s = spatial_rig(rig)
    rest = spatial_statics.rest_equilibrium(s)
    locked = spatial_statics.linearise(s, rest, rotor="locked")
    free = spatial_statics.linearise(s, rest, rotor="free")
    out["modes_at_rest"] = _mode_rows(locked.modes(), N_MODES)
    wd, z = free.dominant(0)
    out["dominant_at_rest"] = {"omega_d_rad_s": wd, "zeta": z}
    rows, eq = [], None
    for u in u_mm:
        eq = bend_equilibrium(s, rig.tendons[0].angle_deg, float(u), start=eq)
        m = spatial_statics.linearise(s, eq, rotor="locked").modes()
        wd, z = spatial_statics.linearise(s, eq, rotor="free").dominant(0)
        rows.append({
            "u_mm": float(u), "static_tension_n": float(eq.tension[0]),
            "omega_d_rad_s": float(m.omega_d.iloc[0]), "zeta": float(m.zeta.iloc[0]),
            "omega_d2_rad_s": float(m.omega_d.iloc[1]), "zeta2": float(m.zeta.iloc[1]),
            "dominant_omega_d_rad_s": wd, "dominant_zeta": z,
        })  # fmt: skip
    out["across_travel"] = rows
    return out


def report(rig: RigFile, points: int = 5) -> dict[str, Any]:
    """Everything ``rig check`` prints, as one JSON-ready object."""
    d = rigfile.derived(rig)
    hw, a = rig.hardware, rig.arm
    p = rig_parameters(rig, planar_gravity=False)
    t1 = rig.tendons[0]
    out: dict[str, Any] = {
        "rig": rig.name, "file": rig.source, "hash": rig.hash, "schema_version": rig.schema_version,
        "n_tendons": rig.n_tendons, "tendon_angles_deg": [t.angle_deg for t in rig.tendons],
        "mm_per_step": d.mm_per_step[0], "mm_per_step_per_axis": list(d.mm_per_step),
        "travel_mm": hw.travel_mm, "travel_steps": list(d.travel_steps),
        "release_mm": hw.release_mm, "release_steps": list(d.release_steps),
        "speed_limit_mm_s": hw.speed_limit_mm_s, "max_step_rate_hz": list(d.max_rate_steps_s),
        "min_interval_us": d.min_interval_us, "max_interval_us": d.max_interval_us,
        "adc_max_counts": d.adc_max, "adc_offset_counts": d.offset_counts,
        "adc_counts_per_n": list(d.gain_counts_per_n),
        "adc_n_per_count": [1.0 / g for g in d.gain_counts_per_n],
        "adc_clip_low_counts": d.clip_low_counts, "adc_clip_high_counts": d.clip_high_counts,
        "adc_range_n": [[(d.clip_low_counts - d.offset_counts) / g, r]
                        for g, r in zip(d.gain_counts_per_n, d.readable_n, strict=True)],
        "pull_out_n": [t.pull_out_n for t in rig.tendons], "hold_estimate_n": list(d.hold_n),
        "cable_stiffness_n_m": t1.cable_stiffness_n_m, "series_stiffness_n_m": p.k,
        "pretension_n": t1.pretension_n,
        "rod_bending_stiffness_n_m2": p.E * p.second_moment,
        "rod_tip_stiffness_n_m": 3.0 * p.E * p.second_moment / p.L**3,
        "rod_mass_kg": p.rod_mass, "disc_mass_kg": p.disc_mass, "disc_inertia_kg_m2": p.disc_inertia,
        "total_mass_kg": p.total_mass, "gravity_direction": list(a.gravity_direction),
    }  # fmt: skip
    ram = capacity.stepper_ram(rig.n_tendons, d.min_interval_us, hw.programme_max_items)
    link = capacity.daq_link(rig, d.travel_steps, d.release_steps)
    out["firmware"] = (
        f"fits the boards: the stepper's tables take {ram.tables_bytes} of the {ram.tables_max_bytes} B its "
        f"RAM leaves them ({hw.programme_max_items} programme items, at most {ram.max_items}); the DAQ's "
        f"longest data lines ({link.line_bytes} bytes) at {link.rate_hz} Hz use {100 * link.share:.0f} % of "
        f"{link.baud} baud (at most {100 * capacity.DAQ_LINK_SHARE:.0f} %; such lines fit up to "
        f"{link.max_rate_hz} Hz)"
    )
    out["boards"] = {
        "stepper_tables_bytes": ram.tables_bytes, "stepper_tables_max_bytes": ram.tables_max_bytes,
        "stepper_static_bytes": ram.static_bytes, "programme_max_items_fit": ram.max_items,
        "daq_line_bytes_max": link.line_bytes, "daq_bits_per_s": link.bits_per_s,
        "daq_link_share": link.share, "daq_min_baud": link.min_baud,
        "daq_max_rate_hz_longest_lines": link.max_rate_hz,
    }  # fmt: skip
    out.update(predicted_modes(rig, points))
    top = out["across_travel"][-1]["static_tension_n"]
    out["static_tension_at_travel_n"] = top
    out["assumptions"] = (
        "predicted by the twin from the file's values (untuned unless the file holds tuned values); the "
        "twin's parameters absent from the file (rotor, spool and carriage inertia, amplifier, noise) are "
        "the paper rig's"
    )
    if top > t1.pull_out_n:
        raise RigFileError(
            f"{rig.source}: [hardware] travel_mm: the stepper cannot hold {hw.travel_mm:g} mm: the twin's "
            f"static tension there is {top:.1f} N, above its pull-out tension {t1.pull_out_n:.1f} N"
        )
    return out


def _text(r: dict[str, Any]) -> str:
    lines = [
        f"rig {r['rig']} ({r['file']}), hash {r['hash']}, schema {r['schema_version']}: valid",
        f"  tendons: {r['n_tendons']} at {', '.join(f'{a:g}' for a in r['tendon_angles_deg'])} deg",
        "  cable per step: " + ", ".join(f"{m:.5f} mm" for m in r["mm_per_step_per_axis"]),
        f"  travel: {r['travel_mm']:g} mm = " + ", ".join(f"{n} steps" for n in r["travel_steps"]),
        *(
            [
                f"  release below position 0 (the rest): {r['release_mm']:g} mm = "
                + ", ".join(f"{n} steps" for n in r["release_steps"])
            ]
            if any(r["release_steps"])
            else []
        ),
        f"  speed limit {r['speed_limit_mm_s']:g} mm/s: fastest step "
        + ", ".join(f"{s:.0f} steps/s" for s in r["max_step_rate_hz"])
        + f"; step interval {r['min_interval_us']}-{r['max_interval_us']} us",
        f"  firmware: {r['firmware']}",
        f"  ADC: 0-{r['adc_max_counts']} counts, zero load at {r['adc_offset_counts']:.2f} counts, "
        "clipped at "
        f"<= {r['adc_clip_low_counts']} and >= {r['adc_clip_high_counts']}",
    ]
    for i, (lo, hi) in enumerate(r["adc_range_n"]):
        lines.append(
            f"  load cell {i + 1}: {r['adc_n_per_count'][i]:.4f} N per count, reads {lo:.2f} to {hi:.2f} N"
        )
    lines += [
        "  stepper: pull-out " + ", ".join(f"{v:.1f} N" for v in r["pull_out_n"])
        + "; static tension at full travel: estimate " + ", ".join(f"{v:.1f} N" for v in r["hold_estimate_n"])
        + f", twin {r['static_tension_at_travel_n']:.2f} N",
        f"  arm: rod EI {r['rod_bending_stiffness_n_m2']:.4g} N m^2 "
        f"(tip stiffness {r['rod_tip_stiffness_n_m']:.3g}"
        f" N/m), rod {r['rod_mass_kg'] * 1e3:.2f} g, discs {r['disc_mass_kg'] * 1e3:.3f} g each, total "
        f"{r['total_mass_kg'] * 1e3:.2f} g",
        f"  cable: {r['cable_stiffness_n_m']:.0f} N/m "
        f"(with the microstep spring {r['series_stiffness_n_m']:.0f}"
        f" N/m), pretension {r['pretension_n']:g} N",
        f"  predicted modes at rest ({r['twin']} twin, spools held): "
        + ", ".join(f"{m['omega_d_rad_s']:.2f} rad/s (zeta {m['zeta']:.4f})" for m in r["modes_at_rest"]),
        f"  dominant mode at rest (rotor free): {r['dominant_at_rest']['omega_d_rad_s']:.3f} rad/s, "
        f"zeta {r['dominant_at_rest']['zeta']:.4f}",
        "  across the travel:    u_mm  tension_N  omega_d1  zeta1   omega_d2  dominant",
    ]  # fmt: skip
    for row in r["across_travel"]:
        lines.append(
            f"                     {row['u_mm']:6.2f}  {row['static_tension_n']:8.3f}  "
            f"{row['omega_d_rad_s']:8.3f}"
            f"  {row['zeta']:.4f}  {row['omega_d2_rad_s']:8.2f}  {row['dominant_omega_d_rad_s']:8.3f}"
        )
    lines.append(f"  ({r['assumptions']})")
    return "\n".join(lines)


def _finite(obj: Any) -> Any:
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_finite(v) for v in obj]
    return obj


def run(args: argparse.Namespace) -> int:
    """Run ``rig check``, ``rig new`` or ``rig firmware``; return the exit status."""
    if args.rig_command == "firmware":
        return rig_firmware.run(args)
    if args.rig_command == "new":
        path = Path(args.file)
        if path.exists():
            raise DataFileError(f"{path}: exists already; rig new never overwrites (choose another name)")
        name = args.name if args.name is not None else path.stem
        text = template_text(rigfile.default_rig(), name=name)
        rigfile.loads(text, source=str(path))  # the template must itself be valid (and the name too)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        print(
            f"wrote {path}: the paper's rig, every key commented; edit it, then: "
            f"python -m helpers rig check {path}"
        )
        return 0
    if args.points < 2:
        raise ValueError(f"--points must be >= 2, got {args.points}")
    rig = rigfile.load(rigfile.resolve(args.file))
    capacity.require_fit(rig)  # a rig the boards cannot hold is refused, as the header generator refuses it
    r = report(rig, args.points)
    print(json.dumps(_finite(r), indent=1) if args.json else _text(r))
    return 0
