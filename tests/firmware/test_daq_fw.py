"""DAQ firmware (Mega 2560) in simavr: sample timing, ADC values, step counting, overrun accounting."""

from __future__ import annotations

import bisect

import fwsim
import numpy as np
import pytest

pytestmark = pytest.mark.firmware

F = fwsim.F_CPU
T_START, T_STOP, T_END = 0.05, 10.10, 10.20


def triangle_mv(t: np.ndarray | float) -> np.ndarray:
    """0 -> 5000 mV -> 0 over 4 s: every ADC code is visited, at 0.5 counts per ms."""
    phase = np.mod(np.asarray(t, dtype=float), 4.0)
    return np.where(phase < 2.0, 2500.0 * phase, 2500.0 * (4.0 - phase))


def step_edges() -> tuple[list[tuple[float, str, int]], list[tuple[float, int]]]:
    """STEP (E4 = D2) pulses of 5 us with DIR (G5 = D4), as the Uno sends them; edges and (t, sign)."""
    bursts = [  # (start s, n pulses, rate Hz, direction)
        (1.0, 300, 1000.0, +1),
        (2.0, 156, 1567.0, +1),  # the stepper board's top rate
        (3.0, 456, 800.0, -1),
        (4.5, 50, 2000.0, +1),
        (5.0, 73, 333.0, -1),
        (7.0, 1, 1.0, +1),
    ]
    edges: list[tuple[float, str, int]] = [(0.001, "E4", 0), (0.001, "G5", 0)]
    pulses: list[tuple[float, int]] = []
    for start, n, rate, sign in bursts:
        edges.append((start - 50e-6, "G5", 1 if sign > 0 else 0))  # DIR set up 50 us before the first pulse
        for k in range(n):
            t = start + k / rate
            edges += [(t, "E4", 1), (t + 5e-6, "E4", 0)]
            pulses.append((t, sign))
    edges.sort(key=lambda e: e[0])
    return edges, pulses


@pytest.fixture(scope="module")
def stream_1khz(firmware_build):
    wave_t = np.arange(0.0, T_END + 0.01, 0.01)
    edges, pulses = step_edges()
    run = fwsim.run(
        "daq",
        [
            (0.02, fwsim.command("PING")),
            (T_START, fwsim.command("START")),
            (T_STOP, fwsim.command("STOP")),
        ],
        T_END,
        wave=list(zip(wave_t, triangle_mv(wave_t), strict=True)),
        edges=edges,
    )
    return run, pulses


def test_ten_seconds_at_1khz_without_overrun_or_gap(stream_1khz):
    run, _ = stream_1khz
    data = run.data()
    seq = np.array([d[0] for d in data])
    assert run.overruns() == []
    np.testing.assert_array_equal(seq, np.arange(len(seq)))
    stop = [ln.body for ln in run.lines if ln.body.startswith("OK STOP")]
    assert stop == [f"OK STOP {len(seq)}"]
    # one sample per 1 ms period between START and STOP (give or take the period in progress at either end)
    assert abs(len(seq) - (T_STOP - T_START) * 1000) <= 2
    print(f"\n1 kHz for {T_STOP - T_START:.2f} s: {len(seq)} samples, 0 overruns")


