"""Tension held by measurement: the host's trim, the floor watch, the twin's eyelet error.

The trim's rule and the floor watch are tested on fake measurements and synthetic parsed samples (no board,
well under a second); the driver running both on the virtual four-tendon rig, and the eyelet error of the
twin, are the slow tests at the end.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from helpers import recordings, rigfile
from helpers.board import stream_reference as hs
from helpers.board.programmes import Move, Programme
from helpers.commands.home import home
from helpers.rig import Rig
from helpers.rig.stream import ShapedCheck, board_shaper, stream
from helpers.rig.trim import (
    REST_WINDOW_S,
    TRIM_MAX_STEPS,
    BelowFloor,
    FloorWatch,
    Rest,
    TensionGuard,
    TrimFailed,
    nudge,
    rest_steps,
    rest_tensions,
    trim,
    trim_steps,
)  # fmt: skip
from helpers.virtual.emulator.world import build_world, forget_world, get_world, register_world
from helpers.virtual.spatial.from_rig import spatial_rig

NPC, OFFSET = 0.040690104166666664, 122.88  # the four-tendon rigs' nominal chain: N per count, zero counts


class Arm:
    """A fake arm: each tendon's tension linear in every tendon's whole steps, read with a fixed error."""

    def __init__(self, base, per_step=2.7, coupling=0.3, error=0.0, stuck=()):
        self.base = np.asarray(base, dtype=float)
        n = self.base.size
        self.k = np.full((n, n), coupling) + np.eye(n) * (per_step - coupling)
        for i in stuck:  # a slack cable: its steps change nothing
            self.k[i, :] = 0.0
        self.steps = np.zeros(n, dtype=int)
        self.error, self.moves = error, []

    def measure(self):
        return self.base + self.k @ self.steps + self.error

    def move(self, vector):
        assert sum(map(abs, vector)) == 1  # one whole step of one tendon
        self.moves.append(vector)
        self.steps += np.asarray(vector)


def _fewest(arm, targets, tolerance=0.1):
    """Each tendon's fewest whole steps at which it reads >= its target (the others where the trim left
    them)."""
    out = []
    for i in range(arm.base.size):
        s = arm.steps.copy()
        s[i] = -20
        while (arm.base + arm.k @ s + arm.error)[i] < targets[i] - tolerance:
            s[i] += 1
        out.append(int(s[i]))
    return out


def test_a_tendon_below_its_target_is_pulled_to_the_fewest_steps_that_reach_it():
    targets = [2.355] * 4
    arm = Arm([0.25, 2.36, 1.0, 2.355])  # tendon 1 about 0.1 mm slack, tendon 3 half of it
    result = trim_steps(targets, arm.measure, arm.move)
    assert result.steps == (1, 0, 1, 0)
    assert list(arm.steps) == _fewest(arm, targets)
    assert all(t >= g - 0.1 for t, g in zip(result.after_n, targets, strict=True))
    assert result.moves == 2 and result.before_n[0] == pytest.approx(0.25)
    # one step is 2.7 N: with a band of +-1 N this would oscillate; here a tendon at 0.3 N above stays
    assert trim_steps(targets, Arm([2.655] * 4).measure, Arm([0] * 4).move).steps == (0, 0, 0, 0)


def test_a_tendon_a_whole_step_above_its_target_is_let_out_when_the_planners_step_is_given():
    targets = [2.355] * 4
    arm = Arm([8.0, 2.4, 2.4, 2.4])  # tendon 1 two steps too tight
    result = trim_steps(targets, arm.measure, arm.move, step_n=[2.7] * 4)
    assert list(arm.steps) == _fewest(arm, targets) and result.steps[0] == -2
    assert arm.measure()[0] >= 2.355 - 0.1
    # without the planner's step a tendon above its target is left there (pulled in only)
    assert trim_steps(targets, Arm([8.0, 2.4, 2.4, 2.4]).measure, lambda v: None).steps == (0, 0, 0, 0)


def test_a_let_out_that_goes_below_is_pulled_back_one_step():
    arm = Arm([5.2, 2.4], per_step=2.7, coupling=0.0)
    arm.k[0, 0] = 4.0  # stiffer than the planner thought: one step out takes it below
    result = trim_steps([2.355, 2.355], arm.measure, arm.move, step_n=[2.7, 2.7])
    assert result.steps == (0, 0) and arm.moves == [(-1, 0), (1, 0)]


def test_a_tendon_that_cannot_reach_its_target_is_refused_naming_it():
    arm = Arm([2.4, 0.2, 2.4], stuck=(1,))
    with pytest.raises(TrimFailed, match=rf"^tendon 2: 0.20 N measured after {TRIM_MAX_STEPS} move"):
        trim_steps([2.355] * 3, arm.measure, arm.move)
    assert len(arm.moves) == TRIM_MAX_STEPS  # bounded
    with pytest.raises(TrimFailed, match="one finite tension per tendon"):
        trim_steps([2.0, 2.0], lambda: [2.0, float("nan")], arm.move)
    with pytest.raises(TrimFailed, match="finite tensions >= 0"):
        trim_steps([2.0, -1.0], lambda: [2.0, 2.0], arm.move)


# -- the trim at a stream's rest: one measurement, one set-point ------------------------------------------
def test_a_rest_trim_takes_its_steps_from_one_measurement():
    targets = [2.0, 2.0, 2.0, 2.0]
    measured = [1.5, 2.0, 6.0, -3.0]  # 0.4 N below (less the 0.1 N tolerance), at it, 4.1 above, 4.9 below
    assert rest_steps(measured, targets, [2.7] * 4) == (1, 0, -1, 2)  # ceil(.4/2.7), -, -floor(4.1/2.7), ceil
    assert rest_steps(measured, targets) == (0, 0, 0, 1)  # no planner's step: one on the farthest below
    assert rest_steps([1.95, 2.0, 2.0, 2.0], targets, [2.7] * 4) == (0, 0, 0, 0)  # within the tolerance
    with pytest.raises(TrimFailed, match="tendon 2: -20.00 N measured .* needs more than the trim's 6 steps"):
        rest_steps([2.0, -20.0, 2.0, 2.0], targets, [2.7] * 4)  # ceil(21.9 / 2.7) = 9 steps
    with pytest.raises(TrimFailed, match="not one finite tension per tendon"):
        rest_steps([2.0, float("nan"), 2.0, 2.0], targets)


def test_a_rest_trim_predicts_with_the_coupling_so_one_step_lifts_an_opposed_pair():
    pair = np.array([[2.7, 0.0, 2.5, 0.0], [0.0, 2.7, 0.0, 2.5], [2.5, 0.0, 2.7, 0.0], [0.0, 2.5, 0.0, 2.7]])
    measured = [0.0, 2.0, 0.2, 2.0]  # tendons 1 and 3 (opposed) both about 2 N low
    assert rest_steps(measured, [2.0] * 4, pair) == (1, 0, 0, 0)  # 1 lifts 3 with it: one step, not two
    assert rest_steps(measured, [2.0] * 4, np.diag(pair)) == (1, 0, 1, 0)  # blind to the coupling: two
    assert rest_steps([2.0, 2.0, 7.5, 2.0], [2.0] * 4, pair) == (0, 0, 0, 0)  # letting 3 out drops 1 too
    with pytest.raises(TrimFailed, match="tension per step must be finite, > 0 N"):
        rest_steps(measured, [2.0] * 4, -pair)


class _Daq:
    def __init__(self, counts):
        self.rows = [(k, 1000 * k, *counts, 0, 0, 0, 0) for k in range(400)]


class _Rig:
    """What a rest trim reads of a rig: its calibration and the DAQ's parsed samples (counts held)."""

    def __init__(self, counts):
        self.n = 4
        self.calibration = [type("Cal", (), {"newtons_per_count": 0.1, "offset_counts": 0.0})()] * 4
        self.daq = _Daq(counts)


