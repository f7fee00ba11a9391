"""The twin's implicit step (``integrator="rosw"``) against its theory and against RK4.

Oracles: the W-method order conditions and stability function of its coefficients, worked out here from the
method's definition; third-order convergence to a finely stepped RK4 solution; the linear stability of one
step about rest through the kernel itself (both rigs); agreement with RK4 at a quarter of its step within the
band ``docs/virtual_rig.md`` states, through slack and re-engagement; energy without damping; the planar and
the spatial kernels on the paper's one tendon.
"""

import dataclasses

import numpy as np
import pytest

from helpers.board.programmes import experiment_programme
from helpers.virtual import ArmPlant, RigParameters
from helpers.virtual import _kernel as kern
from helpers.virtual.integrators import (
    bend_programmes,
    limiting_mode,
    planar_system,
    spatial_system,
    step_limit,
)
from helpers.virtual.spatial.plant import SpatialPlant
from helpers.virtual.spatial.rig import four_tendon_rig, paper_rig
from helpers.virtual.spatial.simulate import merge_programmes
from helpers.virtual.statics import equilibrium, model_arrays

RIG = RigParameters().with_integrator("rk4")  # the reference
ROSW = RIG.with_integrator("rosw")
UNDAMPED = {"alpha": 0.0, "beta_chord": 0.0, "floor_zeta": 0.0, "rotor_zeta": 0.0, "carriage_zeta": 0.0}
# docs/virtual_rig.md, section 2: the implicit step at its step against RK4 at a quarter of it
BAND_PEAK_N = 0.15
BAND_SAMPLE_N = 1.0  # any single sample of the amplifier's output, at a snap


def _tableau():
    G = np.array(kern._RW_G)
    a = np.array(kern._RW_A)
    b = np.array(kern._RW_B)
    return G, a, b


def test_coefficients_meet_the_w_method_conditions_to_third_order():
    """For any T: k_i = h f(Y_i) + h T sum_{j<=i} G_ij k_j; expanding to h^3 gives these sums (the f-only ones
    are classical RK4's, which the method's a and b are)."""
    G, a, b = _tableau()
    c = a.sum(axis=1)
    g = G.sum(axis=1)
    assert b.sum() == pytest.approx(1.0, abs=1e-15)
    assert b @ c == pytest.approx(0.5, abs=1e-15)
    assert b @ c**2 == pytest.approx(1 / 3, abs=1e-15)
    assert b @ a @ c == pytest.approx(1 / 6, abs=1e-15)
    assert b @ g == pytest.approx(0.0, abs=1e-14)  # T f
    assert b @ a @ g == pytest.approx(0.0, abs=1e-14)  # f' T f
    assert b @ G @ c == pytest.approx(0.0, abs=1e-14)  # T f' f
    assert b @ G @ g == pytest.approx(0.0, abs=1e-14)  # T T f


def test_stability_function_is_l_stable_and_a_stable():
    """y' = lambda y with T = lambda: R(z) = 1 + z b (I - z (a + G))^-1 1; R(inf) = 0, |R(iy)| <= 1."""
    G, a, b = _tableau()
    B = a + G

    def R(z):
        return 1.0 + z * (b @ np.linalg.solve(np.eye(4) - z * B, np.ones(4)))

    assert abs(1.0 - b @ np.linalg.solve(B, np.ones(4))) < 1e-13
    ys = np.concatenate([np.linspace(0.0, 10.0, 2001), np.geomspace(10.0, 1e6, 500)])
    assert max(abs(R(1j * y)) for y in ys) <= 1.0 + 1e-12
    assert abs(R(-1e8)) < 1e-6 and abs(R(1e4j)) < 1e-3  # the stiff end is damped out


def test_the_kernel_runs_the_same_method_in_its_solve_only_form():
    G, a, b = _tableau()
    Gi = np.linalg.inv(G)
    np.testing.assert_allclose(kern._RW_TA, a @ Gi, atol=1e-14)
    np.testing.assert_allclose(kern._RW_TM, b @ Gi, atol=1e-14)
    np.testing.assert_allclose(kern._RW_TE, -kern._RW_GAM * np.tril(Gi, -1), atol=1e-14)


def _free_vibration(params):
    """Released from rest with a bending velocity (the cable stays taut): true tension and angles, 100 ms."""
    plant = ArmPlant(params.replace(amp_bandwidth_hz=0.0))
    n = params.n_elements
    y = plant.state
    y[n : 2 * n] += 0.05 * np.linspace(0.0, 1.0, n)
    plant.set_state(y)
    _, tension, angles = plant.advance_all(np.arange(1, 101) * 1e-3)
    assert plant.transitions == 0
    return tension, angles


def test_implicit_step_converges_at_third_order_to_a_fine_rk4_solution():
    ref, ref_angles = _free_vibration(RIG.replace(max_step=1e-3 / 256))
    errors = [np.max(np.abs(_free_vibration(ROSW.replace(max_step=1e-3 / n))[0] - ref)) for n in (16, 32)]
    assert errors[1] < 1e-5  # N
    assert 6.0 < errors[0] / errors[1] < 11.0  # (1/2)^-3 = 8
    tension, angles = _free_vibration(ROSW)
    assert np.max(np.abs(tension - ref)) < 2e-3 and np.max(np.abs(angles - ref_angles)) < 2e-6


