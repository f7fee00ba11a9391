"""``tune``'s verification runs in lanes (``verify(lanes=...)``, ``tune --lanes N``): the recordings do not
depend on the lane width; an interrupt and an unstable lane end the runs they reach as they end alone."""

import json
import os
import signal
from pathlib import Path

import numpy as np
import pytest

from helpers import rigfile
from helpers.paper.calibration import uncalibrated
from helpers.paper.shapers import design_tdfs
from helpers.research import design, lane_runs, tune
from helpers.research import tune_tendons as tt
from helpers.rig import Rig
from helpers.rigfile import default_rig, derived
from helpers.virtual.emulator.lockstep import Lockstep
from helpers.virtual.emulator.world import build_world, forget_world, register_world


def _candidates() -> tune.Candidates:
    zv, zvd = design_tdfs()
    made = {s: design.as_design(d, s, origin="test") for s, d in (("zv", zv), ("zvd", zvd))}
    return tune.Candidates({(200.0, 20.0): made}, {(200.0, 20.0): {}})


def _verify(folder: Path, lanes: int):
    rig = default_rig()
    forget_world("tune-lanes-test", rig)
    calibration = [uncalibrated(m) for m in derived(rig).mm_per_step]
    seeds = iter(range(1000, 1100))
    with Rig("virtual", rig, calibration=calibration, world="tune-lanes-test") as r:
        rows = tune.verify(r, _candidates(), folder, 2, seeds=lambda: next(seeds), progress=False,
                           lanes=lanes)  # fmt: skip
    forget_world("tune-lanes-test", rig)
    return rows


@pytest.mark.slow  # about 3-4 s
def test_verification_in_lanes_does_not_depend_on_the_lane_width(tmp_path):
    one, four = _verify(tmp_path / "one", 1), _verify(tmp_path / "four", 4)
    assert list(one["recording"]) == list(four["recording"]) and len(set(one["recording"])) == 4
    for name in one["recording"].unique():
        csv = f"{name}.csv"
        assert (tmp_path / "one" / csv).read_bytes() == (tmp_path / "four" / csv).read_bytes()
    numbers = one.select_dtypes("number").columns
    assert np.array_equal(one[numbers].to_numpy(), four[numbers].to_numpy(), equal_nan=True)
    # and they are not today's chained runs: the second run of the chain starts later on the device clock
    chained = _verify(tmp_path / "chain", 0)
    a, b = ((tmp_path / f / f"{chained['recording'].iloc[-1]}.csv").read_text().splitlines()[1] for f in
            ("one", "chain"))  # fmt: skip
    assert a.split(",")[1] != b.split(",")[1]


def test_an_interrupt_reaches_every_session_and_each_saves_its_run_aborted(tmp_path):
    """SIGINT in the middle of a batch (sent from a session's plant call, so that it comes mid-run): every
    session's guard gets it at its next plant call and saves what it recorded, marked aborted."""
    rig = default_rig()
    calibration = [uncalibrated(m) for m in derived(rig).mm_per_step]
    zv, _ = design_tdfs()
    names = [f"lanes-int-{k}" for k in range(3)]
    worlds = [build_world(rig, n) for n in names]
    lockstep = Lockstep([w.plant.params for w in worlds])
    calls = []

    class Kicking:  # lane 1's plant: sends SIGINT to the process at its 60th call (about 2 s into its run)
        def __init__(self, plant):
            self.plant = plant

        def advance(self, *args):
            calls.append(1)
            if len(calls) == 60:
                os.kill(os.getpid(), signal.SIGINT)
            return self.plant.advance(*args)

    for k, w in enumerate(worlds):
        w.plant = lockstep.plant(k) if k != 1 else Kicking(lockstep.plant(k))
        register_world(w)

    def session(k):
        with Rig("virtual", rig, calibration=calibration, world=names[k]) as r:
            return r.run_pulse(200, 20, zv, system="zv", path=tmp_path / f"run{k}", t_end_s=10.0, rate_hz=500,
                               progress=False, noise_seed=7 + k)  # fmt: skip

    try:
        with pytest.raises(KeyboardInterrupt):
            lockstep.run([lambda k=k: session(k) for k in range(3)])
    finally:
        for n in names:
            forget_world(n, rig)
    saved = sorted(tmp_path.glob("run*_aborted_*.json"))
    assert len(saved) == 3 and not list(tmp_path.glob("run?.json"))
    for path in saved:
        meta = json.loads(path.read_text())
        assert meta["status"] == "aborted" and "Ctrl-C" in meta["abort_reason"]
        assert 0 < meta["counts"]["samples"] < 5075  # cut in the middle


