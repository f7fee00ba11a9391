"""Every protection of the one-tendon path holds on a rig of several tendons (the one ``Rig``).

On the in-process four-tendon virtual rig (the emulated four-tendon boards and the spatial twin): a signal
(SIGINT, SIGTERM, SIGHUP) during a coordinated programme ends it with the boards stopped and what was
recorded saved ``aborted`` with the reason; a signal after the last sample saves the run whole; a stepper
that hangs, a DAQ that resets, are found (the hung stepper by ``POS`` once ``DONE`` is late on the DAQ's
clock) and the run saved ``aborted``; a move asked of a tendon the rig does not have is refused in one line
with nothing sent. Faults are injected by the emulated boards (``helpers.virtual.emulator.boards.Faults``,
URL options); every wait is on the device clock.
"""

from __future__ import annotations

import dataclasses
import io
import os
import signal
import threading
import time

import numpy as np
import pytest

from helpers import recordings, rigfile
from helpers.__main__ import error_line
from helpers.base.signals import Interrupted, interrupts_from_signals
from helpers.board.programmes import Dwell, Move, Programme
from helpers.rig import BoardReset, BoardTimeout, Rig, SafetyError, WrongRig
from helpers.rig.stream import stream
from helpers.rig.trim import TensionGuard
from helpers.virtual.emulator.world import build_world, forget_world, register_world

PULL = (8, 0, 0, 5)
PROGRAMME = Programme((Dwell(300), Move(100_000, PULL), Dwell(1500), Move(100_000, tuple(-n for n in PULL)),
                       Dwell(300)))  # fmt: skip
"""2.3 s: tendons 1 and 4 pulled 8 and 5 steps, held 1.5 s, released."""


@pytest.fixture(scope="module")
def four() -> rigfile.RigFile:
    return rigfile.load(rigfile.resolve("four-tendon"))


_count = iter(range(10_000))


@pytest.fixture
def rig_of(four):
    """``rig_of(**options)``: a connected rig on a fresh four-tendon world (URL fault options)."""
    made = []

    def make(daq_options: str = "", stepper_options: str = "", silence_s: float = 2.0):
        name = f"protect-{next(_count)}"
        world = register_world(build_world(four, name))
        rig = Rig("virtual", four, world=name, daq_options=daq_options, stepper_options=stepper_options,
                  silence_s=silence_s)  # fmt: skip
        made.append((rig, name))
        return rig, world

    yield make
    for rig, name in made:
        rig.close()
        forget_world(name)


def _only(folder):
    csvs = sorted(folder.glob("*.csv"))
    assert len(csvs) == 1, [p.name for p in folder.iterdir()]
    return recordings.load(csvs[0])


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP], ids=["INT", "TERM", "HUP"])
def test_a_signal_mid_run_stops_every_tendon_and_saves_what_was_recorded(rig_of, tmp_path, sig):
    rig, world = rig_of()
    started: list[float] = []

    def send_in_the_hold(w):  # 1 s of device time after GO: tendons 1 and 4 pulled, in the hold
        if w.go_times and not started:
            started.append(w.go_times[-1])
        if started and w.t > started[0] + 1.0:
            w.listeners.remove(send_in_the_hold)
            os.kill(os.getpid(), sig)

    world.listeners.append(send_in_the_hold)
    with interrupts_from_signals(), pytest.raises(KeyboardInterrupt) as info:
        rig.run(PROGRAMME, path=tmp_path / "p", progress=False, guard=TensionGuard())
    exc = info.value
    assert exc.cleanup == []  # ABORT, EN 0 and STOP reached the boards
    assert world.stepper.received[-2:] == ["ABORT", "EN 0"] and not world.stepper.enabled
    assert not world.daq.streaming and world.daq.received[-1] == "STOP"
    rec = _only(tmp_path)
    assert rec.status == "aborted" and rec.path.name.startswith("p_aborted_") and rec.path == exc.saved_path
    said = {signal.SIGINT: "Ctrl-C", signal.SIGTERM: "SIGTERM", signal.SIGHUP: "SIGHUP"}[sig]
    reason = rec.meta["abort_reason"]
    assert reason.startswith("Interrupted: interrupted by ") and said in reason, reason
    assert rec.tendons == 4 and rec.frame["steps_0"].max() == 8 and rec.frame["steps_3"].max() == 5
    line, status = error_line(exc)
    assert status == 128 + sig and "partial recording saved to" in line
    assert "the stepper was stopped and disabled and the DAQ stopped" in line


def test_a_signal_after_the_last_sample_saves_the_run_whole(rig_of, tmp_path, monkeypatch):
    rig, world = rig_of()
    real = rig.recording

    def signalled(*args, **kwargs):  # building the recording: every sample is in
        monkeypatch.setattr(rig, "recording", real)
        os.kill(os.getpid(), signal.SIGTERM)
        return real(*args, **kwargs)

    monkeypatch.setattr(rig, "recording", signalled)
    with interrupts_from_signals(), pytest.raises(Interrupted) as info:
        rig.run(PROGRAMME, path=tmp_path / "p", progress=False, guard=TensionGuard())
        time.sleep(0)  # a signal handled after the run comes here
    assert info.value.complete and info.value.saved_path == tmp_path / "p.csv"
    rec = _only(tmp_path)
    assert rec.status == "complete" and rec.meta["done_positions"] == [0, 0, 0, 0]
    last = rec.frame.iloc[-1]
    assert rec.frame["steps_0"].max() == 8 and [last[f"steps_{i}"] for i in range(4)] == [0, 0, 0, 0]


