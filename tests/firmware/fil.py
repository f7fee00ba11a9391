"""Firmware in the loop: a whole experiment recorded through helpers.rig from the real firmware images in
simavr, with the virtual rig's physics, exactly.

The plant does not feed back into the stepper (no step depends on the tension), so a run is simulated in
three passes:

1. **Edges.** The stepper sketch alone runs, in simavr, the commands the host will send (a programme; or a
   stream whose set-points are sent in time to drive consecutive periods) and its STEP/DIR pins are logged.
2. **Tension.** The virtual rig's plant, through the public API of :mod:`helpers.virtual` only
   (``RigParameters``, ``ArmPlant.advance``, the ``LoadCell``'s calibration), is driven with those edges, time
   0 at the first STEP edge; the tension, as the load cell and its amplifier turn it into a voltage, becomes
   the DAQ sketch's ADC waveform: 0.05 ms apart, plus the values just before and at every step (a step moves
   the tension at once).
3. **Record.** Both sketches run in one harness, in lockstep, wired as on the bench (the stepper's STEP and
   DIR into the DAQ's step counter), on pseudo-terminals; :class:`helpers.rig.Rig` connects to them as to
   hardware and records the run (``run_pulse`` or ``stream``). The harness starts the ADC waveform at the
   first STEP edge the DAQ board sees (``-t E4``), so the tension follows the steps the stepper firmware
   issues during the recording. The firmware is deterministic, so those steps are pass 1's:
   :func:`check_alignment` verifies it sample by sample, and that every ADC count is the plant's tension.

Usage (needs the Debian packages of ``firmware/README.md``)::

    python tests/firmware/fil.py            # Table I scenario and a streamed move: FIL against in-process

Why a tool under ``tests/``, not in ``helpers``: it needs the firmware build tree and the simavr harness,
which the package does not ship, and it is how the project checks its firmware against its virtual rig; a
user of ``helpers`` records with the virtual rig or the hardware directly.
"""

from __future__ import annotations

import itertools
import subprocess
import sys
import tempfile
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import fwsim
import numpy as np
import pandas as pd

if str(fwsim.REPO) not in sys.path:  # run as a script from anywhere: this repository's helpers
    sys.path.insert(0, str(fwsim.REPO))

from stream_run import velocity_units

from helpers.board import stream_reference as hs  # noqa: E402
from helpers.board.programmes import Programme, experiment_programme  # noqa: E402
from helpers.paper import metrics  # noqa: E402

MM_PER_STEP = __import__("math").pi * 65.0 / 800  # the paper's cable per step, by hand
from helpers.paper.shapers import design_tdfs  # noqa: E402
from helpers.rig import Rig  # noqa: E402
from helpers.rig.stream import PERIOD_US, stream  # noqa: E402
from helpers.rigfile import default_rig  # noqa: E402
from helpers.virtual import ArmPlant, LoadCell, RigParameters, simulate  # noqa: E402
from helpers.virtual.emulator.world import VirtualWorld, forget_world, parameters_dict, register_world  # noqa: E402

F = fwsim.F_CPU
WAVE_DT_S = 5e-5
"""Spacing of the ADC waveform's points between steps (s). The harness interpolates linearly in between, which
cuts the crest of each step's kick (about 10 counts in 0.3 ms at the Down move's snaps) by up to h^2/8 times
the curvature: at 0.1 ms up to 0.66 count of the plant, at 0.05 ms 0.17 (:func:`interpolation_error`, over
every interval of both cases)."""
CYCLE_S = 1.0 / F
PLANT_LEAD_S = 1e-3
"""The plant starts at rest this long before the first step (plant time = waveform time + this)."""
SIMAVR_MV_PER_COUNT = 5000 / 1023
"""simavr's ADC: count = floor(mV * 1023 / 5000) with the harness's 5000 mV reference."""
HARNESS_ROUNDING_COUNTS = 0.5 / SIMAVR_MV_PER_COUNT + 1e-4
"""The harness hands simavr whole millivolts: the ADC input is the waveform to within half a millivolt (0.1023
count), plus the waveform file's own rounding (times to 1 ns, at most 40 counts/ms during a kick; mV to 1e-4):
under 1e-4 count."""

_names = itertools.count()


