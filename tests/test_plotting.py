"""Figure helpers whose output is a number or a title: slack detection, honest precision, source labels."""

import matplotlib
import numpy as np
import pytest
from rig_fakes import make_rig

from helpers import recordings
from helpers.plotting import identification
from helpers.plotting.experiments import fig_scenario

matplotlib.use("Agg")


def test_slack_spans_finds_stretches_at_zero_tension_longer_than_the_minimum():
    t = np.arange(0.0, 2.0, 0.001)
    adc = np.full(t.size, 300.0)
    adc[(t >= 0.5) & (t < 0.8)] = 50.4  # 0.3 s slack, within the 1-count margin of 50
    adc[(t >= 1.2) & (t < 1.23)] = 50.0  # 30 ms: too short to report
    adc[(t >= 1.5) & (t < 1.9)] = 51.5  # 1.5 counts above zero: taut
    spans = identification.slack_spans(t, adc, zero_counts=50.0)
    assert spans == [pytest.approx((0.5, 0.799))]


def test_fft_peak_is_quoted_no_finer_than_its_window_resolves():
    assert identification._decimals(0.5) == 1  # 1 s window: half a bin is 0.5 Hz
    assert identification._decimals(0.05) == 2
    assert identification._decimals(5.0) == 0


def test_fig5_names_itself_the_pulse_and_the_virtual_rig():
    t = np.arange(0.0, 12.0, 0.001)
    adc = 300.0 - 250.0 * (t > 8.0)
    pulse = {"v_in_mm_s": 100.0, "x_f_mm": 10.0, "t_up_s": 1.0, "t_down_s": 8.0}
    fig = identification.fig5_force_response(t, adc, source="virtual-rig", pulse=pulse, zero_counts=50.0)
    title = fig.axes[0].get_title()
    assert title.startswith("Fig. 5 (virtual rig)") and "100 mm/s, 10 mm, up at 1 s, down at 8 s" in title
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert any("cable slack" in label for label in labels)


def test_fig_scenario_draws_a_recording_of_todays_format_and_marks_its_clipped_samples(tmp_path):
    # the driver records format 4 (the calibration one value per tendon, in lists), as a live cell of notebook
    # 04 does: its figure draws it as it draws the shipped format-1 recordings
    rig, _ = make_rig()
    with rig:
        path = rig.run_pulse(200, 20, path=tmp_path / "unshaped_v200_x20_r1", progress=False).path
    rec = recordings.load(path)
    assert rec.meta["schema_version"] == 4 and isinstance(rec.meta["calibration"]["offset_counts"], list)
    rec.frame.loc[rec.frame.index[5000:5007], "adc"] = 1023  # seven samples at the ADC's top: clipped
    fig = fig_scenario([rec], (200.0, 20.0))
    crosses = [line for line in fig.axes[0].get_lines() if line.get_label().startswith("clipped")]
    assert len(crosses) == 1 and len(crosses[0].get_xdata()) == 7
