"""The pseudo-terminal server: a Rig connects by device path, records a programme and a stream, and the data
say virtual-rig."""

from __future__ import annotations

import io
import threading
import time

import pytest
from rig_fakes import CALIBRATION, make_world

from helpers import recordings
from helpers import streaming as hs
from helpers.emulator.server import serve
from helpers.programmes import Dwell, Programme, Segment
from helpers.rig import Rig

READY_S = 60.0
"""Deadline (s) for the server and the boards to be ready: waits end on readiness, only a failure takes it."""


def _serve(speed: float):
    """Serve a fresh test-double world on pseudo-terminals in a thread: its ports, the world, a stop."""
    world = make_world()
    out = io.StringIO()
    stop = threading.Event()
    kwargs = {"speed": speed, "duration": 30.0, "out": out, "stop": stop}
    thread = threading.Thread(target=serve, args=(world,), kwargs=kwargs, daemon=True)
    thread.start()
    deadline = time.monotonic() + READY_S
    while out.getvalue().count("\n") < 2 and thread.is_alive() and time.monotonic() < deadline:
        time.sleep(0.01)  # the server prints its two device paths when it is ready
    paths = dict(line.split() for line in out.getvalue().splitlines())
    assert paths["daq"].startswith("/dev/pts/") and paths["stepper"].startswith("/dev/pts/")

    def finish() -> None:
        stop.set()
        thread.join(timeout=READY_S)
        assert not thread.is_alive()

    return (paths["daq"], paths["stepper"]), world, finish


def test_record_over_pseudo_terminals(tmp_path):
    ports, world, finish = _serve(speed=4.0)
    rig = Rig.connect(ports, calibration=CALIBRATION, hello_timeout=READY_S)
    prog = Programme((Dwell(100), Segment(1, 20, 1000), Dwell(100), Segment(-1, 20, 1000), Dwell(50)))
    rec = rig.run(prog, path=tmp_path / "pty", progress=False)
    rig.close()
    back = recordings.load(tmp_path / "pty")
    assert back.meta["source"]["kind"] == "virtual-rig"
    assert back.meta["source"]["via"] == "pseudo-terminal server"
    assert rec.status == "complete" and back.meta["counts"]["dropped"] == 0
    assert back.frame["steps"].max() == 20 and back.frame["steps"].iloc[-1] == 0
    assert back.meta["done_position"] == 0
    finish()


@pytest.mark.streaming
def test_stream_over_pseudo_terminals_in_real_time(tmp_path):
    """The same Rig.stream as in-process, paced by the server's device clock through the ports (at half real
    time: the host may stall 140 ms, a busy shared machine, before the board runs short)."""
    ports, world, finish = _serve(speed=0.5)
    rig = Rig.connect(ports, calibration=CALIBRATION, hello_timeout=READY_S)
    shaper = hs.StreamShaper((1024, 2048, 1024), (0, 40_000, 80_000))
    setpoints = [150.0] * 8 + [0.0] * 10 + [-150.0] * 8 + [0.0] * 4
    # a lead of 7 periods (70 ms of device time) before the board would run short
    rec = rig.stream(setpoints, shaper, path=tmp_path / "s", progress=False, lead_in_s=0.3, tail_s=0.3,
                     lead_periods=7)  # fmt: skip
    rig.close()
    finish()
    back = recordings.load(tmp_path / "s")
    st = back.meta["scenario"]["stream"]
    assert rec.status == "complete" and back.meta["source"]["via"] == "pseudo-terminal server"
    assert st["periods"] == list(range(1, 31)) and st["fifo_full"] == st["underruns"] == 0
    ref = hs.simulate(shaper, hs.PeriodCommands(dict(enumerate(st["setpoints"], start=1)), 31))
    assert back.frame["steps"].max() == ref.directions.cumsum().max() > 0
    assert back.meta["done_position"] == ref.position == back.frame["steps"].iloc[-1] == 0
