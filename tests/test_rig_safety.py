"""Every out-of-range request is refused with a clear error before a single byte reaches either board."""

from __future__ import annotations

import math
import re
import warnings

import pytest
from rig_fakes import SpyPort, make_rig

from helpers import rigfile
from helpers.board.programmes import Dwell, Programme, Segment
from helpers.rig import SafetyError, check_request


@pytest.fixture()
def spied(request):
    """A rig on the test doubles whose ports record every byte written; the test's ``shipped_rig`` if any."""
    shipped = request.getfixturevalue("shipped_rig") if "shipped_rig" in request.fixturenames else None
    rig, world = make_rig(rig=None if shipped is None else shipped.load())
    rig.daq.port = SpyPort(rig.daq.port)
    rig.stepper.port = SpyPort(rig.stepper.port)
    n_daq, n_stepper = len(world.daq.received), len(world.stepper.received)
    yield rig
    assert bytes(rig.daq.port.written) == b""
    assert bytes(rig.stepper.port.written) == b""
    assert len(world.daq.received) == n_daq and len(world.stepper.received) == n_stepper


def _speed(r):
    return r.hw("speed_limit_mm_s")


BAD_PULSES = {  # (v, x) and the message, each from the rig's own keys
    "speed": (lambda r: (_speed(r) + 1.0, 5.0), lambda r: f"exceeds the limit of {_speed(r):.0f} mm/s"),
    "travel": (
        lambda r: (50.0, r.hw("travel_mm") + 0.5),
        lambda r: f"travel limit of {r.hw('travel_mm'):.0f} mm",
    ),
    "travel in steps": (
        lambda r: (50.0, (r.travel_steps + 0.6) * r.mm_per_step),
        lambda r: f"beyond the travel of {r.travel_steps} steps",
    ),
    "nan speed": (lambda r: (math.nan, 5.0), lambda r: "finite"),
    "infinite distance": (lambda r: (100.0, math.inf), lambda r: "finite"),
    "negative speed": (lambda r: (-100.0, 5.0), lambda r: "> 0"),
    "negative distance": (lambda r: (100.0, -5.0), lambda r: "> 0"),
    "zero speed": (lambda r: (0.0, 5.0), lambda r: "> 0"),
    "half a step": (lambda r: (100.0, 0.4 * r.mm_per_step), lambda r: "half a step"),
    "not a number": (lambda r: ("fast", 5.0), lambda r: "number"),
}


@pytest.mark.parametrize("case", list(BAD_PULSES))
# rig-parametrised (tests/conftest.py)
def test_bad_pulse_requests_are_refused_before_sending(spied, shipped_rig, case, tmp_path):
    request, message = BAD_PULSES[case]
    v, x = request(shipped_rig)
    with pytest.raises(SafetyError, match=re.escape(message(shipped_rig))):
        spied.run_pulse(v, x, path=tmp_path / "never", progress=False)
    assert not (tmp_path / "never.csv").exists()


def test_check_request_accepts_the_rigs_scenarios(shipped_rig):  # rig-parametrised
    r = shipped_rig
    paper_sets = [(100, 10), (200, 10), (200, 20), (200, 30), (300, 20)]
    for v, x in r.scaled(paper_sets) + [(r.fastest_mm_s, r.longest_mm)]:
        assert check_request(v, x, rigfile.load(r.path)) == (float(v), float(x))


def _longer_than_the_host_allows(r):
    n = math.floor(r.hw("max_programme_s") * 1e3 / r.hw("max_dwell_ms")) + 1
    return tuple(Dwell(r.hw("max_dwell_ms")) for _ in range(n))


BAD_PROGRAMMES = {  # the items and the limit named, each from the rig's own keys
    "beyond the travel": (lambda r: (Segment(1, r.travel_steps + 1, 1000),), "travel limit"),
    "below zero": (lambda r: (Segment(-1, 1, 1000),), "travel limit"),
    "above the speed limit": (lambda r: (Segment(1, 10, r.min_interval_us - 1),), "interval limit"),
    "above the step-rate cap": (
        lambda r: (Segment(1, 10, math.ceil(1e6 / r.hw("step_rate_cap_hz")) - 1),),
        "interval limit",
    ),
    "too slow": (lambda r: (Segment(1, 10, r.hw("max_interval_us") + 1),), "interval limit"),
    "too many items": (
        lambda r: tuple(Dwell(1) for _ in range(r.hw("programme_max_items") + 1)),
        "programme length",
    ),
    "empty": (lambda r: (), "programme length"),
    "long dwell": (lambda r: (Dwell(r.hw("max_dwell_ms") + 1),), "dwell limit"),
    "longer than the host allows": (_longer_than_the_host_allows, "host's limit"),
}


@pytest.mark.parametrize("case", list(BAD_PROGRAMMES))
def test_bad_programmes_are_refused_before_sending(spied, shipped_rig, case, tmp_path):  # rig-parametrised
    items, message = BAD_PROGRAMMES[case]
    with pytest.raises(SafetyError, match=message):
        spied.run(Programme(items(shipped_rig)), path=tmp_path / "never", progress=False)


def test_bad_sample_rates_are_refused_before_sending(spied, shipped_rig, tmp_path):  # rig-parametrised
    low, high = shipped_rig.hw("daq_rate_min_hz"), shipped_rig.hw("daq_rate_max_hz")
    for rate in (low - 1, high + 1, float(low), True):
        with pytest.raises(SafetyError, match="rate"):
            spied.run(Programme((Dwell(10),)), rate_hz=rate, path=tmp_path / "never", progress=False)


def test_not_a_programme(spied, tmp_path):
    with pytest.raises(SafetyError, match="Programme"):
        spied.run([("SEG", 1, 10, 1000)], path=tmp_path / "never", progress=False)
    assert not tmp_path.joinpath("never.csv").exists()


def test_negative_or_nan_items_cannot_even_be_built():
    for build in (lambda: Segment(1, -3, 1000), lambda: Dwell(-1), lambda: Segment(1, 10, math.nan)):
        with pytest.raises(ValueError):
            build()


def test_hardware_with_a_virtual_rig_calibration_warns(monkeypatch):
    from helpers.rig import Rig, driver

    virtual_cal = {
        "newtons_per_count": 0.02,
        "offset_counts": 50.0,
        "mm_per_step": 0.25525,
        "origin": "data/calibration/calibration.json",
        "source": "virtual-rig",
    }
    first, world = make_rig()
    first.close()
    connect = dict(world=world.name, timeout=0.5, hello_timeout=1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the virtual rig with a virtual calibration: as it should be
        Rig("virtual", rigfile.default_rig(), virtual_cal, **connect).close()
    monkeypatch.setattr(driver, "virtual_source_for", lambda urls: None)  # these ports: as hardware
    monkeypatch.setattr(Rig, "world", property(lambda self: None))
    with pytest.warns(UserWarning, match="recorded on the virtual rig"):
        Rig("virtual", rigfile.default_rig(), virtual_cal, **connect).close()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Rig("virtual", rigfile.default_rig(), dict(virtual_cal, source="hardware"), **connect).close()
