"""The experiment's scenarios on a rig: the paper's, scaled where they do not fit the rig file.

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
from helpers.rigfile import RigFile, derived


def fastest_mm_s(rig: RigFile) -> float:
    """The fastest cable speed a pulse may ask for on ``rig``, mm/s (its speed limit, or its step-rate cap's).

    The slowest tendon's: a rig's scenarios are the same cable moves on every tendon.
    """
    hw = rig.hardware
    return min(min(hw.speed_limit_mm_s, hw.step_rate_cap_hz * mm) for mm in derived(rig).mm_per_step)


def longest_mm(rig: RigFile) -> float:
    """The longest pulse ``rig`` allows, mm: its travel in whole steps (the shortest over its tendons)."""
    d = derived(rig)
    return min(rig.hardware.travel_mm, *(n * mm for n, mm in zip(d.travel_steps, d.mm_per_step, strict=True)))


def scale_values(values: Sequence[float], limit: float, resolution: float) -> tuple[float, ...]:
    """``values`` unchanged when they fit ``limit``, else all scaled by ``limit / max`` and floored."""
    top = max(values)
    if top <= limit:
        return tuple(float(v) for v in values)
    factor = limit / top
    return tuple(round(math.floor(v * factor / resolution + 1e-9) * resolution, 6) for v in values)


def scale_conditions(
    conditions: Sequence[tuple[float, float]], fastest: float, longest: float
) -> tuple[tuple[float, float], ...]:
    """Scale a set of ``(v_in mm/s, x_f mm)`` conditions to a rig by the module's rule.

    Parameters
    ----------
    conditions : sequence of (float, float)
        The paper's conditions.
    fastest : float
        The rig's fastest speed, mm/s (:func:`fastest_mm_s`).
    longest : float
        The rig's longest pulse, mm (:func:`longest_mm`).

    Returns
    -------
    tuple of (float, float)
        The conditions, unchanged when they fit; duplicates (after rounding) are kept once.
    """
    speeds = scale_values([v for v, _ in conditions], fastest, 1.0)
    dists = scale_values([x for _, x in conditions], longest, 0.1)
    return tuple(dict.fromkeys(zip(speeds, dists, strict=True)))  # duplicates dropped, the order kept


def scaled(conditions: Sequence[tuple[float, float]], rig: RigFile) -> tuple[tuple[float, float], ...]:
    """``conditions`` scaled to ``rig`` (:func:`scale_conditions` with the rig's fastest and longest)."""
    return scale_conditions(conditions, fastest_mm_s(rig), longest_mm(rig))


def table_i_conditions(rig: RigFile) -> tuple[tuple[float, float], ...]:
    """Table I's four (v_in, x_f) conditions on ``rig`` (the paper's on the paper's rig)."""
    return scaled(paper.TABLE_I_CONDITIONS, rig)


def scenario_name(system: str, v_in: float, x_f: float, repetition: int | None = None) -> str:
    """File name of a pulse scenario, e.g. ``zvd_v200_x20_r1`` (a decimal point is ``p``: ``x6p6``)."""
    base = f"{system}_v{v_in:g}_x{x_f:g}".replace(".", "p")
    return base if repetition is None else f"{base}_r{repetition}"


def identification_run(rig: RigFile) -> dict:
    """The identification run on ``rig``: the paper's (100 mm/s, 10 mm, 9-10 s), scaled if needed."""
    run = paper.IDENTIFICATION_RUN
    ((v, x),) = scaled([(run["v_in_mm_s"], run["x_f_mm"])], rig)
    return {"v_in_mm_s": v, "x_f_mm": x, "window_s": run["window_s"]}


def identification_name(rig: RigFile) -> str:
    """File name of the identification run on ``rig``: ``pulse_v100_x10`` on the paper's rig."""
    run = identification_run(rig)
    return f"pulse_v{run['v_in_mm_s']:g}_x{run['x_f_mm']:g}".replace(".", "p")


def survey_positions(positions_mm: Sequence[float], rig: RigFile) -> tuple[float, ...]:
    """Survey positions on ``rig``: ``positions_mm``, or as many spread over its travel."""
    travel = rig.hardware.travel_mm
    if max(positions_mm) <= travel:
        return tuple(float(p) for p in positions_mm)
    n = len(positions_mm) - 1
    return tuple(round(math.floor(travel * k / n * 10 + 1e-9) / 10, 6) for k in range(n + 1))
