"""The uncertainty model and the percentile-optimal shapers on the linear model."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from helpers.base.paths import STORED_TABLES_DIR
from helpers.paper.identify import IdentifiedMode
from helpers.paper.shapers import Shaper, zv, zvd
from helpers.research.modemap import ModeMap
from helpers.research.robustness import (
    at_duration,
    linear_residual_pct,
    load_designs,
    optimise_shaper,
    predicted_map,
    robust_designs,
    save_designs,
    tune_family,
    uncertainty_model,
)

IDENT = IdentifiedMode(omega_d=25.0, zeta=0.05, omega_d_std=0.0, zeta_std=0.0)


def constant_model(zeta_prior=(0.05, 0.05)):
    """One mode everywhere (25 rad/s damped), exact identification: the distribution is a point."""
    return uncertainty_model(ModeMap.constant(25.0, 0.05), IDENT, zeta_prior=zeta_prior)


def test_the_predicted_map_is_the_rig_as_it_runs_from_the_stored_table():
    with open(STORED_TABLES_DIR / "virtual_frequency_map.csv", newline="") as f:
        rows = {float(r["u_mm"]): r for r in csv.DictReader(f)}
    m = predicted_map()
    assert m.range_mm == (0.0, 35.0) and not m.has_second_mode
    for x in (0.0, 20.0, 35.0):
        assert m.at(x).omega_d == float(rows[x]["dominant_omega_d_rad_s"])
        assert m.at(x).zeta == float(rows[x]["dominant_zeta"])
    assert predicted_map(share2=0.1).has_second_mode


def test_the_sample_puts_up_moves_at_their_amplitude_and_down_moves_at_rest():
    model = uncertainty_model(predicted_map(), IDENT, zeta_prior=(0.02, 0.08))
    s = model.sample(200, seed=3)
    assert len(s) == 400 and list(s.move[:4]) == ["up", "down", "up", "down"]
    assert np.array_equal(s.position_mm[0::2], s.amplitude_mm) and np.all(s.position_mm[1::2] == 0)
    assert 10 <= s.amplitude_mm.min() and s.amplitude_mm.max() <= 30
    assert 0.02 <= s.zeta.min() and s.zeta.max() <= 0.08
    # no identification error (se 0): Down cases sit exactly at the map's rest frequency
    wd_down = s.omega_n[1::2] * np.sqrt(1 - s.zeta[1::2] ** 2)
    assert np.allclose(wd_down, predicted_map().at(0.0).omega_d, rtol=1e-12)
    again = model.sample(200, seed=3)
    assert np.array_equal(again.omega_n, s.omega_n)


def test_the_identification_error_spreads_the_frequency():
    ident = IdentifiedMode(omega_d=25.0, zeta=0.05, omega_d_std=0.25, zeta_std=0.0)  # 1 %
    s = uncertainty_model(ModeMap.constant(25.0, 0.05), ident).sample(512)
    assert model_sigma(s) == pytest.approx(0.01, rel=0.15)


def model_sigma(sample):
    return float(np.std(sample.identification_error))


def test_linear_residual_is_singer_and_seering_v_in_percent():
    s = constant_model().sample(8)
    assert np.allclose(linear_residual_pct(None, s), 100.0)
    omega_n = 25.0 / math.sqrt(1 - 0.05**2)
    assert np.allclose(linear_residual_pct(zv(omega_n, 0.05), s), 0.0, atol=1e-9)
    # undamped: ZV designed at 1.2 times the mode turns it by pi / 1.2 between its two equal impulses
    undamped = uncertainty_model(ModeMap.constant(25.0, 0.0), IDENT, zeta_prior=(0.0, 0.0)).sample(8)
    v = linear_residual_pct(zv(1.2 * 25.0, 0.0), undamped)
    assert np.allclose(v, 100 * abs(math.cos(math.pi / 2.4)), rtol=1e-12)


def test_tuning_a_family_finds_the_mode_of_a_point_distribution():
    t = tune_family("ZVD", constant_model().sample(16), reference_omega_d=23.0, zeta=0.05)
    assert t.omega_d == pytest.approx(25.0, rel=1e-4) and t.objective_pct < 1e-3
    assert t.name == "zvd-tuned" and t.family == "ZVD"


def test_the_duration_cap_of_a_tuned_family_holds():
    s = uncertainty_model(predicted_map(), IDENT).sample(64)
    t = tune_family("ZVD", s, 25.0, 0.05, max_duration_s=0.2)
    assert t.duration <= 0.2 + 1e-9


def test_the_optimiser_beats_its_starts_within_the_cap():
    model = uncertainty_model(predicted_map(), IDENT, zeta_prior=(0.02, 0.08))
    s = model.sample(32, seed=1)
    cap = zvd(25.0 / math.sqrt(1 - 0.05**2), 0.05).duration
    best = optimise_shaper(s, cap, 25.0, 0.05, n_impulses=3, max_iter=80)
    assert best.duration <= cap + 1e-12 and np.all(best.shaper.amplitudes > 0)
    assert best.shaper.amplitudes.sum() == pytest.approx(1.0)
    start = np.percentile(linear_residual_pct(zvd(25.0 / math.sqrt(1 - 0.05**2), 0.05), s), 95)
    assert best.objective_pct <= start
    tuned = tune_family("ZVD", s, 25.0, 0.05, max_duration_s=cap)
    assert best.objective_pct <= tuned.objective_pct + 1e-9 or best.objective_pct < 0.9 * start


def test_a_family_at_a_duration_keeps_its_shape_and_scales_its_frequency():
    s = uncertainty_model(predicted_map(), IDENT, zeta_prior=(0.03, 0.06)).sample(32)
    tuned = tune_family("2-hump EI", s, 25.0, 0.05)
    for target in (0.8 * tuned.duration, 1.25 * tuned.duration):  # compressed, stretched
        at = at_duration(tuned, target, s, 95.0, "robust")
        assert at.name == "2-hump-ei-at-robust" and at.family == "2-hump EI"
        assert at.duration == pytest.approx(target, rel=1e-12)
        assert np.allclose(at.shaper.amplitudes, tuned.shaper.amplitudes, rtol=1e-12)
        assert np.allclose(at.shaper.times * at.omega_d, tuned.shaper.times * tuned.omega_d, rtol=1e-12)
        assert at.objective_pct == pytest.approx(np.percentile(linear_residual_pct(at.shaper, s), 95))
    with pytest.raises(ValueError, match="not a family"):
        at_duration(optimise_shaper(s, 0.2, 25.0, 0.05, n_impulses=3, max_iter=5), 0.3, s, 95.0, "x")


@pytest.mark.slow
def test_a_longer_cap_never_hurts_and_the_design_set_round_trips(tmp_path):
    model = uncertainty_model(predicted_map(), IDENT, zeta_prior=(0.03, 0.06), amplitude_mm=(10.0, 20.0))
    designs = robust_designs(model, n_draws=48, families=("ZVD", "EI"), extra_families=(), max_iter=150)
    d = designs.designs
    at = {f"{f}-at-{r}" for f in ("zvd", "ei") for r in ("robust", "robust-short")}
    assert set(d) == {"zvd-tuned", "ei-tuned", "robust", "robust-short", *at}
    assert designs.equal_duration == {r: (f"zvd-at-{r}", f"ei-at-{r}") for r in ("robust", "robust-short")}
    for name in at:  # every compared family at each robust design's duration
        assert d[name].duration == pytest.approx(d[name.split("-at-")[1]].duration, rel=1e-12)
    # the longer cap starts from the shorter optimum too
    assert d["robust"].duration >= d["robust-short"].duration - 1e-12
    assert d["robust"].objective_pct <= d["robust-short"].objective_pct + 1e-9
    best = min(d["zvd-tuned"].objective_pct, d["ei-tuned"].objective_pct)
    assert d["robust"].objective_pct <= best + 1e-9
    path = save_designs(designs, tmp_path / "set.json")
    entries = load_designs(path)
    assert entries["ei-tuned"]["family"] == "EI" and "vtol" in entries["ei-tuned"]
    back = Shaper(np.array(entries["robust"]["amplitudes"]), np.array(entries["robust"]["times"]))
    assert back.allclose(d["robust"].shaper)
