"""The rig file (docs/rig_file.md): loading, one-line refusals, derived values, the shipped rigs."""

from __future__ import annotations

import dataclasses
import hashlib
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest

from helpers import rigfile
from helpers.rigfile import RigFileError

PAPER_TEXT = (rigfile.RIGS_DIR / "paper.toml").read_text()


def _edit(text: str, key: str, value: str) -> str:
    """``text`` with the line ``key = ...`` given a new value (the key must be there once)."""
    new, n = re.subn(rf"(?m)^{re.escape(key)} = .*$", f"{key} = {value}", text)
    assert n == 1, key
    return new


def _refusal(text: str) -> str:
    with pytest.raises(RigFileError) as info:
        rigfile.loads(text, source="my.toml")
    line = str(info.value)
    assert "\n" not in line
    assert line.startswith("my.toml: ")
    return line


# --- the paper's rig: today's numbers, as literals from today's code -----------------------------------
def test_paper_rig_derives_todays_limits():
    rig = rigfile.default_rig()
    d = rigfile.derived(rig)
    assert rig.name == "paper" and rig.n_tendons == 1 and not rig.explicit_tendons
    assert d.mm_per_step[0] == pytest.approx(0.25525440310417, rel=1e-12)  # pi 65 / 800
    assert d.min_interval_us == 639  # Limits.min_interval_us
    assert d.max_interval_us == 1_000_000
    assert d.travel_steps == (156,)  # Limits.max_position_steps
    assert d.adc_max == 1023
    assert (d.clip_low_counts, d.clip_high_counts) == (116, 628)  # hardware.CLIP_LOW/HIGH_COUNTS
    assert d.offset_counts == pytest.approx(122.88)
    assert d.gain_counts_per_n[0] == pytest.approx(24.576)  # 16 mA over 20 N through 150 ohm, 10 bits of 5 V
    assert d.readable_n[0] == pytest.approx((628 - 122.88) / 24.576)
    assert rig.tendons[0].pull_out_n == pytest.approx(19.4624, abs=1e-3)  # docs/virtual_rig.md: 19.5 N
    hw = rig.hardware
    assert (hw.daq_rate_min_hz, hw.daq_rate_max_hz, hw.daq_rate_default_hz) == (100, 2000, 1000)
    assert (hw.daq_baud, hw.stepper_baud, hw.programme_max_items, hw.max_dwell_ms) == (
        500000,
        115200,
        64,
        60000,
    )


def test_paper_rig_file_matches_the_virtual_rig_and_the_paper():
    from helpers.paper import numbers as paper
    from helpers.virtual.parameters import RigParameters

    rig = rigfile.default_rig()
    p = RigParameters()
    a = rig.arm
    assert a.length_mm * 1e-3 == pytest.approx(paper.BACKBONE["L_m"], rel=1e-15)
    assert a.discs == paper.BACKBONE["n_discs"]
    assert a.backbone_diameter_mm * 1e-3 == pytest.approx(paper.BACKBONE["d_m"], rel=1e-15)
    assert rig.hardware.spool_diameter_mm == 65.0 and rig.hardware.steps_per_rev == 800
    assert a.disc_mass_g == pytest.approx(p.disc_mass * 1e3, rel=1e-14)
    assert a.cable_offset_mm == pytest.approx(p.r * 1e3, rel=1e-14)
    assert a.pretension_n == p.pretension
    assert a.cable_stiffness_n_m == pytest.approx(p.k_cable, rel=1e-14)
    assert (a.damping_alpha_per_s, a.damping_beta_chord_s) == (p.alpha, p.beta_chord)
    assert rig.hardware.holding_torque_n_m == p.holding_torque
    assert rig.hardware.load_cell_range_n == p.span_n


def test_hash_is_the_files_sha256_prefix(tmp_path):
    path = tmp_path / "r.toml"
    path.write_bytes(PAPER_TEXT.encode())
    rig = rigfile.load(path)
    assert rig.hash == hashlib.sha256(PAPER_TEXT.encode()).hexdigest()[:8]
    assert re.fullmatch(r"[0-9a-f]{8}", rig.hash)
    path.write_bytes((PAPER_TEXT + "# a comment changes the hash\n").encode())
    assert rigfile.load(path).hash != rig.hash


def test_second_rig_follows_from_its_numbers():
    rig = rigfile.load(rigfile.RIGS_DIR / "long-arm.toml")
    d = rigfile.derived(rig)
    assert (rig.hardware.spool_diameter_mm, rig.hardware.steps_per_rev) == (40.0, 1600)
    assert (rig.arm.length_mm, rig.arm.discs, rig.hardware.load_cell_range_n) == (450.0, 10, 10.0)
    assert d.mm_per_step[0] == pytest.approx(math.pi * 40 / 1600)
    assert d.min_interval_us == 524  # ceil(1e6 / (150 mm/s / 0.07854 mm))
    assert d.travel_steps == (254,)  # floor(20 / 0.07854)
    assert d.gain_counts_per_n[0] == pytest.approx(49.152)  # twice the paper's: half the range