def _planned_end(rows, check):
    for row in rows:  # one at a time, as the stream takes them: a trim reads the plan so far
        check.setpoint(tuple(row))
    return np.array(check.end())


@pytest.mark.parametrize("shaper", [None, "zvd"])
@pytest.mark.parametrize("back, steps", [
    (-60, [1, 0, -1, 2]),  # tendon 3 came back down (12.81 steps, counted 13): let out one
    (0, [1, 0, 0, 2]),  # it stands above its count (14.53, counted 14): a let-out from there is not made
])  # fmt: skip
def test_a_rest_trims_set_point_moves_the_boards_count_by_exactly_its_steps(shaper, back, steps):
    """The trim's one set-point, planned by the host's copy of the board's planner (as the board plans it):
    every tendon's count at the end differs from the untrimmed stream's by exactly the trim's steps, from
    wherever between two counts the stop left its commanded position."""
    four = rigfile.load(rigfile.resolve("four-tendon"))
    from helpers.paper.shapers import design_tdfs

    board = board_shaper(design_tdfs(22.7, 0.05)[1] if shaper else None, 4)
    start = (10, 10, 10, 10)
    moves = [(37, -20, 95, 11)] * 5 + [(-13, 7, back, -3)] * 3  # leaves each tendon between two counts
    rows = moves + [(0, 0, 0, 0)] * 120
    plain = _planned_end(rows, ShapedCheck(board, start, four))
    guard = TensionGuard(rests=[Rest(100, (2.0,) * 4, [2.7] * 4)], watch=False)
    check, widened, notes = ShapedCheck(board, start, four), [], []
    fed = guard.at_rests(iter(rows), _Rig([15, 20, 60, -30]), 1000, check.where,
                         lambda: widened.append(1), 1640, notes)  # fmt: skip
    trimmed = _planned_end(fed, check)
    assert (trimmed - plain).tolist() == steps  # tensions 1.5, 2.0, 6.0, -3.0 N against 2.0
    assert notes == [{"setpoint": 100, "targets_n": [2.0] * 4, "measured_n": [1.5, 2.0, 6.0, -3.0],
                      "steps": steps}] and widened == [1]  # fmt: skip


