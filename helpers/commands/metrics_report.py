"""``python -m helpers metrics PATH...``: Table II metrics (peak, overshoot, settling) for any recordings.

The command behind a researcher's own experiments: point it at recordings (files, folders or glob patterns)
and it prints, like the paper's Table II, the metrics of every run and motion and their means over the
repetitions of each scenario. The numbers are those of :mod:`helpers.paper.metrics` (definitions in
``docs/metrics.md``); this module only finds the recordings, says which it skipped and why, and writes the
tables::

    python -m helpers metrics data/runs/mine
    python -m helpers metrics "data/experiments/zvd_*" --band 0.02
    python -m helpers metrics data/runs/mine --csv results/mine --markdown results/mine.md

A recording of several tendons (a move in task space, or any programme of one's own) gets one row per
tendon that makes an up-hold-down move and motion, numbered as the rig file numbers them (from 1), and the
tip's rows where the twin provides it: one analysis of the move
(:func:`helpers.research.residuals.recording_residuals`), whose motions come from the lead tendon (the one
that pulls most towards the bend), with a pre-pull reported in its own table, not folded into the move's
rows; a tendon that pays out or is held has no row, and a line says so.

A path may name a recording by its ``.csv``, its ``.json`` or its stem. Recordings that cannot be analysed
are skipped, never silently: a malformed or incomplete pair, an aborted run (``--include-aborted`` analyses
it anyway), a load-cell calibration run, a file that is not a recording, a stream of several tendons
(``helpers.research.tip_stream_metrics`` measures it). Every table carries the data's
``source`` (``virtual-rig`` or ``hardware``), so a simulated number is never mistaken for a measured one.
"""

from __future__ import annotations

import argparse
import glob
import math
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from helpers.base.cli import DefaultsHelp, arg_number
from helpers.base.paths import shown, user_data_root
from helpers.base.tables import to_markdown
from helpers.paper import metrics
from helpers.paper import numbers as paper
from helpers.recordings import RESERVED_NAMES, Recording, RecordingError, RecordingExists, load, recording_rig
from helpers.research.residuals import recording_residuals

_GLOB_CHARS = set("*?[")

RUN_COLUMNS = [
    "recording", "source", "v_in_mm_s", "x_f_mm", "system", "repetition", "motion",
    "peak_n", "overshoot_pct", "settling_ms", "band", "reason",
]  # fmt: skip
"""Columns of the per-run table (its CSV adds the other columns of :func:`~metrics.metrics_by_run`)."""

MEAN_COLUMNS = [
    "source", "x_f_mm", "v_in_mm_s", "system", "motion", "n_runs",
    "peak_n_mean", "peak_n_std", "overshoot_pct_mean", "overshoot_pct_std",
    "settling_ms_mean", "settling_ms_std", "band", "reason",
]  # fmt: skip
"""Columns of the per-scenario table."""

PRECISION = {"peak_n": 2, "overshoot_pct": 1, "settling_ms": 0}
"""Digits shown after the point (text and Markdown); CSV files keep six significant digits."""


@dataclass
class Selection:
    """The recordings a command line names: those that load, and those skipped with the reason."""

    recordings: list[Recording] = field(default_factory=list)
    skipped: list[tuple[str, str]] = field(default_factory=list)


def _stems_in(folder: Path) -> list[Path]:
    """Every recording stem under ``folder`` (recursively), hidden files and reserved names left out."""
    stems = {
        p.with_suffix("")
        for p in folder.rglob("*")
        if p.suffix in (".csv", ".json") and not p.name.startswith(".") and p.is_file()
    }
    return sorted(s for s in stems if s.name.lower() not in RESERVED_NAMES)


