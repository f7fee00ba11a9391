"""The firmware's rig header: ``python -m helpers.rigfile.firmware_header RIGFILE -o OUT.h``.

Writes a C header with the compiled-in limits and constants of a rig (``docs/rig_file.md``, "The firmware
header"): exactly the macros of :data:`MACROS`. Standard library only; exit status 0, or 2 with one line for
a bad rig file or argument (nothing is written then).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

from helpers.rigfile import RigFile, RigFileError, derived, load, resolve

__all__ = ["MACROS", "OPTIONAL_MACROS", "header_text", "firmware_problem", "main"]

MAX_TRAVEL_STEPS = 255
"""Each axis's travel is an 8-bit table entry on the boards."""

MAX_PROGRAMME_ITEMS = 255
"""The stepper's programme table is indexed by 8 bits."""

MIN_INTERVAL_US = 500
"""The stepper board's shortest step interval."""

MACROS = (
    "RIG_HASH", "RIG_NAME", "RIG_AXES", "RIG_CHANNELS", "RIG_MIN_INTERVAL_US", "RIG_MAX_INTERVAL_US",
    "RIG_AXIS_TRAVEL_STEPS", "RIG_PROGRAMME_MAX", "RIG_DAQ_RATE_MIN_HZ", "RIG_DAQ_RATE_MAX_HZ",
    "RIG_DAQ_RATE_DEFAULT_HZ", "RIG_DAQ_BAUD", "RIG_STEPPER_BAUD", "RIG_ADC_CLIP_LOW_COUNTS",
    "RIG_ADC_CLIP_HIGH_COUNTS",
)  # fmt: skip
"""The header's macros, in order (the contract with the firmware)."""

OPTIONAL_MACROS = ("RIG_AXIS_RELEASE_STEPS",)
"""Macros written only when they differ from the firmware's default (``RIG_AXIS_RELEASE_STEPS``: each axis's
paid-out range below position 0, written after ``RIG_AXIS_TRAVEL_STEPS`` when some axis has one; absent, every
axis has none), so that the header of a rig without them is the same text as before they existed."""


def _c_string(text: str) -> str:
    safe = "".join(c if c.isprintable() and c not in '"\\' else "_" for c in text)
    return f'"{safe}"'


def firmware_problem(rig: RigFile) -> str | None:
    """Why the boards' firmware cannot be built for ``rig`` (its fixed-size tables and timers), or None.

    The limits of ``firmware/common/rig_config.h``: travel 1-255 steps per axis (8-bit table), the release
    below position 0 and the travel together at most 255 steps per axis (an item's steps of one axis are an
    8-bit count of at most their sum), a programme of 1-255 items, step intervals 500 us to 1 s, DAQ rates
    31-4000 Hz.
    """
    d = derived(rig)
    hw = rig.hardware
    worst = max(d.travel_steps)
    if worst > MAX_TRAVEL_STEPS:
        axis = d.travel_steps.index(worst) + 1
        return (
            f"[hardware] travel_mm: {worst} steps on axis {axis}: the boards hold at most {MAX_TRAVEL_STEPS} "
            f"steps of travel per axis (at most {MAX_TRAVEL_STEPS * d.mm_per_step[axis - 1]:.2f} mm)"
        )
    span = [t + r for t, r in zip(d.travel_steps, d.release_steps, strict=True)]
    if max(span) > MAX_TRAVEL_STEPS:
        axis = span.index(max(span)) + 1
        room = MAX_TRAVEL_STEPS - d.travel_steps[axis - 1]
        return (
            f"[hardware] release_mm: {d.release_steps[axis - 1]} steps below position 0 and "
            f"{d.travel_steps[axis - 1]} of travel on axis {axis}: the boards hold at most "
            f"{MAX_TRAVEL_STEPS} steps of both together per axis (a release of at most "
            f"{room * d.mm_per_step[axis - 1]:.2f} mm)"
        )
    if hw.programme_max_items > MAX_PROGRAMME_ITEMS:
        return f"[hardware] programme_max_items: at most {MAX_PROGRAMME_ITEMS} on the boards"
    if d.min_interval_us < MIN_INTERVAL_US:
        return (
            f"[hardware] speed_limit_mm_s: the fastest step interval {d.min_interval_us} us is below the "
            f"firmware's {MIN_INTERVAL_US} us"
        )
    if d.max_interval_us > 1_000_000:
        return "[hardware] max_interval_us: at most 1000000 us on the boards"
    if hw.daq_rate_min_hz < 31 or hw.daq_rate_max_hz > 4000:
        return "[hardware] daq_rate_*_hz: the DAQ board samples at 31-4000 Hz"
    return None


