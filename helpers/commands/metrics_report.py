"""``python -m helpers metrics PATH...``: Table II metrics (peak, overshoot, settling) for any recordings.

The command behind a researcher's own experiments: point it at recordings (files, folders or glob patterns)
and it prints, like the paper's Table II, the metrics of every run and motion and their means over the
repetitions of each scenario. The numbers are those of :mod:`helpers.paper.metrics` (definitions in
``docs/metrics.md``); this module only finds the recordings, says which it skipped and why, and writes the
tables::

    python -m helpers metrics data/runs/mine
    python -m helpers metrics "data/experiments/zvd_*" --band 0.02
    python -m helpers metrics data/runs/mine --csv results/mine --markdown results/mine.md

A path may name a recording by its ``.csv``, its ``.json`` or its stem. Recordings that cannot be analysed
are skipped, never silently: a malformed or incomplete pair, an aborted run (``--include-aborted`` analyses
it anyway), a load-cell calibration run, a file that is not a recording. Every table carries the data's
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

import pandas as pd

from helpers.base.cli import DefaultsHelp, arg_number
from helpers.base.paths import shown
from helpers.base.tables import to_markdown
from helpers.commands.metrics_tendons import (
    tendon_markdown,
    tendon_table,
    tendon_text,
    tip_markdown,
    tip_table,
    tip_text,
)
from helpers.paper import metrics
from helpers.paper import numbers as paper
from helpers.recordings import RESERVED_NAMES, Recording, RecordingError, RecordingExists, load, recording_rig

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
    # several tendons: every tendon's motions come from its own step count (metrics_tendons)
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
        help="also write STEM_runs.csv and STEM_scenarios.csv (full precision, with the data source)",
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
    tendons = tendon_table(several, args.band)
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
        if stem is not None:
            targets.append((stem.with_name(f"{stem.name}_tendons.csv"),
                            tendons.to_csv(index=False, float_format="%.6g")))  # fmt: skip
        tip = tip_table(several, args.band)
        if stem is not None and not tip.empty:
            tip_csv = tip.to_csv(index=False, float_format="%.6g")
            targets.append((stem.with_name(f"{stem.name}_tip.csv"), tip_csv))
        markdown += tendon_markdown(tendons, args.band)
        text += tendon_text(tendons, args.band)
        markdown += tip_markdown(tip, args.band)
        text += tip_text(tip, args.band)
        if not single.recordings:
            markdown += "\n" + _skipped_text(selection.skipped).replace("\n  ", "\n- ") + "\n"
            text += "\n" + _skipped_text(selection.skipped) + "\n"
    if args.markdown not in (None, "-"):
        targets.append((Path(args.markdown), markdown))
    for path, _ in targets:  # refuse before writing any, so that a refusal leaves nothing half-done
        if path.exists() and not args.replace:
            raise RecordingExists(f"{shown(path)} exists; pass --replace to overwrite it")
    sys.stdout.write(markdown if args.markdown == "-" else text)
    for path, text in targets:
        _write(path, text, args.replace)
        print(f"wrote {shown(path)}", file=sys.stderr)
    return 0
