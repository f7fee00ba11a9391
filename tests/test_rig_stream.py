"""helpers.rig.stream.stream on the in-process virtual rig (test-double plant, one tendon): a stream of
set-points through the board's shaper -> one recording, paced by the device clock, checked before sending, and
safe however it ends.

The oracle for what the board does is helpers.board.stream_reference (the firmware's reference, checked
against the
firmware tick for tick in tests/firmware); set-points in board units are computed here from PROTOCOL.md's
unit (2^-16 step per 16 us = 0.95367431640625 steps/s)."""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest
from rig_fakes import (
    MM_PER_STEP,  # the paper's cable per step, by hand
    SpyPort,
    make_rig,
    make_world,
)
from stream_run import PeriodCommands, simulate
from tendon_fakes import talk

from helpers import recordings, rigfile
from helpers.board import stream_reference as hs
from helpers.rig import BoardReset, BoardTimeout, SafetyError
from helpers.rig.stream import StreamLimit, StreamStarved, stream

pytestmark = pytest.mark.streaming

SHAPER = hs.StreamShaper((1024, 2048, 1024), (0, 40_000, 80_000))  # 0.25, 0.5, 0.25 at 0, 40, 80 ms
STEPS_PER_S_PER_UNIT = 0.95367431640625
PROFILE = [0.0] * 5 + [150.0] * 8 + [0.0] * 20 + [-150.0] * 8 + [0.0] * 5  # mm/s per 10 ms period


def board_units(mm_s: float) -> int:
    return round(mm_s / MM_PER_STEP / STEPS_PER_S_PER_UNIT)


class FifoWatch:
    """Records, at every control tick of the emulated board, how many set-points wait in its FIFO."""

    def __init__(self, monkeypatch) -> None:
        self.before_tick: list[tuple[int, int]] = []
        tick = hs.StreamSession.tick

        def watched(session):
            self.before_tick.append((session.next_period, len(session.fifo)))
            return tick(session)

        monkeypatch.setattr(hs.StreamSession, "tick", watched)


def _stream_start(world) -> list[float]:
    """The device time of STREAM, as the emulated board holds it (captured while it streams)."""
    seen: list[float] = []

    def look(w):
        if w.stepper.stream is not None and not seen:
            seen.append(w.stepper.stream.t0)

    world.listeners.append(look)
    return seen


@pytest.mark.parametrize("kind", ["array", "generator"])
def test_a_stream_records_what_the_reference_says_the_board_does(tmp_path, monkeypatch, kind):
    rig, world = make_rig()
    fifo = FifoWatch(monkeypatch)
    t_stream = _stream_start(world)
    setpoints = np.array(PROFILE) if kind == "array" else (v for v in PROFILE)
    rec = stream(rig, setpoints, SHAPER, path=tmp_path / "s", progress=False, lead_periods=3)
    assert rec.status == "complete"
    back = recordings.load(tmp_path / "s")
    sc = back.meta["scenario"]
    st = sc["stream"]
    units = [board_units(v) for v in PROFILE]
    n = len(units)
    assert sc["kind"] == "stream" and st["source"] == kind and st["rate_hz"] == 100
    assert st["impulses"]["amplitudes"] == [1024, 2048, 1024]
    assert st["impulses"]["delays_us"] == [0, 40_000, 80_000]
    assert st["setpoints"] == units and st["n_setpoints"] == n
    digest = hashlib.sha256(b"".join(u.to_bytes(2, "little", signed=True) for u in units)).hexdigest()
    assert st["setpoints_sha256"] == digest
    # paced by the device clock: every set-point in its own period, in order, none refused, none late
    assert st["periods"] == list(range(1, n + 1)) and st["end_period"] == n + 1
    assert st["fifo_full"] == st["underruns"] == 0 and st["notices"] == []
    active = [depth for period, depth in fifo.before_tick if period <= n]
    assert len(active) == n and min(active) >= 1 and max(active) <= 4  # fed, never starved, never near 8
    # the recorded step count is the reference's steps at the board's STEP edges (16 us after each tick)
    ref = simulate(SHAPER, PeriodCommands(dict(enumerate(units, start=1)), n + 1))
    edges = t_stream[0] + ref.ticks * 0.5e-6 + 16e-6
    t = (back.frame["t_us"].to_numpy() - world.t0_us) / 1e6
    expected = np.array([ref.directions[edges <= ti + 1e-9].sum() for ti in t])
    np.testing.assert_array_equal(back.frame["steps"].to_numpy(), expected)
    assert back.meta["done_position"] == ref.position == 0
    assert expected.max() == ref.directions.cumsum().max() > 0
    # the lead-in before STREAM and the tail after DONE are recorded
    assert t_stream[0] - t[0] >= 1.0 - 1e-3 and t[-1] - edges[-1] >= 1.0
    assert world.stepper.received[-2:] == ["END", "EN 0"] and not world.stepper.enabled
    assert not world.daq.streaming