def test_one_step_is_stable_about_rest_where_rk4_is_not():
    """Through the kernel: RK4's limit is the tip disc rocking against the cable (9.9 krad/s, 0.298 ms); the
    implicit step's spectral radius stays below one at 0.5 and 1 ms."""
    system = planar_system(RIG)
    limit = step_limit(system, "rk4", h_hi=5e-4)
    assert limit == pytest.approx(2.98e-4, rel=0.01)
    mode = limiting_mode(system, "rk4", limit)
    assert mode["where"] == f"node {RIG.n_elements}" and mode["omega"] == pytest.approx(9923, rel=0.01)
    from helpers.virtual.integrators import _radius

    for h in (5e-4, 1e-3):
        assert _radius(system, h, "rosw") <= 1.0
    assert _radius(system, 4e-4, "rk4") > 1.2


def test_four_tendons_one_step_is_stable_at_half_a_millisecond():
    rig = four_tendon_rig()
    system = spatial_system(rig)
    from helpers.virtual.integrators import _radius

    assert _radius(system, 2.5e-4, "rk4") > 1.0  # beyond RK4's 0.219 ms: two taut pairs rock the tip disc
    assert _radius(system, 5e-4, "rosw") <= 1.0


def test_table_i_run_within_the_band_of_rk4_at_a_quarter_of_the_step():
    """The 200 mm/s, 10 mm unshaped run (its Up peak is the most sensitive row): 0.9-2.2 s."""
    prog, _ = experiment_programme(200.0, 10.0)
    st, sg = prog.step_times()
    t = np.arange(1, 2201) * 1e-3
    sel = st <= t[-1]
    fast = ArmPlant(ROSW)
    out = fast.advance(t, st[sel], sg[sel])
    ref = ArmPlant(RIG.replace(max_step=ROSW.max_step / 4)).advance(t, st[sel], sg[sel])
    up = (t > 0.9) & (t < 2.2)
    assert abs(out[up].max() - ref[up].max()) < BAND_PEAK_N
    assert np.max(np.abs(out - ref)) < BAND_SAMPLE_N
    assert fast.integrator_steps < 1.1 * 2 * 2200  # two steps per millisecond, and a few splits


def test_slack_and_reengagement_with_the_implicit_step():
    """An overrunning release: the cable goes slack and snaps back; the tension never goes negative, the
    snaps come when RK4 at a quarter of the step has them, and the hold after it is the same."""
    prog, _ = experiment_programme(200.0, 20.0)
    st, sg = prog.step_times()
    t = np.arange(7801, 9501) * 1e-3
    runs = {}
    for name, p in (("rosw", ROSW), ("ref", RIG.replace(max_step=ROSW.max_step / 4))):
        plant = ArmPlant(p)
        pre = st <= t[0]
        plant.advance(np.arange(1, 7801) * 1e-3, st[pre], sg[pre])
        sel = st > t[0]
        runs[name] = (plant.advance(t, st[sel], sg[sel], raw=True), plant.transitions)
    tension, ref = runs["rosw"][0], runs["ref"][0]
    assert np.all(tension >= 0.0) and runs["rosw"][1] >= 10
    slack, ref_slack = tension == 0.0, ref == 0.0
    assert slack.sum() > 50 and abs(int(slack.sum()) - int(ref_slack.sum())) <= 0.05 * ref_slack.sum()
    snaps = np.flatnonzero(np.diff(slack.astype(int)) == -1)
    ref_snaps = np.flatnonzero(np.diff(ref_slack.astype(int)) == -1)
    assert snaps.size == ref_snaps.size and np.max(np.abs(snaps - ref_snaps)) <= 2  # ms
    hold = t > 9.3
    assert np.max(np.abs(tension[hold] - ref[hold])) < 0.01


def test_four_tendon_bend_with_slack_antagonists_stays_within_the_band():
    """Tendons paying out go slack and snap back many times in one step: every transition is located in
    time order, so no snap is integrated with the wrong stiffness (before, a 28 N spike)."""
    rig = dataclasses.replace(four_tendon_rig(), arm=four_tendon_rig().arm.with_integrator("rosw"))
    times, tendons, signs, _ = merge_programmes(bend_programmes(rig, 45.0, 20.0, 200.0), 4)
    t = np.arange(1, 1401) * 1e-3
    keep = times <= t[-1]
    fast = SpatialPlant(rig)
    steps = (times[keep], tendons[keep], signs[keep])
    out = fast.advance(t, *steps)
    ref_rig = dataclasses.replace(rig, arm=rig.arm.with_integrator("rk4"))
    ref = SpatialPlant(ref_rig, max_step=fast.max_step / 4).advance(t, *steps)
    assert fast.transitions > 20
    assert np.max(np.abs(out["output"] - ref["output"])) < BAND_SAMPLE_N
    assert np.max(np.abs(out["output"].max(axis=0) - ref["output"].max(axis=0))) < BAND_PEAK_N
    assert np.max(np.linalg.norm(out["tip"] - ref["tip"], axis=1)) < 5e-4  # m


