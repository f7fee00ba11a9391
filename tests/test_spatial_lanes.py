"""The four-tendon twin in lanes: several scenarios per kernel call, each lane the bits of its run alone."""

from __future__ import annotations

import re

import numpy as np
import pytest
from numba import njit

from helpers.virtual import RigParameters
from helpers.virtual.spatial import _kernel as kern
from helpers.virtual.spatial.plant import SpatialLanes, SpatialPlant, lane_group
from helpers.virtual.spatial.rig import four_tendon_rig

T = np.arange(1, 361) * 1e-3  # 0.36 s at 1 kHz
KEYS = ("output", "tension", "q", "tip")


def _rigs(integrator: str, n: int) -> list:
    """``n`` four-tendon rigs that differ in pretension, damping and disc mass (one lane group)."""
    base = RigParameters().with_integrator(integrator)
    cases = [(None, 1.0, 1.0), (1.2, 1.3, 0.9), (0.9, 0.8, 1.1), (1.1, 1.0, 1.2), (None, 1.5, 1.0),
             (1.0, 0.7, 0.8), (1.3, 1.1, 1.0), (0.95, 1.0, 1.05)][:n]  # fmt: skip
    rigs = []
    for pre, damp, mass in cases:
        arm = base.replace(alpha=base.alpha * damp, disc_mass=base.disc_mass * mass)
        rigs.append(four_tendon_rig(arm, pretension_n=pre))
    return rigs


def _programmes(n: int) -> list:
    """Each lane its own steps: pulls towards different directions (different tendons and rates), and in lane
    1 a fast release of tendon 0 that slackens it (taut/slack transitions)."""
    progs = []
    for k in range(n):
        rng = np.random.default_rng(100 + k)
        if k == 1:
            st = np.linspace(0.02, 0.1, 200)
            progs.append((st, np.zeros(200, np.int64), -np.ones(200)))
            continue
        count = 30 + 15 * k
        st = np.sort(rng.uniform(0.01, 0.3, count))
        pulled = np.array([k % 4, (k + 1) % 4])  # a bend between two neighbours, the share set by the lane
        tendons = pulled[(rng.random(count) < 0.3 + 0.08 * k).astype(int)]
        signs = np.where(rng.random(count) < 0.15, -1.0, 1.0)
        progs.append((st, tendons.astype(np.int64), signs))
    return progs


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a).view(np.int64)


def _alone_and_in_lanes(rigs: list, progs: list, rows: list[np.ndarray], split: int) -> SpatialLanes:
    lanes = SpatialLanes(rigs)
    got = {k: [] for k in KEYS}
    for part in (slice(0, split), slice(split, None)):  # two calls: the state carries over
        sample = np.stack([r[part] for r in rows])
        sel = [(p[0] > t0 + 1e-12) & (p[0] <= r[-1]) for p, t0, r in zip(progs, lanes.t, sample, strict=True)]
        steps = ([p[i][s] for p, s in zip(progs, sel, strict=True)] for i in range(3))
        out = lanes.advance_all(sample, *steps)
        for key in KEYS:
            got[key].append(out[key])
    crossings = 0
    for k, (rig, prog) in enumerate(zip(rigs, progs, strict=True)):
        plant = SpatialPlant(rig)
        alone = plant.advance(rows[k], *prog)
        for key in KEYS:
            assert np.array_equal(_bits(np.concatenate(got[key], axis=1)[k]), _bits(alone[key])), (k, key)
        assert np.array_equal(_bits(lanes.state[k]), _bits(plant.state)), k
        assert lanes.integrator_steps[k] == plant.integrator_steps
        assert lanes.transitions[k] == plant.transitions
        assert np.array_equal(lanes.max_rotor_lag_steps[k], plant.max_rotor_lag_steps)
        assert np.array_equal(lanes.position_steps[k], plant.position_steps)
        assert lanes.t[k] == plant.t
        crossings += plant.transitions
    assert crossings > 0  # the comparison crossed taut/slack transitions
    tension = np.concatenate(got["tension"], axis=1)
    assert tension[1, -1, 0] == 0.0 and tension[1, 0, 0] > 0.0  # lane 1: its tendon 1 released until slack
    assert not np.array_equal(got["tip"][0][0], got["tip"][0][2])  # the lanes did differ
    return lanes