def test_sample_instants_are_timer_exact(stream_1khz):
    run, _ = stream_1khz
    cycles = np.array([c for c, _ in run.adc])
    t_us = np.array([d[1] for d in run.data()])
    assert len(cycles) == len(t_us), "one conversion per data line"
    d_cycles = np.diff(cycles)
    assert np.all(np.abs(d_cycles - F // 1000) <= 8), "conversions start every 16000 cycles (+-0.5 us)"
    d_us = np.diff(t_us)
    assert np.all(np.abs(d_us - 1000) <= 4), "t_us advances by 1000 us (micros() has 4 us resolution)"
    lag = cycles / 16.0 - t_us
    assert np.ptp(lag) <= 12, "micros() keeps a constant offset from the simulated clock"


def test_adc_values_match_the_waveform_within_one_count(stream_1khz):
    run, _ = stream_1khz
    data = run.data()
    cycles = np.array([c for c, _ in run.adc])
    t_us = np.array([d[1] for d in data], dtype=float)
    adc = np.array([d[2] for d in data])
    # the injected waveform at the firmware's own timestamp (its micros() offset from the simulated clock
    # estimated from the conversion log)
    offset_us = np.median(cycles / 16.0 - t_us)
    expected = np.floor(triangle_mv((t_us + offset_us) * 1e-6) * 1023.0 / fwsim.VREF_MV)
    err = adc - expected
    assert np.max(np.abs(err)) <= 1, f"worst error {np.max(np.abs(err)):.0f} counts"
    assert np.mean(err == 0) > 0.9, "nearly all samples are exact"
    # and exactly what the simulated converter produced for the millivolts it was given
    mv = np.array([m for _, m in run.adc])
    np.testing.assert_array_equal(adc, (mv * 1023) // fwsim.VREF_MV)
    assert adc.min() == 0 and adc.max() >= 1022, "the full scale was exercised"


def test_step_pulses_counted_exactly_with_direction(stream_1khz):
    run, pulses = stream_1khz
    data = run.data()
    cycles = np.array([c for c, _ in run.adc])
    steps = np.array([d[3] for d in data])
    times = [t for t, _ in pulses]
    csum = np.concatenate([[0], np.cumsum([s for _, s in pulses])])
    guard = 20e-6  # a pulse this close to a sample instant may fall on either side of it
    bad = []
    for k, c in enumerate(cycles):
        t = c / F
        lo = csum[bisect.bisect_left(times, t - guard)]
        hi = csum[bisect.bisect_left(times, t + guard)]
        if not min(lo, hi) <= steps[k] <= max(lo, hi):
            bad.append((k, t, steps[k], lo, hi))
    assert not bad, f"step counts off at {len(bad)} samples, first {bad[:3]}"
    assert steps[-1] == csum[-1] == 300 + 156 - 456 + 50 - 73 + 1
    assert steps.max() == 456 and steps.min() == -23


@pytest.fixture(scope="module")
def stream_2khz(firmware_build):
    run = fwsim.run(
        "daq",
        [
            (0.02, fwsim.command("RATE 2000")),
            (T_START, fwsim.command("START")),
            (3.05, fwsim.command("STOP")),
        ],
        3.2,
        wave=[(0.0, 1000.0), (4.0, 1000.0)],
    )
    return run


def test_every_sample_period_accounted_for_at_2khz(stream_2khz):
    """At the top rate the link may not keep up; then the board must say so: data + overruns = periods."""
    run = stream_2khz
    data = run.data()
    seq = np.array([d[0] for d in data])
    np.testing.assert_array_equal(seq, np.arange(len(seq)))  # no gap in seq, overrun or not
    start = next(ln for ln in run.lines if ln.body.startswith("OK START"))
    stop = next(ln for ln in run.lines if ln.body.startswith("OK STOP"))
    assert stop.body == f"OK STOP {len(seq)}"
    assert start.body == "OK START 2000"
    # The sampler runs from START's processing to STOP's processing; bound the number of periods by
    # the command arrival times (each command takes < 0.5 ms to arrive and be handled).
    periods_lo = (3.05 - (T_START + 0.0005)) * 2000 - 1
    periods_hi = (3.05 + 0.0005 - T_START) * 2000 + 1
    total = len(seq) + sum(run.overruns())
    assert periods_lo <= total <= periods_hi
    # every overrun warning comes before a data line or before the STOP reply, never at the end unreported
    bodies = run.bodies()
    for i, b in enumerate(bodies):
        if b.startswith("W,OVERRUN"):
            assert bodies[i + 1].startswith(("D,", "OK STOP"))
    print(
        f"\n2 kHz for 3.00 s: {len(seq)} samples, {sum(run.overruns())} periods reported missed "
        f"({len(run.overruns())} warnings)"
    )