def expand(paths: list[str]) -> list[Path]:
    """Turn command-line paths (files, folders, glob patterns) into recording stems, in order, once each.

    Parameters
    ----------
    paths : list of str
        Paths as typed; a pattern is expanded here (``**`` recurses), so quoting it is fine.

    Returns
    -------
    list of pathlib.Path
        Stems (the path without ``.csv``/``.json``).

    Raises
    ------
    ValueError
        A path that does not exist, or a pattern that matches nothing.
    """
    stems: list[Path] = []
    for text in paths:
        if _GLOB_CHARS & set(text):
            matches = sorted(glob.glob(text, recursive=True))
            if not matches:
                raise ValueError(f"no file matches {text!r}")
            found = [Path(m) for m in matches]
        else:
            found = [Path(text)]
        for path in found:
            if path.is_dir():
                stems.extend(_stems_in(path))
            elif path.suffix in (".csv", ".json") and path.exists():
                stems.append(path.with_suffix(""))
            elif path.with_suffix(".csv").exists() or path.with_suffix(".json").exists():
                stems.append(path)
            elif path.suffix not in (".csv", ".json") and path.exists():
                stems.append(path)  # reported as "not a recording" when it is loaded
            else:
                raise ValueError(f"{text}: no such recording, folder or file")
    unique = dict.fromkeys(Path(os.path.normpath(s)) for s in stems)
    return list(unique)


def _why_not(rec: Recording, include_aborted: bool) -> str:
    """Why ``rec`` cannot go into Table II ('' when it can)."""
    sc = rec.meta.get("scenario") or {}
    if sc.get("kind") == "calibration":
        return "a load-cell calibration run (no motion to analyse)"
    if rec.tendons > 1 and sc.get("kind") == "stream":
        return "a stream of several tendons (no up-hold-down move: helpers.research.tip_stream_metrics)"
    # several tendons: the move's motions come from its lead tendon's count (move_tables)
    keys = () if rec.tendons > 1 else ("v_in_mm_s", "x_f_mm", "system")
    missing = [k for k in keys if sc.get(k) is None]
    if missing:
        return f"its scenario has no {', '.join(missing)}"
    if rec.status != "complete" and not include_aborted:
        why = rec.meta.get("abort_reason") or "no reason recorded"
        return f"{rec.status} run ({why}); --include-aborted analyses it"
    return ""


def select(paths: list[str], include_aborted: bool = False) -> Selection:
    """Load the recordings ``paths`` name; keep the analysable ones, list the rest with the reason.

    Parameters
    ----------
    paths : list of str
        Files, folders or glob patterns (see :func:`expand`).
    include_aborted : bool
        Analyse runs whose status is not ``complete`` as well.

    Returns
    -------
    Selection
    """
    out = Selection()
    for stem in expand(paths):
        label = shown(stem)
        if stem.name.lower() in RESERVED_NAMES:
            out.skipped.append((label, "not a recording (a calibration or identification result)"))
            continue
        if stem.suffix and stem.suffix not in (".csv", ".json"):
            out.skipped.append((label, "not a recording (expected a .csv/.json pair)"))
            continue
        try:
            rec = load(stem.with_suffix(".csv"))
        except RecordingError as exc:
            out.skipped.append((label, str(exc).removeprefix(f"{stem.with_suffix('.csv')}: ")))
            continue
        why = _why_not(rec, include_aborted)
        if why:
            out.skipped.append((label, why))
        else:
            out.recordings.append(rec)
    return out


def run_table(selection: Selection, band: float, **kwargs: Any) -> pd.DataFrame:
    """Metrics of every run and motion, with the recording's name and data source.

    Parameters
    ----------
    selection : Selection
        From :func:`select`.
    band : float
        Settling band, a fraction of the step.
    **kwargs
        Passed to :func:`helpers.paper.metrics.motion_metrics`.

    Returns
    -------
    pandas.DataFrame
        :data:`RUN_COLUMNS` first, then the rest of :func:`helpers.paper.metrics.metrics_by_run`'s columns,
        in the
        paper's order.
    """
    parts = []
    for rec in selection.recordings:
        df = metrics.metrics_by_run([rec], band, include_aborted=True, **kwargs)
        df.insert(0, "recording", shown(rec.path.with_suffix("")) if rec.path else rec.name)
        df.insert(1, "source", (rec.meta.get("source") or {}).get("kind", "unknown"))
        parts.append(df)
    if not parts:
        reasons = "; ".join(f"{name}: {why}" for name, why in selection.skipped) or "no recordings given"
        raise RecordingError(f"no recording could be analysed ({reasons})")
    runs = metrics.paper_order(pd.concat(parts, ignore_index=True))
    rest = [c for c in runs.columns if c not in RUN_COLUMNS]
    return runs[RUN_COLUMNS + rest]


