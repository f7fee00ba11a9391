"""Serial I/O figures: the DAQ stream over the pseudo-terminal server, and one scenario on the in-process rig.

1. Start ``python -m helpers serve-virtual-rig`` (a separate process, paced at ``speed`` x real time), connect
   to its two pseudo-terminals by device path exactly as to hardware, and stream ``device_s`` seconds of DAQ
   samples at ``rate_hz``: report the samples received, the dropped / corrupted / overrun counts (target 0
   dropped) and the sustained rate in samples per wall second and per device second.
2. Record one 12 s scenario (200 mm/s, 20 mm, robust TDF) on the in-process virtual rig: report the wall time
   (target <= 1 s; the first run in a process also pays numba's compilation, reported separately).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from helpers.paper.calibration import uncalibrated
from helpers.paper.shapers import design_tdfs
from helpers.rig import Rig
from helpers.rig.static import record_static
from helpers.rigfile import default_rig, derived


def start_server(
    speed: float, timeout: float = 120.0, rig: str | None = None
) -> tuple[subprocess.Popen, str, str]:
    """Start ``python -m helpers serve-virtual-rig`` (of ``rig``, default the selected one); its two paths."""
    extra = [] if rig is None else ["--rig", rig]
    proc = subprocess.Popen(
        [sys.executable, "-m", "helpers", "serve-virtual-rig", "--speed", str(speed), "--rig-name", "bench",
         *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    paths: dict[str, str] = {}
    t0 = time.monotonic()
    while len(paths) < 2:
        line = proc.stdout.readline()
        if not line:
            proc.kill()
            raise RuntimeError(f"serve-virtual-rig exited: {proc.stderr.read()[-500:]}")
        kind, _, path = line.strip().partition(" ")
        if kind in ("daq", "stepper"):
            paths[kind] = path
        if time.monotonic() - t0 > timeout:
            proc.kill()
            raise RuntimeError("serve-virtual-rig did not print its device paths in time")
    return proc, paths["daq"], paths["stepper"]


def pty_stream(device_s: float = 60.0, rate_hz: int = 1000, speed: float = 1.0) -> dict[str, Any]:
    """Stream ``device_s`` of DAQ samples through the pseudo-terminal server; return the figures."""
    proc, daq, stepper = start_server(speed)
    try:
        paper = default_rig()
        rig = Rig((daq, stepper), paper, calibration=uncalibrated(derived(paper).mm_per_step[0]))
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            rec = record_static(
                rig, device_s, {"kind": "benchmark"}, path=Path(tmp) / "bench", rate_hz=rate_hz
            )
            wall = time.perf_counter() - t0
        rig.close()
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    c = rec.meta["counts"]
    span = (rec.frame["t_us"].iloc[-1] - rec.frame["t_us"].iloc[0]) / 1e6 if len(rec.frame) > 1 else 0.0
    return {
        "samples": c["samples"],
        "dropped": c["dropped"],
        "corrupted": c["corrupted"],
        "overruns": c["overruns"],
        "wall_s": wall,
        "device_s": span,
        "rate_per_wall_s": c["samples"] / wall,
        "rate_per_device_s": (c["samples"] - 1) / span if span else 0.0,
        "source": rec.meta["source"]["kind"],
        "speed": speed,
    }


def in_process_scenario() -> dict[str, Any]:
    """Wall time of one 12 s scenario on the in-process virtual rig (first run and a warm second run)."""
    _, zvd = design_tdfs()
    rig = Rig("virtual", default_rig(), world="bench-inprocess")
    walls = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(2):
            t0 = time.perf_counter()
            rec = rig.run_pulse(200, 20, zvd, system="zvd", path=Path(tmp) / f"s{i}", progress=False)
            walls.append(time.perf_counter() - t0)
    rig.close()
    return {
        "first_wall_s": walls[0],
        "wall_s": walls[1],
        "samples": len(rec.frame),
        "device_s": float(rec.frame["t_s"].iloc[-1]),
    }


def run_serial_benchmark(device_s: float = 60.0, speed: float = 1.0) -> dict[str, Any]:
    """Measure and print the serial figures; return them.

    Parameters
    ----------
    device_s : float
        Device seconds streamed over the pseudo-terminals (60 s at 1 kHz in the issue).
    speed : float
        Pacing of the server (1 = real time, as hardware streams).
    """
    pty = pty_stream(device_s, 1000, speed)
    print(
        f"pty server, 1 kHz for {pty['device_s']:.1f} s of device time at speed {speed:g}: "
        f"{pty['samples']} samples, {pty['dropped']} dropped (target 0), {pty['corrupted']} corrupted, "
        f"{pty['overruns']} overruns; {pty['rate_per_device_s']:.1f} samples per device s, "
        f"{pty['rate_per_wall_s']:.1f} per wall s ({pty['wall_s']:.1f} s wall)"
    )
    inproc = in_process_scenario()
    print(
        "in-process virtual rig, one 12 s scenario (200 mm/s, 20 mm, robust TDF, "
        f"{inproc['samples']} samples): {inproc['wall_s']:.2f} s wall (target <= 1 s); "
        f"first run in the process {inproc['first_wall_s']:.2f} s "
        "(includes numba compilation)"
    )
    return {"pty": pty, "in_process": inproc}
