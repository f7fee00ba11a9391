"""Equilibria and linearisation of the nonlinear arm: static shapes, tension and the frequency map.

- :func:`model_arrays` packs :class:`~helpers.virtual.parameters.RigParameters` into the arrays the compiled
  kernel uses, including the cable's reference length, fixed by the rule "at cable position 0 the arm rests in
  static equilibrium with the cable tension equal to the pretension".
- :func:`equilibrium` solves the static shape for a cable displacement ``u`` (Newton with a finite-difference
  Jacobian, continued in ``u`` from the rest state).
- :func:`linearise` linearises the full dynamics about an equilibrium (finite differences of the compiled
  right-hand side) and returns the poles, the tension residues and the dominant mode.
- :func:`frequency_map` gives omega_d(u) and zeta(u) of the dominant mode for u = 0..40 mm.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy import linalg

from helpers.virtual import _kernel as kern
from helpers.virtual.parameters import RigParameters

__all__ = [
    "ModelArrays",
    "model_arrays",
    "Equilibrium",
    "equilibrium",
    "equilibrium_at_tension",
    "node_positions",
    "Linearisation",
    "linearise",
    "frequency_map",
]


@dataclass(frozen=True)
class ModelArrays:
    """The arrays the compiled kernel works on (see :mod:`helpers.virtual._kernel`)."""

    P: np.ndarray
    mu: np.ndarray
    m_nodes: np.ndarray
    kap: np.ndarray
    cj: np.ndarray
    eye: np.ndarray
    phi_rest: np.ndarray

    @property
    def n(self) -> int:
        """Number of segments."""
        return int(self.mu.shape[0])

    def with_bilateral(self) -> ModelArrays:
        """A copy whose cable can also push (for linearising about a just-taut cable)."""
        P = self.P.copy()
        P[kern.I_BILATERAL] = 1.0
        return ModelArrays(P, self.mu, self.m_nodes, self.kap, self.cj, self.eye, self.phi_rest)


def _raw_arrays(params: RigParameters) -> ModelArrays:
    n = params.n_segments
    m_nodes = params.node_masses()
    mu = np.cumsum(m_nodes[::-1])[::-1].copy()
    kap = np.full(n, params.joint_stiffness)
    kap[0] = 2.0 * params.joint_stiffness  # the clamp joint carries half a cell: second-order lumping
    cj = params.beta * kap
    P = np.zeros(kern.N_PACKED)
    P[kern.I_L] = params.segment_length
    P[kern.I_R] = params.r
    P[kern.I_PHI0] = params.base_angle
    P[kern.I_G] = params.g
    P[kern.I_ALPHA] = params.alpha
    P[kern.I_K] = params.k
    P[kern.I_ELLREF] = 0.0
    P[kern.I_JSEG] = params.segment_inertia()
    return ModelArrays(P, mu, m_nodes, kap, cj, params.eyelet_nodes(), np.full(n, params.base_angle))


def _newton(fun, x0: np.ndarray, tol: float = 1e-11, max_iter: int = 60) -> np.ndarray:
    """Damped Newton on ``fun(x) = 0`` with a forward-difference Jacobian."""
    x = np.array(x0, dtype=float)
    f = fun(x)
    n = x.size
    for _ in range(max_iter):
        norm = np.linalg.norm(f)
        if norm < tol:
            return x
        J = np.empty((n, n))
        for j in range(n):
            h = 1e-7 * max(1.0, abs(x[j]))
            xp = x.copy()
            xp[j] += h
            J[:, j] = (fun(xp) - f) / h
        dx = np.linalg.solve(J, -f)
        step = 1.0
        while step > 1e-4:
            xn = x + step * dx
            fn = fun(xn)
            if np.linalg.norm(fn) < norm:
                break
            step *= 0.5
        x, f = xn, fn
    if np.linalg.norm(f) > 1e3 * tol:
        raise RuntimeError(f"static equilibrium did not converge (residual {np.linalg.norm(f):.3e})")
    return x


def _force_scale(arr: ModelArrays) -> float:
    return float(arr.kap[0])


def _solve_at_tension(arr: ModelArrays, lam: float, phi0: np.ndarray) -> np.ndarray:
    out = np.empty(arr.n)
    scale = _force_scale(arr)

    def fun(phi: np.ndarray) -> np.ndarray:
        kern.static_force(phi, 0.0, lam, arr.P, arr.mu, arr.kap, arr.eye, out)
        return out / scale

    return _newton(fun, phi0)


def _solve_at_u(arr: ModelArrays, u: float, phi0: np.ndarray) -> np.ndarray:
    out = np.empty(arr.n)
    scale = _force_scale(arr)

    def fun(phi: np.ndarray) -> np.ndarray:
        kern.static_force(phi, u, -1.0, arr.P, arr.mu, arr.kap, arr.eye, out)
        return out / scale

    return _newton(fun, phi0)


@functools.lru_cache(maxsize=64)
def model_arrays(params: RigParameters) -> ModelArrays:
    """Pack the parameters and find the rest state (tension = pretension at cable position 0).

    The rest shape is found by continuation: gravity and the pretension are raised together from zero in
    20 stages, Newton at each, starting from the straight arm.
    """
    arr = _raw_arrays(params)
    phi = np.full(arr.n, params.base_angle)
    n_stages = 20 if (params.g > 0 or params.pretension > 0) else 1
    P = arr.P.copy()
    for stage in range(1, n_stages + 1):
        frac = stage / n_stages
        P[kern.I_G] = params.g * frac
        staged = ModelArrays(P, arr.mu, arr.m_nodes, arr.kap, arr.cj, arr.eye, arr.phi_rest)
        phi = _solve_at_tension(staged, params.pretension * frac, phi)
    P[kern.I_G] = params.g
    ell = kern.cable_length(phi, P, arr.eye)
    P[kern.I_ELLREF] = ell - params.pretension / params.k
    for a in (P, phi):
        a.setflags(write=False)
    return ModelArrays(P, arr.mu, arr.m_nodes, arr.kap, arr.cj, arr.eye, phi)


def node_positions(params: RigParameters, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Backbone node positions (m) for segment angles ``phi`` (``(..., N)``): arrays ``(..., N + 1)``."""
    phi = np.asarray(phi, dtype=float)
    lseg = params.segment_length
    zeros = np.zeros(phi.shape[:-1] + (1,))
    x = np.concatenate([zeros, np.cumsum(lseg * np.cos(phi), axis=-1)], axis=-1)
    y = np.concatenate([zeros, np.cumsum(lseg * np.sin(phi), axis=-1)], axis=-1)
    return x, y


