"""Saving result tables as CSV (for machines), Markdown (for the README) and LaTeX (for a paper).

Markdown is written here rather than with ``DataFrame.to_markdown`` so that the project does not need the
``tabulate`` package for one function; LaTeX uses pandas' own ``to_latex`` (jinja2 comes with Jupyter).
"""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from helpers.base.paths import figure_path


def _cell(value: object, precision: int) -> str:
    if isinstance(value, float):
        return "NaN" if math.isnan(value) else f"{value:.{precision}f}"
    return str(value)


def to_markdown(table: pd.DataFrame, precision: int = 1) -> str:
    """Render ``table`` as a GitHub-flavoured Markdown table with fixed precision.

    Parameters
    ----------
    table : pandas.DataFrame
        The table; its index is not written.
    precision : int
        Digits after the decimal point of float cells.

    Returns
    -------
    str
        The Markdown text, ending in a newline.
    """
    header = "| " + " | ".join(str(c) for c in table.columns) + " |"
    rule = "|" + "|".join("---" for _ in table.columns) + "|"
    rows = [
        "| " + " | ".join(_cell(v, precision) for v in row) + " |"
        for row in table.itertuples(index=False, name=None)
    ]
    return "\n".join([header, rule, *rows]) + "\n"


def save_table(
    table: pd.DataFrame,
    stem: str,
    precision: int = 1,
    caption: str = "",
    *,
    source: str | None = None,
    round_csv: bool = False,
) -> list[Path]:
    """Save ``table`` as ``figures/<stem>.csv``, ``.md`` and ``.tex``.

    Every number is rounded once, from full precision, to the digits shown (never a rounded value rounded
    again).

    Parameters
    ----------
    table : pandas.DataFrame
        The table, at full precision.
    stem : str
        File name without extension, e.g. ``"table2_metrics"``.
    precision : int
        Digits after the decimal point in the Markdown and LaTeX versions (and in the CSV if ``round_csv``).
    caption : str
        Caption of the LaTeX table (and a first line of the Markdown file when given).
    source : str, optional
        Where the numbers come from (e.g. ``"virtual-rig"``): written as the CSV's first column ``source``,
        so that the file carries its provenance wherever it is copied.
    round_csv : bool
        Write the CSV with ``precision`` digits too (a display table); by default it keeps six significant
        digits.

    Returns
    -------
    list of pathlib.Path
        The three files written.
    """
    csv_table = table if source is None else table.assign(source=source)[["source", *table.columns]]
    csv = figure_path(f"{stem}.csv")
    csv_table.to_csv(csv, index=False, float_format=f"%.{precision}f" if round_csv else "%.6g")
    md = figure_path(f"{stem}.md")
    md.write_text((f"{caption}\n\n" if caption else "") + to_markdown(table, precision))
    tex = figure_path(f"{stem}.tex")
    latex = table.to_latex(
        index=False, float_format=lambda x: _cell(float(x), precision), caption=caption or None
    )
    tex.write_text(latex)
    return [csv, md, tex]
