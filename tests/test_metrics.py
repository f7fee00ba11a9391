"""helpers.paper.metrics on synthetic up-hold-down recordings whose metrics are known in closed form.

The tension is a step (up at 1 s, down at 8 s) through a second-order system, whose overshoot is
exp(-zeta pi / sqrt(1 - zeta^2)); settling instants are found independently by brute force on a 10 us grid of
the continuous closed form. The step count rises from exactly the sample where the tension's step starts.
"""

import math
from types import SimpleNamespace

import matplotlib
import numpy as np
import pandas as pd
import pytest

from helpers.paper import metrics
from helpers.paper.numbers import TABLE_I_CONDITIONS, table_ii
from helpers.research import residuals, table_ii_checks

matplotlib.use("Agg")

FS = 1000.0
T = np.arange(0.0, 12.0, 1.0 / FS)
T_UP, T_DOWN = 1.0, 8.0
N_STEPS = 78


def step2(tau, zeta, wn):
    """Unit step response of wn^2 / (s^2 + 2 zeta wn s + wn^2), zero for tau < 0."""
    tau = np.asarray(tau, dtype=float)
    wd = wn * math.sqrt(1.0 - zeta**2)
    y = 1.0 - np.exp(-zeta * wn * tau) * (np.cos(wd * tau) + zeta / math.sqrt(1 - zeta**2) * np.sin(wd * tau))
    return np.where(tau >= 0.0, y, 0.0)


def tension(t, zeta=0.2, wn=25.0, low=1.0, high=9.0):
    """Up step at T_UP from ``low`` to ``high`` and down step at T_DOWN back (superposition)."""
    return low + (high - low) * (step2(t - T_UP, zeta, wn) - step2(t - T_DOWN, zeta, wn))


def steps_profile(t=T, t_up=T_UP, t_down=T_DOWN, duration=0.1):
    """Step count ramping 0 -> N_STEPS from t_up (first step on the sample at t_up) and back from t_down."""
    ramp = lambda t0: np.clip(np.floor((t - t0) / duration * N_STEPS) + 1, 0, N_STEPS) * (t >= t0 - 1e-9)  # noqa: E731
    return (ramp(t_up) - ramp(t_down)).astype(int)


def reference_levels(f, start, end):
    """y0 and yf by the definition, computed here on the sample grid: medians of the 0.5 s before the start
    and of the last 1.0 s of the window [start, end) (end included if it is the last sample)."""
    pre = T[(T >= start - 0.5) & (T < start)]
    win = T[(T >= start) & ((T < end) | (end >= T[-1]))]
    return float(np.median(f(pre))), float(np.median(f(win[win >= win[-1] - 1.0])))


def brute_settling(f, start, end, band, dt=1e-5):
    """Last time the continuous signal is outside the band, from ``start`` (ms), on a 10 us grid."""
    y0, yf = reference_levels(f, start, end)
    tt = np.arange(start, end, dt)
    out = np.flatnonzero(np.abs(f(tt) - yf) > band * abs(yf - y0))
    return 1e3 * (tt[out[-1]] + dt - start)


def frame_of(t, y, steps):
    return pd.DataFrame({"t_s": t, "tension_n": y, "steps": steps, "cable_mm": steps * 0.25525})


# ---------------------------------------------------------------------------------------------------------
# segmentation


def test_segmentation_uses_the_recorded_steps_not_nominal_times():
    s = steps_profile(t_up=1.2345, t_down=8.4321)
    m = metrics.segment_motions(T, s)
    assert m.up_start == pytest.approx(1.235)  # first sample at or after the first step
    assert m.down_start == pytest.approx(8.433)
    assert m.end == T[-1]
    i_up, i_down = np.searchsorted(T, [m.up_start, m.down_start])
    assert s[i_up - 1] == 0 and s[i_up] > 0
    assert s[i_down] < s[i_down - 1] == N_STEPS


def test_segmentation_errors_are_named():
    with pytest.raises(ValueError, match="no up move"):
        metrics.segment_motions(T, np.zeros(T.size))
    with pytest.raises(ValueError, match="no down move"):
        metrics.segment_motions(T, np.minimum(np.arange(T.size), 50))
    with pytest.raises(ValueError, match="same length"):
        metrics.segment_motions(T, np.zeros(T.size - 1))
    with pytest.raises(ValueError, match="increasing"):
        metrics.segment_motions(T[::-1], steps_profile())


