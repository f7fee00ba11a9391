"""Your own rig's firmware, built for real: ``make -C firmware RIG=relative.toml`` from the user's folder and
``python -m helpers rig firmware FILE``; what the boards cannot hold stopped by make in one line before
anything compiles; the host's RAM model (``helpers.rigfile.capacity``) against avr-size, and the firmware's
static assertions at the very boundary the host computes (one rule, one source).

The three-tendon rig here is the tests' own (tendons at 0, 120 and 240 degrees, in a temporary folder).
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import fwsim
import pytest

from helpers import rigfile
from helpers.rigfile import capacity

pytestmark = pytest.mark.firmware

FOUR = (fwsim.REPO / "rigs" / "four-tendon.toml").read_text()
PAPER = (fwsim.REPO / "rigs" / "paper.toml").read_text()
_RAM = re.compile(r"^ *(daq_mega|stepper_uno): .* (\d+) B RAM \(data \+ bss\)", re.M)


def _edit(text: str, key: str, value: str) -> str:
    out, n = re.subn(rf"(?m)^{key} = .*$", f"{key} = {value}", text)
    assert n == 1, key
    return out


def three_tendon(items: int) -> str:
    head, _, _ = FOUR.partition("[[tendon]]")
    text = head.replace('name = "four-tendon"', 'name = "three-tendon-test"')
    text += "".join(f"[[tendon]]\nangle_deg = {a}\n\n" for a in (0.0, 120.0, 240.0))
    return _edit(text, "programme_max_items", str(items))


def _make(cwd: Path, *args: str, timeout: float = 600) -> subprocess.CompletedProcess:
    """``make -C <repo>/firmware ARGS`` typed in ``cwd`` (a shell exports PWD: so does this)."""
    env = {"PATH": "/usr/bin:/bin", "PWD": str(cwd), "HOME": str(cwd)}
    return subprocess.run(
        ["make", "-C", str(fwsim.FIRMWARE), "-j2", f"PYTHON={sys.executable}", *args], cwd=cwd, env=env,
        capture_output=True, text=True, check=False, timeout=timeout,
    )  # fmt: skip


def _static_bytes(output: str) -> dict[str, int]:
    return {board: int(n) for board, n in _RAM.findall(output)}


def test_make_builds_a_relative_rig_path_at_the_largest_programme_the_host_allows(tmp_path: Path) -> None:
    """121 items of 9 bytes on three axes: (2048 - 557 - 320 - 77) // 9 = 121; the build's static assertions
    pass there, and the stepper's data + bss is the host's model to the byte."""
    (tmp_path / "three.toml").write_text(three_tendon(121))
    proc = _make(tmp_path, "RIG=three.toml", "BUILD=" + str(tmp_path / "build"), "firmware", "size")
    assert proc.returncode == 0, proc.stderr[-3000:]
    ram = _static_bytes(proc.stdout)
    rig = rigfile.load(tmp_path / "three.toml")
    model = capacity.stepper_ram(3, rigfile.derived(rig).min_interval_us, 121)
    assert model.tables_bytes == 121 * 9 + 77 and model.tables_bytes <= model.tables_max_bytes == 1171
    assert ram["stepper_uno"] == model.static_bytes == 121 * 9 + 77 + 557
    assert 0 < ram["daq_mega"] < 8192
    print(f"three tendons, 121 items: stepper {ram['stepper_uno']} B, DAQ {ram['daq_mega']} B of static RAM")
    header = (tmp_path / "build" / "rig_config.h").read_text()
    assert f'#define RIG_HASH "{rig.hash}"' in header and "#define RIG_PROGRAMME_MAX 121" in header


def test_rig_firmware_builds_from_where_the_user_stands(tmp_path: Path) -> None:
    """The paper's numbers at its largest programme (119 items): built by the command into --out."""
    (tmp_path / "mine.toml").write_text(_edit(PAPER, "programme_max_items", "119"))
    proc = subprocess.run(
        [sys.executable, "-m", "helpers", "rig", "firmware", "mine.toml", "--out", "fw"], cwd=tmp_path,
        env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(fwsim.REPO), "HOME": str(tmp_path)},
        capture_output=True, text=True, check=False, timeout=600,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (tmp_path / "fw" / "daq_mega.hex").stat().st_size > 0
    assert (tmp_path / "fw" / "stepper_uno.hex").stat().st_size > 0
    ram = _static_bytes(proc.stdout)  # the command prints the build's RAM lines
    assert ram["stepper_uno"] == capacity.stepper_ram(1, 639, 119).static_bytes == 119 * 7 + 353 + 77 + 460


@pytest.mark.parametrize(
    ("text", "start"),
    [(_edit(PAPER, "programme_max_items", "255"),
      "[hardware] programme_max_items: 255 items do not fit the stepper board"),
     (_edit(FOUR, "daq_baud", "9600"), "[hardware] daq_baud: 9600 baud cannot carry the DAQ's data lines"),
     (PAPER.replace("gravity_m_s2 = 9.81", "gravity_m_s2 = " + "[" * 5000 + "]" * 5000),
      "[arm] gravity_m_s2: arrays or inline tables nested 5000 deep"),
     (_edit(PAPER, "gravity_direction", "[1e308, 1e308, 0]"), "[arm] gravity_direction: must be a nonzero")],
    ids=["programme", "baud", "nesting", "overflow"],
)  # fmt: skip
def test_make_refuses_in_one_line_before_compiling(tmp_path: Path, text: str, start: str) -> None:
    (tmp_path / "bad.toml").write_text(text)
    build = tmp_path / "build"
    proc = _make(tmp_path, "RIG=bad.toml", f"BUILD={build}", "firmware")
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr, proc.stderr[-2000:]
    assert re.match(rf"Makefile:\d+: \*\*\* error: {re.escape(str(tmp_path / 'bad.toml'))}: ", proc.stderr)
    assert start in proc.stderr and proc.stderr.endswith(".  Stop.\n")
    assert not list(build.rglob("*.o")) and not (build / "rig_config.h").exists()


