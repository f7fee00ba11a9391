"""Tests of helpers.research.model_fit: the linear model's unknowns solved from the identified mode.

The core keeps the fit's result as data (``helpers.paper.model.FITTED``); here the fit is run again and must
reproduce those stored values.
"""

from __future__ import annotations

import pytest

from helpers.paper import model
from helpers.paper import numbers as paper
from helpers.research import model_fit


def test_the_fit_reproduces_the_stored_fitted_model():
    refit = model_fit.fit_to_mode()
    stored = model.FITTED
    message = f"store in helpers.paper.model.FITTED: r={refit.r!r}, k={refit.k!r}, zeta={refit.zeta!r}"
    for field in ("r", "k", "zeta"):
        assert getattr(refit, field) == pytest.approx(getattr(stored, field), rel=1e-9), message
    assert refit.replace(r=stored.r, k=stored.k, zeta=stored.zeta) == stored  # every other field as stored


def test_the_stored_fitted_model_meets_the_fit_conditions():
    dom = model.dominant_mode(model.FITTED)
    assert dom.omega_d == pytest.approx(paper.OMEGA_D, rel=1e-9)
    assert dom.zeta == pytest.approx(paper.ZETA, rel=1e-9)
    assert model.static_tip_gain(model.FITTED) * model_fit.U_REF == pytest.approx(model_fit.Y_REF, rel=1e-9)


def test_calibration_hits_other_targets_too():
    p = model_fit.fit_to_mode(model.ArmParameters(disc_mass=1.2e-3), omega_d=24.0, zeta=0.03)
    dom = model.dominant_mode(p)
    assert dom.omega_d == pytest.approx(24.0, rel=1e-6)
    assert dom.zeta == pytest.approx(0.03, rel=1e-6)
    assert model.static_tip_gain(p) * model_fit.U_REF == pytest.approx(model_fit.Y_REF, rel=1e-6)


@pytest.mark.parametrize("disc_mass", [0.1e-3, 3e-3])
def test_calibration_refuses_an_infeasible_disc_mass(disc_mass):
    with pytest.raises(ValueError, match="disc mass"):
        model_fit.fit_to_mode(model.ArmParameters(disc_mass=disc_mass))
