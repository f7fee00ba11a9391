"""Several scenarios in one kernel call (SIMD lanes): packed arithmetic, each lane the bits of its run."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from numba import njit

from helpers.board.programmes import experiment_programme
from helpers.virtual import ArmPlant, RigParameters
from helpers.virtual.lanes import LaneArray, lane, select, set_lane, vexp, vsin, vsqrt
from helpers.virtual.plant import ArmLanes, lane_group


@njit(error_model="numpy")
def _arithmetic(x, y, out):
    """Every kind of operation the kernels use, written once for scalars and lanes."""
    for i in range(x.shape[0]):
        a = x[i]
        b = y[i]
        c = a * b - a / (b + 3.0) + 2.0 * a
        acc = 0.0
        for j in range(3):
            acc += c * (j + 0.5)
        big = abs(c) > 0.5
        d = select(big, c * c, -c)
        e = vsin(a) + vexp(b) + vsqrt(abs(d)) + acc
        e = set_lane(e, 0, lane(e, 0) * 0.5)  # lane 0 of each vector (the scalar: the value itself)
        out[i] = e


def _packed(asm: str) -> int:
    return len(re.findall(r"\tv?(?:add|sub|mul|div|sqrt)pd\t", asm))


def _fused(asm: str) -> int:
    return len(re.findall(r"\tvfn?m(?:add|sub)", asm))


@pytest.mark.parametrize("width", [4, 8])
def test_lane_arithmetic_is_packed_and_gives_the_scalar_bits(width):
    rng = np.random.default_rng(width)
    x = rng.normal(size=(64, width)) * 3.0
    y = rng.normal(size=(64, width))
    x[0, 1], y[1, 2] = -0.0, 1e-300  # a signed zero and a tiny number
    out = np.zeros((64, width))
    _arithmetic(LaneArray(x), LaneArray(y), LaneArray(out))
    for k in range(width):
        alone = np.zeros(64)
        _arithmetic(x[:, k].copy(), y[:, k].copy(), alone)  # halved (a scalar is its own lane 0)
        expected = alone if k == 0 else 2.0 * alone  # the other lanes were not halved (exact in binary)
        assert np.array_equal(out[:, k].view(np.int64), expected.view(np.int64)), k
    lanes_sig = next(s for s in _arithmetic.signatures if str(s[0]) == f"LaneArray({width}, 1d)")
    asm = _arithmetic.inspect_asm(lanes_sig)
    assert _packed(asm) >= 8 and _fused(asm) == 0  # SIMD on every lane, no contraction into FMA


# ---- the plant ----------------------------------------------------------------------------------------
def _runs(base: RigParameters, n: int, t_end: float = 2.4) -> tuple[list, list]:
    """``n`` different rigs and programmes, each with its own number of steps.

    Pulls of different speed and size; the release at 1.4 s slackens the cable and it snaps back (taut/slack
    transitions).
    """
    cases = [(200.0, 20.0, 1.0, 1.0, 1.0), (300.0, 15.0, 1.1, 0.9, 1.3), (100.0, 10.0, 0.9, 1.1, 0.8),
             (250.0, 20.0, 1.0, 1.2, 0.6), (150.0, 5.0, 1.2, 1.0, 1.0), (200.0, 10.0, 0.8, 0.8, 2.0),
             (300.0, 20.0, 1.0, 1.0, 0.5), (120.0, 18.0, 1.05, 1.0, 1.0)][:n]  # fmt: skip
    rigs, progs = [], []
    for v, a, mass, stiff, damp in cases:
        rigs.append(base.replace(disc_mass=base.disc_mass * mass, k=base.k * stiff, alpha=base.alpha * damp,
                                 beta_chord=base.beta_chord * damp))  # fmt: skip
        progs.append(experiment_programme(v, a, None, 0.2, 1.4, t_end)[0].step_times())
    return rigs, progs


def _alone_and_in_lanes(rigs: list, progs: list, t: np.ndarray, split: int) -> None:
    lanes = ArmLanes(rigs)
    got = [[], [], []]
    for part in (t[:split], t[split:]):  # two calls: the state carries over, as in ArmPlant
        sel = [(st > lanes.t.max() - 1e-12) & (st <= part[-1]) for st, _ in progs]
        times = [st[s] for (st, _), s in zip(progs, sel, strict=True)]
        signs = [sg[s] for (_, sg), s in zip(progs, sel, strict=True)]
        for acc, out in zip(got, lanes.advance_all(part, times, signs), strict=True):
            acc.append(out)
    output, tension, angles = (np.concatenate(g, axis=1) for g in got)
    crossings = 0
    for k, (rig, (st, sg)) in enumerate(zip(rigs, progs, strict=True)):
        plant = ArmPlant(rig)
        out, raw, ang = plant.advance_all(t, st, sg)
        assert np.array_equal(output[k].view(np.int64), out.view(np.int64)), k
        assert np.array_equal(tension[k].view(np.int64), raw.view(np.int64)), k
        assert np.array_equal(angles[k].view(np.int64), ang.view(np.int64)), k
        assert np.array_equal(lanes.state[k].view(np.int64), plant.state.view(np.int64)), k
        assert lanes.integrator_steps[k] == plant.integrator_steps
        assert lanes.transitions[k] == plant.transitions
        assert lanes.max_rotor_lag_steps[k] == plant.max_rotor_lag_steps
        crossings += plant.transitions
    assert crossings > 0  # the comparison crossed taut/slack transitions


@pytest.mark.parametrize("integrator", ["rk4", "rosw"])
def test_each_lane_takes_the_steps_and_bits_of_its_run_alone(integrator):
    # three rigs in four lanes (the fourth repeats the third); two calls, a transition-rich release
    rigs, progs = _runs(RigParameters().with_integrator(integrator), 3)
    t = np.arange(1, 2401) * 1e-3
    _alone_and_in_lanes(rigs, progs, t, split=1317)


@pytest.mark.parametrize(
    "change",
    [
        {"actuator": "ideal"},  # the drive moves the cable: every step evaluates the right-hand side again
        {"eyelet_mu": 0.05},  # capstan friction: libm per lane
        {"elements_per_disc": 2, "max_step": 1e-3 / 3},  # runs over two elements (the bowing's run terms)
    ],
)
def test_lanes_hold_on_the_kernels_other_branches(change):
    rigs, progs = _runs(RigParameters().with_integrator("rosw").replace(**change), 4, t_end=1.8)
    t = np.arange(1, 1801) * 1e-3
    _alone_and_in_lanes(rigs, progs, t, split=900)


@pytest.mark.slow
@pytest.mark.parametrize("integrator", ["rk4", "rosw"])
def test_eight_lanes_over_a_full_table_i_run(integrator):
    rigs, progs = _runs(RigParameters().with_integrator(integrator), 8, t_end=12.0)
    progs = [experiment_programme(v, a, None)[0].step_times() for v, a in
             ((200.0, 20.0), (300.0, 20.0), (100.0, 10.0), (200.0, 10.0), (300.0, 10.0), (100.0, 20.0),
              (200.0, 20.0), (300.0, 20.0))]  # fmt: skip
    t = np.arange(1, 12001) * 1e-3
    _alone_and_in_lanes(rigs, progs, t, split=6000)


def test_rigs_that_cannot_share_a_call_are_refused():
    assert lane_group(RigParameters()) == lane_group(RigParameters().replace(k=15000.0, alpha=3.0))
    assert lane_group(RigParameters()) != lane_group(RigParameters().with_integrator("rk4"))
    with pytest.raises(ValueError, match="must share lane_group"):
        ArmLanes([RigParameters(), RigParameters().replace(actuator="ideal")])
    with pytest.raises(ValueError, match="1 to 8 rigs"):
        ArmLanes([RigParameters()] * 9)
    lanes = ArmLanes([RigParameters()] * 2)
    with pytest.raises(ValueError, match="one step_times and step_signs per rig"):
        lanes.advance_all([0.001], [[]], [[]])
    with pytest.raises(ValueError, match="strictly increasing"):
        lanes.advance_all([0.002, 0.001], [[], []], [[], []])
    assert math.isfinite(float(lanes.t[0]))


@pytest.mark.parametrize("integrator", ["rk4", "rosw"])
def test_a_sample_a_few_ulps_ahead_takes_no_step(integrator):
    # an interval shorter than 1e-9 of a step (the emulated boards' fault instants end intervals anywhere)
    # is arrived at without a step; the lanes' driver once counted its steps below zero there, for ever
    plant = ArmPlant(RigParameters().with_integrator(integrator))
    before = plant.advance([0.2])
    steps = plant.integrator_steps
    again = plant.advance([np.nextafter(0.2, 1.0), 0.2 + 1e-15])
    assert plant.integrator_steps == steps and np.array_equal(again, np.repeat(before, 2))
    assert plant.t == 0.2 + 1e-15


def test_each_lane_on_its_own_samples_takes_the_bits_of_its_run_alone():
    # per-lane sample times (the lockstep of several worlds: each board samples on its own clock), two calls
    rigs, progs = _runs(RigParameters().with_integrator("rosw"), 3, t_end=1.6)
    times = [np.arange(1, 1601) * 1e-3 + k * 0.37e-3 for k in range(3)]
    lanes = ArmLanes(rigs)
    got = []
    for part in (slice(0, 700), slice(700, 1600)):
        rows = np.stack([t[part] for t in times])
        sel = [(st > t0 - 1e-12) & (st <= r[-1]) for (st, _), t0, r in zip(progs, lanes.t, rows, strict=True)]
        out, _, _ = lanes.advance_all(rows, [st[s] for (st, _), s in zip(progs, sel, strict=True)],
                                      [sg[s] for (_, sg), s in zip(progs, sel, strict=True)])  # fmt: skip
        got.append(out)
    output = np.concatenate(got, axis=1)
    for k, (rig, (st, sg)) in enumerate(zip(rigs, progs, strict=True)):
        alone = ArmPlant(rig).advance(times[k], st, sg)
        assert np.array_equal(output[k].view(np.int64), alone.view(np.int64)), k
    assert not np.array_equal(output[0], output[1])  # the lanes did differ