def test_make_names_where_it_looked_for_a_missing_rig_file(tmp_path: Path) -> None:
    proc = _make(tmp_path, "RIG=nope.toml", f"BUILD={tmp_path / 'build'}", "firmware")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1
    assert f"RIG=nope.toml: no such file (looked for {tmp_path}/nope.toml {fwsim.FIRMWARE}/nope.toml)" in (
        proc.stderr
    )


def _header_for(tmp_path: Path, text: str, **changes: str) -> Path:
    """The generated header of ``text``, with macros changed by hand (a config the host would not write)."""
    (tmp_path / "r.toml").write_text(text)
    header = tmp_path / "rig.h"
    generator = [sys.executable, "-m", "helpers.rigfile.firmware_header"]
    proc = subprocess.run(
        [*generator, str(tmp_path / "r.toml"), "-o", str(header)], cwd=fwsim.REPO, capture_output=True,
        text=True, check=False, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    body = header.read_text()
    for name, value in changes.items():
        body, n = re.subn(rf"(?m)^#define {name} .*$", f"#define {name} {value}", body)
        assert n == 1, name
    header.write_text(body)
    return header


def _compile(tmp_path: Path, header: Path, sketch: str) -> subprocess.CompletedProcess:
    build = tmp_path / "build"
    target = f"{build}/{sketch}/{sketch}.o"
    return _make(tmp_path, f"RIG_CONFIG={header}", f"BUILD={build}", target, timeout=300)


def test_the_firmware_refuses_one_item_past_the_hosts_limit(tmp_path: Path) -> None:
    """The host allows 121 items on three axes and refuses 122.

    A header forced to 122 items (with the host's own table size for them, 122 x 9 + 77 = 1175 > 1171) stops
    the compile at the sketch's assertion.
    """
    assert capacity.firmware_problem(rigfile.loads(three_tendon(122), "t.toml")).startswith(
        "[hardware] programme_max_items: 122 items do not fit"
    )
    header = _header_for(
        tmp_path, three_tendon(121), RIG_PROGRAMME_MAX="122", RIG_STEPPER_TABLES_BYTES=str(122 * 9 + 77)
    )
    proc = _compile(tmp_path, header, "stepper_uno")
    assert proc.returncode != 0 and "does not fit the Uno's RAM" in proc.stderr, proc.stderr[-2000:]
    assert "not the size helpers/rigfile/capacity.py computes" not in proc.stderr  # the model itself holds


def test_the_firmware_refuses_a_header_whose_ram_model_differs_from_its_tables(tmp_path: Path) -> None:
    header = _header_for(tmp_path, PAPER, RIG_STEPPER_TABLES_BYTES="879")  # the model says 878
    proc = _compile(tmp_path, header, "stepper_uno")
    assert proc.returncode != 0
    assert "not the size helpers/rigfile/capacity.py computes" in proc.stderr, proc.stderr[-2000:]


@pytest.mark.parametrize(("rate", "ok"), [(2309, True), (2310, False)])
def test_the_daq_conversion_rule_agrees_with_the_sketch(tmp_path: Path, rate: int, ok: bool) -> None:
    """Four channels take 4 x 104 + 16 = 432 us: the host allows 2309 Hz (1000000 // 2309 = 433) and refuses
    2310 (432); the DAQ sketch's static assertion draws the line at the same rate."""
    rig = rigfile.loads(_edit(FOUR, "daq_rate_max_hz", str(rate)), "f.toml")
    assert (capacity.firmware_problem(rig) is None) == ok
    header = _header_for(tmp_path, FOUR, RIG_DAQ_RATE_MAX_HZ=str(rate))
    proc = _compile(tmp_path, header, "daq_mega")
    assert (proc.returncode == 0) == ok, proc.stderr[-2000:]
    if not ok:
        assert "too many channels for the rate" in proc.stderr


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(p.name for p in (fwsim.REPO / "rigs").glob("*.toml")))
def test_every_shipped_rig_builds_and_prints_its_ram_budget(tmp_path: Path, name: str) -> None:
    """Both sketches build for each shipped rig file and print both RAM lines (the stepper's: the model's)."""
    proc = _make(fwsim.REPO / "rigs", f"RIG={name}", f"BUILD={tmp_path / 'build'}", "firmware", "size")
    assert proc.returncode == 0, proc.stderr[-3000:]
    ram = _static_bytes(proc.stdout)
    assert set(ram) == {"daq_mega", "stepper_uno"}
    rig = rigfile.load(fwsim.REPO / "rigs" / name)
    d = rigfile.derived(rig)
    model = capacity.stepper_ram(rig.n_tendons, d.min_interval_us, rig.hardware.programme_max_items)
    assert ram["stepper_uno"] == model.static_bytes
    print(f"{name}: stepper {ram['stepper_uno']} B, DAQ {ram['daq_mega']} B of static RAM")
