"""The emulated boards answer as PROTOCOL.md says, run programmes in device time, and are reachable by URL."""

from __future__ import annotations

import numpy as np
import pytest
import serial
from crc_reference import link_hex
from rig_fakes import (
    GAIN,
    K_N_PER_MM,
    MM_PER_STEP,  # the paper's cable per step, by hand
    OFFSET,
    PRETENSION_N,
    make_world,
)
from stream_run import PeriodCommands, simulate

from helpers import rigfile
from helpers.board import stream_reference as hs
from helpers.board.protocol import StreamParser, checksum, frame
from helpers.virtual.emulator.boards import Faults


def built_for(rig_file) -> dict:
    """``make_world``'s keyword for boards built for a shipped rig file (the rig as a value)."""
    return {"rig": rigfile.load(rig_file.path)}


def talk(board, *commands, checksum=True):
    """Send commands; return every line the board has queued since the last call (checksums verified)."""
    for c in commands:
        board.receive(frame(c) if checksum else (c + "\n").encode("latin-1"))
    p = StreamParser()
    _, msgs = p.feed(board.take_output())
    assert p.stats.corrupted == 0
    return msgs


def test_hello_on_reset_and_pong_with_the_documented_checksum(rig_file):  # rig-parametrised
    version = f"2.3.0+{rig_file.hash}"  # the firmware version and the rig file's hash
    w = make_world(**built_for(rig_file))
    assert w.daq.take_output() == frame(f"HELLO daq {version}")
    w.daq.receive(b"PING*79\n")
    pong = f"PONG daq {version}"
    assert w.daq.take_output() == f"{pong}*{link_hex(pong)}\n".encode()  # tests/crc_reference.py's CRC
    assert talk(w.stepper, "PING") == [f"HELLO stepper {version}", f"PONG stepper {version}"]


def test_daq_errors_and_limits():
    w = make_world()
    d = w.daq
    d.take_output()
    r = talk(d, "RATE 99", "RATE 2001", "RATE 500")
    assert r[0].startswith("ERR RANGE") and r[1].startswith("ERR RANGE") and r[2] == "OK RATE 500"
    assert talk(d, "RATE")[0].startswith("ERR ARG")
    assert talk(d, "RATE x")[0].startswith("ERR ARG")
    assert talk(d, "RATE  500")[0].startswith("ERR ARG")  # double space: an empty token
    assert talk(d, "FOO")[0].startswith("ERR UNKNOWN")
    assert talk(d, "RATE 200*00", checksum=False)[0].startswith("ERR CHECKSUM")
    assert d.rate == 500  # the command with the wrong checksum did nothing
    assert talk(d, f"RATE 200*{checksum('RATE 200').lower()}", checksum=False) == [
        "OK RATE 200"
    ]  # lower-case hex accepted, as the firmware
    assert talk(d, "X" * 64, checksum=False)[0].startswith("ERR TOOLONG")
    assert talk(d, "X" * 60)[0].startswith("ERR UNKNOWN")  # 63 characters with "*hh" still fit
    assert talk(d, "RATE 300", checksum=False)[0].startswith("ERR NOCRC")  # a command needs its *hh ...
    assert d.rate == 200  # ... and one without it did nothing
    assert talk(d, "", checksum=False) == []  # a blank line gets no reply
    assert talk(d, "START") == ["OK START 200"]
    assert talk(d, "RATE 300")[0].startswith("ERR STATE")
    assert talk(d, "START")[0].startswith("ERR STATE")
    assert talk(d, "PING") == ["PONG daq 2.3.0+481e87e3"]  # allowed while streaming


