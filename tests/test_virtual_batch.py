"""The virtual rig's batch API: many runs per call (threads, lanes), the bits of one fresh plant per run."""

from __future__ import annotations

import numpy as np
import pytest

from helpers.board.programmes import experiment_programme
from helpers.virtual import RigParameters, simulate
from helpers.virtual.batch import BatchRun, PlantPool, lane_groups, run_batch

# short pulses (1.4 s): up at 0.2 s, down at 0.8 s
PROGRAMMES = [experiment_programme(200.0, x, None, 0.2, 0.8, 1.4)[0] for x in (2.0, 4.0, 6.0)]


def test_threads_give_the_bits_of_a_fresh_plant_per_run_in_order():
    soft = RigParameters().replace(k=15000.0)
    cases = [(PROGRAMMES[0], RigParameters(), 1), (PROGRAMMES[1], soft, 2), (PROGRAMMES[2], soft, 3),
             (PROGRAMMES[0], soft, 4)]  # fmt: skip
    runs = [BatchRun(p, params, seed=s, tag=i) for i, (p, params, s) in enumerate(cases)]
    pool = PlantPool()
    results, stats = run_batch(runs, threads=2, pool=pool)
    for run, got in zip(runs, results, strict=True):
        fresh = simulate(run.programme, params=run.params, seed=run.seed)
        assert np.array_equal(got.tension, fresh.tension) and np.array_equal(got.adc, fresh.adc)
        assert got.params == run.params
    # two rigs on at most two threads: at most four plants built, reused for the rest
    assert stats.runs == 4 and 2 <= stats.plants_built <= 4 and pool.built == stats.plants_built
    assert stats.simulate_s > 0 and stats.wall_s > 0
    # in one thread: one plant per rig, kept for the next call
    serial_pool = PlantPool()
    assert run_batch(runs, pool=serial_pool)[1].plants_built == 2
    assert run_batch(runs, pool=serial_pool)[1].plants_built == 0


def test_reduce_runs_in_the_worker_and_its_value_is_kept():
    runs = [BatchRun(p, tag=i) for i, p in enumerate(PROGRAMMES)]
    peaks, stats = run_batch(runs, threads=2, reduce=lambda run, r: (run.tag, float(r.tension.max())))
    assert [t for t, _ in peaks] == [0, 1, 2]
    assert peaks[0][1] < peaks[1][1] < peaks[2][1]  # a longer pull, a higher tension
    assert stats.reduce_s >= 0 and stats.runs == 3


@pytest.mark.parametrize("threads", [0, 1.5, True])
def test_bad_thread_counts_are_refused(threads):
    with pytest.raises(ValueError, match="threads must be a positive integer"):
        run_batch([], threads=threads)


def test_lanes_give_the_bits_of_one_run_per_call_in_order():
    rk4 = RigParameters().with_integrator("rk4")
    soft = rk4.replace(k=15000.0)
    rosw = RigParameters().with_integrator("rosw")
    cases = [(PROGRAMMES[0], rk4), (PROGRAMMES[1], rosw), (PROGRAMMES[2], soft),
             (PROGRAMMES[1], rk4), (PROGRAMMES[0], rosw),
             (PROGRAMMES[2], rk4)]  # fmt: skip
    runs = [BatchRun(p, params, seed=i, tag=i) for i, (p, params) in enumerate(cases)]
    # the RK4 rigs share a call (the soft cable too), the implicit step's two runs another
    assert lane_groups(runs, 4) == [[0, 2, 3, 5], [1, 4]]
    assert lane_groups(runs, 2) == [[0, 2], [1, 4], [3, 5]]
    one, stats1 = run_batch(runs, threads=2)
    many, stats4 = run_batch(runs, threads=2, lanes=4)
    assert stats1.kernel_calls == 6 and stats4.kernel_calls == 2 and stats4.runs == 6
    for a, b in zip(one, many, strict=True):
        assert a.params == b.params and a.max_rotor_lag_steps == b.max_rotor_lag_steps
        for name in ("tension", "output", "adc", "steps", "angles"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), name
    with pytest.raises(ValueError, match="lanes must be an integer from 1 to 8"):
        run_batch(runs, lanes=9)
