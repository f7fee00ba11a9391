"""The paper's experiment on a rig: the twelve scenarios of Table I, each repeated, recorded into ``data/``.

The procedure of ``python -m helpers record table-i`` (notebook 04's live cell writes the same loop with
:class:`helpers.rig.Rig`): for each system
(unshaped, the non-robust TDF, the robust TDF) and each condition of Table I (scaled by
:mod:`helpers.paper.scenarios` on a rig it does not fit), one
:meth:`helpers.rig.Rig.run_pulse` per repetition, saved as ``<system>_v<v_in>_x<x_f>_r<n>``
(:func:`helpers.paper.scenarios.scenario_name`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from helpers.base.paths import DATA_DIR
from helpers.paper import numbers as paper
from helpers.paper import scenarios
from helpers.paper.scenarios import scenario_name

__all__ = ["NoiseSeeds", "record_table_i", "scenario_name"]


class NoiseSeeds:
    """Noise seeds for successive runs: ``base``, ``base + 1``, ... (None on hardware)."""

    def __init__(self, base: int | None) -> None:
        self.next = base

    def take(self) -> int | None:
        """The next seed (None on hardware)."""
        if self.next is None:
            return None
        seed, self.next = self.next, self.next + 1
        return seed


def record_table_i(
    rig: Any,
    shapers: dict[str, Any],
    design: dict[str, Any] | None,
    repetitions: int = 3,
    group: Path = DATA_DIR / "experiments",
    t_end_s: float = 12.0,
    rate_hz: int = 1000,
    replace: bool = False,
    seeds: NoiseSeeds | None = None,
) -> list[Path]:
    """Record the twelve scenarios of Table I, ``repetitions`` times each, into ``group``.

    Parameters
    ----------
    rig : helpers.rig.Rig
        A connected rig (hardware or virtual).
    shapers : dict
        ``{"unshaped": None, "zv": Shaper, "zvd": Shaper}``.
    design : dict, optional
        Where the shapers came from (``zeta``, ``omega_d``, ``origin``), written into every scenario.
    repetitions : int
        Runs per scenario.
    group : pathlib.Path
        Destination folder.
    t_end_s : float
        Programme (and recording) length, s.
    rate_hz : int
        DAQ sample rate.
    replace : bool
        Replace existing recordings of the same names.
    seeds : optional
        The noise seeds of successive runs (in-process virtual rig).

    Returns
    -------
    list of pathlib.Path
        The CSV files written, in recording order.
    """
    seeds = seeds or NoiseSeeds(None)
    paths = []
    for system in paper.SYSTEMS:
        for v, x in scenarios.table_i_conditions(rig.rig):
            for rep in range(1, repetitions + 1):
                path = Path(group) / scenario_name(system, v, x, rep)
                rec = rig.run_pulse(
                    v,
                    x,
                    shapers[system],
                    system=system,
                    path=path,
                    repetition=rep,
                    t_end_s=t_end_s,
                    rate_hz=rate_hz,
                    progress=False,
                    scenario_extra={"design": design},
                    replace=replace,
                    noise_seed=seeds.take(),
                )
                print(f"{path.name}: {rec.status}, {len(rec.frame)} samples", flush=True)
                paths.append(rec.path)
    return paths
