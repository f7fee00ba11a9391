"""Firmware in the loop for several tendons: a coordinated four-tendon programme recorded through
:class:`helpers.rig.Rig` from both firmware images built for ``rigs/four-tendon.toml``
(``firmware/common/rig_config_four_tendon.h``) in simavr, with the spatial twin's physics.

The one-tendon check's three passes (``fil.py``), for four axes and four channels:

1. **Edges.** The four-axis stepper sketch alone runs ``EN 1``, the programme (``CLEAR``, ``MSEG``/``WAIT``)
   and ``GO`` in simavr; the STEP/DIR pins of every axis are logged (``firmware/PROTOCOL.md``: axis 0 on
   D5/D6, 1 on D2/B2, 2 on D3/B3, 3 on D4/B4). Time 0 is axis 0's first STEP edge: the programme's first item
   must step axis 0 first (it has the most steps of that item), since the harness starts the ADC waveform at
   that edge.
2. **Tension.** The spatial twin (:class:`helpers.virtual.spatial.plant.SpatialPlant` of the rig file, as
   the in-process virtual rig builds it) is driven with those edges, tendon ``a`` by axis ``a``; each
   amplifier's output, through its own noise-free load cell (the loop's clipping included), becomes ADC
   channel ``a``'s waveform in millivolts, 0.05 ms apart plus the values just before and at every step of
   any axis.
3. **Record.** Both sketches run in one harness, in lockstep, every axis wired as on the bench (Uno STEP/DIR
   of axis ``a`` into the Mega's counter inputs of axis ``a``); ``Rig`` opens their
   pseudo-terminals as hardware, checks both builds against the rig file, and records the programme. The
   Mega converts channel ``c`` ``c`` conversions (104 us) after channel 0; the harness reads every
   channel's waveform at each conversion start, so each channel is the twin at its own instant, as in the
   emulated world (:mod:`helpers.virtual.emulator.world`).

:func:`check_alignment` sets the recording beside passes 1 and 2 sample by sample: every step count is
pass 1's at channel 0's conversion (but for steps the DAQ counts late, within its sampling interrupt), every
ADC count simavr's conversion of the millivolts the harness logged.

Usage (needs the Debian packages of ``firmware/README.md``)::

    python tests/firmware/fil4.py           # the four-tendon programme: FIL against in-process, per tendon
"""

from __future__ import annotations

import itertools
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import fwsim
import numpy as np
import pandas as pd

if str(fwsim.REPO) not in sys.path:  # run as a script from anywhere: this repository's helpers
    sys.path.insert(0, str(fwsim.REPO))

from helpers import rigfile  # noqa: E402
from helpers.board.programmes import Dwell, Move, Programme  # noqa: E402
from helpers.commands.metrics_report import move_tables  # noqa: E402
from helpers.recordings import Recording  # noqa: E402
from helpers.research.residuals import move_phases, residual_table, rising_tendon  # noqa: E402
from helpers.rig import Rig  # noqa: E402
from helpers.rig.link import Waiter  # noqa: E402
from helpers.rig.trim import TensionGuard  # noqa: E402

UNWATCHED = TensionGuard(watch=False)
"""The runs compared here are a comparison of two paths, not moves: their programmes slacken a tendon (tendon
2 below the floor for longer than the floor watch allows at about 4.1 s), and both are recorded whole."""
from helpers.virtual.emulator.world import ADC_CONVERSION_S, build_world, forget_world, register_world  # noqa: E402
from helpers.virtual.sensor import LoadCell  # noqa: E402
from helpers.virtual.spatial.from_rig import spatial_rig  # noqa: E402
from helpers.virtual.spatial.plant import SpatialPlant  # noqa: E402

