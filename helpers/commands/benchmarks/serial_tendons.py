"""Serial I/O figures for several tendons: every channel's DAQ stream over the pseudo-terminal server.

Start ``python -m helpers serve-virtual-rig --rig RIG`` (a rig file of several tendons: the emulated boards of
its build and the spatial twin, paced at ``speed`` x real time), connect a
:class:`~helpers.rig.Rig` to its two pseudo-terminals by device path exactly as to hardware, and
run a coordinated programme of ``device_s`` seconds (a small pull of tendon 0, a hold, the pull back) at
``rate_hz``: report the samples received, the dropped / corrupted / overrun counts (target 0 dropped), the
bytes per data line the DAQ sent and the link's load at the build's baud rate (``firmware/PROTOCOL.md``, link
budget), and the sustained rate per wall and per device second.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

from helpers import rigfile
from helpers.board.programmes import Dwell, Move, Programme
from helpers.board.protocol import frame
from helpers.commands.benchmarks.serial import start_server
from helpers.rig import Rig

PULL_STEPS = 4
"""Steps of tendon 0's pull: small enough that no tendon leaves its pretension's neighbourhood."""


def _line_bytes(row: tuple[int, ...]) -> int:
    """Bytes on the wire of the data line ``row`` (``seq, t_us, adc_i.., steps_i..``) as the DAQ frames it."""
    return len(frame("D," + ",".join(str(int(v)) for v in row)))


def pty_stream_tendons(device_s: float = 60.0, rate_hz: int = 1000, speed: float = 1.0,
                       rig_name: str = "four-tendon") -> dict[str, Any]:  # fmt: skip
    """Run a ``device_s`` programme on a rig of several tendons through the pseudo-terminal server."""
    rig_file = rigfile.load(rigfile.resolve(rig_name))
    proc, daq, stepper = start_server(speed, rig=str(rigfile.resolve(rig_name)))
    try:
        rig = Rig((daq, stepper), rig_file, hello_timeout=120.0)
        n = rig_file.n_tendons
        window_us = 100_000
        hold_ms = int(round(device_s * 1000)) - 2 * window_us // 1000
        pull = (PULL_STEPS,) + (0,) * (n - 1)
        back = (-PULL_STEPS,) + (0,) * (n - 1)
        prog = Programme((Move(window_us, pull), Dwell(hold_ms), Move(window_us, back)))
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            rec = rig.run(prog, path=Path(tmp) / "bench", rate_hz=rate_hz, tail_s=0.2, progress=False)
            frame_ = rec.frame
            wall = time.perf_counter() - t0
        stats = rig.daq.parser.stats
        rows = list(rig.daq.rows)
        baud = rig_file.hardware.daq_baud
        rig.close()
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    sizes = [_line_bytes(r) for r in rows] if rows else [0]
    span = (frame_["t_us"].iloc[-1] - frame_["t_us"].iloc[0]) / 1e6 if len(frame_) > 1 else 0.0
    mean_bytes = sum(sizes) / len(sizes)
    return {
        "rig": rig_file.name, "tendons": n, "samples": len(frame_), "dropped": stats.dropped,
        "corrupted": stats.corrupted, "overruns": stats.overruns, "wall_s": wall, "device_s": span,
        "rate_per_wall_s": len(frame_) / wall, "rate_per_device_s": (len(frame_) - 1) / span if span else 0.0,
        "line_bytes_mean": mean_bytes, "line_bytes_max": max(sizes), "baud": baud,
        "link_load": mean_bytes * 10 * rate_hz / baud, "speed": speed,
    }  # fmt: skip


def run_serial_tendons_benchmark(device_s: float = 60.0, speed: float = 1.0) -> dict[str, Any]:
    """Measure and print the four-tendon serial figures; return them."""
    r = pty_stream_tendons(device_s, 1000, speed)
    print(
        f"pty server, rig {r['rig']} ({r['tendons']} channels and step counts per line), 1 kHz for "
        f"{r['device_s']:.1f} s of device time at speed {speed:g}: {r['samples']} samples, "
        f"{r['dropped']} dropped (target 0), {r['corrupted']} corrupted, {r['overruns']} overruns; "
        f"data lines {r['line_bytes_mean']:.1f} bytes on average ({r['line_bytes_max']} at most): "
        f"{100 * r['link_load']:.0f} % of {r['baud']} baud; {r['rate_per_device_s']:.1f} samples per "
        f"device s, {r['rate_per_wall_s']:.1f} per wall s ({r['wall_s']:.1f} s wall)"
    )
    return r