# --- residual vibration ----------------------------------------------------------------------------------
def residual_vibration(frame: pd.DataFrame, table: pd.DataFrame) -> dict:
    """Residual vibration of each move (:func:`helpers.paper.metrics.residual_vibration`: half the
    peak-to-peak
    tension from 0.1 s to 1.1 s after the move's last step, in percent of ``yf - y0``).

    The last step of a move is the first sample showing the move's last change of the step count.
    Returns ``{"Up": pct, "Down": pct}``.
    """
    t = frame["t_s"].to_numpy(float)
    steps = frame["steps"].to_numpy()
    y = frame["tension_n"].to_numpy(float)
    out = {}
    for _, row in table.iterrows():
        idx = np.flatnonzero((t >= row["start_s"]) & (t < row["end_s"]))
        changes = idx[1:][np.diff(steps[idx]) != 0]
        t_last = t[changes[-1]] if len(changes) else row["start_s"]
        out[row["motion"]] = metrics.residual_vibration(t, y, t_last, row["y0_n"], row["yf_n"])
    return out


def compare(rec: Any) -> pd.DataFrame:
    """Table II metrics and the residual vibration of a recording, one row per motion."""
    return compare_frame(rec.frame)


def compare_frame(frame: pd.DataFrame) -> pd.DataFrame:
    """Table II metrics and the residual vibration of a frame (``t_s``, ``steps``, ``tension_n``)."""
    table = metrics.recording_metrics(frame)
    residual = residual_vibration(frame, table)
    table["residual_pct"] = [residual[m] for m in table["motion"]]
    return table.set_index("motion")[["peak_n", "overshoot_pct", "settling_ms", "residual_pct"]]


# --- pass 1: the stepper's edges ------------------------------------------------------------------------
@dataclass
class Edges:
    """STEP rising edges (s from the first one) and the direction of each step."""

    t: np.ndarray
    signs: np.ndarray
    replies: list[str] = field(default_factory=list)


def _edges(script: list[tuple[float, bytes]], duration: float) -> Edges:
    run = fwsim.run("stepper", script, duration, watch=("D5", "D6"))
    dir_level, rises, signs = 0, [], []
    for cycle, pin, level in run.pins:
        if pin == "D6":
            dir_level = level
        elif level == 1:
            rises.append(cycle)
            signs.append(1 if dir_level else -1)
    if not rises:
        raise RuntimeError("the stepper firmware issued no step")
    cycles = np.array(rises, dtype=np.int64)
    return Edges((cycles - cycles[0]) * CYCLE_S, np.array(signs), [ln.body for ln in run.lines])


def programme_edges(programme: Programme) -> Edges:
    """Pass 1 for a programme: ``EN 1``, the programme, ``GO``."""
    commands = ["EN 1", *programme.commands(), "GO"]
    script = [(0.05 + 0.01 * i, fwsim.command(c)) for i, c in enumerate(commands)]
    return _edges(script, script[-1][0] + programme.duration_s + 0.05)


def stream_edges(shaper: hs.StreamShaper, setpoints_units: list[int], lead: int = 4) -> Edges:
    """Pass 1 for a stream: set-point j (1, 2, ...) is sent ``lead`` periods before control tick j, so that
    the board assigns it period j (checked from its replies), then ``END``."""
    commands = ["EN 1", *shaper.commands()]
    script = [(0.05 + 0.01 * i, fwsim.command(c)) for i, c in enumerate(commands)]
    t_stream = script[-1][0] + 0.01
    script.append((t_stream, fwsim.command("STREAM")))
    period = PERIOD_US * 1e-6
    for j, u in enumerate(setpoints_units, start=1):
        script.append(
            (t_stream + 0.005 + max(j - lead, 0) * period + 0.0002 * (j % 2), fwsim.command(f"V {u}"))
        )
    script.append((script[-1][0] + 0.001, fwsim.command("END")))
    end = t_stream + (len(setpoints_units) + 5) * period + shaper.duration_s + 0.1
    edges = _edges(script, end)
    periods = [int(r.split()[2]) for r in edges.replies if r.startswith("OK V ")]
    if periods != list(range(1, len(setpoints_units) + 1)):
        raise RuntimeError(
            f"pass 1: the stream's set-points did not take consecutive periods ({periods[:12]})"
        )
    return edges


# --- pass 2: the tension, as the DAQ's ADC waveform ------------------------------------------------------
@dataclass
class Waveform:
    """The ADC input (mV) at times (s from the first STEP edge), and how it was made."""

    t: np.ndarray
    mv: np.ndarray
    params: RigParameters
    sensor: LoadCell


