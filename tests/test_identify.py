"""helpers.paper.identify on synthetic free decays whose mode is known (the paper's zeta = 0.044, omega_d =
25.085).

The synthetic recording imitates the identification run: a 1 kHz, 12 s record; the release transient starts
at 8.05 s (after the 50 ms down move) and the 9-10 s window is analysed. The load cell is imitated by an ADC
reading ``offset + gain * tension`` with Gaussian noise, rounded to integer counts and clipped to 0-1023.
"""

import json
import math

import matplotlib
import numpy as np
import pytest

from helpers.paper import identify as ident
from helpers.paper.numbers import OMEGA_D, ZETA

matplotlib.use("Agg")

FS = 1000.0
T = np.arange(0.0, 12.0, 1.0 / FS)
WINDOW = (9.0, 10.0)
T_RELEASE = 8.05
OMEGA_N = OMEGA_D / math.sqrt(1.0 - ZETA**2)
SIGMA = ZETA * OMEGA_N


def decay(
    amplitude=120.0, noise=1.0, seed=0, offset=300.0, quantise=True, zeta=ZETA, omega_d=OMEGA_D, phase=0.7
):
    """ADC counts of a free decay (amplitude in counts at the release) plus noise, 10-bit quantised."""
    rng = np.random.default_rng(seed)
    sigma = zeta * omega_d / math.sqrt(1.0 - zeta**2)
    tau = np.clip(T - T_RELEASE, 0.0, None)
    y = offset + amplitude * np.exp(-sigma * tau) * np.sin(omega_d * tau + phase)
    y = y + rng.normal(0.0, noise, T.size)
    return np.clip(np.round(y), 0, 1023) if quantise else y


@pytest.mark.parametrize("amplitude", [50.0, 120.0, 200.0])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fit_recovers_the_paper_mode_from_adc_counts(amplitude, seed):
    r = ident.identify(T, decay(amplitude, seed=seed), WINDOW, method="fit")
    assert r.omega_d == pytest.approx(OMEGA_D, rel=0.005)
    assert r.zeta == pytest.approx(ZETA, rel=0.05)
    assert r.omega_n == pytest.approx(r.omega_d / math.sqrt(1.0 - r.zeta**2))
    assert r.method == "fit"
    assert r.n_cycles == pytest.approx((WINDOW[1] - WINDOW[0]) * OMEGA_D / (2 * math.pi), rel=0.01)


@pytest.mark.parametrize("seed", range(5))
def test_log_decrement_and_fft_within_their_tolerances(seed):
    """Stated tolerances: log decrement zeta 10 %, omega_d 1 %; FFT peak omega_d 0.5 %."""
    y = decay(60.0, seed=seed)
    r_ld = ident.identify(T, y, WINDOW, method="logdec")
    r_fft = ident.identify(T, y, WINDOW, method="fft")
    assert r_ld.zeta == pytest.approx(ZETA, rel=0.10)
    assert r_ld.omega_d == pytest.approx(OMEGA_D, rel=0.01)
    assert r_fft.omega_d == pytest.approx(OMEGA_D, rel=0.005)
    assert r_fft.zeta == r_ld.zeta  # the FFT gives no damping; the log decrement's is reported
    assert math.isnan(r_fft.omega_d_std)


@pytest.mark.parametrize("seed", range(3))
def test_a_weak_faster_mode_does_not_spoil_the_estimate(seed):
    """A second mode (90 rad/s, 10 counts, zeta 0.02) on top of the dominant one: still within tolerance."""
    tau = np.clip(T - T_RELEASE, 0.0, None)
    y = decay(100.0, seed=seed) + 10.0 * np.exp(-0.02 * 90.0 * tau) * np.sin(90.0 * tau)
    r = ident.identify(T, y, WINDOW)
    assert r.omega_d == pytest.approx(OMEGA_D, rel=0.005)
    assert r.zeta == pytest.approx(ZETA, rel=0.05)