def test_a_rest_trim_asked_where_the_stream_moves_is_refused():
    four = rigfile.load(rigfile.resolve("four-tendon"))
    check = ShapedCheck(board_shaper(None, 4), (10,) * 4, four)
    guard = TensionGuard(rests=[Rest(3, (2.0,) * 4)])
    fed = guard.at_rests(iter([(5, 0, 0, 0)] * 10), _Rig([20] * 4), 1000, check.where, lambda: None, 1640, [])
    with pytest.raises(TrimFailed, match="set-point 3 moves \\[5, 0, 0, 0\\]: a rest trim needs a rest"):
        list(fed)


def test_a_rest_trim_without_a_window_of_samples_measures_nothing_and_moves_nothing():
    four = rigfile.load(rigfile.resolve("four-tendon"))
    check, notes = ShapedCheck(board_shaper(None, 4), (10,) * 4, four), []
    rig = _Rig([0] * 4)
    rig.daq.rows = rig.daq.rows[: round(REST_WINDOW_S * 1000) - 1]  # one sample short of the window
    guard = TensionGuard(rests=[Rest(2, (2.0,) * 4)])
    fed = list(guard.at_rests(iter([(0,) * 4] * 5), rig, 1000, check.where, lambda: None, 1640, notes))
    assert fed == [(0,) * 4] * 5 and notes[0]["skipped"].startswith("299 samples")


# -- the floor watch on parsed samples (device time: counted in samples) ------------------------------------
def _rows(tension: np.ndarray, t0_us: int = 5_000_000) -> np.ndarray:
    """Parsed samples ``[seq, t_us, adc..., steps...]`` at 1 kHz giving ``tension`` (rows x tendons, N)."""
    k, n = tension.shape
    adc = np.round(tension / NPC + OFFSET)
    rows = np.column_stack([np.arange(k), t0_us + 1000 * np.arange(k), adc, np.zeros((k, n))])
    return rows.astype(np.int64)


