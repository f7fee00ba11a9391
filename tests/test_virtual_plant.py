"""Validation of the virtual rig's physics against independent oracles.

Oracles: convergence in resolution at large deflection (a 4x finer rod), constant-curvature statics of a rod
pulled by a frictionless cable, the Euler-Bernoulli cantilever's frequencies, the paper's linear modal model
(``helpers.paper.model``) built from the same parameters, conservation of energy without damping, a separately
written dense-Lagrangian implementation (``helpers.virtual.reference``: right-hand side and solve_ivp), the
stepper's torque law, and the paper's identified mode through the project's own identification code.
"""

import math

import numpy as np
import pytest

from helpers.paper import model
from helpers.paper import numbers as paper
from helpers.virtual import (
    ArcChain,
    ArmPlant,
    LoadCell,
    RigParameters,
    equilibrium,
    frequency_map,
    linearise,
    simulate,
)
from helpers.virtual import _kernel as kern
from helpers.virtual.reference import ReferenceArm
from helpers.virtual.statics import equilibrium_at_tension, model_arrays
from helpers.virtual.studies import SENSITIVITY_VARIANTS, _variant, actuator_sensitivity
from rigs import SHIPPED

CAL = RigParameters().with_integrator("rk4")  # the explicit kernel (the implicit step: test_integrators)
MM_PER_STEP = SHIPPED["paper"].mm_per_step  # the paper's cable per step, by hand (tests/rigs.py)
UNDAMPED = {"alpha": 0.0, "beta_chord": 0.0, "floor_zeta": 0.0, "rotor_zeta": 0.0, "carriage_zeta": 0.0}


def pulse_steps(v_mm_s: float, x_mm: float, t_up: float, t_down: float) -> tuple[np.ndarray, np.ndarray]:
    """Step times and signs of an up/down velocity pulse (independent of helpers.paper.profiles)."""
    n = round(x_mm / MM_PER_STEP)
    dt = MM_PER_STEP / v_mm_s
    up = t_up + dt * np.arange(1, n + 1)
    down = t_down + dt * np.arange(1, n + 1)
    return np.concatenate([up, down]), np.concatenate([np.ones(n), -np.ones(n)])


# --- convergence in resolution, at large deflection -------------------------------------------------------
U_MM = (0.0, 10.0, 20.0, 30.0, 40.0)


@pytest.fixture(scope="module")
def convergence():
    """Frequency maps of the rig (1 arc per disc interval) and of a 4x finer rod, same parameters; and the
    same two without the bowing between eyelets (the plain arc chain)."""
    maps = {m: frequency_map(CAL.replace(elements_per_disc=m), np.array(U_MM)) for m in (1, 4)}
    for m in (1, 4):
        maps["plain", m] = frequency_map(CAL.replace(elements_per_disc=m, bowing=False), np.array([40.0]))
    return maps


@pytest.mark.slow  # the convergence study (notebook 06 prints and nbval checks the same table)
def test_static_tension_converged_within_1_percent_up_to_40_mm(convergence):
    coarse, fine = convergence[1], convergence[4]
    rel = np.abs(coarse.static_tension_n.to_numpy() / fine.static_tension_n.to_numpy() - 1)
    assert np.all(rel < 0.01), rel
    assert fine.static_tension_n.iloc[-1] > 3 * CAL.pretension  # large deflection, not only at rest
    assert fine.tip_angle_deg.iloc[-1] > 250.0


@pytest.mark.slow  # see above
def test_dominant_frequency_converged_within_half_a_percent_up_to_40_mm(convergence):
    coarse, fine = convergence[1], convergence[4]
    rel = np.abs(coarse.omega_d_rad_s.to_numpy() / fine.omega_d_rad_s.to_numpy() - 1)
    assert np.all(rel < 0.005), rel
    # the same mode at both resolutions, and it stiffens as the arm curls
    assert np.all(np.diff(fine.omega_d_rad_s.to_numpy()) > 0)
    assert fine.omega_d_rad_s.iloc[-1] > 1.5 * fine.omega_d_rad_s.iloc[0]


@pytest.mark.slow  # see above
def test_the_plain_arc_chain_misses_at_40_mm_and_the_bowing_is_what_meets_it(convergence):
    """Without the bowing between eyelets the arcs are stiff by more than 0.5 % at 40 mm; the bowing is the
    part of the cable's moment they cannot carry, and it moves the coarse rod, not the fine one."""
    plain = convergence["plain", 1].omega_d_rad_s.iloc[0] / convergence["plain", 4].omega_d_rad_s.iloc[0] - 1
    assert plain > 0.005
    bowed = convergence[1].omega_d_rad_s.iloc[-1] / convergence[4].omega_d_rad_s.iloc[-1] - 1
    assert abs(bowed) < plain - 0.001
    shift = {m: abs(convergence[m].omega_d_rad_s.iloc[-1] / convergence["plain", m].omega_d_rad_s.iloc[0] - 1)
             for m in (1, 4)}  # fmt: skip
    assert shift[4] < shift[1] / 3  # it vanishes as the elements shrink


