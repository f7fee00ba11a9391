"""Notebook 03's interactive shaper study: physically sensible, quick enough to follow a slider, honest
about its inputs."""

import matplotlib
import pytest

import helpers
from helpers.paper.identify import load_identification
from helpers.research.playground import SHAPERS, ShaperPlayground

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


def test_an_update_redraws_the_same_figure_with_the_new_study(playground):
    """The slider's path: the first update draws the figure, the next ones redraw it in place with the new
    study's numbers (their CPU time is `python -m helpers bench playground`'s figure, never asserted here)."""
    playground.update(1.0, 0.0)
    fig = playground.fig
    heights = [[b.get_height() for b in bars] for bars in playground._bars.values()]
    study = playground.update(1.3, -0.02)
    assert playground.fig is fig
    after = [[b.get_height() for b in bars] for bars in playground._bars.values()]
    assert after != heights
    linear = dict(zip(SHAPERS, [b.get_height() for b in playground._bars["linear"]], strict=True))
    assert linear == {name: study.residual_linear[name] for name in SHAPERS}


def test_batch_runs_are_not_interactive(monkeypatch):
    monkeypatch.setenv("HELPERS_BATCH", "1")
    assert helpers.interactive() is False
    monkeypatch.delenv("HELPERS_BATCH")
    assert helpers.interactive() is True