def _watch(watch_ms=20):
    return FloorWatch(1.0, watch_ms, 1000, [NPC] * 4, [OFFSET] * 4)


def _dip(length: int, tendon: int = 2, total: int = 200) -> np.ndarray:
    t = np.full((total, 4), 2.355)
    t[50 : 50 + length, tendon] = 0.4
    return t


def test_a_pay_out_steps_dip_of_3_ms_is_no_abort():
    watch = _watch()
    watch.feed(_rows(_dip(3)))
    assert watch.longest.tolist() == [0, 0, 3, 0]
    watch.feed(_rows(_dip(20)))  # exactly the watch time: still allowed
    assert watch.longest[2] == 20


def test_a_tendon_below_the_floor_for_longer_than_the_watch_stops_the_run_naming_it():
    watch = _watch()
    watch.t0_us = 4_000_000  # GO's device time
    with pytest.raises(BelowFloor) as info:
        watch.feed(_rows(_dip(30)))
    message = str(info.value)
    assert message.startswith("tendon 3 below the floor 1.00 N for 21 ms (21 samples at 1000 Hz, least 0.4")
    assert "at device time t = 1.070 s after GO (from 1.050 s)" in message
    assert "[arm] floor_watch_ms" in message


def test_the_watch_counts_samples_across_blocks_and_at_the_rate():
    watch = _watch()
    rows = _rows(_dip(30))
    with pytest.raises(BelowFloor, match="^tendon 3 .* for 21 ms"):
        for k in range(0, len(rows), 7):  # the link's blocks: the count carries over
            watch.feed(rows[k : k + 7])
    slow = FloorWatch(1.0, 20, 500, [NPC] * 4, [OFFSET] * 4)  # 2 ms per sample: 10 samples are 20 ms
    slow.feed(_rows(_dip(10)))
    with pytest.raises(BelowFloor, match="for 22 ms \\(11 samples at 500 Hz"):
        slow.feed(_rows(_dip(11)))


def _reference_watch(tension: np.ndarray, floor_n: float, limit: int) -> tuple[int, int] | None:
    """Sample by sample, tendon by tendon: the first (sample, tendon) whose run below the floor exceeds
    ``limit`` samples, or None (the watch's rule written out plainly)."""
    run = [0] * tension.shape[1]
    for k, row in enumerate(tension):
        for i, t in enumerate(row):
            run[i] = run[i] + 1 if t < floor_n else 0
            if run[i] > limit:
                return k, i
    return None


@pytest.mark.parametrize("seed", range(6))
def test_the_block_watch_stops_where_a_sample_by_sample_watch_stops_whatever_the_blocks(seed):
    rng = np.random.default_rng(seed)
    tension = np.full((3000, 4), 2.355)
    for _ in range(40):  # dips of 1-40 samples on random tendons, some overlapping
        k, i, n = rng.integers(0, 2990), rng.integers(0, 4), rng.integers(1, 41)
        tension[k : k + n, i] = rng.uniform(0.0, 0.99)
    counted = (np.round(tension / NPC + OFFSET) - OFFSET) * NPC  # the tension the rows' counts give back
    expected = _reference_watch(counted, 1.0, 20)
    rows = _rows(tension)
    watch, cuts = _watch(), np.sort(rng.choice(np.arange(1, 3000), size=60, replace=False))
    got = None
    try:
        for block in np.split(rows, cuts):  # blocks of 1 to a few hundred rows, as the link gives them
            watch.feed(block)
    except BelowFloor as exc:
        got = str(exc)
    if expected is None:
        assert got is None
    else:
        k, i = expected
        assert got is not None and got.startswith(f"tendon {i + 1} below the floor 1.00 N for 21 ms")
        assert f"t = {(5_000_000 + 1000 * k) / 1e6:.3f} s on the DAQ's clock" in got


