"""Table II metrics of recordings of several tendons (``schema_version`` 3), one set per tendon.

Each tendon ``i`` of a recording is analysed as a one-tendon recording of its own
(:func:`tendon_frame_view`: ``tension_n_i`` against ``steps_i``, its load
cell's calibration and the recording's rig for the range check): its Up and Down motions are found from its
own step count, and :func:`helpers.paper.metrics.recording_metrics` gives the peak, overshoot and settling
time of each. A tendon whose count makes no up-hold-down move gets NaN with the segmentation's reason. The
table has one row per recording, tendon and motion; ``python -m helpers metrics`` prints it after the
one-tendon tables.

The tip, where the twin provides it (a virtual-rig recording's optional ``tip_*`` columns,
``docs/recording_format.md``): :func:`tip_table` analyses the tip's displacement magnitude from its first
sample, ``|p(t) - p(t_0)|`` in mm, with the same definitions, its Up and Down motions segmented on the step
count of the tendon that moves most (the largest range of ``steps_i``; the lowest ``i`` of equals). One row
per such recording and motion, printed after the per-tendon table; recordings without the tip have none.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pandas as pd

from helpers.base.paths import shown
from helpers.base.tables import to_markdown
from helpers.paper import metrics
from helpers.recordings import TIP_MM_COLUMNS, Recording, recording_rig

__all__ = ["TENDON_COLUMNS", "TIP_COLUMNS", "tendon_table", "tendon_text", "tendon_markdown", "tip_frame",
           "tip_table", "tip_text", "tip_markdown"]  # fmt: skip

TENDON_COLUMNS = [
    "recording", "source", "tendon", "motion", "peak_n", "overshoot_pct", "settling_ms", "y0_n", "yf_n",
    "band", "reason",
]  # fmt: skip
"""Columns of the per-tendon table (``tendon`` 0-based, the boards' axis and channel)."""


def tendon_frame_view(frame: pd.DataFrame, tendon: int) -> pd.DataFrame:
    """Tendon ``tendon``'s columns under the one-tendon names, for the analyses written for one tendon.

    ``adc_i``, ``steps_i``, ``tension_n_i``, ``cable_mm_i`` become ``adc``, ``steps``, ``tension_n``,
    ``cable_mm`` (``seq``, ``t_us``, ``t_s`` kept), as :mod:`helpers.paper.metrics` reads them.
    """
    names = {f"adc_{tendon}": "adc", f"steps_{tendon}": "steps", f"tension_n_{tendon}": "tension_n",
             f"cable_mm_{tendon}": "cable_mm"}  # fmt: skip
    cols = ["seq", "t_us", "t_s", *names]
    return frame.loc[:, [c for c in cols if c in frame.columns]].rename(columns=names)


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
            parts.append(_labelled(df, rec, "tendon", i))
    return _ordered(parts, TENDON_COLUMNS)


def _labelled(df: pd.DataFrame, rec: Recording, key: str, value: int) -> pd.DataFrame:
    """``df`` with the recording's name, its source and ``key`` = ``value`` as its first three columns."""
    df.insert(0, "recording", shown(rec.path.with_suffix("")) if rec.path else rec.name)
    df.insert(1, "source", (rec.meta.get("source") or {}).get("kind", "unknown"))
    df.insert(2, key, value)
    return df


def _ordered(parts: list[pd.DataFrame], columns: list[str]) -> pd.DataFrame:
    """The parts in one table, ``columns`` first (an empty table of them without parts)."""
    if not parts:
        return pd.DataFrame(columns=columns)
    table = pd.concat(parts, ignore_index=True)
    return table[columns + [c for c in table.columns if c not in columns]]


TIP_COLUMNS = [
    "recording", "source", "paced_by", "motion", "peak_mm", "overshoot_pct", "settling_ms", "y0_mm", "yf_mm",
    "band", "reason",
]  # fmt: skip
"""Columns of the tip's table (``paced_by``: the 0-based tendon whose step count segments the motions)."""


def tip_frame(rec: Recording) -> tuple[pd.DataFrame, int] | None:
    """The tip's analysed frame and the tendon that paces it; None without the twin's tip.

    The frame has ``t_s``, ``steps`` (the count of the tendon that moves most) and ``tip_mm`` (the tip's
    displacement magnitude from its first sample, mm).
    """
    f = rec.frame
    if not all(c in f.columns for c in TIP_MM_COLUMNS) or len(f) == 0:
        return None
    ranges = [np.ptp(f[f"steps_{i}"].to_numpy()) for i in range(rec.tendons)]
    lead = int(np.argmax(ranges))
    p = f.loc[:, list(TIP_MM_COLUMNS)].to_numpy(float)
    out = pd.DataFrame({"t_s": f["t_s"].to_numpy(float), "steps": f[f"steps_{lead}"].to_numpy(),
                        "tip_mm": np.linalg.norm(p - p[0], axis=1)})  # fmt: skip
    return out, lead


def tip_table(recs: list[Recording], band: float, **kwargs: Any) -> pd.DataFrame:
    """The tip's Table II metrics of every recording with the twin's tip (see the module's docstring)."""
    parts = []
    for rec in recs:
        found = tip_frame(rec)
        if found is None:
            continue
        frame, lead = found
        df = metrics.recording_metrics(frame, band, column="tip_mm", **kwargs)
        df = df.rename(columns={"peak_n": "peak_mm", "y0_n": "y0_mm", "yf_n": "yf_mm"})
        parts.append(_labelled(df, rec, "paced_by", lead))
    return _ordered(parts, TIP_COLUMNS)


def _tip_displayed(table: pd.DataFrame) -> pd.DataFrame:
    return pd.DataFrame({
        "recording": table["recording"], "paced by tendon": table["paced_by"].astype(str),
        "motion": table["motion"], "peak mm": table["peak_mm"].map(lambda v: _cell(v, 2)),
        "overshoot %": table["overshoot_pct"].map(lambda v: _cell(v, 1)),
        "settling ms": table["settling_ms"].map(lambda v: _cell(v, 0)),
    })  # fmt: skip


def _tip_notes(table: pd.DataFrame) -> list[str]:
    return [f"{r.recording} tip {r.motion}: {r.reason}" for r in table.itertuples(index=False)
            if isinstance(r.reason, str) and r.reason]  # fmt: skip


TIP_TITLE = "Tip displacement |p - p0| (twin-provided, simulated; settling band ±{}%)"


def tip_text(table: pd.DataFrame, band: float) -> str:
    """The tip's table for the terminal ('' when no recording has the tip)."""
    if table.empty:
        return ""
    lines = ["", TIP_TITLE.format(f"{100 * band:g} ") + ":", _tip_displayed(table).to_string(index=False)]
    found = _tip_notes(table)
    if found:
        lines += ["", "Notes (NaN or bounded values):", *(f"  {x}" for x in found)]
    return "\n".join(lines) + "\n"


def tip_markdown(table: pd.DataFrame, band: float) -> str:
    """The tip's table as Markdown ('' when no recording has the tip)."""
    if table.empty:
        return ""
    parts = ["\n## " + TIP_TITLE.format(f"{100 * band:g} ") + "\n", to_markdown(_tip_displayed(table))]
    found = _tip_notes(table)
    if found:
        parts.append("Notes (NaN or bounded values):\n\n" + "".join(f"- {x}\n" for x in found))
    return "\n".join(parts)


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