def test_daq_streams_at_its_rate_and_stop_reports_the_count():
    w = make_world()
    talk(w.daq, "RATE 500", "START")
    w.advance_to(w.t + 0.1)
    p = StreamParser()
    rows, _ = p.feed(w.daq.take_output())
    assert [r[0] for r in rows] == list(range(50))
    assert np.all(np.diff([r[1] for r in rows]) == 2000)
    assert set(r[2] for r in rows) == {round(OFFSET + GAIN * PRETENSION_N)}
    assert talk(w.daq, "STOP") == ["OK STOP 50"]
    assert talk(w.daq, "STOP") == ["OK STOP 0"]


def test_overruns_are_reported_never_skipped_silently():
    w = make_world(daq_faults=Faults(overrun_every=10))
    talk(w.daq, "START")
    w.advance_to(w.t + 0.1055)
    p = StreamParser()
    rows, _ = p.feed(w.daq.take_output())
    assert p.stats.dropped == 0  # seq has no gaps ...
    assert (
        p.stats.overruns == w.daq.injected["overrun_periods"] == 10
    )  # ... and each missed period is reported
    assert len(rows) + p.stats.overruns == 105


def test_stepper_limits(rig_file):  # rig-parametrised: the limits from the rig file's keys
    r = rig_file
    fastest, slowest, travel = r.min_interval_us, r.hw("max_interval_us"), r.travel_steps
    s = make_world(**built_for(r)).stepper
    s.take_output()
    assert talk(s, f"SEG 1 10 {fastest - 1}")[0].startswith("ERR RANGE")  # faster than the speed limit
    assert talk(s, f"SEG 1 10 {slowest + 1}")[0].startswith("ERR RANGE")
    assert talk(s, "SEG 2 10 1000")[0].startswith("ERR RANGE")
    assert talk(s, "SEG 1 0 1000")[0].startswith("ERR RANGE")
    assert talk(s, f"WAIT {r.hw('max_dwell_ms') + 1}")[0].startswith("ERR RANGE")
    assert talk(s, "WAIT -1")[0].startswith("ERR RANGE")
    assert talk(s, "SEG 1 10")[0].startswith("ERR ARG")
    assert talk(s, f"SEG 1 10 {fastest}") == ["OK SEG 1"]
    assert talk(s, "GO")[0].startswith("ERR STATE")  # driver disabled
    assert talk(s, "EN 2")[0].startswith("ERR RANGE")
    assert talk(s, "EN 1", "SEG -1 11 1000", "GO")[-1].startswith("ERR RANGE")  # would leave 0..travel
    talk(s, "CLEAR")
    for i in range(r.hw("programme_max_items")):
        assert talk(s, "WAIT 1") == [f"OK WAIT {i + 1}"]
    assert talk(s, "WAIT 1")[0].startswith("ERR FULL")
    assert talk(s, "CLEAR", f"SEG 1 {travel + 1} 1000")[-1].startswith("ERR RANGE")
    assert talk(s, "SEG 1 100 1000", f"SEG 1 {travel - 99} 1000", "GO")[-1].startswith("ERR RANGE")
    assert talk(s, "CLEAR", "SEG 1 100 1000", f"SEG 1 {travel - 100} {fastest}", "GO")[-1].startswith("OK GO")


def test_config_replies_are_the_rigs_limits(rig_file):  # rig-parametrised
    r = rig_file
    w = make_world(**built_for(r))
    w.stepper.take_output(), w.daq.take_output()
    limits = (r.hw("programme_max_items"), r.min_interval_us, r.hw("max_interval_us"), r.travel_steps)
    assert talk(w.stepper, "CONFIG") == ["OK CONFIG 1 {} {} {} {}".format(*limits)]  # one axis
    assert talk(w.daq, "CONFIG") == [f"OK CONFIG 1 1 {r.hw('daq_rate_min_hz')} {r.hw('daq_rate_max_hz')}"]
    assert talk(w.daq, f"RATE {r.hw('daq_rate_max_hz') + 1}")[0].startswith("ERR RANGE")
    assert talk(w.daq, f"RATE {r.hw('daq_rate_min_hz')}") == [f"OK RATE {r.hw('daq_rate_min_hz')}"]