def test_a_run_of_several_tendons_without_its_guard_is_refused_before_a_byte(tmp_path):
    four = rigfile.load(rigfile.resolve("four-tendon"))
    register_world(build_world(four, "trim-guardless")).stepper.take_output()
    with Rig("virtual", four, world="trim-guardless") as rig:
        sent = len(get_world("trim-guardless").stepper.received)
        with pytest.raises(ValueError, match=r"^a run of 4 tendons needs its guard: guard=helpers\.rig"):
            rig.run(Programme((Move(40_000, (2, 0, 0, 0)),)), path=tmp_path / "p", progress=False)
        assert len(get_world("trim-guardless").stepper.received) == sent
    forget_world("trim-guardless")
    assert not list(tmp_path.iterdir())  # nothing reserved, nothing saved


def test_the_rig_file_states_the_watch_time_and_its_default():
    four = rigfile.load(rigfile.resolve("four-tendon"))
    assert four.arm.floor_watch_ms == 20
    text = (rigfile.RIGS_DIR / "four-tendon.toml").read_text()
    longer = rigfile.loads(text.replace("gravity_m_s2 = 9.81", "gravity_m_s2 = 9.81\nfloor_watch_ms = 35"))
    assert longer.arm.floor_watch_ms == 35
    with pytest.raises(rigfile.RigFileError, match="floor_watch_ms"):
        rigfile.loads(text.replace("gravity_m_s2 = 9.81", "gravity_m_s2 = 9.81\nfloor_watch_ms = 0"))


# -- the driver on the virtual four-tendon rig (slow: device seconds of the spatial twin) --------------------
@pytest.fixture(scope="module")
def four_rig():
    four = rigfile.load(rigfile.resolve("four-tendon"))
    register_world(build_world(four, "trim-test-rig")).stepper.take_output()
    rig = Rig("virtual", four, world="trim-test-rig", stepper_options="&reset_on_open=0")
    yield rig
    rig.close()
    forget_world("trim-test-rig")


@pytest.mark.slow
def test_a_run_that_slackens_a_tendon_is_stopped_by_the_floor_watch_and_saved_aborted(four_rig, tmp_path):
    with pytest.raises(BelowFloor) as info:  # tendon 3 paid out 10 mm: the arm bends onto tendon 1, slack too
        four_rig.run(Programme((Move(100_000, (0, 0, -40, 0)),)), path=tmp_path / "slack", progress=False,
                     guard=TensionGuard())  # fmt: skip
    rec = info.value.recording
    assert rec.meta["status"] == "aborted" and info.value.saved_path.name.startswith("slack_aborted_")
    assert rec.meta["abort_reason"].startswith("BelowFloor: tendon ")
    assert " below the floor 1.00 N for 21 ms (21 samples at 1000 Hz" in rec.meta["abort_reason"]
    assert "after GO" in rec.meta["abort_reason"]
    assert four_rig.positions()[2] > -40  # stopped before the end
    home(four_rig.stepper, four_rig.rig)


@pytest.mark.slow
def test_the_trim_brings_a_paid_out_tendon_back_to_its_target_and_a_run_records_it(four_rig, tmp_path):
    pre = four_rig.rig.arm.pretension_n  # the planner's static tension at rest
    assert nudge(four_rig, (-1, 0, 0, 0)) == (-1, 0, 0, 0)  # one step paid out: about 2.7 N less on tendon 1
    _, before = rest_tensions(four_rig)
    assert before[0] < pre - 1.0
    result = trim(four_rig, [pre] * 4)
    assert result.steps == (1, 0, 0, 0) and four_rig.positions() == (0, 0, 0, 0)
    assert all(abs(t - pre) < 0.1 for t in result.after_n)
    nudge(four_rig, (0, -1, 0, 0))
    rec = four_rig.run(Programme((Move(40_000, (2, 0, 0, 0)), Move(40_000, (-2, 0, 0, 0)))),
                       path=tmp_path / "trimmed", progress=False, guard=TensionGuard([pre] * 4))  # fmt: skip
    measured = rec.meta["scenario"]["measured_trim"]
    assert measured["steps"] == [0, 1, 0, 0] and rec.meta["scenario"]["start_positions_steps"] == [0, 0, 0, 0]
    assert rec.meta["status"] == "complete" and four_rig.positions() == (0, 0, 0, 0)
    assert recordings.load(rec.path).meta["scenario"]["measured_trim"] == measured  # checked on load
    home(four_rig.stepper, four_rig.rig)


