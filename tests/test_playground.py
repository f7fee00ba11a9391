"""Notebook 03's interactive shaper study: physically sensible, quick enough to follow a slider, honest
about its inputs."""

import statistics
import time

import matplotlib
import pytest

import helpers
from helpers.identify import load_identification
from helpers.playground import SHAPERS, ShaperPlayground

matplotlib.use("Agg")


@pytest.fixture(scope="module")
def playground():
    mode = load_identification()
    return ShaperPlayground(mode.omega_d, mode.zeta)


def test_a_shaper_designed_for_the_mode_removes_it_on_the_linear_model(playground):
    study = playground.study(1.0, 0.0)
    assert study.residual_linear["unshaped"] > 30.0  # the unshaped move rings
    for name in SHAPERS:
        # ZV/ZVD cancel the design mode exactly and EI leaves at most its 5 % tolerance; only the higher modes
        # of the model and the 1 ms sampling remain
        assert study.residual_linear[name] < (5.5 if name == "ei" else 2.0), name


def test_robust_shapers_tolerate_a_wrong_frequency_better_than_zv(playground):
    study = playground.study(1.2, 0.0)
    assert study.residual_linear["zvd"] < study.residual_linear["zv"] / 2
    assert study.residual_linear["ei"] < study.residual_linear["zv"] / 2
    # the rig is nonlinear and its frequency moves with the deflection; shaping still helps there
    for name in SHAPERS:
        assert study.residual_rig[name] < study.residual_rig["unshaped"] / 2, name


def test_sliders_outside_their_range_are_refused(playground):
    with pytest.raises(ValueError, match="design_ratio"):
        playground.study(2.5, 0.0)
    with pytest.raises(ValueError, match="design damping"):
        playground.study(1.0, -0.1)


def test_each_update_after_the_first_takes_at_most_0_3_s_of_cpu(playground):
    """The issue's interactivity target, measured in CPU time of this process (not wall time, which other
    processes on a shared machine inflate); the update includes redrawing the figure."""
    playground.update(1.0, 0.0)  # the first draws the figure
    cpu = []
    for ratio, zeta_error in [(1.1, 0.0), (0.9, 0.02), (1.3, -0.02), (1.2, 0.05), (0.8, 0.0)]:
        start = time.process_time()
        playground.update(ratio, zeta_error)
        cpu.append(time.process_time() - start)
    print(f"update CPU time: median {statistics.median(cpu):.3f} s, max {max(cpu):.3f} s")
    assert statistics.median(cpu) <= 0.3


def test_batch_runs_are_not_interactive(monkeypatch):
    monkeypatch.setenv("HELPERS_BATCH", "1")
    assert helpers.interactive() is False
    monkeypatch.delenv("HELPERS_BATCH")
    assert helpers.interactive() is True