@pytest.fixture
def spied():
    rig, world = make_rig()
    rig.daq.port = SpyPort(rig.daq.port)
    rig.stepper.port = SpyPort(rig.stepper.port)
    yield rig
    assert bytes(rig.daq.port.written) == b""
    assert bytes(rig.stepper.port.written) in (b"", b"POS*8E\n")  # at most the question where the cable is


OVERSHOOT = hs.StreamShaper((6144, -2048), (0, 50_000), allow_negative=True)  # 1.5 v, then -0.5 v


class _Shaper:
    def __init__(self, amplitudes, times, name="bad"):
        self.amplitudes, self.times, self.name = amplitudes, times, name


REFUSED = [
    ({"setpoints": [0.0, 400.0]}, SafetyError, "set-point 1: 400 mm/s exceeds the stream's speed limit"),
    ({"setpoints": [0.0, math.nan]}, SafetyError, "set-point 1: nan mm/s is not finite"),
    ({"setpoints": [0.0, "fast"]}, SafetyError, "set-point 1: 'fast' is not a number"),
    ({"setpoints": []}, SafetyError, "no set-points"),
    ({"setpoints": "abc"}, SafetyError, "array or an iterable"),
    ({"setpoints": [[1.0, 2.0]]}, SafetyError, "set-point 0: 2 speeds for the rig's 1 tendon(s)"),
    ({"shaper": _Shaper([0.5, 0.4], [0.0, 0.1])}, ValueError, "sum to 0.9, not 1"),
    ({"shaper": _Shaper([0.5, 0.5], [0.0, 1.5])}, ValueError, "cannot be loaded on the board"),
    ({"lead_periods": 8}, ValueError, "lead must be"),
    ({"tail_s": -1.0}, ValueError, "tail_s"),
    ({"rate_hz": 50}, SafetyError, "DAQ rate"),
    # the whole shaped motion, from where the cable is, with the board's planner:
    ({"setpoints": [390.0] * 50}, SafetyError, "would reach the travel limit (156 steps)"),
    ({"setpoints": [-100.0] * 5}, SafetyError, "would reach the travel limit (0 steps)"),
    # where clamps are allowed, a command past the travel is refused still: 390 mm/s is 15.28 steps a period
    ({"setpoints": [390.0] * 50, "allow_clamps": True}, SafetyError, "set-point 10: the set-points integ"),
    # 100 mm/s = 411 units = 3.92 steps a period: 38 periods command 148.9 steps, the overshoot of 1.5 v
    # before -0.5 v (5 periods later) adds 0.5 x 3.92 x 5 = 9.8 steps: 158.7 > 156
    ({"setpoints": [100.0] * 38, "shaper": OVERSHOOT}, SafetyError, "would reach the travel limit (156"),
    ({"setpoints": [365.0] * 10, "shaper": OVERSHOOT}, SafetyError, "would exceed the speed limit"),
]


@pytest.mark.parametrize("kwargs, error, message", REFUSED)
def test_bad_streams_are_refused_before_anything_moves(spied, tmp_path, kwargs, error, message):
    kwargs = {"setpoints": [0.0, 100.0, 0.0], "shaper": None, **kwargs}
    with pytest.raises(error, match=message.replace("(", r"\(").replace(")", r"\)")):
        stream(spied, path=tmp_path / "never", progress=False, **kwargs)
    assert not list(tmp_path.iterdir())