def test_four_tendon_files():
    for name, gravity in (("four-tendon", (-1.0, 0.0, 0.0)), ("hanging", (0.0, 0.0, 1.0))):
        rig = rigfile.load(rigfile.RIGS_DIR / f"{name}.toml")
        assert [t.angle_deg for t in rig.tendons] == [0.0, 90.0, 180.0, 270.0]
        assert rig.arm.gravity_direction == gravity
        assert all(t.steps_per_rev == 800 and t.spool_diameter_mm == 65.0 for t in rig.tendons)


def test_tendon_overrides_and_default_tendon():
    text = PAPER_TEXT.replace(
        "[boards]",
        "[[tendon]]\nangle_deg = 0.0\n\n[[tendon]]\nangle_deg = 180.0\n"
        "offset_mm = 9.0\nspool_diameter_mm = 60.0\npretension_n = 1.0\n\n[boards]",
    )
    rig = rigfile.loads(text)
    t1, t2 = rig.tendons
    assert t1.offset_mm == 7.7833 and t1.spool_diameter_mm == 65.0
    assert (t2.offset_mm, t2.spool_diameter_mm, t2.pretension_n, t2.steps_per_rev) == (9.0, 60.0, 1.0, 800)
    assert rigfile.derived(rig).travel_steps == (156, int(40 / (math.pi * 60 / 800)))


def test_a_rig_is_named_by_a_path_or_a_shipped_name(tmp_path):
    assert rigfile.resolve("long-arm") == rigfile.RIGS_DIR / "long-arm.toml"  # a shipped rig's name
    assert rigfile.load(rigfile.resolve("long-arm")).name == "long-arm"
    other = tmp_path / "x.toml"
    other.write_text(_edit(PAPER_TEXT, "name", '"mine"'))
    assert rigfile.resolve(other) == other and rigfile.load(rigfile.resolve(str(other))).name == "mine"
    assert rigfile.resolve("no-such-rig") == Path("no-such-rig")  # not shipped: the path as given
    with pytest.raises(rigfile.RigFileError, match="no-such-rig: no such rig file"):
        rigfile.load(rigfile.resolve("no-such-rig"))


# --- bad input: one line naming the file, the key and the problem -----------------------------------
def test_malformed_toml():
    line = _refusal(PAPER_TEXT.replace("[arm]", "[arm"))
    assert "not valid TOML" in line


def test_unknown_key_suggests_the_nearest():
    line = _refusal(PAPER_TEXT.replace("spool_diameter_mm = 65.0", "spool_diameter_m = 65.0"))
    assert "[hardware] spool_diameter_m: unknown key" in line and "'spool_diameter_mm'" in line
    line = _refusal(PAPER_TEXT.replace("[arm]\n", "[arm]\ndisc_mas_g = 1.0\n"))
    assert "[arm] disc_mas_g" in line and "disc_mass_g" in line
    assert "unknown" in _refusal(PAPER_TEXT.replace("[boards]", "[bords]"))


def test_negative_diameter():
    line = _refusal(_edit(PAPER_TEXT, "spool_diameter_mm", "-65.0"))
    assert "[hardware] spool_diameter_mm: must be > 0 mm" in line


def test_zero_discs():
    line = _refusal(_edit(PAPER_TEXT, "discs", "0"))
    assert "[arm] discs: must be >= 1" in line


def test_wrong_unit_is_implausible():
    line = _refusal(_edit(PAPER_TEXT, "backbone_diameter_mm", "0.00082"))
    assert "[arm] backbone_diameter_mm" in line and "another unit" in line


def test_wrong_type_and_missing_key():
    assert "whole number" in _refusal(_edit(PAPER_TEXT, "steps_per_rev", "800.5"))
    assert "must be a number" in _refusal(_edit(PAPER_TEXT, "length_mm", '"240"'))
    line = _refusal(PAPER_TEXT.replace("length_mm = 240.0", ""))
    assert "[arm] length_mm: missing" in line
    assert "schema_version" in _refusal(_edit(PAPER_TEXT, "schema_version", "2"))


def test_unsafe_speed_is_refused():
    text = _edit(_edit(PAPER_TEXT, "steps_per_rev", "1600"), "spool_diameter_mm", "40.0")
    line = _refusal(text)  # 400 mm/s at 0.0785 mm/step = 5093 steps/s > 2000
    assert "[hardware] speed_limit_mm_s" in line and "5093 steps/s" in line and "157.1 mm/s" in line


def test_five_tendons_are_refused():
    tables = "".join(f"[[tendon]]\nangle_deg = {a}.0\n\n" for a in (0, 72, 144, 216, 288))
    line = _refusal(PAPER_TEXT.replace("[boards]", tables + "[boards]"))
    assert "[[tendon]]" in line and "5 tendons" in line


def test_two_tendons_at_one_angle_are_refused():
    tables = "[[tendon]]\nangle_deg = 0.0\n\n[[tendon]]\nangle_deg = 360.0\n\n"
    assert "[[tendon]] #2 angle_deg" in _refusal(PAPER_TEXT.replace("[boards]", tables + "[boards]"))