@pytest.mark.slow
def test_with_and_without_bowing_the_rod_converges_to_the_same_limit():
    """4x and 8x finer rods at 40 mm: the gap between the two models shrinks at second order, and the 8x rods
    agree to 0.03 % in tension and frequency; the bowed rig is within 0.5 % of the 8x rod too."""
    u = np.array([40.0])
    maps = {(b, m): frequency_map(CAL.replace(elements_per_disc=m, bowing=b), u)
            for b in (True, False) for m in (4, 8)}  # fmt: skip
    rig = frequency_map(CAL, u)
    for col in ("static_tension_n", "omega_d_rad_s"):
        gap = {m: abs(maps[True, m][col].iloc[0] / maps[False, m][col].iloc[0] - 1) for m in (4, 8)}
        assert gap[8] < gap[4] / 3
        assert gap[8] < 3e-4
    rel_err = abs(rig.omega_d_rad_s.iloc[0] / maps[True, 8].omega_d_rad_s.iloc[0] - 1)
    assert rel_err < 0.005
    assert abs(rig.static_tension_n.iloc[0] / maps[True, 8].static_tension_n.iloc[0] - 1) < 0.01


def test_frequency_map_rows_and_columns():
    fm = frequency_map(CAL, np.array([0.0, 5.0]))
    assert list(fm.columns[:5]) == ["u_mm", "static_tension_n", "omega_n_rad_s", "omega_d_rad_s", "zeta"]
    assert fm.static_tension_n.iloc[0] == pytest.approx(CAL.pretension, rel=1e-9)
    assert np.all(fm.omega_d_rad_s < fm.omega_n_rad_s)
    assert np.all(fm.omega_d2_rad_s > 3 * fm.omega_d_rad_s)


# --- statics ---------------------------------------------------------------------------------------------
def _circle(x, y):
    """Least-squares circle through points (Kasa fit): centre and radius."""
    A = np.column_stack([2 * x, 2 * y, np.ones_like(x)])
    (cx, cy, c), *_ = np.linalg.lstsq(A, x**2 + y**2, rcond=None)
    return cx, cy, math.sqrt(c + cx**2 + cy**2)


def _check_constant_curvature(p, tension, rel):
    eq = equilibrium_at_tension(p, tension)
    cx, cy, radius = _circle(eq.x, eq.y)
    # the backbone nodes lie on one circle ...
    assert np.max(np.abs(np.hypot(eq.x - cx, eq.y - cy) - radius)) < 1e-3 * radius
    # ... of curvature tension r / EI, i.e. tension = EI theta / (L r) with theta = L / radius the total bend
    theta = p.L / radius
    assert tension == pytest.approx(p.EI * theta / (p.L * p.r), rel=rel)
    return theta


@pytest.mark.slow  # a fine rod's statics, 4 tensions (notebook 06's statics oracle checks them too)
@pytest.mark.parametrize("tension", [0.5, 2.0, 5.0, 9.0])
def test_constant_curvature_statics_fine_rod(tension):
    """Gravity off, cable following the backbone (an eyelet at every node): a circular arc."""
    p = CAL.replace(g=0.0, pretension=0.0, elements_per_disc=8, eyelets_every_node=True, actuator="ideal")
    _check_constant_curvature(p, tension, rel=0.002)


def _bow_p_prime(D: float) -> float:
    """d/dD of P(D) = (1 + sin D / D - 4 (1 - cos D) / D^2) / (2 D^2), from the series of sin and cos."""
    # sin D / D = sum (-1)^j D^2j / (2j+1)!, 4 (1 - cos D) / D^2 = sum 4 (-1)^j D^2j / (2j+2)!
    c = [((-1) ** j / math.factorial(2 * j + 1) - 4 * (-1) ** j / math.factorial(2 * j + 2)) / 2
         for j in range(30)]  # fmt: skip
    return sum(c[j] * (2 * j - 2) * D ** (2 * j - 3) for j in range(2, 30))


