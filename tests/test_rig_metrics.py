"""Metrics use the recording's rig: its sensor range, and no two rigs in one table unless asked."""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from helpers import recordings, rigfile
from helpers.paper import metrics
from rigs import SHIPPED

PAPER_TEXT = (rigfile.RIGS_DIR / "paper.toml").read_text()


def _rig(**edits: str) -> rigfile.RigFile:
    text = PAPER_TEXT
    for key, value in edits.items():
        text, n = re.subn(rf"(?m)^{key} = .*$", f"{key} = {value}", text)
        assert n == 1
    return rigfile.loads(text)


def test_clip_limits_follow_the_rigs_adc_chain():
    assert metrics.clip_limits(None, rigfile.default_rig()) == (116.0, 628.0)
    # 100 ohm: 3.8 mA reads 77.8 counts (floored), 20.5 mA reads 419.8 (rounded, less the 2-count margin)
    shunt = _rig(shunt_ohm="100.0", name='"shunt100"')
    assert metrics.clip_limits(None, shunt) == (77.0, 418.0)
    adc = np.array([77, 78, 417, 418])
    assert metrics.clipped_samples(adc, None, shunt).tolist() == [True, False, False, True]
    assert metrics.clipped_samples(adc).tolist() == [True, True, False, False]  # the host's (paper's) chain


def test_the_sensor_range_is_the_rigs(rig_file):  # rig-parametrised (tests/conftest.py)
    # a recording's rig (an argument); without one, the paper's rig (its 116 and 628 counts, by hand)
    low, high = rig_file.clip_counts
    rig = rigfile.load(rig_file.path)
    assert metrics.clip_limits(None, rig) == (float(low), float(high))
    assert metrics.clip_limits() == tuple(float(c) for c in SHIPPED["paper"].clip_counts) == (116.0, 628.0)
    adc = np.array([low, low + 1, high - 1, high])
    assert metrics.clipped_samples(adc, None, rig).tolist() == [True, False, False, True]
    # a recording's calibration with another zero reading: only the ADC's rails bound the range
    other_chain = {"offset_counts": rig_file.counts(rig_file.hw("loop_zero_ma")) + 50.0}
    assert metrics.clip_limits(other_chain, rig) == (0.0, float(rig_file.adc_max))


def _rec(name: str, rig: rigfile.RigFile | None) -> SimpleNamespace:
    t = np.arange(0.0, 2.0, 0.001)
    frame = pd.DataFrame({"t_s": t, "steps": np.zeros_like(t), "tension_n": np.full_like(t, 2.0),
                          "adc": np.full(t.size, 172)})  # fmt: skip
    meta = {"scenario": {"v_in_mm_s": 100.0, "x_f_mm": 10.0, "system": "unshaped"}, "status": "complete"}
    if rig is not None:
        meta["rig"] = recordings.rig_section(rig)
    return SimpleNamespace(name=name, frame=frame, meta=meta)


def test_two_rigs_in_one_table_are_refused_unless_asked():
    other = rigfile.load(rigfile.RIGS_DIR / "long-arm.toml")
    same = [_rec("a", None), _rec("b", rigfile.default_rig())]  # an old recording is the paper's rig
    assert len(metrics.metrics_by_run(same)) == 4
    mixed = [_rec("a", None), _rec("b", other)]
    with pytest.raises(ValueError, match=r"2 rigs in one table \(long-arm, paper\)"):
        metrics.metrics_by_run(mixed)
    assert len(metrics.metrics_by_run(mixed, mix_rigs=True)) == 4


def test_metrics_command_refuses_two_rigs_unless_asked(tmp_path, capsys):
    import json
    import shutil

    from helpers.__main__ import main
    from helpers.base.paths import DATA_DIR

    for stem in ("zv_v200_x10_r2", "zv_v200_x20_r2"):
        for ext in (".csv", ".json"):
            shutil.copy(DATA_DIR / "experiments" / f"{stem}{ext}", tmp_path / f"{stem}{ext}")
    # one run's samples as a recording of the long-arm rig (its cable per step; a speed within its 150 mm/s)
    run = recordings.load(tmp_path / "zv_v200_x20_r2.csv")
    m = run.meta
    other = recordings.from_samples(
        run.frame[["seq", "t_us", "adc", "steps"]].to_numpy(),
        rigfile.load(rigfile.RIGS_DIR / "long-arm.toml"),
        source=m["source"],
        scenario={**m["scenario"], "v_in_mm_s": 100.0},
        rate_hz=m["rate_hz"],
        started_utc=m["started_utc"],
        firmware=m["firmware"],
        counts=m["counts"],
    )
    recordings.save(other, run.path, replace=True)
    assert json.loads(run.path.with_suffix(".json").read_text())["rig"]["name"] == "long-arm"
    assert main(["metrics", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "2 rigs in one table (long-arm, paper)" in err and "--mix-rigs" in err
    assert main(["metrics", str(tmp_path), "--mix-rigs"]) == 0