def tension_waveform(edges: Edges, duration_s: float, params: RigParameters | None = None) -> Waveform:
    """Drive the plant with the edges and turn its tension into the ADC's millivolts (noise-free sensor).

    ``mV = (offset + tension / newtons_per_count + 0.5) x 5000/1023``, so that simavr's ``floor(mV x 1023 /
    5000)`` gives the load cell's rounded count (to within the harness's rounding of mV to an integer: 0.1
    count).
    """
    params = params or RigParameters()
    sensor = LoadCell(params, seed=None, noise_rms=0.0)
    grid = np.arange(0.0, duration_s, WAVE_DT_S)
    # the first point is the rest (the harness holds it until the trigger); then, for every step, the value
    # one CPU cycle before it and the value at it (the plant applies a step before a sample at the same time)
    t = np.unique(np.concatenate([[-CYCLE_S], grid, edges.t[1:] - CYCLE_S, edges.t]))
    plant = ArmPlant(params)
    keep = edges.t <= t[-1]
    tension = plant.advance(t + PLANT_LEAD_S, edges.t[keep] + PLANT_LEAD_S, edges.signs[keep])
    counts = sensor.offset_counts + tension / sensor.newtons_per_count
    mv = (counts + 0.5) * SIMAVR_MV_PER_COUNT
    return Waveform(t, mv, params, sensor)


def exact_counts(wave: Waveform, edges: Edges, at_s: np.ndarray) -> np.ndarray:
    """The load cell's continuous count at times ``at_s`` (s from the first edge), from a fresh plant.

    The plant is integrated through the waveform's own points as well as ``at_s``: RK4 takes its steps
    between output times, and during a move the tension depends on that partition by up to about 0.15 N
    (4 counts; the rig's step-size error at the re-engagement snaps, docs/virtual_rig.md section 2). On the
    waveform's 0.05 ms partition, points added in between move it by 0.1 count or less, so what is left is the
    waveform's interpolation and the harness's rounding.
    """
    at = np.asarray(at_s, dtype=float)
    grid = np.union1d(wave.t[wave.t <= at[-1]], at)
    plant = ArmPlant(wave.params)
    keep = edges.t <= grid[-1]
    tension = plant.advance(grid + PLANT_LEAD_S, edges.t[keep] + PLANT_LEAD_S, edges.signs[keep])
    return (wave.sensor.offset_counts + tension / wave.sensor.newtons_per_count)[np.searchsorted(grid, at)]


# --- pass 3: the recording -------------------------------------------------------------------------------
@dataclass
class FilRun:
    """A recording made through the firmware, and what the harness logged of its ADC."""

    recording: Any
    conversions: np.ndarray  # cycle of every ADC conversion start of the DAQ board
    conversion_mv: np.ndarray
    trigger_cycle: int
    wall_s: float


def _truth(params: RigParameters, sensor: LoadCell) -> dict[str, Any]:
    return {
        "newtons_per_count": sensor.newtons_per_count,
        "offset_counts": sensor.offset_counts,
        "mm_per_step": MM_PER_STEP,
        "origin": "the virtual rig's load cell (true calibration)",
        "source": "virtual-rig",
    }


def record(wave: Waveform, action: str, kwargs: dict[str, Any], tmp: Path, pace: float = 1.0) -> FilRun:
    """Run both sketches on pseudo-terminals with the waveform and record ``Rig.<action>(**kwargs)``."""
    wave_path, adc_path = tmp / "wave.txt", tmp / "adc.log"
    wave_path.write_text("".join(f"{t:.9f} {mv:.4f}\n" for t, mv in zip(wave.t, wave.mv, strict=True)))
    proc, daq_path, stepper_path = fwsim.rig_process(
        pace=pace, extra=("-a", str(wave_path), "-t", "E4", "-A", str(adc_path))
    )
    t0 = time.monotonic()
    try:
        with warnings.catch_warnings():  # the simavr ports look like hardware until the source is said below
            warnings.simplefilter("ignore", UserWarning)
            rig = Rig((daq_path, stepper_path), default_rig(), _truth(wave.params, wave.sensor), timeout=60.0,
                      hello_timeout=60.0, silence_s=60.0)  # fmt: skip  # simavr on a busy host may stall
        rig.source = {
            "kind": "virtual-rig",
            "via": "firmware in the loop (both sketches in simavr, plant from helpers.virtual)",
            "parameters": parameters_dict(wave.params),
        }
        try:
            rec = _act(rig, action, kwargs, tmp / f"fil_{action}")
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
            c, v = line.split()
            conv.append(int(c))
            mv.append(int(v))
    if trigger < 0:
        raise RuntimeError("the harness never saw a STEP edge on the DAQ board (no trigger)")
    return FilRun(rec, np.array(conv, dtype=np.int64), np.array(mv), trigger, wall)


