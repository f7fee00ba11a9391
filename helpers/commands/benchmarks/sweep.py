"""Speed of sweeps: runs per second on 1 and 2 workers of a local Dask cluster, and what Dask costs.

The tasks are realistic: 12 s runs of the paper's pulse (200 mm/s, 20 mm) with three shapers (ZVD, EI,
2-hump EI) over eight design frequency errors, 24 runs chunked as a sweep chunks them by default (4 runs per
chunk, 6 tasks). Measured in one call, each configuration best of ``repeats`` (the machine may be shared):

- a **bare loop** over the chunks in this process (:func:`helpers.research.sweep.runs.run_chunk`, no Dask),
  with the time per run inside :func:`helpers.virtual.simulate` (the integration) and outside it (design,
  programme, metrics): the per-run overhead;
- **runs per CPU second** of one thread: the sweep's own tasks with one run per kernel call and with lanes
  (a chunk's runs in the SIMD lanes of one call, :mod:`helpers.virtual.lanes`), and the batch API alone on
  eight of those runs at 1, 4 and 8 runs per call, each integrator (RK4, the implicit step);
- the **batch API** in one process, 1 thread and 2 threads (the kernels release the GIL);
- a **local cluster** of 1 worker and of 2 workers (processes, one thread each), each started and warmed up
  (each worker has loaded the compiled kernels and run a chunk) before the clock starts, and each alone on
  the machine while it is measured: the bare loop and the 1-worker cluster take turns, ``repeats`` times, then
  that cluster closes and the 2-worker cluster runs. (With both clusters alive, the idle workers of one took
  CPU from the other on 2 cores: the 1-worker figure came out 6-9 % slower than the bare loop, against -1 to
  +3 % with its cluster alone.)

Figures: runs per second, the scaling ratio 2 workers / 1 worker, Dask's overhead on 1 worker against the
bare loop (in % of the task time), and simulated seconds per wall second in aggregate.
"""

from __future__ import annotations

import os
import time
from typing import Any

from helpers.research.sweep.definition import SweepDefinition
from helpers.research.sweep.execute import local_client
from helpers.research.sweep.runs import LANES, run_chunk, sweep_runs
from helpers.virtual import RigParameters
from helpers.virtual.batch import run_batch

__all__ = ["BENCH_DEFINITION", "run_sweep_benchmark"]

BENCH_DEFINITION = SweepDefinition(
    name="bench",
    shapers=("zvd", "ei", "2-hump-ei"),
    grid={"freq_error": [-0.15, -0.1, -0.05, 0.0, 0.05, 0.1, 0.15, 0.2]},
)
"""The benchmark's sweep: 24 runs of 12 s in 6 chunks (the default chunking)."""


def _load() -> str:
    try:
        return "load average " + ", ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:  # pragma: no cover - not on every platform
        return "load average unavailable"


def _on_cluster(client: Any, text: str, chunks: int) -> float:
    """Wall time of all chunks on a warmed cluster."""
    t0 = time.perf_counter()
    client.gather([client.submit(run_chunk, text, c, pure=False) for c in range(chunks)])
    return time.perf_counter() - t0


def _bare(text: str, chunks: int) -> tuple[float, float]:
    """Wall time of all chunks in a loop here, and the part of it inside ``simulate``."""
    t0 = time.perf_counter()
    inside = sum(run_chunk(text, c)["stats"]["simulate_s"] for c in range(chunks))
    return time.perf_counter() - t0, inside


BATCH_RUNS = range(8)
"""The benchmark sweep's runs given to the batch API (the first eight: ZVD, EI, 2-hump EI at three errors)."""


def _cpu(fn: Any, repeats: int) -> float:
    """Least CPU time of this process over ``repeats`` calls of ``fn``."""
    best = float("inf")
    for _ in range(repeats):
        c0 = time.process_time()
        fn()
        best = min(best, time.process_time() - c0)
    return best


