"""The second shipped rig (rigs/long-arm.toml) end to end on its twin: calibration, pulse, identification."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pytest

from helpers.base.paths import DATA_DIR
from helpers.rig.static import PAPER_MASSES_KG, calibration_masses_kg


def test_calibration_masses_follow_the_load_cell(shipped_rig):  # rig-parametrised (tests/conftest.py)
    assert calibration_masses_kg(20.0) == PAPER_MASSES_KG == (0.0, 0.2, 0.5, 1.0, 1.5, 1.9)
    assert calibration_masses_kg(10.0) == (0.0, 0.1, 0.25, 0.5, 0.75, 0.95)
    # the host's masses (record calibration) are its rig's: within the load cell's range, below saturation
    CALIBRATION_MASSES_KG = calibration_masses_kg(shipped_rig.load().tendons[0].load_cell_range_n)  # noqa: N806
    assert CALIBRATION_MASSES_KG == shipped_rig.calibration_masses_kg
    range_n = shipped_rig.hw("load_cell_range_n")
    assert max(CALIBRATION_MASSES_KG) * 9.80665 < range_n
    top_counts = shipped_rig.counts(shipped_rig.hw("loop_zero_ma")) + max(CALIBRATION_MASSES_KG) * 9.80665 * (
        shipped_rig.gain_counts_per_n
    )
    assert top_counts < shipped_rig.clip_counts[1]


def _helpers(*argv: str, cwd, env) -> subprocess.CompletedProcess:
    proc = subprocess.run([sys.executable, "-m", "helpers", *argv], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=600)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    return proc


@pytest.mark.slow
def test_second_rig_identified_mode_agrees_with_its_prediction(tmp_path):
    env = dict(os.environ)
    data = tmp_path / "data"
    (data / "identification").mkdir(parents=True)
    shutil.copy(DATA_DIR / "identification" / "result.json", data / "identification" / "result.json")
    _helpers("record", "calibration", "--rig", "long-arm", "--data-dir", str(data), "--quiet", cwd=tmp_path,
             env=env)  # fmt: skip
    cal = json.loads((data / "calibration" / "calibration.json").read_text())
    assert cal["gain_counts_per_n"] == pytest.approx(49.152, rel=2e-3)  # 16 mA over 10 N, 150 ohm, 10 bits
    assert cal["mm_per_step"] == pytest.approx(0.0785398, rel=1e-6)
    _helpers("record", "pulse", "--rig", "long-arm", "--v-in", "100", "--x-f", "10", "--data-dir", str(data),
             "--group", "id", "--quiet", cwd=tmp_path, env=env)  # fmt: skip
    predicted = json.loads(_helpers("rig", "check", "long-arm", "--json", "--points", "2", cwd=tmp_path,
                                    env=env).stdout)["dominant_at_rest"]  # fmt: skip
    code = (
        "import sys, json; from helpers import recordings; "
        "from helpers.paper.identify import identify_recording; "
        "rec = recordings.load(sys.argv[1]); r = identify_recording(rec); "
        "print(json.dumps({'rig': rec.meta['rig']['name'], 'omega_d': r.omega_d, 'zeta': r.zeta}))"
    )
    proc = subprocess.run([sys.executable, "-c", code, str(data / "id" / "unshaped_v100_x10.csv")], env=env,
                          capture_output=True, text=True, timeout=300)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-2000:]
    found = json.loads(proc.stdout)
    assert found["rig"] == "long-arm"
    # a damped-sine fit on 9-10 s of a noisy (0.5 count rms) 1 kHz record: within 0.5 % (omega_d), 5 % (zeta)
    assert found["omega_d"] == pytest.approx(predicted["omega_d_rad_s"], rel=5e-3)
    assert found["zeta"] == pytest.approx(predicted["zeta"], rel=5e-2)