def header_text(path: str | Path) -> str:
    """The header for the rig file at ``path`` (checked first, then against the firmware's limits)."""
    rig = load(path)
    problem = firmware_problem(rig)
    if problem is not None:
        raise RigFileError(f"{rig.source}: {problem}")
    d = derived(rig)
    hw = rig.hardware
    values = {
        "RIG_HASH": _c_string(rig.hash),
        "RIG_NAME": _c_string(rig.name),
        "RIG_AXES": str(rig.n_tendons),
        "RIG_CHANNELS": str(rig.n_tendons),
        "RIG_MIN_INTERVAL_US": str(d.min_interval_us),
        "RIG_MAX_INTERVAL_US": f"{d.max_interval_us}L",
        "RIG_AXIS_TRAVEL_STEPS": "{" + ", ".join(str(n) for n in d.travel_steps) + "}",
        "RIG_PROGRAMME_MAX": str(hw.programme_max_items),
        "RIG_DAQ_RATE_MIN_HZ": str(hw.daq_rate_min_hz),
        "RIG_DAQ_RATE_MAX_HZ": str(hw.daq_rate_max_hz),
        "RIG_DAQ_RATE_DEFAULT_HZ": str(hw.daq_rate_default_hz),
        "RIG_DAQ_BAUD": f"{hw.daq_baud}L",
        "RIG_STEPPER_BAUD": f"{hw.stepper_baud}L",
        "RIG_ADC_CLIP_LOW_COUNTS": str(d.clip_low_counts),
        "RIG_ADC_CLIP_HIGH_COUNTS": str(d.clip_high_counts),
    }
    assert tuple(values) == MACROS
    if any(d.release_steps):
        items = list(values.items())
        at = list(values).index("RIG_AXIS_TRAVEL_STEPS") + 1
        items.insert(at, ("RIG_AXIS_RELEASE_STEPS", "{" + ", ".join(str(n) for n in d.release_steps) + "}"))
        values = dict(items)
    guard = "RIG_CONFIG_H"
    lines = [
        f"/* Generated by python -m helpers.rigfile.firmware_header from {Path(path).name} "
        f"(rig {rig.name}, hash {rig.hash}). Do not edit: edit the rig file and rebuild. */",
        f"#ifndef {guard}",
        f"#define {guard}",
        "",
    ]
    lines += [f"#define {name} {value}" for name, value in values.items()]
    lines += ["", f"#endif /* {guard} */", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Write the header; return the exit status (0, or 2 with one line on stderr)."""
    parser = argparse.ArgumentParser(
        prog="python -m helpers.rigfile.firmware_header", description="write the firmware's rig header"
    )
    parser.add_argument("rigfile", help="the rig file (a path, or a shipped rig's name such as paper)")
    parser.add_argument("-o", "--output", required=True, help="the header to write (e.g. build/rig_config.h)")
    args = parser.parse_args(argv)
    try:
        text = header_text(resolve(args.rigfile))
    except RigFileError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    out = Path(args.output)
    try:
        if out.exists() and out.read_text() == text:
            return 0  # unchanged: keep its time stamp, so make does not rebuild
        out.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}.", suffix=".tmp")
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, out)
    except OSError as exc:
        print(f"error: {out}: could not write ({exc.strerror})", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