@pytest.mark.parametrize("bowing", [False, True])
@pytest.mark.parametrize("tension", [0.5, 3.0, 9.0])
def test_uniform_bending_of_the_12_disc_rig_matches_its_closed_form(tension, bowing):
    """The rig itself, gravity off: every interval bends by the same angle D, the eyelets (and the clamp's
    guide) lie on a circle of radius l/D - r, and the cable runs are its chords, so
    ``ell(D) = 12 * 2 (l/D - r) sin(D/2)``. The plain arcs' equilibrium ``12 EI D / l = -tension * d ell/dD``
    gives ``tension = EI D / (l b)``, ``b = 2 l sin(D/2) / D^2 - (l/D - r) cos(D/2)``: the continuum's
    ``EI theta/(L r)`` with the moment arm lengthened by the chords cutting the corners (by ``l D / 12`` for
    small D). The bowing adds ``-tension^2 H / 2`` with ``H = 12 (l^3/EI) P(D)`` (each arc's mean square
    distance from its run, about its mean, is ``l^2 P(D)``): ``a tension^2 + b tension = EI D / l`` with
    ``a = (l^3 / 2 EI) P'(D)``."""
    p = CAL.replace(g=0.0, pretension=0.0, actuator="ideal", bowing=bowing)
    eq = equilibrium_at_tension(p, tension)
    D = np.diff(np.concatenate([[p.base_angle], eq.q]))
    np.testing.assert_allclose(D, D.mean(), rtol=1e-9)
    D, le, r = D.mean(), p.element_length, p.r
    b = 2 * le * math.sin(D / 2) / D**2 - (le / D - r) * math.cos(D / 2)
    a = le**3 / (2 * p.EI) * _bow_p_prime(D) if bowing else 0.0
    closed = (math.sqrt(b * b + 4 * a * p.EI * D / le) - b) / (2 * a) if bowing else p.EI * D / (le * b)
    assert tension == pytest.approx(closed, rel=1e-9)
    continuum = p.EI * 12 * D / (p.L * r)
    assert continuum > tension  # the corner cutting is real: the discrete rig bends more per newton
    if tension == 9.0:
        assert 12 * D > 3.0  # large deflection, not only at rest


def test_bowing_bends_the_coarse_rod_like_a_fine_one():
    """Uniform bending at 9 N, gravity off: the turning per disc interval of the rig (one arc per interval)
    against a rod with 6 arcs per interval, which resolves the bowing itself. The plain arcs are 0.09 % short,
    the bowed ones within 0.01 %."""
    turning = {}
    for m, bowing in ((1, False), (1, True), (6, True)):
        p = CAL.replace(g=0.0, pretension=0.0, actuator="ideal", elements_per_disc=m, bowing=bowing)
        turning[m, bowing] = equilibrium_at_tension(p, 9.0).q[-1]
    fine = turning[6, True]
    assert turning[1, False] / fine - 1 < -6e-4
    assert abs(turning[1, True] / fine - 1) < 1e-4


def test_bowing_compliance_matches_quadrature_and_its_gradient():
    """The closed form and series of ``ArcChain.bow_compliance`` (and its analytic gradient) against the
    reference's Gauss-Legendre quadrature of the distances from the cable runs (gradient by complex step), for
    one and several elements per run, at random shapes up to large bends."""
    rng = np.random.default_rng(7)
    for m, every in ((1, False), (2, False), (3, False), (2, True)):
        p = CAL.replace(elements_per_disc=m, eyelets_every_node=every)
        q = np.cumsum(rng.normal(0.1, 0.4, p.n_elements))
        H, dH = ArcChain(p).bow_compliance(q)
        H_ref, dH_ref = ReferenceArm(p).bow_grad(q)
        assert H > 0 and H == pytest.approx(H_ref, rel=1e-10)
        np.testing.assert_allclose(dH, dH_ref, rtol=1e-8, atol=1e-10 * np.abs(dH_ref).max())
    assert ArcChain(CAL.replace(bowing=False)).bow_compliance(q[: CAL.n_elements])[0] == 0.0


def test_static_tension_rises_with_cable_displacement():
    tensions = [equilibrium(CAL, u).tension for u in (0.0, 0.01, 0.02, 0.03)]
    assert tensions[0] == pytest.approx(CAL.pretension, rel=1e-9)
    assert np.all(np.diff(tensions) > 0)


# --- linear vibrations ------------------------------------------------------------------------------------
def test_cantilever_frequencies_without_cable():
    """Uniform wire, gravity off, (almost) no cable: omega_n = beta_n^2 sqrt(EI / (rho A L^4))."""
    p = CAL.replace(g=0.0, pretension=0.0, k=1e-9, disc_mass=0.0, elements_per_disc=2, actuator="ideal",
                    **UNDAMPED)  # fmt: skip
    w = linearise(p, 0.0).undamped()
    scale = math.sqrt(p.EI / (p.rho * p.area * p.L**4))
    for i, beta in enumerate(model.cantilever_roots(2)):
        assert w[i] == pytest.approx(beta**2 * scale, rel=0.01)


