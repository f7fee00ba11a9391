"""``python -m helpers rig firmware FILE``: build, and upload, both boards' firmware for a rig file.

``FILE`` is a path from where you stand (or a shipped rig's name). The rig is checked first, the boards'
capacity included (``helpers.rigfile.capacity``): a rig they cannot hold is refused in one line, exit 2,
before anything is compiled. Then ``make -C firmware RIG=<absolute path> BUILD=<out>`` builds both sketches
against the header generated from it into ``--out`` (default ``firmware/build/rig-<name>-<hash>/``, which git
ignores) and prints each board's RAM budget. ``--upload --board daq|stepper --port PORT`` then flashes one
board with ``avrdude``; ``--dry-run`` prints the exact commands (``make``, ``avrdude``) and runs none.

Exit status: 0; 1 if the toolchain is missing or the build fails; 2 for a bad rig file, a rig the boards
cannot hold or a bad argument; 4 if the port is missing, not permitted, or ``avrdude`` fails on it.
"""

from __future__ import annotations

import argparse
import os
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from helpers import rigfile
from helpers.base.paths import REPO_ROOT
from helpers.rigfile import RigFile, capacity

__all__ = ["BOARDS", "Board", "add_arguments", "make_command", "avrdude_command", "missing_tools", "run"]

FIRMWARE_DIR: Path = REPO_ROOT / "firmware"
"""The repository's firmware (sketches, Makefile)."""

BUILD_PACKAGES = "gcc-avr avr-libc arduino-core-avr make"
"""The Debian packages that build the firmware (``firmware/README.md``)."""

NO_SUDO = "without sudo, ask an admin to install them"


@dataclass(frozen=True)
class Board:
    """One board: its sketch, the MCU and how its bootloader takes a new firmware (``firmware/Makefile``)."""

    sketch: str
    name: str
    mcu: str
    programmer: str
    baud: int


BOARDS: dict[str, Board] = {
    # The Mega 2560's stk500v2 bootloader, reset through DTR ("wiring"); the Uno's optiboot ("arduino"). Both
    # at 115200 baud, with -D (no chip erase first: the bootloaders erase each page as they write it), as the
    # Arduino IDE uploads them.
    "daq": Board("daq_mega", "Arduino Mega 2560", "atmega2560", "wiring", 115200),
    "stepper": Board("stepper_uno", "Arduino Uno", "atmega328p", "arduino", 115200),
}
"""``--board`` -> the board (the same avrdude options as ``make -C firmware upload-daq|upload-stepper``)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``rig firmware`` options."""
    parser.add_argument("file", help="the rig file: a path from here, or a shipped rig's name (paper, ...)")
    parser.add_argument(
        "--out", metavar="DIR", default=None,
        help="where the build goes (default: firmware/build/rig-NAME-HASH/, ignored by git)",
    )  # fmt: skip
    parser.add_argument("--upload", action="store_true", help="flash one board after the build (avrdude)")
    parser.add_argument(
        "--board", choices=sorted(BOARDS), help="with --upload: daq (Mega 2560) or stepper (Uno)"
    )
    parser.add_argument(
        "--port", metavar="PORT",
        help="with --upload: the board's serial port, e.g. /dev/ttyACM0 (ls -l /dev/serial/by-id/)",
    )  # fmt: skip
    parser.add_argument(
        "--dry-run", action="store_true", help="print the make and avrdude commands; run none"
    )


def default_out(rig: RigFile) -> Path:
    """The build folder of ``rig`` by default: ``firmware/build/rig-<name>-<hash>`` (git ignores it)."""
    return FIRMWARE_DIR / "build" / f"rig-{rig.name}-{rig.hash}"


def make_command(rig_path: Path, out: Path) -> list[str]:
    """The ``make`` command that builds both sketches for the rig file at ``rig_path`` into ``out``."""
    return [
        "make", "-C", str(FIRMWARE_DIR), f"RIG={rig_path}", f"BUILD={out}", f"PYTHON={sys.executable}",
        "firmware", "size",
    ]  # fmt: skip


def avrdude_command(board: Board, port: str, out: Path) -> list[str]:
    """The ``avrdude`` command that flashes ``board`` on ``port`` with the build in ``out``."""
    hex_file = out / f"{board.sketch}.hex"
    return [
        "avrdude", "-p", board.mcu, "-c", board.programmer, "-P", port, "-b", str(board.baud), "-D",
        "-U", f"flash:w:{hex_file}:i",
    ]  # fmt: skip


