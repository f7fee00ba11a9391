"""One chunk of a sweep: design each run's shaper, build its programme, run the virtual rig, measure it.

:func:`run_chunk` is the task a sweep sends to a Dask worker (or runs in a loop). It rebuilds the definition
from its canonical JSON (cached per process), runs the chunk's runs through
:func:`helpers.virtual.batch.run_batch` (runs that can share a kernel call in its SIMD lanes, :data:`LANES`
at a time; otherwise one plant per thread and rig, reused) and returns small arrays
(:data:`VARIABLES`). Per run and move (Up, Down):

- ``residual_pct``: residual vibration of the **true** tension of the measured cable
  (:func:`helpers.paper.metrics.residual_vibration`: half the peak-to-peak 0.1-1.1 s after the move's last
  step, in
  % of the step ``yf - y0``; ``y0`` the median of the 0.5 s before the move, ``yf`` the median of the last
  1.0 s of the motion's window, as Table II defines them), and ``step_n`` = ``yf - y0``;
- per noise seed, what a user reads from the ADC: ``residual_adc_pct`` and the Table II metrics ``peak_n``,
  ``overshoot_pct``, ``settling_ms`` (:func:`helpers.paper.metrics.motion_metrics`, 5 % band);
- ``move_duration_s`` (from the move's start, ``t_up`` or ``t_down``, to its last step in the quantised
  programme: the shaper's duration + ``t_p``) and
  ``shaper_duration_s`` (``move_duration_s - x_f / v_in``).

Per run: ``max_rotor_lag_steps`` (health), ``status`` (0 done, 1 the design or the programme was refused at
this point, 2 the integration failed) and the rig's lowest mode at rest (``rig_omega_d_rad_s``, ``rig_zeta``:
the linearised rig as it runs, once per distinct rig and process). Every number depends only on the run, not
on the chunking, the worker or the thread count.
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from helpers.board.programmes import experiment_programme
from helpers.paper import metrics
from helpers.recordings import counts_to_newtons
from helpers.research.modemap import ModeMap
from helpers.research.sweep.definition import SweepDefinition
from helpers.research.sweep.shaping import ShapingContext, shaping_for
from helpers.research.sweep.variables import VARIABLES
from helpers.virtual import LoadCell, RigParameters, linearise
from helpers.virtual.batch import BatchRun, BatchStats, run_batch
from helpers.virtual.simulate import SimResult

__all__ = ["LANES", "run_chunk", "sweep_runs", "rig_for", "rig_mode", "context_for"]


@functools.lru_cache(maxsize=8)
def _definition(text: str) -> SweepDefinition:
    return SweepDefinition.from_dict(json.loads(text))


@functools.lru_cache(maxsize=8)
def context_for(text: str) -> ShapingContext:
    """The shaping context of a resolved definition's canonical JSON (cached per process)."""
    d = _definition(text)
    if d.identified is None or not isinstance(d.mode_map, dict):
        raise ValueError("run_chunk needs a resolved definition (SweepDefinition.resolved())")
    return ShapingContext(
        float(d.identified["omega_d"]),
        float(d.identified["zeta"]),
        ModeMap.from_dict(d.mode_map),
        d.custom_shapers,
    )


def rig_for(point: dict[str, Any], base: RigParameters | None = None) -> RigParameters:
    """The rig of a run: the tuned rig with its disc mass, cable stiffness and damping scaled."""
    p = RigParameters() if base is None else base
    s = float(point["damping_scale"])
    return p.replace(
        disc_mass=p.disc_mass * float(point["disc_mass_scale"]),
        k=p.k * float(point["stiffness_scale"]),
        alpha=p.alpha * s,
        beta_chord=p.beta_chord * s,
    )


@functools.lru_cache(maxsize=256)
def rig_mode(params: RigParameters) -> tuple[float, float]:
    """``(omega_d, zeta)`` of the rig's lowest mode at rest, rotor free (cached per process)."""
    m = linearise(params, 0.0, rotor="free").modes()
    return float(m["omega_d"].iloc[0]), float(m["zeta"].iloc[0])


