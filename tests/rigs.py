"""The shipped rig files as the rig-parametrised tests see them: their keys, and what follows by hand.

A :class:`ShippedRig` reads a rig file with ``tomllib`` and fills a key the file leaves out from the
*default* column of ``docs/rig_file.md``; its derived values (cable per step, the limits in steps and
intervals, the ADC chain in counts, the hash, the calibration masses, the scaled scenarios) are computed
here by the arithmetic ``docs/rig_file.md`` states, never by the package, so a test comparing the package
with them checks the package.

The fixtures are in ``tests/conftest.py`` (which tests use them: its docstring).
"""

from __future__ import annotations

import functools
import hashlib
import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
RIGS = {"paper": REPO / "rigs" / "paper.toml", "long-arm": REPO / "rigs" / "long-arm.toml"}
"""The shipped single-tendon rig files the rig-parametrised tests run for: the paper's and the second rig."""

PAPER_MASSES_KG = (0.0, 0.2, 0.5, 1.0, 1.5, 1.9)
"""The calibration masses of the paper's rig (0-18.6 N), chosen for a 20 N span (docs/rig_file.md)."""


@functools.cache
def documented_defaults() -> dict[str, dict[str, Any]]:
    """``{table: {key: default}}`` from the tables of ``docs/rig_file.md`` (keys with a default only)."""
    out: dict[str, dict[str, Any]] = {}
    table = None
    for line in (REPO / "docs" / "rig_file.md").read_text().splitlines():
        heading = re.match(r"### `\[(\w+)\]`", line)
        if heading:
            table = heading.group(1)
            out[table] = {}
            continue
        if line.startswith("## "):
            table = None
        row = re.match(r"\| `(\w+)` \| [^|]* \| ([^|]+) \|", line)
        if table and row and row.group(2).strip() != "required":
            text = row.group(2).strip()
            try:
                out[table][row.group(1)] = int(text) if re.fullmatch(r"-?\d+", text) else float(text)
            except ValueError:
                out[table][row.group(1)] = text
    return out


def floor_to(value: float, resolution: float) -> float:
    """``value`` floored to a multiple of ``resolution`` (the scenarios' rule; a hair of tolerance)."""
    return round(math.floor(value / resolution + 1e-9) * resolution, 6)


@dataclass(frozen=True)
class ShippedRig:
    """A shipped rig file: its name, path and keys, and the values that follow from them by hand."""

    name: str
    path: Path

    @functools.cached_property
    def data(self) -> dict[str, Any]:
        """The file's TOML."""
        return tomllib.loads(self.path.read_text())

    def hw(self, key: str) -> Any:
        """A ``[hardware]`` key: the file's value, else the documented default."""
        return self.data["hardware"].get(key, documented_defaults()["hardware"].get(key))

    @property
    def hash(self) -> str:
        """The rig's hash: the first 8 hex digits of the sha256 of the file's bytes."""
        return hashlib.sha256(self.path.read_bytes()).hexdigest()[:8]

    def load(self) -> Any:
        """The rig file as the package reads it (a :class:`helpers.rigfile.RigFile`), to pass to the code."""
        from helpers import rigfile  # the value the code under test takes; never its arithmetic

        return rigfile.load(self.path)

    @property
    def mm_per_step(self) -> float:
        """Cable per step, mm: pi x spool diameter / steps per revolution."""
        return math.pi * self.hw("spool_diameter_mm") / self.hw("steps_per_rev")

    @property
    def travel_steps(self) -> int:
        """The travel in whole steps."""
        return math.floor(self.hw("travel_mm") / self.mm_per_step + 1e-9)

    @property
    def max_step_rate(self) -> float:
        """Fastest step rate, steps/s: the speed limit's, or the cap if lower."""
        return min(self.hw("step_rate_cap_hz"), self.hw("speed_limit_mm_s") / self.mm_per_step)

    @property
    def min_interval_us(self) -> int:
        """Fastest step interval, us (rounded up: never faster than the limit)."""
        return math.ceil(1e6 / self.max_step_rate - 1e-9)

    @property
    def fastest_mm_s(self) -> float:
        """Fastest speed a pulse may ask for: the speed limit, or the step-rate cap's speed if lower."""
        return min(self.hw("speed_limit_mm_s"), self.hw("step_rate_cap_hz") * self.mm_per_step)

    @property
    def longest_mm(self) -> float:
        """Longest pulse, mm: the travel in whole steps."""
        return self.travel_steps * self.mm_per_step

    def counts(self, current_ma: float) -> float:
        """ADC reading of a loop current: 2^bits I R / V_ref."""
        return 2 ** self.hw("adc_bits") * current_ma * 1e-3 * self.hw("shunt_ohm") / self.hw("adc_vref_v")

    @property
    def adc_max(self) -> int:
        """The ADC's top reading."""
        return 2 ** self.hw("adc_bits") - 1

    @property
    def clip_counts(self) -> tuple[int, int]:
        """Readings at or beyond these are clipped: the loop's saturation (the high one less the margin)."""
        low = math.floor(self.counts(self.hw("loop_min_ma")))
        margin = self.hw("adc_clip_margin_counts")
        high = min(self.adc_max, round(self.counts(self.hw("loop_max_ma"))) - margin)
        return low, high

    @property
    def gain_counts_per_n(self) -> float:
        """ADC counts per newton: the loop's span in counts over the load cell's range."""
        span = self.counts(self.hw("loop_full_ma")) - self.counts(self.hw("loop_zero_ma"))
        return span / self.hw("load_cell_range_n")

    @property
    def calibration_masses_kg(self) -> tuple[float, ...]:
        """The paper's masses on a span of 20 N or more, the same fractions of a smaller span (to 1 g)."""
        scale = min(1.0, self.hw("load_cell_range_n") / 20.0)
        return tuple(round(m * scale, 3) for m in PAPER_MASSES_KG)

    def scaled(self, conditions: list[tuple[float, float]]) -> list[tuple[float, float]]:
        """A set of (mm/s, mm) conditions by the scaling rule: speeds to 1 mm/s, distances to 0.1 mm."""
        top_v, top_x = max(v for v, _ in conditions), max(x for _, x in conditions)
        fv = 1.0 if top_v <= self.fastest_mm_s else self.fastest_mm_s / top_v
        fx = 1.0 if top_x <= self.longest_mm else self.longest_mm / top_x
        out: list[tuple[float, float]] = []
        for v, x in conditions:
            pair = (
                float(v) if fv == 1.0 else floor_to(v * fv, 1.0),
                float(x) if fx == 1.0 else floor_to(x * fx, 0.1),
            )
            if pair not in out:
                out.append(pair)
        return out


SHIPPED = {name: ShippedRig(name, path) for name, path in RIGS.items()}
