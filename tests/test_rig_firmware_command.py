"""``python -m helpers rig firmware FILE``: the rig file from where the user stands, the exact make and
avrdude commands (dry run), the refusals, and an upload through stand-in ``make`` and ``avrdude`` programs (no
toolchain or board needed here; tests/firmware/test_rig_firmware_fw.py builds for real).

The avrdude options are written here by hand from the boards' bootloaders (the Mega 2560's stk500v2,
``-c wiring``; the Uno's optiboot, ``-c arduino``; both 115200 baud, ``-D``: avrdude's manual, "-D Disable
auto erase for flash memory") and compared with the Makefile's own upload recipes.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from helpers.commands import rig_firmware

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "rigs" / "paper.toml"
FIRMWARE = ROOT / "firmware"


def _run(argv: list[str], cwd: Path, path: str = "/usr/bin:/bin") -> subprocess.CompletedProcess:
    env = {"PATH": path, "PYTHONPATH": str(ROOT), "HOME": str(cwd)}
    return subprocess.run(
        [sys.executable, "-m", "helpers", "rig", "firmware", *argv], cwd=cwd, env=env, capture_output=True,
        text=True, timeout=300,
    )  # fmt: skip


@pytest.fixture
def my_rig(tmp_path: Path) -> tuple[Path, str]:
    """A user's rig file in the folder they stand in (the paper's numbers, another name)."""
    text = PAPER.read_text().replace('name = "paper"', 'name = "mine"')
    (tmp_path / "my_rig.toml").write_text(text)
    return tmp_path, hashlib.sha256(text.encode()).hexdigest()[:8]


@pytest.mark.parametrize(
    ("board", "port", "avrdude"),
    [("daq", "/dev/ttyACM0",
      "avrdude -p atmega2560 -c wiring -P /dev/ttyACM0 -b 115200 -D -U flash:w:{out}/daq_mega.hex:i"),
     ("stepper", "/dev/ttyACM1",
      "avrdude -p atmega328p -c arduino -P /dev/ttyACM1 -b 115200 -D -U flash:w:{out}/stepper_uno.hex:i")],
)  # fmt: skip
def test_dry_run_prints_the_exact_commands_for_a_relative_path(my_rig, board, port, avrdude):
    here, digest = my_rig
    proc = _run(["my_rig.toml", "--upload", "--board", board, "--port", port, "--dry-run"], cwd=here)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    out = FIRMWARE / "build" / f"rig-mine-{digest}"  # the default: an ignored folder of the repository
    assert proc.stdout.splitlines() == [
        f"make -C {FIRMWARE} RIG={here / 'my_rig.toml'} BUILD={out} PYTHON={sys.executable} firmware size",
        avrdude.format(out=out),
    ]
    assert not out.exists()  # a dry run builds nothing


def test_dry_run_with_out_and_without_upload(my_rig):
    here, _ = my_rig
    (here / "sub").mkdir()
    proc = _run(["../my_rig.toml", "--out", "builds/mine", "--dry-run"], cwd=here / "sub")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines() == [
        f"make -C {FIRMWARE} RIG={here / 'sub' / '..' / 'my_rig.toml'} "
        f"BUILD={here / 'sub' / 'builds' / 'mine'} PYTHON={sys.executable} firmware size"
    ]


@pytest.mark.skipif(shutil.which("make") is None, reason="needs make (Debian package make)")
@pytest.mark.parametrize("board", ["daq", "stepper"])
def test_the_makefile_uploads_with_the_same_avrdude_command(tmp_path, board):
    build = tmp_path / "build"
    proc = subprocess.run(
        ["make", "-n", "-C", str(FIRMWARE), f"BUILD={build}", "PORT=/dev/ttyX", f"upload-{board}"],
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    recipe = [ln.split() for ln in proc.stdout.splitlines() if ln.startswith("avrdude ")]
    assert recipe == [rig_firmware.avrdude_command(rig_firmware.BOARDS[board], "/dev/ttyX", build)]


def test_a_rig_the_boards_cannot_hold_is_refused_before_make(my_rig):
    here, _ = my_rig
    text = (here / "my_rig.toml").read_text().replace("programme_max_items = 64", "programme_max_items = 255")
    (here / "my_rig.toml").write_text(text)
    proc = _run(["my_rig.toml", "--dry-run"], cwd=here)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.count("\n") == 1
    assert proc.stderr.startswith("error: my_rig.toml: [hardware] programme_max_items: 255 items do not")


@pytest.mark.parametrize(
    ("argv", "message"),
    [(["--upload", "--port", "/dev/ttyACM0"], "error: --upload needs --board daq|stepper and --port PORT"),
     (["--board", "daq"], "error: --board and --port go with --upload"),
     (["--upload", "--board", "uno", "--port", "/dev/ttyACM0"], "invalid choice: 'uno'")],
)  # fmt: skip
def test_bad_arguments_are_one_line(my_rig, argv, message):
    here, _ = my_rig
    proc = _run(["my_rig.toml", *argv, "--dry-run"], cwd=here)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and message in proc.stderr, proc.stderr


def _stand_ins(folder: Path, avrdude_status: int = 0) -> Path:
    """``make`` and ``avrdude`` programs that log their arguments.

    The stand-in make writes the two hex files and prints RAM lines as the Makefile does.
    """
    bin_dir = folder / "bin"
    bin_dir.mkdir()
    log = folder / "log.txt"
    make = (
        "#!/bin/sh\n"
        f'echo "make $*" >> {log}\n'
        'for a in "$@"; do case "$a" in BUILD=*) out="${a#BUILD=}";; esac; done\n'
        'mkdir -p "$out" && touch "$out/daq_mega.hex" "$out/stepper_uno.hex"\n'
        "echo 'daq_mega: 6282 B flash (2.4% Full), 1525 B RAM (data + bss) of 8192 B'\n"
        "echo 'stepper_uno: 14608 B flash (44.6% Full), 1338 B RAM (data + bss) of 2048 B'\n"
    )
    avrdude = (
        f'#!/bin/sh\necho "avrdude $*" >> {log}\n'
        "echo 'avrdude: stk500v2_getsync(): timeout communicating with programmer' >&2\n"
        f"exit {avrdude_status}\n"
    )
    for name, text in (("make", make), ("avrdude", avrdude)):
        (bin_dir / name).write_text(text)
        (bin_dir / name).chmod(0o755)
    for tool in ("avr-gcc", "avr-g++", "avr-objcopy", "avr-size"):  # present, never run
        (bin_dir / tool).write_text("#!/bin/sh\nexit 1\n")
        (bin_dir / tool).chmod(0o755)
    return bin_dir


@pytest.mark.skipif(
    not Path("/usr/share/arduino/hardware/arduino/avr/cores/arduino/Arduino.h").exists(),
    reason="the command checks for Debian's arduino-core-avr (package arduino-core-avr)",
)
def test_build_then_upload_through_stand_ins(my_rig):
    here, digest = my_rig
    bin_dir = _stand_ins(here)
    port = here / "ttyACM7"
    port.write_text("")  # a file stands in for the serial port
    proc = _run(
        ["my_rig.toml", "--out", "out", "--upload", "--board", "stepper", "--port", str(port)], cwd=here,
        path=f"{bin_dir}:/usr/bin:/bin",
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    out = here / "out"
    avrdude = f"avrdude -p atmega328p -c arduino -P {port} -b 115200 -D -U flash:w:{out}/stepper_uno.hex:i"
    assert (here / "log.txt").read_text().splitlines() == [
        f"make -C {FIRMWARE} RIG={here / 'my_rig.toml'} BUILD={out} PYTHON={sys.executable} firmware size",
        avrdude,
    ]
    lines = proc.stdout.splitlines()
    assert lines[0] == f"firmware for rig mine (hash {digest}, my_rig.toml) in {out}:"
    assert lines[1].startswith("  daq_mega: 6282 B flash") and lines[2].startswith("  stepper_uno: 14608 B")
    assert avrdude in lines
    assert lines[-1] == f"flashed the Arduino Uno on {port}: it now reports rig mine, hash {digest}"


def test_a_failed_upload_and_a_missing_port_are_one_line_exit_4(my_rig):
    here, _ = my_rig
    bin_dir = _stand_ins(here, avrdude_status=1)
    port = here / "ttyACM7"
    port.write_text("")
    path = f"{bin_dir}:/usr/bin:/bin"
    argv = ["my_rig.toml", "--out", "out", "--upload", "--board", "daq", "--port"]  # nothing into the repo
    proc = _run([*argv, str(port)], cwd=here, path=path)
    assert proc.returncode == 4 and proc.stderr.count("\n") == 1, proc.stderr
    assert proc.stderr == (
        f"error: avrdude failed on {port} (exit status 1): avrdude: stk500v2_getsync(): timeout "
        "communicating with programmer; is the Arduino Mega 2560 on that port (--board daq)?\n"
    )
    proc = _run([*argv, "/dev/ttyACM99"], cwd=here, path=path)
    assert proc.returncode == 4 and proc.stderr.count("\n") == 1
    assert proc.stderr.startswith("error: /dev/ttyACM99: no such serial port")
    assert "ls -l /dev/serial/by-id/ or python -m serial.tools.list_ports -v" in proc.stderr


def test_a_port_without_permission_names_the_dialout_group(monkeypatch, tmp_path):
    port = tmp_path / "ttyACM0"
    port.write_text("")
    monkeypatch.setattr(os, "access", lambda path, mode: False)
    problem = rig_firmware._port_problem(str(port))
    assert problem == (
        f"{port}: permission denied: add yourself to the dialout group (sudo usermod -aG dialout $USER, then "
        "log out and in; without sudo, ask an admin)"
    )


def test_a_missing_toolchain_names_the_debian_packages(my_rig):
    here, _ = my_rig
    empty = here / "empty"
    empty.mkdir()
    (empty / "make").symlink_to(shutil.which("make") or "/bin/false")
    proc = _run(["my_rig.toml"], cwd=here, path=str(empty))
    assert proc.returncode == 1 and proc.stderr.count("\n") == 1, proc.stderr
    missing = "(avr-gcc, avr-g++, avr-objcopy, avr-size"
    assert proc.stderr.startswith(f"error: the firmware toolchain is missing {missing}")
    packages = "gcc-avr avr-libc arduino-core-avr make"
    assert f"sudo apt-get install -y --no-install-recommends {packages}" in proc.stderr
    assert "without sudo, ask an admin" in proc.stderr