def _stalling_host(world, at: int, stall_s: float):
    """Set-points of 50 mm/s; before the ``at``-th the host stalls for ``stall_s`` of device time."""
    for i in range(40):
        if i == at:
            world.advance_to(world.t + stall_s)
        yield 50.0


def _too_fast_at(at: int):
    for i in range(40):
        yield 1000.0 if i == at else 50.0


def _interrupt_after(world, seconds: float):
    def listener(w):
        if w.stepper.stream is not None and w.t > w.stepper.stream.t0 + seconds:
            w.listeners.clear()
            raise KeyboardInterrupt

    world.listeners.append(listener)


ENDINGS = [
    # what goes wrong, the error, its message, whether the stepper can still hear the cleanup
    ("too fast", SafetyError, "set-point 25: 1000 mm/s exceeds", True),
    ("ctrl-c", KeyboardInterrupt, None, True),
    ("reset", BoardReset, "stepper board reset", True),
    ("hang", BoardTimeout, "did not answer 'V", False),
    ("host stalls", StreamStarved, r"watchdog fired \(N,WATCHDOG,", True),
    ("clamp in the tail", StreamLimit, r"after the last set-point, the shaped stream would reach the", True),
]


@pytest.mark.parametrize("what, error, message, heard", ENDINGS, ids=[e[0] for e in ENDINGS])
def test_every_way_a_stream_ends_early_cleans_up_and_saves(tmp_path, what, error, message, heard):
    options = {"reset": "&reset_at=2.0", "hang": "&hang_at=2.0"}.get(what, "")
    rig, world = make_rig(stepper_options=options, silence_s=0.5)
    shaper = hs.StreamShaper.quantise([0.25, 0.5, 0.25], [0.0, 0.125, 0.25])  # ZVD-like: 250 ms
    setpoints = {
        "too fast": _too_fast_at(25),
        "host stalls": _stalling_host(world, 20, 0.15),
        "clamp in the tail": iter([390.0] * 11),  # 168 steps in all: only the shaper's tail reaches 156
    }.get(what, iter([50.0] * 300))
    if what == "ctrl-c":
        _interrupt_after(world, 0.5)
    with pytest.raises(error, match=message) as info:
        stream(rig, setpoints, shaper, path=tmp_path / "s", progress=False)
    saved = info.value.saved_path
    assert saved.name.startswith("s_aborted_") and not (tmp_path / "s.csv").exists()
    rec = recordings.load(saved)
    assert rec.status == "aborted" and error.__name__ in rec.meta["abort_reason"]
    st = rec.meta["scenario"]["stream"]
    assert 0 < st["n_setpoints"] == len(st["periods"])
    assert len(rec.frame) == rig.daq.parser.stats.samples > 1000
    if heard:  # ABORT (the stream stops at once) and EN 0 (driver off) reached the stepper
        assert world.stepper.received[-2:] == ["ABORT", "EN 0"] and not world.stepper.enabled
        assert world.stepper.stream is None
    else:
        assert "cleanup: ABORT to the stepper board failed" in rec.meta["abort_reason"]
    assert not world.daq.streaming and world.daq.received[-1] == "STOP"
    if what == "clamp in the tail":  # the host planned the tail before END: stopped before the board clamped
        assert st["notices"] == [] and st["n_setpoints"] == 11 and st["end_period"] is None
    if what == "host stalls":
        assert st["watchdog"] and not world.stepper.enabled


def test_clamps_may_be_allowed_and_are_counted(tmp_path):
    rig, world = make_rig()
    # the command stays within the travel (148.9 steps up and back), the overshooting shaper does not
    setpoints = [100.0] * 38 + [0.0] * 30 + [-100.0] * 38
    rec = stream(rig, iter(setpoints), OVERSHOOT, path=tmp_path / "c", progress=False, allow_clamps=True)
    st = rec.meta["scenario"]["stream"]
    # the motion was not the command's (clamped): never complete, and saved beside the name it asked for
    assert rec.status == "deviated" and "clamped" in rec.meta["deviation"]
    assert rec.path.name.startswith("c_deviated_") and not (tmp_path / "c.csv").exists()
    assert st["clamps"] == {"speed": 0, "travel": 2}
    assert st["notices"] == ["N,LIMIT,TRAVEL,156", "N,LIMIT,TRAVEL,0"]
    sent = dict(zip(st["periods"], st["setpoints"], strict=True))
    ref = simulate(OVERSHOOT, PeriodCommands(sent, st["end_period"]))
    assert rec.frame["steps"].max() == 156 and rec.meta["done_position"] == ref.position != 0
    assert recordings.load(rec.path).status == "deviated"


