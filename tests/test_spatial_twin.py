"""The spatial twin's description, statics, small vibrations and frequency map (fast oracles).

The time-domain oracles (the compiled kernel against the dense Lagrangian and against the planar rig's
Table II, energy, antagonism in time, convergence against a finer rod) are in test_spatial_twin_slow.py.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pandas as pd
import pytest

from helpers.__main__ import main
from helpers.base.paths import REPO_ROOT
from helpers.virtual import RigParameters
from helpers.virtual import statics as planar
from helpers.virtual.spatial.chain import Control, SpatialChain
from helpers.virtual.spatial.direction_map import bend_command, bend_equilibrium, frequency_map, parse_values
from helpers.virtual.spatial.reference import energy
from helpers.virtual.spatial.rig import (
    PRESETS,
    SpatialRig,
    TendonSpec,
    four_tendon_rig,
    hanging_rig,
    paper_rig,
    preset,
)
from helpers.virtual.spatial.statics import equilibrium, linearise, spatial_model


# --- the rig description --------------------------------------------------------------------------------
def test_presets_are_the_three_rigs_of_the_docs():
    paper, four, hang = paper_rig(), four_tendon_rig(), hanging_rig()
    assert set(PRESETS) == {"paper", "four-tendon", "hanging"}
    assert paper.n_tendons == 1 and paper.gravity_direction == (-1.0, 0.0, 0.0)
    assert [t.angle_deg for t in four.tendons] == [0.0, 90.0, 180.0, 270.0]
    assert four.gravity_direction == (-1.0, 0.0, 0.0) and hang.gravity_direction == (0.0, 0.0, 1.0)
    arm = RigParameters()
    for t in four.tendons:  # the paper's stepper, spool, load cell and the tuned cable on every tendon
        assert t.offset_mm == pytest.approx(arm.r * 1e3)
        assert (t.spool_diameter_mm, t.steps_per_rev) == (65.0, 800)
        assert t.holding_torque_n_m == arm.holding_torque and t.load_cell_range_n == arm.span_n
        assert t.cable_stiffness_n_m == pytest.approx(arm.k_cable)
    assert preset("hanging") == hang


def test_tendon_fields_are_the_documented_rig_file_keys():
    doc = (REPO_ROOT / "docs" / "spatial_twin.md").read_text()
    keys = list(TendonSpec().to_dict())
    assert keys == ["angle_deg", "offset_mm", "spool_diameter_mm", "steps_per_rev", "holding_torque_n_m",
                    "load_cell_range_n", "pretension_n", "cable_stiffness_n_m"]  # fmt: skip
    for key in keys + ["gravity_direction", "shear_modulus_gpa"]:
        assert re.search(rf"`{key}`", doc), f"docs/spatial_twin.md does not document {key}"


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: TendonSpec(offset_mm=-1.0), "offset_mm"),
        (lambda: TendonSpec(steps_per_rev=0), "steps_per_rev"),
        (lambda: TendonSpec(pretension_n=math.nan), "pretension_n"),
        (lambda: SpatialRig(tendons=tuple(TendonSpec(angle_deg=a) for a in range(0, 360, 72))), "1 to 4"),
        (lambda: SpatialRig(tendons=(TendonSpec(), TendonSpec(angle_deg=360.0))), "same angle"),
        (lambda: SpatialRig(gravity_direction=(0.0, 0.0, 0.0)), "gravity_direction"),
        (lambda: SpatialRig(tendons=(TendonSpec(pretension_n=25.0),)), "pull-out"),
        (lambda: SpatialRig(arm=RigParameters(actuator="ideal")), r"stepper\+carriage"),
    ],
)
def test_bad_rigs_are_refused_in_one_line(build, message):
    with pytest.raises(ValueError, match=message) as err:
        build()
    assert "\n" not in str(err.value)


# --- the arm in numpy --------------------------------------------------------------------------------------
def _twisted_state(rig: SpatialRig, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """A bent and twisted shape with every tendon taut (so the bowing's cross terms are on)."""
    model = spatial_model(rig)
    rng = np.random.default_rng(seed)
    q = model.q_rest + rng.normal(0.0, 0.04, model.q_rest.size)
    ell = model.chain.tendon_lengths(q)
    x = model.ell_ref_arm - ell + rng.uniform(2e-5, 6e-5, rig.n_tendons)  # every arm-side cable stretched
    return q, x


def test_gradient_is_the_derivative_of_the_energy():
    # the hand-derived gradient (tendon runs, bowing with its coupled terms, gravity, springs) against the
    # complex-step derivative of the energy written from the positions (reference.energy)
    rig = four_tendon_rig()
    model = spatial_model(rig)
    chain = model.chain
    q, x = _twisted_state(rig)
    ctrl = Control(lam=np.full(4, np.nan), e0=x - model.ell_ref_arm, kinv=1.0 / model.k2)
    grad, lam, _ = chain.potential_grad(q, ctrl)
    assert np.all(lam > 0.5)
    H = chain.bow_matrix(q)
    assert np.max(np.abs(H - np.diag(np.diag(H)))) > 0  # coupled
    nq, nt = chain.nq, 4
    y = np.concatenate([q, np.zeros(nq), model.psi0, np.zeros(nt), x, np.zeros(nt)])
    h = 1e-7
    eye = np.eye(y.size)
    num = np.array([(energy(rig, y + h * eye[k], np.zeros(nt)) - energy(rig, y - h * eye[k], np.zeros(nt)))
                    / (2 * h) for k in range(nq)])  # fmt: skip
    assert np.max(np.abs(num - grad)) < 1e-6 * np.max(np.abs(grad))


def test_bowing_matrix_with_one_tendon_is_the_planar_compliance():
    p = RigParameters()
    rig = paper_rig(p)
    q = spatial_model(rig).q_rest
    theta = planar.model_arrays(p).q_rest
    H_planar = float(planar.ArcChain(p).bow_compliance(theta)[0])
    assert float(SpatialChain(rig).bow_matrix(q)[0, 0]) == pytest.approx(H_planar, rel=1e-12)


# --- one tendon reduces to the planar rig -----------------------------------------------------------------
@pytest.fixture(scope="module")
def reduction():
    p = RigParameters()
    rig = paper_rig(p)
    rows = []
    eq = None
    for u_mm in (0.0, 40.0):
        eq = equilibrium(rig, u_mm * 1e-3, start=eq, du_max=4e-3)
        locked = linearise(rig, eq, rotor="locked").modes()
        in_plane = locked[locked.in_plane > 0.999].reset_index(drop=True)
        free = linearise(rig, eq, rotor="free")
        pe = planar.equilibrium(p, u_mm * 1e-3)
        pl = planar.linearise(p, u_mm * 1e-3, eq=pe, rotor="locked").modes()
        pf = planar.linearise(p, u_mm * 1e-3, eq=pe, rotor="free")
        rows.append({"u_mm": u_mm, "tension": (eq.tension[0], pe.tension),
                     "modes": (in_plane.omega_d.values[:2], pl.omega_d.values[:2]),
                     "dominant": (free.dominant(0)[0], pf.omega_d), "locked": locked})  # fmt: skip
    return rows


def test_one_tendon_static_tension_is_the_planar_rigs(reduction):
    for row in reduction:
        spatial, plane = row["tension"]
        assert abs(spatial / plane - 1) < 1e-3, row["u_mm"]  # the criterion: 0.1 %; measured 1e-12


def test_one_tendon_frequency_map_is_the_planar_rigs(reduction):
    for row in reduction:
        spatial, plane = row["modes"]
        assert np.all(np.abs(spatial / plane - 1) < 2e-3), row["u_mm"]  # 0.2 %; measured 1e-13
        assert abs(row["dominant"][0] / row["dominant"][1] - 1) < 2e-3


def test_one_tendon_rig_is_stable_out_of_its_plane(reduction):
    # the spatial twin adds the sideways and twisting modes the planar rig cannot have; at 0-40 mm they are
    # oscillatory and damped (the planar motion is stable), and the tension does not see them
    for row in reduction:
        m = row["locked"]
        side = m[m.in_plane < 1e-6]
        assert len(side) >= 2 and side.omega_d.min() > 10.0 and (side.zeta > 0).all()
        assert side.weight.max() < 1e-9 * m.weight.max()


# --- symmetry of the hanging rig ------------------------------------------------------------------------
@pytest.fixture(scope="module")
def hanging_pulls():
    rig = hanging_rig()
    out = {}
    for beta in (0.0, 90.0, 180.0, 270.0, 45.0):
        eq = bend_equilibrium(rig, beta, 5.0)
        out[beta] = (eq, linearise(rig, eq, rotor="locked").modes())
    return out


def test_any_one_tendon_pulled_alike_gives_the_same_tension_and_modes(hanging_pulls):
    ref_eq, ref_modes = hanging_pulls[0.0]
    for i, beta in enumerate((0.0, 90.0, 180.0, 270.0)):
        eq, modes = hanging_pulls[beta]
        assert eq.tension[i] == pytest.approx(ref_eq.tension[0], rel=1e-3)
        others = np.delete(eq.tension, i)
        assert np.allclose(others, hanging_rig().pretensions[0], rtol=1e-9)
        assert np.allclose(modes.omega_d.values[:6], ref_modes.omega_d.values[:6], rtol=1e-3)
        assert np.allclose(modes.zeta.values[:6], ref_modes.zeta.values[:6], rtol=1e-3)
    assert ref_eq.tension[0] > 1.5 * hanging_rig().pretensions[0]  # the pull did load the tendon


def test_a_pull_shared_by_two_neighbours_bends_the_arm_in_the_plane_between_them(hanging_pulls):
    eq, modes = hanging_pulls[45.0]
    assert eq.tension[0] == pytest.approx(eq.tension[1], rel=1e-9)
    p = eq.positions
    assert np.max(np.abs(p[:, 0] - p[:, 1])) < 1e-9 * np.max(np.abs(p))  # every node in the plane x = y
    assert p[-1, 0] > 0.02
    az = modes.azimuth_deg.values[:2]
    assert np.all((np.abs(az - 45.0) < 1e-6) | (np.abs(az - 135.0) < 1e-6))  # in the plane or across it


# --- the map over direction ------------------------------------------------------------------------------
def test_bend_command_shares_the_pull_as_cos_and_sin():
    rig = four_tendon_rig()
    u, pulled = bend_command(rig, 30.0, 10.0)
    assert list(pulled) == [True, True, False, False]
    assert u[:2] == pytest.approx([10e-3 * math.cos(math.radians(30)), 10e-3 * math.sin(math.radians(30))])
    with pytest.raises(ValueError, match="no tendon faces 180 deg"):
        bend_command(paper_rig(), 180.0, 5.0)
    with pytest.raises(ValueError, match="bend_mm"):
        bend_command(rig, 0.0, -1.0)


def test_frequency_map_splits_the_modes_with_bend_and_gravity_breaks_the_symmetry(hanging_pulls):
    hang = frequency_map(hanging_rig(), [90.0], [0.0], n_modes=2).iloc[0]
    horiz = linearise(four_tendon_rig()).modes()
    rel_err = hang.omega_d2_rad_s / hang.omega_d1_rad_s - 1
    assert rel_err < 1e-9  # degenerate at rest
    bent = hanging_pulls[0.0][1]
    assert bent.omega_d.iloc[1] / bent.omega_d.iloc[0] - 1 > 0.01  # split once bent (5 mm)
    assert horiz.omega_d.iloc[1] / horiz.omega_d.iloc[0] - 1 > 0.01  # the horizontal arm's weight splits them


def test_parse_values_and_the_command_line(capsys):
    assert parse_values("0:90:45", "x") == (0.0, 45.0)
    assert parse_values("5", "x") == (5.0,)
    with pytest.raises(ValueError, match="--bends"):
        parse_values("a,b", "--bends")
    # docs/beyond_the_paper.md's command: the hanging rig bent 10 mm along tendon 1 and between tendons 1, 2
    readme = "virtual-rig frequency-map --preset hanging --directions 0,45 --bends 10"
    assert readme in (REPO_ROOT / "docs" / "beyond_the_paper.md").read_text()
    assert main(readme.split()) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("direction_deg,bend_mm,u1_mm,tension1_n,u2_mm,tension2_n") and len(out) == 3
    head = out[0].split(",")
    along, between = (dict(zip(head, map(float, line.split(",")), strict=True)) for line in out[1:])
    assert along["tension1_n"] > 1.5 * along["tension2_n"] and along["tip_azimuth_deg"] == 0.0
    assert between["tension1_n"] == pytest.approx(between["tension2_n"])
    assert between["tip_azimuth_deg"] == 45.0
    assert between["omega_d2_rad_s"] > 1.05 * between["omega_d1_rad_s"]  # split by the bend
    assert main(["virtual-rig", "frequency-map", "--directions", "120", "--bends", "5"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no tendon faces 120 deg" in err[0]


def test_plotting_functions_draw_the_map():
    import matplotlib

    matplotlib.use("Agg")
    from helpers.virtual.spatial.plots import direction_map_polar, mode_splitting, shapes_3d

    rows = [{"direction_deg": d, "bend_mm": b, "omega_d1_rad_s": 25 + 0.1 * b, "torsion1": 0.5,
             "omega_d2_rad_s": 26 - 0.1 * b, "torsion2": 0.0, "dominant_omega_d_rad_s": 26.0}
            for d in (0.0, 90.0, 180.0, 270.0) for b in (0.0, 10.0)]  # fmt: skip
    df = pd.DataFrame(rows)
    fig = mode_splitting(df, 90.0, "test")
    assert len(fig.axes[0].lines) >= 3
    assert len(direction_map_polar(df, 2).axes[0].lines) == 2
    assert len(shapes_3d([np.zeros((13, 3))], ["rest"]).axes[0].lines) == 1
    with pytest.raises(ValueError, match="no direction 45"):
        mode_splitting(df, 45.0)


def test_a_slack_tendon_leaves_the_linearisation_finite():
    # three tendons 120 degrees apart on a 10-disc arm, gravity off the axis, the third tendon slack at rest:
    # its carriage is free between two slack cables and drops out; the modes stay finite
    arm = RigParameters(n_discs=10)
    rig = SpatialRig(arm=arm, tendons=tuple(TendonSpec.from_arm(arm, angle_deg=a, pretension_n=p)
                                            for a, p in ((0, 1.0), (120, 1.0), (240, 0.0))),
                     gravity_direction=(0.0, 0.3, 1.0))  # fmt: skip
    for rotor in ("locked", "free"):
        lin = linearise(rig, rotor=rotor)
        modes = lin.modes()
        assert np.all(np.isfinite(modes[["omega_d", "zeta", "weight"]].to_numpy()))
        assert 20.0 < modes.omega_d.iloc[0] < 40.0 and np.all(lin.weights[2] == 0.0)
