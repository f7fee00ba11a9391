"""Many runs of the virtual rig per call: a thread pool over plants that are built once and reused.

The compiled kernels release the GIL (``nogil=True``), so plants integrate in parallel in threads of one
process. :func:`run_batch` runs a list of :class:`BatchRun` on ``threads`` threads; each thread keeps its own
:class:`~helpers.virtual.plant.ArmPlant` per distinct :class:`~helpers.virtual.parameters.RigParameters`
(:class:`PlantPool`; the threads themselves are kept for the process, so plants outlive a call) and
:func:`~helpers.virtual.simulate.simulate` resets it before every run, so a result
depends only on its run, never on the thread, the order or the thread count (the same bits as a fresh
plant). An optional ``reduce`` function turns each :class:`~helpers.virtual.simulate.SimResult` into what
the caller keeps (for example a few metrics), in the same thread, so a batch holds no more time series than
it has threads. With ``lanes`` > 1, runs that can share a kernel call run several at once in its SIMD lanes
(:func:`~helpers.virtual.simulate.simulate_lanes`: each lane the same bits as its run alone).
:class:`BatchStats` says where the time went: inside :func:`simulate` (the integration and the ADC), in
``reduce``, and building plants.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

from helpers.virtual.parameters import RigParameters
from helpers.virtual.plant import LANE_WIDTHS, ArmPlant, lane_group
from helpers.virtual.simulate import SimResult, programme_steps, simulate, simulate_lanes

__all__ = ["BatchRun", "BatchStats", "PlantPool", "lane_groups", "run_batch"]


@dataclass(frozen=True)
class BatchRun:
    """One run of a batch: what :func:`helpers.virtual.simulate` needs.

    Attributes
    ----------
    programme : Programme or (times_s, signs)
        What the stepper executes (anything :func:`~helpers.virtual.simulate.simulate` accepts).
    params : RigParameters
        The rig.
    seed : int or None
        Seed of the load-cell noise.
    t_end : float or None
        End of the run, s (default the programme's end).
    rate_hz : float
        Sample rate, Hz.
    tag : object
        Anything the caller wants back with the result (e.g. an index).
    """

    programme: Any
    params: RigParameters = field(default_factory=RigParameters)
    seed: int | None = 0
    t_end: float | None = None
    rate_hz: float = 1000.0
    tag: Any = None


@dataclass
class BatchStats:
    """Where a batch's time went (seconds of thread time, summed over the threads).

    Attributes
    ----------
    runs : int
        Runs done.
    kernel_calls : int
        Calls of the kernel that did them (fewer than ``runs`` with lanes).
    simulate_s : float
        Time inside :func:`~helpers.virtual.simulate.simulate` (the integration, the sample grid, the ADC).
    reduce_s : float
        Time in the ``reduce`` function.
    build_s : float
        Time building plants (once per thread and rig).
    plants_built : int
        Plants built.
    wall_s : float
        Wall time of the call.
    threads : int
        Threads used.
    """

    runs: int = 0
    kernel_calls: int = 0
    simulate_s: float = 0.0
    reduce_s: float = 0.0
    build_s: float = 0.0
    plants_built: int = 0
    wall_s: float = 0.0
    threads: int = 1

    def add(self, other: BatchStats) -> None:
        """Accumulate another batch's figures (wall times add up)."""
        self.runs += other.runs
        self.kernel_calls += other.kernel_calls
        self.simulate_s += other.simulate_s
        self.reduce_s += other.reduce_s
        self.build_s += other.build_s
        self.plants_built += other.plants_built
        self.wall_s += other.wall_s


class PlantPool:
    """Plants kept per thread and per rig, built on first use and reused (each run resets its plant).

    Parameters
    ----------
    max_plants : int
        Plants kept per thread; the least recently used one is dropped beyond this.
    """

    def __init__(self, max_plants: int = 4) -> None:
        if max_plants < 1:
            raise ValueError(f"max_plants must be >= 1, got {max_plants!r}")
        self.max_plants = int(max_plants)
        self._local = threading.local()
        self._lock = threading.Lock()
        self.built = 0
        self.build_s = 0.0

    def plant(self, params: RigParameters) -> ArmPlant:
        """The calling thread's plant for ``params`` (built now if it has none)."""
        cache: OrderedDict[RigParameters, ArmPlant] | None = getattr(self._local, "cache", None)
        if cache is None:
            cache = self._local.cache = OrderedDict()
        plant = cache.get(params)
        if plant is not None:
            cache.move_to_end(params)
            return plant
        t0 = time.perf_counter()
        plant = ArmPlant(params)
        with self._lock:
            self.built += 1
            self.build_s += time.perf_counter() - t0
        cache[params] = plant
        while len(cache) > self.max_plants:
            cache.popitem(last=False)
        return plant


_SHARED_POOL = PlantPool()
"""The pool :func:`run_batch` uses by default: plants survive from one batch to the next in a process."""

_EXECUTORS: dict[int, ThreadPoolExecutor] = {}
_EXECUTORS_LOCK = threading.Lock()


def _executor(threads: int) -> ThreadPoolExecutor:
    """A thread pool of ``threads`` kept for the process, so its threads (and their plants) are reused."""
    with _EXECUTORS_LOCK:
        ex = _EXECUTORS.get(threads)
        if ex is None:
            ex = _EXECUTORS[threads] = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="rig-batch")
        return ex


