"""The spatial twin in time and at its hardest: the long oracles (slow suite).

- the compiled articulated-body kernel against the dense Lagrangian (bent, twisted, every tendon taut, one
  slack), for the paper's rig and the four-tendon rigs;
- one tendon reduces to today's rig in time: the paper's rig through the spatial twin gives the planar twin's
  noise-free Table II (peak within 0.05 N, overshoot within 0.5 pp, settling within what one ADC count of
  band moves it), and its frequency map every 5 mm from 0 to 40 mm within 0.2 %;
- energy: without damping the kernel conserves it through slack and re-engagement of four tendons;
- chunked calls give the same samples as one call;
- convergence at the largest deflection along a tendon and between two tendons against a 4x finer rod;
- antagonism: the dominant frequency a ring-down in time shows against the statics' prediction, as the
  pretension of an antagonistic pair rises.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from helpers.board.programmes import experiment_programme
from helpers.paper import numbers as paper
from helpers.paper.metrics import recording_metrics
from helpers.paper.shapers import design_tdfs
from helpers.virtual import RigParameters, simulate
from helpers.virtual.spatial import _kernel as kern
from helpers.virtual.spatial.direction_map import bend_equilibrium
from helpers.virtual.spatial.plant import SpatialPlant, kernel_arrays
from helpers.virtual.spatial.reference import dense_rhs, energy
from helpers.virtual.spatial.rig import four_tendon_rig, hanging_rig, paper_rig
from helpers.virtual.spatial.simulate import simulate_spatial
from helpers.virtual.spatial.statics import equilibrium, equilibrium_state, linearise, spatial_model
from helpers.virtual.statics import frequency_map as planar_frequency_map

pytestmark = pytest.mark.slow


def _state(rig, seed: int, slack: int | None = None):
    model = spatial_model(rig)
    rng = np.random.default_rng(seed)
    a = kernel_arrays(rig)
    n, nt = a.n, a.nt
    y = a.y_rest.copy()
    y[: 3 * n] += rng.normal(0.0, 0.05, 3 * n)
    y[3 * n : 6 * n] = rng.normal(0.0, 1.0, 3 * n)
    y[6 * n : 6 * n + nt] += rng.normal(0.0, 1e-3, nt)
    y[6 * n + nt : 6 * n + 2 * nt] = rng.normal(0.0, 1.0, nt)
    ell = model.chain.tendon_lengths(y[: 3 * n])
    x = model.ell_ref_arm - ell + rng.uniform(2e-5, 8e-5, nt)
    if slack is not None:
        x[slack] -= 2e-3
    y[6 * n + 2 * nt : 6 * n + 3 * nt] = x
    y[6 * n + 3 * nt :] = rng.normal(0.0, 0.01, nt)
    return y, rng.normal(0.0, 1e-3, nt)


@pytest.mark.parametrize(
    ("rig", "slack"), [(paper_rig(), None), (four_tendon_rig(), None), (hanging_rig(), 2)]
)
def test_kernel_right_hand_side_equals_the_dense_lagrangian(rig, slack):
    a = kernel_arrays(rig)
    for seed in (1, 2):
        y, drive = _state(rig, seed, slack)
        wb, wt, sp = kern.workspaces(a.n, a.nt, a.n)
        st = np.zeros((4, a.nt))
        dy = np.empty_like(y)
        kern.rhs(y, dy, drive, a.geo, a.mb, a.Jd, a.Jp, a.tp, a.W, a.cw, wb, wt, sp, st)
        ref, lam2 = dense_rhs(rig, y, drive)
        assert np.allclose(st[3], lam2, rtol=1e-10, atol=1e-9)
        if slack is not None:
            assert lam2[slack] == 0.0 and np.all(np.delete(lam2, slack) > 0)
        else:
            assert np.all(lam2 > 0)
        assert np.max(np.abs(dy - ref)) < 1e-9 * np.max(np.abs(ref))


@pytest.fixture(scope="module")
def table_ii_pairs():
    zv, zvd = design_tdfs()
    shapers = {"unshaped": None, "zv": zv, "zvd": zvd}
    plant = SpatialPlant(paper_rig())
    out = []
    for v, x in paper.TABLE_I_CONDITIONS:
        for system, shaper in shapers.items():
            prog, _ = experiment_programme(v, x, shaper=shaper)
            planar = simulate(prog, params=RigParameters(), seed=None)
            spatial = simulate_spatial([prog], plant=plant, seed=None)
            out.append((v, x, system, planar, spatial))
    return out


def _one_count_settling_spread(frame: pd.DataFrame, newtons_per_count: float) -> pd.Series:
    """How far each motion's settling time moves when its band is one ADC count wider or narrower (ms)."""
    base = recording_metrics(frame).set_index("motion")
    spread = {}
    for motion, row in base.iterrows():
        step = abs(row["yf_n"] - row["y0_n"])
        bands = [0.05 + k * newtons_per_count / step for k in (-1, 0, 1)]
        times = [recording_metrics(frame, band=b).set_index("motion").loc[motion, "settling_ms"]
                 for b in bands]  # fmt: skip
        spread[motion] = float(np.nanmax(times) - np.nanmin(times))
    return pd.Series(spread)


