"""A stream goes where it was told, however late the host is (in-process virtual rig, device time).

The board takes one set-point per 10 ms period; a period the host is late for gets none. Since firmware 2.1
such a period moves nothing, so the cable never goes further than the set-points sent; the host counts those
periods, follows them in its prediction (stopping the stream before the board would clamp), and a run whose
motion was not its command's is saved as ``deviated``, never ``complete``. The host's lateness is made here by
sources that let device time pass while they are asked for a value (``world.advance_to``), as a slow gamepad
read or a garbage-collection pause would; ``tests/test_rig_pty.py`` does the same over the pseudo-terminals
in real time and under load.
"""

from __future__ import annotations

import numpy as np
import pytest
from rig_fakes import (
    MM_PER_STEP,  # the paper's cable per step, by hand
    make_rig,
)
from stream_run import PeriodCommands, simulate

from helpers import recordings
from helpers.board import stream_reference as hs
from helpers.rig import BoardError
from helpers.rig.stream import StreamLimit, stream

STEPS_PER_UNIT_PERIOD = 625 / 2**16
"""Steps one set-point unit moves in one period (PROTOCOL.md: 2^-16 step per 16 us, 625 x 16 us)."""

UNIT_MM_S = (1 / 2**16) / 16e-6 * MM_PER_STEP


def _units(mm_s: float) -> int:
    return round(mm_s / UNIT_MM_S)


def _source(world, values, late_s):
    """``values``, each after ``late_s(i)`` s of device time has passed in the source."""
    for i, v in enumerate(values):
        world.advance_to(world.t + late_s(i))
        yield v


LATENESS = {
    "on time": lambda i: 0.0,
    "30 ms per value": lambda i: 0.03,
    "60 ms per value": lambda i: 0.06,
    "bursty": lambda i: 0.09 if i % 5 == 4 else 0.0,  # five at once, then 90 ms of nothing
}


@pytest.mark.parametrize("shaped", [False, True], ids=["unshaped", "zvd"])
@pytest.mark.parametrize("late", list(LATENESS))
def test_a_late_host_never_moves_the_cable_further_than_commanded(tmp_path, late, shaped):
    rig, world = make_rig()
    shaper = hs.StreamShaper.quantise([0.25, 0.5, 0.25], [0.0, 0.125, 0.25]) if shaped else None
    command = [50.0] * 8 + [0.0] * 5 + [-25.0] * 4 + [0.0] * 5  # up 4 mm, back 1 mm
    rec = stream(rig, _source(world, command, LATENESS[late]), shaper, path=tmp_path / "s", progress=False)
    st = rec.meta["scenario"]["stream"]
    sent = [_units(v) for v in command]
    assert st["setpoints"] == sent
    exact = sum(sent) * STEPS_PER_UNIT_PERIOD  # the commanded displacement, steps
    peak = sum(u for u in sent if u > 0) * STEPS_PER_UNIT_PERIOD
    steps = rec.frame["steps"].to_numpy()
    assert abs(rec.meta["done_position"] - exact) < 1  # the count stays within a step of the exact position
    assert steps.max() <= np.ceil(peak) and steps.min() >= 0  # never past the command's reach
    gaps = int(np.sum(np.diff(st["periods"]) - 1))  # periods the board got no set-point for
    assert st["underruns"] == gaps
    if late == "on time":
        assert gaps == 0 and rec.status == "complete" and rec.path == tmp_path / "s.csv"
    else:
        assert gaps > 0 and rec.status == "deviated" and "fell behind" in rec.meta["deviation"]
        assert rec.path.name.startswith("s_deviated_") and not (tmp_path / "s.csv").exists()
    # what the board did is the reference's for the periods it reported
    commands = PeriodCommands(dict(zip(st["periods"], st["setpoints"], strict=True)), st["end_period"])
    ref = simulate(rig_shaper(rec), commands, position=0)
    assert ref.position == rec.meta["done_position"] == steps[-1]
    assert recordings.load(rec.path).status == rec.status


def rig_shaper(rec) -> hs.StreamShaper:
    imp = rec.meta["scenario"]["stream"]["impulses"]
    return hs.StreamShaper(tuple(imp["amplitudes"]), tuple(imp["delays_us"]), imp["allow_negative"])


def test_a_stall_that_would_make_the_shaped_motion_clamp_stops_the_stream_before_the_board_does(tmp_path):
    """Up and straight down again at full speed: through ZVD the shaped peak stays under the travel limit
    (the array is accepted); a host that stalls 90 ms at the top holds the unshaped path there, and the
    shaped motion would now reach 156 steps: the host stops the stream before the board gets there."""
    rig, world = make_rig()
    zvd = hs.StreamShaper.quantise([0.25, 0.5, 0.25], [0.0, 0.125, 0.25])
    v = hs.V_MAX * UNIT_MM_S
    command = [v] * 15 + [-v] * 15 + [0.0] * 5
    whole = simulate(zvd, PeriodCommands({k + 1: _units(x) for k, x in enumerate(command)}, 40))
    assert not whole.notices and max(np.cumsum(whole.directions)) < hs.TRAVEL_MAX  # on time: no clamp
    late = {15: 0.09}
    with pytest.raises(StreamLimit, match="fell behind") as info:
        stream(rig, _source(world, command, lambda i: late.get(i, 0.0)), zvd, path=tmp_path / "t",
               progress=False)  # fmt: skip
    saved = recordings.load(info.value.saved_path)
    st = saved.meta["scenario"]["stream"]
    assert saved.status == "aborted" and st["notices"] == [] and st["clamps"]["travel"] == 0
    assert saved.frame["steps"].max() < hs.TRAVEL_MAX and not world.stepper.enabled


def test_a_stepper_with_firmware_2_0_is_refused_a_stream_before_anything_moves(tmp_path):
    rig, world = make_rig()
    rig.stepper.version = "2.0.0"  # as a board of that firmware reports itself
    with pytest.raises(BoardError, match="firmware 2.0.0.*hold the last set-point"):
        stream(rig, [50.0] * 5, None, path=tmp_path / "u", progress=False)
    assert not any(c.startswith(("STREAM", "V ", "SHAPER")) for c in world.stepper.received)
    assert not (tmp_path / "u.csv").exists()