@dataclass(frozen=True)
class _Job:
    index: int  # position in the chunk
    point: dict[str, Any]
    up_start: float
    up_end: float
    down_start: float
    down_end: float


def _windows(times: np.ndarray, t_down: float) -> tuple[float, float, float, float]:
    up = times[times < t_down - 1e-9]
    down = times[times >= t_down - 1e-9]
    return float(up[0]), float(up[-1]), float(down[0]), float(down[-1])


def _measure(
    job: _Job, result: SimResult, seeds: tuple[int, ...], run_cfg: dict[str, float]
) -> dict[str, np.ndarray]:
    t, y = result.t, result.tension
    t_end = run_cfg["t_end_s"]
    spans = ((job.up_start, job.down_start, job.up_end, "Up"), (job.down_start, t_end, job.down_end, "Down"))
    nominal = (run_cfg["t_up_s"], run_cfg["t_down_s"])
    out = {k: np.full((len(seeds), 2), np.nan) for k in ("residual_adc_pct", "peak_n", "overshoot_pct",
                                                           "settling_ms")}  # fmt: skip
    out.update({k: np.full(2, np.nan) for k in ("residual_pct", "step_n", "move_duration_s",
                                                "shaper_duration_s")})  # fmt: skip
    t_p = float(job.point["amplitude_mm"]) / float(job.point["speed_mm_s"])
    sensor = LoadCell(result.params, seed=seeds[0])
    for m, (start, end, move_end, motion) in enumerate(spans):
        true = metrics.motion_metrics(t, y, start, end, motion)  # y0 and yf as Table II defines them
        y0, yf = true.y0, true.yf
        out["residual_pct"][m] = metrics.residual_vibration(t, y, move_end, y0, yf)
        out["step_n"][m] = yf - y0
        out["move_duration_s"][m] = move_end - nominal[m]
        out["shaper_duration_s"][m] = move_end - nominal[m] - t_p
        for k, seed in enumerate(seeds):
            adc = result.adc if k == 0 else _reseeded(sensor, seed, result.output)
            newtons = counts_to_newtons(adc, result.newtons_per_count, result.offset_counts)
            mm = metrics.motion_metrics(t, newtons, start, end, motion, clipped=metrics.clipped_samples(adc))
            out["peak_n"][k, m] = mm.peak
            out["overshoot_pct"][k, m] = mm.overshoot_pct
            out["settling_ms"][k, m] = mm.settling_ms
            if math.isfinite(mm.y0) and math.isfinite(mm.yf):
                out["residual_adc_pct"][k, m] = metrics.residual_vibration(t, newtons, move_end, mm.y0, mm.yf)
    out["max_rotor_lag_steps"] = np.array(result.max_rotor_lag_steps)
    return out


def _reseeded(sensor: LoadCell, seed: int, output: np.ndarray) -> np.ndarray:
    sensor.reseed(seed)
    return sensor.counts(output)


LANES = 8
"""Runs of a chunk per kernel call (:func:`helpers.virtual.batch.run_batch`'s ``lanes``): its SIMD lanes."""


def _programme(point: dict[str, Any], ctx: ShapingContext, run_cfg: dict[str, float]) -> Any:
    """A run's programme: its shaper designed, the pulse quantised (``ValueError`` if either is refused)."""
    shaping = shaping_for(point["shaper"], point, ctx)
    prog, _ = experiment_programme(
        point["speed_mm_s"], point["amplitude_mm"], shaping, run_cfg["t_up_s"], run_cfg["t_down_s"],
        run_cfg["t_end_s"],
    )  # fmt: skip
    return prog


