"""Run the firmware ELF files in simavr through ``firmware/build/simavr_harness`` (see firmware/README.md).

Everything here is test support: it writes the harness's input files, runs it, and parses what it logged.
The checksum is the table-free reference CRC of ``tests/crc_reference.py`` (anchored to published catalogue
check values), independent of ``helpers.rig`` and of the firmware's table-driven CRC.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests"))  # for crc_reference, shared with the host-side tests

from crc_reference import link_hex  # noqa: E402

FIRMWARE = REPO / "firmware"
BUILD = FIRMWARE / "build"
HARNESS = BUILD / "simavr_harness"
F_CPU = 16_000_000
MCU = {"daq": "atmega2560", "stepper": "atmega328p"}
ELF = {"daq": BUILD / "daq_mega.elf", "stepper": BUILD / "stepper_uno.elf"}
VREF_MV = 5000

APT_PACKAGES = "gcc-avr avr-libc arduino-core-avr simavr libsimavr-dev"
INSTALL_HINT = f"apt-get install -y --no-install-recommends {APT_PACKAGES} make gcc"


def missing_toolchain() -> list[str]:
    """Names of the missing pieces of the firmware toolchain (empty when everything is there)."""
    missing = [
        tool for tool in ("make", "gcc", "avr-gcc", "avr-g++", "avr-objcopy") if shutil.which(tool) is None
    ]
    files = {
        "avr-libc (avr/io.h)": "/usr/lib/avr/include/avr/io.h",
        "arduino-core-avr": "/usr/share/arduino/hardware/arduino/avr/cores/arduino/Arduino.h",
        "libsimavr-dev (simavr/sim_avr.h)": "/usr/include/simavr/sim_avr.h",
    }
    missing += [name for name, path in files.items() if not Path(path).exists()]
    libdirs = ["/usr/lib", "/usr/lib64", "/usr/local/lib"] + [
        str(p) for p in Path("/usr/lib").glob("*-linux-gnu*")
    ]
    if not any(Path(d, lib).exists() for d in libdirs for lib in ("libsimavr.so", "libsimavr.a")):
        missing.append("libsimavr")
    return missing


def checksum(body: bytes) -> str:
    """The CRC-8 of PROTOCOL.md of the bytes, two upper-case hex digits (the reference implementation)."""
    return link_hex(body)


def with_checksum(body: str) -> str:
    """``body*hh`` (no newline)."""
    return f"{body}*{checksum(body.encode('ascii'))}"


def command(body: str) -> bytes:
    """A command line as a host sends it: ``body*hh\\n`` (every command must carry its checksum)."""
    return (with_checksum(body) + "\n").encode("ascii")


def _escape(data: bytes) -> str:
    out = []
    for b in data:
        c = chr(b)
        if c == "\\":
            out.append("\\\\")
        elif 0x20 <= b < 0x7F:
            out.append(c)
        else:
            out.append(f"\\x{b:02x}")
    return "".join(out)


@dataclass
class Line:
    """One line a board sent: the cycle count at its ``\\n``, the body, and whether its checksum is right."""

    cycle: int
    raw: str
    body: str
    checksum_ok: bool

    @property
    def t(self) -> float:
        """Simulated time (s) at the line's end."""
        return self.cycle / F_CPU


@dataclass
class SimRun:
    """What one harness run produced."""

    lines: list[Line]
    pins: list[tuple[int, str, int]] = field(default_factory=list)
    adc: list[tuple[int, int]] = field(default_factory=list)
    stderr: str = ""

    def bodies(self) -> list[str]:
        """The bodies of all lines, in order."""
        return [ln.body for ln in self.lines]

    def replies(self) -> list[Line]:
        """All lines except data lines and overrun warnings."""
        return [ln for ln in self.lines if not ln.body.startswith(("D,", "W,"))]

    def data(self) -> list[tuple[int, int, int, int]]:
        """Data lines as (seq, t_us, adc, steps)."""
        out = []
        for ln in self.lines:
            if ln.body.startswith("D,"):
                seq, t_us, adc, steps = ln.body.split(",")[1:]
                out.append((int(seq), int(t_us), int(adc), int(steps)))
        return out

    def overruns(self) -> list[int]:
        """The ``n`` of every ``W,OVERRUN,<n>`` line."""
        return [int(ln.body.split(",")[2]) for ln in self.lines if ln.body.startswith("W,OVERRUN,")]


_LINE = re.compile(r"(\d+) (.*)")