def lane_groups(runs: Sequence[BatchRun], lanes: int) -> list[list[int]]:
    """The runs' indices cut into groups of up to ``lanes`` that can share a kernel call, in order.

    Runs share a call when their rigs share :func:`helpers.virtual.plant.lane_group` and their sample times
    (rate and end) are the same; each group takes the next runs of its kind as they come.
    """
    groups: list[list[int]] = []
    open_group: dict[tuple, list[int]] = {}
    for i, run in enumerate(runs):
        end = run.t_end if run.t_end is not None else programme_steps(run.programme)[2]
        key = (lane_group(run.params), float(run.rate_hz), float(end))
        group = open_group.get(key)
        if group is None or len(group) >= lanes:
            group = open_group[key] = []
            groups.append(group)
        group.append(i)
    return groups


def run_batch(
    runs: Sequence[BatchRun],
    threads: int = 1,
    reduce: Callable[[BatchRun, SimResult], Any] | None = None,
    pool: PlantPool | None = None,
    lanes: int = 1,
) -> tuple[list[Any], BatchStats]:
    """Run every run of ``runs`` on the virtual rig, ``threads`` at a time, and return the results in order.

    Parameters
    ----------
    runs : sequence of BatchRun
        The runs.
    threads : int
        Threads (1: in the calling thread). The kernels release the GIL, so up to one per core helps.
    reduce : callable, optional
        ``reduce(run, result)`` computed in the worker thread; its return value is kept instead of the
        :class:`~helpers.virtual.simulate.SimResult`.
    pool : PlantPool, optional
        Where plants are kept (default: one pool shared by every batch of this process).
    lanes : int
        Runs per kernel call (1: one plant per run; up to ``max(LANE_WIDTHS)``: runs that can share a call,
        :func:`lane_groups`, run in its SIMD lanes, :func:`~helpers.virtual.simulate.simulate_lanes`). The
        results are the same bits either way.

    Returns
    -------
    (list, BatchStats)
        One entry per run, in the order of ``runs``, and the time spent.

    Raises
    ------
    ValueError
        ``threads`` below 1, ``lanes`` outside 1..8, or a run that :func:`~helpers.virtual.simulate.simulate`
        refuses.
    """
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise ValueError(f"threads must be a positive integer, got {threads!r}")
    if isinstance(lanes, bool) or not isinstance(lanes, int) or not 1 <= lanes <= max(LANE_WIDTHS):
        raise ValueError(f"lanes must be an integer from 1 to {max(LANE_WIDTHS)}, got {lanes!r}")
    pool = _SHARED_POOL if pool is None else pool
    built0, build0 = pool.built, pool.build_s
    stats = BatchStats(threads=threads)
    lock = threading.Lock()

    def one(group: list[int]) -> list[Any]:
        t0 = time.perf_counter()
        if len(group) == 1:
            run = runs[group[0]]
            plant = pool.plant(run.params)
            t0 = time.perf_counter()
            results = [simulate(run.programme, run.rate_hz, t_end=run.t_end, seed=run.seed, plant=plant)]
        else:
            chosen = [runs[i] for i in group]
            first = chosen[0]
            results = simulate_lanes([r.programme for r in chosen], [r.params for r in chosen], first.rate_hz,
                                     first.t_end, [r.seed for r in chosen])  # fmt: skip
        t1 = time.perf_counter()
        pairs = zip(group, results, strict=True)
        out = results if reduce is None else [reduce(runs[i], r) for i, r in pairs]
        t2 = time.perf_counter()
        with lock:
            stats.runs += len(group)
            stats.kernel_calls += 1
            stats.simulate_s += t1 - t0
            stats.reduce_s += t2 - t1
        return out

    groups = lane_groups(runs, lanes) if lanes > 1 else [[i] for i in range(len(runs))]
    start = time.perf_counter()
    if threads == 1 or len(groups) <= 1:
        done = [one(g) for g in groups]
    else:
        done = list(_executor(threads).map(one, groups))
    results: list[Any] = [None] * len(runs)
    for group, outs in zip(groups, done, strict=True):
        for i, out in zip(group, outs, strict=True):
            results[i] = out
    stats.wall_s = time.perf_counter() - start
    stats.plants_built = pool.built - built0
    stats.build_s = pool.build_s - build0
    return results, stats