def test_programme_runs_in_device_time_and_the_daq_counts_its_steps():
    w = make_world()
    w.daq.take_output(), w.stepper.take_output()
    talk(w.daq, "RATE 2000", "ZERO", "START")
    r = talk(w.stepper, "CLEAR", "WAIT 10", "SEG 1 20 1000", "WAIT 5", "SEG -1 8 2000", "EN 1", "GO")
    assert r[-1] == "OK GO 4"
    go = w.t
    w.advance_to(go + 0.0509)  # the programme lasts 10 + 20 + 5 + 16 = 51 ms
    assert talk(w.stepper) == []
    w.advance_to(go + 0.2)
    assert talk(w.stepper) == ["DONE 12"]
    rows, _ = StreamParser().feed(w.daq.take_output())
    t = np.array([r[1] for r in rows]) / 1e6 - go
    steps = np.array([r[3] for r in rows])
    # protocol timing: step k of a segment at t0 + k*interval
    step_times = np.concatenate([0.010 + 0.001 * np.arange(1, 21), 0.035 + 0.002 * np.arange(1, 9)])
    signs = np.concatenate([np.ones(20), -np.ones(8)])
    expected = np.array([signs[step_times <= ti + 1e-9].sum() for ti in t])
    np.testing.assert_array_equal(steps, expected)
    adc = np.array([r[2] for r in rows])
    np.testing.assert_array_equal(
        adc, np.rint(OFFSET + GAIN * (PRETENSION_N + K_N_PER_MM * MM_PER_STEP * expected))
    )


def test_done_arrives_at_the_programme_end_and_abort_disables():
    w = make_world()
    w.stepper.take_output()
    talk(w.stepper, "CLEAR", "SEG 1 10 1000", "WAIT 20", "EN 1", "GO")
    go = w.t
    w.advance_to(go + 0.0299)
    assert talk(w.stepper) == []
    w.advance_to(go + 0.0301)
    assert talk(w.stepper) == ["DONE 10"]
    assert talk(w.stepper, "POS") == ["OK POS 10"]
    talk(w.stepper, "CLEAR", "SEG -1 10 1000", "GO")
    w.advance_to(w.t + 0.0045)
    assert talk(w.stepper, "ABORT")[-1] == "ABORTED 6"  # 4 steps of -1 from 10
    assert not w.stepper.enabled and not w.stepper.running
    assert talk(w.stepper, "GO")[0].startswith("ERR STATE")


def test_reset_sends_hello_and_forgets_state():
    w = make_world(stepper_faults=Faults(reset_at=0.01))
    w.stepper.take_output()
    talk(w.stepper, "CLEAR", "SEG 1 50 1000", "EN 1", "GO")
    w.advance_to(w.t + 0.02)
    msgs = talk(w.stepper)
    assert msgs[-1] == "HELLO stepper 2.3.0+481e87e3"
    assert not w.stepper.enabled and not w.stepper.running and w.stepper.position == 0


def _open(url, timeout=None):
    """The URL opened with pyserial, as the host driver opens it (the emulator's package registered)."""
    if "helpers.virtual.emulator" not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append("helpers.virtual.emulator")
    return serial.serial_for_url(url, baudrate=115200, timeout=timeout, write_timeout=1.0, exclusive=True)


def test_url_handler_same_rig_name_same_world():
    w = make_world()
    d = _open(f"virtual://daq?rig={w.name}", timeout=0.01)
    s = _open(f"virtual://stepper?rig={w.name}", timeout=0.01)
    assert d.world is s.world is w
    assert d.read(100).startswith(b"HELLO daq")
    s.write(frame("PING"))
    # reset on open, reply
    assert s.read(100) == frame("HELLO stepper 2.3.0+481e87e3") + frame("PONG stepper 2.3.0+481e87e3")
    t0 = w.t
    assert s.read(10) == b""  # nothing to come: the read waited its timeout in device time
    assert w.t == pytest.approx(t0 + 0.01)
    with pytest.raises(serial.SerialException, match="unknown option"):
        _open(f"virtual://daq?rig={w.name}&bogus=1")
    with pytest.raises(serial.SerialException):
        _open("virtual://mega?rig=x")