# ---------------------------------------------------------------------------------------------------------
# closed-form metrics


@pytest.mark.parametrize("zeta", [0.05, 0.2, 0.4, 0.7])
def test_up_and_down_of_a_second_order_step(zeta):
    wn, low, high = 25.0, 1.0, 9.0
    y = tension(T, zeta, wn, low, high)
    mp = math.exp(-zeta * math.pi / math.sqrt(1.0 - zeta**2))
    up = metrics.motion_metrics(T, y, T_UP, T_DOWN, "Up")
    down = metrics.motion_metrics(T, y, T_DOWN, T[-1], "Down")
    assert up.reason == "" and down.reason == ""
    assert up.y0 == pytest.approx(low) and up.yf == pytest.approx(high, rel=1e-4)
    assert up.peak == pytest.approx(high + (high - low) * mp, rel=1e-4)
    assert up.overshoot_pct == pytest.approx(100.0 * mp, abs=0.02)

    def f(tt):
        return tension(tt, zeta, wn, low, high)

    # Down: the minimum undershoots the final value; the overshoot is positive, the same closed form when the
    # record is long enough to settle (for zeta = 0.05 it still rings by 0.5 % of the step at 12 s, so the
    # levels are the medians of the definition, computed here from the closed form)
    trough = low - (high - low) * mp
    assert down.peak == pytest.approx(trough, rel=1e-3, abs=1e-4)
    y0_ref, yf_ref = reference_levels(f, T_DOWN, T[-1])
    assert down.overshoot_pct == pytest.approx(100.0 * (yf_ref - trough) / (y0_ref - yf_ref), abs=0.02)
    if zeta >= 0.2:
        assert down.overshoot_pct == pytest.approx(100.0 * mp, abs=0.02)

    assert up.settling_ms == pytest.approx(brute_settling(f, T_UP, T_DOWN, 0.05), abs=0.1)
    assert down.settling_ms == pytest.approx(brute_settling(f, T_DOWN, T[-1], 0.05), abs=0.1)
    assert up.settled_s == pytest.approx(T_UP + up.settling_ms / 1e3)


@pytest.mark.parametrize("band", [0.01, 0.02, 0.05, 0.1, 0.2])
def test_first_order_approach_settles_at_tau_ln_one_over_band(band):
    tau = 0.3
    y = 2.0 + 5.0 * np.where(T >= T_UP, 1.0 - np.exp(-(T - T_UP) / tau), 0.0)
    m = metrics.motion_metrics(T, y, T_UP, T[-1], "Up", band)
    assert m.settling_ms == pytest.approx(1e3 * tau * math.log(1.0 / band), abs=0.05)
    assert m.overshoot_pct == pytest.approx(0.0, abs=1e-6)


def test_settling_time_does_not_grow_with_the_band():
    y = tension(T, 0.1)
    bands = [0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.4]
    settle = [metrics.motion_metrics(T, y, T_UP, T_DOWN, "Up", b).settling_ms for b in bands]
    assert np.all(np.isfinite(settle))
    assert np.all(np.diff(settle) <= 0) and settle[0] > settle[-1]


def test_slack_cable_on_the_down_move():
    """Tension cannot go below zero: the undershoot is clipped, the peak is 0, the overshoot follows."""
    zeta, wn, low, high = 0.1, 25.0, 2.0, 10.0

    def f(tt):
        return np.maximum(tension(tt, zeta, wn, low, high), 0.0)

    y = f(T)
    assert np.sum(y[T > T_DOWN] == 0.0) > 10  # slack for a while
    d = metrics.motion_metrics(T, y, T_DOWN, T[-1], "Down")
    assert d.peak == 0.0
    assert d.overshoot_pct == pytest.approx(100.0 * (low - 0.0) / (high - low), abs=0.01)
    assert d.settling_ms == pytest.approx(brute_settling(f, T_DOWN, T[-1], 0.05), abs=0.1)


@pytest.mark.parametrize(("gain", "offset"), [(2.5, 0.0), (0.1, 30.0), (7.0, -3.0)])
def test_metrics_follow_an_affine_change_of_units(gain, offset):
    """Overshoot and settling do not depend on the sensor's gain and offset; peaks transform with them."""
    y = tension(T, 0.15)
    for start, end, motion in ((T_UP, T_DOWN, "Up"), (T_DOWN, T[-1], "Down")):
        a = metrics.motion_metrics(T, y, start, end, motion)
        b = metrics.motion_metrics(T, gain * y + offset, start, end, motion)
        assert b.peak == pytest.approx(gain * a.peak + offset)
        assert b.overshoot_pct == pytest.approx(a.overshoot_pct, rel=1e-9)
        assert b.settling_ms == pytest.approx(a.settling_ms, abs=1e-6)


