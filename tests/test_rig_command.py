"""``python -m helpers rig check|new`` and the firmware header generator (docs/rig_file.md)."""

from __future__ import annotations

import hashlib
import json
import re
import shutil
import subprocess

import pytest

from helpers import rigfile
from helpers.__main__ import main
from helpers.rigfile import firmware_header


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    status = main(argv)
    out = capsys.readouterr()
    return status, out.out, out.err


def test_check_json_of_the_paper_rig(capsys):
    status, out, _ = _run(["rig", "check", "paper", "--json", "--points", "2"], capsys)
    assert status == 0
    r = json.loads(out)
    assert r["mm_per_step"] == pytest.approx(0.2552544, abs=1e-7)
    assert (r["min_interval_us"], r["travel_steps"], r["adc_clip_high_counts"]) == (639, [156], 628)
    modes = r["modes_at_rest"]
    assert len(modes) >= 2 and all(set(m) >= {"omega_d_rad_s", "zeta"} for m in modes)
    assert [m["omega_d_rad_s"] for m in modes] == sorted(m["omega_d_rad_s"] for m in modes)
    # the paper's file holds the tuned twin: its dominant mode is the paper's identified one
    assert r["dominant_at_rest"]["omega_d_rad_s"] == pytest.approx(25.085, abs=0.01)
    assert r["dominant_at_rest"]["zeta"] == pytest.approx(0.044, abs=5e-4)
    assert r["cable_stiffness_n_m"] == pytest.approx(71706.96, rel=1e-6)
    assert r["pretension_n"] == 2.3554
    assert r["rod_bending_stiffness_n_m2"] == pytest.approx(206.8e9 * 3.141592653589793 * 0.82e-3**4 / 64)
    assert r["rod_mass_kg"] == pytest.approx(7850 * 3.141592653589793 / 4 * 0.82e-3**2 * 0.24)
    assert r["static_tension_at_travel_n"] < r["pull_out_n"][0]


def test_check_text_of_the_second_rig(capsys):
    status, out, _ = _run(["rig", "check", str(rigfile.RIGS_DIR / "long-arm.toml"), "--points", "2"], capsys)
    assert status == 0
    assert "0.07854 mm" in out and "254 steps" in out and "524-1000000 us" in out
    assert "firmware: fits the boards" in out
    assert "predicted modes at rest" in out


def test_check_refuses_a_bad_file_in_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    text = (rigfile.RIGS_DIR / "paper.toml").read_text().replace("discs = 12", "discs = 0")
    bad.write_text(text)
    status, out, err = _run(["rig", "check", str(bad)], capsys)
    assert status == 2 and out == ""
    assert err.count("\n") == 1 and "[arm] discs" in err and str(bad) in err


def test_new_writes_a_valid_template_and_never_overwrites(tmp_path, capsys):
    path = tmp_path / "mine.toml"
    status, _, _ = _run(["rig", "new", str(path)], capsys)
    assert status == 0
    text = path.read_text()
    assert text.count("#") > 40  # commented
    rig = rigfile.load(path)
    assert rig.name == "mine"
    assert rigfile.derived(rig) == rigfile.derived(rigfile.default_rig())
    status, _, err = _run(["rig", "new", str(path)], capsys)
    assert status == 5 and "exists already" in err
    assert path.read_text() == text


# --- the firmware header --------------------------------------------------------------------------------
def _macros(text: str) -> dict[str, str]:
    return dict(re.findall(r"(?m)^#define (RIG_\w+) (.+)$", text))


def test_header_of_the_paper_rig(tmp_path):
    out = tmp_path / "rig_config.h"
    assert firmware_header.main([str(rigfile.DEFAULT_RIG), "-o", str(out)]) == 0
    m = _macros(out.read_text())
    m.pop("RIG_CONFIG_H", None)
    assert list(m) == list(firmware_header.MACROS)
    digest = hashlib.sha256(rigfile.DEFAULT_RIG.read_bytes()).hexdigest()[:8]
    assert m["RIG_HASH"] == f'"{digest}"' and m["RIG_NAME"] == '"paper"'
    assert (m["RIG_AXES"], m["RIG_CHANNELS"], m["RIG_PROGRAMME_MAX"]) == ("1", "1", "64")
    assert (m["RIG_MIN_INTERVAL_US"], m["RIG_MAX_INTERVAL_US"]) == ("639", "1000000L")
    assert m["RIG_AXIS_TRAVEL_STEPS"] == "{156}"
    assert (m["RIG_DAQ_RATE_MIN_HZ"], m["RIG_DAQ_RATE_MAX_HZ"], m["RIG_DAQ_RATE_DEFAULT_HZ"]) == (
        "100", "2000", "1000",
    )  # fmt: skip
    assert (m["RIG_DAQ_BAUD"], m["RIG_STEPPER_BAUD"]) == ("500000L", "115200L")
    assert (m["RIG_ADC_CLIP_LOW_COUNTS"], m["RIG_ADC_CLIP_HIGH_COUNTS"]) == ("116", "628")