def _release_energy(params):
    p = params.replace(actuator="ideal", amp_bandwidth_hz=0.0, **UNDAMPED)
    plant = ArmPlant(p)
    e_rest = plant.energy()
    eq = equilibrium(p, 0.015)
    y = np.array(model_arrays(p).y_rest)
    y[: p.n_elements] = eq.q
    plant.set_state(y, position_steps=0)
    e0 = plant.energy()
    energies, tensions = [], []
    for t in np.arange(1, 201) * 2e-3:
        tensions.append(plant.advance([t], raw=True)[0])
        energies.append(plant.energy())
    return (np.array(energies) - e0) / abs(e0 - e_rest), np.array(tensions), plant.transitions


def test_energy_without_damping_only_falls_and_less_with_a_finer_step():
    """Let go bent, cable slackening and snapping back: the implicit step damps what it cannot resolve (it
    never adds energy), and the loss shrinks with the step."""
    runs = [_release_energy(ROSW.replace(max_step=h)) for h in (5e-4, 1.25e-4, 3.125e-5)]
    for change, tensions, transitions in runs:
        assert transitions >= 10 and tensions.min() == 0.0 and tensions.max() > 0.5
        assert change.max() < 1e-9  # in units of the released energy
    losses = [-change[-1] for change, _, _ in runs]
    assert losses[2] < 0.01 and losses[2] < losses[1] / 4 < losses[0] / 4


def test_spatial_and_planar_implicit_steps_agree_on_one_tendon():
    prog, _ = experiment_programme(200.0, 20.0)
    st, sg = prog.step_times()
    t = np.arange(1, 2001) * 1e-3
    sel = st <= t[-1]
    rig = paper_rig()
    rig = dataclasses.replace(rig, arm=rig.arm.with_integrator("rosw"))
    spatial = SpatialPlant(rig).advance(t, st[sel], np.zeros(int(sel.sum()), dtype=np.int64), sg[sel])
    planar = ArmPlant(ROSW).advance(t, st[sel], sg[sel])
    np.testing.assert_allclose(spatial["output"][:, 0], planar, rtol=0, atol=1e-8)


def test_integrator_is_a_parameter_and_refused_when_unknown():
    assert RIG.integrator == "rk4" and RIG.max_step == 2.5e-4 and ROSW.max_step == 5e-4
    assert (RigParameters().integrator, RigParameters().max_step) == ("rosw", 5e-4)  # the default
    with pytest.raises(ValueError, match="integrator must be one of"):
        RIG.replace(integrator="euler")
    with pytest.raises(ValueError, match="integrator must be one of"):
        RIG.with_integrator("euler")



@pytest.mark.parametrize("h", [1e-300, 1e-160, 1e-30])
def test_a_sliver_of_a_step_stays_finite_with_four_tendons(h):
    """A piece of a step far shorter than any physics (a transition's search can end next to a kink marked
    with +-1e-300 and leave such a piece) is integrated with ``T = 0``: the Woodbury form of the four-tendon
    solve divides by ``beta = (gamma h)^2``, which underflows to 0 below about 1e-154 s. Found in a four-
    tendon random tip stream at 0.5 ms: its state went NaN at 6.32 s, at 0.25 ms and 1 ms it ran through."""
    from helpers.virtual.spatial import _kernel as sk
    from helpers.virtual.spatial.plant import kernel_arrays

    rig = dataclasses.replace(four_tendon_rig(), arm=RigParameters().with_integrator("rosw"))
    a = kernel_arrays(rig)
    n, nt, y = a.mb.shape[0], a.tp.shape[0], a.y_rest.copy()
    wb, wt, sp = np.zeros((n, sk.N_WB)), np.zeros((nt, n + 1, sk.N_WT)), np.zeros(sk.N_SP + 3 * n)
    wfb, wft, wfs = np.zeros((n, sk.N_WFB)), np.zeros((2, nt, 3 * n)), np.zeros(sk.N_WFS)
    k1, st, out, bufs = np.empty(y.size), np.zeros((4, nt)), np.empty(y.size), np.empty((10, y.size))
    drive = np.zeros(nt)
    sk.rhs(y, k1, drive, a.geo, a.mb, a.Jd, a.Jp, a.tp, a.W, a.cw, wb, wt, sp, st)
    taut1, taut2 = np.empty(nt, dtype=np.bool_), np.empty(nt, dtype=np.bool_)
    sk._branch(st, taut1, taut2, nt)
    sk.wgeom(a.geo, a.tp, wb, wt, sp, taut1, taut2, wfb, wft, wfs)
    sk._step(sk.SCHEME_ROSW, y, k1, h, drive, a.geo, a.mb, a.Jd, a.Jp, a.tp, a.W, a.cw, wb, wt, sp, st, wfb,
             wft, wfs, bufs, out)  # fmt: skip
    assert np.all(np.isfinite(out))
    assert np.allclose(out, y, rtol=0, atol=1e-12)  # nothing happens in a sliver