def test_down_motion_is_the_mirror_image_of_an_up_motion():
    """Sign convention: a Down motion of y has the metrics of an Up motion of -y (peak mirrored)."""
    y = tension(T, 0.25)
    down = metrics.motion_metrics(T, y, T_DOWN, T[-1], "Down")
    up_of_mirror = metrics.motion_metrics(T, -y, T_DOWN, T[-1], "Up")
    assert down.overshoot_pct > 0
    assert down.overshoot_pct == pytest.approx(up_of_mirror.overshoot_pct, rel=1e-12)
    assert down.settling_ms == pytest.approx(up_of_mirror.settling_ms, abs=1e-9)
    assert down.peak == pytest.approx(-up_of_mirror.peak)


def test_wrong_direction_gives_nan_overshoot_with_reason():
    y = tension(T, 0.2, low=9.0, high=1.0)  # tension falls on the "up" move
    m = metrics.motion_metrics(T, y, T_UP, T_DOWN, "Up")
    assert math.isnan(m.overshoot_pct) and "falls" in m.reason
    assert math.isfinite(m.settling_ms)


# ---------------------------------------------------------------------------------------------------------
# metrics that cannot be computed


def test_undamped_oscillation_never_settles():
    y = tension(T, 1e-9)  # zeta ~ 0: keeps ringing
    m = metrics.motion_metrics(T, y, T_UP, T_DOWN, "Up")
    assert math.isnan(m.settling_ms) and math.isnan(m.settled_s)
    assert "settle" in m.reason
    assert math.isfinite(m.peak) and math.isfinite(m.overshoot_pct)


def test_drift_to_the_end_never_settles():
    y = np.where(T >= T_UP, np.expm1(T - T_UP), 0.0)  # still growing by 65 % in the last half second
    m = metrics.motion_metrics(T, y, T_UP, T[-1], "Up")
    assert math.isnan(m.settling_ms)
    assert "never settles" in m.reason


@pytest.mark.parametrize("noise", [0.0, 0.05])
def test_flat_signal_is_a_zero_step(noise):
    y = 4.0 + np.random.default_rng(1).normal(0.0, noise, T.size)
    m = metrics.motion_metrics(T, y, T_UP, T_DOWN, "Up")
    assert math.isnan(m.overshoot_pct) and math.isnan(m.settling_ms)
    assert "zero step" in m.reason
    assert m.peak == pytest.approx(np.max(y[(T >= T_UP) & (T < T_DOWN)]))


def test_ringing_before_the_motion_is_not_taken_for_noise():
    """An Up motion still ringing when the Down move starts is signal, not noise: the Down step is a step."""
    y = tension(T, 0.01)  # sigma = 0.25 /s: 1.4 N of ringing left at 8 s on an 8 N step
    assert np.ptp(y[(T > 7.5) & (T < T_DOWN)]) > 2.0
    m = metrics.motion_metrics(T, y, T_DOWN, T[-1], "Down")
    assert "zero step" not in m.reason
    assert math.isfinite(m.overshoot_pct)


def test_missing_samples_beyond_tolerance_give_nan():
    y = tension(T, 0.2)
    lost = (T > 1.30) & (T < 1.35)  # 50 ms lost in the up window
    m = metrics.motion_metrics(T[~lost], y[~lost], T_UP, T_DOWN, "Up")
    assert all(math.isnan(v) for v in (m.y0, m.yf, m.peak, m.overshoot_pct, m.settling_ms))
    assert "gap" in m.reason
    # the same gap as NaN samples
    y_nan = np.where(lost, np.nan, y)
    m_nan = metrics.motion_metrics(T, y_nan, T_UP, T_DOWN, "Up")
    assert "gap" in m_nan.reason and math.isnan(m_nan.peak)
    # a gap in the pre-motion span counts too; a gap in the other motion does not
    pre_lost = (T > 0.7) & (T < 0.75)
    assert "gap" in metrics.motion_metrics(T[~pre_lost], y[~pre_lost], T_UP, T_DOWN, "Up").reason
    assert metrics.motion_metrics(T[~lost], y[~lost], T_DOWN, T[-1], "Down").reason == ""