F = fwsim.F_CPU
CYCLE_S = 1.0 / F
WAVE_DT_S = 5e-5
"""Spacing of the ADC waveform's points between steps (s), as the one-tendon check's."""
PLANT_LEAD_S = 1e-3
"""The twin starts at rest this long before the first step."""
SIMAVR_MV_PER_COUNT = 5000 / 1023
RIG_FILE = fwsim.REPO / "rigs" / "four-tendon.toml"
CONFIG = fwsim.FIRMWARE / "common" / "rig_config_four_tendon.h"
UNO_AXES = [("D5", "D6"), ("D2", "B2"), ("D3", "B3"), ("D4", "B4")]
MEGA_AXES = [("E4", "G5"), ("E5", "E3"), ("D2", "A1"), ("D3", "A3")]
WIRES = ",".join(f"{us}:{ms},{ud}:{md}" for (us, ud), (ms, md) in zip(UNO_AXES, MEGA_AXES, strict=True))
SIMAVR_SLOWDOWN = 10.0
"""How many times longer than the programme (and its tail) the host waits for ``DONE`` in wall time: simavr
runs both boards, four channels at 1 Mbaud, below real time (about 0.4 x here)."""
METRICS = ["peak_n", "overshoot_pct", "settling_ms"]

_names = itertools.count()


def build(into: Path) -> dict[str, Path]:
    """Both sketches built for the four-tendon config into ``into``; the ELF of each board."""
    proc = subprocess.run(
        ["make", "-C", str(fwsim.FIRMWARE), "-j2", f"RIG_CONFIG={CONFIG}", f"BUILD={into}", "firmware"],
        capture_output=True, text=True, check=False, timeout=600,
    )  # fmt: skip
    if proc.returncode != 0:
        raise RuntimeError(f"four-tendon build failed:\n{proc.stdout[-2000:]}{proc.stderr[-2000:]}")
    return {"daq": into / "daq_mega.elf", "stepper": into / "stepper_uno.elf"}


def four_rig() -> rigfile.RigFile:
    """``rigs/four-tendon.toml``."""
    return rigfile.load(RIG_FILE)


# --- pass 1: every axis's edges --------------------------------------------------------------------------
@dataclass
class Edges:
    """STEP rising edges of every axis, merged in time: s from axis 0's first, the axis and the direction."""

    t: np.ndarray
    axes: np.ndarray
    signs: np.ndarray


def programme_edges(programme: Programme, elf: Path, axes: int = 4) -> Edges:
    """Pass 1: ``EN 1``, the programme's commands and ``GO`` to the stepper sketch alone."""
    commands = ["EN 1", *programme.commands(axes), "GO"]
    script = [(0.05 + 0.01 * i, fwsim.command(c)) for i, c in enumerate(commands)]
    watch = [p for pair in UNO_AXES for p in pair]
    run = fwsim.run("stepper", script, script[-1][0] + programme.duration_s + 0.05, watch=watch, elf=elf)
    step_axis = {s: a for a, (s, _) in enumerate(UNO_AXES)}
    dir_axis = {d: a for a, (_, d) in enumerate(UNO_AXES)}
    level = [0] * len(UNO_AXES)
    cycles, which, signs = [], [], []
    for cycle, pin, lv in run.pins:
        if pin in dir_axis:
            level[dir_axis[pin]] = lv
        elif lv == 1:
            a = step_axis[pin]
            cycles.append(cycle)
            which.append(a)
            signs.append(1 if level[a] else -1)
    c, w = np.array(cycles, dtype=np.int64), np.array(which, dtype=np.int64)
    if not len(c) or w[0] != 0:
        raise RuntimeError("pass 1: axis 0 must step first (the harness starts the waveform at its edge)")
    return Edges((c - c[0]) * CYCLE_S, w, np.array(signs, dtype=np.int64))


# --- pass 2: every tendon's tension as its channel's waveform --------------------------------------------
@dataclass
class Waveform:
    """The ADC inputs (mV, one column per channel) at times (s from axis 0's first STEP edge)."""

    t: np.ndarray
    mv: np.ndarray
    cells: list[LoadCell]


