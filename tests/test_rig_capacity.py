"""What the boards cannot hold, and malformed rig files: refused in one line naming file, table and key.

The expected numbers are worked by hand here from the firmware's structures (``stepper_uno.ino``'s ``Item``
and ``StreamMem``, ``stream_plan.h``'s ``Planner``, ``SpAxis``, ``SpShaper``; avr-gcc packs them byte by byte)
and from ``firmware/PROTOCOL.md``'s data line; the firmware tests (``tests/firmware/test_rig_firmware_fw.py``)
check the same model against real builds. The command line runs in a subprocess where its exit status and its
single line on stderr are the point.
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from helpers import rigfile
from helpers.rigfile import RigFileError, capacity, schema
from helpers.rigfile.model import _deepest

ROOT = Path(__file__).resolve().parents[1]
PAPER = (ROOT / "rigs" / "paper.toml").read_text()
FOUR = (ROOT / "rigs" / "four-tendon.toml").read_text()


def _edit(text: str, key: str, value: str) -> str:
    lines = text.splitlines(keepends=True)
    hits = [i for i, ln in enumerate(lines) if ln.split("=")[0].strip() == key]
    assert len(hits) == 1, key
    lines[hits[0]] = f"{key} = {value}\n"
    return "".join(lines)


def three_tendon(**changes: str) -> str:
    """A three-tendon rig (0/120/240 deg) from the four-tendon file (the tests' own; not shipped)."""
    head, _, _ = FOUR.partition("[[tendon]]")
    text = head.replace('name = "four-tendon"', 'name = "three-tendon-test"')
    text += "".join(f"[[tendon]]\nangle_deg = {a}\n\n" for a in (0.0, 120.0, 240.0))
    for key, value in changes.items():
        text = _edit(text, key, value)
    return text


def _cli(*argv: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, *argv], cwd=cwd, capture_output=True, text=True, timeout=300,
        env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT), "HOME": str(cwd)},
    )  # fmt: skip


def _one_line(proc: subprocess.CompletedProcess) -> str:
    assert proc.returncode == 2, (proc.returncode, proc.stderr[-2000:])
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr[-2000:]
    return proc.stderr.strip()


