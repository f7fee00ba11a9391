"""A finished run is never thrown away, whatever signal arrives when; a name in use is refused before a run.

Signals are sent to this process at chosen instants (by patching the step at which one arrives) and at
random instants (from a thread); in every case the run's recording is on disk: complete if every sample was
in, else aborted with what was recorded. A second run asking for a name that a running one holds is refused
before it starts.
"""

from __future__ import annotations

import os
import random
import signal
import threading
import time

import pytest
from rig_fakes import make_rig

from helpers import recordings
from helpers.base import signals
from helpers.base.signals import Interrupted, interrupts_from_signals
from helpers.board.programmes import Dwell, Programme, Segment
from helpers.recordings import RecordingExists
from helpers.rig import driver

PROGRAMME = Programme((Dwell(50), Segment(1, 10, 2000), Dwell(50), Segment(-1, 10, 2000), Dwell(50)))


def _signal_self(signum=signal.SIGTERM):
    os.kill(os.getpid(), signum)


def _only_pair(folder):
    csvs = sorted(folder.glob("*.csv"))
    assert len(csvs) == 1 and csvs[0].with_suffix(".json").exists(), sorted(p.name for p in folder.iterdir())
    return recordings.load(csvs[0])


@pytest.mark.parametrize(
    "where",
    ["the final EN 0", "building the recording", "the save", "after the save"],
)
def test_a_signal_after_the_last_sample_still_saves_the_whole_run(tmp_path, monkeypatch, where):
    rig, world = make_rig()
    full = rig.run(PROGRAMME, path=tmp_path / "ref" / "r", progress=False)  # the same run, undisturbed
    rig.stepper.command("EN 0")
    fired = []

    def once(fn):
        def wrapped(*a, **k):
            if not fired:
                fired.append(where)
                _signal_self()
            return fn(*a, **k)

        return wrapped

    if where == "the final EN 0":  # the body's last command, after its last sample
        real_command = rig.stepper.command

        def command(body, *a, **k):
            if body == "EN 0" and not fired:
                fired.append(where)
                _signal_self()
            return real_command(body, *a, **k)

        monkeypatch.setattr(rig.stepper, "command", command)
    elif where == "building the recording":
        monkeypatch.setattr(rig, "recording", once(rig.recording))
    elif where == "the save":
        monkeypatch.setattr(driver.recordings, "save", once(recordings.save))
    with interrupts_from_signals(), pytest.raises(Interrupted) as info:
        rig.run(PROGRAMME, path=tmp_path / "g" / "p", progress=False)
        if where == "after the save":
            _signal_self()
            time.sleep(0)  # the handler runs here, inside the raises block
    if where != "after the save":
        assert info.value.complete and info.value.saved_path == tmp_path / "g" / "p.csv"
    rec = _only_pair(tmp_path / "g")
    assert rec.status == "complete" and rec.path.name == "p.csv"
    assert len(rec.frame) == len(full.frame) and rec.frame["steps"].max() == 10
    assert not world.stepper.enabled


def test_signals_at_random_instants_never_lose_a_finished_run(tmp_path):
    """A SIGTERM at a random instant of 30 runs: each leaves one loadable recording (or none if it came
    before the run started), complete with every sample if the run had finished."""
    rig, world = make_rig()
    t0 = time.perf_counter()
    full = rig.run(PROGRAMME, path=tmp_path / "ref" / "r", progress=False)
    span = 1.5 * (time.perf_counter() - t0)  # about a run's wall time: instants before, in and after it
    rng = random.Random(20)
    outcomes = {"complete": 0, "aborted": 0, "before": 0}
    for i in range(30):
        folder = tmp_path / f"g{i}"
        delay = rng.uniform(0.0, span)
        sender = threading.Thread(target=lambda d=delay: (time.sleep(d), _signal_self()))
        saved = None
        with interrupts_from_signals():
            try:
                try:
                    sender.start()
                    rig.run(PROGRAMME, path=folder / "p", progress=False)
                finally:
                    sender.join()
                time.sleep(0)  # a signal sent after the run is handled here, inside the try
            except Interrupted as exc:
                saved = getattr(exc, "saved_path", None)
        if not list(folder.glob("*.csv")):  # the signal came before the run started: nothing to save
            assert saved is None
            outcomes["before"] += 1
            continue
        rec = _only_pair(folder)
        if rec.status == "complete":
            assert len(rec.frame) == len(full.frame)
        else:
            # loadable (checksum, gaps, time: _only_pair) and aborted; its length is no check: the boards
            # stream from START in device time, and on a busy host the wait before GO can outlast the whole
            # run (500 samples against 300 seen so)
            assert rec.status == "aborted" and rec.meta["abort_reason"]
        outcomes[rec.status] += 1
        rig.stepper.command("EN 0")
    assert sum(outcomes.values()) == 30


def test_a_second_run_to_the_same_name_is_refused_before_it_starts(tmp_path, monkeypatch):
    rig, world = make_rig()
    other, other_world = make_rig()
    inner = []

    def while_running(rows):
        if not inner:  # the first run is recording: a second asks for its name
            inner.append(None)
            with pytest.raises(RecordingExists, match=f"process {os.getpid()} is recording under this name"):
                other.run(PROGRAMME, path=tmp_path / "p", progress=False)
            inner.append("refused")
            assert set(other_world.stepper.received) == {"PING", "CONFIG"}  # nothing asked but its build

    world.listeners.append(lambda w: while_running(None) if w.t > 0.6 else None)
    rec = rig.run(PROGRAMME, path=tmp_path / "p", progress=False)
    assert inner == [None, "refused"] and rec.status == "complete"
    # once saved, the name is free of its reservation but taken by the recording
    assert not list(tmp_path.glob(".*reserved*"))
    with pytest.raises(RecordingExists, match="exists"):
        other.run(PROGRAMME, path=tmp_path / "p", progress=False)


def test_signals_held_defers_a_signal_sent_from_another_thread():
    got = []
    with interrupts_from_signals():
        try:
            with signals.signals_held():
                t = threading.Thread(target=_signal_self)
                t.start()
                t.join()
                time.sleep(0)
                got.append("not interrupted inside")
            time.sleep(0)
        except Interrupted as exc:
            got.append(exc.signum)
    assert got == ["not interrupted inside", signal.SIGTERM]


def test_nested_blocks_keep_the_handler_and_leave_the_handlers_as_they_found_them():
    """A block inside another finds the handler in place; the outermost one alone installs and restores it."""
    before = signal.getsignal(signal.SIGTERM)
    assert before is not signals._handler
    with interrupts_from_signals():
        with signals.signals_held():
            with interrupts_from_signals():
                assert signal.getsignal(signal.SIGTERM) is signals._handler
        assert signal.getsignal(signal.SIGTERM) is signals._handler
    assert signal.getsignal(signal.SIGTERM) == before
    with signals.signals_held():  # alone again: it installs the handler itself
        assert signal.getsignal(signal.SIGTERM) is signals._handler
    assert signal.getsignal(signal.SIGTERM) == before
