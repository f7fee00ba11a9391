"""The arc-chain arm in numpy: geometry, potential, mass and damping matrices, equilibria, linearisation.

:class:`ArcChain` is the arm of ``docs/virtual_rig.md`` written as plain (vectorised, complex-step safe)
numpy: ``N`` constant-curvature elements, coordinates the tangent angles at the element ends, the discs
turning with the rod, the cable straight from eyelet to eyelet, and the rod's bowing away from the cable
between eyelets as a compliance ``H(q)`` in series with the cable (:meth:`ArcChain.bow_compliance`). Exact
Hessians of the potential come from the complex-step method (``h = 1e-30``: no subtractive cancellation),
the mass matrix from the node Jacobians in closed form, so the printed frequencies do not depend on round-off
(BLAS threads, CPU).

- :func:`model_arrays` packs a :class:`~helpers.virtual.parameters.RigParameters` into the arrays of the
  compiled kernel (:mod:`helpers.virtual._kernel`), with the rest state: "at cable position 0 the arm rests
  in static equilibrium with the cable tension equal to the pretension" (the rotor at its static lag).
- :func:`equilibrium` is the frictionless static equilibrium with the cable end at the spool displaced by
  ``u`` from rest and the spool held there (rotor locked).
- :func:`linearise` gives the small vibrations about an equilibrium, with the rotor locked or free on its
  microstep spring (the rig as it runs).
- :func:`frequency_map` tabulates both for ``u = 0..40 mm``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import linalg

from helpers.virtual import _kernel as kern
from helpers.virtual.parameters import RigParameters

__all__ = [
    "ArcChain",
    "chord_functions",
    "KernelArrays",
    "model_arrays",
    "Equilibrium",
    "equilibrium",
    "equilibrium_at_tension",
    "node_positions",
    "Linearisation",
    "linearise",
    "frequency_map",
    "floor_modes",
    "modal_state",
    "state_space_poles",
    "DECAY_S",
    "rk4_stable_step",
    "stable_max_step",
]

_SERIES_TERMS = 14  # |D| < 0.2: truncation below 1e-25


def chord_functions(D: np.ndarray, order: int = 1) -> tuple[np.ndarray, ...]:
    """Chord functions ``f1 = sin D / D``, ``f2 = (1 - cos D) / D`` of an arc turning by ``D``, derivatives.

    ``(f1, f2)`` is the chord of a unit-length arc in the frame of its start tangent. A Taylor series is
    used for ``|Re D| < 0.2``; complex arguments are supported (complex step).

    Returns
    -------
    tuple of numpy.ndarray
        ``(f1, f2, f1', f2')``, or with ``order=2`` also ``(f1'', f2'')``.
    """
    D = np.asarray(D)
    small = np.abs(D.real) < 0.2
    Ds = np.where(small, D, 0.0)
    Dl = np.where(small, 1.0, D)
    zero = np.zeros_like(Ds)
    f1s, f2s, f1ps, f2ps, f1pps, f2pps = zero, zero, zero, zero, zero, zero
    # F(D) = f1 + i f2 = sum_n (i D)^n / (n + 1)!: even n -> f1, odd n -> f2
    for n in range(_SERIES_TERMS + 1):
        term = (1.0 if n % 4 in (0, 1) else -1.0) / math.factorial(n + 1)
        t0 = term * Ds**n
        t1 = term * n * Ds ** (n - 1) if n >= 1 else zero
        t2 = term * n * (n - 1) * Ds ** (n - 2) if n >= 2 else zero
        if n % 2 == 0:
            f1s, f1ps, f1pps = f1s + t0, f1ps + t1, f1pps + t2
        else:
            f2s, f2ps, f2pps = f2s + t0, f2ps + t1, f2pps + t2
    s = np.sin(Dl)
    c = np.cos(Dl)
    out = [
        np.where(small, f1s, s / Dl),
        np.where(small, f2s, (1.0 - c) / Dl),
        np.where(small, f1ps, c / Dl - s / Dl**2),
        np.where(small, f2ps, s / Dl - (1.0 - c) / Dl**2),
    ]
    if order == 2:
        out += [
            np.where(small, f1pps, -s / Dl - 2.0 * c / Dl**2 + 2.0 * s / Dl**3),
            np.where(small, f2pps, c / Dl - 2.0 * s / Dl**2 + 2.0 * (1.0 - c) / Dl**3),
        ]
    return tuple(out)


_BOW_SERIES = 16  # |D| < 2: truncation below 1e-20 of the leading term


def _bow_coefficients() -> tuple[np.ndarray, np.ndarray]:
    """Taylor coefficients (in ``D^2``) of :func:`bow_functions`' ``P`` and ``Q``."""
    a = np.array([(-1.0) ** j / math.factorial(2 * j + 1) for j in range(_BOW_SERIES + 2)])  # sin D / D
    b = np.array([2.0 * (-1.0) ** j / math.factorial(2 * j + 2) for j in range(_BOW_SERIES + 2)])  # S2
    return 0.5 * (a[1:-1] - 2.0 * b[1:-1]), b[1:-1] - a[1:-1]


_BOW_P, _BOW_Q = _bow_coefficients()