def test_lowest_modes_agree_with_linear_model():
    """Like with like: uniform mass, cable along the backbone, no gravity, small amplitude, 96 elements and 96
    modes. Both converge slowly here and from opposite sides (the modal model from above through truncation,
    the rig from below at first order: the tip's cable acts as a stiff rotational spring), so 96/96."""
    disc_mass, r, k = 1.0e-3, 7.8e-3, 6000.0
    rig = CAL.replace(g=0.0, pretension=0.0, disc_mass=disc_mass, disc_mass_uniform=True,
                      eyelets_every_node=True, elements_per_disc=8, r=r, k=k, actuator="ideal",
                      **UNDAMPED)  # fmt: skip
    w_rig = linearise(rig, 0.0).undamped()[:3]
    arm = model.ArmParameters(E=rig.E, rho=rig.rho, d=rig.d, L=rig.L, r=r, disc_mass=disc_mass, n_discs=12,
                              k=k, zeta=0.0, n_modes=96)  # fmt: skip
    p_model = model.poles(arm)
    w_model = np.sort(np.abs(p_model[p_model.imag > 0]))[:3]
    np.testing.assert_allclose(w_rig, w_model, rtol=0.015)
    assert np.all(w_rig < w_model)  # the two sides of the common limit


def test_tuned_rig_has_the_papers_mode_at_rest():
    m = linearise(CAL, 0.0, rotor="free").modes()
    assert m.omega_d.iloc[0] == pytest.approx(paper.OMEGA_D, rel=1e-4)
    assert m.zeta.iloc[0] == pytest.approx(paper.ZETA, rel=1e-3)
    lin = linearise(CAL, 0.0, rotor="free")
    assert lin.omega_d == pytest.approx(m.omega_d.iloc[0])  # the lowest mode dominates the tension


def test_default_step_is_within_its_integrators_stability():
    """RK4: within 90 % of its limit over the linearisations to 40 mm; the implicit step: one step's spectral
    radius about rest at most one (tests/test_integrators.py has the rest)."""
    from helpers.virtual.integrators import _radius, planar_system
    from helpers.virtual.statics import rk4_stable_step

    if CAL.integrator == "rk4":
        h_star = min(rk4_stable_step(linearise(CAL, u, rotor="free").poles) for u in (0.0, 0.02, 0.04))
        assert CAL.max_step <= 0.9 * h_star
    else:
        assert _radius(planar_system(CAL), CAL.max_step, CAL.integrator) <= 1.0


# --- the O(N) kernel against the dense Lagrangian ---------------------------------------------------------
def test_kernel_bowing_factors_match_numpy():
    """The kernel's shorter series and closed forms of the bowing factors against the numpy ones, through both
    branches (|D| < 0.8 or 1 and beyond)."""
    from helpers.virtual.statics import bow_functions

    D = np.concatenate([np.linspace(-2.5, 2.5, 501), [1e-6, 0.7999, 0.8001, 0.9999, 1.0001]])
    P, Q, dP, dQ = bow_functions(D)
    for i, d in enumerate(D):
        p_, dp_ = kern.bow_p(d, math.sin(d), math.cos(d))
        assert p_ == pytest.approx(P[i], rel=1e-11) and dp_ == pytest.approx(dP[i], rel=1e-11)
        full = kern.bow_funcs(d, math.sin(d), math.cos(d))
        np.testing.assert_allclose(full, [P[i], dP[i], Q[i], dQ[i]], rtol=1e-11)
    assert P[-5] == pytest.approx(1e-12 / 720, rel=1e-9) and Q[-5] == pytest.approx(1 / 12, rel=1e-9)

@pytest.mark.parametrize(
    ("actuator", "m"), [("ideal", 1), ("stepper", 1), ("stepper+carriage", 1), ("stepper+carriage", 2)]
)
def test_kernel_right_hand_side_equals_dense_lagrangian(actuator, m):
    """Random states, every damping term, taut cables: the articulated-body kernel against plain numpy (with
    two elements per cable run, the bowing also turns the runs)."""
    rng = np.random.default_rng(3)
    p = CAL.replace(actuator=actuator, beta_disc=2e-4, elements_per_disc=m)
    a = model_arrays(p)
    ref = ReferenceArm(p)
    n = a.n
    for _ in range(3):
        y = np.array(a.y_rest)
        y[:n] += rng.normal(0, 0.3, n)
        y[n : 2 * n] = rng.normal(0, 5.0, n)
        y[2 * n :] = rng.normal(0, [1e-3, 2.0, 1e-4, 0.2])
        # make both cables taut by 0.5 mm: the stretches as the kernel defines them (module docstring)
        ell = float(ArcChain(p).cable_length(y[:n]))
        R, P = p.spool_radius, a.P
        drive = P[kern.I_ELLREF] - ell + 5e-4
        if actuator == "stepper":
            y[2 * n] = drive / R
            drive = y[2 * n] + 0.01
        elif actuator == "stepper+carriage":
            y[2 * n + 2] = P[kern.I_ELLREF] - ell + 5e-4
            y[2 * n] = (y[2 * n + 2] + P[kern.I_S1REF] + 5e-4) / R
            drive = y[2 * n] + 0.01
        dy, e1, e2, lam1, lam2 = kern.rhs(y, drive, a.P, a.mb, a.Jb, a.disc, a.W, a.cw)
        assert e2 == pytest.approx(5e-4, rel=1e-6) and lam2 > 0.0
        if actuator == "stepper+carriage":
            assert e1 == pytest.approx(5e-4, rel=1e-6) and lam1 > 0.0
        dense = ref.rhs(0.0, np.append(y, 0.0), drive)[:-1]
        np.testing.assert_allclose(dy, dense, rtol=1e-9, atol=1e-9 * np.abs(dense).max())