def noise_free_cells(rig: rigfile.RigFile) -> list[LoadCell]:
    """One noise-free load cell per tendon (each its rig file's span), as the virtual world's."""
    twin = spatial_rig(rig)
    return [LoadCell(twin.arm, seed=None, noise_rms=0.0, span_n=t.load_cell_range_n) for t in twin.tendons]


def tension_waveform(edges: Edges, duration_s: float, rig: rigfile.RigFile) -> Waveform:
    """Drive the spatial twin with the edges; each amplifier's output as its ADC channel's millivolts.

    ``mV = (loop counts + 0.5) x 5000/1023``: simavr's ``floor(mV x 1023 / 5000)`` is then the load cell's
    rounded count (to the harness's rounding of mV to an integer: 0.1 count).
    """
    cells = noise_free_cells(rig)
    grid = np.arange(0.0, duration_s, WAVE_DT_S)
    t = np.unique(np.concatenate([[-CYCLE_S], grid, edges.t[1:] - CYCLE_S, edges.t]))
    plant = SpatialPlant(spatial_rig(rig))
    keep = edges.t <= t[-1]
    out = plant.advance(t + PLANT_LEAD_S, edges.t[keep] + PLANT_LEAD_S, edges.axes[keep], edges.signs[keep])
    output = np.asarray(out["output"], dtype=float)
    counts = np.column_stack([_loop_counts(cell, output[:, c]) for c, cell in enumerate(cells)])
    return Waveform(t, (counts + 0.5) * SIMAVR_MV_PER_COUNT, cells)


def _loop_counts(cell: LoadCell, output_n: np.ndarray) -> np.ndarray:
    """The cell's continuous ADC reading (before rounding) of amplifier outputs: its ``counts`` unrounded."""
    scale = cell.offset_counts / cell.current(np.array([0.0]))[0]  # counts per ampere of the loop
    return scale * cell.current(output_n)


# --- pass 3: the recording --------------------------------------------------------------------------------
@dataclass
class FilRun:
    """A recording made through the firmware, and what the harness logged of the DAQ's ADC."""

    frame: pd.DataFrame
    recording: Recording
    conversions: np.ndarray  # cycle of every conversion start of the DAQ board
    conversion_mv: np.ndarray  # (n, channels): the millivolts handed to simavr at each
    trigger_cycle: int
    wall_s: float


def record(wave: Waveform, programme: Programme, elfs: dict[str, Path], tmp: Path,
           tail_s: float, pace: float = 0.0) -> FilRun:  # fmt: skip
    """Both sketches on pseudo-terminals with the waveform; ``Rig.run(programme)`` through them."""
    wave_path, adc_path = tmp / "wave.txt", tmp / "adc.log"
    wave_path.write_text(
        "".join(f"{t:.9f} " + " ".join(f"{v:.4f}" for v in row) + "\n" for t, row in zip(wave.t, wave.mv,
                                                                                            strict=True))
    )  # fmt: skip
    proc = subprocess.Popen(
        [str(fwsim.HARNESS), "-m", fwsim.MCU["daq"], "-p", "-s", str(pace), "-2", str(elfs["stepper"]),
         "-M", fwsim.MCU["stepper"], "-c", WIRES, "-a", str(wave_path), "-t", "E4", "-A", str(adc_path),
         str(elfs["daq"])],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
    )  # fmt: skip
    assert proc.stdout is not None
    first, second = (proc.stdout.readline().decode().split() for _ in range(2))
    if len(first) != 2 or first[0] != "PTY" or len(second) != 2 or second[0] != "PTY2":
        proc.kill()
        raise RuntimeError(f"harness did not report two pseudo-terminals: {first!r} {second!r}")
    t0 = time.monotonic()
    try:
        rig = Rig(f"{first[1]},{second[1]}", four_rig(), timeout=60.0, hello_timeout=60.0,
                  silence_s=60.0)  # simavr on a busy host may stall: only a failure waits this long
        rig.source = {"kind": "virtual-rig", "via": "firmware in the loop (both four-tendon sketches in "
                      "simavr, plant from helpers.virtual.spatial)"}  # fmt: skip
        # simavr runs the two boards below real time: the silence interval (wall time here), stretched
        rig.daq.waiter = lambda timeout: Waiter(SIMAVR_SLOWDOWN * timeout, None)  # type: ignore[method-assign]
        try:
            rec = rig.run(programme, path=tmp / "fil4", tail_s=tail_s, progress=False, guard=UNWATCHED)
            frame = rec.frame
        finally:
            rig.close()
    finally:
        proc.terminate()
        proc.wait(timeout=30)
    wall = time.monotonic() - t0
    trigger, conv, mv = -1, [], []
    for line in adc_path.read_text().splitlines():
        if line.startswith("# trigger"):
            trigger = int(line.split()[2])
        else:
            c, *vs = line.split()
            conv.append(int(c))
            mv.append([int(v) for v in vs])
    if trigger < 0:
        raise RuntimeError("the harness never saw a STEP edge of axis 0 on the DAQ board (no trigger)")
    return FilRun(frame, rec, np.array(conv, dtype=np.int64), np.array(mv), trigger, wall)