def test_one_tendon_gives_the_planar_rigs_table_ii(table_ii_pairs):
    worst = {"peak_n": 0.0, "overshoot_pct": 0.0}
    for v, x, system, planar, spatial in table_ii_pairs:
        a = recording_metrics(planar.frame("output")).set_index("motion")
        b = recording_metrics(spatial.frame(0, "output")).set_index("motion")
        spread = _one_count_settling_spread(planar.frame("output"), planar.newtons_per_count)
        for motion in ("Up", "Down"):
            dp = abs(a.loc[motion, "peak_n"] - b.loc[motion, "peak_n"])
            do = abs(a.loc[motion, "overshoot_pct"] - b.loc[motion, "overshoot_pct"])
            ds = abs(a.loc[motion, "settling_ms"] - b.loc[motion, "settling_ms"])
            assert dp <= 0.05 and do <= 0.5, (v, x, system, motion, dp, do)
            assert ds <= max(1.0, spread[motion]), (v, x, system, motion, ds, spread[motion])
            worst = {"peak_n": max(worst["peak_n"], dp), "overshoot_pct": max(worst["overshoot_pct"], do)}
        assert np.max(np.abs(planar.output - spatial.output[:, 0])) < 1e-6
        assert np.max(np.abs(spatial.q[:, 0::3])) < 1e-12  # nothing leaves the plane
    assert worst["peak_n"] < 1e-6  # measured: 1e-11 N, 1e-9 pp


def test_energy_is_conserved_without_damping_through_slack_and_snaps():
    # the four-tendon arm held bent towards 45 deg, then tendons 1 and 2 let go by 2 mm at once: they go
    # slack, the arm swings back against 3 and 4, and the cables go slack and snap taut again
    # RK4 at fine steps conserves it; the implicit step only loses energy (tests/test_integrators.py)
    arm = RigParameters(alpha=0.0, beta_chord=0.0, floor_zeta=0.0, rotor_zeta=0.0, carriage_zeta=0.0)
    arm = arm.with_integrator("rk4")
    rig = four_tendon_rig(arm)
    y, drive = equilibrium_state(rig, bend_equilibrium(rig, 45.0, 15.0))
    released = drive - np.array([1, 1, 0, 0]) * 8 * rig.step_angle(0)
    drifts = []
    for h in (5e-5, 2.5e-5):
        plant = SpatialPlant(rig, max_step=h)
        e_rest = energy(rig, plant.state, np.zeros(4))
        plant.set_state(y, drive=released)
        e0 = energy(rig, y, released)
        es, tensions = [], []
        for k in range(1, 41):
            tensions.append(plant.advance([0.005 * k])["tension"][0])
            es.append(energy(rig, plant.state, released))
        tensions = np.array(tensions)
        assert plant.transitions >= 4 and tensions[:, 0].min() == 0.0 and tensions.max() > 2.0
        drifts.append(max(abs(e - e0) for e in es) / abs(e0 - e_rest))
    assert drifts[1] < 1e-3 and drifts[1] < drifts[0] / 4, drifts


def test_chunked_advance_equals_one_call_and_reset():
    rig = hanging_rig()
    plant = SpatialPlant(rig, max_step=1.0 / 6000)
    t = np.arange(1, 301) * 1e-3
    st = np.array([0.05, 0.0502, 0.06, 0.061, 0.2])
    tk = np.array([0, 1, 0, 3, 0])
    sg = np.array([1.0, 1.0, 1.0, -1.0, -1.0])
    one = plant.advance(t, st, tk, sg)["output"]
    plant.reset()
    first = plant.advance(t[:100], st[:4], tk[:4], sg[:4])["output"]
    parts = [first, plant.advance(t[100:], st[4:], tk[4:], sg[4:])["output"]]
    assert np.array_equal(np.concatenate(parts), one)
    assert list(plant.position_steps) == [1, 1, 0, -1]


