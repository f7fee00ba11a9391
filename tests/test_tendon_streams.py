"""Streams of several tendons: the emulated four-tendon stepper's multi-axis stream mode, and the host's
:func:`helpers.rig.stream.stream` on a rig of four tendons (checks before any byte, the stream, its
recording, a board reset mid-stream).

Expected values by hand from ``rigs/four-tendon.toml``: pi 65 / 800 = 0.2552544 mm per step, so one
set-point unit (2^-16 step per 16 us = 0.95367 steps/s) is 0.2434288 mm/s, and a unit held for one 10 ms
period (625 x 16 us) moves 625 / 65536 = 0.0095367 step. The travel is 156 steps (39.8 mm), the release below
rest floor(20 / 0.2552544) = 78 steps (19.9 mm), the set-point limit floor(2^20 / 639) = 1640 units =
399.2 mm/s.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from tendon_fakes import Clock, talk

from helpers import recordings, rigfile
from helpers.__main__ import error_line
from helpers.board import stream_reference as hs
from helpers.commands.home import home
from helpers.rig import BoardReset, Rig, SafetyError
from helpers.rig.stream import SetpointSource, StreamLimit, check_stream
from helpers.rig.stream import stream as run_stream
from helpers.virtual.emulator.boards import StepperEmulator, build_limits
from helpers.virtual.emulator.world import build_world, forget_world, get_world, register_world


@pytest.fixture(scope="module")
def four() -> rigfile.RigFile:
    return rigfile.load(rigfile.resolve("four-tendon"))


# --- the emulated four-tendon stepper ----------------------------------------------------------------------
def test_emulated_stepper_streams_every_axis(four) -> None:
    """Unit shaper, ten periods of MV 1000 0 500 -100 (the FIFO holds 8): axis 0 moves
    floor(10 x 1000 x 625 / 65536) = floor(95.37) = 95 steps, axis 2 floor(47.68) = 47, axis 3 is driven down
    from 0 and held there (its notice names the axis); period k drives [(k + 1) T, (k + 2) T), so axis 0's
    first step is due 20 ms + 65536 / 1000 x 16 us = 21.048576 ms after STREAM, on the tick at or after it
    (21.0490 ms), its edge 24 us later. The build has no release (``RIG_AXIS_RELEASE_STEPS`` absent), so
    axis 3 is held at 0."""
    clock = Clock()
    s = StepperEmulator(clock, dataclasses.replace(build_limits(four), release_steps=()))
    s.reset()
    s.out.clear()
    assert talk(s, "EN 1", "MSEG 100000 1 1 1 1", *hs.UNIT_SHAPER.commands(), "STREAM") == [
        "OK EN 1", "OK MSEG 1", "OK SHAPER 1", "OK IMP 0", "OK STREAM 0",
    ]  # fmt: skip
    replies = talk(s, *["MV 1000 0 500 -100"] * 8, "MV 1000 0 500 -100")
    assert replies == [f"OK MV {k}" for k in range(1, 9)] + ["ERR FULL 8 set-points queued"]
    s.steps_until(0.0105)  # tick 1 takes period 1's set-points: axis 3 is held at 0 at once
    assert talk(s, "MV 1000 0 500 -100", "MV 1000 0 500 -100") == [
        "N,LIMIT,TRAVEL,0,3", "OK MV 9", "ERR FULL 8 set-points queued",
    ]  # fmt: skip
    s.steps_until(0.0205)
    assert talk(s, "MV 1000 0 500 -100", "V 7", "END") == ["OK MV 10", "ERR FULL 8 set-points queued",
                                                            "OK END 11"]  # fmt: skip
    times, axes, signs = s.steps_until(1.0)
    assert [b.decode().split("*")[0] for b in s.out] == ["DONE 95 0 47 0"]
    s.out.clear()
    assert [int((axes == a).sum()) for a in range(4)] == [95, 0, 47, 0] and set(signs.tolist()) == {1}
    assert times[axes == 0][0] == pytest.approx(0.0210490 + 24e-6, abs=1e-9)
    assert talk(s, "GO", "POS") == ["ERR STATE programme empty", "OK POS 95 0 47 0"]  # STREAM emptied it


def test_emulated_stepper_streams_a_paid_out_axis_down_to_its_release(four) -> None:
    """Unit shaper, eight periods of MV 0 0 0 -1640 (the fastest): axis 3 would go 8 x 1640 x 625 / 65536 =
    125.1 steps down, but the build's release holds it at -78 (its notice names the position and the axis).
    Its first step is due 20 ms + 65536 / 1640 x 16 us = 20.639375 ms after STREAM: tick ceil(41278.75) =
    41279 (20.6395 ms), its edge 24 us later."""
    clock = Clock()
    s = StepperEmulator(clock, build_limits(four))
    s.reset()
    s.out.clear()
    assert talk(s, "EN 1", *hs.UNIT_SHAPER.commands(), "STREAM", *["MV 0 0 0 -1640"] * 8) == [
        "OK EN 1", "OK SHAPER 1", "OK IMP 0", "OK STREAM 0", *[f"OK MV {k}" for k in range(1, 9)],
    ]  # fmt: skip
    s.steps_until(0.0105)
    assert talk(s, "END") == ["OK END 9"]
    times, axes, signs = s.steps_until(1.0)
    lines = [b.decode().split("*")[0] for b in s.out]
    assert lines == ["N,LIMIT,TRAVEL,-78,3", "DONE 0 0 0 -78"]
    assert set(axes.tolist()) == {3} and len(axes) == 78 and set(signs.tolist()) == {-1}
    assert times[0] == pytest.approx(41279 * 0.5e-6 + 24e-6, abs=1e-9)


def test_emulated_stepper_stream_refusals(four) -> None:
    clock = Clock()
    s = StepperEmulator(clock, build_limits(four))
    s.reset()
    s.out.clear()
    assert talk(s, "EN 1", "SHAPER 2 0", "IMP 0 2048 0", "IMP 1 2048 620016", "MV 0 0 0 0") == [
        "OK EN 1", "OK SHAPER 2", "OK IMP 0",
        "ERR RANGE delay: 0 first, rising, 16 us units, <= 0.62 s",  # a build with several axes: 0.62 s
        "ERR STATE not streaming",
    ]  # fmt: skip
    assert talk(s, "SHAPER 2 0", "IMP 0 2048 0", "IMP 1 2048 620000", "STREAM", "MV 1 2 3", "MV 0 1641 0 0",
                 "CLEAR", "SEG 1 1 1000", "MSEG 10000 1 1 1 1", "WAIT 1", "SHAPER 1 0", "STREAM",
                 "ABORT") == [
        "OK SHAPER 2", "OK IMP 0", "OK IMP 1", "OK STREAM 0",
        "ERR ARG MV needs 4 integers", "ERR RANGE axis 1 set-point -1640..1640",
        *["ERR STATE streaming"] * 6,
        "ABORTED 0 0 0 0",
    ]  # fmt: skip
    assert not s.enabled and s.stream is None


# --- the host: checks before any byte -----------------------------------------------------------------------
def _rows(n: int, **columns: float) -> np.ndarray:
    a = np.zeros((n, 4))
    for name, value in columns.items():
        a[:, int(name[1:]) - 1] = value
    return a


@pytest.mark.parametrize(
    ("setpoints", "message"),
    [
        # 50 mm/s = 205.40 -> 205 units = 1.95503 steps per period: the (unit-shaped) motion of period 80
        # passes 156 steps (79.8 periods)
        (_rows(100, t2=50.0), "tendon 2, set-point 79: the shaped stream would reach the travel limit (156 "
                              "steps) in period 80"),
        # -50 mm/s = -205 units = -1.95503 steps per period: period 40 passes -78 steps (the release)
        (_rows(50, t1=-50.0), "tendon 1, set-point 39: the shaped stream would reach the travel limit (-78 "
                              "steps) in period 40"),
        # 400 mm/s = 1643.2 units > 1640 (399.2 mm/s)
        (_rows(3, t3=400.0), "tendon 3, set-point 0: 400 mm/s exceeds the stream's speed limit of 399.2 mm/s "
                             "(1640 board units)"),
        (np.full((2, 4), np.nan), "tendon 1, set-point 0: nan mm/s is not finite"),
        (np.zeros((5, 3)), "set-point 0: 3 speeds for the rig's 4 tendon(s)"),
        (np.zeros((0, 4)), "no set-points: the stream is empty"),
        (np.zeros((60_001, 4)), "60001 set-points last 600 s, over the host's limit of 600 s"),
    ],
)  # fmt: skip
def test_streams_past_a_tendons_limit_are_refused_in_one_line(four, setpoints, message) -> None:
    with pytest.raises(SafetyError) as info:
        check_stream(setpoints, four, (0, 0, 0, 0), hs.UNIT_SHAPER)
    assert message in str(info.value) and "\n" not in str(info.value)
    assert error_line(info.value)[1] == 3  # docs/faults.md: refused by the safety limits


def test_a_period_with_every_tendon_slack_is_refused(four) -> None:
    """Without pretension every tendon is slack at zero: pulling tendon 1 at 10 mm/s (41.08 -> 41 units) for
    five periods and releasing it for five brings every tendon back to 0 steps at set-point 9."""
    slack = rigfile.loads(four.text.replace("pretension_n = 2.3554", "pretension_n = 0.0"), "slack.toml")
    there = _rows(5, t1=10.0)
    plan = check_stream(there, slack, (0, 0, 0, 0), hs.UNIT_SHAPER)
    assert plan.end == (1, 0, 0, 0)  # 5 x 41 x 625 / 65536 = 1.955 steps
    back = np.vstack([there, -there])
    with pytest.raises(SafetyError) as info:
        check_stream(back, slack, (0, 0, 0, 0), hs.UNIT_SHAPER)
    assert str(info.value).startswith(
        "tendons 1-4, set-point 9: every tendon slack at positions (0, 0, 0, 0) steps "
        "(pretension + k pull = 0.00, 0.00, 0.00, 0.00 N <= 0)"
    )
    # with the rig file's pretension (2.3554 N each) the same stream is allowed
    assert check_stream(back, four, (0, 0, 0, 0), hs.UNIT_SHAPER).end == (0,) * 4


def test_a_shaped_overshoot_is_refused_naming_the_tendon(four) -> None:
    """A 1.5 / -0.5 shaper (the second impulse 50 ms later) makes 365 mm/s (1499 units) on tendon 4 a shaped
    1.5 x 1499 = 2248.5 units in period 1, over the 1640 limit; allowed, the plan says so with the notice."""
    overshoot = hs.StreamShaper((6144, -2048), (0, 50_000), allow_negative=True)
    rows = _rows(3, t4=365.0)
    assert SetpointSource(rows, four).check_all()[0].tolist() == [0, 0, 0, 1499]
    with pytest.raises(StreamLimit, match=r"^tendon 4, set-point 0: the shaped stream would exceed the speed "
                                          r"limit .* in period 1$"):  # fmt: skip
        check_stream(rows, four, (0, 0, 0, 0), overshoot)
    assert check_stream(rows, four, (0, 0, 0, 0), overshoot, allow_clamps=True).end[3] > 0
    long = hs.StreamShaper((2048, 2048), (0, 700_000))
    with pytest.raises(SafetyError, match="beyond the 0.62 s a stepper board with several axes holds"):
        check_stream(rows, four, (0, 0, 0, 0), long)


# --- the host: streaming on the virtual four-tendon rig ----------------------------------------------------
@pytest.fixture(scope="module")
def stream_rig(four):
    register_world(build_world(four, "tendon-streams-test")).stepper.take_output()  # its HELLO at power-up
    # a stepper that keeps counting when its port opens (no reset): home() may trust its count
    rig = Rig("virtual", four, world="tendon-streams-test", stepper_options="&reset_on_open=0")
    yield rig
    rig.close()
    forget_world("tendon-streams-test")


def test_refused_streams_send_nothing(stream_rig) -> None:
    world = get_world("tendon-streams-test")
    sent = len(world.stepper.received), len(world.daq.received)
    with pytest.raises(SafetyError, match="tendon 2, set-point 0: 400 mm/s exceeds"):
        run_stream(stream_rig, _rows(100, t2=400.0), path="unused/never")
    with pytest.raises(ValueError, match="lead must be an integer number of periods in 1-7"):
        run_stream(stream_rig, _rows(3), path="unused/never", lead_periods=8)
    with pytest.raises(SafetyError, match="tendon 2, set-point 79: the shaped stream would reach"):
        run_stream(stream_rig, _rows(100, t2=50.0), path="unused/never")  # asked where the tendons are first
    assert (len(world.stepper.received) - sent[0], len(world.daq.received)) == (1, sent[1])  # POS alone
    assert world.stepper.received[-1] == "POS"


def test_a_four_tendon_stream_records_every_channel(stream_rig, tmp_path) -> None:
    """Tendon 1 at 20 mm/s (82.16 -> 82 units) for 20 periods: floor(20 x 82 x 625 / 65536) = floor(15.64)
    = 15 steps; tendon 2 at 15 mm/s (61.62 -> 62) for 10 periods from period 21: floor(5.91) = 5; tendon 4 at
    30 mm/s (123.24 -> 123) for 10: floor(11.73) = 11; tendon 3 at -30 mm/s for 10 pays out below rest: -11.73
    steps, the count within one step of it, -11. Through a two-impulse shaper (0.5, 0.5 at 50 ms) every tendon
    ends where its set-points integrate to."""
    sp = _rows(40)
    sp[:20, 0], sp[20:30, 1], sp[:10, 3], sp[:10, 2] = 20.0, 15.0, 30.0, -30.0
    shaper = hs.StreamShaper((2048, 2048), (0, 50_000))
    rec = run_stream(stream_rig, sp, shaper, path=tmp_path / "g" / "four_stream", tail_s=0.3, lead_in_s=0.2,
                     progress=False)  # fmt: skip
    assert rec.status == "complete" and stream_rig.positions() == (15, 5, -11, 11)
    stream = rec.meta["scenario"]["stream"]
    assert rec.meta["scenario"]["kind"] == "stream" and rec.meta["tendons"] == 4
    assert stream["periods"] == list(range(1, 41)) and stream["end_period"] == 41  # no underrun (one clock)
    assert stream["tendon_setpoints"][0] == [82] * 20 + [0] * 20
    assert stream["tendon_setpoints"][1] == [0] * 20 + [62] * 10 + [0] * 10
    assert stream["tendon_setpoints"][3] == [123] * 10 + [0] * 30
    assert stream["tendon_setpoints"][2] == [-123] * 10 + [0] * 30
    assert stream["setpoints"] == stream["tendon_setpoints"][0] and stream["notices"] == []
    assert stream["impulses"]["delays_us"] == [0, 50_000]
    loaded = recordings.load(rec.path)
    f = loaded.frame
    assert loaded.tendons == 4 and (f["t_us"].diff().dropna() == 1000).all()
    assert [int(f[f"steps_{i}"].iloc[-1]) for i in range(4)] == [15, 5, -11, 11]
    assert [int(f[f"steps_{i}"].iloc[0]) for i in range(4)] == [0, 0, 0, 0]
    # tendon 1's first step: period 1 drives from 20 ms after STREAM, half of it (the first impulse) at once:
    # 65536 / (0.5 x 82) x 16 us = 25.6 ms more, 45.6 ms after STREAM (the DAQ's sample then, within 2 ms)
    first = f["t_us"][f["steps_0"] > 0].iloc[0] - rec.meta["t_go_us"]  # GO is STREAM here
    assert 45_000 <= first <= 48_000, first
    # tendon 2: period 21 drives from 220 ms, its first step 65536 / (0.5 x 62) x 16 us = 33.8 ms later
    first = f["t_us"][f["steps_1"] > 0].iloc[0] - rec.meta["t_go_us"]
    assert 253_800 <= first <= 256_800, first
    home(stream_rig.stepper, stream_rig.rig)
    assert stream_rig.positions() == (0, 0, 0, 0)


def test_a_board_reset_mid_stream_stops_it_and_saves_what_was_recorded(stream_rig, tmp_path) -> None:
    world = get_world("tendon-streams-test")
    def reset_into_the_stream(w):  # the stepper reboots 0.2 s of device time after STREAM
        if w.stepper.stream is not None and w.t > w.stepper.stream.t0 + 0.2:
            w.listeners.remove(reset_into_the_stream)
            w.stepper.faults.reset_at = w.t + 1e-3

    world.listeners.append(reset_into_the_stream)
    with pytest.raises(BoardReset) as info:
        run_stream(stream_rig, _rows(60, t1=20.0), path=tmp_path / "g" / "reset", lead_in_s=0.2,
                   progress=False)  # fmt: skip
    exc = info.value
    assert error_line(exc)[1] != 0 and exc.cleanup == []  # the rebooted board took ABORT and EN 0
    assert exc.saved_path.name.startswith("reset_aborted_") and not (tmp_path / "g" / "reset.csv").exists()
    rec = recordings.load(exc.saved_path)
    assert rec.status == "aborted"
    assert rec.meta["abort_reason"].startswith("BoardReset: the stepper board reset")
    assert 0 < rec.meta["scenario"]["stream"]["n_setpoints"] < 60 and len(rec.frame) > 300
    assert not world.stepper.enabled and world.stepper.stream is None and not world.daq.streaming


def test_an_allowed_clamp_is_recorded_as_deviated(stream_rig, tmp_path) -> None:
    """The overshooting shaper above on tendon 4 with ``allow_clamps``: the board clamps period 1 (its notice
    names axis 3), the run goes on and is saved as ``deviated`` beside the name; the tendon ends where the
    board's planner said."""
    overshoot = hs.StreamShaper((6144, -2048), (0, 50_000), allow_negative=True)
    rows = _rows(3, t4=365.0)
    plan = check_stream(rows, stream_rig.rig, stream_rig.positions(), overshoot, allow_clamps=True)
    rec = run_stream(stream_rig, rows, overshoot, path=tmp_path / "g" / "clamped", allow_clamps=True,
                     tail_s=0.2, lead_in_s=0.2, progress=False)  # fmt: skip
    assert rec.status == "deviated" and "clamped the shaped motion" in rec.meta["deviation"]
    assert rec.meta["scenario"]["stream"]["notices"] == ["N,LIMIT,SPEED,1,3"]
    assert rec.meta["scenario"]["stream"]["clamps"] == {"speed": 1, "travel": 0}
    assert rec.path.name.startswith("clamped_deviated_") and not (tmp_path / "g" / "clamped.csv").exists()
    assert stream_rig.positions() == plan.end and plan.end[3] > 0
    home(stream_rig.stepper, stream_rig.rig)
