"""Several worlds' plants in lockstep (``helpers.virtual.emulator.lockstep``): each gets its bits alone."""

import numpy as np
import pytest

from helpers.board.programmes import experiment_programme
from helpers.virtual import ArmPlant, RigParameters
from helpers.virtual.emulator.lockstep import Lockstep
from helpers.virtual.spatial.plant import SpatialPlant
from helpers.virtual.spatial.rig import four_tendon_rig


def _calls(k: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Session ``k``'s plant calls: its own clock, chunk lengths, sample count per call and programme."""
    v, x = (200.0, 300.0, 100.0)[k], (20.0, 10.0, 15.0)[k]
    st, sg = experiment_programme(v, x, None, 0.2, 0.8, 1.2)[0].step_times()
    rate, chunk = (1000.0, 500.0, 800.0)[k], (0.05, 0.031, 0.07)[k]
    t = np.arange(1, int(1.2 * rate) + 1) / rate + k * 1.7e-4
    calls, t0 = [], 0.0
    for end in np.arange(chunk, 1.2 + 1e-9, chunk):
        ts = t[(t > t0) & (t <= end)]
        if ts.size:
            sel = (st > t0) & (st <= ts[-1])
            calls.append((ts, st[sel], sg[sel]))
            t0 = ts[-1]
    return calls[: (len(calls), len(calls) - 5, len(calls))[k]]  # session 1 ends early: its lane is parked


def test_sessions_in_lockstep_get_the_outputs_they_get_alone():
    rigs = [RigParameters().replace(k=RigParameters().k * f) for f in (1.0, 0.9, 1.1)]
    lockstep = Lockstep(rigs)

    def session(k):
        plant = lockstep.plant(k)
        return [plant.advance(*c) for c in _calls(k)]

    got = lockstep.run([lambda k=k: session(k) for k in range(3)])
    for k, rig in enumerate(rigs):
        plant = ArmPlant(rig)
        alone = [plant.advance(*c) for c in _calls(k)]
        assert len(got[k]) == len(alone)
        for a, b in zip(got[k], alone, strict=True):
            assert np.array_equal(a.view(np.int64), b.view(np.int64)), k
    assert lockstep.kernel_calls > lockstep.rounds  # calls of unequal sample counts were served in pieces


def test_a_session_that_fails_raises_and_the_others_finish():
    lockstep = Lockstep([RigParameters()] * 2)
    done = []

    def good():
        plant = lockstep.plant(0)
        for c in _calls(0)[:4]:
            plant.advance(*c)
        done.append(True)

    def bad():
        lockstep.plant(1).advance([0.002, 0.001])  # not increasing

    with pytest.raises(ValueError, match="strictly increasing"):
        lockstep.run([good, bad])
    assert done == [True]


def _outcomes(plant, calls) -> list:
    """Each call's outputs (their bits), or the message of the error it raised; the session goes on."""
    got = []
    for c in calls:
        try:
            got.append(plant.advance(*c).view(np.int64).tolist())
        except FloatingPointError as exc:
            got.append(str(exc))
    return got


def test_an_unstable_lane_fails_its_own_session_only_as_its_plant_alone():
    """Lane 1's step is far too long for RK4: its calls raise from about 0.1 s on (every later one too, as
    alone), while lanes 0 and 2, in the same kernel calls, get the bits they get alone."""
    rk4 = RigParameters().with_integrator("rk4")
    rigs = [rk4, rk4.replace(max_step=1e-3), rk4.replace(k=rk4.k * 1.1)]
    lockstep = Lockstep(rigs)
    got = lockstep.run([lambda k=k: _outcomes(lockstep.plant(k), _calls(k)) for k in range(3)])
    for k, rig in enumerate(rigs):
        assert got[k] == _outcomes(ArmPlant(rig), _calls(k)), k
    errors = [o for o in got[1] if isinstance(o, str)]
    assert errors and got[1][0] != errors[0] and got[1][-1] == errors[-1]  # fine at first, unstable after
    assert not any(isinstance(o, str) for o in got[0] + got[2])


# ---- several tendons: the spatial twin's plants in lockstep -----------------------------------------------
def _spatial_calls(k: int) -> list[tuple[np.ndarray, ...]]:
    """Session ``k``'s calls to a four-tendon plant: its own clock, chunks and steps of its own tendons."""
    rng = np.random.default_rng(k)
    n = 40 + 10 * k
    st = np.sort(rng.uniform(0.01, 0.3, n))
    sk = rng.integers(0, 4, n)
    sg = np.where(rng.random(n) < 0.2, -1.0, 1.0)
    rate, chunk = (1000.0, 500.0, 800.0)[k], (0.05, 0.031, 0.07)[k]
    t = np.arange(1, int(0.35 * rate) + 1) / rate + k * 1.7e-4
    calls, t0 = [], 0.0
    for end in np.arange(chunk, 0.35 + 1e-9, chunk):
        ts = t[(t > t0) & (t <= end)]
        if ts.size:
            sel = (st > t0) & (st <= ts[-1])
            calls.append((ts, st[sel], sk[sel], sg[sel]))
            t0 = ts[-1]
    return calls[: (len(calls), len(calls) - 2, len(calls))[k]]  # session 1 ends early: its lane is parked


@pytest.mark.slow  # the spatial lanes' first compile: about 22 s of CPU on a cold cache
def test_spatial_sessions_in_lockstep_get_the_outputs_they_get_alone():
    base = RigParameters()
    rigs = [four_tendon_rig(base.replace(alpha=base.alpha * f)) for f in (1.0, 0.8, 1.2)]
    lockstep = Lockstep(rigs)

    def session(k):
        plant = lockstep.plant(k)
        return [plant.advance(*c) for c in _spatial_calls(k)]

    got = lockstep.run([lambda k=k: session(k) for k in range(3)])
    for k, rig in enumerate(rigs):
        plant = SpatialPlant(rig)
        alone = [plant.advance(*c) for c in _spatial_calls(k)]
        assert len(got[k]) == len(alone)
        for a, b in zip(got[k], alone, strict=True):
            for key in ("output", "tension", "q", "tip"):
                assert np.array_equal(a[key].view(np.int64), b[key].view(np.int64)), (k, key)
    assert lockstep.kernel_calls > lockstep.rounds  # calls of unequal sample counts were served in pieces