@pytest.mark.slow  # 8-18 s of solve_ivp; the default suite keeps the energy and statics oracles
def test_compiled_integrator_converges_to_the_solve_ivp_reference():
    """A 4-disc arm with stepper and carriage through the start of a pull: the fixed-step kernel converges to
    the solve_ivp reference at fourth order as the step shrinks (equations and integrator agree)."""
    p = CAL.replace(n_discs=4, disc_mass=CAL.disc_mass * 3)
    times, signs = pulse_steps(200.0, 2.0, 0.002, 1.0)
    up = signs > 0
    t = np.arange(1, 16) * 1e-3
    ref = ReferenceArm(p).run(t, times[up], signs[up], rtol=1e-8, atol=1e-11, method="RK45", raw=True)
    errors = []
    for h in (2e-4, 5e-5):
        errors.append(
            np.max(np.abs(ArmPlant(p.replace(max_step=h)).advance(t, times[up], signs[up], raw=True) - ref))
        )
    assert errors[1] < 2e-3  # N: a twentieth of an ADC count
    assert errors[1] < errors[0] / 50  # (1/4)^4 = 1/256 for RK4


@pytest.mark.slow
@pytest.mark.parametrize("actuator", ["ideal", "stepper", "stepper+carriage"])
def test_compiled_integrator_agrees_with_solve_ivp_reference_through_slack(actuator):
    """Pull, a release that slackens the cable(s), re-engagement; amplifier output and true tension."""
    p = CAL.replace(n_discs=4, disc_mass=CAL.disc_mass * 3, actuator=actuator, max_step=1.25e-5)
    times, signs = pulse_steps(200.0, 6.0, 0.02, 0.10)
    t = np.arange(1, 201) * 1e-3
    fast = ArmPlant(p)
    out, raw, _ = fast.advance_all(t, times, signs)
    assert fast.transitions >= 1 and raw.min() == 0.0
    ref = ReferenceArm(p)
    assert np.max(np.abs(raw - ref.run(t, times, signs, rtol=1e-10, atol=1e-13, raw=True))) < 1e-4
    # the amplifier is integrated for a tension linear over each step: second order, so a looser bound
    assert np.max(np.abs(out - ref.run(t, times, signs, rtol=1e-10, atol=1e-13))) < 2e-3


# --- dynamics ---------------------------------------------------------------------------------------------
def _release_energy(h, actuator):
    p = CAL.replace(max_step=h, actuator=actuator, amp_bandwidth_hz=0.0, **UNDAMPED)
    plant = ArmPlant(p)
    e_rest = plant.energy()
    # the arm held bent by the ideal cable, then let go at once: it swings down, the cable goes slack and
    # re-engages, many times; with a stepper: the commanded position jumps by a full step and the rotor snaps
    if actuator == "ideal":
        eq = equilibrium(p, 0.015)
        y = np.array(model_arrays(p).y_rest)
        y[: p.n_elements] = eq.q
        plant.set_state(y, position_steps=0)
    else:
        plant.set_state(plant.state, position_steps=4)
    e0 = plant.energy()
    energies, tensions = [], []
    for t in np.arange(1, 201) * 2e-3:
        tensions.append(plant.advance([t], raw=True)[0])
        energies.append(plant.energy())
    return np.max(np.abs(np.array(energies) - e0)) / abs(e0 - e_rest), np.array(tensions), plant.transitions