@pytest.mark.slow
def test_a_trim_that_cannot_reach_a_target_stops_the_run_before_it_moves_saved_aborted(four_rig, tmp_path):
    nudge(four_rig, (0, 0, -20, 0))  # tendon 3 paid out 5 mm: six steps do not take it back to its tension
    with pytest.raises(TrimFailed, match=r"^tendon 3: -?0.00 N measured after 6 move\(s\) of one") as info:
        four_rig.run(Programme((Move(40_000, (2, 0, 0, 0)),)), path=tmp_path / "t", progress=False,
                     guard=TensionGuard([four_rig.rig.arm.pretension_n] * 4))  # fmt: skip
    assert info.value.recording.meta["status"] == "aborted"
    assert info.value.recording.meta["abort_reason"].startswith("TrimFailed: tendon 3: ")
    assert four_rig.positions() == (0, 0, -14, 0)  # the programme never ran
    home(four_rig.stepper, four_rig.rig)


@pytest.mark.slow
def test_a_stream_asked_to_watch_the_floor_is_stopped_and_one_asked_to_trim_streams_from_the_trim(tmp_path):
    four = rigfile.load(rigfile.resolve("four-tendon"))
    shaper = hs.StreamShaper((2048, 2048), (0, 50_000))
    sp = np.zeros((40, 4))
    sp[:20, 0], sp[:10, 3], sp[:10, 2] = 20.0, 30.0, -30.0  # tendon 3 paid out 3 mm at 30 mm/s
    with Rig("virtual", four, world="trim-stream-watched") as trig:
        with pytest.raises(BelowFloor, match=r"^tendon \d below the floor 1.00 N for 21 ms") as info:
            stream(trig, sp, shaper, path=tmp_path / "watched", tail_s=0.3, lead_in_s=0.2, progress=False,
                   guard=TensionGuard())  # fmt: skip
    assert info.value.recording.meta["status"] == "aborted"
    small = np.zeros((20, 4))
    small[:10, 0] = 5.0  # tendon 1 pulled about 0.5 mm
    pre = four.arm.pretension_n
    with Rig("virtual", four, world="trim-stream-trimmed") as trig:
        nudge(trig, (-1, 0, 0, 0))  # one step paid out: the trim pulls it back before the stream
        rec = stream(trig, small, shaper, path=tmp_path / "trimmed", tail_s=0.3, lead_in_s=0.2,
                     progress=False, guard=TensionGuard([pre] * 4))  # fmt: skip
        end = trig.positions()
    sc = rec.meta["scenario"]
    assert rec.meta["status"] == "complete" and sc["measured_trim"]["steps"] == [1, 0, 0, 0]
    assert sc["start_positions_steps"] == [0, 0, 0, 0]
    assert end[0] == int(rec.frame["steps_0"].iloc[-1]) > 0
    assert recordings.load(rec.path).meta["scenario"]["measured_trim"] == sc["measured_trim"]  # on load


# -- the twin's eyelet error ([[tendon]] twin_eyelet_error_mm): read by the virtual rig's twin only ----------
FOUR_TEXT = (rigfile.RIGS_DIR / "four-tendon.toml").read_text()