def mean_table(runs: pd.DataFrame, band: float) -> pd.DataFrame:
    """Per-scenario means and spreads over repetitions (:func:`~metrics.summarise`), per data source.

    Parameters
    ----------
    runs : pandas.DataFrame
        From :func:`run_table`.
    band : float
        The band the runs were analysed with.

    Returns
    -------
    pandas.DataFrame
        :data:`MEAN_COLUMNS` plus the counts ``<metric>_n``; runs of different sources are never averaged
        together.
    """
    parts = []
    for source, g in runs.groupby("source", sort=True):
        table = metrics.summarise(g, band)
        table.insert(0, "source", source)
        parts.append(table)
    table = pd.concat(parts, ignore_index=True)
    rest = [c for c in table.columns if c not in MEAN_COLUMNS]
    return table[MEAN_COLUMNS + rest]


def _number(value: Any, digits: int) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "NaN"
    text = f"{float(value):.{digits}f}"
    return text


def _pm(mean: Any, std: Any, digits: int) -> str:
    if isinstance(std, float) and math.isnan(std):
        return _number(mean, digits)
    return f"{_number(mean, digits)} ± {_number(std, digits)}"


def displayed(runs: pd.DataFrame, means: pd.DataFrame) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The two tables as text cells, each number rounded once from full precision (:data:`PRECISION`).

    Parameters
    ----------
    runs, means : pandas.DataFrame
        From :func:`run_table` and :func:`mean_table`.

    Returns
    -------
    tuple of pandas.DataFrame
        String tables for the terminal and Markdown; a note number in ``note`` points at the reasons.
    """
    def label(system: str) -> str:
        return f"{system} ({paper.SYSTEM_LABELS[system]})" if system in paper.SYSTEM_LABELS else system

    r = pd.DataFrame(
        {
            "recording": runs["recording"],
            "source": runs["source"],
            "x_f mm": runs["x_f_mm"].map(lambda v: f"{v:g}"),
            "v_in mm/s": runs["v_in_mm_s"].map(lambda v: f"{v:g}"),
            "system": runs["system"].map(label),
            "rep": runs["repetition"].astype(str),
            "motion": runs["motion"],
            "peak N": runs["peak_n"].map(lambda v: _number(v, PRECISION["peak_n"])),
            "overshoot %": runs["overshoot_pct"].map(lambda v: _number(v, PRECISION["overshoot_pct"])),
            "settling ms": runs["settling_ms"].map(lambda v: _number(v, PRECISION["settling_ms"])),
        }
    )
    m = pd.DataFrame(
        {
            "source": means["source"],
            "x_f mm": means["x_f_mm"].map(lambda v: f"{v:g}"),
            "v_in mm/s": means["v_in_mm_s"].map(lambda v: f"{v:g}"),
            "system": means["system"].map(label),
            "motion": means["motion"],
            "runs": means["n_runs"].astype(str),
        }
    )
    titles = {"peak_n": "peak N", "overshoot_pct": "overshoot %", "settling_ms": "settling ms"}
    for metric, title in titles.items():
        m[title] = [
            _pm(a, b, PRECISION[metric])
            for a, b in zip(means[f"{metric}_mean"], means[f"{metric}_std"], strict=True)
        ]
    return r, m


def notes(runs: pd.DataFrame) -> list[str]:
    """The reasons behind NaN or bounded values, one line per run and motion that has one."""
    return [
        f"{row.recording} {row.motion}: {row.reason}"
        for row in runs.itertuples(index=False)
        if isinstance(row.reason, str) and row.reason
    ]


def report_text(runs: pd.DataFrame, means: pd.DataFrame, skipped: list[tuple[str, str]], band: float) -> str:
    """The terminal report: per-run table, per-scenario means, notes and skipped recordings."""
    r, m = displayed(runs, means)
    lines = [
        f"Per run ({len(runs) // 2 if len(runs) else 0} recordings; settling band ±{100 * band:g} %):",
        r.to_string(index=False),
        "",
        "Per scenario (mean ± sample standard deviation over the runs):",
        m.to_string(index=False),
    ]
    if any(s != "hardware" for s in runs["source"].unique()):
        lines += ["", "Source 'virtual-rig': simulated recordings, not hardware measurements."]
    found = notes(runs)
    if found:
        lines += ["", "Notes (NaN or bounded values):", *(f"  {n}" for n in found)]
    lines += ["", _skipped_text(skipped)]
    return "\n".join(lines) + "\n"


def _skipped_text(skipped: list[tuple[str, str]]) -> str:
    if not skipped:
        return "Skipped: none."
    return "\n".join([f"Skipped {len(skipped)}:", *(f"  {name}: {why}" for name, why in skipped)])


def report_markdown(
    runs: pd.DataFrame, means: pd.DataFrame, skipped: list[tuple[str, str]], band: float
) -> str:
    """The same report as Markdown (two tables, notes, skipped recordings)."""
    r, m = displayed(runs, means)
    parts = [
        f"## Per scenario (mean ± sample standard deviation; settling band ±{100 * band:g} %)\n",
        to_markdown(m),
        "## Per run\n",
        to_markdown(r),
    ]
    if any(s != "hardware" for s in runs["source"].unique()):
        parts.append("Source `virtual-rig`: simulated recordings, not hardware measurements.\n")
    found = notes(runs)
    if found:
        parts.append("Notes (NaN or bounded values):\n\n" + "".join(f"- {n}\n" for n in found))
    parts.append(_skipped_text(skipped).replace("\n  ", "\n- ") + "\n")
    return "\n".join(parts)


# --- recordings of several tendons: every tendon's rows, the pre-pull apart, the tip ----------------------
TENDON_COLUMNS = [
    "recording", "source", "tendon", "role", "motion", "peak_n", "overshoot_pct", "settling_ms", "y0_n",
    "yf_n", "band", "reason",
]  # fmt: skip
"""Columns of the per-tendon table (``tendon`` numbered as the rig file does, from 1; its CSV adds the
residual analysis' columns, :func:`helpers.research.residuals.residual_table`)."""

TIP_COLUMNS = [
    "recording", "source", "lead", "motion", "peak_mm", "overshoot_pct", "settling_ms", "y0_mm", "yf_mm",
    "band", "reason",
]  # fmt: skip
"""Columns of the tip's table (``lead``: the tendon, from 1, whose count gives the motions)."""

PREPULL_COLUMNS = ["recording", "tendon", "prepull_steps", "pulled_s", "released_s", "prepulled_n", "rest_n"]
"""Columns of the pre-pull's table: when every tendon was pulled in and let out, each one's tension before the
move (the median of the 0.5 s before Up) and at rest after the release (the median of the recording's last
0.5 s after its last step; NaN when less than 0.1 s of it is recorded)."""

_RENAMED = {"peak": "peak_n", "y0": "y0_n", "yf": "yf_n"}


@dataclass
class MoveTables:
    """The tables of recordings of several tendons.

    ``lines``: one per recording, its lead and its tendons without a Table II row (and why).
    """

    tendons: pd.DataFrame
    tip: pd.DataFrame
    prepull: pd.DataFrame
    lines: list[str]


def _label(rec: Recording) -> str:
    return shown(rec.path.with_suffix("")) if rec.path else rec.name


def _no_row(tendon: int, role: str, held: int) -> str:
    if role == "paid out":
        return f"tendon {tendon} pays out ({held:+d} steps in the hold)"
    return f"tendon {tendon} is held (its count at its level in the hold)"


def _prepull_rows(rec: Recording, label: str, phases: Any) -> list[dict[str, Any]]:
    f = rec.frame
    t = f["t_s"].to_numpy(float)
    counts = f[[f"steps_{i}" for i in range(rec.tendons)]].to_numpy()
    changed = np.flatnonzero(np.any(np.diff(counts, axis=0) != 0, axis=1))
    settled = max(float(t[changed[-1] + 1]), float(t[-1]) - metrics.PRE_S) if changed.size else float(t[0])
    before = (t >= phases.up_start_s - metrics.PRE_S) & (t < phases.up_start_s)
    after = t >= settled
    rows = []
    for i in range(rec.tendons):
        y = f[f"tension_n_{i}"].to_numpy(float)
        seen = not math.isnan(phases.release_s) and t[-1] - settled >= 0.1
        rest = float(np.median(y[after])) if seen else math.nan
        rows.append({"recording": label, "tendon": i + 1, "prepull_steps": phases.prepull,
                     "pulled_s": phases.prepull_s, "released_s": phases.release_s,
                     "prepulled_n": float(np.median(y[before])) if before.any() else math.nan,
                     "rest_n": rest})  # fmt: skip
    return rows


def move_tables(recs: list[Recording], band: float) -> MoveTables:
    """Table II rows of every tendon that makes an up-hold-down move, and of the tip, per recording.

    Each recording's move is analysed once (:func:`helpers.research.residuals.recording_residuals`): its
    motions from the lead tendon's count (the one that pulls most towards the bend; without a recorded
    direction, the one whose count rises most), the pre-pull apart from them. A tendon that pays out or is
    held makes no up-hold-down move: it has no row, and the recording's line says so.
    """
    tendons, tips, prepull, lines = [], [], [], []
    for rec in recs:
        label = _label(rec)
        source = (rec.meta.get("source") or {}).get("kind", "unknown")
        try:
            table, phases, why = recording_residuals(rec, band)
        except ValueError as exc:
            lines.append(f"{label}: no Table II rows: {exc}")
            continue
        table = table.rename(columns=_RENAMED).assign(recording=label, source=source, band=band)
        rows = table[table["role"].isin(["lead", "pulled"])]
        tendons.append(rows.sort_values(["tendon", "motion"], ascending=[True, False], kind="stable"))
        tip = table[table["signal"] == "tip"].rename(columns={"peak_n": "peak_mm", "y0_n": "y0_mm",
                                                               "yf_n": "yf_mm"})  # fmt: skip
        tips.append(tip)
        first = table[(table["motion"] == "Up") & (table["unit"] == "N")]
        without = [_no_row(r.tendon, r.role, r.held_steps) for r in first.itertuples() if r.role in
                   ("paid out", "held")]  # fmt: skip
        line = f"{label}: lead tendon {phases.lead + 1} ({why})"
        if phases.prepull:
            line += f"; pre-pull of {phases.prepull} step(s) on every tendon reported apart (below)"
        if without:
            line += f"; {', '.join(without)}: no up-hold-down move, so no Table II row"
        lines.append(line)
        if phases.prepull:
            prepull += _prepull_rows(rec, label, phases)

    def ordered(parts: list[pd.DataFrame], columns: list[str]) -> pd.DataFrame:
        if not parts:
            return pd.DataFrame(columns=columns)
        out = pd.concat(parts, ignore_index=True)
        return out[columns + [c for c in out.columns if c not in columns]]

    return MoveTables(ordered(tendons, TENDON_COLUMNS), ordered(tips, TIP_COLUMNS),
                      pd.DataFrame(prepull, columns=PREPULL_COLUMNS), lines)  # fmt: skip


def _moves_displayed(t: MoveTables) -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    def cells(table: pd.DataFrame, metric: str, digits: int) -> pd.Series:
        return table[metric].map(lambda v: _number(v, digits))

    tendons = pd.DataFrame({
        "recording": t.tendons["recording"], "source": t.tendons["source"],
        "tendon": t.tendons["tendon"].astype(str), "role": t.tendons["role"], "motion": t.tendons["motion"],
        "y0 N": cells(t.tendons, "y0_n", 2), "peak N": cells(t.tendons, "peak_n", 2),
        "overshoot %": cells(t.tendons, "overshoot_pct", 1),
        "settling ms": cells(t.tendons, "settling_ms", 0),
    })  # fmt: skip
    tip = pd.DataFrame({
        "recording": t.tip["recording"], "lead tendon": t.tip["lead"].astype(str), "motion": t.tip["motion"],
        "peak mm": cells(t.tip, "peak_mm", 2), "overshoot %": cells(t.tip, "overshoot_pct", 1),
        "settling ms": cells(t.tip, "settling_ms", 0),
    })  # fmt: skip
    pre = pd.DataFrame({
        "recording": t.prepull["recording"], "tendon": t.prepull["tendon"].astype(str),
        "steps": t.prepull["prepull_steps"].astype(str), "pulled at s": cells(t.prepull, "pulled_s", 3),
        "released from s": cells(t.prepull, "released_s", 3),
        "pre-pulled N": cells(t.prepull, "prepulled_n", 2), "at rest after N": cells(t.prepull, "rest_n", 2),
    })  # fmt: skip
    return tendons, tip, pre


def _move_notes(t: MoveTables) -> list[str]:
    rows = [f"{r.recording} tendon {r.tendon} {r.motion}: {r.reason}" for r in t.tendons.itertuples()
            if isinstance(r.reason, str) and r.reason]  # fmt: skip
    return rows + [f"{r.recording} tip {r.motion}: {r.reason}" for r in t.tip.itertuples()
                   if isinstance(r.reason, str) and r.reason]  # fmt: skip


TIP_TITLE = "Tip displacement |p - p0| from where it stood before the move (twin-provided, simulated)"
PREPULL_TITLE = "Pre-pull (every tendon pulled in before the move, let out after it; not in the rows above)"


def _moves_parts(t: MoveTables, band: float) -> list[tuple[str, pd.DataFrame | list[str]]]:
    """(title, table or lines) of the report on recordings of several tendons, in order."""
    tendons, tip, pre = _moves_displayed(t)
    n = len({line.split(": ")[0] for line in t.lines})
    parts: list[tuple[str, pd.DataFrame | list[str]]] = [
        (f"Per tendon ({n} recording(s) of several tendons; tendons numbered as in the rig file; motions "
         f"from the lead tendon's count; settling band ±{100 * band:g} %)", tendons),
        ("Lead tendon, and tendons without a Table II row", t.lines),
    ]  # fmt: skip
    if not t.prepull.empty:
        parts.append((PREPULL_TITLE, pre))
    if not t.tip.empty:
        parts.append((f"{TIP_TITLE}; settling band ±{100 * band:g} %", tip))
    if any(s != "hardware" for s in t.tendons["source"].unique()):
        parts.append(("", ["Source 'virtual-rig': simulated recordings, not hardware measurements."]))
    notes_ = _move_notes(t)
    if notes_:
        parts.append(("Notes (NaN or bounded values)", notes_))
    return parts


def moves_text(t: MoveTables, band: float) -> str:
    """The report on recordings of several tendons, for the terminal."""
    lines: list[str] = []
    for title, body in _moves_parts(t, band):
        lines += [""] if lines else []
        lines += [f"{title}:"] if title else []
        lines += [body.to_string(index=False)] if isinstance(body, pd.DataFrame) else [
            f"  {x}" if title else x for x in body]  # fmt: skip
    return "\n".join(lines) + "\n"


def moves_markdown(t: MoveTables, band: float) -> str:
    """The same report as Markdown."""
    parts = []
    for title, body in _moves_parts(t, band):
        head = f"## {title}\n" if title else ""
        parts.append(head + ("\n" + to_markdown(body) if isinstance(body, pd.DataFrame) else
                             "\n" + "".join(f"- {x}\n" if title else f"{x}\n" for x in body)))  # fmt: skip
    return "\n".join(parts)


def check_output_folder(path: Path) -> None:
    """Refuse to create an output's missing folder anywhere but under the working directory or ``my_data/``.

    A folder that exists is used wherever it is; a missing one is created only inside the current directory or
    the user's data folder (:func:`helpers.base.paths.user_data_root`), never e.g. at the file
    system's root from a mistyped absolute path.

    Raises
    ------
    ValueError
        A missing folder elsewhere (exit status 2: nothing was written).
    """
    parent = Path(os.path.abspath(path)).parent
    if parent.is_dir():
        return
    roots = (Path.cwd().resolve(), user_data_root().resolve())
    missing = parent
    while not missing.parent.is_dir() and missing.parent != missing:
        missing = missing.parent
    if not any(Path(os.path.realpath(missing.parent)).is_relative_to(r) for r in roots):
        raise ValueError(
            f"{path}: the folder {missing} does not exist; outputs create folders only inside the "
            "current directory or my_data/ (create it first, or write elsewhere)"
        )


def _write(path: Path, text: str, replace: bool) -> Path:
    """Write ``text`` to ``path`` whole (temporary file, then rename); refuse to overwrite unless asked."""
    if path.exists() and not replace:
        raise RecordingExists(f"{shown(path)} exists; pass --replace to overwrite it")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise RecordingError(f"{shown(path)}: cannot write ({exc.strerror or exc})") from exc
    return path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``python -m helpers metrics``."""
    parser.formatter_class = DefaultsHelp
    parser.description = (
        "Table II metrics (peak, overshoot, settling time; docs/metrics.md) of recordings, per run and "
        "as means over the repetitions of each scenario. Skipped recordings are listed with the reason."
    )
    parser.add_argument(
        "paths", nargs="+", metavar="PATH",
        help="recordings: a .csv/.json file or its stem, a folder (searched recursively) or a glob pattern",
    )  # fmt: skip
    parser.add_argument(
        "--band", type=arg_number(0, 0.5, lo_open=True), default=0.05,
        help="settling band, a fraction of the step, in (0, 0.5]",
    )  # fmt: skip
    parser.add_argument(
        "--csv", metavar="STEM", type=Path,
        help="also write STEM_runs.csv and STEM_scenarios.csv (full precision, with the data source); a "
        "missing folder is created only inside the current directory or my_data/",
    )  # fmt: skip
    parser.add_argument(
        "--markdown", metavar="FILE",
        help="write the report as Markdown to FILE ('-': print Markdown instead of the plain text)",
    )  # fmt: skip
    parser.add_argument("--replace", action="store_true", help="overwrite existing --csv/--markdown files")
    parser.add_argument(
        "--include-aborted", action="store_true", help="analyse aborted runs too (else skipped)"
    )
    parser.add_argument(
        "--mix-rigs", action="store_true", help="accept recordings of different rigs (rig files) in one table"
    )


def run(args: argparse.Namespace) -> int:
    """Run ``python -m helpers metrics``."""
    selection = select(args.paths, include_aborted=args.include_aborted)
    rigs = {(r.hash, r.name) for r in (recording_rig(rec.meta, rec.name) for rec in selection.recordings)}
    if len(rigs) > 1 and not getattr(args, "mix_rigs", False):
        names = ", ".join(sorted(name for _, name in rigs))
        raise ValueError(f"recordings of {len(rigs)} rigs in one table ({names}): --mix-rigs mixes them")
    several = [rec for rec in selection.recordings if rec.tendons > 1]
    single = Selection([rec for rec in selection.recordings if rec.tendons == 1], selection.skipped)
    targets: list[tuple[Path, str]] = []
    stem = None if args.csv is None else (args.csv.with_suffix("") if args.csv.suffix == ".csv" else args.csv)
    if single.recordings or not several:
        runs = run_table(single, args.band)
        means = mean_table(runs, args.band)
        if stem is not None:
            for suffix, table in (("runs", runs), ("scenarios", means)):
                csv_text = table.to_csv(index=False, float_format="%.6g")
                targets.append((stem.with_name(f"{stem.name}_{suffix}.csv"), csv_text))
        markdown = report_markdown(runs, means, selection.skipped, args.band)
        text = report_text(runs, means, selection.skipped, args.band)
    else:
        markdown = text = ""
    if several:
        moves = move_tables(several, args.band)
        if stem is not None:
            for suffix, table in (("tendons", moves.tendons), ("prepull", moves.prepull), ("tip", moves.tip)):
                if suffix == "tendons" or not table.empty:
                    csv_text = table.to_csv(index=False, float_format="%.6g")
                    targets.append((stem.with_name(f"{stem.name}_{suffix}.csv"), csv_text))
        markdown += ("\n" if markdown else "") + moves_markdown(moves, args.band)
        text += ("\n" if text else "") + moves_text(moves, args.band)
        if not single.recordings:
            markdown += "\n" + _skipped_text(selection.skipped).replace("\n  ", "\n- ") + "\n"
            text += "\n" + _skipped_text(selection.skipped) + "\n"
    if args.markdown not in (None, "-"):
        targets.append((Path(args.markdown), markdown))
    for path, _ in targets:  # refuse before writing any, so that a refusal leaves nothing half-done
        check_output_folder(path)
        if path.exists() and not args.replace:
            raise RecordingExists(f"{shown(path)} exists; pass --replace to overwrite it")
    sys.stdout.write(markdown if args.markdown == "-" else text)
    for path, text in targets:
        _write(path, text, args.replace)
        print(f"wrote {shown(path)}", file=sys.stderr)
    return 0