def bow_functions(D: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The shape factors of the bowing compliance of an arc turning by ``D``, and their derivatives.

    An arc of length ``l`` turning by ``D`` whose mid-tangent makes the angle ``c`` with a straight line
    (the cable run) has ``(1/l) int (h - mean h)^2 ds = l^2 (P(D) + Q(D) sin^2 c)``, ``h`` the distance of
    the arc's points from the line: ``P = (1 + S1 - 2 S2) / (2 D^2)``, ``Q = (S2 - S1) / D^2`` with
    ``S1 = sin D / D``, ``S2 = 2 (1 - cos D) / D^2``; ``P = D^2/720 - ...``, ``Q = 1/12 - D^2/180 + ...``.
    Taylor series for ``|Re D| < 2``, the closed form beyond; complex arguments supported.

    Returns
    -------
    tuple of numpy.ndarray
        ``(P, Q, P', Q')``.
    """
    D = np.asarray(D)
    small = np.abs(D.real) < 2.0
    x = np.where(small, D, 0.0) ** 2
    Ps = np.zeros_like(x)
    Qs = np.zeros_like(x)
    dPs = np.zeros_like(x)
    dQs = np.zeros_like(x)
    for j in range(_BOW_SERIES - 1, -1, -1):  # Horner in x = D^2; derivatives d/dD = 2 D d/dx
        Ps = Ps * x + _BOW_P[j]
        Qs = Qs * x + _BOW_Q[j]
        if j >= 1:
            dPs = dPs * x + j * _BOW_P[j]
            dQs = dQs * x + j * _BOW_Q[j]
    Ds = np.where(small, D, 0.0)
    dPs = 2.0 * Ds * dPs
    dQs = 2.0 * Ds * dQs
    Dl = np.where(small, 3.0, D)
    s, c = np.sin(Dl), np.cos(Dl)
    S1 = s / Dl
    S2 = 2.0 * (1.0 - c) / Dl**2
    dS1 = (c - S1) / Dl
    dS2 = (2.0 * s / Dl**2) - 2.0 * S2 / Dl
    Pl = (1.0 + S1 - 2.0 * S2) / (2.0 * Dl**2)
    Ql = (S2 - S1) / Dl**2
    dPl = (dS1 - 2.0 * dS2) / (2.0 * Dl**2) - 2.0 * Pl / Dl
    dQl = (dS2 - dS1) / Dl**2 - 2.0 * Ql / Dl
    return (np.where(small, Ps, Pl), np.where(small, Qs, Ql), np.where(small, dPs, dPl),
            np.where(small, dQs, dQl))  # fmt: skip


class ArcChain:
    """The arm's geometry, potential and matrices for coordinates ``q`` = tangent angles ``theta_1..theta_N``.

    Every geometric function accepts a leading batch dimension and complex arrays.

    Parameters
    ----------
    params : RigParameters
        The rig (only the arm's and the cable's fields are used here).
    """

    def __init__(self, params: RigParameters) -> None:
        self.params = params
        self.N = params.n_elements
        self.l = params.element_length
        self.m_nodes = params.node_masses()
        self.J_nodes = params.node_inertias()
        self.disc_nodes = params.disc_nodes()
        self.eye_nodes = np.concatenate([[0], params.eyelet_nodes()])  # the clamp guide first
        self.kap = params.EI / self.l
        # interval (cable run) of each element: run q goes from eyelet q-1 to eyelet q (the guide is 0)
        self.element_run = np.searchsorted(self.eye_nodes, np.arange(1, self.N + 1), side="left") - 1
        self._run_sum = (self.element_run[:, None] == np.arange(len(self.eye_nodes) - 1)).astype(float)
        self.bow_scale = self.l**3 / params.EI if params.bowing else 0.0

    # --- geometry ---------------------------------------------------------------------------------
    def full_angles(self, q: np.ndarray) -> np.ndarray:
        """``[theta_0, theta_1, ..., theta_N]`` with the clamp direction first."""
        q = np.asarray(q)
        base = np.full(q.shape[:-1] + (1,), self.params.base_angle, dtype=q.dtype)
        return np.concatenate([base, q], axis=-1)

    def geometry(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """Node positions and chord derivatives.

        Returns
        -------
        dict
            ``p`` (..., N+1, 2) node positions (clamp first); ``own`` (..., N, 2) = d chord_i / d theta_i;
            ``prev`` (..., N, 2) = d chord_{i+1} / d theta_i (zero for the last).
        """
        th = self.full_angles(q)
        c, s = np.cos(th), np.sin(th)
        D = th[..., 1:] - th[..., :-1]
        f1, f2, f1p, f2p = chord_functions(D)
        c0, s0 = c[..., :-1], s[..., :-1]
        chx = self.l * (c0 * f1 - s0 * f2)
        chy = self.l * (s0 * f1 + c0 * f2)
        bx = self.l * (c0 * f1p - s0 * f2p)
        by = self.l * (s0 * f1p + c0 * f2p)
        own = np.stack([bx, by], axis=-1)
        nxt = np.stack([-chy - bx, chx - by], axis=-1)  # d chord_i / d theta_{i-1}
        prev = np.zeros_like(own)
        prev[..., :-1, :] = nxt[..., 1:, :]
        ch = np.stack([chx, chy], axis=-1)
        zero = np.zeros(ch.shape[:-2] + (1, 2), dtype=ch.dtype)
        pos = np.concatenate([zero, np.cumsum(ch, axis=-2)], axis=-2)
        return {"p": pos, "own": own, "prev": prev, "theta": th}

    def eyelets(self, q: np.ndarray, geo: dict | None = None) -> np.ndarray:
        """Eyelet positions (..., Q+1, 2), the clamp guide first: ``p + r n(theta)``."""
        geo = self.geometry(q) if geo is None else geo
        ang = geo["theta"][..., self.eye_nodes]
        pos = geo["p"][..., self.eye_nodes, :]
        return pos + self.params.r * np.stack([-np.sin(ang), np.cos(ang)], axis=-1)

    def cable_length(self, q: np.ndarray) -> np.ndarray:
        """Cable path from the clamp guide through the eyelets, m."""
        E = self.eyelets(q)
        d = E[..., 1:, :] - E[..., :-1, :]
        return np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2).sum(axis=-1)

    def _map_forces(self, geo: dict, G_node: np.ndarray, g_ang: np.ndarray) -> np.ndarray:
        """Generalised force from node 'forces' ``G_node`` (..., N+1, 2) and direct angle terms (..., N)."""
        S = np.cumsum(G_node[..., ::-1, :], axis=-2)[..., ::-1, :]  # S_j = sum_{k >= j} G_k
        S1 = S[..., 1:, :]
        out = (geo["own"] * S1).sum(-1)
        S2 = np.zeros_like(S1)
        S2[..., :-1, :] = S1[..., 1:, :]
        return out + (geo["prev"] * S2).sum(-1) + g_ang

    def cable_grad(self, q: np.ndarray, geo: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Cable length and its gradient with respect to ``q``."""
        q = np.asarray(q)
        geo = self.geometry(q) if geo is None else geo
        ang = geo["theta"][..., self.eye_nodes]
        r = self.params.r
        E = geo["p"][..., self.eye_nodes, :] + r * np.stack([-np.sin(ang), np.cos(ang)], axis=-1)
        d = E[..., 1:, :] - E[..., :-1, :]
        lengths = np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2)
        uhat = d / lengths[..., None]
        dE = np.zeros_like(E)
        dE[..., 1:, :] += uhat
        dE[..., :-1, :] -= uhat
        dE[..., 0, :] = 0.0  # the guide is fixed
        G_node = np.zeros(geo["p"].shape, dtype=dE.dtype)
        G_node[..., self.eye_nodes, :] = dE
        tvec = np.stack([np.cos(ang), np.sin(ang)], axis=-1)
        dang = -r * (tvec * dE).sum(-1)  # d(eyelet offset)/d(angle) = -r t
        g_ang = np.zeros(q.shape, dtype=dE.dtype)
        g_ang[..., self.eye_nodes[1:] - 1] += dang[..., 1:]
        return lengths.sum(-1), self._map_forces(geo, G_node, g_ang)

    def bow_compliance(self, q: np.ndarray, geo: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Compliance of the rod's bowing between eyelets, in series with the cable (m/N), and its gradient.

        Between two eyelets the cable runs straight and loads the rod with its tension ``T`` along that line
        at the distance ``h(s)`` from it: the moment ``T h(s)``. A constant-curvature element carries only
        its mean; the rest, ``T (h - mean h)`` over each element, bends the rod further and shortens the
        cable's path by ``T H``, ``H = sum_e int_e (h - mean_e h)^2 ds / EI`` (the complementary energy of
        the moment the elements cannot carry; ``docs/virtual_rig.md``). Zero if ``params.bowing`` is off.
        """
        q = np.asarray(q)
        geo = self.geometry(q) if geo is None else geo
        th = geo["theta"]
        D = th[..., 1:] - th[..., :-1]
        tm = th[..., :-1] + 0.5 * D  # direction of each element's chord
        ang = th[..., self.eye_nodes]
        r = self.params.r
        E = geo["p"][..., self.eye_nodes, :] + r * np.stack([-np.sin(ang), np.cos(ang)], axis=-1)
        d = E[..., 1:, :] - E[..., :-1, :]
        Lr = np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2)
        u = d / Lr[..., None]
        ue = u[..., self.element_run, :]
        ct, st = np.cos(tm), np.sin(tm)
        sc = ct * ue[..., 1] - st * ue[..., 0]  # sin(gamma - tm), gamma the run's direction
        cc = ct * ue[..., 0] + st * ue[..., 1]
        P, Q, dP, dQ = bow_functions(D)
        k = self.bow_scale
        H = k * (P + Q * sc**2).sum(-1)
        g_D = k * (dP + dQ * sc**2)
        g_s = 2.0 * k * Q * sc
        g_t = -g_s * cc  # d/d(tm); d/d(gamma) is the opposite
        grad = np.zeros(q.shape, dtype=H.dtype)
        grad = grad + g_D + 0.5 * g_t  # theta_e (end of element e)
        grad[..., :-1] += -g_D[..., 1:] + 0.5 * g_t[..., 1:]  # theta_{e-1} of element e (theta_0 fixed)
        # gamma_q = atan2(d_q): d gamma = perp . (dE_q - dE_{q-1}) / L_q, perp = (-u_y, u_x)
        Gam = -g_t @ self._run_sum  # d H / d gamma, summed over each run's elements
        w = (Gam / Lr)[..., None] * np.stack([-u[..., 1], u[..., 0]], axis=-1)
        dE = np.zeros_like(E, dtype=w.dtype)
        dE[..., 1:, :] += w
        dE[..., :-1, :] -= w
        dE[..., 0, :] = 0.0  # the guide is fixed
        G_node = np.zeros(geo["p"].shape, dtype=dE.dtype)
        G_node[..., self.eye_nodes, :] = dE
        tvec = np.stack([np.cos(ang), np.sin(ang)], axis=-1)
        g_ang = np.zeros(q.shape, dtype=dE.dtype)
        g_ang[..., self.eye_nodes[1:] - 1] += -r * (tvec * dE).sum(-1)[..., 1:]
        return H, grad + self._map_forces(geo, G_node, g_ang)

    def elastic_grad(self, q: np.ndarray) -> np.ndarray:
        """Gradient of the bending energy ``sum EI/(2 l) D_i^2`` (exact for arcs)."""
        th = self.full_angles(q)
        t = self.kap * (th[..., 1:] - th[..., :-1])
        out = t.copy()
        out[..., :-1] -= t[..., 1:]
        return out

    def gravity_grad(self, q: np.ndarray, geo: dict | None = None, g: float | None = None) -> np.ndarray:
        """Gradient of the gravitational energy ``g sum m_j y_j``."""
        geo = self.geometry(q) if geo is None else geo
        g = self.params.g if g is None else g
        G = np.zeros(geo["p"].shape, dtype=geo["p"].dtype)
        G[..., 1:, 1] = g * self.m_nodes
        return self._map_forces(geo, G, np.zeros(np.shape(q), dtype=G.dtype))

    def potential_grad(
        self,
        q: np.ndarray,
        *,
        lam: float | None = None,
        u: float | None = None,
        k: float = 0.0,
        ell_ref: float = 0.0,
        g: float | None = None,
        bilateral: bool = False,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Gradient of the potential and the cable tension.

        Either a prescribed tension ``lam`` or a cable spring ``k`` whose end is displaced by ``u``:
        tension ``k max(0, u + ell(q) - ell_ref)`` (``bilateral``: the spring may also push).
        """
        q = np.asarray(q)
        geo = self.geometry(q)
        ell, dl = self.cable_grad(q, geo)
        H, dH = self.bow_compliance(q, geo)
        if lam is None:
            e = u + ell - ell_ref
            lam_ = np.where((np.real(e) > 0) | bilateral, e / (1.0 / k + H), 0.0)
        else:
            lam_ = np.full(np.shape(ell), lam, dtype=float)
        grad = (self.elastic_grad(q) + self.gravity_grad(q, geo, g) + lam_[..., None] * dl
                - 0.5 * lam_[..., None] ** 2 * dH)  # fmt: skip
        return grad, lam_

    def cable_tangent(self, q: np.ndarray, lam: float, k: float) -> tuple[float, np.ndarray]:
        """The tangent of a cable of stiffness ``k`` (N/m) at tension ``lam`` through the arm in shape ``q``.

        With the bowing compliance ``H`` in series, the tension is ``e / (1/k + H(q))`` for a stretch ``e``,
        and it changes by ``kappa (g . dq + de)`` (``de``: the stretch imposed at the far end).

        Returns
        -------
        kappa : float
            ``1 / (1/k + H)``, N/m.
        g : numpy.ndarray
            ``d ell/dq - lam dH/dq``, m/rad.
        """
        geo = self.geometry(q)
        _, dl = self.cable_grad(q, geo)
        H, dH = self.bow_compliance(q, geo)
        return float(1.0 / (1.0 / k + H)), dl - lam * dH

    def hessian(self, q: np.ndarray, **kwargs: object) -> np.ndarray:
        """Exact Hessian of the potential (complex step on the gradient, one batched call), symmetrised."""
        n = q.size
        h = 1e-30
        Q = q[None, :] + 1j * h * np.eye(n)
        grad, _ = self.potential_grad(Q, **kwargs)
        H = grad.imag / h
        return 0.5 * (H + H.T)

    # --- inertia and damping ----------------------------------------------------------------------
    def node_jacobian(self, q: np.ndarray) -> np.ndarray:
        """D p_j / d q_i, shape (N+1, 2, N)."""
        geo = self.geometry(q)
        N = self.N
        J = np.zeros((N + 1, 2, N), dtype=np.result_type(q, float))
        own, prev = geo["own"], geo["prev"]
        for i in range(N):  # coordinate i moves node i+1 by own_i and every later node by own_i + prev_i
            J[i + 1, :, i] = own[i]
            J[i + 2 :, :, i] = own[i] + prev[i]
        return J

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """``M(q) = sum_j m_j J_j^T J_j + diag(J_nodes)`` (the discs turn with ``theta`` at their node)."""
        Jn = self.node_jacobian(q)[1:]
        return np.einsum("j,jai,jak->ik", self.m_nodes, Jn, Jn) + np.diag(self.J_nodes)

    def disc_rate_matrix(self) -> np.ndarray:
        """Rows: the clamp (zero) and the eyelet discs; ``T @ q'`` are their rotation rates."""
        T = np.zeros((len(self.eye_nodes), self.N))
        for row, node in enumerate(self.eye_nodes[1:], start=1):
            T[row, node - 1] = 1.0
        return T

    def damping_matrix(
        self, q: np.ndarray, M: np.ndarray | None = None, floor: tuple | None = None
    ) -> np.ndarray:
        """Linear damping: ``alpha M`` + disc and chord dashpots + the constant floor ``W^T diag(c) W``."""
        p = self.params
        M = self.mass_matrix(q) if M is None else M
        C = p.alpha * M
        T = self.disc_rate_matrix()
        c_d = p.EI / p.disc_interval
        if p.beta_disc:
            Dd = T[1:] - T[:-1]
            C = C + p.beta_disc * c_d * Dd.T @ Dd
        if p.beta_chord:
            nd = T.shape[0] - 1
            Dc = np.zeros((nd, self.N))
            Dc[0] = 0.5 * T[1]
            for k in range(1, nd):
                Dc[k] = 0.5 * (T[k + 1] - T[k - 1])
            C = C + p.beta_chord * c_d * Dc.T @ Dc
        if floor is not None and floor[1].size:
            W, cw = floor
            C = C + (W.T * cw) @ W
        return C

    # --- statics ----------------------------------------------------------------------------------
    def newton(self, q0: np.ndarray, tol: float = 1e-12, max_iter: int = 60, **kwargs: object) -> np.ndarray:
        """Damped Newton on the gradient of the potential with the exact Hessian."""
        q = np.array(q0, dtype=float)
        scale = float(self.kap)
        g0, _ = self.potential_grad(q, **kwargs)
        for _ in range(max_iter):
            norm = np.linalg.norm(g0) / scale
            if norm < tol:
                return q
            dq = -np.linalg.solve(self.hessian(q, **kwargs), g0)
            step = 1.0
            while True:
                qn = q + step * dq
                gn, _ = self.potential_grad(qn, **kwargs)
                if np.linalg.norm(gn) / scale < norm or step < 1e-3:
                    break
                step *= 0.5
            q, g0 = qn, gn
        if np.linalg.norm(g0) / scale > 1e-8:
            raise RuntimeError(
                f"static equilibrium did not converge (residual {np.linalg.norm(g0) / scale:.2e})"
            )
        return q

    def rest_shape(self, tension: float, n_stages: int = 20) -> np.ndarray:
        """Static shape under a prescribed cable tension (gravity and tension raised together)."""
        p = self.params
        q = np.full(self.N, p.base_angle)
        stages = n_stages if (p.g > 0 or tension > 0) else 1
        for i in range(1, stages + 1):
            f = i / stages
            q = self.newton(q, lam=tension * f, g=p.g * f)
        return q