def test_calibration_fixture_is_read_instead_of_the_cable():
    w = make_world()
    w.daq.take_output()
    w.hang_load(4.0)
    talk(w.daq, "START")
    w.advance_to(w.t + 0.01)
    rows, _ = StreamParser().feed(w.daq.take_output())
    assert {r[2] for r in rows} == {round(OFFSET + GAIN * 4.0)}
    with pytest.raises(ValueError):
        w.hang_load(float("nan"))


# --- the stepper's streaming mode (helpers.board.stream_reference is the oracle)
# --------------------------------------
def _stream_world():
    w = make_world()
    w.daq.take_output(), w.stepper.take_output()
    talk(w.daq, "RATE 2000", "ZERO", "START")
    return w


def test_a_stream_steps_where_the_reference_says():
    w = _stream_world()
    shaper = hs.StreamShaper.quantise([0.25, 0.5, 0.25], [0.0, 0.02, 0.04])
    assert talk(w.stepper, *shaper.commands()) == ["OK SHAPER 3", "OK IMP 0", "OK IMP 1", "OK IMP 2"]
    assert talk(w.stepper, "EN 1", "STREAM") == ["OK EN 1", "OK STREAM 0"]
    t0 = w.t
    setpoints = [400, 800, 800, -300, 0, 1200]
    periods = []
    for i, v in enumerate(setpoints):
        w.advance_to(t0 + 0.004 + 0.01 * i)  # one set-point per period, 4 ms after each tick
        (reply,) = talk(w.stepper, f"V {v}")
        periods.append(int(reply.split()[2]))
    assert periods == [1, 2, 3, 4, 5, 6]
    assert talk(w.stepper, "END") == ["OK END 7"]
    w.advance_to(t0 + 0.3)
    ref = simulate(shaper, PeriodCommands(dict(zip(periods, setpoints, strict=True)), 7))
    assert talk(w.stepper) == [f"DONE {ref.position}"] and w.stepper.enabled  # END keeps the driver on
    rows, _ = StreamParser().feed(w.daq.take_output())
    t = np.array([r[1] for r in rows]) / 1e6
    steps = np.array([r[3] for r in rows])
    edges = t0 + ref.ticks * 0.5e-6 + 16e-6  # the firmware's STEP edge is 16 us after its tick
    expected = np.array([ref.directions[edges <= ti + 1e-9].sum() for ti in t])
    np.testing.assert_array_equal(steps, expected)
    assert steps.max() > 0 and w.stepper.position == ref.position


def test_the_stream_watchdog_and_clamps_as_notices():
    w = _stream_world()
    talk(w.stepper, *hs.UNIT_SHAPER.commands(), "EN 1", "STREAM")
    t0 = w.t
    for i in range(5):
        w.advance_to(t0 + 0.004 + 0.01 * i)
        talk(w.stepper, f"V {hs.V_MAX}")
    w.advance_to(t0 + 0.5)  # the host falls silent: the periods without a set-point move nothing
    # 5 periods at 1640 units: 5 x 1640 x 625 / 2^16 = 78.2 steps; silent periods 6-15, the watchdog at 16
    assert talk(w.stepper) == ["N,WATCHDOG,16", "DONE 78"] and not w.stepper.enabled
    assert talk(w.stepper, "V 0")[0].startswith("ERR STATE")
    talk(w.stepper, "EN 1", "STREAM")
    t0 = w.t
    heard = []
    for i in range(11):  # 11 periods at full speed would be 172 steps: clamped at 156
        w.advance_to(t0 + 0.004 + 0.01 * i)
        heard += [m for m in talk(w.stepper, f"V {hs.V_MAX}") if not m.startswith("OK V")]
    w.advance_to(t0 + 0.5)
    heard += talk(w.stepper)
    ref = simulate(hs.UNIT_SHAPER, PeriodCommands(dict.fromkeys(range(1, 12), hs.V_MAX)), position=78)
    expected = [f"N,{n.kind},{n.value}" for n in ref.notices] + [f"DONE {ref.position}"]
    assert heard == expected == ["N,LIMIT,TRAVEL,156", "N,WATCHDOG,22", "DONE 156"]


