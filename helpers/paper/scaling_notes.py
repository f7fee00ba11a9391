"""What the commands say about the paper's scenarios on the selected rig: which sets were scaled, and to what.

The rule itself is :mod:`helpers.paper.scenarios`; ``record`` and ``tune`` print these notes once per process
(nothing on the paper's rig, where nothing is scaled).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from helpers.paper import numbers as paper
from helpers.paper.hardware import RIG
from helpers.paper.scenarios import FASTEST_MM_S, LONGEST_MM, scale_values, survey_positions

_announced: set[str] = set()


def _mapping(before: Sequence[float], after: Sequence[float], unit: str) -> str:
    """``"200, 300 -> 100, 150 mm/s"`` (distinct values, in order)."""
    pairs = dict(zip(before, after, strict=True))
    return f"{', '.join(f'{b:g}' for b in pairs)} -> {', '.join(f'{a:g}' for a in pairs.values())} {unit}"


def _note(name: str, conditions: Sequence[tuple[float, float]]) -> str | None:
    """How ``conditions`` are scaled on the selected rig, or None when they fit."""
    speeds, dists = [float(v) for v, _ in conditions], [float(x) for _, x in conditions]
    new_speeds, new_dists = scale_values(speeds, FASTEST_MM_S, 1.0), scale_values(dists, LONGEST_MM, 0.1)
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