def test_load_cell_range_the_adc_cannot_read():
    line = _refusal(_edit(PAPER_TEXT, "shunt_ohm", "300.0"))  # 20 mA through 300 ohm = 6 V > 5 V
    assert "[hardware] shunt_ohm" in line and "cannot read" in line
    line = _refusal(_edit(PAPER_TEXT, "load_cell_range_n", "5.0"))  # 17 N at full travel, 5 N cell
    assert "[hardware] load_cell_range_n" in line and "cannot read" in line


def test_travel_the_stepper_cannot_hold():
    line = _refusal(_edit(PAPER_TEXT, "holding_torque_n_m", "0.42"))  # pull-out 12.9 N < 17.3 N at 40 mm
    assert "[hardware] travel_mm" in line and "cannot hold" in line


def test_missing_file_and_not_utf8(tmp_path):
    with pytest.raises(RigFileError, match="no such rig file"):
        rigfile.load(tmp_path / "none.toml")
    bad = tmp_path / "bad.toml"
    bad.write_bytes(b"\xff\xfe")
    with pytest.raises(RigFileError, match="not UTF-8"):
        rigfile.load(bad)


def test_rigfile_is_core_and_imports_no_twin():
    code = (
        "import sys\n"
        "for m in ('numba', 'pydantic', 'scipy', 'pandas', 'serial'): sys.modules[m] = None\n"
        "import helpers.rigfile, helpers.rigfile.firmware_header\n"
        "helpers.rigfile.default_rig()\n"
        "assert not any(m.startswith('helpers.virtual') for m in sys.modules), 'imports the twin'\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-1500:]


def test_dataclasses_are_frozen():
    rig = rigfile.default_rig()
    with pytest.raises(dataclasses.FrozenInstanceError):
        rig.hardware.travel_mm = 80.0  # type: ignore[misc]


def test_docs_name_every_key_and_macro():
    from helpers.base.paths import REPO_ROOT
    from helpers.rigfile import firmware_header, schema
    from helpers.virtual.spatial import rod_file

    doc = (REPO_ROOT / "docs" / "rig_file.md").read_text()
    keys = [
        k.name
        for table in (schema.TOP, schema.HARDWARE, schema.ARM, schema.BOARDS, schema.TENDON, rod_file.ROD)
        for k in table
    ]
    missing = [k for k in keys if f"`{k}`" not in doc]
    missing += [m for m in firmware_header.MACROS if f"`{m}`" not in doc]
    assert not missing, f"docs/rig_file.md does not document {missing}"


# --- the release below position 0 ([hardware] release_mm) ------------------------------------------------
FOUR_TEXT = (rigfile.RIGS_DIR / "four-tendon.toml").read_text()


def _with_release(value: str) -> str:
    return _edit(FOUR_TEXT, "release_mm", value)


def test_release_defaults_to_none_and_the_shipped_four_tendon_rigs_pay_out_78_steps():
    paper = rigfile.default_rig()
    assert "release_mm" not in PAPER_TEXT and paper.hardware.release_mm == 0.0
    assert rigfile.derived(paper).release_steps == (0,)
    # 20 mm / (pi 65 / 800 mm per step) = 20 / 0.2552544 = 78.35 steps, floored as the travel is
    for name in ("four-tendon", "hanging"):
        rig = rigfile.load(rigfile.resolve(name))
        assert rig.hardware.release_mm == 20.0
        assert rigfile.derived(rig).release_steps == (78, 78, 78, 78)
    assert rigfile.load(rigfile.resolve("long-arm")).hardware.release_mm == 0.0


def test_release_is_read_in_mm_and_floored_to_whole_steps():
    assert rigfile.derived(rigfile.loads(_with_release("20.0"))).release_steps == (78,) * 4
    assert rigfile.derived(rigfile.loads(_with_release("10"))).release_steps == (39,) * 4  # 39.18
    assert rigfile.derived(rigfile.loads(_with_release("0.0"))).release_steps == (0,) * 4
    assert (
        rigfile.derived(rigfile.loads(_with_release("0.2552544031041700"))).release_steps == (1,) * 4
    )  # one step


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("-1.0", "my.toml: [hardware] release_mm: must be >= 0 mm, got -1.0"),
        ('"20"', "my.toml: [hardware] release_mm: must be a number mm, got '20'"),
        (
            "0.1",
            "my.toml: [hardware] release_mm: 0.1 mm is less than one step (0.25525 mm): 0 means no "
            "paying out",
        ),
        ("5000.0", "my.toml: [hardware] release_mm: 5000.0 mm is outside the plausible 0-2000 mm"),
    ],
)
def test_a_nonsense_release_is_refused_in_one_line(value, message):
    assert _refusal(_with_release(value)).startswith(message)


def test_a_release_on_a_rig_of_one_tendon_is_refused():
    text = PAPER_TEXT.replace("travel_mm = 40.0", "travel_mm = 40.0\nrelease_mm = 20.0", 1)
    assert _refusal(text).startswith(
        "my.toml: [hardware] release_mm: 20 mm on a rig of one tendon: its position 0 is the end of its "
        "travel"
    )
    assert rigfile.loads(text.replace("release_mm = 20.0", "release_mm = 0.0")).hardware.release_mm == 0.0
