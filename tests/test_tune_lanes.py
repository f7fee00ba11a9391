"""``tune``'s verification runs in lanes (PROTOTYPE, ``verify(lanes=...)``): the recordings do not depend on
the lane width."""

from pathlib import Path

import numpy as np

from helpers.paper.calibration import uncalibrated
from helpers.paper.shapers import design_tdfs
from helpers.research import design, tune
from helpers.rig import Rig
from helpers.rigfile import default_rig, derived
from helpers.virtual.emulator.world import forget_world


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
