import math

import pandas as pd

from helpers.base import tables


def test_markdown_has_fixed_precision_and_nan():
    df = pd.DataFrame({"peak_n": [9.04, math.nan], "system": ["unshaped", "zv"]})
    text = tables.to_markdown(df, precision=2)
    assert text.splitlines() == [
        "| peak_n | system |",
        "|---|---|",
        "| 9.04 | unshaped |",
        "| NaN | zv |",
    ]


def test_save_table_writes_three_formats(tmp_path, monkeypatch):
    monkeypatch.setattr(tables, "figure_path", lambda name: tmp_path / name)
    df = pd.DataFrame({"x_f_mm": [10.0, 20.0], "overshoot_pct": [153.123456, 12.5]})
    paths = tables.save_table(df, "t2", precision=1, caption="Table II")
    assert sorted(p.suffix for p in paths) == [".csv", ".md", ".tex"]
    back = pd.read_csv(tmp_path / "t2.csv")
    assert back["overshoot_pct"].iloc[0] == 153.123  # %.6g keeps six significant digits
    assert "153.1" in (tmp_path / "t2.md").read_text()
    tex = (tmp_path / "t2.tex").read_text()
    assert "\\caption{Table II}" in tex and "153.1" in tex


def test_display_tables_round_once_and_carry_their_source(tmp_path, monkeypatch):
    monkeypatch.setattr(tables, "figure_path", lambda name: tmp_path / name)
    # 35.449 rounds to 35.4 (35.45 -> 35.5 only if it were rounded to two digits first); -0.049 to -0.0
    df = pd.DataFrame({"overshoot_pct": [35.449, 82.25], "peak_n": [-0.049, 9.96]})
    tables.save_table(df, "d", precision=1, source="virtual-rig", round_csv=True)
    csv_lines = (tmp_path / "d.csv").read_text().splitlines()
    assert csv_lines == ["source,overshoot_pct,peak_n", "virtual-rig,35.4,-0.0", "virtual-rig,82.2,10.0"]
    md = (tmp_path / "d.md").read_text()
    assert "| 35.4 | -0.0 |" in md and "source" not in md