def _sessions(tmp: Path, tag: str, params: list, lockstep: Lockstep | None) -> list:
    """Three runs, each in a world of its own on ``params[k]`` (its plant lane ``k`` of ``lockstep``, or
    an ``ArmPlant`` alone, in turn); each run's outcome: its saved recording's path and status."""
    from helpers.virtual import ArmPlant

    rig = default_rig()
    calibration = [uncalibrated(m) for m in derived(rig).mm_per_step]
    zv, _ = design_tdfs()
    names = [f"lanes-{tag}-{k}" for k in range(len(params))]
    for k, (n, p) in enumerate(zip(names, params, strict=True)):
        w = build_world(rig, n)
        w.plant = lockstep.plant(k) if lockstep else ArmPlant(p)
        register_world(w)

    def session(k):
        try:
            with Rig("virtual", rig, calibration=calibration, world=names[k]) as r:
                rec = r.run_pulse(200, 20, zv, system="zv", path=tmp / f"run{k}", t_end_s=10.0, rate_hz=310,
                                  progress=False, noise_seed=7 + k)  # fmt: skip
                return rec.path, rec.meta["status"]
        except FloatingPointError as exc:
            return exc.saved_path, "raised"

    try:
        if lockstep:
            return lockstep.run([lambda k=k: session(k) for k in range(len(params))])
        return [session(k) for k in range(len(params))]
    finally:
        for n in names:
            forget_world(n, rig)


@pytest.mark.slow  # about 3-4 s
def test_an_unstable_lane_aborts_its_own_run_only_saved_as_alone(tmp_path):
    """Lane 1's RK4 step is too long (steps of 0.645 ms at 310 Hz): its integration blows up about 1.35 s
    into its world, in its run. Its run is saved aborted, byte for byte as alone; the other two runs go on to
    the end in the same kernel calls and are saved complete, as alone."""
    rk4 = build_world(default_rig(), "lanes-params").plant.params.with_integrator("rk4")
    params = [rk4, rk4.replace(max_step=6.7e-4), rk4.replace(k=rk4.k * 0.9)]
    alone = _sessions(tmp_path / "alone", "alone", params, None)
    lanes = _sessions(tmp_path / "lanes", "lanes", params, Lockstep(params))
    assert [status for _, status in lanes] == ["complete", "raised", "complete"]
    assert [status for _, status in alone] == ["complete", "raised", "complete"]
    assert "_aborted_" in lanes[1][0].name and "_aborted_" in alone[1][0].name
    for (a, _), (b, _) in zip(alone, lanes, strict=True):
        assert a.with_suffix(".csv").read_bytes() == b.with_suffix(".csv").read_bytes(), b.name
    meta = json.loads(lanes[1][0].with_suffix(".json").read_text())
    assert meta["status"] == "aborted" and meta["abort_reason"].startswith("FloatingPointError")
    assert 0 < meta["counts"]["samples"] < 3000  # cut during its run


@pytest.mark.parametrize("lanes", [-1, 9, 2.0])
def test_a_lane_count_out_of_range_is_refused_before_any_run(tmp_path, lanes):
    with pytest.raises(ValueError, match=r"lanes must be an integer in 0-8"):
        tune.verify(None, _candidates(), tmp_path, 1, lanes=lanes)  # type: ignore[arg-type]
    assert not list(tmp_path.iterdir())


# ---- several tendons: tune_tendons.verify(lanes=...) -----------------------------------------------------
def _verify_tendons(folder: Path, lanes: int):
    rig = rigfile.load(rigfile.resolve("four-tendon"))
    points = [tt.MapPoint(d, 10.0, 25.0, 0.045, 0.0, 0.0, "r") for d in (0.0, 90.0, 180.0, 270.0)]
    forget_world("tune-tendons-lanes-test", rig)
    seeds = iter(range(500, 600))
    with Rig("virtual", rig, world="tune-tendons-lanes-test") as r:
        rows = tt.verify(r, points, folder, 2, directions=(45.0,), bends=(10.0,), systems=("unshaped", "zv"),
                         seeds=lambda: next(seeds), reseed=r.world.reseed, lanes=lanes)  # fmt: skip
    forget_world("tune-tendons-lanes-test", rig)
    return rows


@pytest.mark.slow
def test_four_tendon_verification_in_lanes_does_not_depend_on_the_lane_width(tmp_path, monkeypatch):
    made = []

    class Counted(Lockstep):
        def __init__(self, params):
            super().__init__(params)
            made.append(self)

    monkeypatch.setattr(lane_runs, "Lockstep", Counted)
    one = _verify_tendons(tmp_path / "one", 1)
    assert made == []  # one run per world, each its own SpatialPlant
    three = _verify_tendons(tmp_path / "three", 3)
    assert len(made) == 1 and made[0].spatial and made[0].kernel_calls > 0  # three runs in one SpatialLanes
    names = list(one["recording"].unique())
    assert names == list(three["recording"].unique()) and len(names) == 4  # 2 designs x 2 runs
    for name in names:
        csv = f"{name}.csv"
        assert (tmp_path / "one" / csv).read_bytes() == (tmp_path / "three" / csv).read_bytes()
    numbers = one.select_dtypes("number").columns
    assert np.array_equal(one[numbers].to_numpy(), three[numbers].to_numpy(), equal_nan=True)
    # the two repetitions differ (their noise seeds), so equal files are not equal by construction
    a, b = ((tmp_path / "one" / f"{n}.csv").read_bytes() for n in names[:2])
    assert a != b
