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

import numpy as np
import pytest

from helpers import rigfile
from helpers.board.protocol import frame
from helpers.virtual.emulator.tendon_boards import TendonDaqEmulator, TendonStepperEmulator, build_limits
from helpers.virtual.emulator.tendon_world import tendon_world

REST_COUNTS = 122.88 + 2.3554 * 491.52 / 20.0


@pytest.fixture(scope="module")
def four() -> rigfile.RigFile:
    return rigfile.load(rigfile.resolve("four-tendon"))


class _Clock:
    def __init__(self) -> None:
        self.t, self.seed, self.t0_us, self.go_times = 0.0, 0, 0, []


def _talk(board, *cmds: str) -> list[str]:
    out = []
    for c in cmds:
        board.receive(frame(c))
        out += [line.decode().rstrip("\n").rpartition("*")[0] for line in board.out]
        board.out.clear()
    return out


def _stepper(four: rigfile.RigFile) -> tuple[TendonStepperEmulator, _Clock]:
    clock = _Clock()
    s = TendonStepperEmulator(clock, build_limits(four))
    s.reset()
    s.out.clear()
    return s, clock


def test_build_limits_are_the_rig_files(four: rigfile.RigFile) -> None:
    lim = build_limits(four)
    assert (lim.axes, lim.channels, lim.travel_steps) == (4, 4, (156, 156, 156, 156))
    assert (lim.min_interval_us, lim.max_interval_us, lim.programme_max) == (639, 1_000_000, 64)
    assert lim.rig_hash == four.hash


def test_emulated_stepper_replies_per_axis(four: rigfile.RigFile) -> None:
    s, _ = _stepper(four)
    assert _talk(s, "PING", "CONFIG") == [
        f"PONG stepper 2.2.0+{four.hash}",
        "OK CONFIG 4 64 639 1000000 156 156 156 156",
    ]
    assert _talk(s, "EN 1", "MSEG 100000 10 7 157 0", "MSEG 10000 0 16 0 0", "MSEG 100000 0 0 0",
                 "MSEG 100000 0 0 0 0", "MSEG 200000 100 100 100 100", "MSEG 200000 50 50 50 57", "GO",
                 "POS") == [
        "OK EN 1",
        "ERR RANGE axis 2 steps -156..156",
        "ERR RANGE axis 1 interval 639-1000000 us",  # 16 steps in 10 ms: 625 us apart
        "ERR ARG MSEG needs 5 integers",
        "ERR RANGE no axis moves (a dwell is WAIT)",
        "OK MSEG 1",
        "OK MSEG 2",
        "ERR RANGE axis 3 travel 0-156 steps",  # 100 + 57 = 157
        "OK POS 0 0 0 0",
    ]  # fmt: skip


def test_emulated_stepper_steps_on_the_firmware_ticks(four: rigfile.RigFile) -> None:
    s, clock = _stepper(four)
    assert _talk(s, "EN 1", "MSEG 7001 3 0 1 2", "WAIT 1", "SEG 1 2 1000", "GO")[-1] == "OK GO 3"
    times, axes, signs = s.axis_steps_until(1.0)
    # step k of n in W: tick ceil(k 2W / n) (0.5 us): 14002/3 -> 4668, 9335, 14002 ticks; one step at the
    # window's end; 14002/2 -> 7001, 14002; then the dwell (1 ms) and 1000 us per SEG step
    want = {0: [2334.0, 4667.5, 7001.0, 9001.0, 10001.0], 2: [7001.0], 3: [3500.5, 7001.0]}
    for a, us in want.items():
        np.testing.assert_allclose(times[axes == a] * 1e6, us, atol=1e-6)
    assert list(signs) == [1] * 8 and 1 not in axes
    s.finish_if_due(1.0)
    assert [b.decode().split("*")[0] for b in s.out] == ["DONE 5 0 1 2"]


def test_emulated_daq_sends_every_channel_and_axis(four: rigfile.RigFile) -> None:
    clock = _Clock()
    d = TendonDaqEmulator(clock, build_limits(four))
    d.reset()
    assert _talk(d, "CONFIG", "RATE 50")[1:] == ["OK CONFIG 4 4 100 2000", "ERR RANGE rate 100-2000 Hz"]
    body = d.payload(np.array([[180, 181, 182, 183]]), np.array([[0, 5, -3, 156]]))
    assert body == ["180,181,182,183,0,5,-3,156"]


@pytest.fixture(scope="module")
def world_at_rest(four: rigfile.RigFile):
    w = tendon_world(four, "tendons-test-rest")
    w.daq.take_output()
    w.daq.receive(frame("START"))
    w.advance_to(0.3)
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
    w = tendon_world(four, "tendons-test-pull")
    for b in (w.daq, w.stepper):
        b.take_output()
    _talk(w.daq, "START")
    assert _talk(w.stepper, "EN 1", "MSEG 20000 0 0 0 20", "GO") == ["OK EN 1", "OK MSEG 1", "OK GO 1"]
    w.advance_to(0.4)
    rows = [line.split(b"*")[0].decode().split(",") for line in w.daq.take_output().splitlines()]
    data = np.array([[int(x) for x in r[1:]] for r in rows if r[0] == "D"])
    assert [b.decode().split("*")[0] for b in w.stepper.out] == ["DONE 0 0 0 20"]
    assert list(data[-1, 6:]) == [0, 0, 0, 20]
    # tendon 3 (pulled 20 steps, 5.1 mm) rises well above its pretension; the others do not move first
    assert data[-1, 5] > REST_COUNTS + 3 * 24.576
    assert np.all(np.abs(data[0, 2:6] - REST_COUNTS) < 3.0)
