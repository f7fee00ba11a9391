"""The spatial twin as a bare rod ([rod] in a rod's file), and against SoroSim's tip-release tests.

References: Euler-Bernoulli's clamped-free beam (first mode b_1 = 1.8751; the tip deflections under a tip load
F L^3 / 3 EI and under the rod's weight w L^4 / 8 EI), written here by hand; the dense Lagrangian
(helpers.virtual.spatial.reference) for the compiled kernel; and SoroSim's own output in
data/external/sorosim/ (its held pose at t = 0; its tip ringing at 3.13 Hz, the figure measured independently
of this code by a damped-sine fit of test 1's tip over 0-6 s). Nothing is compared with numbers the code
under test computed.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from helpers.__main__ import main
from helpers.base.paths import DATA_DIR
from helpers.paper.identify import identify
from helpers.recordings import RecordingError
from helpers.rigfile import RigFileError, load
from helpers.virtual.sorosim import rod_file_text, to_clamp, to_file
from helpers.virtual.sorosim_file import read_sorosim
from helpers.virtual.spatial import _kernel as kern
from helpers.virtual.spatial import bare_rod
from helpers.virtual.spatial.plant import kernel_arrays
from helpers.virtual.spatial.reference import dense_rhs
from helpers.virtual.spatial.rod_file import load_rod, loads_rod
from helpers.virtual.spatial.statics import spatial_model

SOROSIM = DATA_DIR / "external" / "sorosim"
TEST1 = SOROSIM / "SpringSteelRodMuJoCo_1.txt"
STEEL = dict(length_m=0.5, radius_m=0.5e-3, youngs_modulus_pa=200e9, density_kg_m3=7800.0,
             shear_modulus_pa=200e9 / 2.6)  # fmt: skip


def _rod(segments: int = 20, gravity=(0.0, 0.0, 0.0), tip=(0.0, 0.0, 0.0), mid=(0.0, 0.0, 0.0), **kw):
    text = bare_rod.rod_file_text("steel", **STEEL, gravity=gravity, segments=segments, tip_force_n=tip,
                                  mid_force_n=mid, **kw)  # fmt: skip
    return loads_rod(text)


def _ei() -> float:
    return STEEL["youngs_modulus_pa"] * math.pi * STEEL["radius_m"] ** 4 / 4


def test_a_rod_file_is_read_only_as_a_rod_and_a_rig_reader_refuses_it(tmp_path):
    path = tmp_path / "rod.toml"
    path.write_text(bare_rod.rod_file_text("steel", **STEEL, gravity=(9.81, 0, 0), segments=10))
    rod = load_rod(path)
    assert rod.rod.segments == 10 and rod.rod.radius_mm == pytest.approx(0.5) and rod.n_tendons == 0
    with pytest.raises(RigFileError, match=r"rod.toml: \[rod\]: this file describes a bare rod"):
        load(path)
    with pytest.raises(RigFileError, match=r"\[rod\]: missing table"):
        load_rod(DATA_DIR.parent / "rigs" / "paper.toml")


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda t: t.replace("radius_mm = 0.5\n", ""), r"\[rod\] radius_mm: missing"),
        (lambda t: t.replace("segments = 10", "segments = 0"), r"\[rod\] segments: must be >= 1"),
        (lambda t: t.replace("held_mid_force_n = [0, 0, 0]", "held_mid_force_n = [0, 1, 0]")
         .replace("segments = 10", "segments = 9"), r"segments: 9 is odd"),
        (lambda t: t.replace("radius_mm = 0.5", "radius_mm = 0.0005"), r"radius_mm: .* plausible"),
        (lambda t: t + "\n[hardware]\ntravel_mm = 1\n", r"hardware: a bare rod's file holds only"),
        (lambda t: t.replace("held_tip_force_n = [0, 0, 0]", "held_tip_force_n = [0, 1]"), r"tip_force_n"),
    ],
)
def test_a_bad_rod_file_is_one_line_naming_the_key(edit, message):
    text = bare_rod.rod_file_text("steel", **STEEL, gravity=(9.81, 0, 0), segments=10)
    with pytest.raises(RigFileError, match=message) as info:
        loads_rod(edit(text), source="rod.toml")
    assert len(str(info.value).splitlines()) == 1 and str(info.value).startswith("rod.toml: ")


def test_the_kernel_agrees_with_the_dense_lagrangian_on_a_bent_twisted_bare_rod():
    rod = bare_rod.rod_rig(_rod(8, gravity=(3.0, -9.0, 1.0)), alpha=0.7, beta_chord=1e-5)
    nq = 3 * rod.arm.n_elements
    gen = np.random.default_rng(3)
    y = np.concatenate([gen.normal(0.0, 0.2, nq), gen.normal(0.0, 2.0, nq)])
    expected, _ = dense_rhs(rod, y, np.zeros(0))
    a = kernel_arrays(rod)
    wb, wt, sp = kern.workspaces(a.n, a.nt, a.n)
    got = np.empty_like(y)
    no_tendon = np.zeros(0)
    kern.rhs(y.copy(), got, no_tendon, a.geo, a.mb, a.Jd, a.Jp, a.tp, a.W, a.cw, wb, wt, sp, np.zeros((4, 0)))
    assert np.max(np.abs(got - expected)) < 1e-9 * np.max(np.abs(expected))


def test_the_statics_match_euler_bernoulli_for_small_loads():
    force, n = 1e-3, 16  # N at the tip: 0.7 % of the length
    rig = _rod(n, tip=(force, 0.0, 0.0))
    twin = bare_rod.rod_rig(rig)
    tip = spatial_model(twin).chain.tip(bare_rod.held_state(twin, bare_rod.held_forces(rig, twin)))
    assert tip[0] == pytest.approx(force * STEEL["length_m"] ** 3 / (3 * _ei()), rel=0.01)
    g = 0.2  # m/s^2 across the rod: a small sag
    sagging = bare_rod.rod_rig(_rod(n, gravity=(g, 0.0, 0.0)))
    w = STEEL["density_kg_m3"] * math.pi * STEEL["radius_m"] ** 2 * g
    assert spatial_model(sagging).chain.tip(spatial_model(sagging).q_rest)[0] == pytest.approx(
        w * STEEL["length_m"] ** 4 / (8 * _ei()), rel=0.01
    )


def test_the_first_mode_converges_to_euler_bernoulli():
    area = math.pi * STEEL["radius_m"] ** 2
    mass = STEEL["density_kg_m3"] * area
    f1 = 1.8751040687**2 / (2 * math.pi) * math.sqrt(_ei() / (mass * STEEL["length_m"] ** 4))
    errors = [abs(bare_rod.first_modes(bare_rod.rod_rig(_rod(n)), 1)[0][0] / f1 - 1) for n in (8, 16, 32)]
    assert errors[2] < 5e-4
    assert errors[0] / errors[1] == pytest.approx(4.0, rel=0.1)  # second order in the element length
    assert errors[1] / errors[2] == pytest.approx(4.0, rel=0.1)


def test_the_held_state_of_sorosim_test_1_is_the_files_pose_at_release():
    test = read_sorosim(TEST1)
    rig = loads_rod(rod_file_text(test, 20))
    twin = bare_rod.rod_rig(rig)
    nodes = spatial_model(twin).chain.positions(bare_rod.held_state(twin, bare_rod.held_forces(rig, twin)))
    assert np.linalg.norm(to_file(nodes[-1]) - test.tip[0]) < 1e-3  # m: of a 261 mm deflection
    assert np.linalg.norm(to_file(nodes[10]) - test.mid[0]) < 1e-3
    assert to_file(np.array(to_clamp([1.0, 2.0, 3.0]))) == pytest.approx([1.0, 2.0, 3.0])


def test_the_released_rod_rings_at_the_files_frequency():
    """Ten segments, three seconds: the twin's tip within 1 % of the 3.13 Hz measured on the file."""
    test = read_sorosim(TEST1)
    rig = loads_rod(rod_file_text(test, 10, 1.57))
    twin = bare_rod.rod_rig(rig)
    times = test.t[test.t <= 3.0]
    rel = bare_rod.release(twin, bare_rod.held_state(twin, bare_rod.held_forces(rig, twin)), times)
    tip = to_file(rel.tip)
    axis = test.tip[0] - test.tip[-1]
    f = identify(times, (tip - tip[-1]) @ (axis / np.linalg.norm(axis))).omega_d / (2 * math.pi)
    assert f == pytest.approx(3.13, rel=0.01)


