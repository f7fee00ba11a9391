"""Serial I/O figures: the DAQ stream over the pseudo-terminal server (1 to 4 tendons), one in-process run.

1. For each rig (default the paper's one tendon and ``four-tendon``): start ``python -m helpers
   serve-virtual-rig --rig RIG`` (a separate process: the emulated boards of the rig's build and its twin,
   paced at ``speed`` x real time), connect a :class:`~helpers.rig.Rig` to its two pseudo-terminals by device
   path exactly as to hardware, and run a programme of ``device_s`` seconds (a small pull of tendon 1, a hold,
   the pull back) at ``rate_hz``: report the samples received, the dropped / corrupted / overrun counts
   (target 0 dropped), the bytes per data line the DAQ sent and the link's load at the build's baud rate
   (``firmware/PROTOCOL.md``, link budget), and the sustained rate per wall and per device second.
2. Record one 12 s scenario (200 mm/s, 20 mm, robust TDF) on the in-process virtual rig: report the wall time
   (target <= 1 s; the first run in a process also pays numba's compilation, reported separately) and the
   recording's CPU time over the bare plant's on the same scenario, measured in the same call (aim <= 1.3x):
   what the emulated boards, the lines, the host and the saved recording add to the physics.
"""

from __future__ import annotations

import copy
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from helpers import rigfile
from helpers.board.programmes import Dwell, Move, Programme
from helpers.board.protocol import frame
from helpers.paper.calibration import uncalibrated
from helpers.paper.shapers import design_tdfs
from helpers.rig import Rig
from helpers.rig.trim import TensionGuard
from helpers.rigfile import default_rig, derived

PULL_STEPS = 4
"""Steps of tendon 1's pull: small enough that no tendon leaves its pretension's neighbourhood."""

RIGS = ("paper", "four-tendon")
"""The shipped rigs ``bench serial`` streams from: one tendon (the paper's) and four."""


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


def _line_bytes(row: tuple[int, ...]) -> int:
    """Bytes on the wire of the data line ``row`` (``seq, t_us, adc_i.., steps_i..``) as the DAQ frames it."""
    return len(frame("D," + ",".join(str(int(v)) for v in row)))


def pty_stream(device_s: float = 60.0, rate_hz: int = 1000, speed: float = 1.0,
               rig_name: str = "paper") -> dict[str, Any]:  # fmt: skip
    """Run a ``device_s`` programme on the rig ``rig_name`` (1 to 4 tendons) through the pty server.

    Parameters
    ----------
    device_s : float
        Device seconds of the programme (a pull of tendon 1 by :data:`PULL_STEPS`, a hold, the pull back).
    rate_hz : int
        The DAQ's sample rate.
    speed : float
        Pacing of the server (1 = real time, as hardware streams).
    rig_name : str
        A shipped rig's name or a rig file's path.

    Returns
    -------
    dict
        The rig's name and tendon count, the sample, drop, corruption and overrun counts, wall and device
        seconds, the rates, the data lines' mean and largest bytes, the baud rate and the link's load.
    """
    rig_file = rigfile.load(rigfile.resolve(rig_name))
    proc, daq, stepper = start_server(speed, rig=str(rigfile.resolve(rig_name)))
    try:
        n = rig_file.n_tendons
        calibration = [uncalibrated(m) for m in derived(rig_file).mm_per_step]  # tension in counts
        rig = Rig((daq, stepper), rig_file, calibration=calibration, hello_timeout=120.0)
        window_us = 100_000
        hold_ms = int(round(device_s * 1000)) - 2 * window_us // 1000
        pull = (PULL_STEPS,) + (0,) * (n - 1)
        back = (-PULL_STEPS,) + (0,) * (n - 1)
        prog = Programme((Move(window_us, pull), Dwell(hold_ms), Move(window_us, back)))
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            rec = rig.run(prog, path=Path(tmp) / "bench", rate_hz=rate_hz, tail_s=0.2, progress=False,
                          guard=TensionGuard() if rig.n > 1 else None)
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
        "link_load": mean_bytes * 10 * rate_hz / baud, "speed": speed, "source": rec.meta["source"]["kind"],
    }  # fmt: skip


class _PlantCalls:
    """The world's plant, keeping every ``advance`` call's arguments and outputs (to replay them bare)."""

    def __init__(self, plant: Any) -> None:
        self.plant, self.calls = plant, []

    def __getattr__(self, name: str) -> Any:
        return getattr(self.plant, name)

    def advance(self, times: np.ndarray, *steps: np.ndarray) -> Any:
        out = self.plant.advance(times, *steps)
        self.calls.append((np.array(times), *(np.array(s) for s in steps), np.array(out)))
        return out