def node_positions(params: RigParameters, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Backbone node positions (m) for tangent angles ``q`` (..., N): arrays (..., N + 1), clamp first."""
    pos = _chain(params).geometry(np.asarray(q, dtype=float))["p"]
    return pos[..., 0], pos[..., 1]


@functools.lru_cache(maxsize=32)
def _chain(params: RigParameters) -> ArcChain:
    return ArcChain(params)


# --- the kernel's arrays and the rest state --------------------------------------------------------------
@dataclass(frozen=True)
class KernelArrays:
    """What the compiled kernel integrates (``helpers.virtual._kernel``) and the rest state.

    Attributes
    ----------
    P, mb, Jb, disc, W, cw : numpy.ndarray
        Packed scalars, node masses, node rotary inertias, eyelet nodes, the constant damping's rows and
        coefficients.
    y_rest : numpy.ndarray
        The rest state ``[theta, theta', psi, psi', x_c, x_c']``.
    q_rest : numpy.ndarray
        The rest shape (tangent angles).
    ell_rest : float
        Cable length through the arm at rest, m.
    d_drive : float
        Drive increment per step: cable (m, ideal) or commanded rotor angle (rad).
    """

    P: np.ndarray
    mb: np.ndarray
    Jb: np.ndarray
    disc: np.ndarray
    W: np.ndarray
    cw: np.ndarray
    y_rest: np.ndarray
    q_rest: np.ndarray
    ell_rest: float
    d_drive: float

    @property
    def n(self) -> int:
        """Number of elements."""
        return int(self.mb.shape[0])


def floor_damping(chain: ArcChain, q_rest: np.ndarray, tension: float) -> tuple[np.ndarray, np.ndarray]:
    """The high-mode floor ``C_f = W^T diag(c) W``: ``W = (M Phi)^T``, ``c = 2 zeta_f omega s(omega)``.

    ``Phi``, ``omega``: the undamped modes of the arm at rest with the cable as a spring of the series
    stiffness ``k``; ``s = 1 / (1 + (omega_f / omega)^8)``. A matrix function of (K, M), so it does not
    depend on the eigenvector basis inside near-degenerate clusters.
    """
    p = chain.params
    if p.floor_zeta == 0.0:
        return np.zeros((0, chain.N)), np.zeros(0)
    kap, g = chain.cable_tangent(q_rest, tension, p.k)
    K = chain.hessian(q_rest, lam=tension) + kap * np.outer(g, g)
    return floor_modes(K, chain.mass_matrix(q_rest), p.floor_omega, p.floor_zeta)


def floor_modes(
    K: np.ndarray, M: np.ndarray, floor_omega: float, floor_zeta: float
) -> tuple[np.ndarray, np.ndarray]:
    """``W = (M Phi)^T`` and ``c = 2 zeta_f omega s(omega)`` of the floor from the undamped modes of (K, M).

    ``s = 1 / (1 + (omega_f / omega)^8)``; the planar (:func:`floor_damping`) and the spatial twin's floor.
    """
    w2, V = linalg.eigh(K, M)
    om = np.sqrt(np.abs(w2))
    s = 1.0 / (1.0 + (floor_omega / om) ** 8)
    return np.ascontiguousarray((M @ V).T), 2.0 * floor_zeta * om * s


@functools.lru_cache(maxsize=64)
def model_arrays(params: RigParameters) -> KernelArrays:
    """Pack the parameters for the kernel and build the rest state (tension = pretension at position 0).

    The rest shape comes from :meth:`ArcChain.rest_shape` (gravity and pretension raised together). The
    rotor rests at its static lag behind the commanded angle 0; the carriage at ``x_c = 0``. The cables'
    reference lengths are set so that this state carries the pretension.
    """
    p = params
    chain = _chain(p)
    lam0 = p.pretension
    q_rest = chain.rest_shape(lam0)
    ell0 = float(chain.cable_length(q_rest))
    h0 = float(chain.bow_compliance(q_rest)[0])  # the bowing's share of the arm-side stretch
    W, cw = floor_damping(chain, q_rest, lam0)
    P = np.zeros(kern.N_PACKED)
    P[kern.I_L] = chain.l
    P[kern.I_R] = p.r
    P[kern.I_TH0] = p.base_angle
    P[kern.I_G] = p.g
    P[kern.I_ALPHA] = p.alpha
    P[kern.I_KAP] = chain.kap
    P[kern.I_CDISC] = p.beta_disc * p.EI / p.disc_interval
    P[kern.I_CCHORD] = p.beta_chord * p.EI / p.disc_interval
    P[kern.I_BOW] = chain.bow_scale
    P[kern.I_BOWRUN] = 1.0 if np.any(np.diff(chain.eye_nodes) > 1) else 0.0
    P[kern.I_MU] = p.eyelet_mu
    P[kern.I_V0] = p.eyelet_v0
    R = p.spool_radius
    P[kern.I_RSP] = R
    P[kern.I_JR] = p.drive_inertia
    P[kern.I_TH] = p.holding_torque
    P[kern.I_NR] = p.rotor_teeth
    P[kern.I_TLAW] = 1.0 if p.torque_law == "sin" else 0.0
    P[kern.I_MEAS] = 1.0 if p.load_cell_side == "spool" else 0.0
    y = np.zeros(2 * chain.N + 4)
    y[: chain.N] = q_rest
    if p.actuator == "ideal":
        P[kern.I_MODE] = 0.0
        P[kern.I_K2] = p.k
        P[kern.I_ELLREF] = ell0 - lam0 * (1.0 / p.k + h0)
        d_drive = p.cable_per_step
    else:
        psi0 = -p.static_lag(lam0)
        if not math.isfinite(psi0):
            raise ValueError(
                f"the pretension {lam0} N exceeds the motor's pull-out tension {p.pull_out_tension:.2f} N"
            )
        y[2 * chain.N] = psi0
        P[kern.I_CR] = p.rotor_damping
        d_drive = p.step_angle
        if p.actuator == "stepper":
            P[kern.I_MODE] = 1.0
            P[kern.I_K2] = p.k_cable
            P[kern.I_ELLREF] = R * psi0 + ell0 - lam0 * (1.0 / p.k_cable + h0)
        else:
            P[kern.I_MODE] = 2.0
            P[kern.I_K1] = p.k_spool_side
            P[kern.I_K2] = p.k_arm_side
            P[kern.I_ELLREF] = ell0 - lam0 * (1.0 / p.k_arm_side + h0)
            P[kern.I_S1REF] = R * psi0 - lam0 / p.k_spool_side
            P[kern.I_MC] = p.carriage_mass
            P[kern.I_CC] = p.carriage_damping
    arrays = KernelArrays(
        P=P, mb=chain.m_nodes.copy(), Jb=chain.J_nodes.copy(), disc=params.eyelet_nodes(), W=W,
        cw=np.ascontiguousarray(cw), y_rest=y, q_rest=q_rest, ell_rest=ell0, d_drive=d_drive,
    )  # fmt: skip
    for a in (arrays.P, arrays.mb, arrays.Jb, arrays.disc, arrays.W, arrays.cw, arrays.y_rest, arrays.q_rest):
        a.setflags(write=False)
    return arrays


# --- equilibria ----------------------------------------------------------------------------------------
def _static_stiffness(params: RigParameters) -> float:
    """Stiffness between the held spool and the arm: cables and load cell in series (``k`` if ideal)."""
    return params.k if params.actuator == "ideal" else params.k_cable


@dataclass(frozen=True)
class Equilibrium:
    """A static equilibrium of the arm.

    Attributes
    ----------
    u : float
        Cable displacement at the spool from the rest position, m (spool held).
    q : numpy.ndarray
        Tangent angles at the element ends, rad.
    tension : float
        Cable tension, N.
    x, y : numpy.ndarray
        Node positions (clamp first), m.
    """

    u: float
    q: np.ndarray
    tension: float
    x: np.ndarray
    y: np.ndarray

    @property
    def tip_angle(self) -> float:
        """Tangent angle at the tip, rad."""
        return float(self.q[-1])


def _make_eq(params: RigParameters, u: float, q: np.ndarray, tension: float) -> Equilibrium:
    x, y = node_positions(params, q)
    return Equilibrium(u=float(u), q=q, tension=float(tension), x=x, y=y)


def _spring(params: RigParameters) -> dict[str, float]:
    arr = model_arrays(params)
    k = _static_stiffness(params)
    h0 = float(_chain(params).bow_compliance(arr.q_rest)[0])
    return {"k": k, "ell_ref": arr.ell_rest - params.pretension * (1.0 / k + h0)}


def _continue(params: RigParameters, q: np.ndarray, u0: float, u1: float, du_max: float = 1e-3) -> np.ndarray:
    chain = _chain(params)
    spring = _spring(params)
    n_inc = max(1, int(math.ceil(abs(u1 - u0) / du_max - 1e-9)))
    for i in range(1, n_inc + 1):
        q = chain.newton(q, u=u0 + (u1 - u0) * i / n_inc, **spring)
    return q


def _tension_at(params: RigParameters, q: np.ndarray, u: float) -> float:
    spring = _spring(params)
    chain = _chain(params)
    e = u + float(chain.cable_length(q)) - spring["ell_ref"]
    return e / (1.0 / spring["k"] + float(chain.bow_compliance(q)[0])) if e > 0 else 0.0


def equilibrium(params: RigParameters, u: float, du_max: float = 1.0e-3) -> Equilibrium:
    """Frictionless static equilibrium with the cable end at the spool displaced by ``u`` (m), spool held.

    Continuation from the rest state in increments of at most ``du_max``; Newton with the exact Hessian.
    """
    if not math.isfinite(u):
        raise ValueError(f"cable displacement must be finite, got {u!r}")
    q = _continue(params, model_arrays(params).q_rest.copy(), 0.0, u, du_max)
    return _make_eq(params, u, q, _tension_at(params, q, u))


def equilibrium_at_tension(params: RigParameters, tension: float, n_stages: int = 20) -> Equilibrium:
    """Static equilibrium with a prescribed cable tension (N), e.g. for the constant-curvature oracle.

    The cable displacement ``u`` at the held spool that produces it is reported as well.
    """
    if not (math.isfinite(tension) and tension >= 0):
        raise ValueError(f"tension must be finite and >= 0, got {tension!r}")
    chain = _chain(params)
    q = model_arrays(params).q_rest.copy()
    for i in range(1, n_stages + 1):
        lam = params.pretension + (tension - params.pretension) * i / n_stages
        q = chain.newton(q, lam=lam)
    spring = _spring(params)
    h = float(chain.bow_compliance(q)[0])
    u = tension * (1.0 / spring["k"] + h) - float(chain.cable_length(q)) + spring["ell_ref"]
    return _make_eq(params, u, q, tension)


# --- linearisation -------------------------------------------------------------------------------------
DECAY_S: float = 1.0
"""Default age (s) of the transient at which :func:`linearise` ranks the modes: the paper identifies on
9-10 s, 1-2 s after the release at 8 s, so the mode that dominates there is the one that matters."""


def modal_state(M: np.ndarray, C: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The well-conditioned state form of ``M x'' + C x' + K x = 0`` (planar and spatial twins alike).

    Mass-normalised modal coordinates from the flexibility problem ``L_K^-1 M L_K^-T psi = omega^-2 psi``
    (``K = L_K L_K^T``), whose largest eigenvalues (the low modes) come out with full relative accuracy; the
    mass-normalised form ``L_M^-1 K L_M^-T`` if ``K`` is not positive definite. The state is the near-normal
    ``[Omega eta, eta']``.

    Returns
    -------
    T : numpy.ndarray
        The modal transformation ``x = T eta``.
    Om : numpy.ndarray
        The undamped modal frequencies (rad/s).
    A : numpy.ndarray
        The state matrix (``2n x 2n``).
    """
    try:
        Lk = linalg.cholesky(K, lower=True)
        Lki = linalg.solve_triangular(Lk, np.eye(K.shape[0]), lower=True)
        Mt = Lki @ M @ Lki.T
        mu, Psi = linalg.eigh(0.5 * (Mt + Mt.T))
        mu, Psi = mu[::-1], Psi[:, ::-1]
        Om = 1.0 / np.sqrt(mu)
        T = (Lki.T @ Psi) * Om
    except linalg.LinAlgError:  # K not positive definite: the mass-normalised form
        Lc = linalg.cholesky(M, lower=True)
        Li = linalg.solve_triangular(Lc, np.eye(M.shape[0]), lower=True)
        Kt = Li @ K @ Li.T
        w2, Phi = linalg.eigh(0.5 * (Kt + Kt.T))
        Om = np.sqrt(np.abs(w2))
        T = Li.T @ Phi
    Cm = T.T @ C @ T
    Cm = 0.5 * (Cm + Cm.T)
    n = M.shape[0]
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.diag(Om)
    A[n:, :n] = -np.diag(Om)
    A[n:, n:] = -Cm
    return T, Om, A


def state_space_poles(
    M: np.ndarray, C: np.ndarray, K: np.ndarray, f_in: np.ndarray, c_out: np.ndarray, decay_s: float = DECAY_S
) -> tuple[np.ndarray, np.ndarray]:
    """Poles of ``M x'' + C x' + K x = f_in u`` and their weights in the step response of ``y = c_out . x``.

    The state form of :func:`modal_state`. Weights: ``2 |r / p| exp(Re p decay_s)``.

    Returns
    -------
    poles : numpy.ndarray
        Sorted by modulus.
    weights : numpy.ndarray
        Amplitude of each pole's term in the step response, ``decay_s`` after the step.
    """
    T, Om, A = modal_state(M, C, K)
    n = M.shape[0]
    b = np.concatenate([np.zeros(n), T.T @ f_in])
    cc = np.concatenate([(c_out @ T) / Om, np.zeros(n)])
    ev, vl, vr = linalg.eig(A, left=True, right=True)
    res = (cc @ vr) * (vl.conj().T @ b) / np.einsum("ij,ij->j", vl.conj(), vr)
    order = np.argsort(np.abs(ev), kind="stable")
    ev, res = ev[order], res[order]
    return ev, 2.0 * np.abs(res / ev) * np.exp(ev.real * decay_s)


@dataclass(frozen=True)
class Linearisation:
    """Small vibrations about an equilibrium.

    Attributes
    ----------
    equilibrium : Equilibrium
        The operating point.
    rotor : str
        ``"locked"`` (spool held) or ``"free"`` (rotor on its microstep spring, the rig as it runs).
    poles : numpy.ndarray
        Eigenvalues of the state matrix (1/s), sorted by modulus.
    weights : numpy.ndarray
        Amplitude of each pole in the measured tension's response to a drive step, ``decay_s`` after it.
    omega_n, zeta, omega_d : float
        The *dominant* mode: the oscillatory pair with the largest weight.
    M, C, K : numpy.ndarray
        Mass, damping and tangent-stiffness matrices (arm coordinates, then rotor and carriage if present).
    n_arm : int
        Number of arm coordinates.
    """

    equilibrium: Equilibrium
    rotor: str
    poles: np.ndarray
    weights: np.ndarray
    omega_n: float
    zeta: float
    omega_d: float
    M: np.ndarray = field(repr=False)
    C: np.ndarray = field(repr=False)
    K: np.ndarray = field(repr=False)
    n_arm: int = 0

    def modes(self) -> pd.DataFrame:
        """The oscillatory poles (upper half-plane), lowest first: omega_n, zeta, omega_d, weight."""
        up = self.poles.imag > 1e-9
        p, w = self.poles[up], self.weights[up]
        order = np.argsort(np.abs(p), kind="stable")
        p, w = p[order], w[order]
        return pd.DataFrame(
            {"omega_n": np.abs(p), "zeta": -p.real / np.abs(p), "omega_d": p.imag, "weight": w}
        )

    def undamped(self) -> np.ndarray:
        """Undamped natural frequencies (rad/s), ascending (``K phi = w^2 M phi``)."""
        return np.sqrt(np.abs(linalg.eigh(self.K, self.M, eigvals_only=True)))


def linearise(
    params: RigParameters,
    u: float = 0.0,
    eq: Equilibrium | None = None,
    rotor: str = "free",
    decay_s: float = DECAY_S,
) -> Linearisation:
    """Linearise the rig about the static equilibrium at cable displacement ``u`` (m).

    Coordinates: the arm's, then (actuators with a stepper) the rotor angle if ``rotor="free"``, then the
    carriage position (``stepper+carriage``). With ``rotor="locked"`` the spool is held; with
    ``rotor="free"`` the rotor sits on the motor's tangent microstep stiffness at its static lag and the
    input is the commanded rotor angle (the cable displacement for the ideal actuator). The output is the
    tension the load cell reads. Velocity-product terms vanish at rest, so ``M``, ``C`` and the exact
    Hessian ``K`` are all there is; a cable with zero tension is linearised as a two-sided spring.
    """
    if rotor not in ("free", "locked"):
        raise ValueError(f"rotor must be 'free' or 'locked', got {rotor!r}")
    p = params
    eq = equilibrium(p, u) if eq is None else eq
    chain = _chain(p)
    arr = model_arrays(p)
    floor = (np.asarray(arr.W), np.asarray(arr.cw))
    q, lam = eq.q, eq.tension
    N = chain.N
    bil = lam <= 1e-12
    Hl = chain.hessian(q, lam=lam)
    M_arm = chain.mass_matrix(q)
    C_arm = chain.damping_matrix(q, M_arm, floor)
    R = p.spool_radius
    if p.actuator == "ideal" or (p.actuator == "stepper" and rotor == "locked"):
        kc, dl = chain.cable_tangent(q, lam, p.k if p.actuator == "ideal" else p.k_cable)
        kc = kc if (lam > 0 or bil) else 0.0
        K = Hl + kc * np.outer(dl, dl)
        bf = -kc * dl
        cvec = kc * dl
        Mf, Cf = M_arm, C_arm
    else:
        carriage = p.actuator == "stepper+carriage"
        free = rotor == "free"
        n = N + int(free) + int(carriage)
        K = np.zeros((n, n))
        Mf = np.zeros((n, n))
        Cf = np.zeros((n, n))
        Mf[:N, :N] = M_arm
        Cf[:N, :N] = C_arm
        bf = np.zeros(n)
        Km = p.tangent_motor_stiffness(p.static_lag(lam)) if free else 0.0
        ir = N if free else -1
        if not carriage:  # stepper, rotor free
            kc, dl = chain.cable_tangent(q, lam, p.k_cable)
            K[:N, :N] = Hl + kc * np.outer(dl, dl)
            K[:N, ir] = K[ir, :N] = kc * R * dl
            K[ir, ir] = kc * R**2 + Km
            Mf[ir, ir] = p.drive_inertia
            Cf[ir, ir] = p.rotor_damping
            bf[ir] = Km
            cvec = np.concatenate([kc * dl, [kc * R]])
        else:
            k1 = p.k_spool_side
            k2, dl = chain.cable_tangent(q, lam, p.k_arm_side)
            ic = n - 1
            K[:N, :N] = Hl + k2 * np.outer(dl, dl)
            K[:N, ic] = K[ic, :N] = k2 * dl
            K[ic, ic] = k1 + k2
            Mf[ic, ic] = p.carriage_mass
            Cf[ic, ic] = p.carriage_damping
            if free:
                K[ir, ir] = k1 * R**2 + Km
                K[ir, ic] = K[ic, ir] = -k1 * R
                Mf[ir, ir] = p.drive_inertia
                Cf[ir, ir] = p.rotor_damping
                bf[ir] = Km
            else:
                bf[ic] = k1 * R  # input: the spool angle
            cvec = np.zeros(n)
            if p.load_cell_side == "arm":
                cvec[:N] = k2 * dl
                cvec[ic] = k2
            else:
                cvec[ic] = -k1
                if free:
                    cvec[ir] = k1 * R
    poles, weights = state_space_poles(Mf, Cf, K, bf, cvec, decay_s)
    up = poles.imag > 1e-9
    if not np.any(up):
        raise ValueError("the linearisation has no oscillatory mode")
    best = poles[int(np.argmax(np.where(up, weights, -1.0)))]
    wn = float(abs(best))
    return Linearisation(
        equilibrium=eq, rotor=rotor, poles=poles, weights=weights, omega_n=wn, zeta=float(-best.real / wn),
        omega_d=float(best.imag), M=Mf, C=Cf, K=K, n_arm=N,
    )  # fmt: skip


def _bending_modes(lin: Linearisation, n_modes: int) -> list[tuple[float, float, float]]:
    """The ``n_modes`` lowest oscillatory poles as ``(omega_n, omega_d, zeta)``."""
    m = lin.modes()
    return [(float(r.omega_n), float(r.omega_d), float(r.zeta)) for r in m.iloc[:n_modes].itertuples()]


def frequency_map(
    params: RigParameters, u_mm: np.ndarray | None = None, n_modes: int = 2, decay_s: float = DECAY_S
) -> pd.DataFrame:
    """The frequency map: statics and small vibrations for cable displacements ``u_mm`` (mm).

    At each ``u``: the frictionless static equilibrium with the spool held (rotor locked) at cable
    displacement ``u`` and the lowest bending modes of the small vibrations about it (rotor locked); also the
    dominant mode of the rig as it runs (rotor free, the mode the identification window sees).

    Returns
    -------
    pandas.DataFrame
        ``u_mm``, ``static_tension_n``, ``omega_n_rad_s``, ``omega_d_rad_s``, ``zeta`` (the lowest bending
        mode), ``omega_d2_rad_s``, ``zeta2`` (the second, if ``n_modes >= 2``), ``tip_angle_deg``,
        ``dominant_omega_d_rad_s``, ``dominant_zeta`` (rotor free, largest weight ``decay_s`` after a step).
    """
    u_mm = np.arange(0.0, 40.01, 1.0) if u_mm is None else np.asarray(u_mm, dtype=float)
    if np.any(~np.isfinite(u_mm)):
        raise ValueError("u_mm must be finite")
    rows = []
    q = model_arrays(params).q_rest.copy()
    u_prev = 0.0
    for u in np.sort(u_mm) * 1e-3:
        q = _continue(params, q, u_prev, u)
        u_prev = u
        eq = _make_eq(params, u, q, _tension_at(params, q, u))
        locked = linearise(params, u, eq=eq, rotor="locked", decay_s=decay_s)
        free = linearise(params, u, eq=eq, rotor="free", decay_s=decay_s)
        modes = _bending_modes(locked, n_modes)
        row = {
            "u_mm": u * 1e3,
            "static_tension_n": eq.tension,
            "omega_n_rad_s": modes[0][0],
            "omega_d_rad_s": modes[0][1],
            "zeta": modes[0][2],
        }
        for i in range(1, n_modes):
            row[f"omega_d{i + 1}_rad_s"] = modes[i][1]
            row[f"zeta{i + 1}"] = modes[i][2]
        row["tip_angle_deg"] = math.degrees(eq.tip_angle - params.base_angle)
        row["dominant_omega_d_rad_s"] = free.omega_d
        row["dominant_zeta"] = free.zeta
        rows.append(row)
    return pd.DataFrame(rows)


def _rk4_amplification(z: np.ndarray) -> np.ndarray:
    return np.abs(1.0 + z + z**2 / 2.0 + z**3 / 6.0 + z**4 / 24.0)


def rk4_stable_step(poles: np.ndarray, h_hi: float = 5e-3) -> float:
    """Largest fixed step ``h`` (s) with ``|R(p h)| <= 1`` for every pole.

    ``R`` is classical RK4's stability polynomial; a scan from below, refined by bisection.
    """
    poles = np.asarray(poles)[np.abs(poles) > 1e-9]
    if poles.size == 0:
        return h_hi
    hs = np.linspace(h_hi / 2000, h_hi, 2000)
    ok = np.array([np.all(_rk4_amplification(poles * h) <= 1 + 1e-12) for h in hs])
    if ok.all():
        return h_hi
    first_bad = int(np.argmin(ok))
    lo = hs[first_bad - 1] if first_bad > 0 else 0.0
    hi = hs[first_bad]
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if np.all(_rk4_amplification(poles * mid) <= 1 + 1e-12):
            lo = mid
        else:
            hi = mid
    return float(lo)


def stable_max_step(
    params: RigParameters, u_mm: tuple[float, ...] = (0.0, 20.0, 40.0), margin: float = 0.9
) -> float:
    """The largest step ``1 ms / n`` (n = 2, 3, ...) within ``margin`` of RK4's linear stability limit.

    The limit is taken over the rig's linearisations (rotor free) at the cable displacements ``u_mm``; the
    stiffest mode is the tip disc rocking against the cable (about ``sqrt(k_arm r^2 / J_disc)``), so it
    falls as the cable gets stiffer. Whole divisions of the 1 ms sample interval keep every sample interval
    split into equal steps.
    """
    q = model_arrays(params).q_rest.copy()
    h = math.inf
    u_prev = 0.0
    for u in sorted(u_mm):
        q = _continue(params, q, u_prev, u * 1e-3)
        u_prev = u * 1e-3
        eq = _make_eq(params, u_prev, q, _tension_at(params, q, u_prev))
        h = min(h, rk4_stable_step(linearise(params, u_prev, eq=eq, rotor="free").poles))
    n = max(2, math.ceil(1e-3 / (margin * h) - 1e-9))
    return 1e-3 / n