@dataclass(frozen=True)
class Equilibrium:
    """A static equilibrium of the arm.

    Attributes
    ----------
    u : float
        Cable displacement from the rest position, m.
    phi : numpy.ndarray
        Segment angles, rad.
    tension : float
        Cable tension, N.
    x, y : numpy.ndarray
        Node positions (clamp first), m.
    """

    u: float
    phi: np.ndarray
    tension: float
    x: np.ndarray
    y: np.ndarray

    @property
    def tip_angle(self) -> float:
        """Angle of the last segment relative to the base tangent, rad (total bend)."""
        return float(self.phi[-1])


def _make_eq(params: RigParameters, arr: ModelArrays, u: float, phi: np.ndarray) -> Equilibrium:
    lam = kern.tension_of(phi, u, arr.P, arr.eye)
    x, y = node_positions(params, phi)
    return Equilibrium(u=float(u), phi=phi, tension=float(lam), x=x, y=y)


def equilibrium(params: RigParameters, u: float, du_max: float = 1.0e-3) -> Equilibrium:
    """Static equilibrium for the cable pulled by ``u`` metres from the rest position.

    Continuation from the rest state in increments of at most ``du_max``.

    Raises
    ------
    ValueError
        If ``u`` is not finite.
    """
    if not math.isfinite(u):
        raise ValueError(f"cable displacement must be finite, got {u!r}")
    arr = model_arrays(params)
    phi = arr.phi_rest.copy()
    n_inc = max(1, int(math.ceil(abs(u) / du_max)))
    for i in range(1, n_inc + 1):
        phi = _solve_at_u(arr, u * i / n_inc, phi)
    return _make_eq(params, arr, u, phi)


