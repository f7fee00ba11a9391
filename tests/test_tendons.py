"""Several tendons on the host's side: the emulated boards built for four tendons, the world that drives the
spatial twin from their step streams, the multi-tendon rig and its safety limits, recordings and metrics.

Expected values are worked out by hand from ``rigs/four-tendon.toml``'s keys: the spool of 65 mm at 800 steps
per revolution gives pi 65 / 800 = 0.255254 mm per step, so the travel of 40 mm is floor(156.7) = 156 steps
and the speed limit of 400 mm/s is 1567.1 steps/s (under the 2000 steps/s cap): a step at most every
ceil(638.1) = 639 us. The 4-20 mA loop through 150 ohm on a 10-bit ADC at 5 V reads 1024 x 0.6 / 5 = 122.88
counts at 0 N and 614.4 at 20 mA: 491.52 counts over the cells' 20 N, 24.576 counts/N; the pretension of
2.3554 N reads 122.88 + 57.887 = 180.77 counts.
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest
from tendon_fakes import Clock, talk
from twins import integrated_by

from helpers import recordings, rigfile
from helpers.__main__ import error_line, main
from helpers.board.programmes import Dwell, Move, Programme
from helpers.board.protocol import frame
from helpers.commands.benchmarks.serial import pty_stream
from helpers.commands.home import PositionUnknown, home
from helpers.commands.metrics_report import move_tables
from helpers.rig import Rig, SafetyError, WrongRig
from helpers.rig.link import Link
from helpers.rig.safety import check_programme, static_tensions
from helpers.rig.trim import TensionGuard
from helpers.virtual.emulator.boards import BuildLimits, DaqEmulator, StepperEmulator, build_limits
from helpers.virtual.emulator.world import (
    VirtualWorld,
    build_world,
    forget_world,
    get_world,
    register_world,
)

REST_COUNTS = 122.88 + 2.3554 * 491.52 / 20.0


@pytest.fixture(scope="module")
def four() -> rigfile.RigFile:
    return rigfile.load(rigfile.resolve("four-tendon"))


def _stepper(four: rigfile.RigFile) -> tuple[StepperEmulator, Clock]:
    clock = Clock()
    s = StepperEmulator(clock, build_limits(four))
    s.reset()
    s.out.clear()
    return s, clock


def test_build_limits_are_the_rig_files(four: rigfile.RigFile) -> None:
    lim = build_limits(four)
    assert (lim.axes, lim.channels, lim.travel_steps) == (4, 4, (156, 156, 156, 156))
    # release_mm = 20 over pi 65 / 800 = 0.25525 mm per step: 78.35, floored
    assert lim.release_steps == (78, 78, 78, 78)
    assert (lim.min_interval_us, lim.max_interval_us, lim.programme_max) == (639, 1_000_000, 64)
    assert lim.rig_hash == four.hash


def test_emulated_stepper_replies_per_axis(four: rigfile.RigFile) -> None:
    s, _ = _stepper(four)
    assert talk(s, "PING", "CONFIG") == [
        f"PONG stepper 2.3.0+{four.hash}",
        "OK CONFIG 4 64 639 1000000 156 156 156 156 78 78 78 78",  # the releases after the travels
    ]
    assert talk(s, "EN 1", "MSEG 200000 10 7 235 0", "MSEG 10000 0 16 0 0", "MSEG 100000 0 0 0",
                 "MSEG 100000 0 0 0 0", "MSEG 200000 100 100 100 100", "MSEG 200000 50 50 50 57", "GO",
                 "POS") == [
        "OK EN 1",
        "ERR RANGE axis 2 steps -234..234",  # 78 below rest + 156 above
        "ERR RANGE axis 1 interval 639-1000000 us",  # 16 steps in 10 ms: 625 us apart
        "ERR ARG MSEG needs 5 integers",
        "ERR RANGE no axis moves (a dwell is WAIT)",
        "OK MSEG 1",
        "OK MSEG 2",
        "ERR RANGE axis 3 travel -78-156 steps",  # 100 + 57 = 157
        "OK POS 0 0 0 0",
    ]  # fmt: skip


def test_emulated_stepper_steps_on_the_firmware_ticks(four: rigfile.RigFile) -> None:
    s, clock = _stepper(four)
    assert talk(s, "EN 1", "MSEG 7001 3 0 1 2", "WAIT 1", "SEG 1 2 1000", "GO")[-1] == "OK GO 3"
    times, axes, signs = s.steps_until(1.0)
    # step k of n in W: tick ceil(k 2W / n) (0.5 us): 14002/3 -> 4668, 9335, 14002 ticks; one step at the
    # window's end; 14002/2 -> 7001, 14002; then the dwell (1 ms) and 1000 us per SEG step
    want = {0: [2334.0, 4667.5, 7001.0, 9001.0, 10001.0], 2: [7001.0], 3: [3500.5, 7001.0]}
    for a, us in want.items():
        np.testing.assert_allclose(times[axes == a] * 1e6, us, atol=1e-6)
    assert list(signs) == [1] * 8 and 1 not in axes
    s.finish_if_due(1.0)
    assert [b.decode().split("*")[0] for b in s.out] == ["DONE 5 0 1 2"]


def test_emulated_daq_sends_every_channel_and_axis(four: rigfile.RigFile) -> None:
    clock = Clock()
    d = DaqEmulator(clock, build_limits(four))
    d.reset()
    assert talk(d, "CONFIG", "RATE 50")[1:] == ["OK CONFIG 4 4 100 2000", "ERR RANGE rate 100-2000 Hz"]
    d.take_output()
    counts, steps = np.array([[180, 181, 182, 183]]), np.array([[0, 5, -3, 156]])
    d.emit_samples(np.array([1]), np.array([0.001]), counts, steps)  # slot 1: 1 ms after START
    assert d.take_output() == frame("D,0,1000,180,181,182,183,0,5,-3,156")


@pytest.fixture(scope="module")
def world_at_rest(four: rigfile.RigFile):
    w = build_world(four, "tendons-test-rest")
    w.daq.take_output()
    w.daq.receive(frame("START"))
    w.advance_to(0.3 + 3 * 104e-6)  # the sample at 0.3 s is complete once its fourth channel is read
    rows = [line.split(b"*")[0].decode().split(",") for line in w.daq.take_output().splitlines()]
    data = np.array([[int(x) for x in r[1:]] for r in rows if r[0] == "D"])
    return w, data


def test_twin_at_rest_reads_the_pretension_on_every_channel(world_at_rest) -> None:
    """At rest every tendon holds its pretension: channels 1 and 3 are mirror images, and 0 and 2 too (the
    horizontal arm's weight is carried by the rod, the tensions are the pretension at the rest state)."""
    _, data = world_at_rest
    assert data.shape[1] == 2 + 4 + 4
    assert len(data) == 300  # 1 kHz for 0.3 s
    late = data[100:, 2:6].mean(axis=0)
    assert np.all(np.abs(late - REST_COUNTS) < 1.0), late
    assert abs(late[1] - late[3]) < 0.5
    assert np.all(data[:, 6:] == 0)


def test_world_drives_each_tendon_from_its_axis(four: rigfile.RigFile) -> None:
    w = build_world(four, "tendons-test-pull")
    for b in (w.daq, w.stepper):
        b.take_output()
    talk(w.daq, "START")
    assert talk(w.stepper, "EN 1", "MSEG 20000 0 0 0 20", "GO") == ["OK EN 1", "OK MSEG 1", "OK GO 1"]
    w.advance_to(0.4)
    rows = [line.split(b"*")[0].decode().split(",") for line in w.daq.take_output().splitlines()]
    data = np.array([[int(x) for x in r[1:]] for r in rows if r[0] == "D"])
    assert [b.decode().split("*")[0] for b in w.stepper.out] == ["DONE 0 0 0 20"]
    assert list(data[-1, 6:]) == [0, 0, 0, 20]
    # tendon 3 (pulled 20 steps, 5.1 mm) rises well above its pretension; the others do not move first
    assert data[-1, 5] > REST_COUNTS + 3 * 24.576
    assert np.all(np.abs(data[0, 2:6] - REST_COUNTS) < 3.0)


def _pull_data(w, ends) -> np.ndarray:
    for b in (w.daq, w.stepper):
        b.take_output()
    talk(w.daq, "START")
    talk(w.stepper, "EN 1", "MSEG 20000 0 0 0 20", "GO")
    for t in ends:
        w.advance_to(t)
    rows = [line.split(b"*")[0].decode().split(",") for line in w.daq.take_output().splitlines()]
    return np.array([[int(x) for x in r[1:]] for r in rows if r[0] == "D"])


def test_intervals_ending_mid_conversion_give_the_samples_of_whole_ones(four: rigfile.RigFile) -> None:
    # the pseudo-terminal server advances the world to wall-clock instants, often between a sample's
    # channel 0 and its channel 3 (312 us later): every sample must still come, from the twin at each
    # channel's own instant, as when the world moves on whole milliseconds
    with integrated_by("rk4"):  # the emulator's timing is the point: RK4 at its stable step in both
        whole = _pull_data(build_world(four, "tendons-test-whole"), np.arange(1, 201) * 1e-3)
        ragged_ends = np.cumsum(np.tile([0.37e-3, 0.05e-3, 0.21e-3, 0.53e-3, 0.11e-3], 200))
        ragged = _pull_data(build_world(four, "tendons-test-ragged"), ragged_ends[ragged_ends <= 0.2])
    n = min(len(whole), len(ragged))
    assert n >= 195  # 1 kHz for 0.2 s, the last sample still converting at 0.2 s in one of them
    np.testing.assert_array_equal(ragged[:n, :2], whole[:n, :2])  # seq and t_us: no sample lost or repeated
    np.testing.assert_array_equal(ragged[:n, 6:], whole[:n, 6:])  # the step counts
    # the ADC counts: the same twin at the same instants, integrated over other step partitions (RK4 at its
    # stable step either way) and the same noise: within one count
    assert np.max(np.abs(ragged[:n, 2:6] - whole[:n, 2:6])) <= 1
    assert ragged[n - 1, 5] > REST_COUNTS + 3 * 24.576  # tendon 3's pull is in the ragged record too


# --- the host: safety per tendon, connecting, running, homing ------------------------------------------
def _programme(*moves):
    """Items from ``(window_us, steps)`` pairs (``steps`` None: a dwell of the window)."""
    return Programme(tuple(Dwell(w // 1000) if n is None else Move(w, n) for w, n in moves))


@pytest.mark.parametrize(
    ("moves", "message"),
    [
        ([(200_000, (100, 0, 0, 0)), (200_000, (57, 0, 0, 0))],
         "tendon 1, item 2 (MSEG 200000 57 0 0 0): travel limit: position 157 steps (40.07 mm) is past "
         "-78-156 steps (-19.9-39.8 mm)"),
        ([(100_000, (0, 0, -79, 0))], "tendon 3, item 1 (MSEG 100000 0 0 -79 0): travel limit: position -79"),
        ([(10_000, (0, 16, 0, 0))],
         "tendon 2, item 1 (MSEG 10000 0 16 0 0): interval limit: a step every 625 us (408 mm/s) is below "
         "the minimum interval 639 us"),
        ([(100_000, (1, 1, 1, 1, 1))], "item 1 (MSEG 100000 1 1 1 1 1): 5 step counts, but the rig has 4"),
        ([(61_000_000, None)], "dwell limit: item 1 (WAIT 61000) exceeds the longest dwell, 60000 ms"),
    ],
)  # fmt: skip
def test_programmes_past_a_tendons_limit_are_refused_in_one_line(four, moves, message) -> None:
    with pytest.raises(SafetyError) as info:
        check_programme(_programme(*moves), four, (0, 0, 0, 0))
    assert message in str(info.value) and "\n" not in str(info.value)
    assert error_line(info.value)[1] == 3  # docs/faults.md: refused by the safety limits


def test_a_state_with_every_tendon_slack_is_refused(four) -> None:
    """With no pretension, pretension + k pull = 0 N at position 0: returning every tendon there leaves the
    arm on no tendon (71706.96 N/m x 10 steps x 0.255254 mm = 183.0 N while pulled)."""
    slack = rigfile.loads(four.text.replace("pretension_n = 2.3554", "pretension_n = 0.0"), "slack.toml")
    check_programme(_programme((100_000, (10, 0, 0, 0))), slack, (0, 0, 0, 0))
    refusal = r"tendons 1-4, item 2: every tendon slack at positions \(0, 0, 0, 0\)"
    with pytest.raises(SafetyError, match=refusal):
        check_programme(_programme((100_000, (10, 0, 0, 0)), (100_000, (-10, 0, 0, 0))), slack, (0, 0, 0, 0))
    np.testing.assert_allclose(static_tensions(slack, (10, 0, 0, 0)), [183.035, 0, 0, 0], atol=1e-3)
    np.testing.assert_allclose(static_tensions(four, (0, 0, 0, 0)), [2.3554] * 4)
    # homing returns to the rest the rig file describes
    check_programme(_programme((100_000, (-10, 0, 0, 0))), slack, (10, 0, 0, 0), rest_ok=True)


def test_boards_reporting_fewer_channels_than_the_rig_file_are_refused(four) -> None:
    w = build_world(four, "tendons-test-two-channels")
    w.limits = BuildLimits(four.hash, (156, 156, 156, 156), channels=2)
    w.daq.limits = w.limits
    register_world(w)
    try:
        with pytest.raises(WrongRig) as info:
            Rig("virtual", four, world=w.name)
    finally:
        forget_world(w.name)
    assert str(info.value).startswith(
        "the daq board was built for 2 load cell(s) and 4 step counter(s), but rig 'four-tendon' has 4 "
        "tendon(s)"
    )
    assert "CONFIG" in w.daq.received and not [c for c in w.stepper.received if c not in ("PING", "CONFIG")]
    assert "make -C firmware RIG=" in str(info.value) and error_line(info.value)[1] == 4


def test_a_stepper_built_without_the_rig_files_release_is_refused(four) -> None:
    w = build_world(four, "tendons-test-no-release")
    # a build without RIG_AXIS_RELEASE_STEPS: its CONFIG lists no release
    w.limits = dataclasses.replace(w.limits, release_steps=())
    w.stepper.limits = w.limits
    register_world(w)
    try:
        with pytest.raises(WrongRig) as info:
            Rig("virtual", four, world=w.name)
    finally:
        forget_world(w.name)
    assert str(info.value).startswith(
        "the stepper board's axis 0 travels -0..156 steps, but rig 'four-tendon' gives tendon 1 -78..156 "
        "(release_mm, travel_mm)"
    )
    assert "\n" not in str(info.value) and error_line(info.value)[1] == 4


class _Configured:
    """A board whose ``CONFIG`` reply is given (no port)."""

    def __init__(self, reply: str) -> None:
        self.reply, self.sent = reply, []

    def command(self, line: str, *args, **kwargs) -> str:  # noqa: D102
        self.sent.append(line)
        return self.reply


def _builds(four, stepper_reply: str) -> None:
    """The rig's check of both boards' builds (``CONFIG``) against ``four``, boards answering as given."""
    rig = type("R", (), {"n": 4, "rig": four, "_config": staticmethod(Rig._config)})()
    rig.daq, rig.stepper = _Configured("OK CONFIG 4 4 100 2000"), _Configured(stepper_reply)
    Rig._check_builds(rig)


def test_config_lists_the_releases_after_the_travels_or_none(four) -> None:
    head = "OK CONFIG 4 64 639 1000000 156 156 156 156"
    _builds(four, head + " 78 78 78 78")  # the four-tendon build: its releases after the travels
    with pytest.raises(WrongRig, match="axis 0 travels -0..156 steps"):  # a build without a release
        _builds(four, head)
    with pytest.raises(WrongRig, match=r"built for CONFIG \(4, 64, .*, 78\), but rig 'four-tendon'"):
        _builds(four, head + " 78")  # neither A nor 2A numbers after the limits
    with pytest.raises(WrongRig, match="built for 3 axis/axes, but rig 'four-tendon' has 4 tendon"):
        _builds(four, "OK CONFIG 3 64 639 1000000 156 156 156 78 78 78")
    with pytest.raises(WrongRig, match="built for 5 axis/axes, but rig 'four-tendon' has 4 tendon"):
        _builds(four, "OK CONFIG 5 64 639 1000000 " + " ".join(["156"] * 5 + ["78"] * 5))


def test_a_one_tendon_build_is_refused_by_a_four_tendon_host(four, monkeypatch) -> None:
    from helpers.virtual.emulator import world as worlds

    paper = build_world(rigfile.default_rig(), "tendons-test-paper")  # one axis, the paper's hash
    # the paper's boards where the four-tendon rig's are looked for (a port of hardware built for another rig)
    monkeypatch.setitem(worlds._WORLDS, ("tendons-test-paper", four.hash), paper)
    with pytest.raises(WrongRig, match="built for rig 481e87e3, but this host runs rig 'four-tendon'"):
        Rig("virtual", four, world="tendons-test-paper")
    assert set(paper.stepper.received) <= {"PING"}  # nothing else sent


@pytest.fixture(scope="module")
def four_rig(four):
    register_world(build_world(four, "tendons-test-rig")).stepper.take_output()  # its HELLO at power-up
    # a stepper that keeps counting when its port opens (no reset): home() may trust its count
    rig = Rig("virtual", four, world="tendons-test-rig", stepper_options="&reset_on_open=0")
    yield rig
    rig.close()
    forget_world("tendons-test-rig")


def _run(rig, programme, tmp_path, tail_s=0.2, **options):
    """Run ``programme`` (a recording under ``tmp_path``); its frame."""
    name = f"r{len(list(tmp_path.glob('*.csv')))}"
    options.setdefault("guard", TensionGuard() if rig.n > 1 else None)  # several tendons: the floor watched
    return rig.run(programme, path=tmp_path / name, tail_s=tail_s, progress=False, **options).frame


def test_a_coordinated_programme_records_every_tendon_and_home_brings_them_back(four_rig, tmp_path) -> None:
    world = get_world("tendons-test-rig")
    sent = len(world.stepper.received)
    with pytest.raises(SafetyError, match="tendon 4, item 1 .* position 157"):
        _run(four_rig, _programme((200_000, (0, 0, 0, 157))), tmp_path)
    assert len(world.stepper.received) == sent  # refused before any byte
    # two coordinated moves from zero, then back to one tendon pulled
    f = _run(four_rig, _programme((40_000, (8, 0, 0, 5))), tmp_path)
    assert four_rig.positions() == (8, 0, 0, 5)
    back = _programme((40_000, (0, 6, 0, -5)), (10_000, None), (40_000, (-8, 0, 0, 0)))
    f = _run(four_rig, back, tmp_path, tail_s=0.3)
    assert four_rig.positions() == (0, 6, 0, 0)
    assert list(f.columns[:10]) == ["seq", "t_us"] + [f"adc_{i}" for i in range(4)] + [
        f"steps_{i}" for i in range(4)
    ]
    assert (f["t_us"].diff().dropna() == 1000).all()  # 1 kHz
    first, last = f.iloc[0], f.iloc[-1]
    assert [first[f"steps_{i}"] for i in range(4)] == [8, 0, 0, 5]  # positions from zero
    assert [last[f"steps_{i}"] for i in range(4)] == [0, 6, 0, 0]
    assert last["cable_mm_1"] == pytest.approx(6 * 3.14159265 * 65 / 800)
    assert f["tension_n_0"].iloc[0] == pytest.approx((first["adc_0"] - 122.88) / 24.576)
    assert "moved tendon 2 6 steps" in home(four_rig.stepper, four_rig.rig)
    assert four_rig.positions() == (0, 0, 0, 0)
    assert home(four_rig.stepper, four_rig.rig).startswith("every tendon is at position 0 already")


def test_tendons_pay_out_below_rest_down_to_the_release_and_home_pulls_them_back(four_rig, tmp_path) -> None:
    world = get_world("tendons-test-rig")
    sent = len(world.stepper.received)
    with pytest.raises(SafetyError, match=r"^programme refused: tendon 3, item 2 .* position -79 .* -78"):
        _run(four_rig, _programme((100_000, (0, 0, -40, 0)), (100_000, (0, 0, -39, 0))), tmp_path)
    assert len(world.stepper.received) == sent  # refused before any byte
    # tendon 3 paid out to the end of its release is slack: a travel test, not a move (no floor watch)
    f = _run(four_rig, _programme((100_000, (20, 0, -78, -5))), tmp_path, guard=TensionGuard(watch=False))
    assert four_rig.positions() == (20, 0, -78, -5)
    assert [f.iloc[-1][f"steps_{i}"] for i in range(4)] == [20, 0, -78, -5]
    assert f.iloc[-1]["cable_mm_2"] == pytest.approx(-78 * 3.14159265 * 65 / 800)
    home(four_rig.stepper, four_rig.rig)
    assert four_rig.positions() == (0, 0, 0, 0)


# --- recordings: version 4 for every tendon count, version 2 (before it) still read ---------------------
def test_one_tendon_recordings_are_written_and_read_as_before(tmp_path) -> None:
    """A version-2 recording (the one-tendon layout before version 4) loads with the one-tendon names too."""
    meta = {
        "schema_version": 2, "source": {"kind": "virtual-rig"}, "scenario": {"kind": "programme"},
        "calibration": {"newtons_per_count": 0.025, "offset_counts": 60.0, "mm_per_step": 0.2552544,
                        "origin": "test"},
        "rate_hz": 1000, "status": "complete", "counts": {"dropped": 0},
        "rig": recordings.rig_section(rigfile.default_rig()),
    }  # fmt: skip
    rows = [(s, 1000 * s, 100 + s, s // 4) for s in range(20)]
    frame = pd.DataFrame(rows, columns=["seq", "t_us", "adc", "steps"])  # version 2's columns, by hand
    rec = recordings.Recording(frame, meta)
    path = recordings.save(rec, tmp_path / "g" / "one")
    assert path.read_text().splitlines()[:2] == ["seq,t_us,adc,steps", "0,0,100,0"]
    rec = recordings.load(path)
    assert rec.meta["schema_version"] == 2 and rec.tendons == 1
    assert list(rec.frame.columns) == ["seq", "t_us", "adc_0", "steps_0", "t_s", "tension_n_0", "cable_mm_0",
                                       "adc", "steps", "tension_n", "cable_mm"]  # fmt: skip
    assert rec.frame["tension_n"].iloc[3] == pytest.approx((103 - 60.0) * 0.025)


@pytest.fixture(scope="module")
def tendon_recording_path(four_rig, tmp_path_factory):
    programme = _programme((40_000, (5, 0, 0, 4)), (40_000, (-5, 3, 0, -4)))
    path = four_rig.run(programme, path=tmp_path_factory.mktemp("tendon_rec") / "g" / "four", tail_s=0.2,
                        progress=False, guard=TensionGuard()).path  # fmt: skip
    home(four_rig.stepper, four_rig.rig)
    return path


def test_a_four_tendon_recording_round_trips_as_version_4(tendon_recording_path) -> None:
    path = tendon_recording_path
    header = "seq,t_us,adc_0,adc_1,adc_2,adc_3,steps_0,steps_1,steps_2,steps_3,tip_x_um,tip_y_um,tip_z_um"
    assert path.read_text().splitlines()[0] == header  # derived columns are never stored; the twin's tip is
    rec = recordings.load(path)
    assert (rec.meta["schema_version"], rec.meta["tendons"], rec.tendons) == (4, 4, 4)
    assert rec.meta["rig"]["name"] == "four-tendon"
    f = rec.frame
    assert [f"tension_n_{i}" in f and f"cable_mm_{i}" in f for i in range(4)] == [True] * 4
    np.testing.assert_allclose(f["tension_n_2"], (f["adc_2"] - 122.88) / 24.576)
    np.testing.assert_allclose(f["cable_mm_1"], f["steps_1"] * 3.14159265358979 * 65 / 800)
    assert list(f.iloc[-1][[f"steps_{i}" for i in range(4)]]) == [0, 3, 0, 0]
    np.testing.assert_allclose(f["t_s"].iloc[:3], [0.0, 0.001, 0.002])
    assert rec.meta["tip"]["origin"].startswith("twin-provided") and rec.meta["tip"]["unit"] == "um"
    np.testing.assert_allclose(f["tip_z_mm"], f["tip_z_um"] / 1000.0)


def test_the_tip_is_the_twins_at_each_sample(pulse_recording_path) -> None:
    """The tip columns are the spatial twin's tip node: at rest (a fresh world) the horizontal arm (gravity
    along -x, rigs/four-tendon.toml) sags towards -x, symmetric in y, and its tip lies within the rod's 240 mm
    of the clamp; the pull of tendons 1 and 2 (90 degrees apart, 0-based 0 and 1) moves it."""
    f = recordings.load(pulse_recording_path).frame
    p0 = f.loc[0, ["tip_x_mm", "tip_y_mm", "tip_z_mm"]].to_numpy(float)
    assert p0[0] < -1.0 and abs(p0[1]) < 0.01 and 200.0 < np.linalg.norm(p0) <= 240.0
    moved = np.linalg.norm(f[["tip_x_mm", "tip_y_mm", "tip_z_mm"]].to_numpy(float) - p0, axis=1)
    assert moved.max() > 1.0


def test_a_recording_without_the_tip_loads_unchanged(tendon_recording_path, tmp_path) -> None:
    """A hardware recording has no tip: without the ``tip`` key and columns it is written and read as before,
    and the metrics have no tip rows."""
    rec = recordings.load(tendon_recording_path, derive=False)
    meta = {k: v for k, v in rec.meta.items() if k not in ("tip", "csv_sha256")}
    bare = recordings.Recording(rec.frame.drop(columns=["tip_x_um", "tip_y_um", "tip_z_um"]), meta)
    path = recordings.save(bare, tmp_path / "g" / "hw")
    header = "seq,t_us,adc_0,adc_1,adc_2,adc_3,steps_0,steps_1,steps_2,steps_3"
    assert path.read_text().splitlines()[0] == header
    back = recordings.load(path)
    assert not any(c.startswith("tip") for c in back.frame.columns)
    assert move_tables([back], 0.05).tip.empty


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda m: m.update(tendons=3), "tendons: 3, but the rig file has 4"),
        (lambda m: (m.update(tendons=3), [m["calibration"][k].pop() for k in ("newtons_per_count",
                    "offset_counts", "mm_per_step")]), "tendons: 3, but the rig file has 4"),
        (lambda m: m["calibration"].update(mm_per_step=[0.25, 0.25]),
         "calibration.mm_per_step: expected a list of 4 numbers > 0 (mm per step, one per tendon)"),
        (lambda m: m.pop("rig"), "rig: missing (a recording of schema_version 4 keeps its rig file)"),
        (lambda m: m.update(schema_version=5), "schema_version: unknown 5 (this code reads (1, 2, 3, 4))"),
        (lambda m: m.update(tip="twin"), "tip: expected an object (the twin-provided tip columns' origin"),
        (lambda m: m.pop("tip"), "header"),  # tip columns without the key: not the contract's header
    ],
)  # fmt: skip
def test_a_bad_four_tendon_recording_is_refused_in_one_line(tendon_recording_path, tmp_path, change, message):
    meta = json.loads(tendon_recording_path.with_suffix(".json").read_text())
    change(meta)
    target = tmp_path / "bad.json"
    target.write_text(json.dumps(meta))
    (tmp_path / "bad.csv").write_bytes(tendon_recording_path.read_bytes())
    with pytest.raises(recordings.RecordingError) as info:
        recordings.load(target)
    assert message in str(info.value) and "\n" not in str(info.value)
    assert error_line(info.value)[1] == 5


def test_a_step_count_within_the_release_and_the_travel_is_a_recording_the_rig_can_make(
    tendon_recording_path, tmp_path
) -> None:
    """A step count changes by at most the release and the travel together from the recording's start: 78 +
    156 = 234 steps on the four-tendon rig (a tendon paid out to -78 when the recording started, then pulled
    to 156, or the reverse)."""
    rec = recordings.load(tendon_recording_path, derive=False)
    for steps, refused in ((-234, False), (-235, True)):
        frame = rec.frame.copy()
        frame["steps_2"] = steps  # tendon 3 stood still in this recording
        meta = {k: v for k, v in rec.meta.items() if k != "csv_sha256"}
        path = recordings.save(recordings.Recording(frame, meta), tmp_path / "g" / f"at{-steps}")
        if not refused:
            assert (recordings.load(path).frame["steps_2"] == steps).all()
            continue
        with pytest.raises(
            recordings.RecordingError, match="steps_2: -235 at row 0 is beyond the travel of 234"
        ):
            recordings.load(path)


# --- metrics per tendon --------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def pulse_recording_path(four, tmp_path_factory):
    """Tendons 1 and 2 (0-based 0 and 1) pulled 6 and 4 steps together after 0.6 s, held 1.6 s, released
    (a rig of its own: the twin at rest)."""
    register_world(build_world(four, "tendons-test-pulse"))
    four_rig = Rig("virtual", four, world="tendons-test-pulse")
    pull, hold = (20_000, (6, 4, 0, 0)), (1_600_000, None)
    programme = _programme((600_000, None), pull, hold, (20_000, (-6, -4, 0, 0)))
    path = four_rig.run(programme, path=tmp_path_factory.mktemp("pulse") / "g" / "p", tail_s=1.6,
                        progress=False, guard=TensionGuard()).path  # fmt: skip
    four_rig.close()
    forget_world("tendons-test-pulse")
    return path


def _by_hand(f, i: int, lead: int = 0) -> dict:
    """docs/metrics.md, from the frame alone: the motions from the lead's count (steps_0: it rises most), y0
    the median of the 0.5 s before, yf the median of the window's last 1.0 s, the Up peak its maximum and the
    Down peak its minimum."""
    t, s, y = f["t_s"].to_numpy(), f[f"steps_{lead}"].to_numpy(), f[f"tension_n_{i}"].to_numpy()
    up = int(np.argmax(s > s[0]))
    top = int(np.argmax(s == s.max()))
    down = top + int(np.argmax(s[top:] < s.max()))
    out = {}
    for name, a, b in (("Up", up, down), ("Down", down, len(t))):
        y0 = np.median(y[(t >= t[a] - 0.5) & (t < t[a])])
        yf = np.median(y[(t >= t[b - 1] - 1.0) & (t < t[b - 1] + 1e-9) & (t >= t[a])])
        peak = y[a:b].max() if name == "Up" else y[a:b].min()
        over = 100 * (peak - yf) / (yf - y0) if name == "Up" else 100 * (yf - peak) / (y0 - yf)
        out[name] = (peak, over)
    return out


def test_metrics_reports_each_tendons_table_ii_metrics(pulse_recording_path, capsys) -> None:
    assert main(["metrics", str(pulse_recording_path)]) == 0
    out = capsys.readouterr().out
    assert "Per tendon (1 recording(s) of several tendons; tendons numbered as in the rig file" in out
    tables = move_tables([recordings.load(pulse_recording_path)], 0.05)
    table = tables.tendons
    # tendons numbered from 1; tendon 1 leads (no direction recorded: its count rises most, 6 against 4)
    assert list(zip(table["tendon"], table["role"], table["motion"], strict=True)) == [
        (1, "lead", "Up"), (1, "lead", "Down"), (2, "pulled", "Up"), (2, "pulled", "Down")
    ]
    f = recordings.load(pulse_recording_path).frame
    for i in (0, 1):
        want = _by_hand(f, i)
        for motion in ("Up", "Down"):
            row = table[(table["tendon"] == i + 1) & (table["motion"] == motion)].iloc[0]
            peak, over = want[motion]
            assert row["peak_n"] == pytest.approx(peak, abs=1e-9)
            assert row["overshoot_pct"] == pytest.approx(over, rel=1e-6)
            assert row["settling_ms"] > 0
    # tendons 3 and 4 never move: no row (no NaN row), and the line says why
    assert table["peak_n"].notna().all() and "segmentation failed" not in out
    assert ("lead tendon 1 (its count rises most (no bend direction recorded)); tendon 3 is held (its "
            "count at its level in the hold), tendon 4 is held (its count at its level in the hold): no "
            "up-hold-down move, so no Table II row") in out


def test_metrics_reports_the_tips_displacement_where_the_twin_provides_it(pulse_recording_path, capsys):
    """docs/metrics.md: the tip's displacement magnitude from where it stood before the move (the median of
    the 0.5 s before Up), its motions from the lead's count (tendon 1: 6 steps against 4), by hand from the
    frame's tip columns."""
    assert main(["metrics", str(pulse_recording_path)]) == 0
    out = capsys.readouterr().out
    assert "Tip displacement |p - p0| from where it stood before the move (twin-provided, simulated)" in out
    rec = recordings.load(pulse_recording_path)
    f = rec.frame.copy()
    t, s = f["t_s"].to_numpy(), f["steps_0"].to_numpy()
    up = t[np.argmax(s > s[0])]
    p = f[["tip_x_um", "tip_y_um", "tip_z_um"]].to_numpy(float) / 1000.0
    p0 = np.median(p[(t >= up - 0.5) & (t < up)], axis=0)
    f["tension_n_0"] = np.sqrt(((p - p0) ** 2).sum(axis=1))  # the tip's signal in _by_hand's place
    want = _by_hand(f, 0)
    table = move_tables([rec], 0.05).tip
    assert list(table["motion"]) == ["Up", "Down"] and list(table["lead"]) == [1, 1]
    for motion in ("Up", "Down"):
        row = table[table["motion"] == motion].iloc[0]
        peak, over = want[motion]
        assert row["peak_mm"] == pytest.approx(peak, abs=1e-9)
        assert row["overshoot_pct"] == pytest.approx(over, rel=1e-6)
    assert table.loc[0, "peak_mm"] > 1.0  # the pull moved the tip by millimetres


def test_metrics_writes_the_tips_table_to_csv_and_markdown(pulse_recording_path, tmp_path, capsys) -> None:
    stem, md = tmp_path / "out", tmp_path / "report.md"
    assert main(["metrics", str(pulse_recording_path), "--csv", str(stem), "--markdown", str(md)]) == 0
    tip = pd.read_csv(tmp_path / "out_tip.csv")
    assert list(tip["motion"]) == ["Up", "Down"] and tip.loc[0, "peak_mm"] > 1.0
    assert "## Tip displacement |p - p0| from where it stood before the move (twin-provided" in md.read_text()


def test_virtual_urls_build_the_four_tendon_world_for_a_four_tendon_rig_file(monkeypatch, four) -> None:
    """With the four-tendon rig file selected, ``virtual://`` (and serve-virtual-rig) build its world."""
    monkeypatch.setenv("HELPERS_RIG", "four-tendon")
    forget_world("tendons-test-url")
    try:
        rig = Rig("virtual", four, world="tendons-test-url")
        try:
            assert get_world("tendons-test-url", four).limits.axes == 4
            assert rig.stepper.command("CONFIG") == "OK CONFIG 4 64 639 1000000 156 156 156 156 78 78 78 78"
        finally:
            rig.close()
    finally:
        forget_world("tendons-test-url")


class _ClockPlant:
    """A plant double whose every output is the time (s) it is read at."""

    t = 0.0

    def advance(self, sample_times, step_times, step_tendons, step_signs):
        self.t = float(sample_times[-1])
        return {"output": np.repeat(np.asarray(sample_times, dtype=float)[:, None], 4, axis=1)}


class _MicrosecondSensor:
    def counts(self, output):
        return np.rint(np.asarray(output) * 1e6).astype(np.int64)

    def reseed(self, seed):
        pass


def test_each_channel_is_read_one_conversion_after_the_previous(four) -> None:
    """PROTOCOL.md: channel c is converted c x 104 us after channel 0, whose instant is ``t_us``."""
    w = VirtualWorld(_ClockPlant(), [_MicrosecondSensor()] * 4, name="skew", limits=build_limits(four))
    w.daq.take_output()
    w.daq.receive(frame("START"))
    w.advance_to(0.0101)
    rows = [line.split(b"*")[0].decode().split(",") for line in w.daq.take_output().splitlines()]
    data = np.array([[int(x) for x in r[1:]] for r in rows if r[0] == "D"])
    assert list(data[:, 1]) == [1000 * k for k in range(1, 10)]  # 10 ms is complete at 10.312 ms only
    for c in range(4):
        assert list(data[:, 2 + c] - data[:, 1]) == [104 * c] * 9


def test_home_command_brings_every_tendon_of_a_four_axis_stepper_back(four, monkeypatch) -> None:
    """``python -m helpers home``'s routine on a four-axis stepper: every axis back in one MSEG (the farthest,
    7 steps, at 50 mm/s: 0.255254 / 50 mm/s = 5105 us per step, a 35.7 ms window); tendon 2, paid out 3 steps
    below its rest, is pulled back up to it."""
    monkeypatch.setenv("HELPERS_RIG", "four-tendon")
    w = register_world(build_world(four, "tendons-test-home"))
    try:
        assert talk(w.stepper, "EN 1", "MSEG 40000 5 -3 0 7", "GO")[-1] == "OK GO 1"
        w.advance_to(0.1)
        url = "virtual://stepper?world=tendons-test-home&reset_on_open=0"
        stepper = Link.open(url, "stepper", four, four.hardware.stepper_baud)
        try:
            said = home(stepper, four)
        finally:
            stepper.close()
        assert w.stepper.positions == [0, 0, 0, 0] and not w.stepper.enabled
        assert said.startswith("moved tendon 1 5, tendon 2 3, tendon 4 7 steps (1.79 mm the farthest) back")
        assert "MSEG 35735 -5 3 0 -7" in w.stepper.received
    finally:
        forget_world("tendons-test-home")


class _RebootedStepper:
    """A stepper board that restarted as its port opened: its positions are unknown."""

    booted_on_open = True

    def __init__(self) -> None:
        self.sent: list[str] = []

    def command(self, line: str) -> str:
        self.sent.append(line)
        return f"OK {line}"


def test_home_after_a_restart_asks_for_every_tendon_at_its_rest_pretension(four) -> None:
    stepper = _RebootedStepper()
    with pytest.raises(PositionUnknown) as info:
        home(stepper, four)  # type: ignore[arg-type]
    text = str(info.value)
    assert "every tendon's position is unknown" in text and "every tendon is at its rest pretension" in text
    assert "slack" not in text.replace("--confirm-slack", "") and "\n" not in text
    assert "confirmed at its rest pretension" in home(stepper, four, confirm_slack=True)  # type: ignore[arg-type]
    assert stepper.sent == ["EN 0"]
    with pytest.raises(PositionUnknown, match="make sure the cable is slack and the arm down at rest"):
        home(stepper, rigfile.default_rig())  # type: ignore[arg-type]  # the paper's one tendon: its slack cable


@pytest.mark.slow
@pytest.mark.parametrize(("rig_name", "n"), [("paper", 1), ("four-tendon", 4)])
def test_a_rig_over_the_pseudo_terminal_server_records_every_channel_without_a_drop(rig_name, n):
    # the server's intervals end at wall-clock instants, mid-conversion of a sample's channels: every sample
    # still arrives, whole (2 s of device time at 1 kHz, 4 x real time); one benchmark for 1 to 4 tendons
    r = pty_stream(device_s=2.0, rate_hz=1000, speed=4.0, rig_name=rig_name)
    assert (r["rig"], r["tendons"]) == (rig_name, n)
    assert (r["dropped"], r["corrupted"], r["overruns"]) == (0, 0, 0)
    assert r["samples"] >= 2000 and r["rate_per_device_s"] == pytest.approx(1000.0, rel=1e-6)
    # a data line: "D", 2 + 2n fields (seq, t_us, n ADC counts, n step counts) of ",x" at least, "*hh\n";
    # at most 91 characters before its newline at four tendons (firmware/PROTOCOL.md)
    assert 1 + (2 + 2 * n) * 2 + 4 <= r["line_bytes_mean"] <= r["line_bytes_max"] <= 91 + 1
