"""Tuning a rig file's twin on its own data (helpers.virtual.rig_file_tuning; the end to end run is slow)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from helpers import rigfile
from helpers.base.jsonfile import DataFileError
from helpers.virtual import rig_file_tuning

LONG_ARM = rigfile.RIGS_DIR / "long-arm.toml"


def test_tuned_text_rewrites_the_arm_keys_and_keeps_the_rest():
    rig = rigfile.load(LONG_ARM)
    values = {"disc_mass_g": 1.25, "cable_offset_mm": 14.5, "cable_stiffness_n_m": 50000.0,
              "pretension_n": 1.75, "damping_alpha_per_s": 2.0, "damping_beta_chord_s": 0.0004}  # fmt: skip
    text = rig_file_tuning.tuned_text(rig, values, ["TUNED (test)", "source recordings: none"])
    assert text.startswith("# TUNED (test)\n# source recordings: none\n")
    tuned = rigfile.loads(text)
    assert tuned.arm.disc_mass_g == 1.25 and tuned.arm.cable_offset_mm == 14.5
    assert tuned.arm.pretension_n == 1.75 and tuned.arm.damping_beta_chord_s == 0.0004
    assert tuned.hardware == rig.hardware and tuned.arm.length_mm == rig.arm.length_mm
    assert tuned.hash != rig.hash


def test_tuned_text_adds_keys_the_input_leaves_to_defaults(tmp_path):
    text = LONG_ARM.read_text().replace("damping_alpha_per_s = 1.887944", "")
    rig = rigfile.loads(text, source="x.toml")
    out = rig_file_tuning.tuned_text(rig, {"damping_alpha_per_s": 3.5}, ["p"])
    assert rigfile.loads(out).arm.damping_alpha_per_s == 3.5


def test_the_series_stiffness_goes_back_to_the_cable_alone():
    from helpers.virtual.from_rig import rig_parameters

    rig = rigfile.load(LONG_ARM)
    values = rig_file_tuning.arm_values(rig, rig_parameters(rig))
    assert values["cable_stiffness_n_m"] == pytest.approx(rig.arm.cable_stiffness_n_m, rel=1e-9)
    assert values["disc_mass_g"] == pytest.approx(rig.arm.disc_mass_g, rel=1e-12)


def test_an_existing_output_is_refused(tmp_path):
    rig = rigfile.load(LONG_ARM)
    out = tmp_path / "x.toml"
    out.write_text("keep")
    with pytest.raises(DataFileError, match="exists already"):
        rig_file_tuning.write_tuned(rig, None, 0.0, None, out)  # type: ignore[arg-type]
    assert out.read_text() == "keep"


def _helpers(*argv, cwd, env, ok=True):
    proc = subprocess.run([sys.executable, "-m", "helpers", *argv], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=900)  # fmt: skip
    if ok:
        assert proc.returncode == 0, proc.stderr[-2000:]
    return proc


@pytest.mark.slow
def test_second_rig_end_to_end_on_its_twin(tmp_path):
    """long-arm: record all (scaled Table I), metrics, tune, virtual-rig tune; the mode against rig check."""
    env = dict(os.environ)
    data = tmp_path / "data"
    rig = ["--rig", str(LONG_ARM)]
    _helpers("record", "calibration", *rig, "--data-dir", str(data), "--quiet", cwd=tmp_path, env=env)
    proc = _helpers("record", "all", *rig, "--data-dir", str(data), "--repetitions", "1", cwd=tmp_path,
                    env=env)  # fmt: skip
    note = "Table I: speeds 200, 300 -> 100, 150 mm/s; distances 10, 20, 30 -> 6.6, 13.2, 19.9 mm"
    assert note in proc.stderr
    assert (data / "experiments" / "zvd_v150_x13p2_r1.csv").exists()
    # metrics without --rig: each recording's own rig (its travel of 254 steps, its 10 N load cell)
    proc = _helpers("metrics", str(data / "experiments"), "--csv", str(tmp_path / "m"), cwd=tmp_path, env=env)
    assert "Skipped: none" in proc.stdout
    # the identified mode against rig check's prediction (the dominant mode at rest, rotor free)
    found = json.loads((data / "identification" / "result.json").read_text())
    predicted = json.loads(_helpers("rig", "check", str(LONG_ARM), "--json", "--points", "2", cwd=tmp_path,
                                    env=env).stdout)["dominant_at_rest"]  # fmt: skip
    # a damped-sine fit on 9-10 s of a noisy 1 kHz record of the same model: 0.5 % (omega_d), 5 % (zeta)
    assert found["omega_d"] == pytest.approx(predicted["omega_d_rad_s"], rel=5e-3)
    assert found["zeta"] == pytest.approx(predicted["zeta"], rel=5e-2)
    # tune: survey over the rig's 20 mm, the scaled grid
    proc = _helpers("tune", *rig, "--data-dir", str(data), "--repetitions", "1", "--quiet", cwd=tmp_path,
                    env=env)  # fmt: skip
    verification = json.loads((data / "tuning" / "table-i_verification.json").read_text())
    assert {(r["v_in_mm_s"], r["x_f_mm"]) for r in verification["rows"]} == {
        (100.0, 6.6), (100.0, 13.2), (100.0, 19.9), (150.0, 13.2),
    }  # fmt: skip
    # virtual-rig tune: a new rig file with provenance, the input untouched
    before = LONG_ARM.read_bytes()
    out = tmp_path / "long-arm-tuned.toml"
    _helpers("virtual-rig", "tune", *rig, "--data-dir", str(data), "--max-evaluations", "3",
             "--out", str(out), cwd=tmp_path, env=env)  # fmt: skip
    assert LONG_ARM.read_bytes() == before
    text = out.read_text()
    assert "# TUNED by `python -m helpers virtual-rig tune`" in text and "unshaped_v150_x13p2_r1.csv" in text
    tuned = rigfile.load(out)
    # tuned on the twin's own data: the disc mass solved from the identified mode comes back within 2 %
    assert tuned.arm.disc_mass_g == pytest.approx(1.0, rel=2e-2)
    again = _helpers("virtual-rig", "tune", *rig, "--data-dir", str(data), "--max-evaluations", "1", "--out",
                     str(out), cwd=tmp_path, env=env, ok=False)  # fmt: skip
    assert again.returncode == 5 and "exists already" in again.stderr