def test_log_decrement_tolerates_a_rough_frequency_hint():
    t, y = _window(T, decay(100.0, seed=3))
    for factor in (0.85, 1.15):
        ld = ident.log_decrement(t, y, omega_hint=factor * OMEGA_D)
        assert ld.omega_d == pytest.approx(OMEGA_D, rel=0.01)
        assert ld.zeta == pytest.approx(ZETA, rel=0.10)


def test_works_in_newtons_as_well_as_counts():
    counts = decay(120.0, seed=3)
    gain, offset = 40.0, 300.0  # counts per N, counts
    newtons = (counts - offset) / gain
    r_c = ident.identify(T, counts, WINDOW)
    r_n = ident.identify(T, newtons, WINDOW)
    assert r_n.zeta == pytest.approx(r_c.zeta, rel=1e-6)
    assert r_n.omega_d == pytest.approx(r_c.omega_d, rel=1e-6)
    assert r_n.fit.amplitude == pytest.approx(r_c.fit.amplitude / gain, rel=1e-6)


def test_noiseless_decay_is_recovered_almost_exactly():
    y = decay(1.0, noise=0.0, quantise=False, offset=2.0)
    r = ident.identify(T, y, WINDOW)
    assert r.zeta == pytest.approx(ZETA, rel=1e-6)
    assert r.omega_d == pytest.approx(OMEGA_D, rel=1e-8)
    ld = ident.log_decrement(*_window(T, y))
    assert ld.zeta == pytest.approx(ZETA, rel=0.01)
    assert ld.omega_d == pytest.approx(OMEGA_D, rel=0.001)
    assert ld.baseline == pytest.approx(2.0, abs=1e-3)


def _window(t, y, window=WINDOW):
    keep = (t >= window[0]) & (t <= window[1])
    return t[keep], y[keep]


def test_uncertainties_are_consistent_with_the_scatter():
    """Over many seeds the truth lies within a few standard errors, and the errors are not inflated."""
    z_zeta, z_omega = [], []
    for seed in range(30):
        r = ident.identify(T, decay(80.0, seed=100 + seed), WINDOW)
        z_zeta.append((r.zeta - ZETA) / r.zeta_std)
        z_omega.append((r.omega_d - OMEGA_D) / r.omega_d_std)
    z_zeta, z_omega = np.array(z_zeta), np.array(z_omega)
    assert np.all(np.abs(z_zeta) < 4.0) and np.all(np.abs(z_omega) < 4.0)
    # a standardised error has unit spread: 0.5-2 rejects standard errors wrong by a factor of two
    assert 0.5 < np.sqrt(np.mean(z_zeta**2)) < 2.0
    assert 0.5 < np.sqrt(np.mean(z_omega**2)) < 2.0


def test_detected_peaks_lie_on_the_true_envelope():
    y = decay(150.0, noise=0.5, seed=4)
    ld = ident.log_decrement(*_window(T, y))
    spacing = np.diff(ld.peak_times)
    assert np.allclose(spacing, 2 * math.pi / OMEGA_D, rtol=0.01)
    # the extrema of a damped sine lie at |sin| = sqrt(1 - zeta^2) on the envelope
    true_env = 150.0 * math.sqrt(1 - ZETA**2) * np.exp(-SIGMA * (ld.peak_times - T_RELEASE))
    assert np.allclose(ld.peak_values - 300.0, true_env, atol=1.5)
    upper, lower = ld.envelope(ld.peak_times)
    assert np.allclose(upper, ld.peak_values, atol=2.0)
    assert np.all(lower < 300.0)
    assert ld.peak_times.size >= 3 and ld.trough_times.size >= 3
    assert np.all((ld.peak_times >= WINDOW[0]) & (ld.peak_times <= WINDOW[1]))