def equilibrium_at_tension(params: RigParameters, tension: float, n_stages: int = 20) -> Equilibrium:
    """Static equilibrium with a prescribed cable tension (N), e.g. for the constant-curvature oracle.

    The cable displacement ``u`` that produces it is reported as well.
    """
    if not (math.isfinite(tension) and tension >= 0):
        raise ValueError(f"tension must be finite and >= 0, got {tension!r}")
    arr = model_arrays(params)
    phi = arr.phi_rest.copy()
    for i in range(1, n_stages + 1):
        lam = params.pretension + (tension - params.pretension) * i / n_stages
        phi = _solve_at_tension(arr, lam, phi)
    ell = kern.cable_length(phi, arr.P, arr.eye)
    u = tension / params.k - ell + arr.P[kern.I_ELLREF]
    x, y = node_positions(params, phi)
    return Equilibrium(u=float(u), phi=phi, tension=float(tension), x=x, y=y)


@dataclass(frozen=True)
class Linearisation:
    """Small vibrations about an equilibrium.

    Attributes
    ----------
    equilibrium : Equilibrium
        The operating point.
    poles : numpy.ndarray
        Eigenvalues of the linearised state matrix (1/s), sorted by modulus.
    residues : numpy.ndarray
        Residues of the tension response to a cable-displacement step, per pole (N/m).
    omega_n, zeta, omega_d : float
        Dominant mode (see :func:`linearise`).
    """

    equilibrium: Equilibrium
    poles: np.ndarray
    residues: np.ndarray
    omega_n: float
    zeta: float
    omega_d: float

    def oscillatory(self) -> pd.DataFrame:
        """The oscillatory poles (upper half-plane) with their frequency, damping and weight."""
        p, r = self.poles, self.residues
        up = p.imag > 0
        p, r = p[up], r[up]
        return pd.DataFrame(
            {
                "omega_n": np.abs(p),
                "zeta": -p.real / np.abs(p),
                "omega_d": p.imag,
                "weight": 2 * np.abs(r / p),
            }
        )


DECAY_S: float = 1.0
"""Default age (s) of the transient at which :func:`linearise` ranks the modes: the paper identifies on
9-10 s, 1-2 s after the release at 8 s, so the mode that dominates there is the one that matters."""


def _mass_matrix(arr: ModelArrays, phi: np.ndarray) -> np.ndarray:
    """The chain's mass matrix ``M_ik = l^2 mu_max(i,k) cos(phi_i - phi_k) + J delta_ik`` (symmetric)."""
    n = arr.n
    l2 = float(arr.P[kern.I_L]) ** 2
    idx = np.arange(n)
    mu_max = arr.mu[np.maximum.outer(idx, idx)]
    return l2 * mu_max * np.cos(np.subtract.outer(phi, phi)) + float(arr.P[kern.I_JSEG]) * np.eye(n)


def _stiffness_matrix(arr: ModelArrays, phi: np.ndarray, u: float, h: float = 1e-6) -> np.ndarray:
    """``K = -dQ/dphi`` of the static generalised force (springs, gravity, cable), symmetrised.

    ``Q`` is minus the gradient of a potential, so ``K`` is its Hessian: central differences of ``Q`` (whose
    terms are of order one in N m, so round-off enters at 1e-10 of ``K``) and the symmetric part.
    """
    n = arr.n
    out = np.empty(n)
    K = np.empty((n, n))
    for j in range(n):
        cols = []
        for sign in (1.0, -1.0):
            x = phi.copy()
            x[j] += sign * h
            kern.static_force(x, u, -1.0, arr.P, arr.mu, arr.kap, arr.eye, out)
            cols.append(out.copy())
        K[:, j] = -(cols[0] - cols[1]) / (2 * h)
    return 0.5 * (K + K.T)


def _damping_matrix(arr: ModelArrays, M: np.ndarray) -> np.ndarray:
    """``C``: mass-proportional ``alpha M`` plus the joint dashpots ``cj`` on the relative rates."""
    n = arr.n
    D = np.eye(n) - np.eye(n, k=-1)  # joint rates from segment rates (the clamp joint's base is fixed)
    return float(arr.P[kern.I_ALPHA]) * M + D.T @ np.diag(arr.cj) @ D