def test_stream_commands_refused_as_the_firmware_refuses_them():
    w = _stream_world()
    s = w.stepper
    assert talk(s, "STREAM") == ["ERR STATE no shaper"]
    assert talk(s, "SHAPER 2 0", "IMP 0 2048 0", "IMP 1 2047 160")[-1].startswith("ERR RANGE")  # sum 4095
    assert talk(s, "IMP 0 4096 0")[0].startswith("ERR STATE")  # the shaper was discarded
    assert talk(s, "SHAPER 1 0", "IMP 0 4096 0", "STREAM")[-1] == "ERR STATE driver disabled"
    assert talk(s, "EN 1", "STREAM", "GO", "SHAPER 1 0", "V 1641") == [
        "OK EN 1", "OK STREAM 0", "ERR STATE streaming", "ERR STATE streaming",
        "ERR RANGE set-point -1640..1640",
    ]  # fmt: skip
    assert talk(s, *["V 0"] * 9)[-1] == "ERR FULL 8 set-points queued"
    assert talk(s, "MEM") == ["OK MEM 560"] and talk(s, "ABORT") == ["ABORTED 0"]
    assert talk(s, "V 0") == ["ERR STATE not streaming"] and not s.enabled


def test_mseg_spreads_its_steps_over_the_window_on_the_firmware_ticks():
    w = make_world()
    s = w.stepper
    s.take_output()
    assert talk(s, "CONFIG")[0].startswith("OK CONFIG 1 ")  # the rig's limits: test_config_replies_...
    assert talk(s, "MSEG 7001 3", "MSEG 2000 -1", "EN 1", "GO")[-1] == "OK GO 2"
    go = w.go_times[-1]
    times, axes, signs = s.steps_until(go + 1.0)
    # PROTOCOL.md: step k of n on the first 0.5 us tick at or after k * W / n from the window's start
    # (7001 us / 3 = 2333.67 us -> 2334.0; 4667.33 -> 4667.5; the window's end; then 7001 + 2000)
    np.testing.assert_allclose((times - go) * 1e6, [2334.0, 4667.5, 7001.0, 9001.0], atol=1e-3)
    assert list(signs) == [1, 1, 1, -1] and list(axes) == [0] * 4


def test_a_one_axis_stream_clamps_at_the_travel_of_its_build(rig_file):  # rig-parametrised
    """PROTOCOL.md: a stream holds each axis within its build's travel (the paper's 156 steps, the long arm's
    254): 20 periods at the top speed, 1640 x 625 / 2^16 = 15.64 steps each, would be 312.8 steps."""
    w = make_world(**built_for(rig_file))
    w.stepper.take_output()
    talk(w.stepper, *hs.UNIT_SHAPER.commands(), "EN 1", "STREAM")
    t0, heard = w.t, []
    for i in range(20):
        w.advance_to(t0 + 0.004 + 0.01 * i)
        heard += [m for m in talk(w.stepper, f"V {hs.V_MAX}") if not m.startswith("OK V")]
    assert talk(w.stepper, "END") == ["OK END 21"]
    w.advance_to(t0 + 0.6)
    heard += talk(w.stepper)
    travel = rig_file.travel_steps
    assert heard == [f"N,LIMIT,TRAVEL,{travel}", f"DONE {travel}"] and w.stepper.position == travel