def sweep_runs(definition_json: str, runs: range, base: RigParameters | None = None) -> list[BatchRun]:
    """Runs of a resolved definition as :class:`~helpers.virtual.batch.BatchRun` (for benchmarks).

    The flat indices ``runs``, each on its rig (:func:`rig_for` on ``base``, default the tuned rig) with its
    programme and first seed; runs whose design is refused are left out.
    """
    d = _definition(definition_json)
    ctx = context_for(definition_json)
    sample = d.sample_values()
    out = []
    for flat in runs:
        point = d.point(flat, sample)
        try:
            prog = _programme(point, ctx, d.run)
        except ValueError:
            continue
        out.append(BatchRun(prog, rig_for(point, base), d.seeds[0], d.run["t_end_s"], d.run["rate_hz"], flat))
    return out


def run_chunk(definition_json: str, chunk: int, threads: int = 1, lanes: int = LANES) -> dict[str, Any]:
    """Run chunk ``chunk`` of a resolved definition (its canonical JSON) and return its arrays.

    Parameters
    ----------
    definition_json : str
        :meth:`SweepDefinition.to_json` of a :meth:`~SweepDefinition.resolved` definition.
    chunk : int
        Which chunk.
    threads : int
        Threads of the batch inside this task (the kernels release the GIL).
    lanes : int
        Runs per kernel call (1: one at a time); the numbers are the same bits either way.

    Returns
    -------
    dict
        ``chunk``, ``runs`` (the flat run indices), one array per :data:`VARIABLES` entry with the runs
        first (then seed, then move, as the entry says), ``messages`` (run index -> why it was refused) and
        ``stats`` (a :class:`helpers.virtual.batch.BatchStats` as a dict: where the time went).
    """
    d = _definition(definition_json)
    ctx = context_for(definition_json)
    runs = d.chunk_range(chunk)
    seeds = d.seeds
    n, s = len(runs), len(seeds)
    res: dict[str, np.ndarray] = {}
    for name, (extra, _, _) in VARIABLES.items():
        shape = (n, *((s,) if "seed" in extra else ()), *((2,) if "move" in extra else ()))
        res[name] = np.full(shape, np.nan)
    res["status"] = np.zeros(n, dtype=np.int8)
    messages: dict[int, str] = {}
    sample = d.sample_values()
    base = RigParameters()
    batch: list[BatchRun] = []
    run_cfg = d.run
    for i, flat in enumerate(runs):
        point = d.point(flat, sample)
        params = rig_for(point, base)
        res["rig_omega_d_rad_s"][i], res["rig_zeta"][i] = rig_mode(params)
        try:
            prog = _programme(point, ctx, run_cfg)
        except ValueError as exc:
            res["status"][i] = 1
            messages[flat] = f"{point['shaper']}: {exc}"
            continue
        times, _ = prog.step_times()
        job = _Job(i, point, *_windows(times, run_cfg["t_down_s"]))
        batch.append(BatchRun(prog, params, seeds[0], run_cfg["t_end_s"], run_cfg["rate_hz"], job))

    def reduce(run: BatchRun, result: SimResult) -> tuple[_Job, dict[str, np.ndarray]]:
        return run.tag, _measure(run.tag, result, seeds, run_cfg)

    stats = BatchStats()
    try:
        width = min(lanes, max(1, len(batch)))
        outputs, stats = run_batch(batch, threads=threads, reduce=reduce, lanes=width)
    except FloatingPointError:  # one run at a time, to mark only the failing ones
        outputs = []
        for run in batch:
            try:
                out, st = run_batch([run], reduce=reduce)
                outputs += out
                stats.add(st)
            except FloatingPointError as exc:
                res["status"][run.tag.index] = 2
                messages[runs[run.tag.index]] = f"{run.tag.point['shaper']}: {exc}"
    for job, values in outputs:
        for name, arr in values.items():
            res[name][job.index] = arr
    return {"chunk": int(chunk), "runs": np.arange(runs.start, runs.stop), **res, "messages": messages,
            "stats": vars(stats).copy()}  # fmt: skip
