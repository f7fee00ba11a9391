"""A bare rod in the spatial twin: a rod file's rod (no discs, no cable), held deflected and released.

The spatial twin's arc chain (:mod:`helpers.virtual.spatial.chain`, the compiled kernel behind
:class:`~helpers.virtual.spatial.plant.SpatialPlant`) without tendons, discs or actuators: ``segments``
constant-strain elements of the rod file's length, radius and material (``docs/rig_file.md``, ``[rod]``),
gravity along its direction, and the damping the file states (none unless it says). Nothing is tuned here.

- :func:`rod_rig`: the twin of a bare rod's file (:func:`helpers.virtual.spatial.rod_file.load_rod`);
- :func:`held_state`: the equilibrium under gravity and the file's held forces on the middle node and the tip
  (Newton on the twin's potential with the exact Hessian, gravity and forces raised together in
  :data:`HOLD_STAGES` steps);
- :func:`release`: the forces removed at ``t = 0``, the rod integrated from rest in the held state (the
  kernel's RK4 at :func:`~helpers.virtual.spatial.statics.stable_max_step`), the tip and the middle sampled;
- :func:`first_modes`: the rod's lowest modes about its rest under gravity (the statics' linearisation).

The frame is the clamp frame: ``z`` along the unloaded rod, from the clamp to the tip.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from helpers.rigfile.model import RigFile
from helpers.virtual.parameters import RigParameters
from helpers.virtual.spatial.chain import Control
from helpers.virtual.spatial.plant import SpatialPlant
from helpers.virtual.spatial.rig import SpatialRig
from helpers.virtual.spatial.statics import (
    _newton,
    linearise,
    rest_equilibrium,
    spatial_model,
    stable_max_step,
)

__all__ = [
    "HOLD_STAGES", "rod_file_text", "rod_rig", "held_forces", "held_state", "Release", "release",
    "first_modes",
]  # fmt: skip

HOLD_STAGES = 10
"""Continuation steps from the straight rod to the held state (gravity and forces raised together)."""


def _vector(v: npt.ArrayLike) -> str:
    return "[" + ", ".join(f"{float(c):.10g}" for c in np.asarray(v, dtype=float)) + "]"


def rod_file_text(
    name: str,
    *,
    length_m: float,
    radius_m: float,
    youngs_modulus_pa: float,
    density_kg_m3: float,
    shear_modulus_pa: float,
    gravity: npt.ArrayLike,
    segments: int,
    mid_force_n: npt.ArrayLike = (0.0, 0.0, 0.0),
    tip_force_n: npt.ArrayLike = (0.0, 0.0, 0.0),
    alpha_per_s: float = 0.0,
    comments: tuple[str, ...] = (),
    description: str = "",
    notes: dict[str, str] | None = None,
) -> str:
    """A bare rod's file (``docs/rig_file.md``, ``[rod]``) in SI arguments (``gravity``: m/s^2, clamp frame).

    ``comments`` head the file; ``notes`` are end-of-line comments by key. Read it back with
    :func:`helpers.virtual.spatial.rod_file.loads_rod`.
    """
    g = np.asarray(gravity, dtype=float)
    size = float(np.linalg.norm(g))
    direction = g / size if size > 0 else np.array([1.0, 0.0, 0.0])
    values = {
        "length_mm": f"{length_m * 1e3:.10g}",
        "radius_mm": f"{radius_m * 1e3:.10g}",
        "youngs_modulus_gpa": f"{youngs_modulus_pa / 1e9:.10g}",
        "density_kg_m3": f"{density_kg_m3:.10g}",
        "shear_modulus_gpa": f"{shear_modulus_pa / 1e9:.10g}",
        "gravity_direction": _vector(direction),
        "gravity_m_s2": f"{size:.10g}",
        "segments": f"{int(segments)}",
        "held_mid_force_n": _vector(mid_force_n),
        "held_tip_force_n": _vector(tip_force_n),
        "damping_alpha_per_s": f"{alpha_per_s:.10g}",
    }
    notes = notes or {}
    lines = [*(f"# {c}" for c in comments), "schema_version = 1", f'name = "{name[:32]}"',
             f'description = "{description}"', "", "[rod]"]  # fmt: skip
    for key, value in values.items():
        lines.append(f"{key} = {value}" + (f"  # {notes[key]}" if key in notes else ""))
    return "\n".join(lines) + "\n"


def rod_rig(rig: RigFile, segments: int | None = None, **damping: float) -> SpatialRig:
    """The spatial twin of a bare rod's file (its ``[rod]`` table).

    Parameters
    ----------
    rig : RigFile
        A bare rod's file (:func:`helpers.virtual.spatial.rod_file.load_rod`).
    segments : int, optional
        Elements of the rod (default: the file's ``segments``), for a convergence study.
    **damping : float
        Replace the file's damping: ``alpha`` (1/s), ``beta_chord`` (s), ``floor_zeta`` (e.g. all 0 for a run
        that must add none).

    Returns
    -------
    SpatialRig
        No tendons, no disc mass; the arm's ``n_discs`` is the number of elements.
    """
    rod = rig.rod
    if rod is None:
        raise ValueError(f"{rig.source}: not a bare rod's file (no [rod] table; docs/rig_file.md)")
    n = rod.segments if segments is None else int(segments)
    if n < 1:
        raise ValueError(f"segments must be a positive integer, got {segments!r}")
    unknown = set(damping) - {"alpha", "beta_chord", "floor_zeta"}
    if unknown:
        raise ValueError(f"unknown damping parameter(s) {sorted(unknown)}: alpha, beta_chord, floor_zeta")
    values = {"alpha": rod.damping_alpha_per_s, "beta_chord": rod.damping_beta_chord_s,
              "floor_zeta": rod.damping_floor_zeta, **damping}  # fmt: skip
    arm = RigParameters(
        E=rod.youngs_modulus_gpa * 1e9, rho=rod.density_kg_m3, d=2e-3 * rod.radius_mm, L=1e-3 * rod.length_mm,
        n_discs=n, disc_mass=0.0, g=rod.gravity_m_s2, **values,
    )  # fmt: skip
    return SpatialRig(arm=arm, tendons=(), gravity_direction=rod.gravity_direction,
                      shear_modulus_gpa=rod.shear_modulus_gpa, name=rig.name)  # fmt: skip


def held_forces(rig: RigFile, rod: SpatialRig) -> dict[int, np.ndarray]:
    """The file's held forces as ``{node: force}`` on ``rod``'s nodes (the middle and the tip), N."""
    n = rod.arm.n_elements
    forces = {}
    mid, tip = np.asarray(rig.rod.held_mid_force_n, float), np.asarray(rig.rod.held_tip_force_n, float)
    if np.any(mid != 0.0):
        if n % 2:
            raise ValueError(f"a force on the middle needs an even number of segments, got {n}")
        forces[n // 2] = mid
    if np.any(tip != 0.0):
        forces[n] = forces.get(n, np.zeros(3)) + tip
    return forces


def held_state(rod: SpatialRig, forces: dict[int, np.ndarray]) -> np.ndarray:
    """The rod's equilibrium under gravity and constant ``forces`` ``{node: force (N, clamp frame)}``.

    Returns
    -------
    numpy.ndarray
        The coordinates ``q`` (3 per element).
    """
    chain = spatial_model(rod).chain
    ctrl = Control(lam=np.zeros(0), e0=np.zeros(0), kinv=np.zeros(0))
    q = np.zeros(chain.nq)
    for i in range(1, HOLD_STAGES + 1):
        f = i / HOLD_STAGES
        q = _newton(chain, q, ctrl, g=chain.gvec * f, forces={k: f * v for k, v in forces.items()})
    return q


@dataclass(frozen=True)
class Release:
    """A released rod, sampled (simulated, never measured).

    Attributes
    ----------
    t : numpy.ndarray
        Sample times, s (0: the release).
    tip, mid : numpy.ndarray
        The tip node's and the middle node's positions in the clamp frame, m, shape (n, 3).
    q_held : numpy.ndarray
        The held state.
    tip_rest : numpy.ndarray
        The tip at the rod's rest under gravity alone, m.
    max_step : float
        The integrator's step, s.
    """

    t: np.ndarray
    tip: np.ndarray
    mid: np.ndarray
    q_held: np.ndarray
    tip_rest: np.ndarray
    max_step: float


def release(
    rod: SpatialRig, q_held: npt.ArrayLike, times: npt.ArrayLike, max_step: float | None = None
) -> Release:
    """Release the rod at rest in ``q_held`` at ``t = 0`` and sample it at ``times``.

    Parameters
    ----------
    rod : SpatialRig
        A bare rod (:func:`rod_rig`).
    q_held : array_like
        The held state (:func:`held_state`).
    times : array_like
        Sample times, s, strictly increasing, the first >= 0.
    max_step : float, optional
        RK4 step, s; default :func:`~helpers.virtual.spatial.statics.stable_max_step` of the rod (the
        explicit integrator's limit is set by the wire's stiffest twisting and bending of one element).

    Returns
    -------
    Release
    """
    if rod.n_tendons:
        raise ValueError("release takes a bare rod (no tendons): helpers.virtual.spatial.bare_rod.rod_rig")
    q_held = np.asarray(q_held, dtype=float)
    h = stable_max_step(rod) if max_step is None else float(max_step)
    plant = SpatialPlant(rod, max_step=h)
    y = np.zeros_like(plant.state)
    y[: q_held.size] = q_held
    plant.set_state(y)
    ts = np.asarray(times, dtype=float)
    out = plant.advance(ts[ts > 0]) if ts[-1] > 0 else {"q": np.empty((0, q_held.size))}
    q = np.vstack([np.tile(q_held, (int(np.sum(ts <= 0)), 1)), out["q"]])
    chain = spatial_model(rod).chain
    nodes = chain.positions(q)
    n = chain.N
    return Release(t=ts, tip=nodes[:, n, :], mid=nodes[:, n // 2, :], q_held=q_held,
                   tip_rest=chain.tip(spatial_model(rod).q_rest), max_step=h)  # fmt: skip


def first_modes(rod: SpatialRig, n: int = 2) -> list[tuple[float, float]]:
    """The rod's ``n`` lowest modes about its rest under gravity: ``(f_d in Hz, zeta)``, lowest first."""
    poles = linearise(rod, rest_equilibrium(rod), rotor="locked").poles
    poles = poles[np.imag(poles) > 0]
    poles = poles[np.argsort(np.imag(poles))][:n]
    return [(float(np.imag(p)) / (2.0 * math.pi), float(-np.real(p) / abs(p))) for p in poles]
