"""Tests of helpers.paper.shapers against the paper's closed form and the input-shaping literature."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers.paper import modes, shapers
from helpers.paper import numbers as paper
from helpers.paper.shapers import Shaper
from helpers.research import families

OMEGA = 2 * math.pi * 4.0  # an arbitrary design frequency (rad/s)

ALL = list(families.FAMILIES.items())
EI_TYPES = {"EI", "2-hump EI", "3-hump EI"}


def _damped_period(omega_n, zeta):
    return 2 * math.pi / (omega_n * math.sqrt(1 - zeta**2))


# -- the paper's two TDFs --------------------------------------------------------------------------
def test_nonrobust_tdf_matches_paper_closed_form():
    zeta, omega_d = 0.044, 25.085
    x = zeta * math.pi / math.sqrt(1 - zeta**2)
    a0 = math.exp(x) / (1 + math.exp(x))
    nonrobust, _ = shapers.design_tdfs(omega_d, zeta)
    assert nonrobust.amplitudes[0] == pytest.approx(a0, abs=1e-12)
    assert nonrobust.amplitudes[1] == pytest.approx(1 - a0, abs=1e-12)
    assert nonrobust.times[1] == pytest.approx(math.pi / omega_d, abs=1e-12)
    # to the digits the paper prints
    assert f"{nonrobust.amplitudes[0]:.4f}" == "0.5345"
    assert f"{nonrobust.amplitudes[1]:.4f}" == "0.4655"
    assert f"{nonrobust.times[1]:.5f}" == "0.12524"


def test_design_tdfs_defaults_are_the_papers_values():
    nonrobust, robust = shapers.design_tdfs()
    a0, a1 = nonrobust.amplitudes
    assert (round(a0, 4), round(a1, 4)) == (paper.ZV_A0, paper.ZV_A1)
    assert round(nonrobust.times[1], 5) == paper.ZV_T
    assert tuple(round(a, 4) for a in robust.amplitudes) == paper.ZVD_AMPLITUDES
    np.testing.assert_allclose(robust.times, [0, paper.ZV_T, 2 * paper.ZV_T], atol=1e-5)


def test_robust_tdf_is_the_square_of_the_nonrobust():
    nonrobust, robust = shapers.design_tdfs()
    squared = nonrobust * nonrobust
    assert len(squared) == 3  # the two impulses at T merged
    assert squared.allclose(robust)
    omega_n = modes.omega_n_from_damped(paper.OMEGA_D, paper.ZETA)
    assert robust.allclose(shapers.zvd(omega_n, paper.ZETA), rtol=1e-12)


def test_design_tdfs_names_match_the_papers_systems():
    zv, zvd = shapers.design_tdfs(20.0, 0.05)
    assert zv.times[1] == pytest.approx(math.pi / 20.0)  # omega_d first, then zeta
    assert (zv.name, zvd.name) == ("zv", "zvd")
    assert set(paper.SYSTEMS) >= {zv.name, zvd.name}


def test_omega_n_from_damped():
    assert modes.omega_n_from_damped(25.085, 0.044) * math.sqrt(1 - 0.044**2) == pytest.approx(25.085)
    with pytest.raises(ValueError, match="zeta"):
        modes.omega_n_from_damped(25.0, 1.0)
    with pytest.raises(ValueError, match="omega_d"):
        modes.omega_n_from_damped(-1.0, 0.1)


# -- zero vibration at the design point ------------------------------------------------------------
@pytest.mark.parametrize("zeta", [0.0, 0.044, 0.1, 0.2])
@pytest.mark.parametrize(("name", "family"), ALL)
def test_design_point_vibration(name, family, zeta):
    s = family(OMEGA, zeta)
    v = s.vibration(OMEGA, zeta)
    if name == "EI" or name == "3-hump EI":
        # by definition V = V_tol at the design point (Singhose's fits hit it to within ~10 %)
        assert v == pytest.approx(0.05, abs=0.006)
    elif name == "2-hump EI":
        # the two-hump EI has its zero at the design point and a hump of V_tol either side
        assert v < 0.005
    else:
        assert v < 1e-9


def test_unit_impulse_has_unit_vibration():
    v = Shaper.unit().sensitivity(OMEGA, 0.05, np.linspace(0.1, 3, 50))
    np.testing.assert_allclose(v, 1.0, atol=1e-12)


def test_vibration_is_vectorised_and_scalar_for_scalars():
    s = shapers.zv(OMEGA, 0.05)
    assert isinstance(s.vibration(OMEGA, 0.05), float)
    w = np.linspace(1, 60, 7)
    np.testing.assert_allclose(s.vibration(w, 0.05), [s.vibration(x, 0.05) for x in w])


def test_zv_sensitivity_closed_form_undamped():
    # For zeta = 0 the ZV shaper leaves V = |cos(pi r / 2)|.
    r = np.linspace(0, 2, 101)
    v = shapers.zv(OMEGA, 0.0).sensitivity(OMEGA, 0.0, r)
    np.testing.assert_allclose(v, np.abs(np.cos(np.pi * r / 2)), atol=1e-12)


# -- robustness: 5 % insensitivity against the literature ----------------------------------------------------
@pytest.mark.parametrize(
    ("name", "width"),
    [("ZV", 0.06), ("ZVD", 0.29), ("EI", 0.40), ("2-hump EI", 0.73), ("3-hump EI", 0.97)],
)
def test_insensitivity_widths_match_literature(name, width):
    s = families.FAMILIES[name](OMEGA, 0.0)
    low, high, measured = s.insensitivity(OMEGA, 0.0, vtol=0.05)
    assert measured == pytest.approx(width, abs=0.015)
    assert low < 1.0 < high


def test_insensitivity_orders_the_families():
    widths = [families.FAMILIES[n](OMEGA, 0.044).insensitivity(OMEGA, 0.044)[2] for n in
              ("ZV", "MZV", "ZVD", "ZVDD")]
    assert widths == sorted(widths)


@pytest.mark.parametrize(
    ("name", "periods"),
    [("ZV", 0.5), ("ZVD", 1.0), ("ZVDD", 1.5), ("MZV", 0.75), ("UM-ZV", 1 / 3)],
)
@pytest.mark.parametrize("zeta", [0.0, 0.044, 0.15])
def test_durations_in_damped_periods(name, periods, zeta):
    s = families.FAMILIES[name](OMEGA, zeta)
    tol = 0.01 if name == "UM-ZV" else 1e-12  # UM-ZV lengthens slightly with damping
    assert s.duration / _damped_period(OMEGA, zeta) == pytest.approx(periods, abs=tol)


@pytest.mark.parametrize(("name", "periods"), [("EI", 1.0), ("2-hump EI", 1.5), ("3-hump EI", 2.0)])
def test_ei_durations_in_periods(name, periods):
    s = families.FAMILIES[name](OMEGA, 0.0)
    assert s.duration / (2 * math.pi / OMEGA) == pytest.approx(periods, abs=1e-3)


# -- agreement with the published closed forms (zeta = 0) and firmware conventions -----------------
def test_ei_undamped_closed_form():
    v = 0.05
    s = families.ei(OMEGA, 0.0, vtol=v)
    period = 2 * math.pi / OMEGA
    np.testing.assert_allclose(s.amplitudes, [(1 + v) / 4, (1 - v) / 2, (1 + v) / 4], atol=1e-3)
    np.testing.assert_allclose(s.times, [0, period / 2, period], atol=1e-3 * period)


def test_two_hump_ei_undamped_closed_form():
    v = 0.05
    x = (v**2 * (math.sqrt(1 - v**2) + 1)) ** (1 / 3)
    a1 = (3 * x**2 + 2 * x + 3 * v**2) / (16 * x)
    s = families.multi_hump_ei(OMEGA, 0.0, humps=2)
    np.testing.assert_allclose(s.amplitudes, [a1, 0.5 - a1, 0.5 - a1, a1], atol=1.5e-3)
    np.testing.assert_allclose(s.times / (2 * math.pi / OMEGA), [0, 0.5, 1, 1.5], atol=3e-3)  # fit accuracy


def test_three_hump_ei_undamped_closed_form():
    v = 0.05
    a1 = (1 + 3 * v + 2 * math.sqrt(2 * v * (v + 1))) / 16
    a2 = (1 - v) / 4
    s = families.multi_hump_ei(OMEGA, 0.0, humps=3)
    np.testing.assert_allclose(s.amplitudes, [a1, a2, 1 - 2 * (a1 + a2), a2, a1], atol=1e-3)
    periods = s.times / (2 * math.pi / OMEGA)
    np.testing.assert_allclose(periods, [0, 0.5, 1, 1.5, 2], atol=2e-3)  # the fit's accuracy


@pytest.mark.parametrize("zeta", [0.0, 0.044, 0.1])
def test_mzv_matches_firmware_formula(zeta):
    # Klipper parameterisation: undamped frequency in Hz, spacing in damped periods, unnormalised amplitudes.
    f = OMEGA / (2 * math.pi)
    df = math.sqrt(1 - zeta**2)
    k = math.exp(-0.75 * zeta * math.pi / df)
    t_d = 1 / (f * df)
    a = np.array([1 - 1 / math.sqrt(2), (math.sqrt(2) - 1) * k, (1 - 1 / math.sqrt(2)) * k * k])
    s = families.mzv(OMEGA, zeta)
    np.testing.assert_allclose(s.amplitudes, a / a.sum(), rtol=1e-12)
    np.testing.assert_allclose(s.times, [0, 0.375 * t_d, 0.75 * t_d], rtol=1e-12)


@pytest.mark.parametrize("zeta", [0.0, 0.044, 0.1])
def test_zv_zvd_match_firmware_formula(zeta):
    f = OMEGA / (2 * math.pi)
    df = math.sqrt(1 - zeta**2)
    k = math.exp(-zeta * math.pi / df)
    t_d = 1 / (f * df)
    zv, zvd = shapers.zv(OMEGA, zeta), shapers.zvd(OMEGA, zeta)
    np.testing.assert_allclose(zv.amplitudes, np.array([1, k]) / (1 + k), rtol=1e-12)
    np.testing.assert_allclose(zv.times, [0, 0.5 * t_d], rtol=1e-12)
    np.testing.assert_allclose(zvd.amplitudes, np.array([1, 2 * k, k * k]) / (1 + k) ** 2, rtol=1e-12)
    np.testing.assert_allclose(zvd.times, [0, 0.5 * t_d, t_d], rtol=1e-12)


def test_ei_times_close_to_firmware_damped_period_convention():
    # Klipper spaces EI in damped periods, we (like Singhose's fit) in undamped ones: 0.1 % apart here.
    zeta = 0.044
    s = families.ei(OMEGA, zeta)
    assert s.duration * OMEGA / (2 * math.pi) == pytest.approx(1.0, abs=1e-12)
    assert s.duration / _damped_period(OMEGA, zeta) == pytest.approx(1.0, abs=1.5e-3)


def test_three_tap_with_half_period_is_zvd():
    zeta = 0.07
    omega_d = OMEGA * math.sqrt(1 - zeta**2)
    assert families.three_tap(OMEGA, zeta, math.pi / omega_d).allclose(shapers.zvd(OMEGA, zeta), rtol=1e-12)


@pytest.mark.parametrize("delay_frac", [0.2, 0.5, 0.9])
def test_three_tap_cancels_mode_for_any_delay(delay_frac):
    zeta = 0.044
    s = families.three_tap(OMEGA, zeta, delay_frac * math.pi / OMEGA)
    assert s.vibration(OMEGA, zeta) < 1e-12


def test_um_zv_is_unity_magnitude():
    s = families.um_zv(OMEGA, 0.044)
    np.testing.assert_array_equal(s.amplitudes, [1, -1, 1])
    undamped = families.um_zv(OMEGA, 0.0)
    np.testing.assert_allclose(undamped.times / (2 * math.pi / OMEGA), [0, 1 / 6, 1 / 3], atol=1e-10)


def test_multihump_refuses_other_tolerances_and_hump_counts():
    with pytest.raises(ValueError, match="vtol"):
        families.multi_hump_ei(OMEGA, 0.05, vtol=0.1)
    with pytest.raises(ValueError, match="humps"):
        families.multi_hump_ei(OMEGA, 0.05, humps=4)


# -- hypothesis properties -----------------------------------------------------------------------------------
@settings(max_examples=60, deadline=None)
@given(
    name=st.sampled_from(list(families.FAMILIES)),
    omega=st.floats(1.0, 500.0),
    zeta=st.floats(0.0, 0.3),
)
def test_amplitudes_sum_to_one_and_times_sorted(name, omega, zeta):
    s = families.FAMILIES[name](omega, zeta)
    assert abs(s.amplitudes.sum() - 1) < 1e-9
    assert s.times[0] == 0
    assert np.all(np.diff(s.times) >= 0)
    if name != "UM-ZV":
        assert np.all(s.amplitudes > 0)


@settings(max_examples=40, deadline=None)
@given(
    a=st.sampled_from(list(families.FAMILIES)),
    b=st.sampled_from(list(families.FAMILIES)),
    wa=st.floats(2.0, 80.0),
    wb=st.floats(2.0, 80.0),
    zeta=st.floats(0.0, 0.3),
    w_eval=st.floats(0.5, 150.0),
)
def test_convolution_multiplies_vibrations(a, b, wa, wb, zeta, w_eval):
    sa, sb = families.FAMILIES[a](wa, zeta), families.FAMILIES[b](wb, zeta)
    prod = sa * sb
    assert prod.vibration(w_eval, zeta) == pytest.approx(
        sa.vibration(w_eval, zeta) * sb.vibration(w_eval, zeta), rel=1e-7, abs=1e-10
    )
    assert prod.duration == pytest.approx(sa.duration + sb.duration)


def test_multi_mode_cancels_every_mode():
    modes = [(25.0, 0.044), (90.0, 0.02)]
    s = families.multi_mode(modes, shapers.zvd)
    for w, z in modes:
        assert s.vibration(w, z) < 1e-9
    assert len(s) == 9
    with pytest.raises(ValueError, match="mode"):
        families.multi_mode([])


# -- applying a shaper to a sampled command ------------------------------------------------------------------
def test_apply_unit_step_gives_staircase():
    dt = 1e-3
    t = np.arange(0, 1, dt)
    u = (t >= 0.1).astype(float)
    s = Shaper(np.array([0.2, 0.5, 0.3]), np.array([0.0, 0.05, 0.12]), "staircase")
    y = s.apply(t, u)
    expected = np.select([t < 0.1 - dt / 2, t < 0.15 - dt / 2, t < 0.22 - dt / 2], [0.0, 0.2, 0.7], 1.0)
    np.testing.assert_allclose(y, expected, atol=1e-12)


def test_apply_interpolates_off_grid_delays():
    t = np.arange(0, 1, 0.01)
    u = t.copy()  # a ramp: the shaped ramp is delayed by sum A_i t_i
    s = Shaper(np.array([0.5, 0.5]), np.array([0.0, 0.0349]), "offgrid")
    y = s.apply(t, u)
    late = t > 0.05
    np.testing.assert_allclose(y[late], t[late] - 0.5 * 0.0349, atol=1e-12)


def test_apply_holds_initial_value_and_preserves_constant():
    t = np.linspace(0, 1, 101)
    y = shapers.zvd(20.0, 0.05).apply(t, np.full_like(t, 3.0))
    np.testing.assert_allclose(y, 3.0)
    with pytest.raises(ValueError, match="length"):
        Shaper.unit().apply(t, t[:-1])


# -- validation ------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("amps", "times", "message"),
    [
        ([0.5, 0.5], [0.0], "length"),
        ([0.5, 0.5], [0.0, float("nan")], "finite"),
        ([0.5, 0.5], [0.1, 0.2], "times\\[0\\]"),
        ([0.3, 0.3, 0.4], [0.0, 0.2, 0.1], "non-decreasing"),
        ([0.5, 0.6], [0.0, 0.1], "sum to 1"),
        ([], [], "at least one"),
    ],
)
def test_shaper_validation(amps, times, message):
    with pytest.raises(ValueError, match=message):
        Shaper(np.array(amps, dtype=float), np.array(times, dtype=float), "bad")


def test_shaper_is_immutable():
    s = shapers.zv(10.0, 0.1)
    with pytest.raises(ValueError):
        s.amplitudes[0] = 1.0


@pytest.mark.parametrize(("omega", "zeta"), [(0.0, 0.1), (float("nan"), 0.1), (10.0, -0.1), (10.0, 1.0)])
def test_constructors_refuse_bad_modes(omega, zeta):
    for family in families.FAMILIES.values():
        with pytest.raises(ValueError):
            family(omega, zeta)


def test_impulse_table():
    s = shapers.zvd(10.0, 0.05)
    table = s.impulse_table()
    assert list(table.columns) == ["time_s", "amplitude", "cumulative"]
    assert table["cumulative"].iloc[-1] == pytest.approx(1.0)
    np.testing.assert_array_equal(table["time_s"], s.times)