@pytest.mark.parametrize(
    ("actuator", "h_fine", "h_coarse"),
    [("ideal", 5e-5, 2e-4), pytest.param("stepper+carriage", 1.25e-5, 5e-5, marks=pytest.mark.slow)],
)
def test_energy_conserved_without_damping(actuator, h_fine, h_coarse):
    """Damping off: the energy stays put through slack and re-engagement (hundreds of times for the undamped
    carriage bouncing between its two cables), up to the integrator's error, which shrinks with the step."""
    err_fine, tensions, transitions = _release_energy(h_fine, actuator)
    err_coarse, _, _ = _release_energy(h_coarse, actuator)
    assert transitions >= 2 and tensions.min() == 0.0 and tensions.max() > 0.5
    assert err_fine < 1e-3
    assert err_fine < err_coarse / 4


def test_damping_dissipates_energy():
    plant = ArmPlant(CAL)
    plant.set_state(plant.state, position_steps=40)
    e = [plant.energy()]
    for t in (0.2, 0.4, 0.8, 1.6):
        plant.advance([t])
        e.append(plant.energy())
    assert np.all(np.diff(e) < 0)


def test_tension_never_negative_slack_and_reengagement_in_overrunning_release():
    times, signs = pulse_steps(200.0, 20.0, 0.2, 1.5)
    t = np.arange(1, 3001) * 1e-3
    plant = ArmPlant(CAL)
    tension = plant.advance(t, times, signs, raw=True)
    assert np.all(tension >= 0.0)
    after = tension[t > 1.5]
    slack = np.flatnonzero(after == 0.0)
    assert slack.size > 0, "the release should overrun and slacken the cable"
    assert np.any(after[slack[-1] :] > 0.5 * CAL.pretension), "the cable should re-engage"
    assert plant.transitions >= 2


def test_step_at_sample_time_applies_before_the_sample():
    p = CAL.replace(actuator="ideal", amp_bandwidth_hz=0.0)
    a, b = ArmPlant(p), ArmPlant(p)
    ta = a.advance([0.01, 0.02], [0.01], [1])
    tb = b.advance([0.01, 0.02], [0.0100001], [1])
    # the arm cannot move in zero time: the cable stretches by one step at once, in series with the rod's
    # bowing between the eyelets (quasi-static)
    bow = ArcChain(p).bow_compliance(a.state[: p.n_elements])[0]
    assert 0.0 < bow * p.k < 0.05
    assert ta[0] - tb[0] == pytest.approx(p.cable_per_step / (1 / p.k + bow), rel=1e-3)
    assert ta[1] == pytest.approx(tb[1], abs=0.05)
    assert a.position_steps == 1


def test_chunked_advance_equals_one_call_and_reset():
    """The amplifier's filter and both cables' states persist between calls: the same bits either way."""
    times, signs = pulse_steps(300.0, 10.0, 0.05, 0.3)
    t = np.arange(1, 601) * 1e-3
    whole = ArmPlant(CAL).advance(t, times, signs)
    plant = ArmPlant(CAL)
    parts = []
    for lo, hi in ((0.0, 0.1234), (0.1234, 0.3), (0.3, 0.6)):
        sel_t = (t > lo) & (t <= hi)
        sel_s = (times > lo) & (times <= hi)
        parts.append(plant.advance(t[sel_t], times[sel_s], signs[sel_s]))
    np.testing.assert_array_equal(np.concatenate(parts), whole)
    assert plant.t == pytest.approx(0.6)
    plant.reset()
    assert plant.t == 0.0 and plant.position_steps == 0
    assert plant.tension() == pytest.approx(CAL.pretension, rel=1e-9)
    assert plant.amplifier_output() == CAL.pretension


def test_amplifier_lags_the_tension_by_its_time_constant():
    """One ideal step: the true tension jumps, the first-order amplifier follows with tau = 1 / (2 pi f_c)."""
    p = CAL.replace(actuator="ideal", amp_bandwidth_hz=200.0)
    plant = ArmPlant(p)
    t = 0.01 + np.array([1e-5, 2e-5, 5e-5])
    out, raw, _ = plant.advance_all(t, [0.01], [1])
    tau = 1.0 / (2 * math.pi * 200.0)
    jump = raw[0] - p.pretension
    # within 50 us the arm has hardly moved: the output is the filter's step response to the jump
    expected = p.pretension + jump * (1 - np.exp(-(t - 0.01) / tau))
    np.testing.assert_allclose(out, expected, atol=0.01 * jump)


# --- the stepper ------------------------------------------------------------------------------------------
def test_stepper_static_lag_follows_the_torque_law():
    p = CAL.replace(actuator="stepper")
    plant = ArmPlant(p)
    n_steps = 60
    plant.advance([0.5], 0.1 + np.arange(n_steps) * 2e-3, np.ones(n_steps))
    plant.advance([8.0])  # settle
    tension = plant.tension()
    y = plant.state
    lag = n_steps * p.step_angle - y[2 * p.n_elements]
    # T_h sin(N_r lag) = R tension at rest
    assert p.holding_torque * math.sin(p.rotor_teeth * lag) == pytest.approx(
        p.spool_radius * tension, rel=1e-3
    )
    assert plant.max_rotor_lag_steps > lag / p.step_angle