def test_a_few_missing_samples_are_tolerated():
    y = tension(T, 0.2)
    keep = np.ones(T.size, bool)
    keep[[1500, 3000, 3001]] = False  # one, then two consecutive samples lost
    full = metrics.motion_metrics(T, y, T_UP, T_DOWN, "Up")
    m = metrics.motion_metrics(T[keep], y[keep], T_UP, T_DOWN, "Up")
    assert m.reason == ""
    assert m.overshoot_pct == pytest.approx(full.overshoot_pct, abs=0.05)
    assert m.settling_ms == pytest.approx(full.settling_ms, abs=1.0)


def test_too_little_data_before_the_motion():
    y = tension(T, 0.2)
    keep = T >= 0.8
    m = metrics.motion_metrics(T[keep], y[keep], T_UP, T_DOWN, "Up")
    assert math.isnan(m.y0) and "before the motion" in m.reason


def test_settling_at_the_very_end_is_not_confirmed(monkeypatch):
    monkeypatch.setattr(metrics, "FINAL_S", 0.3)
    monkeypatch.setattr(metrics, "MIN_HOLD_S", 1.0)
    y = np.where(T >= T_UP, 1.0 - np.exp(-(T - T_UP) / 0.3), 0.0)
    m = metrics.motion_metrics(T, y, T_UP, 2.5, "Up", 0.05)
    assert math.isnan(m.settling_ms) and "cannot confirm" in m.reason


def test_bad_arguments_raise():
    y = tension(T)
    with pytest.raises(ValueError, match="motion"):
        metrics.motion_metrics(T, y, T_UP, T_DOWN, "Sideways")
    with pytest.raises(ValueError, match="band"):
        metrics.motion_metrics(T, y, T_UP, T_DOWN, "Up", band=0.0)
    with pytest.raises(ValueError, match="start < end"):
        metrics.motion_metrics(T, y, T_DOWN, T_UP, "Up")


# ---------------------------------------------------------------------------------------------------------
# recordings and Table II


def fake_recording(v_in, x_f, system, repetition, zeta, noise=0.0, seed=0, source="virtual-rig"):
    rng = np.random.default_rng(seed)
    y = tension(T, zeta) + rng.normal(0.0, noise, T.size)
    meta = {
        "source": {"kind": source},
        "scenario": {"v_in_mm_s": v_in, "x_f_mm": x_f, "system": system, "repetition": repetition},
    }
    return SimpleNamespace(frame=frame_of(T, y, steps_profile()), meta=meta)


def test_recording_metrics_rows():
    df = metrics.recording_metrics(fake_recording(200, 20, "zv", 1, 0.3).frame)
    assert list(df["motion"]) == ["Up", "Down"]
    mp = 100.0 * math.exp(-0.3 * math.pi / math.sqrt(1 - 0.09))
    assert np.allclose(df["overshoot_pct"], mp, atol=0.02)
    assert df.loc[0, "start_s"] == pytest.approx(T_UP) and df.loc[1, "start_s"] == pytest.approx(T_DOWN)
    assert (df["reason"] == "").all()


def test_recording_without_a_down_move_gives_nan_rows():
    rec = fake_recording(200, 20, "zv", 1, 0.3)
    rec.frame["steps"] = np.minimum(np.arange(T.size), 50)
    df = metrics.recording_metrics(rec.frame)
    assert df["peak_n"].isna().all() and df["reason"].str.contains("no down move").all()
    with pytest.raises(ValueError, match="lacks column"):
        metrics.recording_metrics(rec.frame.drop(columns="tension_n"))


