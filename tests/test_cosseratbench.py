"""The spatial twin as a cosseratbench solver (the optional [cosseratbench] extra; slow suite only).

Skipped when cosseratbench is not installed. The references are the benchmark's own (Euler-Bernoulli tip
deflection for the cantilever) or textbook ones computed here by hand (a clamped-free beam's first mode,
beta_1 = 1.8751), never the twin's.
"""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

cosseratbench = pytest.importorskip("cosseratbench")

from cosseratbench import EndCondition, Material, Rod, Scenario, registry, run  # noqa: E402

from helpers.base.paths import REPO_ROOT  # noqa: E402
from helpers.virtual.spatial.cosseratbench_solver import TwinSolver  # noqa: E402

pytestmark = pytest.mark.slow


def test_the_entry_point_names_the_solver():
    entry = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())["project"]["entry-points"]
    target = entry["cosseratbench.solvers"]["continuum-twin"]
    module, name = target.split(":")
    assert module == TwinSolver.__module__ and name == TwinSolver.__name__
    assert TwinSolver().name == "continuum-twin"


def test_the_cantilever_scores_against_euler_bernoulli_and_converges():
    experiment = registry.load_experiment("cantilever")
    errors = {n: run(experiment, TwinSolver(), n_elements=n).metrics["tip_deflection_error"]
              for n in (10, 40)}  # fmt: skip
    assert errors[40] < 2e-3 and errors[40] < errors[10]


@pytest.mark.parametrize("name", ["pendulum", "catenary", "twist", "capstan", "crossing", "pile"])
def test_experiments_outside_the_twins_kind_are_reported_unsupported(name):
    result = run(registry.load_experiment(name), TwinSolver(), n_elements=10)
    assert result.outcome == "unsupported" and result.missing
    if name in ("pendulum", "catenary"):
        assert "pinned start" in result.missing[0]


def test_a_dynamic_release_keeps_its_energy_and_rings_at_the_first_mode():
    """An undamped horizontal steel rod, clamped, released straight under gravity: it swings about its sag."""
    length, radius, e_mod, rho, g = 0.3, 0.5e-3, 200e9, 7800.0, 9.81
    steel = Material(e_mod, e_mod / 2.6, rho)
    rod = Rod(centerline=((0, 0, 0), (length, 0, 0)), radius=radius, material=steel, normal=(0, 0, 1),
              start=EndCondition.CLAMPED)  # fmt: skip
    scenario = Scenario(rods=(rod,), duration=2.0, gravity=(0, 0, -g), self_contact=False)
    traj = TwinSolver().run(scenario, n_elements=20, n_frames=2001)
    z = traj.positions[0][:, -1, 2]
    ei = e_mod * math.pi * radius**4 / 4
    f1 = 1.8751040687**2 / (2 * math.pi) * math.sqrt(ei / (rho * math.pi * radius**2 * length**4))
    spectrum = np.abs(np.fft.rfft((z - z.mean()) * np.hanning(z.size), 16 * z.size))
    freqs = np.fft.rfftfreq(16 * z.size, traj.times[1] - traj.times[0])
    assert freqs[np.argmax(spectrum)] == pytest.approx(f1, rel=0.01)
    first, last = z[traj.times <= 1 / f1], z[traj.times >= 2.0 - 1 / f1]
    assert np.ptp(last) == pytest.approx(np.ptp(first), rel=0.02)  # no damping added, none lost
