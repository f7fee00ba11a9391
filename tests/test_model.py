"""Tests of helpers.paper.model: the paper's linear modal model (eqs. 1-13)."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest
from scipy import integrate, linalg

from helpers.paper import model
from helpers.paper import numbers as paper

CAL = model.FITTED


def _poly(tf: control.TransferFunction, part: str) -> np.ndarray:
    return np.atleast_1d(np.squeeze(getattr(tf, part)[0][0])).astype(float)


def _integrator_removed_gain(tf: control.TransferFunction) -> float:
    """lim_{s->0} s G(s) for a G with one pole at s = 0 (from the polynomial coefficients)."""
    num, den = _poly(tf, "num"), _poly(tf, "den")
    assert den[-1] == 0.0  # the free integrator: velocity in, displacement-like output
    return num[-1] / den[-2]


# --- roots
def test_roots_solve_the_frequency_equation():
    beta = model.cantilever_roots(4)
    assert np.all(np.abs(np.cos(beta) * np.cosh(beta) + 1.0) < 1e-10)
    # the scaled equation holds to machine precision for many more roots
    many = model.cantilever_roots(60)
    assert np.all(np.abs(np.cos(many) + 1.0 / np.cosh(many)) < 1e-13)
    assert np.all(np.diff(many) > 0)


def test_roots_match_the_paper_to_three_decimals():
    assert np.round(model.cantilever_roots(4), 3).tolist() == list(paper.BETA)


def test_high_roots_approach_the_asymptote():
    beta = model.cantilever_roots(12)
    asymptote = (2 * np.arange(1, 13) - 1) * np.pi / 2
    assert abs(beta[-1] - asymptote[-1]) < 1e-12
    assert abs(beta[0] - asymptote[0]) > 0.1  # the first root is not asymptotic


@pytest.mark.parametrize("bad", [0, -1, 2.5, True, "3"])
def test_roots_reject_bad_counts(bad):
    with pytest.raises(ValueError, match="positive integer"):
        model.cantilever_roots(bad)


# --- shapes
@pytest.mark.parametrize("n", [1, 2, 3, 4, 8])
def test_mode_shape_boundary_conditions(n):
    length = 0.24
    scale = (model.cantilever_roots(n)[-1] / length) ** np.arange(5)
    assert abs(model.mode_shape(0.0, n, length)) < 1e-12  # clamped: no displacement
    assert abs(model.mode_shape(0.0, n, length, 1)) < 1e-12 * scale[1]  # ... and no slope
    assert abs(model.mode_shape(length, n, length, 2)) < 1e-9 * scale[2]  # free: no moment
    assert abs(model.mode_shape(length, n, length, 3)) < 1e-9 * scale[3]  # ... and no shear
    assert model.mode_shape(length, n, length) == pytest.approx(1.0, abs=1e-12)  # tip-normalised


@pytest.mark.parametrize("n", [1, 2, 4])
def test_mode_shape_derivatives_are_consistent(n):
    length = 0.24
    x = np.linspace(0.02, 0.22, 7)
    h = 1e-6
    for k in range(4):
        finite_difference = (
            model.mode_shape(x + h, n, length, k) - model.mode_shape(x - h, n, length, k)
        ) / (2 * h)
        analytic = model.mode_shape(x, n, length, k + 1)
        scale = np.max(np.abs(analytic)) + 1.0
        assert np.max(np.abs(finite_difference - analytic)) < 1e-6 * scale
    # Euler-Bernoulli: phi'''' = (beta/L)^4 phi
    beta = model.cantilever_roots(n)[-1]
    np.testing.assert_allclose(
        model.mode_shape(x, n, length, 4), (beta / length) ** 4 * model.mode_shape(x, n, length), rtol=1e-8
    )


def test_modal_mass_is_a_quarter_of_the_total_by_integration():
    p = CAL
    for n in range(1, 5):
        integral, _ = integrate.quad(lambda x, n=n: model.mode_shape(x, n, p.L) ** 2, 0.0, p.L, epsabs=1e-14)
        assert p.mass_per_length * integral == pytest.approx(p.total_mass / 4.0, rel=1e-9)
    np.testing.assert_allclose(model.modal_masses(p), p.total_mass / 4.0)


def test_modes_are_orthogonal():
    for m, n in [(1, 2), (1, 4), (2, 3), (3, 4)]:
        val, _ = integrate.quad(
            lambda x, m=m, n=n: model.mode_shape(x, m) * model.mode_shape(x, n), 0.0, 1.0, epsabs=1e-13
        )
        assert abs(val) < 1e-9


def test_mode_shape_rejects_points_off_the_arm():
    with pytest.raises(ValueError, match="x must lie"):
        model.mode_shape([0.1, 0.3], 1, 0.24)
    with pytest.raises(ValueError, match="derivative"):
        model.mode_shape(0.1, 1, 0.24, derivative=5)


# --- coupling
def test_coupling_within_a_tenth_of_a_percent_of_the_paper():
    ours = np.abs(model.coupling_coefficients(4))
    np.testing.assert_allclose(ours, paper.K_L_OVER_R, rtol=1e-3)


def test_paper_coupling_values_come_from_the_rounded_roots():
    # with the printed 3-decimal roots the tip-normalised slope reproduces every printed digit
    rounded = model.coupling_coefficients(4, beta=paper.BETA)
    np.testing.assert_allclose(rounded, paper.K_L_OVER_R, atol=0.5e-4)
    # whereas the exact roots differ in the 4th digit for modes 2-4
    exact = model.coupling_coefficients(4)
    assert np.all(np.abs(exact[1:] - np.array(paper.K_L_OVER_R[1:])) > 1e-4)


def test_coupling_is_the_tip_slope_of_the_tip_normalised_mode():
    c = model.coupling_coefficients(4)
    slopes = np.array([model.mode_shape(1.0, n, 1.0, derivative=1) for n in range(1, 5)])
    np.testing.assert_allclose(c, slopes, rtol=1e-12)
    assert np.all(c > 0)  # sign convention phi_n(L) = +1
    # high modes: tip slope -> beta_n / L
    many = model.cantilever_roots(10)
    assert abs(model.coupling_coefficients(10)[-1] / many[-1] - 1.0) < 1e-6


# --- parameters
@pytest.mark.parametrize(
    "field,value", [("d", -1e-3), ("L", 0.0), ("E", float("nan")), ("zeta", 1.2), ("k", 0.0), ("n_modes", 0)]
)
def test_parameters_reject_nonsense(field, value):
    with pytest.raises(ValueError, match=field):
        model.ArmParameters().replace(**{field: value})


def test_parameters_derived_quantities():
    p = model.ArmParameters()
    assert p.EI == pytest.approx(p.E * math.pi * p.d**4 / 64)
    assert p.total_mass == pytest.approx(p.rho * math.pi * p.d**2 / 4 * p.L + p.n_discs * p.disc_mass)
    w = model.modal_frequencies(p)
    beta = model.cantilever_roots(4)
    np.testing.assert_allclose(w / w[0], beta**2 / beta[0] ** 2)
    # heavier arm -> lower frequencies, as 1/sqrt(m)
    heavy = p.replace(disc_mass=4 * p.disc_mass + 3 * p.rod_mass / p.n_discs)
    np.testing.assert_allclose(model.modal_frequencies(heavy), w / 2)


def test_default_parameters_are_the_rounded_calibration():
    p = model.ArmParameters()
    for field in ("r", "k", "zeta"):
        assert getattr(p, field) == pytest.approx(getattr(CAL, field), rel=5e-3)


# --- damping
def test_rayleigh_gives_zeta_exactly_on_modes_one_and_two():
    p = model.ArmParameters(zeta=0.037)
    ratios = model.modal_damping_ratios(p)
    np.testing.assert_allclose(ratios[:2], 0.037, rtol=1e-12)
    assert np.all(ratios[2:] > 0.037)  # stiffness-proportional part dominates above omega_2
    w = model.modal_frequencies(p)
    assert np.all(ratios[2:] > 0.037 * w[2:] / (w[0] + w[1]))


def test_rayleigh_coefficients_reject_bad_input():
    with pytest.raises(ValueError, match="omega"):
        model.rayleigh_coefficients(-1.0, 2.0, 0.05)


# --- transfer functions
@pytest.mark.parametrize("n_modes", [1, 2, 3, 4])
def test_model_order_is_2n_plus_1(n_modes):
    p = CAL.replace(n_modes=n_modes)
    tension, tip = model.transfer_functions(p)
    assert model.model_order(tension) == 2 * n_modes + 1
    assert model.model_order(tip) == 2 * n_modes + 1
    assert len(model.poles(p)) == 2 * n_modes + 1
    # the state-space realisation is minimal: PBH rank test at every eigenvalue
    sys_ = model.state_space(p)
    for lam in linalg.eigvals(sys_.A):
        n = sys_.A.shape[0]
        ctrb = np.hstack([sys_.A - lam * np.eye(n), sys_.B])
        obsv = np.vstack([sys_.A - lam * np.eye(n), sys_.C[:1]])
        for mat in (ctrb, obsv):
            s = linalg.svdvals(mat)
            assert s[n - 1] > 1e-9 * s[0]


def test_model_order_counts_cancellations():
    g = control.tf([1.0, 3.0], [1.0, 4.0, 3.0])  # (s+3)/((s+1)(s+3))
    assert model.model_order(g) == 1


def test_transfer_functions_agree_with_the_state_space():
    tension, tip = model.transfer_functions(CAL)
    sys_ = model.state_space(CAL)
    for w in (0.3, 10.0, 25.0, 111.0, 500.0, 2000.0):
        s = 1j * w
        g = sys_.C @ np.linalg.solve(s * np.eye(sys_.A.shape[0]) - sys_.A, sys_.B)
        assert complex(tension(s)) == pytest.approx(complex(g[0, 0]), rel=1e-8)
        assert complex(tip(s)) == pytest.approx(complex(g[1, 0]), rel=1e-8)


def test_transfer_function_matches_equation_11_pointwise():
    p = CAL
    tension, tip = model.transfer_functions(p)
    w, m = model.modal_frequencies(p), model.modal_masses(p)
    c, big_k = model.modal_damping(p), model.coupling(p)
    for s in (2.0 + 5.0j, 0.5j, 40.0 + 300.0j):
        d = m * s**2 + c * s + m * w**2
        denom = s * (1.0 / p.k + np.sum(big_k**2 / d))
        assert complex(tension(s)) == pytest.approx(1.0 / denom, rel=1e-9)
        assert complex(tip(s)) == pytest.approx(np.sum(big_k / d) / denom, rel=1e-9)


def test_strictly_proper_for_finite_k():
    tension, tip = model.transfer_functions(CAL)
    assert model.relative_degree(tension) == 1
    assert model.relative_degree(tip) == 3


def test_tension_improper_for_inextensible_cable():
    p = CAL.replace(k=np.inf)
    tension, tip = model.transfer_functions(p)
    assert model.relative_degree(tension) == -1  # improper, as the paper says
    assert model.relative_degree(tip) == 1
    assert len(model.poles(p)) == 2 * p.n_modes - 1
    with pytest.raises(ValueError, match="finite cable stiffness"):
        model.state_space(p)


def test_stiff_cable_converges_to_the_limit_and_one_pole_pair_escapes():
    limit = model.poles(CAL.replace(k=np.inf))
    stiff = model.poles(CAL.replace(k=1e9))
    np.testing.assert_allclose(stiff[: len(limit)], limit, rtol=1e-4, atol=1e-6)
    assert np.min(np.abs(stiff[len(limit) :])) > 50 * np.max(np.abs(limit))
    # the escaping pair grows with k
    top = [np.max(np.abs(model.poles(CAL.replace(k=k)))) for k in (1e3, 1e5, 1e7)]
    assert top[0] < top[1] < top[2]


def test_residues_match_partial_fractions_of_the_polynomials():
    tension, _ = model.transfer_functions(CAL)
    num, den = _poly(tension, "num"), _poly(tension, "den")
    p, r = model.tension_residues(CAL)
    for pi, ri in zip(p, r, strict=True):
        expected = np.polyval(num, pi) / np.polyval(np.polyder(den), pi)
        assert abs(ri - expected) <= 1e-6 * abs(expected) + 1e-9


# --- statics
def test_static_gains_match_the_modal_sums():
    p = CAL
    beta = model.cantilever_roots(p.n_modes)
    c = model.coupling_coefficients(p.n_modes)
    # independent route: K_n = r c_n / L, k_n = (m/4) beta_n^4 EI / (m L^3) = beta_n^4 EI / (4 L^3)
    big_k = p.r * c / p.L
    kn = beta**4 * p.EI / (4 * p.L**3)
    tension_gain = 1.0 / (1.0 / p.k + np.sum(big_k**2 / kn))
    tip_gain = np.sum(big_k / kn) * tension_gain
    tension, tip = model.transfer_functions(p)
    assert _integrator_removed_gain(tension) == pytest.approx(tension_gain, rel=1e-9)
    assert _integrator_removed_gain(tip) == pytest.approx(tip_gain, rel=1e-9)
    assert model.static_tension_gain(p) == pytest.approx(tension_gain, rel=1e-12)
    assert model.static_tip_gain(p) == pytest.approx(tip_gain, rel=1e-12)


def test_many_modes_converge_to_beam_statics():
    # pure tip moment lambda r: tip slope lambda r L / EI, tip deflection lambda r L^2 / (2 EI)
    p = CAL.replace(n_modes=300, k=np.inf)
    assert model.static_tip_gain(p) == pytest.approx(p.L / (2 * p.r), rel=3e-3)
    assert model.static_tension_gain(p) == pytest.approx(p.EI / (p.r**2 * p.L), rel=3e-3)
    finite = CAL.replace(n_modes=300)
    arm = p.EI / (finite.r**2 * finite.L)
    assert model.static_tension_gain(finite) == pytest.approx(1 / (1 / finite.k + 1 / arm), rel=3e-3)


def test_thirty_mm_of_cable_gives_about_half_a_metre_of_tip():
    assert model.static_tip_gain(CAL) * 0.030 == pytest.approx(0.5, rel=0.02)
    assert 3e-3 < CAL.r < 10e-3  # a cable offset of a few mm, as the discs allow


# --- dominant mode
@pytest.mark.parametrize("k", [300.0, 1e3, CAL.k, 1e4, 1e5])
@pytest.mark.parametrize("n_modes", [2, 3, 4])
def test_dominant_pole_lies_between_the_first_two_modal_frequencies(k, n_modes):
    p = CAL.replace(k=k, n_modes=n_modes)
    w = model.modal_frequencies(p)
    dom = model.dominant_mode(p)
    assert w[0] < dom.omega_n < w[1]
    assert dom.omega_d == pytest.approx(dom.omega_n * math.sqrt(1 - dom.zeta**2), rel=1e-12)
    # it is the slowest-decaying oscillatory pair, and the lowest in frequency
    oscillatory = model.poles(p)[model.poles(p).imag > 0]
    assert -dom.pole.real == pytest.approx(np.min(-oscillatory.real), rel=1e-12)
    assert dom.omega_n == pytest.approx(np.min(np.abs(oscillatory)), rel=1e-12)


def test_calibrated_dominant_pair_also_has_the_largest_velocity_step_amplitude():
    p, r = model.tension_residues(CAL)
    upper = p.imag > 0
    largest = p[upper][np.argmax(np.abs(r[upper] / p[upper]))]
    assert largest == pytest.approx(model.dominant_mode(CAL).pole, rel=1e-12)


def test_calibrated_dominant_mode_is_the_identified_one():
    dom = model.dominant_mode(CAL)
    assert dom.omega_d == pytest.approx(paper.OMEGA_D, rel=5e-3)
    assert dom.zeta == pytest.approx(paper.ZETA, rel=5e-3)
    assert CAL.disc_mass == model.FIXED_DISC_MASS
    assert 1e3 <= CAL.k <= 1e4  # a plausible cable + load-cell stiffness


# --- simulation
def test_pulse_response_settles_at_the_static_tension():
    t = np.arange(0.0, 6.0, 1e-3)
    v = np.where((t >= 1.0) & (t < 1.1), 0.2, 0.0)  # 200 mm/s for 0.1 s: 20 mm
    tension, tip = model.linear_response(CAL, t, v)
    assert tension[0] == 0.0
    assert tension[-1] == pytest.approx(model.static_tension_gain(CAL) * 0.02, rel=1e-3)
    assert tip[-1] == pytest.approx(model.static_tip_gain(CAL) * 0.02, rel=1e-3)
    assert np.max(tension) > 1.2 * tension[-1]  # an unshaped pulse overshoots


def test_simulate_rejects_mismatched_input():
    with pytest.raises(ValueError, match="equal length"):
        model.linear_response(CAL, np.arange(3.0), np.zeros(4))


def test_parameter_table_covers_every_field():
    import dataclasses

    table = model.parameter_table(CAL)
    for field in dataclasses.fields(model.ArmParameters):
        assert table.loc[field.name, "value"] == pytest.approx(float(getattr(CAL, field.name)))
        assert table.loc[field.name, "unit"]


def test_shaped_pulses_leave_no_residual_vibration_in_the_calibrated_model():
    from helpers.plotting.model import shaping_response

    resp = shaping_response(CAL, v_in_mm_s=200.0, x_f_mm=20.0, t_end=10.0)
    final = model.static_tension_gain(CAL) * 0.020
    hold = (resp.t > 2.0) & (resp.t < 7.9)  # from 0.5 s after the shaped moves end
    swing = {name: np.ptp(tension[hold]) for name, tension in resp.tension.items()}
    assert swing["unshaped"] > 0.05 * final
    assert swing["zv"] < 1e-3 * swing["unshaped"]  # designed on the calibrated dominant mode
    assert swing["zvd"] < 1e-3 * swing["unshaped"]
    for tension in resp.tension.values():
        assert tension[hold][-1] == pytest.approx(final, rel=2e-3)