LONG_ARM_UNIT_MM_S = math.pi * 40.0 / 1600 * STEPS_PER_S_PER_UNIT  # rigs/long-arm.toml: 0.0785 mm per step


def test_the_set_point_limit_is_the_builds_not_the_papers(tmp_path):
    """The long-arm rig's fastest step is ceil(1e6 x 0.0785 / 150) = 524 us, so its boards take set-points
    up to floor(2^20 / 524) = 2001 units (149.9 mm/s), not the paper's 1640 of 639 us (the firmware built for
    it says the same: ``tests/firmware/test_second_rig_fw.py``). Its emulated stepper takes V 2001 and refuses
    V 2002 naming 2001; the host streams 2001 units through the unit shaper with no clamp predicted or met
    (5 periods: 5 x 2001 x 625 / 2^16 = 95.4 steps), and refuses 2002 units before anything moves."""
    long_arm = rigfile.load(rigfile.resolve("long-arm"))
    board = make_world(long_arm).stepper
    talk(board)  # its HELLO
    replies = talk(board, *hs.UNIT_SHAPER.commands(), "EN 1", "STREAM", "V 2001", "V 2002")
    assert replies[-2:] == ["OK V 1", "ERR RANGE set-point -2001..2001"]
    rig, _ = make_rig(rig=long_arm)
    rec = stream(rig, [2001 * LONG_ARM_UNIT_MM_S] * 5, None, path=tmp_path / "top", progress=False)
    st = rec.meta["scenario"]["stream"]
    assert rec.status == "complete" and st["setpoints"] == [2001] * 5 and st["notices"] == []
    assert rec.meta["done_position"] == 95 == rec.frame["steps"].max()
    with pytest.raises(SafetyError, match=r"set-point 0: .* \(2001 board units\)"):
        stream(rig, [2002 * LONG_ARM_UNIT_MM_S], None, path=tmp_path / "over", progress=False)


def test_the_pacer_keeps_its_lead_when_the_boards_clocks_differ():
    """A board whose clock runs 0.5 % fast or slow against the DAQ's: the pacer re-anchors on ERR FULL and on
    a late period, so such events stay rare (the FIFO of 8 and its lead absorb the drift in between)."""
    from helpers.rig.stream import Pacer

    for drift in (0.995, 1.005):
        pacer = Pacer(0, lead=4)
        fifo, sent, taken, events = 0, 0, 0, 0
        for step in range(60_000):  # 60 s of DAQ time in 1 ms steps, 6000 set-points
            now = step * 1000.0
            while taken < int(now / (10_000 * drift)):  # the board's tick takes one set-point
                taken += 1
                fifo = max(fifo - 1, 0)
            while pacer.due(now):
                if fifo >= hs.FIFO_DEPTH:  # ERR FULL
                    pacer.refused_full(now)
                    events += 1
                    break
                period = taken + 1 + fifo  # the board's reply: OK V <next period + queued>
                fifo += 1
                sent += 1
                events += period > pacer.next_period  # periods went by without a set-point
                pacer.accepted(period, now)
        assert sent > 5900 and events <= 20, (drift, events)


@pytest.mark.slow
def test_the_example_of_docs_streaming_prints_what_the_page_says(capsys):
    """docs/streaming.md's example, run as it stands on the tuned virtual rig."""
    from helpers.base.paths import REPO_ROOT

    page = (REPO_ROOT / "docs" / "streaming.md").read_text()
    code = page.split("```python\n")[2].split("```")[0]
    printed = page.split("prints (simulated, on the tuned virtual rig):\n\n```\n")[1].split("```")[0]
    exec(compile(code, "docs/streaming.md", "exec"), {})  # noqa: S102 - the page's own example
    assert capsys.readouterr().out == printed
