"""The spatial twin as a ``cosseratbench`` solver (the optional ``[cosseratbench]`` extra).

``cosseratbench`` (Apache-2.0) scores rod solvers against analytic references and takes new solvers through
its ``cosseratbench.solvers`` entry point; ``pyproject.toml`` registers :class:`TwinSolver` there as
``continuum-twin``. The twin's kind of rod: one rod clamped at its start and free at its end, inextensible and
unshearable (constant-strain elements of bending and twist: :mod:`helpers.virtual.spatial.bare_rod`),
without contact. A scenario outside that (a pinned or driven end, several rods, a bent, stretched or moving
start, a load at the clamp) raises ``NotImplementedError`` naming what, which the benchmark reports as
unsupported; the capabilities it lacks (stretch, shear, contact) are declared, so experiments that need them
are not run.

**How a scenario is run.** The rod becomes a bare rod's file (``docs/rig_file.md``, ``[rod]``:
:func:`helpers.virtual.spatial.bare_rod.rod_file_text`) in the clamp frame (``z`` along the rod, ``x`` its
``normal``), the twin is built from it with ``n_elements`` segments, and:

- a **quasi-static** scenario (the result is equilibrium) is solved by the twin's statics: Newton on its
  potential with gravity and the end's load (:func:`~helpers.virtual.spatial.bare_rod.held_state`), not by
  integrating; its frames are the start and then the equilibrium;
- a **dynamic** scenario is integrated by the twin's kernel (RK4 at
  :func:`~helpers.virtual.spatial.statics.stable_max_step`) with **no damping** (the twin's air drag, wire
  damping and high-mode floor all off: the benchmark forbids added damping), from rest in the straight start.

``python -m helpers.virtual.spatial.cosseratbench_solver`` runs every experiment of the installed benchmark
on the twin and prints one line per run (``docs/external_data.md`` has the scores).
"""

from __future__ import annotations

import math
import sys
from typing import Any

import numpy as np

try:
    from cosseratbench import EndCondition, Scenario, Trajectory
except ModuleNotFoundError as exc:  # the optional extra
    raise ModuleNotFoundError(
        'the cosseratbench solver needs the [cosseratbench] extra: pip install -e ".[cosseratbench]"',
        name=exc.name,
    ) from None

from helpers import __version__
from helpers.virtual.spatial import bare_rod
from helpers.virtual.spatial.chain import skew, so3_functions
from helpers.virtual.spatial.plant import SpatialPlant
from helpers.virtual.spatial.rod_file import loads_rod
from helpers.virtual.spatial.statics import spatial_model, stable_max_step

__all__ = ["TwinSolver", "main"]

STRAIGHT_TOLERANCE = 1e-9
"""Largest distance of a start's centerline point from its chord, in rod lengths (a straight start)."""


