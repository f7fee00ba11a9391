"""The spatial twin's equations of motion written from the Lagrangian in plain numpy (the kernel's oracle).

Independently of the compiled articulated-body algorithm (:mod:`helpers.virtual.spatial._kernel`): the
dense mass matrix from the node Jacobians (:meth:`~helpers.virtual.spatial.chain.SpatialChain.mass_matrix`),
the velocity-product terms ``M' q' - (1/2) d(q'^T M q')/dq`` by complex steps of the mass matrix, the
potential's gradient (elastic, gravity, tendons with the coupled bowing) from
:class:`~helpers.virtual.spatial.chain.SpatialChain`, the damping as matrices, and the actuators as in the
kernel. Only the rest state and the cables' references come from
:func:`helpers.virtual.spatial.statics.spatial_model`. Slow (tens of milliseconds per evaluation): for tests.
"""

from __future__ import annotations

import numpy as np

from helpers.virtual.spatial.chain import Control
from helpers.virtual.spatial.rig import SpatialRig
from helpers.virtual.spatial.statics import spatial_model

__all__ = ["dense_rhs", "energy"]


def _velocity_terms(chain, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    h = 1e-30
    Mdot = chain.mass_matrix(q + 1j * h * qd).imag / h
    grad = np.array(
        [qd @ (chain.mass_matrix(q + 1j * h * np.eye(q.size)[k]).imag / h) @ qd for k in range(q.size)]
    )
    return Mdot @ qd - 0.5 * grad


def _split(y: np.ndarray, nq: int, nt: int) -> list[np.ndarray]:
    """The state ``[phi, phi', psi, psi', x_c, x_c']`` in its six parts."""
    return np.split(np.asarray(y, dtype=float), np.cumsum([nq, nq, nt, nt, nt]))


def dense_rhs(rig: SpatialRig, y: np.ndarray, drive: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``dy/dt`` of the state ``[phi, phi', psi, psi', x_c, x_c']`` at commanded rotor angles ``drive``.

    Returns
    -------
    (dy, lam2)
        The derivative and the arm-side tensions.
    """
    model = spatial_model(rig)
    chain, p, nt = model.chain, rig.arm, rig.n_tendons
    q, qd, psi, psid, x, xd = _split(y, chain.nq, nt)
    ctrl = Control(lam=np.full(nt, np.nan), e0=x - model.ell_ref_arm, kinv=1.0 / model.k2)
    grad, lam2, _ = chain.potential_grad(q, ctrl)
    M = chain.mass_matrix(q)
    C = chain.damping_matrix(M, (model.floor_W, model.floor_c))
    qdd = np.linalg.solve(M, -grad - C @ qd - _velocity_terms(chain, q, qd))
    R = np.array([rig.spool_radius(i) for i in range(nt)])
    e1 = R * psi - x - model.s1_ref
    lam1 = np.where(e1 > 0, model.k1 * e1, 0.0)
    Th = np.array([t.holding_torque_n_m for t in rig.tendons])
    d = np.asarray(drive, dtype=float) - psi
    tm = Th * np.sin(p.rotor_teeth * d) if p.torque_law == "sin" else Th * p.rotor_teeth * d
    cr = np.array([rig.rotor_damping(i) for i in range(nt)])
    cc = np.array([rig.carriage_damping(i) for i in range(nt)])
    psidd = (tm - cr * psid - R * lam1) / p.drive_inertia
    xdd = (lam1 - lam2 - cc * xd) / p.carriage_mass
    return np.concatenate([qd, qdd, psid, psidd, xd, xdd]), lam2


def energy(rig: SpatialRig, y: np.ndarray, drive: np.ndarray) -> float:
    """Kinetic + elastic + gravitational + cable + motor energy of the state ``y``, J.

    The arm-side cables and the bowing are ``max_{lam >= 0} lam . e2 - lam^T (diag(1/k2) + H) lam / 2``.
    """
    model = spatial_model(rig)
    chain, p, nt = model.chain, rig.arm, rig.n_tendons
    q, qd, psi, psid, x, xd = _split(y, chain.nq, nt)
    kin = chain.kinematics(q)
    ell = chain.tendon_lengths(q, kin)
    H = chain.bow_matrix(q, kin)
    ctrl = Control(lam=np.full(nt, np.nan), e0=x - model.ell_ref_arm, kinv=1.0 / model.k2)
    lam2 = chain.tensions(ctrl, ell, H)
    e2 = x + ell - model.ell_ref_arm
    arm_side = float(lam2 @ e2 - 0.5 * lam2 @ (np.diag(1.0 / model.k2) + H) @ lam2)
    R = np.array([rig.spool_radius(i) for i in range(nt)])
    e1 = R * psi - x - model.s1_ref
    spool_side = float(np.sum(0.5 * model.k1 * np.where(e1 > 0, e1, 0.0) ** 2))
    Th = np.array([t.holding_torque_n_m for t in rig.tendons])
    d = np.asarray(drive, dtype=float) - psi
    if p.torque_law == "sin":
        motor = float(np.sum(Th / p.rotor_teeth * (1.0 - np.cos(p.rotor_teeth * d))))
    else:
        motor = float(np.sum(0.5 * Th * p.rotor_teeth * d * d))
    kinetic = 0.5 * qd @ chain.mass_matrix(q) @ qd + 0.5 * p.drive_inertia * psid @ psid
    kinetic += 0.5 * p.carriage_mass * xd @ xd
    return float(kinetic + chain.elastic_energy(q) + chain.gravity_energy(q) + arm_side + spool_side + motor)