def linearise(
    params: RigParameters, u: float = 0.0, eq: Equilibrium | None = None, decay_s: float = DECAY_S
) -> Linearisation:
    """Linearise the dynamics about the equilibrium at cable displacement ``u`` (m).

    The *dominant* mode is the oscillatory pair with the largest amplitude in the tension response to a
    cable step, ``decay_s`` seconds after it: ``2 |r_i / p_i| exp(Re(p_i) decay_s)``. With ``decay_s = 0``
    this is ``helpers.model.dominant_mode``'s definition; with the default (1 s) it is the mode the paper's
    identification window (1-2 s after the release) sees.

    The small-vibration equations ``M q'' + C q' + K q = b du`` are assembled from symmetric pieces (the
    mass matrix in closed form, the stiffness as the Hessian of the potential, the Rayleigh-type damping) and
    solved in the coordinates of the undamped modes (``K phi = w^2 M phi``, a symmetric-definite
    problem), where the damped state matrix is nearly normal. This keeps the low frequencies well
    conditioned even for very fine chains, whose stiffest modes are 1e6 times faster than the dominant one:
    the frequencies printed by the notebooks do not depend on round-off (BLAS thread count, CPU). At rest
    the velocity terms vanish, so nothing else enters. The tension output is ``k (u + ell(q) - ell_ref)``;
    if the cable is just taut (zero pretension) it is linearised as a two-sided spring.
    """
    eq = equilibrium(params, u) if eq is None else eq
    arr = model_arrays(params)
    if eq.tension <= 1e-9:
        arr = arr.with_bilateral()
    n = arr.n
    M = _mass_matrix(arr, eq.phi)
    K = _stiffness_matrix(arr, eq.phi, eq.u)
    C = _damping_matrix(arr, M)
    grad = np.empty(n)
    kern.cable_length_grad(eq.phi, arr.P, arr.eye, grad)
    taut = eq.tension > 1e-9 or bool(arr.P[kern.I_BILATERAL])
    k = float(arr.P[kern.I_K]) if taut else 0.0
    c_out = k * grad  # d(tension)/d(phi)
    b_in = -k * grad  # d(Q)/du: the cable's pull on the generalised coordinates per metre of cable
    w2, Phi = linalg.eigh(K, M)  # Phi^T M Phi = I
    Cm = Phi.T @ C @ Phi
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.diag(w2), -0.5 * (Cm + Cm.T)]])
    b = np.concatenate([np.zeros(n), Phi.T @ b_in])
    c = np.concatenate([c_out @ Phi, np.zeros(n)])
    evals, left, right = linalg.eig(A, left=True, right=True)
    res = (c @ right) * (left.conj().T @ b) / np.einsum("ij,ij->j", left.conj(), right)
    order = np.argsort(np.abs(evals), kind="stable")
    evals, res = evals[order], res[order]
    up = evals.imag > 1e-9
    if not np.any(up):
        raise ValueError("the linearisation has no oscillatory mode")
    weights = np.abs(res[up] / evals[up]) * np.exp(evals[up].real * decay_s)
    best = evals[up][np.argmax(weights)]
    omega_n = float(abs(best))
    return Linearisation(
        equilibrium=eq,
        poles=evals,
        residues=res,
        omega_n=omega_n,
        zeta=float(-best.real / omega_n),
        omega_d=float(best.imag),
    )


def frequency_map(
    params: RigParameters, u_mm: np.ndarray | None = None, decay_s: float = DECAY_S
) -> pd.DataFrame:
    """Dominant mode omega_d(u), zeta(u) and static tension about the equilibria for u in ``u_mm`` (mm).

    Returns
    -------
    pandas.DataFrame
        Columns ``u_mm``, ``tension_n``, ``tip_angle_deg``, ``omega_n``, ``zeta``, ``omega_d``, ``period_s``.
    """
    u_mm = np.arange(0.0, 40.01, 2.0) if u_mm is None else np.asarray(u_mm, dtype=float)
    if np.any(~np.isfinite(u_mm)):
        raise ValueError("u_mm must be finite")
    rows = []
    arr = model_arrays(params)
    phi = arr.phi_rest.copy()
    u_prev = 0.0
    for u in np.sort(u_mm) * 1e-3:
        n_inc = max(1, int(math.ceil(abs(u - u_prev) / 1e-3)))
        for i in range(1, n_inc + 1):
            phi = _solve_at_u(arr, u_prev + (u - u_prev) * i / n_inc, phi)
        u_prev = u
        eq = _make_eq(params, arr, u, phi)
        lin = linearise(params, u, eq=eq, decay_s=decay_s)
        rows.append(
            {
                "u_mm": u * 1e3,
                "tension_n": eq.tension,
                "tip_angle_deg": math.degrees(eq.tip_angle - params.base_angle),
                "omega_n": lin.omega_n,
                "zeta": lin.zeta,
                "omega_d": lin.omega_d,
                "period_s": 2 * math.pi / lin.omega_d,
            }
        )
    return pd.DataFrame(rows)
