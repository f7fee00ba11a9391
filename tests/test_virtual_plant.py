"""Validation of the virtual rig's physics against independent oracles.

Oracles: constant-curvature statics of a rod pulled by a frictionless cable, the Euler-Bernoulli cantilever's
frequencies, the paper's linear modal model (``helpers.model``) built from the same parameters, convergence in
the number of segments, conservation of energy without damping, a separately written solve_ivp implementation,
and the paper's identified mode (through the project's own identification code).
"""

import math

import numpy as np
import pytest

from helpers import hardware, model, paper
from helpers.hardware import MM_PER_STEP
from helpers.virtual import (
    ArmPlant,
    LoadCell,
    RigParameters,
    equilibrium,
    linearise,
    simulate,
)
from helpers.virtual.reference import ReferenceArm
from helpers.virtual.statics import equilibrium_at_tension

CAL = RigParameters()
DU = MM_PER_STEP * 1e-3


def pulse_steps(v_mm_s: float, x_mm: float, t_up: float, t_down: float) -> tuple[np.ndarray, np.ndarray]:
    """Step times and signs of an up/down velocity pulse (independent of helpers.profiles)."""
    n = round(x_mm / MM_PER_STEP)
    dt = MM_PER_STEP / v_mm_s
    up = t_up + dt * np.arange(1, n + 1)
    down = t_down + dt * np.arange(1, n + 1)
    return np.concatenate([up, down]), np.concatenate([np.ones(n), -np.ones(n)])


# --- statics --------------------------------------------------------------------------------------


def _circle(x, y):
    """Least-squares circle through points (Kasa fit): centre and radius."""
    A = np.column_stack([2 * x, 2 * y, np.ones_like(x)])
    (cx, cy, c), *_ = np.linalg.lstsq(A, x**2 + y**2, rcond=None)
    return cx, cy, math.sqrt(c + cx**2 + cy**2)


def _check_constant_curvature(p, tension):
    eq = equilibrium_at_tension(p, tension)
    cx, cy, radius = _circle(eq.x, eq.y)
    # the backbone nodes lie on one circle ...
    assert np.max(np.abs(np.hypot(eq.x - cx, eq.y - cy) - radius)) < 1e-3 * radius
    # ... of curvature tension r / EI, i.e. tension = EI theta / (L r) with theta = L / radius the total bend
    theta = p.L / radius
    assert tension == pytest.approx(p.EI * theta / (p.L * p.r), rel=0.01)
    return theta


@pytest.mark.parametrize("tension", [0.5, 2.0, 5.0, 9.0])
def test_constant_curvature_statics_fine_rod(tension):
    """Gravity off, cable following the backbone (eyelets at every node): a circular arc."""
    p = RigParameters(g=0.0, pretension=0.0, segments_per_disc=8, eyelets_every_node=True, r=7.8e-3)
    _check_constant_curvature(p, tension)


@pytest.mark.parametrize("tension", [0.5, 1.5, 3.0])
def test_constant_curvature_statics_rig(tension):
    """The 12-disc rig itself (gravity off, eyelets only at the discs) up to ~1.5 rad of bend."""
    theta = _check_constant_curvature(CAL.replace(g=0.0, pretension=0.0), tension)
    assert 0.1 < theta < 1.6


def test_static_tension_rises_with_cable_displacement():
    tensions = [equilibrium(CAL, u).tension for u in (0.0, 0.01, 0.02, 0.03)]
    assert tensions[0] == pytest.approx(CAL.pretension, rel=1e-6)
    assert np.all(np.diff(tensions) > 0)


# --- linear vibrations ----------------------------------------------------------------------------


def test_cantilever_frequencies_without_cable():
    """Uniform wire, gravity off, (almost) no cable: omega_n = beta_n^2 sqrt(EI / (rho A L^4))."""
    p = RigParameters(g=0.0, pretension=0.0, k=1e-9, disc_mass=0.0, segments_per_disc=2, alpha=0.0, beta=0.0)
    lin = linearise(p, 0.0)
    w = np.sort(np.abs(lin.poles[lin.poles.imag > 0]))
    scale = math.sqrt(p.EI / (p.rho * p.area * p.L**4))
    for i, beta in enumerate(model.cantilever_roots(2)):
        assert w[i] == pytest.approx(beta**2 * scale, rel=0.01)