@dataclass
class Alignment:
    """How pass 3 agrees with passes 1 and 2, sample by sample."""

    samples: int
    step_mismatches: int  # samples whose recorded step count is not pass 1's at that instant
    near_edge: (
        int  # of those, samples taken up to 20 us after a step edge (the DAQ counts it late, see below)
    )
    adc_mismatches: int  # recorded counts that differ from simavr's conversion of the logged millivolts
    harness_error: float  # |logged count - waveform's count| at the samples (the harness's rounding to a mV)
    max_count_error: float  # |logged count - exact plant count| over the run (interpolation + rounding)


def sample_instants(fil: FilRun) -> np.ndarray:
    """The recording's sample instants, s from the first STEP edge (the run's samples are the last
    conversions the harness logged: the DAQ converts once per sample and only while it streams)."""
    return (fil.conversions[-len(fil.recording.frame) :] - fil.trigger_cycle) * CYCLE_S


def check_alignment(fil: FilRun, edges: Edges, wave: Waveform) -> Alignment:
    """Set the recording beside passes 1 and 2, sample by sample."""
    frame = fil.recording.frame
    n = len(frame)
    mv = fil.conversion_mv[-n:]
    at = sample_instants(fil)
    count_at = np.concatenate([[0], np.cumsum(edges.signs)])[np.searchsorted(edges.t, at, side="right")]
    steps = frame["steps"].to_numpy()
    wrong = steps != count_at
    # The DAQ's sampling interrupt busy-waits 16 us before it starts the conversion and reads the step count,
    # with interrupts off: a STEP edge in that span is counted when the interrupt returns, after the sample.
    before = np.searchsorted(edges.t, at, side="right") - 1
    dist = np.where(before >= 0, at - edges.t[np.maximum(before, 0)], np.inf)
    recorded = frame["adc"].to_numpy()
    simavr = np.floor(mv * 1023 / 5000).astype(np.int64)
    after = at >= 0
    exact = exact_counts(wave, edges, at[after])
    logged = mv[after] / SIMAVR_MV_PER_COUNT
    err = np.abs(logged - 0.5 - exact)
    harness = np.abs(logged - np.interp(at[after], wave.t, wave.mv) / SIMAVR_MV_PER_COUNT)
    return Alignment(
        n,
        int(wrong.sum()),
        int((wrong & (dist <= 2e-5)).sum()),
        int((recorded != simavr).sum()),
        float(harness.max()),
        float(err.max()),
    )


def interpolation_error(wave: Waveform, edges: Edges) -> float:
    """The most the harness's linear interpolation of the waveform misses the plant by (counts), whatever the
    sampling phase: the exact plant at the midpoint of every interval between waveform points after the first
    step (where a chord is furthest from a smooth curve), against the chord."""
    mid = wave.t[:-1] + 0.5 * np.diff(wave.t)
    mid = mid[(mid > 0) & (np.diff(wave.t) > CYCLE_S)]
    chord = np.interp(mid, wave.t, wave.mv) / SIMAVR_MV_PER_COUNT - 0.5
    return float(np.abs(chord - exact_counts(wave, edges, mid)).max())


# --- the plant at the recording's own instants --------------------------------------------------------------
def plant_frame(fil: FilRun, edges: Edges, wave: Waveform) -> pd.DataFrame:
    """The virtual rig's plant at the FIL recording's own sample instants, as the noise-free load cell counts.

    Integrated through the waveform's points and those instants (:func:`exact_counts`), so it differs from the
    recording only by the waveform's interpolation and the harness's millivolt; before the first step, the
    rest the harness holds. The steps column is pass 1's count at each instant.
    """
    at = sample_instants(fil)
    after = at >= 0
    counts = np.empty(at.shape)
    counts[after] = exact_counts(wave, edges, at[after])
    counts[~after] = wave.mv[0] / SIMAVR_MV_PER_COUNT - 0.5
    counts = np.clip(np.rint(counts), 0, 1023)
    frame = fil.recording.frame[["t_s"]].copy()
    frame["steps"] = np.concatenate([[0], np.cumsum(edges.signs)])[np.searchsorted(edges.t, at, side="right")]
    frame["tension_n"] = (counts - wave.sensor.offset_counts) * wave.sensor.newtons_per_count
    return frame