@pytest.mark.parametrize("direction_deg", [0.0, 45.0])
def test_convergence_at_the_largest_deflection_against_a_4x_finer_rod(direction_deg):
    # along tendon 1 and between tendons 1 and 2, 40 mm of cable on the horizontal four-tendon rig: static
    # tensions within 1 %, the two lowest modes (spools held) within 0.5 %
    coarse = four_tendon_rig()
    fine = coarse.replace(arm=coarse.arm.replace(elements_per_disc=4))
    results = []
    for rig in (coarse, fine):
        eq = bend_equilibrium(rig, direction_deg, 40.0)
        modes = linearise(rig, eq, rotor="locked").modes()
        results.append((eq.tension, modes.omega_d.values[:2]))
    (tc, wc), (tf, wf) = results
    pulled = tc > 1.01 * coarse.pretensions
    assert pulled.any()
    assert np.all(np.abs(tc[pulled] / tf[pulled] - 1) < 0.01)
    assert np.all(np.abs(wc / wf - 1) < 0.005), (wc, wf)


def _ringdown_frequency(t: np.ndarray, y: np.ndarray) -> float:
    """Damped-sine fit of a ring-down (frequency, rad/s), from the zero crossings' spacing refined by lsq."""
    from scipy.optimize import curve_fit

    y = y - np.mean(y[-200:])
    zc = np.flatnonzero(np.diff(np.sign(y)) != 0)
    w0 = math.pi / np.median(np.diff(t[zc]))

    def model(tt, A, s, w, ph, c):
        return A * np.exp(-s * tt) * np.cos(w * tt + ph) + c

    p, _ = curve_fit(model, t - t[0], y, p0=[np.max(np.abs(y)), 1.0, w0, 0.0, 0.0], maxfev=20000)
    return float(p[2])


def test_antagonistic_pretension_changes_the_dominant_frequency_as_the_statics_predict():
    # the hanging rig, pretension of tendons 1 and 3 raised: a one-step nudge of tendon 1 (it stretches the
    # locked pair by a few newtons), then the ring-down of tendon 1's tension in time, against the statics'
    # prediction: the dominant mode (rotors free) about the equilibrium with tendon 1's spool one step on
    base = hanging_rig()
    predicted, measured = [], []
    for pre in (1.0, 5.0, 10.0):
        rig = base.replace(tendons=tuple(t.replace(pretension_n=pre) if i in (0, 2) else t
                                         for i, t in enumerate(base.tendons)))  # fmt: skip
        eq = equilibrium(rig, [rig.cable_per_step(0), 0.0, 0.0, 0.0], rotor="free")
        predicted.append(linearise(rig, eq, rotor="free").dominant(0)[0])
        plant = SpatialPlant(rig, max_step=1.0 / 6000)
        t = np.arange(1, 2001) * 1e-3
        out = plant.advance(t, [0.0101], [0], [1.0])["tension"][:, 0]
        assert abs(out[-1] - eq.tension[0]) < 0.02  # it settles where the statics put it
        sel = t > 0.3
        measured.append(_ringdown_frequency(t[sel], out[sel]))
    predicted, measured = np.array(predicted), np.array(measured)
    assert np.all(np.abs(measured / predicted - 1) < 5e-3), (predicted, measured)
    assert np.all(np.diff(predicted) < 0) and predicted[0] / predicted[-1] > 1.05  # pretension softens


def test_one_tendon_frequency_map_over_0_to_40_mm_is_the_planar_rigs():
    # the planar rig's frequency map (helpers.virtual.statics.frequency_map: tension, the two lowest bending
    # modes with the spool held, the dominant mode with the rotor free) against the spatial twin's, every 5 mm
    p = RigParameters()
    rig = paper_rig(p)
    u_mm = np.arange(0.0, 40.1, 5.0)
    ref = planar_frequency_map(p, u_mm)
    eq = None
    for row in ref.itertuples():
        eq = equilibrium(rig, row.u_mm * 1e-3, start=eq)
        modes = linearise(rig, eq, rotor="locked").modes()
        in_plane = modes[modes.in_plane > 0.999].reset_index(drop=True)
        dominant = linearise(rig, eq, rotor="free").dominant(0)
        assert abs(eq.tension[0] / row.static_tension_n - 1) < 1e-3
        rel_err = {
            "omega_d1": abs(in_plane.omega_d[0] / row.omega_d_rad_s - 1),
            "omega_d2": abs(in_plane.omega_d[1] / row.omega_d2_rad_s - 1),
            "dominant omega_d": abs(dominant[0] / row.dominant_omega_d_rad_s - 1),
        }
        assert max(rel_err.values()) < 2e-3, rel_err
        assert abs(dominant[1] / row.dominant_zeta - 1) < 2e-3
