"""What the commands say about the paper's scenarios on a rig: which sets were scaled, and to what.

The rule itself is :mod:`helpers.paper.scenarios`; ``record`` and ``tune`` print these notes once per process
(nothing on the paper's rig, where nothing is scaled).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from helpers.paper import numbers as paper
from helpers.paper.scenarios import fastest_mm_s, longest_mm, scale_values, survey_positions
from helpers.rigfile import RigFile

_announced: set[str] = set()


def _mapping(before: Sequence[float], after: Sequence[float], unit: str) -> str:
    """``"200, 300 -> 100, 150 mm/s"`` (distinct values, in order)."""
    pairs = dict(zip(before, after, strict=True))
    return f"{', '.join(f'{b:g}' for b in pairs)} -> {', '.join(f'{a:g}' for a in pairs.values())} {unit}"


def _note(name: str, conditions: Sequence[tuple[float, float]], rig: RigFile) -> str | None:
    """How ``conditions`` are scaled on ``rig``, or None when they fit."""
    speeds, dists = [float(v) for v, _ in conditions], [float(x) for _, x in conditions]
    new_speeds = scale_values(speeds, fastest_mm_s(rig), 1.0)
    new_dists = scale_values(dists, longest_mm(rig), 0.1)
    parts = []
    if tuple(speeds) != new_speeds:
        parts.append("speeds " + _mapping(speeds, new_speeds, "mm/s"))
    if tuple(dists) != new_dists:
        parts.append("distances " + _mapping(dists, new_dists, "mm"))
    return f"  {name}: {'; '.join(parts)}" if parts else None


def scaling_notes(
    rig: RigFile,
    grids: dict[str, Sequence[tuple[float, float]]] | None = None,
    positions_mm: Sequence[float] | None = None,
) -> list[str]:
    """One line per set of the paper's scenarios that ``rig`` scales (none on the paper's rig).

    Parameters
    ----------
    rig : RigFile
        The rig.
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
    lines = [note for name, conditions in sets.items() if (note := _note(name, conditions, rig)) is not None]
    if positions_mm is not None and (scaled := survey_positions(positions_mm, rig)) != tuple(positions_mm):
        lines.append("  survey positions: " + _mapping(positions_mm, scaled, "mm"))
    if lines:
        lines.insert(
            0,
            f"rig {rig.name}: the paper's scenarios do not fit (fastest {fastest_mm_s(rig):.1f} mm/s, "
            f"longest pulse {longest_mm(rig):.2f} mm); scaled (docs/rig_file.md, 'Scenarios on another "
            "rig'):",
        )
    return lines


def announce(
    rig: RigFile,
    grids: dict[str, Sequence[tuple[float, float]]] | None = None,
    positions_mm: Sequence[float] | None = None,
) -> None:
    """Print :func:`scaling_notes` to stderr, once per process and line (arguments as there)."""
    for line in scaling_notes(rig, grids, positions_mm):
        if line not in _announced:
            _announced.add(line)
            print(line, file=sys.stderr)