@dataclass
class Alignment:
    """How pass 3 agrees with passes 1 and 2, sample by sample (every channel and axis)."""

    samples: int
    step_mismatches: int  # (sample, axis) pairs whose step count is not pass 1's at channel 0's conversion
    near_edge: int  # of those, pairs taken up to 20 us after a step edge of that axis (counted late)
    adc_mismatches: int  # recorded counts that differ from simavr's conversion of the logged millivolts
    harness_error: float  # |logged mV - waveform| at the conversions, in counts (the harness's rounding)


def check_alignment(fil: FilRun, edges: Edges, wave: Waveform, channels: int = 4) -> Alignment:
    """Set the recording beside passes 1 and 2, sample by sample."""
    frame = fil.frame
    n = len(frame)
    conv = fil.conversions[-channels * n :].reshape(n, channels)  # channel c is the c-th conversion
    mv = fil.conversion_mv[-channels * n :].reshape(n, channels, -1)
    at = (conv[:, 0] - fil.trigger_cycle) * CYCLE_S
    wrong = near = 0
    for a in range(channels):
        sel = edges.axes == a
        ta, sa = edges.t[sel], edges.signs[sel]
        idx = np.searchsorted(ta, at, side="right")
        count_at = np.concatenate([[0], np.cumsum(sa)])[idx]
        bad = frame[f"steps_{a}"].to_numpy() != count_at
        dist = np.where(idx > 0, at - ta[np.maximum(idx - 1, 0)], np.inf)
        wrong += int(bad.sum())
        near += int((bad & (dist <= 2e-5)).sum())
    own = mv[:, np.arange(channels), np.arange(channels)]  # channel c as converted at its own start
    recorded = np.column_stack([frame[f"adc_{c}"].to_numpy() for c in range(channels)])
    simavr = np.floor(own * 1023 / 5000).astype(np.int64)
    times = (conv - fil.trigger_cycle) * CYCLE_S
    after = times[:, 0] >= 0
    want = np.column_stack([np.interp(times[after, c], wave.t, wave.mv[:, c]) for c in range(channels)])
    harness = np.abs(own[after] - want) / SIMAVR_MV_PER_COUNT
    return Alignment(n, wrong, near, int((recorded != simavr).sum()), float(harness.max()))


# --- the in-process virtual rig, noise-free, for comparison ----------------------------------------------
def in_process(programme: Programme, tail_s: float, tmp: Path) -> Recording:
    """The same programme on the in-process four-tendon virtual rig (``virtual://``, noise-free cells)."""
    rig = four_rig()
    name = f"fil4-reference-{next(_names)}"
    world = build_world(rig, name)
    world.sensors = noise_free_cells(rig)
    register_world(world)
    try:
        host = Rig("virtual", rig, world=name)
        try:
            return host.run(programme, path=tmp / name, tail_s=tail_s, progress=False, guard=UNWATCHED)
        finally:
            host.close()
    finally:
        forget_world(name)


