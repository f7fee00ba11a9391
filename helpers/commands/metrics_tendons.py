"""Table II metrics of recordings of several tendons (``schema_version`` 3), one set per tendon.

Each tendon ``i`` of a recording is analysed as a one-tendon recording of its own
(:func:`helpers.recordings.tendons.tendon_frame_view`: ``tension_n_i`` against ``steps_i``, its load
cell's calibration and the recording's rig for the range check): its Up and Down motions are found from its
own step count, and :func:`helpers.paper.metrics.recording_metrics` gives the peak, overshoot and settling
time of each. A tendon whose count makes no up-hold-down move gets NaN with the segmentation's reason. The
table has one row per recording, tendon and motion; ``python -m helpers metrics`` prints it after the
one-tendon tables.
"""

from __future__ import annotations

import math
from typing import Any

import pandas as pd

from helpers.base.paths import shown
from helpers.base.tables import to_markdown
from helpers.paper import metrics
from helpers.recordings import Recording, recording_rig
from helpers.recordings.tendons import tendon_frame_view

__all__ = ["TENDON_COLUMNS", "tendon_table", "tendon_text", "tendon_markdown"]

TENDON_COLUMNS = [
    "recording", "source", "tendon", "motion", "peak_n", "overshoot_pct", "settling_ms", "y0_n", "yf_n",
    "band", "reason",
]  # fmt: skip
"""Columns of the per-tendon table (``tendon`` 0-based, the boards' axis and channel)."""


def tendon_table(recs: list[Recording], band: float, **kwargs: Any) -> pd.DataFrame:
    """Every tendon's Table II metrics of every recording (see the module's docstring)."""
    parts = []
    for rec in recs:
        cal = rec.meta["calibration"]
        rig = recording_rig(rec.meta, rec.name)
        for i in range(rec.tendons):
            one = {k: cal[k][i] for k in ("newtons_per_count", "offset_counts", "mm_per_step")}
            df = metrics.recording_metrics(tendon_frame_view(rec.frame, i), band, calibration=one, rig=rig,
                                           **kwargs)  # fmt: skip
            df.insert(0, "recording", shown(rec.path.with_suffix("")) if rec.path else rec.name)
            df.insert(1, "source", (rec.meta.get("source") or {}).get("kind", "unknown"))
            df.insert(2, "tendon", i)
            parts.append(df)
    if not parts:
        return pd.DataFrame(columns=TENDON_COLUMNS)
    table = pd.concat(parts, ignore_index=True)
    return table[TENDON_COLUMNS + [c for c in table.columns if c not in TENDON_COLUMNS]]


def _cell(value: Any, digits: int) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "NaN"
    return f"{float(value):.{digits}f}"


def _displayed(table: pd.DataFrame) -> pd.DataFrame:
    return pd.DataFrame(
        {
            "recording": table["recording"],
            "source": table["source"],
            "tendon": table["tendon"].astype(str),
            "motion": table["motion"],
            "peak N": table["peak_n"].map(lambda v: _cell(v, 2)),
            "overshoot %": table["overshoot_pct"].map(lambda v: _cell(v, 1)),
            "settling ms": table["settling_ms"].map(lambda v: _cell(v, 0)),
        }
    )


def _notes(table: pd.DataFrame) -> list[str]:
    return [
        f"{row.recording} tendon {row.tendon} {row.motion}: {row.reason}"
        for row in table.itertuples(index=False)
        if isinstance(row.reason, str) and row.reason
    ]


def tendon_text(table: pd.DataFrame, band: float) -> str:
    """The per-tendon table for the terminal, with its notes."""
    n = table["recording"].nunique()
    lines = [f"Per tendon ({n} recording(s) of several tendons; settling band ±{100 * band:g} %):",
             _displayed(table).to_string(index=False)]  # fmt: skip
    if any(s != "hardware" for s in table["source"].unique()):
        lines += ["", "Source 'virtual-rig': simulated recordings, not hardware measurements."]
    found = _notes(table)
    if found:
        lines += ["", "Notes (NaN or bounded values):", *(f"  {x}" for x in found)]
    return "\n".join(lines) + "\n"


def tendon_markdown(table: pd.DataFrame, band: float) -> str:
    """The per-tendon table as Markdown."""
    parts = [f"## Per tendon (settling band ±{100 * band:g} %)\n", to_markdown(_displayed(table))]
    found = _notes(table)
    if found:
        parts.append("Notes (NaN or bounded values):\n\n" + "".join(f"- {x}\n" for x in found))
    return "\n".join(parts)