def _bare_plant_cpu(plant: Any, calls: list[tuple[np.ndarray, ...]]) -> tuple[float, float]:
    """CPU time of ``plant`` (a copy of the world's at the run's start) advanced over the run's instants.

    One call over every instant the recording asked of the plant and every step it was given: the physics
    of the same scenario without boards, lines or host. Returns the CPU seconds and the largest difference
    (N) from the outputs the recording's plant gave.
    """
    times, outs = (np.concatenate([c[i] for c in calls]) for i in (0, -1))
    steps = [np.concatenate([c[i] for c in calls]) for i in range(1, len(calls[0]) - 1)]
    copy.deepcopy(plant).advance(*calls[0][:-1])  # a copy's first call may compile again: not timed
    c0 = time.process_time()
    out = plant.advance(times, *steps)
    return time.process_time() - c0, float(np.max(np.abs(np.asarray(out) - outs)))


def in_process_scenario(repeats: int = 3) -> dict[str, Any]:
    """One 12 s scenario on the in-process virtual rig: wall time (first and warm run), CPU over the plant's.

    Each of ``repeats`` warm runs' CPU time (``time.process_time``: emulated boards, lines, host, recording
    saved) over the CPU time of the bare plant on the same scenario (:func:`_bare_plant_cpu`), measured
    right after it in the same call; the ratios sorted.
    """
    _, zvd = design_tdfs()
    rig = Rig("virtual", default_rig(), world="bench-inprocess")
    walls, cpus, plants, diffs = [], [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(1 + repeats):
            world = rig.world
            bare = copy.deepcopy(world.plant)
            world.plant = calls = _PlantCalls(world.plant)
            t0, c0 = time.perf_counter(), time.process_time()
            rec = rig.run_pulse(200, 20, zvd, system="zvd", path=Path(tmp) / f"s{i}", progress=False)
            walls.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
            world.plant = calls.plant
            if i:  # the first run also compiles
                plant_cpu, diff = _bare_plant_cpu(bare, calls.calls)
                plants.append(plant_cpu)
                diffs.append(diff)
    rig.close()
    ratios = sorted(c / p for c, p in zip(cpus[1:], plants, strict=True))
    return {
        "first_wall_s": walls[0],
        "wall_s": float(np.median(walls[1:])),
        "cpu_s": cpus[1:],
        "plant_cpu_s": plants,
        "cpu_over_plant": ratios,
        "plant_max_diff_n": max(diffs),
        "samples": len(rec.frame),
        "device_s": float(rec.frame["t_s"].iloc[-1]),
    }


def run_serial_benchmark(
    device_s: float = 60.0, speed: float = 1.0, rigs: Sequence[str] = RIGS
) -> dict[str, Any]:
    """Measure and print the serial figures; return them.

    Parameters
    ----------
    device_s : float
        Device seconds streamed over the pseudo-terminals per rig (60 s at 1 kHz in the issue).
    speed : float
        Pacing of the server (1 = real time, as hardware streams).
    rigs : sequence of str
        The rigs streamed from, each on its own server (default :data:`RIGS`).
    """
    ptys = {}
    for name in rigs:
        r = ptys[name] = pty_stream(device_s, 1000, speed, name)
        print(
            f"pty server, rig {r['rig']} ({r['tendons']} channel(s) and step count(s) per line), 1 kHz for "
            f"{r['device_s']:.1f} s of device time at speed {speed:g}: {r['samples']} samples, "
            f"{r['dropped']} dropped (target 0), {r['corrupted']} corrupted, {r['overruns']} overruns; "
            f"data lines {r['line_bytes_mean']:.1f} bytes on average ({r['line_bytes_max']} at most): "
            f"{100 * r['link_load']:.0f} % of {r['baud']} baud; {r['rate_per_device_s']:.1f} samples per "
            f"device s, {r['rate_per_wall_s']:.1f} per wall s ({r['wall_s']:.1f} s wall); load average "
            + ", ".join(f"{x:.2f}" for x in os.getloadavg())
        )
    inproc = in_process_scenario()
    print(
        "in-process virtual rig, one 12 s scenario (200 mm/s, 20 mm, robust TDF, "
        f"{inproc['samples']} samples): {inproc['wall_s']:.2f} s wall (median warm run; target <= 1 s); "
        f"first run in the process {inproc['first_wall_s']:.2f} s "
        "(includes numba compilation)"
    )
    ratios = inproc["cpu_over_plant"]
    print(
        f"its CPU time over the bare plant's on the same scenario, {len(ratios)} warm runs: "
        f"{' / '.join(f'{r:.2f}x' for r in ratios)} (sorted; aim <= 1.3x; median "
        f"{np.median(inproc['cpu_s']):.3f} s against {np.median(inproc['plant_cpu_s']):.3f} s; the bare "
        f"plant's outputs differ from the runs' by {inproc['plant_max_diff_n']:.1e} N); load average "
        + ", ".join(f"{x:.2f}" for x in os.getloadavg())
    )
    return {"pty": ptys, "in_process": inproc}
