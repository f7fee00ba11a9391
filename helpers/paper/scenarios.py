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
files are the paper's. Which sets were scaled and to what, the commands print once
(:mod:`helpers.paper.scaling_notes`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from helpers.paper import numbers as paper
from helpers.paper.hardware import (
    MAX_PULSE_MM,
    MAX_SPEED_MM_S,
    MAX_STEP_RATE_HZ,
    MAX_TRAVEL_MM,
    MM_PER_STEP,
)

FASTEST_MM_S: float = min(MAX_SPEED_MM_S, MAX_STEP_RATE_HZ * MM_PER_STEP)
"""The fastest cable speed a pulse may ask for, mm/s (the speed limit, or the step-rate cap's speed)."""
LONGEST_MM: float = min(MAX_TRAVEL_MM, MAX_PULSE_MM)
"""The longest pulse the rig allows, mm (its travel in whole steps)."""


def scale_values(values: Sequence[float], limit: float, resolution: float) -> tuple[float, ...]:
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
    speeds = scale_values([v for v, _ in conditions], fastest_mm_s, 1.0)
    dists = scale_values([x for _, x in conditions], longest_mm, 0.1)
    return tuple(dict.fromkeys(zip(speeds, dists, strict=True)))  # duplicates dropped, the order kept


def table_i_conditions() -> tuple[tuple[float, float], ...]:
    """Table I's four (v_in, x_f) conditions on the selected rig (the paper's on the paper's rig)."""
    return scale_conditions(paper.TABLE_I_CONDITIONS)


def scenario_name(system: str, v_in: float, x_f: float, repetition: int | None = None) -> str:
    """File name of a pulse scenario, e.g. ``zvd_v200_x20_r1`` (a decimal point is ``p``: ``x6p6``)."""
    base = f"{system}_v{v_in:g}_x{x_f:g}".replace(".", "p")
    return base if repetition is None else f"{base}_r{repetition}"


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