def one_count_settling_spread(frame: pd.DataFrame, newtons_per_count: float) -> pd.Series:
    """How far each motion's settling time moves when its band is one ADC count wider or narrower (ms).

    A 10-bit load cell resolves the band's edge to a count (about 1.6 % of a 20 mm step's 2.6 N), and a
    settling time is where the tension last leaves the band: a one-count difference between two runs can move
    it by a whole oscillation. This is the settling time's resolution from quantisation alone.
    """
    base = metrics.recording_metrics(frame).set_index("motion")
    spread = {}
    for motion, row in base.iterrows():
        step = abs(row["yf_n"] - row["y0_n"])
        bands = [0.05 + k * newtons_per_count / step for k in (-1, 0, 1)]
        times = [metrics.recording_metrics(frame, band=b).set_index("motion").loc[motion, "settling_ms"]
                 for b in bands]  # fmt: skip
        spread[motion] = float(np.nanmax(times) - np.nanmin(times))
    return pd.Series(spread)


# --- the virtual rig's physics at a given sampling phase ---------------------------------------------------
def virtual_frame(
    edges: Edges, phase_s: float, duration_s: float, params: RigParameters | None = None
) -> Any:
    """The virtual rig (``helpers.virtual.simulate``) on pass 1's edges, sampled at 1 kHz with its samples
    ``phase_s`` (mod 1 ms) after the first edge, as a noise-free load cell counts; 1 s of rest first."""
    t_go = 1.0 - phase_s
    sim = simulate(
        (edges.t, edges.signs), rate_hz=1000, params=params, t_go=t_go, t_end=t_go + duration_s, seed=None
    )
    frame = sim.frame("tension")
    counts = np.clip(np.rint(sim.offset_counts + frame["tension_n"] / sim.newtons_per_count), 0, 1023)
    frame["tension_n"] = (counts - sim.offset_counts) * sim.newtons_per_count
    return frame


def phase_spread(edges: Edges, duration_s: float, n: int = 20) -> pd.DataFrame:
    """How much each metric moves with the sampling phase alone (max - min over ``n`` phases in 1 ms)."""
    tables = [compare_frame(virtual_frame(edges, k * 1e-3 / n, duration_s)) for k in range(n)]
    stacked = pd.concat(tables)
    spread = stacked.groupby(level=0).max() - stacked.groupby(level=0).min()
    return spread.loc[tables[0].index]


# --- the in-process virtual rig, noise-free, for comparison ----------------------------------------------
def in_process(action: str, kwargs: dict[str, Any], tmp: Path, params: RigParameters | None = None) -> Any:
    """The same run on the in-process virtual rig (its plant and a noise-free load cell)."""
    params = params or RigParameters()
    sensor = LoadCell(params, seed=None, noise_rms=0.0)
    name = f"fil-reference-{next(_names)}"
    info = {"parameters": parameters_dict(params), "note": "noise-free load cell, for the FIL comparison"}
    register_world(VirtualWorld(ArmPlant(params), sensor, name=name, info=info))
    try:
        rig = Rig("virtual", default_rig(), _truth(params, sensor), world=name)
        try:
            return _act(rig, action, kwargs, tmp / f"inproc_{action}")
        finally:
            rig.close()
    finally:
        forget_world(name)


def _act(rig: Rig, action: str, kwargs: dict[str, Any], path: Path) -> Any:
    """``rig.run_pulse(**kwargs)`` or ``stream(rig, **kwargs)``, saved at ``path``."""
    if action == "stream":
        return stream(rig, **kwargs, path=path, progress=False)
    return rig.run_pulse(**kwargs, path=path, progress=False)


# --- the two scenarios ------------------------------------------------------------------------------------
def table_i_case(v_mm_s: float = 200.0, x_mm: float = 20.0, t_end_s: float = 10.0):
    """The robust-TDF (ZVD) pulse of Table I: its programme and ``Rig.run_pulse``'s arguments."""
    _, robust = design_tdfs()
    programme, _ = experiment_programme(v_mm_s, x_mm, robust, t_end=t_end_s)
    kwargs = {"v_in_mm_s": v_mm_s, "x_f_mm": x_mm, "shaper": robust, "system": "zvd", "t_end_s": t_end_s}
    return programme, kwargs