def test_weaker_motor_loses_steps_and_the_health_figure_shows_it():
    """Below the pull-out tension T_h / R the rotor slips: its lag passes half a tooth pitch (pi electrical,
    8 microsteps at 800 steps/rev) and the cable ends short of where it was commanded."""
    times, signs = pulse_steps(300.0, 20.0, 0.2, 3.0)
    up = signs > 0
    t = np.arange(1, 2501) * 1e-3
    slip = (math.pi / CAL.rotor_teeth) / CAL.step_angle
    strong = ArmPlant(CAL)
    strong_t = strong.advance(t, times[up], signs[up])
    # the same cable and load cell behind a motor with 0.25 N m: pull-out tension 7.7 N < this run's ~13 N
    R, torque = CAL.spool_radius, 0.25
    k_weak = 1.0 / (1.0 / CAL.k_cable + R**2 / (torque * CAL.rotor_teeth))
    weak = ArmPlant(CAL.replace(holding_torque=torque, k=k_weak))
    weak_t = weak.advance(t, times[up], signs[up])
    assert strong.max_rotor_lag_steps < slip < weak.max_rotor_lag_steps
    held = t > 2.0
    assert np.mean(weak_t[held]) < np.mean(strong_t[held]) - 1.0


def test_bad_input_is_refused():
    plant = ArmPlant(CAL)
    with pytest.raises(ValueError, match="increasing"):
        plant.advance([0.2, 0.1])
    with pytest.raises(ValueError, match="step_signs"):
        plant.advance([0.1], [0.05], [2])
    with pytest.raises(ValueError, match="step_times"):
        plant.advance([0.1], [0.2], [1])
    plant.advance([0.1])
    with pytest.raises(ValueError, match="precede"):
        plant.advance([0.05])
    with pytest.raises(ValueError, match="disc_mass"):
        RigParameters(disc_mass=-1.0)
    with pytest.raises(ValueError, match="n_discs"):
        RigParameters(n_discs=0)
    with pytest.raises(ValueError, match="actuator"):
        RigParameters(actuator="magic")
    with pytest.raises(ValueError, match="microstep spring"):
        RigParameters(k=1e6)


# --- sensor and simulate ----------------------------------------------------------------------------------
def test_cable_travel_per_step_follows_the_papers_spool_and_steps():
    # 65 mm spool, 800 steps per revolution (paper): 0.25525 mm of cable per step
    assert CAL.cable_per_step * 1e3 == pytest.approx(math.pi * 65.0 / 800.0, rel=1e-15)


def test_load_cell_counts_follow_the_current_loop():
    cell = LoadCell(CAL, seed=1)
    quiet = LoadCell(CAL, seed=1, noise_rms=0.0)
    # 4-20 mA over 0-span through 150 ohm into a 10-bit ADC at 5 V (written out here, not from the code)
    gain = 16e-3 / CAL.span_n * 150.0 * 1024 / 5.0
    offset = 4e-3 * 150.0 * 1024 / 5.0
    lam = np.array([0.0, 1.0, 5.0, 17.7, 100.0])
    c = quiet.counts(lam)
    assert c.dtype.kind == "i"
    np.testing.assert_array_equal(c[:4], np.rint(offset + gain * lam[:4]))
    assert c[-1] == round(20.5e-3 * 150.0 * 1024 / 5.0)  # the loop saturates at 20.5 mA, below 1023
    assert cell.full_scale_newtons > 17.7  # the paper's largest tension fits
    noisy = LoadCell(CAL, seed=1, noise_rms=2.0).counts(np.full(20000, 3.0))
    assert np.std(noisy) == pytest.approx(2.0, rel=0.1)  # (quantisation adds 1/12 count^2)
    assert cell.noise_rms == CAL.adc_noise_counts
    with pytest.raises(ValueError):
        cell.counts([np.nan])


def test_simulate_runs_a_programme_and_identifies_the_paper_mode():
    from helpers.board.programmes import experiment_programme
    from helpers.paper.identify import identify

    prog, _ = experiment_programme(100.0, 10.0)
    res = simulate(prog, rate_hz=1000.0, params=CAL, seed=0)
    assert prog.duration_s - 1e-3 < res.t[-1] <= prog.duration_s
    assert res.steps[-1] == 0 and res.steps.max() == round(10.0 / MM_PER_STEP)
    low, high = SHIPPED["paper"].clip_counts  # the paper's chain, by hand (tests/rigs.py)
    assert np.all((res.adc > low) & (res.adc < high))
    x, y = res.shape_at(5.0)
    assert x.shape == (CAL.n_elements + 1,)
    ident = identify(res.t, res.adc.astype(float), window=paper.IDENTIFICATION_RUN["window_s"])
    assert ident.omega_d == pytest.approx(paper.OMEGA_D, rel=0.01)
    assert ident.zeta == pytest.approx(paper.ZETA, rel=0.10)