def test_fft_spectrum_is_single_sided_amplitude():
    """A pure sine's amplitude is read off the spectrum (Hann window, amplitude-corrected)."""
    t = np.arange(0.0, 2.0, 1e-3)
    f0 = 5.3
    res = ident.fft_peak(t, 3.0 + 2.0 * np.sin(2 * math.pi * f0 * t))
    assert res.frequency_hz == pytest.approx(f0, rel=1e-3)
    assert res.peak_amplitude == pytest.approx(2.0, rel=0.02)
    assert res.freqs_hz.shape == res.amplitude.shape
    assert res.resolution_hz == pytest.approx(0.5)


@pytest.mark.parametrize("duration", [0.3, 0.45])
def test_window_with_less_than_two_cycles_raises(duration):
    y = decay(120.0, seed=5)
    with pytest.raises(ValueError, match="too few cycles"):
        ident.identify(T, y, (9.0, 9.0 + duration))


def test_log_decrement_needs_two_peaks():
    y = decay(120.0, seed=6)
    t, yw = _window(T, y, (9.0, 9.3))
    with pytest.raises(ValueError, match="too few cycles"):
        ident.log_decrement(t, yw, omega_hint=OMEGA_D)


def test_pure_noise_does_not_pass_as_a_mode():
    rng = np.random.default_rng(7)
    y = np.round(300.0 + rng.normal(0.0, 1.0, T.size))
    with pytest.raises((ValueError, RuntimeError)):
        ident.identify(T, y, WINDOW, method="logdec")


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda t, y: (t, np.where(np.arange(y.size) == 500, np.nan, y)), "NaN"),
        (lambda t, y: (t[::-1], y), "increasing"),
        (lambda t, y: (np.delete(t, np.arange(400, 420)), np.delete(y, np.arange(400, 420))), "uniform"),
        (lambda t, y: (t[:10], y[:10]), "too short"),
        (lambda t, y: (t, y[:-1]), "same length"),
    ],
)
def test_bad_input_is_named(mutate, message):
    t, y = _window(T, decay(120.0, seed=8))
    t, y = mutate(t, y)
    with pytest.raises(ValueError, match=message):
        ident.identify(t, y)


def test_bad_arguments_are_named():
    y = decay(120.0, seed=9)
    with pytest.raises(ValueError, match="method"):
        ident.identify(T, y, WINDOW, method="half-power")
    with pytest.raises(ValueError, match="no samples"):
        ident.identify(T, y, (20.0, 21.0))
    with pytest.raises(ValueError, match="end > start"):
        ident.identify(T, y, (10.0, 9.0))


def test_to_dict_is_json_ready_and_summary_has_fixed_precision():
    r = ident.identify(T, decay(120.0, seed=10), WINDOW)
    d = json.loads(json.dumps(r.to_dict()))
    for key in ("zeta", "omega_d", "zeta_std", "omega_d_std", "method", "window_s", "recording", "source"):
        assert key in d
    assert d["recording"] is None and d["source"] is None  # unknown provenance is not invented
    assert d["window_s"] == [9.0, 10.0]
    assert d["zeta"] == r.zeta and d["method"] == "fit"
    assert set(d["estimates"]) == {"fit", "logdec", "fft"}
    s = r.summary()
    assert f"{r.zeta:.4f}" in s and f"{r.omega_d:.3f}" in s
    assert "damped-sine fit" in s
    with pytest.raises(AttributeError):
        r.zeta = 0.1  # frozen


def test_identify_recording_reads_the_frame():
    from types import SimpleNamespace

    import pandas as pd

    y = decay(120.0, seed=12)
    rec = SimpleNamespace(
        frame=pd.DataFrame({"t_s": T, "adc": y, "tension_n": (y - 300.0) / 40.0}),
        meta={"source": {"kind": "virtual-rig"}},
        name="pulse_100mms_10mm",
    )
    r = ident.identify_recording(rec)
    assert r.window_s == WINDOW and r.zeta == ident.identify(T, y, WINDOW).zeta
    d = r.to_dict()
    assert d["recording"] == "pulse_100mms_10mm" and d["source"] == "virtual-rig"
    assert ident.identify_recording(rec, column="tension_n").omega_d == pytest.approx(r.omega_d, rel=1e-6)
    with pytest.raises(ValueError, match="lacks column"):
        ident.identify_recording(rec, column="volts")