# --- the stepper's RAM ------------------------------------------------------------------------------------
def test_stepper_ram_of_the_shipped_configs_by_hand():
    # one axis, 639 us (10000 // 639 + 1 = 16 steps per period: 32-step queues), 128 periods of history:
    # Planner 4 + 9 + 2 x 128 = 269; StreamMem 269 + 2 x 32 + 32 / 8 + 2 x 8 = 353; Item 4 + 1 + 1 + 1 = 7;
    # tables 64 x 7 + 353 + 77 (SpShaper) = 878; RAM left 2048 - 460 - 320 = 1268; items (1268 - 430) // 7
    paper = capacity.stepper_ram(1, 639, 64)
    assert (paper.item_bytes, paper.stream_bytes, paper.tables_bytes) == (7, 353, 878)
    assert (paper.tables_max_bytes, paper.max_items, paper.static_bytes) == (1268, 119, 1338)
    # four axes: Planner 4 + 36 + 2 x 4 x 64 = 552; StreamMem 552 + 256 + 16 + 64 = 888; Item 10; the
    # programme (640) shares the stream's RAM: max(640, 888) + 77 = 965; left 2048 - 575 - 320 = 1153
    four = capacity.stepper_ram(4, 639, 64)
    assert (four.item_bytes, four.stream_bytes, four.tables_bytes) == (10, 888, 965)
    assert (four.tables_max_bytes, four.max_items) == (1153, (1153 - 77) // 10)
    # the long arm's 524 us: 10000 // 524 + 1 = 20 steps a period, 64-step queues: 269 + 128 + 8 + 16 = 421
    long_arm = capacity.stepper_ram(1, 524, 64)
    assert (long_arm.stream_bytes, long_arm.tables_bytes, long_arm.max_items) == (421, 946, (1268 - 498) // 7)
    assert capacity.stepper_ram(1, 626, 1).stream_bytes == 353  # 10000 // 626 + 1 = 16
    assert capacity.stepper_ram(1, 625, 1).stream_bytes == 421  # 10000 // 625 + 1 = 17
    # three axes: Planner 4 + 27 + 384 = 415; StreamMem 415 + 192 + 12 + 48 = 667; Item 9; left 1171
    three = capacity.stepper_ram(3, 639, 121)
    assert (three.stream_bytes, three.tables_bytes, three.tables_max_bytes) == (667, 121 * 9 + 77, 1171)
    assert three.fits and not capacity.stepper_ram(3, 639, 122).fits


@pytest.mark.parametrize(
    ("text", "items", "fit"),
    [(PAPER, 119, True), (PAPER, 120, False), (three_tendon(), 121, True), (three_tendon(), 122, False),
     (FOUR, 107, True), (FOUR, 108, False)],
)  # fmt: skip
def test_programme_length_at_the_boundary_of_the_uno_ram(text, items, fit):
    rig = rigfile.loads(_edit(text, "programme_max_items", str(items)), source="r.toml")
    problem = capacity.firmware_problem(rig)
    if fit:
        assert problem is None
    else:
        assert problem.startswith(f"[hardware] programme_max_items: {items} items do not fit the stepper")
        assert f"at most {items - 1} (" in problem


def test_programme_max_items_255_is_refused_by_rig_check_and_the_header_generator(tmp_path):
    (tmp_path / "my_rig.toml").write_text(_edit(PAPER, "programme_max_items", "255"))
    expected = (
        "error: my_rig.toml: [hardware] programme_max_items: 255 items do not fit the stepper board (Arduino "
        "Uno, 2048 B of RAM) with 1 axis: at most 119 (7 B per item; the stream's state 353 B, the shaper 77 "
        "B, the rest of the sketch 460 B and 320 B of stack; the table's index is 8 bits)"
    )
    assert _one_line(_cli("-m", "helpers", "rig", "check", "my_rig.toml", cwd=tmp_path)) == expected
    header = _cli("-m", "helpers.rigfile.firmware_header", "my_rig.toml", "-o", "h.h", cwd=tmp_path)
    assert _one_line(header) == expected and not (tmp_path / "h.h").exists()


def test_four_axes_with_64_step_queues_leave_no_room_for_a_programme():
    # the long arm's spool and steps on four tendons: 0.0785398 mm per step at 150 mm/s is 1909.9 steps/s,
    # a step every 524 us: 64-step queues, a stream state of 552 + 512 + 32 + 64 = 1160 B, + 77 > 1153
    text = _edit(_edit(FOUR, "spool_diameter_mm", "40.0"), "steps_per_rev", "1600")
    text = _edit(_edit(_edit(text, "speed_limit_mm_s", "150.0"), "travel_mm", "19.0"), "release_mm", "0.0")
    problem = capacity.firmware_problem(rigfile.loads(text, source="r.toml"))
    assert problem.startswith("[hardware] speed_limit_mm_s: with 4 axes and a fastest step of 524 us")
    # at most 0.0785398 x 1e6 / 626 = 125.46 mm/s, floored to 0.1; the rig at that speed fits
    assert "(1160 B:" in problem and "at least 626 us (at most 125.4 mm/s)" in problem
    slower = rigfile.loads(_edit(text, "speed_limit_mm_s", "125.4"), "r.toml")
    assert capacity.firmware_problem(slower) is None


# --- the DAQ ----------------------------------------------------------------------------------------------
def test_longest_data_lines_by_hand():
    # D, + seq (600 s x 2000 Hz = 1200000: 7) + , + t_us (10) + ,1023 + ,-156 + *hh\n = 2+7+1+10+5+5+4 = 34
    paper = rigfile.default_rig()
    d = rigfile.derived(paper)
    assert capacity.daq_line_bytes(paper, d.travel_steps, d.release_steps) == 34
    # four channels and four axes (-234: 156 of travel and 78 below rest): 2+7+1+10 + 4 x 5 + 4 x 5 + 4 = 64,
    # PROTOCOL.md's "worst inside the fields' ranges"
    four = rigfile.loads(FOUR)
    d4 = rigfile.derived(four)
    assert capacity.daq_line_bytes(four, d4.travel_steps, d4.release_steps) == 64
    link = capacity.daq_link(four, d4.travel_steps, d4.release_steps)
    assert (link.bits_per_s, link.share, link.max_rate_hz) == (640_000, 0.64, 1406)  # 900000 // 640


def test_a_four_tendon_rig_at_9600_baud_is_refused(tmp_path):
    (tmp_path / "slow.toml").write_text(_edit(FOUR, "daq_baud", "9600"))
    line = _one_line(_cli("-m", "helpers", "rig", "check", "slow.toml", cwd=tmp_path))
    assert line == (
        "error: slow.toml: [hardware] daq_baud: 9600 baud cannot carry the DAQ's data lines: 4 load cells "
        "and 4 step counts make lines of up to 64 bytes, 640000 bit/s at daq_rate_default_hz = 1000 Hz (10 "
        "bits per byte), 6667 % of the line (at most 90 %): at least 711112 baud (500000, 1000000 and "
        "2000000 are exact at 16 MHz)"
    )


def test_line_rate_at_the_boundary_of_the_margin():
    # the paper's 340000 bit/s within 90 %: at least ceil(340000 / 0.9) = 377778 baud
    assert math.ceil(340_000 / 0.9) == 377_778
    ok = rigfile.loads(_edit(PAPER, "daq_baud", "377778"), source="r.toml")
    assert capacity.firmware_problem(ok) is None
    slow = rigfile.loads(_edit(PAPER, "daq_baud", "377777"), source="r.toml")
    assert capacity.firmware_problem(slow).startswith("[hardware] daq_baud: 377777 baud cannot carry")
    # at a default rate of 500 Hz the same link carries four channels' 320000 bit/s at 500000 baud (64 %)
    half = rigfile.loads(_edit(_edit(FOUR, "daq_baud", "500000"), "daq_rate_default_hz", "500"), "r.toml")
    assert capacity.firmware_problem(half) is None


def test_the_daq_converts_its_channels_within_one_sample_period():
    # the DAQ sketch: CHANNELS x 104 + 16 < 1000000 / RATE_MAX (integer division); four channels: 432 us, so
    # 1000000 // 2309 = 433 passes and 1000000 // 2310 = 432 does not
    assert [capacity.daq_max_rate_for_channels(c) for c in (1, 2, 3, 4)] == [8264, 4444, 3039, 2309]
    assert capacity.firmware_problem(rigfile.loads(_edit(FOUR, "daq_rate_max_hz", "2309"), "r.toml")) is None
    problem = capacity.firmware_problem(rigfile.loads(_edit(FOUR, "daq_rate_max_hz", "2310"), "r.toml"))
    assert problem.startswith("[hardware] daq_rate_max_hz: 2310 Hz: the DAQ board converts its 4 channels")
    assert "at most 2309 Hz" in problem


@pytest.mark.parametrize(
    ("key", "value", "start"),
    [("max_dwell_ms", "60001", "[hardware] max_dwell_ms: 60001 ms: the stepper board's WAIT takes at most"),
     ("adc_bits", "12", "[hardware] adc_bits: 12: the DAQ board's ADC (ATmega2560) has 10 bits"),
     ("stepper_baud", "2000001", "[hardware] stepper_baud: 2000001 baud: the boards' 16 MHz UART runs at"),
     ("daq_rate_max_hz", "4001", "[hardware] daq_rate_*_hz: the DAQ board samples at 31-4000 Hz")],
)  # fmt: skip
def test_other_limits_of_the_boards(key, value, start):
    problem = capacity.firmware_problem(rigfile.loads(_edit(PAPER, key, value), source="r.toml"))
    assert problem is not None and problem.startswith(start), problem
    assert capacity.firmware_problem(rigfile.default_rig()) is None


def test_every_shipped_rig_fits_the_boards():
    for path in sorted((ROOT / "rigs").glob("*.toml")):
        assert capacity.firmware_problem(rigfile.load(path)) is None, path.name


# --- malformed files --------------------------------------------------------------------------------------
DEEP = "[" * 5000 + "]" * 5000


@pytest.mark.parametrize(
    ("text", "expected"),
    [(PAPER.replace("gravity_m_s2 = 9.81", f"gravity_m_s2 = {DEEP}"),
      "error: bad.toml: [arm] gravity_m_s2: arrays or inline tables nested 5000 deep (line {line}): a rig "
      "file nests at most one (gravity_direction)"),
     (PAPER.replace("description = ", f"nest = {DEEP}\ndescription = "),
      "error: bad.toml: nest: arrays or inline tables nested 5000 deep (line {line}): a rig file nests at "
      "most one (gravity_direction)"),
     (_edit(PAPER, "gravity_direction", "[1e308, 1e308, 0]"),
      "error: bad.toml: [arm] gravity_direction: must be a nonzero vector of three numbers of at most 1e+06 "
      "in magnitude, got [1e+308, 1e+308, 0]"),
     (_edit(PAPER, "daq_baud", "99999999999999999999"),
      "error: bad.toml: [hardware] daq_baud: 99999999999999999999 is beyond TOML's 64-bit integers"),
     (_edit(PAPER, "spool_diameter_mm", "1" + "0" * 400),
      "error: bad.toml: [hardware] spool_diameter_mm: 1{digits} is beyond TOML's 64-bit integers")],
    ids=["deep value", "deep unknown key", "gravity overflow", "int beyond 64 bits", "int beyond a float"],
)  # fmt: skip
def test_malformed_files_give_one_line_from_rig_check_and_the_header_generator(tmp_path, text, expected):
    (tmp_path / "bad.toml").write_text(text)
    line_no = 1 + text[: text.find("[[[[")].count("\n")  # the line where the deep value starts
    expected = expected.replace("{line}", str(line_no))
    head, _, tail = expected.partition("{digits}")
    for proc in (
        _cli("-m", "helpers", "rig", "check", "bad.toml", cwd=tmp_path),
        _cli("-m", "helpers.rigfile.firmware_header", "bad.toml", "-o", "h.h", cwd=tmp_path),
    ):
        line = _one_line(proc)
        assert line.startswith(head) and line.endswith(tail) and len(line) < 240, line  # a 401-digit value
        assert line == expected or "{digits}" in expected  # shown shortened
    assert not (tmp_path / "h.h").exists()


def test_deep_nesting_in_a_tendon_table_names_it():
    text = FOUR.replace("angle_deg = 180.0", "angle_deg = 180.0\noffset_mm = {a = " + DEEP + "}", 1)
    with pytest.raises(RigFileError) as err:
        rigfile.loads(text, source="f.toml")
    line = str(err.value)
    assert line.startswith("f.toml: [[tendon]] #3 offset_mm: arrays or inline tables nested 5001 deep (line ")
    assert "\n" not in line


def test_nesting_is_located_past_strings_and_comments():
    text = (
        'name = "a [[[ b"  # [[[[\n'
        "s = '''\n[[[[[[\n'''\n"
        '[hardware]\nt = """ \\""" [[[[ """\n'
        "x = [[1], [2, [3]]]\n"
        "[[tendon]]\n[[tendon]]\ny = [{a = [1]}]\n"
    )
    assert _deepest(text) == ("[hardware] x", 3, 7)
    assert _deepest(text.replace("[[1], [2, [3]]]", "1")) == ("[[tendon]] #2 y", 3, 10)


TABLES = (("hardware", schema.HARDWARE), ("arm", schema.ARM), ("tendon", schema.TENDON))
NUMBERS = [(table, key) for table, keys in TABLES for key in keys if key.kind in ("float", "int")]
EXTREMES = ["1e308", "-1e308", "5e-324", "nan", "inf", "-inf", str(2**63 - 1), str(-(2**63)), str(2**64), "0"]


@pytest.mark.parametrize(("table", "key"), NUMBERS, ids=[f"{t}.{k.name}" for t, k in NUMBERS])
def test_extreme_numbers_are_refused_in_one_line_or_accepted(table, key):
    """Every number key at the extremes of floats and integers: a rig value (and the boards' verdict) or one
    RigFileError line, never another exception."""
    for value in EXTREMES:
        if table == "tendon":
            text = FOUR.replace("angle_deg = 90.0", f"angle_deg = 90.0\n{key.name} = {value}", 1)
            if key.name == "angle_deg":
                text = FOUR.replace("angle_deg = 90.0", f"angle_deg = {value}", 1)
        else:
            text = PAPER
            if f"\n{key.name} = " not in PAPER:  # a key the paper's file leaves to its default
                text = PAPER.replace(f"[{table}]\n", f"[{table}]\n{key.name} = 1\n")
            text = _edit(text, key.name, value)
        try:
            rig = rigfile.loads(text, source="x.toml")
        except RigFileError as exc:
            assert "\n" not in str(exc) and str(exc).startswith("x.toml: "), str(exc)
            continue
        try:
            capacity.require_fit(rig)
        except RigFileError as exc:
            assert "\n" not in str(exc) and str(exc).startswith("x.toml: [hardware] "), str(exc)