def test_scenario_table_mean_spread_and_order():
    zetas = {"unshaped": (0.05, 0.06, 0.07), "zv": (0.3, 0.35, 0.4), "zvd": (0.6, 0.65, 0.7)}
    recs = [
        fake_recording(v, x, system, rep + 1, z)
        for (v, x) in reversed(TABLE_I_CONDITIONS)
        for system, zs in zetas.items()
        for rep, z in enumerate(zs)
    ]
    table = metrics.scenario_table(recs, band=0.05)
    assert len(table) == 4 * 3 * 2
    assert table.attrs["band"] == 0.05 and (table["band"] == 0.05).all()
    # paper's order: conditions as Table I, then pulse / non-robust / robust, then Up / Down
    assert list(zip(table["v_in_mm_s"], table["x_f_mm"], strict=True))[::6] == list(TABLE_I_CONDITIONS)
    assert list(table["system"][:6]) == ["unshaped", "unshaped", "zv", "zv", "zvd", "zvd"]
    assert list(table["motion"][:2]) == ["Up", "Down"]
    mp = np.array([100.0 * math.exp(-z * math.pi / math.sqrt(1 - z * z)) for z in zetas["zv"]])
    row = table[(table["system"] == "zv") & (table["motion"] == "Up")].iloc[0]
    assert row["overshoot_pct_mean"] == pytest.approx(mp.mean(), abs=0.02)
    assert row["overshoot_pct_std"] == pytest.approx(mp.std(ddof=1), abs=0.02)
    assert row["overshoot_pct_n"] == 3 and row["n_runs"] == 3
    # more damping, less overshoot and faster settling: unshaped > zv > zvd
    up = table[table["motion"] == "Up"].groupby("system")[["overshoot_pct_mean", "settling_ms_mean"]].mean()
    assert up.loc["unshaped"].gt(up.loc["zv"]).all() and up.loc["zv"].gt(up.loc["zvd"]).all()


def test_scenario_table_counts_only_computable_values():
    good = fake_recording(200, 20, "zv", 1, 0.3)
    flat = fake_recording(200, 20, "zv", 2, 0.3)
    flat.frame["tension_n"] = 3.0
    table = metrics.scenario_table([good, flat])
    up = table[table["motion"] == "Up"].iloc[0]
    assert up["n_runs"] == 2 and up["overshoot_pct_n"] == 1 and up["peak_n_n"] == 2
    assert math.isnan(up["overshoot_pct_std"])
    assert "rep 2: zero step" in up["reason"]


def test_scenario_table_needs_scenario_metadata():
    rec = fake_recording(200, 20, "zv", 1, 0.3)
    del rec.meta["scenario"]["system"]
    with pytest.raises(ValueError, match="scenario"):
        metrics.scenario_table([rec])
    with pytest.raises(ValueError, match="no complete recordings"):
        metrics.scenario_table([])


def test_paper_comparison_sets_the_paper_beside_ours():
    recs = [fake_recording(200, 20, s, 1, z) for s, z in (("unshaped", 0.05), ("zv", 0.3), ("zvd", 0.6))]
    cmp = metrics.paper_comparison(metrics.scenario_table(recs))
    paper = table_ii()
    assert len(cmp) == len(paper)
    row = cmp[
        (cmp["x_f_mm"] == 20)
        & (cmp["v_in_mm_s"] == 200)
        & (cmp["system"] == "zvd")
        & (cmp["motion"] == "Down")
    ]
    ref = paper[
        (paper["x_f_mm"] == 20)
        & (paper["v_in_mm_s"] == 200)
        & (paper["system"] == "zvd")
        & (paper["motion"] == "Down")
    ]
    assert row["settling_ms_paper"].item() == ref["settling_ms"].item()
    assert math.isfinite(row["settling_ms"].item())
    assert cmp[(cmp["x_f_mm"] == 30)]["peak_n"].isna().all()  # no recordings of that condition


def test_band_sweep_is_monotonic():
    recs = [fake_recording(200, 20, "unshaped", 1, 0.08)]
    sweep = table_ii_checks.band_sweep(recs, (0.02, 0.05, 0.1))
    up = sweep[sweep["motion"] == "Up"].sort_values("band")["settling_ms_mean"].to_numpy()
    assert np.all(np.diff(up) < 0)