def _status_5(capsys, *argv: str) -> str:
    assert main(["virtual-rig", "sorosim", *argv]) == 5
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_a_bad_sorosim_file_is_one_line_naming_the_file_and_line(tmp_path, capsys):
    lines = TEST1.read_text().splitlines()
    description = "sorosim_dynamics_steel.json"
    (tmp_path / description).write_text((SOROSIM / description).read_text())
    one_line = tmp_path / "SpringSteelRodMuJoCo_2.txt"
    one_line.write_text(lines[0] + "\n")
    assert "line 2: missing" in _status_5(capsys, str(one_line))
    cut = tmp_path / "SpringSteelRodMuJoCo_3.txt"
    cut.write_text("\n".join(lines[:500]) + "\n" + lines[500][:20] + "\n")
    assert "SpringSteelRodMuJoCo_3.txt: line 501" in _status_5(capsys, str(cut))
    alone = tmp_path / "other" / "SpringSteelRodMuJoCo_1.txt"
    alone.parent.mkdir()
    alone.write_text(TEST1.read_text())
    assert "no description of the rod" in _status_5(capsys, str(alone))
    with pytest.raises(RecordingError, match="no such file"):
        read_sorosim(tmp_path / "absent.txt")


@pytest.mark.slow
def test_the_command_compares_the_twin_with_test_1_within_1_percent(capsys):
    assert main(["virtual-rig", "sorosim", str(TEST1)]) == 0
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if line.startswith("tip frequency"))
    file_hz, twin_hz = (float(v) for v in row.split()[-4:-2])
    assert file_hz == pytest.approx(3.13, abs=0.005)  # the figure measured independently on the file
    assert twin_hz == pytest.approx(file_hz, rel=0.01)
    assert "FITTED" in out and "not a validation" in out and "convergence" in out
    assert "RMS tip distance 0-2 s" in out and "RMS tip distance 0-10 s" in out and "phase lag at 2 s" in out