@pytest.mark.slow  # the lanes' first compile: about 22 s of CPU per width on a cold cache
@pytest.mark.parametrize(
    ("integrator", "width"),
    [("rosw", 4), ("rk4", 4), ("rosw", 8)],
)
def test_each_lane_takes_the_bits_and_steps_of_its_run_alone(integrator, width):
    # width - 1 rigs (the last lane repeats the last rig), two calls, a lane that goes slack
    n = width - 1
    _alone_and_in_lanes(_rigs(integrator, n), _programmes(n), [T] * n, split=170)


@pytest.mark.slow  # the lanes' first compile: about 22 s of CPU per width on a cold cache
def test_each_lane_on_its_own_samples_takes_the_bits_of_its_run_alone():
    # per-lane sample times (the lockstep of several worlds, each on its own clock)
    rows = [T + k * 0.37e-3 for k in range(4)]
    _alone_and_in_lanes(_rigs("rosw", 4), _programmes(4), rows, split=200)


@pytest.mark.slow  # the lanes' first compile: about 22 s of CPU per width on a cold cache
def test_a_lane_that_fails_leaves_the_others_their_bits_and_restore_puts_it_back():
    rigs, progs = _rigs("rosw", 3), _programmes(3)
    alone = [SpatialPlant(rig).advance(T, *prog) for rig, prog in zip(rigs, progs, strict=True)]
    lanes = SpatialLanes(rigs)
    first = lanes.advance_all(T[:100], *([p[i][p[0] <= T[99]] for p in progs] for i in range(3)))
    saved = lanes.save()
    rest = [([p[i][p[0] > T[99]] for p in progs]) for i in range(3)]
    lanes._y.data[5, 2] = np.nan  # lane 2's state broken
    second = lanes.advance_all(T[100:], *rest, check=False)
    assert lanes.unstable() == [2]
    assert not np.all(np.isfinite(second["tip"][2]))
    for k in (0, 1):
        for key in KEYS:
            both = np.concatenate([first[key][k], second[key][k]])
            assert np.array_equal(_bits(both), _bits(alone[k][key])), (k, key)
    lanes.restore(saved, [0, 1, 2])
    again = lanes.advance_all(T[100:], *rest)
    for k in range(3):
        for key in KEYS:
            both = np.concatenate([first[key][k], again[key][k]])
            assert np.array_equal(_bits(both), _bits(alone[k][key])), (k, key)
    lanes._y.data[0, 1] = np.inf
    with pytest.raises(FloatingPointError, match=r"lane\(s\) \[1\]"):
        lanes.advance_all([T[-1] + 1e-3], [[]] * 3, [[]] * 3, [[]] * 3)


def test_rigs_that_cannot_share_a_call_are_refused():
    assert lane_group(four_tendon_rig()) == lane_group(four_tendon_rig(RigParameters().replace(alpha=3.0)))
    rk4 = four_tendon_rig(RigParameters().with_integrator("rk4"))
    with pytest.raises(ValueError, match="must share lane_group"):
        SpatialLanes([four_tendon_rig(), rk4])
    with pytest.raises(ValueError, match="1 to 8 rigs"):
        SpatialLanes([four_tendon_rig()] * 9)
    lanes = SpatialLanes([four_tendon_rig()] * 2)
    with pytest.raises(ValueError, match="one step_times, step_tendons and step_signs per rig"):
        lanes.advance_all([0.001], [[]], [[]], [[]])
    with pytest.raises(ValueError, match="step_tendons must name tendons"):
        lanes.advance_all([0.001], [[5e-4], []], [[4], []], [[1.0], []])


def _packed(asm: str) -> int:
    return len(re.findall(r"\tv?(?:add|sub|mul|div|sqrt)pd\t", asm))


def _fused(asm: str) -> int:
    return len(re.findall(r"\tvfn?m(?:add|sub)", asm))


@pytest.mark.slow  # the lanes' first compile: about 22 s of CPU per width on a cold cache
def test_the_lanes_right_hand_side_is_packed_and_not_contracted():
    lanes = SpatialLanes([four_tendon_rig()] * 4)
    w = lanes._work
    fresh = njit(error_model="numpy")(kern.rhs.py_func)  # compiled here (the cached kernel keeps no assembly)
    fresh(lanes._y, w.k1, lanes._drive, lanes._geo, lanes._mb, lanes._Jd, lanes._Jp, lanes._tp, lanes._W,
          lanes._cw, w.wb, w.wt, w.sp, w.st)  # fmt: skip
    assert np.all(np.isfinite(w.k1.data))
    asm = fresh.inspect_asm(fresh.signatures[0])
    assert _packed(asm) >= 500 and _fused(asm) == 0  # SIMD on every lane, no contraction into FMA