def test_scenario_figure_is_written(tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    import helpers.base.paths
    from helpers.plotting import experiments as plots

    monkeypatch.setattr(helpers.base.paths, "FIGURES_DIR", tmp_path)
    recs = [
        fake_recording(v, x, s, r, z)
        for (v, x) in ((200, 20), (200, 10))
        for s, z in (("unshaped", 0.05), ("zv", 0.3), ("zvd", 0.6))
        for r in (1, 2)
    ]
    fig = plots.fig_scenario(recs, (200, 20), save=True)
    assert (tmp_path / "fig9_20mm_200mms.png").stat().st_size > 0
    assert "virtual rig" in fig._suptitle.get_text() and fig._suptitle.get_text().startswith("Fig. 9")
    assert len(fig.axes) == 4  # one row per system (the traces cannot hide each other) and the cable
    assert [ax.get_title(loc="left") for ax in fig.axes[:3]] == ["Pulse", "Non-robust TDF", "Robust TDF"]
    for ax, pair in zip(fig.axes[:3], (recs[0:2], recs[2:4], recs[4:6]), strict=True):
        (mean_line,) = ax.lines  # the mean of the two repetitions of this condition, nothing else
        expected = (pair[0].frame["tension_n"].to_numpy() + pair[1].frame["tension_n"].to_numpy()) / 2
        np.testing.assert_allclose(mean_line.get_ydata(), expected)
        assert len(ax.collections) == 1  # the band between the repetitions
        fig_a = plots.fig_scenario(recs, (200, 10), save=True)
    assert (tmp_path / "figA_10mm_200mms.png").exists()
    assert "no figure in the paper" in fig_a._suptitle.get_text()
    with pytest.raises(ValueError, match="no recording"):
        plots.fig_scenario(recs, (300, 20))
    hw = [fake_recording(200, 20, "zv", 1, 0.3, source="hardware")]
    assert "virtual" not in plots.fig_scenario(hw, (200, 20))._suptitle.get_text()
    plt.close("all")


def test_aborted_runs_stay_out_of_table_ii_unless_asked():
    import types

    t = np.arange(0, 12, 1e-3)
    steps = np.where((t >= 1) & (t < 8), 10, 0)
    y = 2.0 + 0.5 * steps
    frame = pd.DataFrame({"t_s": t, "steps": steps, "tension_n": y})
    sc = {"v_in_mm_s": 200.0, "x_f_mm": 10.0, "system": "unshaped"}
    good = types.SimpleNamespace(name="good", frame=frame, meta={"status": "complete", "scenario": sc})
    cut = types.SimpleNamespace(name="cut", frame=frame, meta={"status": "aborted", "scenario": sc})
    table = metrics.scenario_table([good, cut])
    assert set(table["n_runs"]) == {1} and table.attrs["skipped"] == ["cut: aborted"]
    assert set(metrics.scenario_table([good, cut], include_aborted=True)["n_runs"]) == {2}
    with pytest.raises(ValueError, match="no complete recordings"):
        metrics.scenario_table([cut])


# ---------------------------------------------------------------------------------------------------------
# the range check: clipped samples make the peak a bound, for hardware and virtual recordings alike

# the paper's chain written out here: a 4-20 mA loop (saturating at 3.8 and 20.5 mA) through 150 ohm into a
# 10-bit ADC with a 5 V reference; within 2 counts of the upper saturation counts as clipped
LOW = math.floor(3.8e-3 * 150 * 1024 / 5)
HIGH = round(20.5e-3 * 150 * 1024 / 5) - 2


def test_clipped_samples_are_the_adc_rails_and_the_loop_saturation():
    adc = np.array([0, LOW, LOW + 1, 123, 558, HIGH - 1, HIGH, 630, 1023])
    expected = np.array([True, True, False, False, False, False, True, True, True])
    np.testing.assert_array_equal(metrics.clipped_samples(adc), expected)


def _counts_recording(y, ceiling, source):
    """A recording whose ADC reads offset + gain * y, cut at ``ceiling`` counts, and the tension derived."""
    gain, offset = 24.576, 122.88
    adc = np.minimum(np.rint(offset + gain * y), ceiling).astype(int)
    frame = frame_of(T, (adc - offset) / gain, steps_profile())
    frame["adc"] = adc
    meta = {"source": {"kind": source}, "scenario": {"v_in_mm_s": 200, "x_f_mm": 20, "system": "unshaped",
                                                     "repetition": 1}}  # fmt: skip
    return SimpleNamespace(frame=frame, meta=meta)


@pytest.mark.parametrize("source", ["hardware", "virtual-rig"])
def test_a_clipped_peak_is_a_flagged_bound_carried_into_the_tables(source):
    # overshoots to ~22 N, beyond the loop's 20.6 N; a cable only pulls, so no reading below 0 N
    y = np.maximum(tension(T, zeta=0.05, low=2.0, high=13.0), 0.0)
    rec = _counts_recording(y, round(20.5e-3 * 150 * 1024 / 5), source)
    df = metrics.recording_metrics(rec.frame).set_index("motion")
    up, down = df.loc["Up"], df.loc["Down"]
    assert up["peak_is_bound"] and up["n_clipped"] > 0
    assert "lower bound" in up["reason"]
    # the value is kept: the largest reading, below the true peak
    assert up["peak_n"] == pytest.approx(rec.frame["tension_n"].max())
    assert up["peak_n"] < y.max()
    assert not down["peak_is_bound"] and down["reason"] == ""
    table = metrics.scenario_table([rec])
    row = table[(table.system == "unshaped") & (table.motion == "Up")].iloc[0]
    assert row["peak_is_bound"] and "rep 1: peak is a lower bound" in row["reason"]
    cmp = metrics.paper_comparison(table)
    assert cmp[(cmp.system == "unshaped") & (cmp.motion == "Up") & (cmp.x_f_mm == 20)
               & (cmp.v_in_mm_s == 200)]["peak_is_bound"].item()  # fmt: skip


def test_an_unclipped_recording_is_not_flagged():
    y = np.maximum(tension(T, zeta=0.05, low=2.0, high=9.0), 0.0)
    df = metrics.recording_metrics(_counts_recording(y, 1023, "hardware").frame)
    assert not df["peak_is_bound"].any() and (df["n_clipped"] == 0).all()


def test_a_virtual_recording_that_clips_is_flagged_whatever_the_gain():
    """A simulated run read through a chain whose span is set below the run's own peak: it must clip."""
    from helpers.board.programmes import experiment_programme
    from helpers.virtual import LoadCell, RigParameters, simulate

    params = RigParameters()
    prog, _ = experiment_programme(300.0, 20.0)
    first = simulate(prog, params=params)
    peak = first.output.max()
    # span such that the loop saturates (at 20.5 mA) at 70 % of this run's peak, whatever the default gain
    span = 0.7 * peak * 16.0 / 16.5
    run = simulate(prog, params=params, sensor=LoadCell(params, span_n=span))
    assert np.any(metrics.clipped_samples(run.adc))
    df = metrics.recording_metrics(run.frame("adc")).set_index("motion")
    assert df.loc["Up", "peak_is_bound"] and "lower bound" in df.loc["Up", "reason"]
    assert df.loc["Up", "peak_n"] < peak
    assert not df.loc["Down", "peak_is_bound"]


def test_the_scenario_figure_marks_clipped_samples():
    import matplotlib.pyplot as plt

    from helpers.plotting import experiments as plots

    y = np.maximum(tension(T, zeta=0.05, low=2.0, high=13.0), 0.0)
    rec = _counts_recording(y, round(20.5e-3 * 150 * 1024 / 5), "hardware")
    fig = plots.fig_scenario([rec], (200, 20))
    labels = [line.get_label() for line in fig.axes[0].lines]
    assert any("clipped" in label for label in labels)
    plt.close("all")


# ---------------------------------------------------------------------------------------------------------
# held-out predictions


def _as_scenario_table(df):
    return df.rename(columns={m: f"{m}_mean" for m in metrics.METRIC_COLUMNS})


def test_prediction_errors_are_ours_minus_the_papers_on_the_shaped_rows():
    paper = table_ii()
    ours = paper.copy()
    ours["peak_n"] += 1.0
    ours["overshoot_pct"] -= 5.0
    err = table_ii_checks.prediction_errors(_as_scenario_table(ours))
    assert len(err) == 16 and set(err["system"]) == {"zv", "zvd"}
    np.testing.assert_allclose(err["peak_err_n"], 1.0)
    np.testing.assert_allclose(err["overshoot_err_pp"], -5.0)
    np.testing.assert_allclose(err["settling_err_ms"], 0.0)
    assert not err["peak_is_bound"].any()


def test_ordering_agreement_of_the_paper_with_itself_and_with_a_reversed_table():
    paper = table_ii()
    same = table_ii_checks.ordering_agreement(_as_scenario_table(paper), "overshoot_pct")
    assert len(same) == 4 * 2 * 3 and same["agrees"].all()
    # 8 informative orderings (robust against non-robust), 16 trivial ones (a shaper below the pulse)
    assert set(same.loc[same.informative, "ordering"]) == {"zvd < zv"} and same.informative.sum() == 8
    pulse = paper.set_index(["v_in_mm_s", "x_f_mm", "system", "motion"])["overshoot_pct"]
    first = same.iloc[0]  # 10 mm Up, zv < unshaped: the margin is the paper's own difference
    assert first["ours_margin"] == pytest.approx(
        pulse[(200.0, 10.0, "unshaped", "Up")] - pulse[(200.0, 10.0, "zv", "Up")]
    )
    # the paper's one exception: at 30 mm / 200 mm/s the robust TDF's Up overshoot is above the non-robust's
    row = same[(same.x_f_mm == 30) & (same.motion == "Up") & (same.ordering == "zvd < zv")]
    assert not row["paper"].item()
    reversed_ = paper.copy()
    reversed_["settling_ms"] = -reversed_["settling_ms"]
    flipped = table_ii_checks.ordering_agreement(_as_scenario_table(reversed_), "settling_ms")
    # reversing every value flips every ordering except ties (the paper has one: 30 mm Up, 1044 ms twice)
    key = paper.set_index(["v_in_mm_s", "x_f_mm", "system", "motion"])["settling_ms"]
    ties = [key[(v, x, a, m)] == key[(v, x, b, m)]
            for v, x, m, (a, b) in zip(flipped.v_in_mm_s, flipped.x_f_mm, flipped.motion,
                                       (o.split(" < ") for o in flipped.ordering), strict=True)]  # fmt: skip
    assert sum(ties) == 1
    np.testing.assert_array_equal(flipped["agrees"].to_numpy(), np.array(ties))
    with pytest.raises(ValueError, match="metric"):
        table_ii_checks.ordering_agreement(_as_scenario_table(paper), "peak_n")


def test_another_chain_is_bounded_by_the_adc_rails_only():
    """A calibration whose zero is not the 4 mA loop's (e.g. 50 counts) comes from another chain: only 0 and
    1023 count as clipped, so its ordinary readings above 628 counts are not flagged."""
    other = {"offset_counts": 50.0, "newtons_per_count": 0.02}
    adc = np.array([0, 50, 117, 700, 1022, 1023])
    expected = [True, False, False, False, False, True]
    np.testing.assert_array_equal(metrics.clipped_samples(adc, other), expected)
    paper_chain = {"offset_counts": 123.4, "newtons_per_count": 1 / 24.576}
    expected = [True, True, False, True, True, True]
    np.testing.assert_array_equal(metrics.clipped_samples(adc, paper_chain), expected)
    y = np.maximum(tension(T, zeta=0.05, low=2.0, high=13.0), 0.0)
    adc = np.rint(50 + 50 * y).astype(int)  # 50 counts/N: ~22 N reads ~1150 -> the ADC's top clips
    frame = frame_of(T, (np.minimum(adc, 1023) - 50) / 50, steps_profile())
    frame["adc"] = np.minimum(adc, 1023)
    df = metrics.recording_metrics(frame, calibration=other).set_index("motion")
    assert df.loc["Up", "peak_is_bound"] and not df.loc["Down", "peak_is_bound"]


def test_move_residuals_match_the_closed_form_after_each_move():
    zeta = 0.15
    rec = fake_recording(200, 20, "zv", 1, zeta)
    rec.frame["tension_n"] += 5.0  # 6 N at rest: the Down transient (62 % of 8 N) stays taut
    table = residuals.move_residuals(rec.frame)
    assert list(table["motion"]) == ["Up", "Down"]
    for row, t0 in zip(table.itertuples(), (T_UP, T_DOWN), strict=True):
        assert row.move_end_s == pytest.approx(t0 + 0.1, abs=2e-3)  # the step ramp lasts 0.1 s
        # the definition evaluated on the continuous closed form, on a 10 us grid
        tt = np.arange(row.move_end_s + 0.1, row.move_end_s + 1.1, 1e-5)
        y = tension(tt, zeta) + 5.0
        expected = 100.0 * (y.max() - y.min()) / 2.0 / 8.0  # the step is 9 - 1 = 8 N
        assert row.residual_pct == pytest.approx(expected, rel=0.01)
        assert row.noise_floor_pct == pytest.approx(0.0, abs=1e-9)  # a noise-free signal at rest
        assert not row.slack and row.reason == ""
    noisy = residuals.move_residuals(fake_recording(200, 20, "zv", 1, 0.6, noise=0.05).frame)
    assert (noisy["noise_floor_pct"] > 0.5).all()  # +-3 sigma of 0.05 N is ~2 % of 8 N


def test_a_slack_cable_in_the_residual_window_is_said():
    rec = fake_recording(200, 20, "unshaped", 1, 0.05)
    rec.frame["tension_n"] = rec.frame["tension_n"] - 1.5  # the Down move now dips below 0 N
    down = residuals.move_residuals(rec.frame).set_index("motion").loc["Down"]
    assert down["slack"] and "slack" in down["reason"]