def stream_case(v_mm_s: float = 200.0, move_periods: int = 10, hold_s: float = 4.0):
    """A streamed up-hold-down move through the board-loaded ZV shaper: set-points and ``stream``'s
    arguments."""
    zv, _ = design_tdfs()
    hold = round(hold_s * 100)
    mm_s = [0.0] * 10 + [v_mm_s] * move_periods + [0.0] * hold + [-v_mm_s] * move_periods + [0.0] * 10
    shaper = hs.board_shaper(zv)
    kwargs = {"setpoints": mm_s, "shaper": zv, "lead_in_s": 1.0, "tail_s": 4.0}
    return shaper, [velocity_units(v, MM_PER_STEP) for v in mm_s], kwargs


def run_case(which: str, tmp: Path, pace: float = 1.0) -> dict[str, Any]:
    """Passes 1-3 for ``"table-i"`` or ``"stream"`` and the in-process run; the comparison and checks."""
    if which == "table-i":
        programme, kwargs = table_i_case()
        edges = programme_edges(programme)
        action = "run_pulse"
        after_first = kwargs["t_end_s"]  # the first step is 1 s after GO: 1 s to spare
    else:
        shaper, setpoint_units, kwargs = stream_case()
        edges = stream_edges(shaper, setpoint_units)
        action = "stream"
        after_first = edges.t[-1] + shaper.duration_s + kwargs["tail_s"] + 2.0
    wave = tension_waveform(edges, after_first)
    fil = record(wave, action, kwargs, tmp, pace)
    ref = in_process(action, kwargs, tmp)
    at = sample_instants(fil)
    duration = float(at[-1])  # the FIL recording's end, from its first step
    plant = plant_frame(fil, edges, wave)
    return {
        "fil": compare(fil.recording),
        "in_process": compare(ref),
        "plant_at_instants": compare_frame(plant),
        "phase_spread": phase_spread(edges, duration),
        "settling_resolution": one_count_settling_spread(ref.frame, wave.sensor.newtons_per_count),
        "settling_resolution_plant": one_count_settling_spread(plant, wave.sensor.newtons_per_count),
        "alignment": check_alignment(fil, edges, wave),
        "interpolation_error": interpolation_error(wave, edges),
        "recording": fil.recording,
        "reference": ref,
        "wall_s": fil.wall_s,
        "edges": edges,
    }


def _show(which: str, result: dict[str, Any]) -> None:
    print(f"\n== {which}: firmware in the loop (FIL) against the virtual rig (noise-free load cell)")
    table = {
        "FIL": result["fil"],
        "FIL - in-process": result["fil"] - result["in_process"],
        "phase spread": result["phase_spread"],
        "FIL - plant at its instants": result["fil"] - result["plant_at_instants"],
    }
    with pd.option_context("display.width", 250):
        print(pd.concat(table, axis=1).round(3).to_string())
    a = result["alignment"]
    print(
        f"samples {a.samples}; steps column vs pass 1: {a.step_mismatches} differ ({a.near_edge} up to 20 "
        f"us after an edge); ADC counts vs simavr's conversion: {a.adc_mismatches} differ; ADC input vs "
        f"waveform: {a.harness_error:.3f} count at most; vs exact plant: {a.max_count_error:.3f} (the "
        f"waveform's interpolation at any phase: {result['interpolation_error']:.3f}); "
        f"{len(result['edges'].t)} steps; wall {result['wall_s']:.1f} s"
    )
    print("settling moved by one ADC count of band (ms): in-process",
          result["settling_resolution"].round(1).to_dict(), "plant at the instants",
          result["settling_resolution_plant"].round(1).to_dict())  # fmt: skip
    st = result["recording"].meta["scenario"].get("stream")
    if st:
        print(f"stream: {st['n_setpoints']} set-points, periods consecutive: "
              f"{st['periods'] == list(range(1, st['n_setpoints'] + 1))}, FIFO full {st['fifo_full']}, "
              f"underruns {st['underruns']}")  # fmt: skip


def main() -> int:
    """Print the FIL comparison for both scenarios."""
    missing = fwsim.missing_toolchain()
    if missing:
        print(f"firmware toolchain missing ({', '.join(missing)}): {fwsim.INSTALL_HINT}", file=sys.stderr)
        return 1
    subprocess.run(["make", "-C", str(fwsim.FIRMWARE)], check=True, capture_output=True)
    for which in ("table-i", "stream"):
        with tempfile.TemporaryDirectory(prefix="fil-") as tmp:
            _show(which, run_case(which, Path(tmp)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