def test_a_stepper_that_hangs_is_found_by_pos_when_done_is_late_on_the_daqs_clock(rig_of, tmp_path):
    rig, world = rig_of(stepper_options="&hang_at=1.5", silence_s=0.5)  # device s after the port opens
    with pytest.raises(BoardTimeout, match="the stepper board did not answer 'POS' in 0.5 s") as info:
        rig.run(PROGRAMME, path=tmp_path / "p", progress=False, guard=TensionGuard())
    rec = recordings.load(info.value.saved_path)
    assert rec.status == "aborted" and rec.meta["abort_reason"].startswith("BoardTimeout")
    assert "cleanup: ABORT to the stepper board failed" in rec.meta["abort_reason"]  # the line says so
    # the DAQ's clock ran past the programme's end and a grace before the host asked (no wall-clock deadline)
    t = (rec.frame["t_us"].to_numpy() - rec.meta["t_go_us"]) / 1e6
    assert t[-1] >= PROGRAMME.duration_s + 1.0
    assert "the driver may be on" in error_line(info.value)[0]


def test_a_daq_that_resets_mid_run_stops_the_stepper_and_saves_what_came_before(rig_of, tmp_path):
    rig, world = rig_of(daq_options="&reset_at=1.5")
    with pytest.raises(BoardReset, match="the daq board reset") as info:
        rig.run(PROGRAMME, path=tmp_path / "p", progress=False, guard=TensionGuard())
    assert info.value.cleanup == []
    rec = recordings.load(info.value.saved_path)
    assert rec.status == "aborted" and len(rec.frame) == rec.meta["counts"]["samples"] > 100
    assert rec.frame["t_us"].iloc[-1] <= 1.5e6 + world.t0_us  # nothing after the reset
    assert world.stepper.received[-2:] == ["ABORT", "EN 0"] and not world.stepper.running


def test_a_move_of_a_tendon_the_rig_does_not_have_is_refused_with_nothing_sent(rig_of, tmp_path):
    rig, world = rig_of()
    sent = len(world.stepper.received), len(world.daq.received)
    five = Programme((Move(100_000, (1, 0, 0, 0, 2)),))
    with pytest.raises(SafetyError) as info:
        rig.run(five, path=tmp_path / "never", progress=False, guard=TensionGuard())
    assert str(info.value) == (
        "programme refused: item 1 (MSEG 100000 1 0 0 0 2): 5 step counts, but the rig has 4 tendon(s)"
    )
    assert error_line(info.value)[1] == 3
    with pytest.raises(SafetyError, match="set-point 0: 5 speeds for the rig's 4 tendon"):
        stream(rig, np.zeros((10, 5)), None, path=tmp_path / "never")
    assert (len(world.stepper.received), len(world.daq.received)) == sent  # not a byte
    assert not list(tmp_path.iterdir())


def test_a_one_tendon_rig_file_refuses_the_boards_of_four(four, tmp_path):
    """Boards built for another tendon count with the rig file's hash (a header edited by hand): ``CONFIG``
    names it, before any other command."""
    name = "protect-paper-on-four"
    paper = rigfile.default_rig()
    world = build_world(four, name)  # four axes and channels, the paper's hash: kept as the paper's world
    limits = dataclasses.replace(world.limits, rig_hash=paper.hash)
    world.limits = world.daq.limits = world.stepper.limits = limits
    register_world(world)
    try:
        with pytest.raises(WrongRig) as info:
            Rig("virtual", paper, world=name)
    finally:
        forget_world(name)
    assert str(info.value).startswith(
        "the daq board was built for 4 load cell(s) and 4 step counter(s), but rig 'paper' has 1 tendon(s)"
    )
    assert set(world.daq.received) == {"PING", "CONFIG"} and set(world.stepper.received) == {"PING"}


def test_a_move_over_the_pseudo_terminal_server_at_half_speed_completes(four, tmp_path):
    """``serve-virtual-rig --speed 0.5``: the device clock at half real time; the move ends on ``DONE``."""
    from helpers.virtual.emulator.server import serve

    world = build_world(four, "protect-pty")
    out, stop = io.StringIO(), threading.Event()
    server = threading.Thread(target=serve, args=(world,), kwargs={"speed": 0.5, "duration": 60.0, "out": out,
                                                                    "stop": stop}, daemon=True)  # fmt: skip
    server.start()
    deadline = time.monotonic() + 60.0  # readiness: the server prints its two device paths
    while out.getvalue().count("\n") < 2 and server.is_alive() and time.monotonic() < deadline:
        time.sleep(0.01)
    paths = dict(line.split() for line in out.getvalue().splitlines())
    try:
        with Rig((paths["daq"], paths["stepper"]), four, hello_timeout=60.0) as rig:
            short = Programme((
                Dwell(100), Move(50_000, (3, 0, 0, 2)), Dwell(100), Move(50_000, (-3, 0, 0, -2),
            )))
            rec = rig.run(short, path=tmp_path / "pty", progress=False, guard=TensionGuard())
    finally:
        stop.set()
        server.join(timeout=60.0)
    assert rec.status == "complete" and rec.meta["done_positions"] == [0, 0, 0, 0]
    assert rec.frame["steps_0"].max() == 3 and rec.meta["counts"]["dropped"] == 0
