"""The experiment's scenarios on the selected rig: the paper's, scaled where they do not fit the rig file.

The paper's Table I speeds (200, 300 mm/s) and distances (10-30 mm), its identification run (100 mm/s,
10 mm), ``tune``'s grids and the survey's positions are written for the paper's rig. On another rig
(``docs/rig_file.md``) a set of them that does not fit is **scaled**, never clamped one by one, by this
rule:

- speeds: when the set's fastest speed exceeds the fastest speed a request may ask for (the file's
  ``speed_limit_mm_s``, or the step-rate cap's speed ``step_rate_cap_hz x mm_per_step`` if lower: what
  ``helpers.rig.safety.check_request`` accepts), every speed of the set is multiplied by
  ``fastest / set's fastest`` and floored to a whole mm/s;
- distances: when the set's longest distance exceeds the longest pulse (the travel in whole steps), every
  distance is multiplied by ``longest pulse / set's longest`` and floored to 0.1 mm;
- survey positions: when the last exceeds the travel, they are spread over the travel in the same number of
  equal steps (0.1 mm).

Ratios within a set are kept (to the rounding), so Table I's structure (three distances at one speed, one
at a faster speed) survives. On the paper's rig nothing is scaled: the values, the scenario names and the
files are the paper's. :func:`scaling_notes` says which sets were scaled and to what; the commands print it
once.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence

from helpers.paper import numbers as paper
from helpers.paper.hardware import (
    MAX_PULSE_MM,
    MAX_SPEED_MM_S,
    MAX_STEP_RATE_HZ,
    MAX_TRAVEL_MM,
    MM_PER_STEP,
    RIG,
)

FASTEST_MM_S: float = min(MAX_SPEED_MM_S, MAX_STEP_RATE_HZ * MM_PER_STEP)
"""The fastest cable speed a pulse may ask for, mm/s (the speed limit, or the step-rate cap's speed)."""
LONGEST_MM: float = min(MAX_TRAVEL_MM, MAX_PULSE_MM)
"""The longest pulse the rig allows, mm (its travel in whole steps)."""

_announced: set[str] = set()


def _scale(values: Sequence[float], limit: float, resolution: float) -> tuple[float, ...]:
    """``values`` unchanged when they fit ``limit``, else all scaled by ``limit / max`` and floored."""
    top = max(values)
    if top <= limit:
        return tuple(float(v) for v in values)
    factor = limit / top
    return tuple(round(math.floor(v * factor / resolution + 1e-9) * resolution, 6) for v in values)


def scale_conditions(
    conditions: Sequence[tuple[float, float]],
    fastest_mm_s: float = FASTEST_MM_S,
    longest_mm: float = LONGEST_MM,
) -> tuple[tuple[float, float], ...]:
    """Scale a set of ``(v_in mm/s, x_f mm)`` conditions to a rig by the module's rule.

    Parameters
    ----------
    conditions : sequence of (float, float)
        The paper's conditions.
    fastest_mm_s : float
        The rig's fastest speed (default: the selected rig's).
    longest_mm : float
        The rig's longest pulse (default: the selected rig's).

    Returns
    -------
    tuple of (float, float)
        The conditions, unchanged when they fit; duplicates (after rounding) are kept once.
    """
    speeds = _scale([v for v, _ in conditions], fastest_mm_s, 1.0)
    dists = _scale([x for _, x in conditions], longest_mm, 0.1)
    out: list[tuple[float, float]] = []
    for pair in zip(speeds, dists, strict=True):
        if pair not in out:
            out.append(pair)
    return tuple(out)


def table_i_conditions() -> tuple[tuple[float, float], ...]:
    """Table I's four (v_in, x_f) conditions on the selected rig (the paper's on the paper's rig)."""
    return scale_conditions(paper.TABLE_I_CONDITIONS)


def identification_run() -> dict:
    """The identification run on the selected rig: the paper's (100 mm/s, 10 mm, 9-10 s), scaled if needed."""
    run = paper.IDENTIFICATION_RUN
    ((v, x),) = scale_conditions([(run["v_in_mm_s"], run["x_f_mm"])])
    return {"v_in_mm_s": v, "x_f_mm": x, "window_s": run["window_s"]}


def identification_name() -> str:
    """File name of the identification run: ``pulse_v100_x10`` on the paper's rig."""
    run = identification_run()
    return f"pulse_v{run['v_in_mm_s']:g}_x{run['x_f_mm']:g}".replace(".", "p")


def survey_positions(positions_mm: Sequence[float]) -> tuple[float, ...]:
    """Survey positions on the selected rig: ``positions_mm``, or as many spread over the travel."""
    if max(positions_mm) <= MAX_TRAVEL_MM:
        return tuple(float(p) for p in positions_mm)
    n = len(positions_mm) - 1
    return tuple(round(math.floor(MAX_TRAVEL_MM * k / n * 10 + 1e-9) / 10, 6) for k in range(n + 1))


def _mapping(before: Sequence[float], after: Sequence[float], unit: str) -> str:
    """``"200, 300 -> 100, 150 mm/s"`` (distinct values, in order)."""
    pairs = dict(zip(before, after, strict=True))
    return f"{', '.join(f'{b:g}' for b in pairs)} -> {', '.join(f'{a:g}' for a in pairs.values())} {unit}"


def _note(name: str, conditions: Sequence[tuple[float, float]]) -> str | None:
    """How ``conditions`` are scaled on the selected rig, or None when they fit."""
    speeds, dists = [float(v) for v, _ in conditions], [float(x) for _, x in conditions]
    new_speeds, new_dists = _scale(speeds, FASTEST_MM_S, 1.0), _scale(dists, LONGEST_MM, 0.1)
    parts = []
    if tuple(speeds) != new_speeds:
        parts.append("speeds " + _mapping(speeds, new_speeds, "mm/s"))
    if tuple(dists) != new_dists:
        parts.append("distances " + _mapping(dists, new_dists, "mm"))
    return f"  {name}: {'; '.join(parts)}" if parts else None


def scaling_notes(
    grids: dict[str, Sequence[tuple[float, float]]] | None = None, positions_mm: Sequence[float] | None = None
) -> list[str]:
    """One line per scaled set of the selected rig (none on the paper's rig).

    Parameters
    ----------
    grids : dict, optional
        Further named sets of paper conditions to report (``tune``'s grids).
    positions_mm : sequence of float, optional
        Survey positions to report (``tune``'s survey).

    Returns
    -------
    list of str
    """
    sets: dict[str, Sequence[tuple[float, float]]] = {
        "identification run": [(paper.IDENTIFICATION_RUN["v_in_mm_s"], paper.IDENTIFICATION_RUN["x_f_mm"])],
        "Table I": paper.TABLE_I_CONDITIONS,
        **(grids or {}),
    }
    lines = [note for name, conditions in sets.items() if (note := _note(name, conditions)) is not None]
    if positions_mm is not None and (scaled := survey_positions(positions_mm)) != tuple(positions_mm):
        lines.append("  survey positions: " + _mapping(positions_mm, scaled, "mm"))
    if lines:
        lines.insert(
            0,
            f"rig {RIG.name}: the paper's scenarios do not fit (fastest {FASTEST_MM_S:.1f} mm/s, longest "
            f"pulse {LONGEST_MM:.2f} mm); scaled (docs/rig_file.md, 'Scenarios on another rig'):",
        )
    return lines


def announce(
    grids: dict[str, Sequence[tuple[float, float]]] | None = None, positions_mm: Sequence[float] | None = None
) -> None:
    """Print :func:`scaling_notes` to stderr, once per process (arguments as there)."""
    for line in scaling_notes(grids, positions_mm):
        if line not in _announced:
            _announced.add(line)
            print(line, file=sys.stderr)