def _with_errors(errors) -> rigfile.RigFile:
    text = FOUR_TEXT
    for angle, error in zip(("0.0", "90.0", "180.0", "270.0"), errors, strict=True):
        key = f"angle_deg = {angle}\n"
        text = text.replace(key, f"{key}twin_eyelet_error_mm = {error}\n")
    return rigfile.loads(text)


def test_without_an_eyelet_error_the_virtual_rigs_twin_is_the_planners():
    four = rigfile.load(rigfile.resolve("four-tendon"))
    nominal = spatial_rig(four)
    assert spatial_rig(four, as_built=True) == nominal  # absent: the same twin, so the same bytes
    assert spatial_rig(_with_errors([0.0] * 4), as_built=True) == nominal  # 0 on every tendon: the same


def test_an_eyelet_error_lowers_that_tendons_tension_in_the_virtual_rig_only():
    four = rigfile.load(rigfile.resolve("four-tendon"))
    one = _with_errors([0.1, 0.0, 0.0, 0.0])
    assert spatial_rig(one) == spatial_rig(four)  # the planners do not know it
    built = spatial_rig(one, as_built=True).pretensions
    pre = four.arm.pretension_n
    assert built[0] == pytest.approx(pre - 1.07, abs=0.05)  # 0.1 mm of cable: about 1 N of 2.36 N
    assert built[2] < pre - 0.5  # its antagonist eases with it (the arm bends towards tendon 1)
    assert built[1] == pytest.approx(pre, abs=0.01) and built[3] == pytest.approx(pre, abs=0.01)
    every = spatial_rig(_with_errors([0.1] * 4), as_built=True).pretensions
    assert np.all(every < 0.35)  # 0.1 mm on every tendon: all four below the 1 N floor at rest
    with pytest.raises(ValueError, match="twin_eyelet_error_mm: 0.5 mm leaves tendon 1 slack"):
        spatial_rig(_with_errors([0.5] * 4), as_built=True)


@pytest.mark.slow
def test_a_short_run_is_byte_identical_with_the_eyelet_errors_at_zero(tmp_path):
    digests = []
    for k, rig in enumerate((rigfile.load(rigfile.resolve("four-tendon")), _with_errors([0.0] * 4))):
        with Rig("virtual", rig, world=f"trim-identical-{k}") as trig:
            rec = trig.run(Programme((Move(40_000, (3, 0, 0, 0)),)), path=tmp_path / f"r{k}", progress=False,
                           noise_seed=7, guard=TensionGuard())  # fmt: skip
        digests.append(hashlib.sha256(rec.path.with_suffix(".csv").read_bytes()).hexdigest())
    assert digests[0] == digests[1]


@pytest.mark.slow
def test_with_the_eyelets_off_open_loop_breaks_the_floor_and_the_measured_trim_keeps_it(tmp_path):
    rig = _with_errors([0.1] * 4)  # unknown to the planner: every tendon about 2.1 N slacker at rest
    pre = [rig.arm.pretension_n] * 4  # the planner's static tension at rest
    there_and_back = Programme((Move(60_000, (4, 0, 0, 0)), Move(60_000, (-4, 0, 0, 0))))
    with Rig("virtual", rig, world="trim-eyelets-open") as trig:
        with pytest.raises(BelowFloor, match=r"^tendon \d below the floor 1.00 N .* \(from 0.00"):  # at rest
            trig.run(there_and_back, path=tmp_path / "open", progress=False, guard=TensionGuard())
    with Rig("virtual", rig, world="trim-eyelets-trimmed") as trig:  # the same arm, from its rest
        rec = trig.run(there_and_back, path=tmp_path / "trimmed", progress=False, guard=TensionGuard(pre))
    trim = rec.meta["scenario"]["measured_trim"]
    assert all(t < 1.0 for t in trim["before_n"]) and all(t >= 2.355 - 0.1 for t in trim["after_n"])
    assert trim["steps"] == [1, 0, 0, 1]  # two tendons pulled a step: the arm's coupling lifts the other two
    assert rec.meta["status"] == "complete"
    tension = rec.frame[[f"tension_n_{i}" for i in range(4)]].to_numpy()
    assert tension.min() >= rig.arm.tension_floor_n  # every sample of every tendon above the floor


