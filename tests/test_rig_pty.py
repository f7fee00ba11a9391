"""The pseudo-terminal server: a Rig connects by device path, records, and the data say virtual-rig."""

from __future__ import annotations

import io
import threading
import time

from rig_fakes import CALIBRATION, make_world

from helpers import recordings
from helpers.emulator.server import serve
from helpers.programmes import Dwell, Programme, Segment
from helpers.rig import Rig


def test_record_over_pseudo_terminals(tmp_path):
    world = make_world()
    out = io.StringIO()
    stop = threading.Event()
    kwargs = {"speed": 4.0, "duration": 30.0, "out": out, "stop": stop}
    thread = threading.Thread(target=serve, args=(world,), kwargs=kwargs, daemon=True)
    thread.start()
    for _ in range(200):
        if out.getvalue().count("\n") >= 2:
            break
        time.sleep(0.01)
    paths = dict(line.split() for line in out.getvalue().splitlines())
    assert paths["daq"].startswith("/dev/pts/") and paths["stepper"].startswith("/dev/pts/")
    rig = Rig.connect((paths["daq"], paths["stepper"]), calibration=CALIBRATION, hello_timeout=2.0)
    prog = Programme((Dwell(100), Segment(1, 20, 1000), Dwell(100), Segment(-1, 20, 1000), Dwell(50)))
    rec = rig.run(prog, path=tmp_path / "pty", progress=False)
    rig.close()
    back = recordings.load(tmp_path / "pty")
    assert back.meta["source"]["kind"] == "virtual-rig"
    assert back.meta["source"]["via"] == "pseudo-terminal server"
    assert rec.status == "complete" and back.meta["counts"]["dropped"] == 0
    assert back.frame["steps"].max() == 20 and back.frame["steps"].iloc[-1] == 0
    assert back.meta["done_position"] == 0
    stop.set()
    thread.join(timeout=10)
    assert not thread.is_alive()