def test_dominant_mode_agrees_with_linear_model():
    """Like with like: uniform mass, cable along the backbone, no gravity, small amplitude, enough modes."""
    disc_mass, r, k = 1.0e-3, 7.8e-3, 6000.0
    rig = RigParameters(
        g=0.0, pretension=0.0, disc_mass=disc_mass, disc_mass_uniform=True, eyelets_every_node=True,
        segments_per_disc=4, r=r, k=k, alpha=0.0, beta=0.0,
    )  # fmt: skip
    lin = linearise(rig, 0.0, decay_s=0.0)
    # the modal model needs many modes to converge (the cable couples to all of them): 48, like 48 segments
    arm = model.ArmParameters(
        E=rig.E, rho=rig.rho, d=rig.d, L=rig.L, r=r, disc_mass=disc_mass, n_discs=12, k=k, zeta=0.0,
        n_modes=48,
    )
    p_model = model.poles(arm)
    w_model = np.sort(np.abs(p_model[p_model.imag > 0]))[:3]
    w_rig = np.sort(np.abs(lin.poles[lin.poles.imag > 0]))[:3]
    np.testing.assert_allclose(w_rig, w_model, rtol=0.02)


@pytest.mark.parametrize("zeta", [0.02, 0.06])
def test_rayleigh_damping_gives_the_requested_modal_damping(zeta):
    from helpers.rig_tuning import rayleigh_for

    lin = linearise(rayleigh_for(CAL, zeta), 0.0)
    # the cable makes the damping non-proportional: close, not exact
    assert lin.zeta == pytest.approx(zeta, rel=0.05)


def test_convergence_in_number_of_segments():
    """The rig's dominant frequency at rest converges as each disc interval is split into more segments."""
    w = [linearise(CAL.replace(segments_per_disc=m), 0.0).omega_d for m in (1, 2, 4, 8)]
    diffs = np.abs(np.diff(w))
    assert np.all(diffs[1:] < diffs[:-1])
    assert abs(w[-1] - w[-2]) / w[-1] < 0.005
    assert abs(w[0] - w[-1]) / w[-1] < 0.05


# --- dynamics -------------------------------------------------------------------------------------


def _release_energy(h):
    p = CAL.replace(alpha=0.0, beta=0.0, max_step=h)
    eq = equilibrium(p, 0.015)
    plant = ArmPlant(p)
    # the arm held bent by 15 mm of cable, then the cable is let go at once: it swings down, the cable goes
    # slack and re-engages, many times
    plant.set_state(np.concatenate([eq.phi, np.zeros(p.n_segments)]), position_steps=0)
    e0 = plant.energy()
    scale = abs(e0 - ArmPlant(p).energy())
    energies, tensions = [], []
    for t in np.arange(1, 201) * 2e-3:
        tensions.append(plant.advance([t])[0])
        energies.append(plant.energy())
    return np.max(np.abs(np.array(energies) - e0)) / scale, np.array(tensions), plant.transitions


def test_energy_conserved_without_damping_through_slack_and_reengagement():
    err_fine, tensions, transitions = _release_energy(1.0e-4)
    err_coarse, _, _ = _release_energy(2.0e-4)
    assert transitions >= 2
    assert tensions.min() == 0.0 and tensions.max() > 0.5
    assert err_fine < 1e-3
    # the residual drift is the integrator's (RK4 dissipates the stiffest modes), so it shrinks with the step
    assert err_fine < err_coarse / 4


def test_damping_dissipates_energy():
    eq = equilibrium(CAL, 0.015)
    plant = ArmPlant(CAL)
    plant.set_state(np.concatenate([eq.phi, np.zeros(CAL.n_segments)]), position_steps=0)
    e = [plant.energy()]
    for t in (0.2, 0.4, 0.8, 1.6):
        plant.advance([t])
        e.append(plant.energy())
    assert np.all(np.diff(e) < 0)


def test_tension_never_negative_slack_and_reengagement_in_overrunning_release():
    times, signs = pulse_steps(200.0, 20.0, 0.2, 1.5)
    t = np.arange(1, 3001) * 1e-3
    plant = ArmPlant(CAL)
    tension = plant.advance(t, times, signs)
    assert np.all(tension >= 0.0)
    after = tension[t > 1.5]
    slack = np.flatnonzero(after == 0.0)
    assert slack.size > 0, "the release should overrun and slacken the cable"
    assert np.any(after[slack[-1] :] > 0.5 * CAL.pretension), "the cable should re-engage"
    assert plant.transitions >= 2


def test_step_at_sample_time_applies_before_the_sample():
    a, b = ArmPlant(CAL), ArmPlant(CAL)
    ta = a.advance([0.01, 0.02], [0.01], [1])
    tb = b.advance([0.01, 0.02], [0.0100001], [1])
    # the arm cannot move in zero time: the cable stretches by one step at once
    assert ta[0] - tb[0] == pytest.approx(CAL.k * DU, rel=1e-3)
    assert ta[1] == pytest.approx(tb[1], abs=0.05)
    assert a.position_steps == 1