def per_tendon(rec: Recording, band: float = 0.05) -> pd.DataFrame:
    """Every tendon's Table II metrics (``python -m helpers metrics``' table), indexed by tendon, motion."""
    return move_tables([rec], band).tendons.set_index(["tendon", "motion"])[METRICS]


def one_count_settling_spread(rec: Recording) -> pd.Series:
    """How far each tendon's settling times move when the band is one ADC count wider or narrower (ms).

    A settling time is the last exit from the band; a one-count difference between two runs at the band's
    edge can move it by a whole oscillation (``fil.one_count_settling_spread`` for one tendon). NaN where no
    settling time is defined.
    """
    base = per_tendon(rec)
    table = move_tables([rec], 0.05).tendons.set_index(["tendon", "motion"])
    out = {}
    for (tendon, motion), row in table.iterrows():
        step = abs(row["yf_n"] - row["y0_n"])
        npc = rec.meta["calibration"]["newtons_per_count"][tendon - 1]  # tendons numbered from 1
        if not (step > 0) or np.isnan(base.loc[(tendon, motion), "settling_ms"]):
            out[(tendon, motion)] = float("nan")
            continue
        times = [per_tendon(rec, 0.05 + k * npc / step).loc[(tendon, motion), "settling_ms"] for k in (-1, 1)]
        times.append(base.loc[(tendon, motion), "settling_ms"])
        out[(tendon, motion)] = float(np.nanmax(times) - np.nanmin(times))
    return pd.Series(out)


def twin_frame(edges: Edges, phase_s: float, duration_s: float, rig: rigfile.RigFile,
               rate_hz: int = 1000) -> pd.DataFrame:  # fmt: skip
    """The spatial twin alone on pass 1's edges, sampled as the DAQ does (channel c c x 104 us after
    channel 0) at ``rate_hz`` with channel 0 ``phase_s`` (mod one period) after axis 0's first edge, through
    noise-free cells rounded to counts; 1 s of rest first. Columns: ``t_s``, ``steps_i``, ``tension_n_i``."""
    cells = noise_free_cells(rig)
    n = len(cells)
    period = 1.0 / rate_hz
    t0 = np.arange(-1.0 + phase_s, duration_s, period)
    reads = (t0[:, None] + np.arange(n)[None, :] * ADC_CONVERSION_S).ravel()
    lead = 1.0 + PLANT_LEAD_S
    keep = edges.t <= reads[-1]
    out = SpatialPlant(spatial_rig(rig)).advance(reads + lead, edges.t[keep] + lead, edges.axes[keep],
                                                 edges.signs[keep])  # fmt: skip
    every = np.asarray(out["output"], dtype=float).reshape(len(t0), n, -1)
    frame = pd.DataFrame({"t_s": t0 - t0[0]})
    for a in range(n):
        sel = edges.axes == a
        frame[f"steps_{a}"] = np.concatenate([[0], np.cumsum(edges.signs[sel])])[
            np.searchsorted(edges.t[sel], t0, side="right")
        ]
    for c, cell in enumerate(cells):
        counts = cell.counts(every[:, c, c])
        frame[f"tension_n_{c}"] = (counts - cell.offset_counts) * cell.newtons_per_count
    return frame