def test_header_of_a_four_tendon_rig_and_of_the_second_rig(tmp_path):
    out = tmp_path / "h.h"
    assert firmware_header.main(["four-tendon", "-o", str(out)]) == 0
    m = _macros(out.read_text())
    assert (m["RIG_AXES"], m["RIG_CHANNELS"]) == ("4", "4")
    assert m["RIG_AXIS_TRAVEL_STEPS"] == "{156, 156, 156, 156}"
    # 20 mm below rest / 0.2552544 mm per step = 78.35: the release table, right after the travel's
    assert m["RIG_AXIS_RELEASE_STEPS"] == "{78, 78, 78, 78}"
    names = list(m)
    assert names[names.index("RIG_AXIS_TRAVEL_STEPS") + 1] == "RIG_AXIS_RELEASE_STEPS"
    assert m["RIG_DAQ_BAUD"] == "1000000L"  # four channels per line need more than 500 kbaud
    assert firmware_header.main(["long-arm", "-o", str(out)]) == 0
    m = _macros(out.read_text())
    assert (m["RIG_MIN_INTERVAL_US"], m["RIG_AXIS_TRAVEL_STEPS"]) == ("524", "{254}")
    assert "RIG_AXIS_RELEASE_STEPS" not in m  # no release: the header as before the key existed


def test_header_refuses_a_release_and_travel_over_the_boards_8_bits(tmp_path, capsys):
    # the four-tendon rig: 156 steps of travel at pi 65 / 800 = 0.2552544 mm per step; a release of 25.5 mm is
    # floor(99.90) = 99 steps (255 in all, the most), 25.6 mm floor(100.29) = 100 (256); at most 99 steps,
    # 25.27 mm
    text = (rigfile.RIGS_DIR / "four-tendon.toml").read_text()
    out = tmp_path / "h.h"
    for release, ok in (("25.5", True), ("25.6", False)):
        rig_path = tmp_path / f"four{release}.toml"
        rig_path.write_text(text.replace("release_mm = 20.0", f"release_mm = {release}"))
        assert firmware_header.main([str(rig_path), "-o", str(out)]) == (0 if ok else 2)
    err = capsys.readouterr().err
    assert (
        err.count("\n") == 1 and "[hardware] release_mm: 100 steps below position 0 and 156 of travel" in err
    )
    assert "at most 255 steps of both together per axis (a release of at most 25.27 mm)" in err
    assert _macros(out.read_text())["RIG_AXIS_RELEASE_STEPS"] == "{99, 99, 99, 99}"  # 25.5 mm's, kept


def test_header_refuses_a_bad_rig_and_writes_nothing(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text(
        (rigfile.RIGS_DIR / "paper.toml").read_text() + "\n[[tendon]]\nangle_deg = 0.0\nofset_mm = 3\n"
    )
    out = tmp_path / "h.h"
    assert firmware_header.main([str(bad), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "ofset_mm" in err and "offset_mm" in err
    assert not out.exists()


def test_header_refuses_a_rig_the_boards_cannot_hold(tmp_path, capsys):
    text = (rigfile.RIGS_DIR / "long-arm.toml").read_text().replace("travel_mm = 20.0", "travel_mm = 25.0")
    rig_path = tmp_path / "long.toml"
    rig_path.write_text(text)
    assert rigfile.derived(rigfile.load(rig_path)).travel_steps == (318,)  # a valid rig file ...
    out = tmp_path / "h.h"
    assert firmware_header.main([str(rig_path), "-o", str(out)]) == 2  # ... the boards cannot hold
    err = capsys.readouterr().err
    assert "[hardware] travel_mm: 318 steps" in err and "at most 255" in err and not out.exists()


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc (Debian package gcc)")
def test_header_compiles_as_c(tmp_path):
    header = tmp_path / "rig_config.h"
    assert firmware_header.main(["four-tendon", "-o", str(header)]) == 0
    src = tmp_path / "use.c"
    src.write_text(
        '#include "rig_config.h"\n'
        "static const long travel[RIG_AXES] = RIG_AXIS_TRAVEL_STEPS;\n"
        "static const char hash[] = RIG_HASH;\n"
        '_Static_assert(sizeof(hash) == 9, "8 hex chars");\n'
        '_Static_assert(RIG_MIN_INTERVAL_US < RIG_MAX_INTERVAL_US, "intervals");\n'
        '_Static_assert(RIG_ADC_CLIP_LOW_COUNTS < RIG_ADC_CLIP_HIGH_COUNTS, "clip");\n'
        "int main(void) { return (int)(travel[RIG_AXES - 1] - 156) + RIG_CHANNELS - 4; }\n"
    )
    proc = subprocess.run(["gcc", "-std=c11", "-Wall", "-Werror", "-fsyntax-only", str(src)], cwd=tmp_path,
                          capture_output=True, text=True, timeout=60)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