def test_chunked_advance_equals_one_call_and_reset():
    times, signs = pulse_steps(300.0, 10.0, 0.05, 0.3)
    t = np.arange(1, 601) * 1e-3
    whole = ArmPlant(CAL).advance(t, times, signs)
    plant = ArmPlant(CAL)
    parts = []
    for lo, hi in ((0.0, 0.1234), (0.1234, 0.3), (0.3, 0.6)):
        sel_t = (t > lo) & (t <= hi)
        sel_s = (times > lo) & (times <= hi)
        parts.append(plant.advance(t[sel_t], times[sel_s], signs[sel_s]))
    np.testing.assert_allclose(np.concatenate(parts), whole, atol=1e-9)
    assert plant.t == pytest.approx(0.6)
    plant.reset()
    assert plant.t == 0.0 and plant.position_steps == 0
    assert plant.tension() == pytest.approx(CAL.pretension, rel=1e-6)


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


def test_recursive_dynamics_equal_dense_mass_matrix_solve():
    """The O(n) articulated-body recursion against the dense M(q) and its Cholesky solve."""
    from helpers.virtual import _kernel as kern
    from helpers.virtual.statics import model_arrays

    rng = np.random.default_rng(3)
    for p in (CAL, CAL.replace(segments_per_disc=3, alpha=0.0), RigParameters(disc_mass_uniform=True)):
        a = model_arrays(p)
        for _ in range(3):
            y = np.concatenate([a.phi_rest + rng.normal(0, 0.3, a.n), rng.normal(0, 5, a.n)])
            fast, dense = np.empty_like(y), np.empty_like(y)
            lam_fast = kern.rhs(y, 0.004, a.P, a.mu, a.kap, a.cj, a.eye, fast)
            lam_dense = kern.rhs_dense(y, 0.004, a.P, a.mu, a.kap, a.cj, a.eye, dense)
            assert lam_fast == pytest.approx(lam_dense, rel=1e-12)
            np.testing.assert_allclose(fast, dense, rtol=1e-9, atol=1e-9 * np.abs(dense).max())


def test_compiled_integrator_agrees_with_solve_ivp_reference():
    """A small arm (4 discs) through a pull, an overrunning release with slack, and re-engagement."""
    p = CAL.replace(n_discs=4, disc_mass=CAL.disc_mass * 3)
    times, signs = pulse_steps(200.0, 6.0, 0.02, 0.25)
    t = np.arange(1, 451) * 1e-3
    fast = ArmPlant(p)
    tension = fast.advance(t, times, signs)
    ref = ReferenceArm(p).run(t, times, signs, rtol=1e-9, atol=1e-12)
    assert fast.transitions >= 1
    assert np.min(tension) == 0.0
    assert np.max(np.abs(tension - ref)) < 0.02  # N: one ADC count at 50 counts/N


# --- sensor and simulate --------------------------------------------------------------------------


def test_cable_travel_per_step_follows_the_papers_spool_and_steps():
    # 65 mm spool, 800 steps per revolution (paper): 0.25525 mm of cable per step
    assert hardware.MM_PER_STEP == pytest.approx(math.pi * 65.0 / 800.0, rel=1e-15)
    assert hardware.MM_PER_STEP == pytest.approx(0.25525, abs=5e-6)


def test_load_cell_counts():
    cell = LoadCell(CAL, seed=1)
    quiet = LoadCell(CAL, seed=1, noise_rms=0.0)
    lam = np.array([0.0, 1.0, 5.0, 100.0])
    c = quiet.counts(lam)
    assert c.dtype.kind == "i"
    assert c[0] == round(quiet.offset_counts) and c[-1] == 1023
    assert (c[2] - c[1]) == round(4.0 / quiet.newtons_per_count)
    assert cell.full_scale_newtons > 18.0
    noisy = cell.counts(np.full(20000, 3.0))
    assert np.std(noisy) == pytest.approx(1.0, rel=0.1)
    with pytest.raises(ValueError):
        cell.counts([np.nan])


def test_simulate_runs_a_programme_and_identifies_the_paper_mode():
    from helpers.identify import identify
    from helpers.programmes import experiment_programme

    prog, _ = experiment_programme(100.0, 10.0)
    res = simulate(prog, rate_hz=1000.0, params=CAL, seed=0)
    assert prog.duration_s - 1e-3 < res.t[-1] <= prog.duration_s
    assert res.steps[-1] == 0 and res.steps.max() == round(10.0 / MM_PER_STEP)
    assert np.all((res.adc >= 0) & (res.adc <= 1023))
    x, y = res.shape_at(5.0)
    assert x.shape == (CAL.n_segments + 1,)
    ident = identify(res.t, res.adc.astype(float), window=paper.IDENTIFICATION_RUN["window_s"])
    assert ident.omega_d == pytest.approx(paper.OMEGA_D, rel=0.01)
    assert ident.zeta == pytest.approx(paper.ZETA, rel=0.10)
