"""The virtual rig's batch API: many runs per call in threads, the same bits as one fresh plant per run."""

from __future__ import annotations

import numpy as np
import pytest

from helpers.board.programmes import experiment_programme
from helpers.virtual import RigParameters, simulate
from helpers.virtual.batch import BatchRun, PlantPool, run_batch

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
