"""Every out-of-range request is refused with a clear error before a single byte reaches either board."""

from __future__ import annotations

import math
import warnings

import pytest
from rig_fakes import SpyPort, make_rig

from helpers.board.programmes import Dwell, Programme, Segment
from helpers.rig import SafetyError, check_request


@pytest.fixture()
def spied():
    rig, world = make_rig()
    rig.daq.port = SpyPort(rig.daq.port)
    rig.stepper.port = SpyPort(rig.stepper.port)
    n_daq, n_stepper = len(world.daq.received), len(world.stepper.received)
    yield rig
    assert bytes(rig.daq.port.written) == b""
    assert bytes(rig.stepper.port.written) == b""
    assert len(world.daq.received) == n_daq and len(world.stepper.received) == n_stepper


BAD_PULSES = [
    (401.0, 10.0, "exceeds the limit of 400 mm/s"),  # speed
    (200.0, 40.5, "travel limit of 40 mm"),  # travel
    (math.nan, 10.0, "finite"),
    (200.0, math.inf, "finite"),
    (-100.0, 10.0, "> 0"),
    (200.0, -5.0, "> 0"),
    (0.0, 10.0, "> 0"),
    (200.0, 0.05, "half a step"),
    ("fast", 10.0, "number"),
]


@pytest.mark.parametrize("v, x, message", BAD_PULSES)
def test_bad_pulse_requests_are_refused_before_sending(spied, v, x, message, tmp_path):
    with pytest.raises(SafetyError, match=message):
        spied.run_pulse(v, x, path=tmp_path / "never", progress=False)
    assert not (tmp_path / "never.csv").exists()


def test_check_request_accepts_the_paper_conditions():
    for v, x in [(100, 10), (200, 10), (200, 20), (200, 30), (300, 20)]:
        assert check_request(v, x) == (float(v), float(x))


BAD_PROGRAMMES = [
    (Programme((Segment(1, 157, 1000),)), "travel limit"),  # beyond 40 mm
    (Programme((Segment(-1, 1, 1000),)), "travel limit"),  # below zero
    (Programme((Segment(1, 10, 638),)), "interval limit"),  # 400.0 mm/s: above the speed limit
    (Programme((Segment(1, 10, 499),)), "interval limit"),  # > 2000 steps/s
    (Programme((Segment(1, 10, 1_000_001),)), "interval limit"),
    (Programme(tuple(Dwell(1) for _ in range(65))), "programme length"),  # too many items
    (Programme(()), "programme length"),  # empty
    (Programme((Dwell(60_001),)), "dwell limit"),
    (Programme(tuple(Dwell(60_000) for _ in range(11))), "host's limit"),  # 11 minutes
]


@pytest.mark.parametrize("programme, message", BAD_PROGRAMMES)
def test_bad_programmes_are_refused_before_sending(spied, programme, message, tmp_path):
    with pytest.raises(SafetyError, match=message):
        spied.run(programme, path=tmp_path / "never", progress=False)


@pytest.mark.parametrize("rate", [99, 2001, 1000.0, True])
def test_bad_sample_rates_are_refused_before_sending(spied, rate, tmp_path):
    with pytest.raises(SafetyError, match="rate"):
        spied.run(Programme((Dwell(10),)), rate_hz=rate, path=tmp_path / "never", progress=False)


def test_not_a_programme(spied):
    with pytest.raises(SafetyError, match="Programme"):
        spied.run([("SEG", 1, 10, 1000)], progress=False)


def test_negative_or_nan_items_cannot_even_be_built():
    for build in (lambda: Segment(1, -3, 1000), lambda: Dwell(-1), lambda: Segment(1, 10, math.nan)):
        with pytest.raises(ValueError):
            build()


def test_hardware_with_a_virtual_rig_calibration_warns():
    from helpers.rig import Rig

    virtual_cal = {
        "newtons_per_count": 0.02,
        "offset_counts": 50.0,
        "mm_per_step": 0.25525,
        "origin": "data/calibration/calibration.json",
        "source": "virtual-rig",
    }
    with pytest.warns(UserWarning, match="recorded on the virtual rig"):
        Rig(None, None, calibration=virtual_cal, source={"kind": "hardware"})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Rig(None, None, calibration=virtual_cal, source={"kind": "virtual-rig"})
        Rig(None, None, calibration=dict(virtual_cal, source="hardware"), source={"kind": "hardware"})