def missing_tools() -> list[str]:
    """The pieces of the build toolchain that are missing (empty when it is there)."""
    tools = ("make", "avr-gcc", "avr-g++", "avr-objcopy", "avr-size")
    missing = [t for t in tools if shutil.which(t) is None]
    core = Path("/usr/share/arduino/hardware/arduino/avr/cores/arduino/Arduino.h")
    if not core.exists():
        missing.append("arduino-core-avr")
    return missing


def _fail(line: str, status: int) -> int:
    print(f"error: {line}", file=sys.stderr)
    return status


def _port_problem(port: str) -> str | None:
    """Why ``port`` cannot be opened for an upload, or None."""
    if not os.path.exists(port):
        return (
            f"{port}: no such serial port (an Uno or a Mega shows as /dev/ttyACM*, a CH340 clone as "
            "/dev/ttyUSB*: ls -l /dev/serial/by-id/ or python -m serial.tools.list_ports -v)"
        )
    if not os.access(port, os.R_OK | os.W_OK):
        return (
            f"{port}: permission denied: add yourself to the dialout group (sudo usermod -aG dialout $USER, "
            "then log out and in; without sudo, ask an admin)"
        )
    return None


def run(args: argparse.Namespace) -> int:
    """Build (and upload) the firmware for ``args.file``; return the exit status."""
    if args.upload and (args.board is None or args.port is None):
        raise ValueError("--upload needs --board daq|stepper and --port PORT")
    if not args.upload and (args.board is not None or args.port is not None):
        raise ValueError("--board and --port go with --upload")
    rig_path = rigfile.resolve(args.file)
    rig = rigfile.load(rig_path)
    capacity.require_fit(rig)  # refused here, in one line, rather than by make
    out = (Path(args.out) if args.out is not None else default_out(rig)).absolute()
    rig_abs = rig_path.absolute()
    for what, path in (("the rig file's path", rig_abs), ("--out", out)):
        if any(c.isspace() for c in str(path)):
            raise ValueError(f"{path}: make cannot take {what} with a space in it; move or link it elsewhere")
    build = make_command(rig_abs, out)
    board = BOARDS[args.board] if args.upload else None
    upload = avrdude_command(board, args.port, out) if board is not None else None
    if args.dry_run:
        print(shlex.join(build))
        if upload is not None:
            print(shlex.join(upload))
        return 0
    if not (FIRMWARE_DIR / "Makefile").exists():
        return _fail(f"{FIRMWARE_DIR}: no firmware here; building needs the repository (a git clone)", 1)
    missing = missing_tools()
    if missing:
        return _fail(
            f"the firmware toolchain is missing ({', '.join(missing)}): sudo apt-get install -y "
            f"--no-install-recommends {BUILD_PACKAGES} ({NO_SUDO})",
            1,
        )
    proc = subprocess.run(build, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        lines = [ln for ln in (proc.stderr + proc.stdout).splitlines() if ln.strip()]
        why = next((ln for ln in lines if "***" in ln or "error" in ln.lower()), lines[-1] if lines else "")
        return _fail(f"the build failed (make exit status {proc.returncode}): {why.strip()}", 1)
    print(f"firmware for rig {rig.name} (hash {rig.hash}, {rig_path}) in {out}:")
    for line in proc.stdout.splitlines():
        if line.startswith(("daq_mega:", "stepper_uno:")):
            print(f"  {line}")
    for key, b in BOARDS.items():
        print(f"  {out / (b.sketch + '.hex')}: the {key} board ({b.name})")
    if upload is None:
        print(f"upload: python -m helpers rig firmware {args.file} --upload --board daq|stepper --port PORT")
        return 0
    if shutil.which("avrdude") is None:
        return _fail(f"avrdude is not installed: sudo apt-get install avrdude ({NO_SUDO})", 1)
    problem = _port_problem(args.port)
    if problem is not None:
        return _fail(problem, 4)
    print(shlex.join(upload))
    proc = subprocess.run(upload, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        lines = [ln.strip() for ln in (proc.stderr + proc.stdout).splitlines() if ln.strip()]
        return _fail(
            f"avrdude failed on {args.port} (exit status {proc.returncode}): {lines[-1] if lines else '?'}; "
            f"is the {board.name} on that port (--board {args.board})?",
            4,
        )
    print(f"flashed the {board.name} on {args.port}: it now reports rig {rig.name}, hash {rig.hash}")
    return 0