def test_a_nudge_interrupted_mid_move_leaves_the_stepper_aborted_and_disabled(monkeypatch):
    four = rigfile.load(rigfile.resolve("four-tendon"))
    with Rig("virtual", four, world="trim-nudge-interrupted") as trig:
        world = get_world("trim-nudge-interrupted")

        def interrupted(*args, **kwargs):
            raise KeyboardInterrupt

        monkeypatch.setattr(trig, "_until_done", interrupted)
        sent = len(world.stepper.received)
        with pytest.raises(KeyboardInterrupt):
            nudge(trig, (1, 0, 0, 0))
        after = [line.strip() for line in world.stepper.received[sent:]]
        assert after[-2:] == ["ABORT", "EN 0"] and "GO" in after  # stopped and disabled after GO


@pytest.mark.slow
def test_with_the_eyelets_off_a_stream_trimmed_at_its_rest_ends_taut_where_open_loop_ends_slack(tmp_path):
    """The line to 10 mm towards 0 deg and back, pre-pulled one step, ZVD, on the twin with every eyelet
    0.1 mm off (each tendon about 2 N below the planners' tension) and no trim before the stream, so that
    the rest trims meet the error. At the stop every tendon is measured about 2 N low and one tendon of each
    opposed pair is pulled a step (the planner's coupling lifts the other); back at rest every tendon is at
    its target; from the trim to the end every tendon stays above the floor. Open loop the stream ends with
    every tendon slack (its let-out returns the arm to the misplaced eyelets' 0.2-0.3 N)."""
    from helpers.research.task_shaping import pretensioned
    from helpers.research.tip_stream import figure_path, plan_stream, rest_trims, stream_design

    four, off = rigfile.load(rigfile.resolve("four-tendon")), _with_errors([0.1] * 4)
    floor = four.arm.tension_floor_n
    path = figure_path("line", 10.0)
    base = spatial_rig(four)
    plan = plan_stream(four, path, spatial=base, prepull=1)
    design = stream_design(four, path, "zvd", spatial=pretensioned(four, base, 1))
    rests = rest_trims(plan, four, design.shaper, REST_WINDOW_S)  # the planners' tensions and coupling
    assert len(rests) == 2  # the stop at 10 mm and the one back at rest (the 0.3 s lead is too short)
    guards = {"open": TensionGuard(watch=False), "trimmed": TensionGuard(watch=False, rests=rests)}
    recs = {}
    for name, guard in guards.items():
        with Rig("virtual", off, world=f"rest-trim-{name}") as trig:
            recs[name] = stream(trig, plan.board_setpoints_mm_s, design.shaper, path=tmp_path / name,
                                lead_in_s=0.2, progress=False, noise_seed=3, guard=guard)  # fmt: skip
    stop, back = recs["trimmed"].meta["scenario"]["stream"]["rest_trims"]
    assert stop["setpoint"] == rests[0].setpoint
    assert all(t - 2.3 < m < t - 1.5 for m, t in zip(stop["measured_n"], stop["targets_n"], strict=True))
    assert sorted(stop["steps"][0::2]) == [0, 1] and sorted(stop["steps"][1::2]) == [0, 1]  # one per pair
    assert back["steps"] == [0, 0, 0, 0]
    assert all(m >= t - 0.1 for m, t in zip(back["measured_n"], back["targets_n"], strict=True))
    tensions = {}
    for name, rec in recs.items():
        f = rec.frame
        after = (f["t_s"] >= (stop["setpoint"] + 2) * 0.01).to_numpy()  # from the trim's motion on
        tensions[name] = f[[f"tension_n_{i}" for i in range(4)]].to_numpy()[after]
    assert tensions["trimmed"].min() >= floor
    assert np.all(tensions["open"][-500:].max(axis=0) < floor)  # the last 0.5 s: every tendon slack
