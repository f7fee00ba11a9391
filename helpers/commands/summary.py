"""The one-screen summary printed at the end of ``python -m helpers reproduce``.

It reads only files that exist after the notebooks ran (``data/identification/result.json`` and
``figures/table2_metrics.csv`` from notebook 05), so it summarises what was actually regenerated. Sections
whose inputs do not exist say so instead of printing numbers.
"""

from __future__ import annotations

import pandas as pd

from helpers.base.jsonfile import DataFileError
from helpers.base.paths import FIGURES_DIR
from helpers.paper import numbers as paper
from helpers.paper.identify import load_identification
from helpers.paper.shapers import design_tdfs

TABLE_II_CSV = FIGURES_DIR / "table2_metrics.csv"
"""Where notebook 05 saves our Table II (means and spreads over repetitions)."""


def _identification_lines() -> list[str]:
    try:
        res = load_identification()
    except DataFileError as exc:
        return [f"identified mode: {exc}"]
    zv, zvd = design_tdfs(res.omega_d, res.zeta)
    return [
        f"identified mode ({res.source or '?'}, {res.method}): "
        f"zeta = {res.zeta:.4f} (paper {paper.ZETA:.3f}), "
        f"omega_d = {res.omega_d:.3f} rad/s (paper {paper.OMEGA_D:.3f})",
        f"  ZV : A0 = {zv.amplitudes[0]:.4f}, A1 = {zv.amplitudes[1]:.4f}, T = {zv.times[1]:.5f} s "
        f"(paper {paper.ZV_A0:.4f}, {paper.ZV_A1:.4f}, {paper.ZV_T:.5f} s)",
        "  ZVD: " + ", ".join(f"{a:.4f}" for a in zvd.amplitudes)
        + " (paper " + ", ".join(f"{a:.4f}" for a in paper.ZVD_AMPLITUDES) + ")",
    ]


def _table_lines() -> list[str]:
    if not TABLE_II_CSV.exists():
        return [f"Table II: {TABLE_II_CSV.name} not found (run notebook 05)"]
    ours = pd.read_csv(TABLE_II_CSV)
    theirs = paper.table_ii()
    keys = ["v_in_mm_s", "x_f_mm", "system", "motion"]
    merged = ours.merge(theirs, on=keys, how="inner")
    lines = ["Table II, Up motion, overshoot % / settling ms: ours (virtual rig) vs paper (hardware)"]
    for (v, x), g in merged[merged["motion"] == "Up"].groupby(["v_in_mm_s", "x_f_mm"], sort=False):
        cells = []
        for system in paper.SYSTEMS:
            row = g[g["system"] == system]
            if row.empty:
                continue
            r = row.iloc[0]
            cells.append(
                f"{paper.SYSTEM_LABELS[system]} {r['overshoot_pct_mean']:.0f}/{r['settling_ms_mean']:.0f} "
                f"({r['overshoot_pct']:.0f}/{r['settling_ms']:.0f})"
            )
        lines.append(f"  {x:.0f} mm {v:.0f} mm/s: " + "; ".join(cells))
    return lines


def print_summary() -> None:
    """Print the identified mode and the headline numbers of Table II beside the paper's."""
    print("-- summary ---------------------------------------------------------------")
    for line in _identification_lines() + _table_lines():
        print(line)