def test_eyelet_friction_only_dissipates():
    """Capstan friction with each eyelet's own sliding speed: with every viscous term off, the energy of a
    free vibration falls and never rises (beyond the integrator's noise)."""
    p = CAL.replace(eyelet_mu=0.1, max_step=2.5e-5, amp_bandwidth_hz=0.0, **UNDAMPED)
    plant = ArmPlant(p)
    n = 39
    plant.advance([0.1], 0.01 + np.arange(1, n + 1) * 1.3e-3, np.ones(n))
    energies = []
    for t in np.arange(0.101, 0.6, 0.002):
        plant.advance([t])
        energies.append(plant.energy())
    e = np.array(energies)
    assert e[-1] < 0.95 * e[0]
    assert np.max(np.diff(e)) < 1e-6 * e[0]


@pytest.mark.slow  # a sensitivity study of the assumed motor (docs/virtual_rig.md)
def test_a_weaker_motor_on_the_same_cable_loses_steps_where_the_assumed_one_holds():
    """The actuator assumption that matters (docs/virtual_rig.md): the paper's 4.3 kg cm cannot hold the
    unshaped 300 mm/s pulse, whose peak tension passes the motor's pull-out; the assumed 1.5x holds it."""
    rig = RigParameters().with_integrator("rk4")  # the studies' reference (helpers.virtual.studies)
    weak = _variant(rig, SENSITIVITY_VARIANTS["paper torque"])
    assert weak.k_cable == pytest.approx(rig.k_cable, rel=1e-12) and weak.k < rig.k  # the same cable
    assert weak.pull_out_tension == pytest.approx(rig.pull_out_tension / 1.5, rel=1e-12)
    stiff = _variant(rig, SENSITIVITY_VARIANTS["3x stiffer cable"])
    assert stiff.k_cable == pytest.approx(3 * rig.k_cable, rel=1e-12) and stiff.max_step < rig.max_step
    df = actuator_sensitivity(
        variants={"rig": {}, "paper torque": SENSITIVITY_VARIANTS["paper torque"]},
        conditions=((300.0, 20.0),),
        systems=("unshaped",),
    )
    runs = df.drop_duplicates("variant").set_index("variant")
    assert runs.loc["rig", "lost_steps"] == 0 and runs.loc["rig", "end_tension_n"] > 2.0
    assert runs.loc["paper torque", "lost_steps"] >= 16  # at least a tooth slipped ...
    assert runs.loc["paper torque", "end_tension_n"] < 0.5  # ... and the cable is left slack
    assert paper.table_ii().peak_n.max() > weak.pull_out_tension  # the paper's own peak: beyond 4.3 kg cm


@pytest.mark.slow
def test_the_stored_convergence_study_is_what_the_rig_computes():
    # notebook 06 reads figures/virtual_convergence.csv; if this fails, the rig changed since it was stored:
    # python -m helpers virtual-rig studies --only convergence
    import pandas as pd

    from helpers.base.paths import stored_table
    from helpers.virtual.studies import STUDY_FILES, convergence

    stored = pd.read_csv(stored_table(STUDY_FILES["convergence"]))
    fresh = convergence()
    assert list(stored.columns) == list(fresh.columns)
    np.testing.assert_allclose(stored.to_numpy(float), fresh.to_numpy(float), rtol=1e-5, atol=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("study", ["pulses", "spatial"])
def test_the_stored_pulse_and_spatial_studies_are_what_the_twin_computes(study):
    # notebook 06 reads figures/virtual_pulse_table.csv and virtual_spatial_map.csv; if this fails, the
    # twin changed since they were stored: python -m helpers virtual-rig studies --only pulses spatial
    import pandas as pd

    from helpers.base.paths import stored_table
    from helpers.virtual.studies import STUDY_FILES, pulse_study, spatial_map

    stored = pd.read_csv(stored_table(STUDY_FILES[study]))
    fresh = {"pulses": pulse_study, "spatial": spatial_map}[study]()
    assert list(stored.columns) == list(fresh.columns) and len(stored) == len(fresh)
    numeric = fresh.select_dtypes("number").columns
    np.testing.assert_allclose(
        stored[numeric].to_numpy(float), fresh[numeric].to_numpy(float), rtol=1e-5, atol=1e-9, equal_nan=True
    )
    text = [c for c in fresh.columns if c not in numeric]
    assert (stored[text].astype(str).to_numpy() == fresh[text].astype(str).to_numpy()).all()