def test_result_json_round_trips_through_load_identification(tmp_path):
    """The file notebook 02's live cell and `record all` write is what the shaper design reads back."""
    import dataclasses

    r = ident.identify(T, decay(120.0, seed=13), WINDOW)
    r = dataclasses.replace(r, recording="pulse_100mms_10mm", source="virtual-rig")
    path = ident.save_identification(r, tmp_path / "identification" / "result.json")
    assert json.loads(path.read_text())["method"] == "fit"
    assert not list(path.parent.glob(".*tmp"))  # the temporary file was renamed away
    mode = ident.load_identification(path)
    assert (mode.zeta, mode.omega_d) == (r.zeta, r.omega_d)
    assert mode.source == "virtual-rig" and mode.window_s == (9.0, 10.0)
    assert mode.omega_n == pytest.approx(r.omega_d / math.sqrt(1 - r.zeta**2), rel=1e-14)


def test_load_identification_names_the_problem(tmp_path):
    from helpers.base.jsonfile import DataFileError, MissingDataError

    path = tmp_path / "result.json"
    with pytest.raises(MissingDataError, match="record all"):
        ident.load_identification(path)
    record = {
        "zeta": 0.045, "omega_d": 25.1, "zeta_std": 0.002, "omega_d_std": 0.05, "method": "fit",
        "window_s": [9.0, 10.0], "recording": "pulse", "source": "virtual-rig",
    }  # fmt: skip
    path.write_text(json.dumps(record))
    assert ident.load_identification(path).omega_d == 25.1
    for key, bad, message in (("method", None, "method"), ("zeta", 1.5, "zeta"), ("omega_d", "x", "omega_d")):
        broken = dict(record)
        if bad is None:
            del broken[key]
        else:
            broken[key] = bad
        path.write_text(json.dumps(broken))
        with pytest.raises(DataFileError, match=message):
            ident.load_identification(path)
    path.write_text("{not json")
    with pytest.raises(DataFileError, match="JSON"):
        ident.load_identification(path)


def test_identification_figures_are_written(tmp_path, monkeypatch):
    import helpers.base.paths
    from helpers.plotting import identification as plots

    monkeypatch.setattr(helpers.base.paths, "FIGURES_DIR", tmp_path)
    y = decay(120.0, seed=11)
    r = ident.identify(T, y, WINDOW)
    fig5 = plots.fig5_force_response(T, y, source="virtual-rig", save=True)
    fig6 = plots.fig6_logdec_fft(r, T, y, save=True)
    assert (tmp_path / "fig5_force_response.png").stat().st_size > 0
    assert (tmp_path / "fig6_logdec_fft.png").stat().st_size > 0
    assert "virtual rig" in fig5.axes[0].get_title()
    # the upper panel shows only the window
    xs = fig6.axes[0].lines[0].get_xdata()
    assert xs.min() >= WINDOW[0] and xs.max() <= WINDOW[1]
    import matplotlib.pyplot as plt

    plt.close("all")


def test_peak_thinning_breaks_ties_the_same_whatever_the_sort():
    """Equal heights within the minimum distance (common on ADC counts): the later peak is kept, by a stable
    sort, where scipy's find_peaks orders ties by numpy's default sort, which depends on the CPU's SIMD."""
    from scipy import signal

    from helpers.paper.identify import _peaks

    y = np.zeros(60)
    y[[10, 14, 40]] = [5.0, 5.0, 3.0]  # two equal peaks 4 samples apart, a lower one far away
    assert _peaks(y, prominence=1.0, distance=6).tolist() == [14, 40]
    # without ties it is scipy's own selection
    rng = np.random.default_rng(3)
    z = np.sin(np.linspace(0, 20, 800)) + 0.05 * rng.standard_normal(800)
    expected, _ = signal.find_peaks(z, prominence=0.3, distance=40)
    assert _peaks(z, prominence=0.3, distance=40).tolist() == expected.tolist()
