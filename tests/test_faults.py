"""Injected faults give a clear error within their timeout, leave the driver disabled and the data on disk."""

from __future__ import annotations

import pytest
from rig_fakes import make_rig

from helpers import recordings
from helpers.board.programmes import Dwell, Programme, Segment
from helpers.rig import BoardDisconnected, BoardReset, BoardTimeout, RunAborted

PROG = Programme((Dwell(100), Segment(1, 40, 1000), Dwell(300), Segment(-1, 40, 1000), Dwell(100)))
FAULT_AT = 0.8  # device seconds after the ports open: during the hold (after the 0.5 s wait for rest)

CASES = [
    ("daq", "reset_at", BoardReset, "daq board reset"),
    ("daq", "hang_at", BoardTimeout, "daq board sent no sample"),
    ("daq", "disconnect_at", BoardDisconnected, "daq board disconnected"),
    ("stepper", "reset_at", BoardReset, "stepper board reset"),
    ("stepper", "hang_at", BoardTimeout, "stepper board did not answer 'POS' in 0.5 s"),  # DONE late: asked
    ("stepper", "disconnect_at", BoardDisconnected, "stepper board disconnected"),
]


@pytest.mark.parametrize("board, fault, error, message", CASES)
def test_board_fault_aborts_cleanly(tmp_path, board, fault, error, message):
    opts = f"&{fault}={FAULT_AT}"
    where = {"daq_options": opts} if board == "daq" else {"stepper_options": opts}
    rig, world = make_rig(silence_s=0.5, **where)
    path = tmp_path / "aborted"
    with pytest.raises(error, match=message) as info:
        rig.run(PROG, path=path, progress=False)
    # every sample received before the fault is on disk, in an aborted recording that loads
    assert not path.with_suffix(".csv").exists()  # an aborted run never takes the run's own name
    assert info.value.saved_path.name.startswith("aborted_aborted_")
    rec = recordings.load(info.value.saved_path)
    assert rec.status == "aborted" and error.__name__ in rec.meta["abort_reason"]
    assert info.value.recording.meta["status"] == "aborted"
    assert len(rec.frame) == rig.daq.parser.stats.samples > 100
    if board == "daq":
        assert rec.frame["t_us"].iloc[-1] <= (FAULT_AT + 1e-3) * 1e6 + world.t0_us
    # the driver is disabled: the stepper heard ABORT and EN 0 ...
    assert not world.stepper.running
    if not (board == "stepper" and fault in ("hang_at", "disconnect_at")):
        assert world.stepper.received[-2:] == ["ABORT", "EN 0"] and not world.stepper.enabled
    else:  # ... unless it is the board that cannot hear: then the reason says the host could not disable it
        assert "cleanup: ABORT to the stepper board failed" in rec.meta["abort_reason"]
        assert "EN 0 to the stepper board failed" in rec.meta["abort_reason"]
    if not (board == "daq" and fault in ("hang_at", "disconnect_at")):
        assert not world.daq.streaming and world.daq.received[-1] == "STOP"


def test_keyboard_interrupt_mid_run_saves_and_disables(tmp_path):
    rig, world = make_rig()

    def interrupt(w):
        if w.t > 0.75:
            w.listeners.clear()
            raise KeyboardInterrupt

    world.listeners.append(interrupt)
    with pytest.raises(KeyboardInterrupt) as info:
        rig.run(PROG, path=tmp_path / "ki", progress=False)
    rec = recordings.load(info.value.saved_path)
    assert rec.status == "aborted" and "KeyboardInterrupt" in rec.meta["abort_reason"]
    assert world.stepper.received[-2:] == ["ABORT", "EN 0"] and not world.stepper.enabled
    assert not world.daq.streaming
    assert len(rec.frame) == rig.daq.parser.stats.samples > 0


def _injected_during_the_run(world):
    """The DAQ's injected-fault counts from the run's own START on (the wait for rest streams before it)."""
    before = {}
    start = world.daq.cmd_START

    def snapshot_start(cmd):
        before.clear()
        before.update(world.daq.injected)
        return start(cmd)

    world.daq.cmd_START = snapshot_start
    return lambda: {k: v - before.get(k, 0) for k, v in world.daq.injected.items()}


def test_transport_faults_are_counted_exactly_and_the_run_completes(tmp_path):
    rig, world = make_rig(daq_options="&drop=0.01&corrupt=0.01&garbage=0.005&seed=3")
    injected = _injected_during_the_run(world)
    rec = rig.run(PROG, path=tmp_path / "noisy", progress=False)
    inj = injected()
    counts = recordings.load(tmp_path / "noisy").meta["counts"]
    assert rec.status == "complete" and inj["dropped"] > 0 and inj["corrupted"] > 0 and inj["garbage"] > 0
    assert counts["dropped"] == inj["dropped"] + inj["corrupted"]  # a corrupted data line loses its seq too
    assert counts["corrupted"] == inj["corrupted"] + inj["garbage"]
    assert counts["samples"] + counts["dropped"] == world.daq.n_sent


def test_overruns_are_counted(tmp_path):
    rig, world = make_rig(daq_options="&overrun_every=50")
    injected = _injected_during_the_run(world)
    rec = rig.run(PROG, path=tmp_path / "late", progress=False)
    assert rec.meta["counts"]["overruns"] == injected()["overrun_periods"] > 0
    assert rec.meta["counts"]["dropped"] == 0


def test_a_stream_of_garbage_aborts_with_a_clear_reason(tmp_path):
    rig, world = make_rig(daq_options="&garbage=1.0&corrupt=0.5")
    with pytest.raises(RunAborted, match="corrupted lines") as info:
        rig.run(PROG, path=tmp_path / "garbage", progress=False)
    assert recordings.load(info.value.saved_path).status == "aborted"
    assert world.stepper.received[-2:] == ["ABORT", "EN 0"]


def test_a_run_that_fails_before_any_sample_saves_an_empty_loadable_recording(tmp_path):
    rig, world = make_rig(daq_options="&disconnect_at=0.01", silence_s=0.5)
    with pytest.raises(BoardDisconnected) as info:
        rig.run(PROG, path=tmp_path / "early", progress=False)
    rec = recordings.load(info.value.saved_path)
    assert rec.status == "aborted" and len(rec.frame) == 0


def test_a_save_that_fails_during_an_abort_is_reported_not_hidden(tmp_path, monkeypatch):
    from helpers.__main__ import error_line
    from helpers.recordings import RecordingError

    rig, world = make_rig(stepper_options="&reset_at=0.8")

    def full_disk(*args, **kwargs):
        raise RecordingError("data/x.csv: could not save (no space left on device)")

    monkeypatch.setattr(recordings, "save", full_disk)
    with pytest.raises(BoardReset) as info:
        rig.run(PROG, path=tmp_path / "lost", progress=False)
    assert info.value.saved_path is None and "no space left" in info.value.save_error
    line, status = error_line(info.value)
    assert status == 4 and "could NOT be saved" in line and "no space left" in line and "\n" not in line