def _per_cpu_second(text: str, chunks: int, runs: int, repeats: int) -> dict[str, dict[int, float]]:
    """Runs per CPU second of one thread, the sweep's tasks and the batch API (module docstring).

    The sweep's tasks one run per call and with lanes take turns, so that a change in the machine's load hits
    both alike.
    """
    out: dict[str, dict[int, float]] = {"sweep": {1: float("inf"), LANES: float("inf")}}
    for c in range(chunks):  # every rig's statics and each lane width compiled or loaded before timing
        run_chunk(text, c, lanes=1)
        run_chunk(text, c)
    for _ in range(repeats):
        for lanes in (1, LANES):
            cpu = _cpu(lambda: [run_chunk(text, c, lanes=lanes) for c in range(chunks)], 1)  # noqa: B023
            out["sweep"][lanes] = min(out["sweep"][lanes], cpu)
    out["sweep"] = {k: runs / v for k, v in out["sweep"].items()}
    for integrator in ("rk4", "rosw"):
        batch = sweep_runs(text, BATCH_RUNS, RigParameters().with_integrator(integrator))
        for lanes in (1, 4, 8):
            run_batch(batch, lanes=lanes)
        out[integrator] = {lanes: len(batch) / _cpu(lambda: run_batch(batch, lanes=lanes), repeats)  # noqa: B023
                           for lanes in (1, 4, 8)}  # fmt: skip
    return out