def run(
    board: str,
    script: Iterable[tuple[float, bytes | str]],
    duration: float,
    *,
    wave: Sequence[tuple[float, ...]] | None = None,
    edges: Sequence[tuple[float, str, int]] | None = None,
    watch: Sequence[str] = (),
    timeout: float = 300.0,
    elf: Path | None = None,
) -> SimRun:
    """Run one board's firmware in simavr.

    Parameters
    ----------
    board : {"daq", "stepper"}
    script : iterable of (t_s, bytes)
        Bytes sent to the UART at simulated time ``t_s`` (str is encoded as ASCII; nothing is appended).
    duration : float
        Simulated seconds to run.
    wave : sequence of (t_s, mV) or (t_s, mV0, mV1, ...), optional
        ADC0 input (ADC0, ADC1, ... with more columns), piecewise linear. The ADC log then holds
        ``(cycle, mV)`` per conversion, or ``(cycle, (mV0, mV1, ...))`` with several columns.
    edges : sequence of (t_s, "E4", level), optional
        Input pin levels to apply at the given times.
    watch : sequence of str
        Output pins to log, e.g. ``("D5", "D6", "D7")``.
    elf : Path, optional
        Another build of the board's firmware (e.g. for another rig config) instead of ``ELF[board]``.
    """
    with tempfile.TemporaryDirectory(prefix="fwsim-") as tmp:
        tmpd = Path(tmp)
        args = [str(HARNESS), "-m", MCU[board], "-d", f"{duration:.9f}", "-T"]
        script_path = tmpd / "script.txt"
        with script_path.open("w") as f:
            for t, data in script:
                raw = data.encode("ascii") if isinstance(data, str) else data
                f.write(f"{t:.9f} {_escape(raw)}\n")
        args += ["-i", str(script_path)]
        if wave is not None:
            (tmpd / "wave.txt").write_text(
                "".join(f"{row[0]:.9f} " + " ".join(f"{mv:.6f}" for mv in row[1:]) + "\n" for row in wave)
            )
            args += ["-a", str(tmpd / "wave.txt"), "-A", str(tmpd / "adc.log")]
        if edges is not None:
            (tmpd / "edges.txt").write_text("".join(f"{t:.9f} {pin} {int(lv)}\n" for t, pin, lv in edges))
            args += ["-e", str(tmpd / "edges.txt")]
        if watch:
            args += ["-w", ",".join(watch), "-l", str(tmpd / "pins.log")]
        args.append(str(elf or ELF[board]))
        proc = subprocess.run(args, capture_output=True, timeout=timeout, check=False)
        if proc.returncode != 0:
            raise RuntimeError(f"harness failed ({proc.returncode}): {proc.stderr.decode(errors='replace')}")
        lines = []
        for text in proc.stdout.decode("ascii", errors="replace").splitlines():
            m = _LINE.fullmatch(text)
            if not m:
                raise AssertionError(f"harness output line without a cycle stamp: {text!r}")
            raw = m.group(2)
            body, star, given = raw.rpartition("*")
            ok = bool(star) and given == checksum(body.encode("ascii", errors="replace"))
            lines.append(Line(int(m.group(1)), raw, body if star else raw, ok))
        pins = []
        if watch:
            for text in (tmpd / "pins.log").read_text().splitlines():
                c, pin, lv = text.split()
                pins.append((int(c), pin, int(lv)))
        adc = []
        if wave is not None:
            for text in (tmpd / "adc.log").read_text().splitlines():
                c, *mvs = text.split()
                adc.append((int(c), int(mvs[0]) if len(mvs) == 1 else tuple(int(v) for v in mvs)))
        return SimRun(lines, pins, adc, proc.stderr.decode(errors="replace"))


def schedule(
    n: int, pauses: Sequence[float] | None = None, spacing: float = 0.02, start: float = 0.05
) -> list[float]:
    """Send times of ``n`` commands: ``spacing`` apart plus each command's extra pause."""
    pauses = list(pauses) if pauses is not None else [0.0] * n
    times, t = [], start
    for i in range(n):
        times.append(t)
        t += spacing + pauses[i]
    return times + [t]


def command_session(
    board: str, commands: Sequence[bytes], pauses: Sequence[float] | None = None, spacing: float = 0.02
) -> tuple[SimRun, list[list[Line]]]:
    """Send the commands on a schedule and group the lines by the command window they arrived in.

    Returns the run and, per command, every line (data lines included) that arrived after the command was
    sent and before the next one.
    """
    times = schedule(len(commands), pauses, spacing)
    result = run(board, list(zip(times, commands, strict=False)), times[-1] + 0.02)
    groups: list[list[Line]] = [[] for _ in commands]
    bounds = [int(t * F_CPU) for t in times]
    for ln in result.lines:
        for i in range(len(commands)):
            if bounds[i] <= ln.cycle < bounds[i + 1]:
                groups[i].append(ln)
    return result, groups


def pty_process(board: str, pace: float = 0.0) -> tuple[subprocess.Popen, str]:
    """Start the harness on a pseudo-terminal; returns the process and the device path."""
    proc = subprocess.Popen(
        [str(HARNESS), "-m", MCU[board], "-p", "-s", str(pace), str(ELF[board])],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        env={**os.environ},
    )
    assert proc.stdout is not None
    first = proc.stdout.readline().decode().strip()
    if not first.startswith("PTY "):
        proc.kill()
        raise RuntimeError(f"harness did not report a pseudo-terminal: {first!r}")
    return proc, first[4:]


def rig_process(pace: float = 1.0, extra: Sequence[str] = ()) -> tuple[subprocess.Popen, str, str]:
    """Start both boards in one harness, wired as on the bench (Uno STEP D5 -> Mega D2, DIR D6 -> Mega D4).

    ``extra``: more harness options for the DAQ board (e.g. ``-a WAVE -t E4 -A ADCLOG``). Returns the process
    and the DAQ's and the stepper's pseudo-terminal paths.
    """
    proc = subprocess.Popen(
        [
            str(HARNESS),
            "-m",
            MCU["daq"],
            "-p",
            "-s",
            str(pace),
            "-2",
            str(ELF["stepper"]),
            "-M",
            MCU["stepper"],
            "-c",
            "D5:E4,D6:G5",
            *extra,
            str(ELF["daq"]),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
    )
    assert proc.stdout is not None
    first, second = (proc.stdout.readline().decode().split() for _ in range(2))
    if len(first) != 2 or first[0] != "PTY" or len(second) != 2 or second[0] != "PTY2":
        proc.kill()
        raise RuntimeError(f"harness did not report two pseudo-terminals: {first!r} {second!r}")
    return proc, first[1], second[1]