def _frame(scenario_rod: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(origin, R)``: the clamp's position and the clamp frame's axes as columns (world = origin + R x)."""
    points = np.asarray(scenario_rod.centerline, dtype=float)
    z = points[-1] - points[0]
    z = z / np.linalg.norm(z)
    n = np.asarray(scenario_rod.normal, dtype=float)
    x = n - (n @ z) * z
    x = x / np.linalg.norm(x)
    return points[0], np.column_stack([x, np.cross(z, x), z])


def _check(scenario: Scenario) -> Any:
    """The one rod of ``scenario``, if it is of the twin's kind; else ``NotImplementedError`` naming why."""
    if len(scenario.rods) != 1:
        raise NotImplementedError(f"{len(scenario.rods)} rods (the twin is one rod)")
    rod = scenario.rods[0]
    if rod.start is not EndCondition.CLAMPED:
        raise NotImplementedError(f"a {rod.start.value} start (the twin's rod is clamped at its start)")
    if rod.end is not EndCondition.FREE:
        raise NotImplementedError(f"a {rod.end.value} end (the twin's rod is free at its end)")
    if rod.start_motion is not None or rod.end_motion is not None:
        raise NotImplementedError("a driven end (the twin's clamp holds still)")
    points = np.asarray(rod.centerline, dtype=float)
    chord = points[-1] - points[0]
    length = float(np.linalg.norm(chord))
    off = points - points[0]
    off = off - np.outer(off @ chord / length**2, chord)
    if np.max(np.linalg.norm(off, axis=1)) > STRAIGHT_TOLERANCE * length:
        raise NotImplementedError("a bent start (the twin starts straight)")
    if abs(rod.length - length) > 1e-9 * length:
        raise NotImplementedError("a stretched start (the twin's rod is inextensible)")
    if any(load.at.value != "end" for load in rod.loads):
        raise NotImplementedError("a load at the clamp")
    if rod.loads and not scenario.quasi_static:
        raise NotImplementedError("a constant load in a dynamic run (the twin's integrator applies none)")
    return rod


class TwinSolver:
    """The spatial twin as a ``cosseratbench`` solver (``continuum-twin``); see the module docstring."""

    name = "continuum-twin"
    backend_version = __version__
    capabilities: frozenset = frozenset()  # no stretch, no shear, no contact of any kind

    def __init__(self, time_step_scale: float = 1.0) -> None:
        if not (math.isfinite(time_step_scale) and 0 < time_step_scale <= 1):
            raise ValueError(f"time_step_scale must lie in (0, 1], got {time_step_scale!r}")
        self.time_step_scale = float(time_step_scale)

    def _rig(self, scenario: Scenario, n_elements: int) -> tuple[Any, Any, np.ndarray, np.ndarray, dict]:
        rod = _check(scenario)
        origin, R = _frame(rod)
        tip_force = sum((np.asarray(load.force, dtype=float) for load in rod.loads), np.zeros(3))
        m = rod.material
        text = bare_rod.rod_file_text(
            "cosseratbench", length_m=rod.length, radius_m=rod.radius, youngs_modulus_pa=m.youngs_modulus,
            density_kg_m3=m.density, shear_modulus_pa=m.shear_modulus,
            gravity=R.T @ np.asarray(scenario.gravity, dtype=float), segments=n_elements,
            tip_force_n=R.T @ tip_force, comments=("a cosseratbench scenario's rod (clamp frame)",),
        )  # fmt: skip
        rig = loads_rod(text, source="<cosseratbench scenario>")
        twin = bare_rod.rod_rig(rig, alpha=0.0, beta_chord=0.0, floor_zeta=0.0)
        return rig, twin, origin, R, bare_rod.held_forces(rig, twin)

    def _step(self, twin: Any) -> float:
        return self.time_step_scale * stable_max_step(twin)

    def settings(self, scenario: Scenario, *, n_elements: int, n_frames: int) -> dict:
        """The numerical choices this adapter makes for ``scenario`` (none for one it cannot run)."""
        try:
            _, twin, _, _, _ = self._rig(scenario, n_elements)
        except NotImplementedError as exc:  # run() says it again, and the benchmark reports it unsupported
            return {"unsupported": str(exc)}
        if scenario.quasi_static:
            return {"method": "statics: Newton on the twin's potential (exact Hessian), not integrated",
                    "damping": "none"}  # fmt: skip
        return {"integrator": "classical RK4 (explicit), the spatial twin's compiled kernel",
                "time_step": self._step(twin), "damping": "none (drag, wire damping, floor off)"}  # fmt: skip

    def run(self, scenario: Scenario, *, n_elements: int, n_frames: int) -> Trajectory:
        """Simulate ``scenario`` with ``n_elements`` elements; ``n_frames`` frames from 0 to its duration."""
        rig, twin, origin, R, forces = self._rig(scenario, n_elements)
        times = np.linspace(0.0, scenario.duration, n_frames)
        chain = spatial_model(twin).chain
        q0 = np.zeros(chain.nq)
        if scenario.quasi_static:
            q = np.vstack([q0, np.tile(bare_rod.held_state(twin, forces), (n_frames - 1, 1))])
        else:
            plant = SpatialPlant(twin, max_step=self._step(twin))
            plant.set_state(np.zeros_like(plant.state))
            out = plant.advance(times[1:])
            q = np.vstack([q0, out["q"]])
            if not np.all(np.isfinite(q)):
                raise FloatingPointError("the twin's integration diverged")
        kin = chain.kinematics(q)
        positions = origin + kin["p"] @ R.T
        half = so3_functions((0.25 * kin["phi"] ** 2).sum(-1))
        K = skew(0.5 * kin["phi"])
        mid = np.eye(3) + half[0][..., None, None] * K + half[1][..., None, None] * (K @ K)
        d1 = (kin["R"][:, :-1] @ mid)[..., :, 0] @ R.T  # each element's x axis at its middle
        return Trajectory(times, (positions,), (d1,))


def main(argv: list[str] | None = None) -> int:
    """Run every installed experiment on the twin at its default resolution; one line per run."""
    from cosseratbench import registry, run
    from cosseratbench.runs import describe

    names = (argv if argv else None) or registry.names(registry.EXPERIMENTS)
    solver = TwinSolver()
    for name in names:
        result = run(registry.load_experiment(name), solver)
        print(f"{name:12s} continuum-twin n={result.n_elements:<4d} {describe(result.summary())}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