def run_sweep_benchmark(repeats: int = 2, quiet: bool = False) -> dict[str, Any]:
    """Measure and print the sweep figures (module docstring); the last line names the scaling ratio.

    Parameters
    ----------
    repeats : int
        Repeats of each configuration (the best is reported).
    quiet : bool
        Do not print.

    Returns
    -------
    dict
        ``runs``, ``bare_runs_per_s``, ``runs_per_s_1``, ``runs_per_s_2``, ``scaling``,
        ``dask_overhead_pct``, ``sim_s_per_wall_s_2``, ``simulate_ms_per_run``, ``outside_ms_per_run``,
        ``batch_thread_scaling``, ``cluster_start_s``, ``runs_per_cpu_s`` (one thread: ``"sweep"`` -> runs per
        kernel call (1 or ``LANES``) -> runs per CPU second of the sweep's tasks; ``"rk4"``, ``"rosw"`` -> 1,
        4, 8 -> the batch API's).
    """
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats!r}")
    d = BENCH_DEFINITION.resolved()
    text = d.to_json()
    runs, chunks, t_sim = d.n_runs, d.n_chunks, d.run["t_end_s"]
    say = (lambda *a: None) if quiet else print
    say(f"Sweep tasks: {runs} runs of {t_sim:.0f} s (200 mm/s, 20 mm; ZVD, EI, 2-hump EI x 8 design errors), "
        f"{chunks} chunks of {d.chunk_runs}; {os.cpu_count()} cores; {_load()}")  # fmt: skip
    run_chunk(text, 0)  # load the kernels here too
    bare, inside, wall1, wall2, started = float("inf"), 0.0, float("inf"), float("inf"), 0.0
    t0 = time.perf_counter()
    with local_client(1) as one:
        one.run(run_chunk, text, 0)  # the worker loads the kernels and runs one chunk
        started += time.perf_counter() - t0
        # interleaved, so that a change in the machine's load hits both alike
        for _ in range(repeats):
            wall, sim = _bare(text, chunks)
            if wall < bare:
                bare, inside = wall, sim
            wall1 = min(wall1, _on_cluster(one, text, chunks))
    t0 = time.perf_counter()
    with local_client(2) as two:
        two.run(run_chunk, text, 0)
        started += time.perf_counter() - t0
        for _ in range(repeats):
            wall2 = min(wall2, _on_cluster(two, text, chunks))
    sim_ms, outside_ms = 1e3 * inside / runs, 1e3 * (bare - inside) / runs
    say(f"  bare loop (no Dask), 1 core: {runs / bare:.2f} runs/s ({bare:.2f} s); per run {sim_ms:.0f} ms in "
        f"simulate (the integration) + {outside_ms:.1f} ms outside it (design, programme, metrics): "
        f"{100 * (bare - inside) / bare:.1f} %")  # fmt: skip

    per_cpu = _per_cpu_second(text, chunks, runs, repeats)
    one, lanes = per_cpu["sweep"][1], per_cpu["sweep"][LANES]
    say(f"  runs per CPU second, one thread, the sweep's own tasks (run_chunk: design, run, metrics; the "
        f"default integrator, as the sweeps run): one run per kernel call {one:.2f}, with lanes (a chunk's "
        f"{d.chunk_runs} runs in one call) {lanes:.2f} -> {lanes / one:.2f}x per core (aim >= 3x)")
    for integrator in ("rk4", "rosw"):
        r = per_cpu[integrator]
        name = "RK4" if integrator == "rk4" else "implicit step"
        say(f"  runs per CPU second, one thread, the batch API ({len(BATCH_RUNS)} of those runs, {name}): "
            f"one per call {r[1]:.2f}, 4 per call {r[4]:.2f} ({r[4] / r[1]:.2f}x), 8 per call {r[8]:.2f} "
            f"({r[8] / r[1]:.2f}x)")  # fmt: skip
    rk4_1, rosw_1 = per_cpu["rk4"][1], per_cpu["rosw"][1]
    say(f"  (one run per call: the implicit step {rosw_1 / rk4_1:.2f}x RK4; every lane is bit for bit its "
        "run alone: tests/test_lanes.py)")  # fmt: skip
    batch = sweep_runs(text, BATCH_RUNS)[:4]
    run_batch(batch[:2], threads=2)
    walls, busy = {}, 0.0
    for threads in (1, 2):
        walls[threads] = float("inf")
        for _ in range(repeats):
            c0 = time.process_time()
            wall = run_batch(batch, threads=threads)[1].wall_s
            if wall < walls[threads]:
                walls[threads], busy = wall, (time.process_time() - c0) / wall
    thread_scaling = walls[1] / walls[2]
    # CPU time over wall time of the 2-thread batch: 2 when both threads ran at once (the kernels release the
    # GIL), 1 when another process held the second core
    say(f"  batch API, one process, 4 runs one per call: 1 thread {walls[1]:.2f} s, 2 threads "
        f"{walls[2]:.2f} s -> {thread_scaling:.2f}x (cores busy with the 2 threads: {busy:.2f})")  # fmt: skip

    rate0, rate1, rate2 = runs / bare, runs / wall1, runs / wall2
    overhead = 100 * (wall1 - bare) / bare
    scaling = rate2 / rate1
    say(f"  local Dask cluster, 1 worker: {rate1:.2f} runs/s ({wall1:.2f} s); scheduling overhead against "
        f"the bare loop {overhead:+.1f} % of task time")  # fmt: skip
    say(f"  local Dask cluster, 2 workers: {rate2:.2f} runs/s ({wall2:.2f} s); {runs * t_sim / wall2:.0f} "
        f"simulated s per wall s in aggregate")  # fmt: skip
    say(f"  cluster start-up and warm-up (not timed above): {started:.1f} s for both clusters")
    say(f"  after: {_load()}")
    say(f"scaling ratio 2 workers / 1 worker: {scaling:.2f}x (target >= 1.8)")
    return {
        "runs": runs,
        "bare_runs_per_s": rate0,
        "runs_per_s_1": rate1,
        "runs_per_s_2": rate2,
        "scaling": scaling,
        "dask_overhead_pct": overhead,
        "sim_s_per_wall_s_2": runs * t_sim / wall2,
        "simulate_ms_per_run": sim_ms,
        "outside_ms_per_run": outside_ms,
        "batch_thread_scaling": thread_scaling,
        "cluster_start_s": started,
        "runs_per_cpu_s": per_cpu,
    }


if __name__ == "__main__":  # pragma: no cover
    run_sweep_benchmark()