def phase_spread(edges: Edges, duration_s: float, rig: rigfile.RigFile, n: int = 10) -> pd.DataFrame:
    """How much each tendon's metrics move with the sampling phase alone (max - min over ``n`` phases in one
    period of the twin sampled as the DAQ does, :func:`twin_frame`), by the metrics' own analysis (the motions
    from the lead's count, tendons numbered from 1)."""
    tables = []
    for k in range(n):
        frame = twin_frame(edges, k * 1e-3 / n, duration_s, rig)
        counts = frame[[f"steps_{a}" for a in range(rig.n_tendons)]].to_numpy()
        phases = move_phases(frame["t_s"].to_numpy(), counts, rising_tendon(counts))
        m = residual_table(frame, rig.n_tendons, phases).rename(columns={"peak": "peak_n"})
        tables.append(m[m["unit"] == "N"].set_index(["tendon", "motion"])[METRICS])
    stacked = pd.concat(tables)
    return stacked.groupby(level=[0, 1]).max() - stacked.groupby(level=[0, 1]).min()


# --- the scenario -------------------------------------------------------------------------------------
def four_tendon_programme(hold_ms: int = 3000) -> Programme:
    """A coordinated up-hold-down move of every tendon: 1 s at rest (the metrics' baseline), 16, 10, 6 and 8
    steps (4.1, 2.6, 1.5 and 2.0 mm at 0.2553 mm per step) in 0.1 s, a dwell, and back in 0.1 s. Axis 0 has
    the most steps of the move: it steps first (the waveform's origin)."""
    up = (16, 10, 6, 8)
    return Programme((Dwell(1000), Move(100_000, up), Dwell(hold_ms), Move(100_000, tuple(-n for n in up))))


def run_case(tmp: Path, elfs: dict[str, Path], hold_ms: int = 3000, tail_s: float = 3.0) -> dict[str, Any]:
    """Passes 1-3 and the in-process run of :func:`four_tendon_programme`; the per-tendon metrics."""
    programme = four_tendon_programme(hold_ms)
    edges = programme_edges(programme, elfs["stepper"])
    wave = tension_waveform(edges, programme.duration_s + tail_s + 2.0, four_rig())
    fil = record(wave, programme, elfs, tmp, tail_s)
    ref = in_process(programme, tail_s, tmp)
    duration = float(fil.recording.frame["t_s"].iloc[-1]) - 1.0  # the recording's end, from the first step
    return {
        "fil": per_tendon(fil.recording),
        "in_process": per_tendon(ref),
        "alignment": check_alignment(fil, edges, wave),
        "settling_resolution": one_count_settling_spread(ref),
        "phase_spread": phase_spread(edges, duration, four_rig()),
        "recording": fil.recording,
        "reference": ref,
        "edges": edges,
        "wall_s": fil.wall_s,
    }


def show(result: dict[str, Any]) -> None:
    """Print the comparison."""
    print("\n== four tendons: firmware in the loop (FIL) against the in-process virtual rig (noise-free)")
    table = {"FIL": result["fil"], "in-process": result["in_process"],
             "FIL - in-process": result["fil"] - result["in_process"],
             "phase spread": result["phase_spread"].reindex(result["fil"].index)}  # fmt: skip
    with pd.option_context("display.width", 250):
        print(pd.concat(table, axis=1).round(3).to_string())
    a = result["alignment"]
    print(f"samples {a.samples}; step counts vs pass 1: {a.step_mismatches} differ ({a.near_edge} up to 20 "
          f"us after an edge); ADC counts vs simavr's conversion: {a.adc_mismatches} differ; ADC input vs "
          f"waveform: {a.harness_error:.3f} count at most; {len(result['edges'].t)} steps; wall "
          f"{result['wall_s']:.1f} s")  # fmt: skip


def main() -> int:
    """Print the four-tendon FIL comparison."""
    missing = fwsim.missing_toolchain()
    if missing:
        print(f"firmware toolchain missing ({', '.join(missing)}): {fwsim.INSTALL_HINT}", file=sys.stderr)
        return 1
    subprocess.run(["make", "-C", str(fwsim.FIRMWARE)], check=True, capture_output=True)
    with tempfile.TemporaryDirectory(prefix="fil4-") as tmp:
        show(run_case(Path(tmp), build(Path(tmp) / "build")))
    return 0


if __name__ == "__main__":
    sys.exit(main())
