"""The spatial arc chain in numpy: kinematics, tendon paths, potential and its gradient, mass and damping.

The rod is cut into ``N`` elements of constant strain (the piecewise-constant-strain Cosserat rod without
shear or stretch): element ``e`` turns its end frame against its start frame by the rotation vector
``phi_e = (a_e, b_e, c_e)`` (``a``, ``b``: bending about the start frame's ``x`` and ``y``; ``c``: twist about
its ``z``, the tangent), ``E_e = exp([phi_e])``, and its end node sits at the chord ``l J_l(phi_e) e3`` in the
start frame (``J_l`` the left Jacobian of SO(3)). Without twist an element is a circular arc in the plane
its bending axis is normal to: in the ``x-z`` plane (``a = c = 0``) it is the planar rig's arc exactly, with
``b_e = D_e = theta_e - theta_{e-1}``. The potential ``sum_e (EI (a^2 + b^2) + GJ c^2) / (2 l)`` is exact
for constant strain.

Nodes carry the planar rig's point masses; a disc node also the disc's rotary inertia ``diag(J_d, J_d, J_p)``
in its frame, and every node the wire's polar inertia. Tendon ``i`` runs straight from eyelet to eyelet, at
``p_k + R_k rho_i`` on disc ``k`` (``rho_i = r_i (cos a_i, sin a_i, 0)``), from the clamp's guide to the knot
on the tip disc. The rod's bowing between eyelets generalises the planar rig's: the part of the tendons'
moment an element cannot carry is the complementary energy ``(1/2) lam^T H(q) lam``, with the tendon-coupled
compliance ``H_ij = sum_e (l^3/EI) (P(D_e) + Q(D_e) sigma_ie . sigma_je)`` (``D_e`` the element's bending
angle, ``sigma_ie`` the component of tendon ``i``'s run across element ``e`` normal to the element's chord).
With one element per run (the rig) the run is parallel to the chord but for twist, and the tilt term is left
out: against a 4x finer rod, a twist-driven tilt term over-softens the twisting modes (the lowest sideways
mode of the paper's rig at 40 mm: -0.93 % with it, +0.12 % without), so one-element runs use the planar
rig's ``P`` alone; finer rods (the convergence study) keep ``Q`` for their runs' in-plane tilt, as the
planar rig does.

Every function is plain numpy, batched over leading dimensions and complex-step safe, so the Hessians of the
statics are exact (:mod:`helpers.virtual.spatial.statics`); the compiled kernel writes the same equations
again (:mod:`helpers.virtual.spatial._kernel`), and the tests compare the two.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from helpers.virtual.spatial.rig import SpatialRig
from helpers.virtual.statics import _BOW_P, _BOW_Q, bow_functions

__all__ = ["so3_functions", "bow_functions_x", "SpatialChain", "Control", "skew"]

_N_SO3 = 16  # terms of the series in x = |phi|^2 below 1: truncation below 1e-20


def _so3_coefficients() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    k = np.arange(_N_SO3 + 3)
    fact = np.array([math.factorial(int(i)) for i in range(2 * len(k) + 4)], dtype=float)
    sign = (-1.0) ** k
    return sign / fact[2 * k + 1], sign / fact[2 * k + 2], sign / fact[2 * k + 3]


_SA, _SB, _SC = _so3_coefficients()


def _horner(coef: np.ndarray, x: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``sum_j coef_j x^j`` over ``j < n`` and its x-derivative."""
    f = np.zeros_like(x)
    df = np.zeros_like(x)
    for j in range(n - 1, -1, -1):
        df = df * x + f
        f = f * x + coef[j]
    return f, df


def so3_functions(x: np.ndarray) -> tuple[np.ndarray, ...]:
    """``A = sin t / t``, ``B = (1 - cos t) / t^2``, ``C = (t - sin t) / t^3`` of ``t = sqrt(x)`` and d/dx.

    ``exp([phi]) = I + A [phi] + B [phi]^2`` and ``J_l(phi) = I + B [phi] + C [phi]^2`` with ``x = |phi|^2``.
    Series for ``|Re x| < 1``, closed forms beyond; complex arguments supported (complex step).

    Returns
    -------
    tuple of numpy.ndarray
        ``(A, B, C, A_x, B_x, C_x)``.
    """
    x = np.asarray(x)
    small = np.abs(x.real) < 1.0
    xs = np.where(small, x, 0.0)
    A1, Ax1 = _horner(_SA, xs, _N_SO3)
    B1, Bx1 = _horner(_SB, xs, _N_SO3)
    C1, Cx1 = _horner(_SC, xs, _N_SO3)
    if np.all(small):
        return A1, B1, C1, Ax1, Bx1, Cx1
    xl = np.where(small, 4.0, x)
    t = np.sqrt(xl)
    s, co = np.sin(t), np.cos(t)
    A2 = s / t
    B2 = (1.0 - co) / xl
    C2 = (t - s) / (xl * t)
    Ax2 = (co - A2) / (2.0 * xl)
    Bx2 = (A2 - 2.0 * B2) / (2.0 * xl)
    Cx2 = (B2 - 3.0 * C2) / (2.0 * xl)
    return tuple(
        np.where(small, u, v) for u, v in ((A1, A2), (B1, B2), (C1, C2), (Ax1, Ax2), (Bx1, Bx2), (Cx1, Cx2))
    )


def bow_functions_x(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The planar rig's bowing shape factors ``P``, ``Q`` as functions of ``x = D^2``, and d/dx.

    (:func:`helpers.virtual.statics.bow_functions`: ``P = D^2/720 - ...``, ``Q = 1/12 - ...``.) Series for
    ``|Re x| < 4``, the closed form beyond; complex arguments supported.

    Returns
    -------
    tuple of numpy.ndarray
        ``(P, Q, P_x, Q_x)``.
    """
    x = np.asarray(x)
    small = np.abs(x.real) < 4.0
    xs = np.where(small, x, 0.0)
    P1, Px1 = _horner(_BOW_P, xs, len(_BOW_P))
    Q1, Qx1 = _horner(_BOW_Q, xs, len(_BOW_Q))
    if np.all(small):
        return P1, Q1, Px1, Qx1
    xl = np.where(small, 9.0, x)
    D = np.sqrt(xl)
    P2, Q2, dP2, dQ2 = bow_functions(D)
    return (np.where(small, P1, P2), np.where(small, Q1, Q2), np.where(small, Px1, dP2 / (2.0 * D)),
            np.where(small, Qx1, dQ2 / (2.0 * D)))  # fmt: skip


def skew(v: np.ndarray) -> np.ndarray:
    """``[v]x`` (..., 3, 3) of vectors (..., 3)."""
    v = np.asarray(v)
    z = np.zeros_like(v[..., 0])
    return np.stack(
        [np.stack([z, -v[..., 2], v[..., 1]], -1), np.stack([v[..., 2], z, -v[..., 0]], -1),
         np.stack([-v[..., 1], v[..., 0], z], -1)], -2,
    )  # fmt: skip


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis (complex safe, broadcasting)."""
    return np.stack(
        [a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1], a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
         a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], -1,
    )  # fmt: skip


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (a * b).sum(-1)


@dataclass(frozen=True)
class Control:
    """How each tendon is held in a static problem.

    Attributes
    ----------
    lam : numpy.ndarray
        Prescribed tension per tendon (N), NaN where the tendon is displacement-controlled.
    e0 : numpy.ndarray
        For displacement-controlled tendons: the stretch at ``q`` is ``e0 + ell(q)`` (``u - ell_ref``), m.
    kinv : numpy.ndarray
        For displacement-controlled tendons: the compliance of the spring between the held end and the arm,
        m/N (the bowing's is added).
    motor : tuple or None
        ``(R, T_h, N_r, sin_law)``: the held end is a stepper's commanded angle, and its rotor lags it by
        ``lag(lam) = asin(R lam / T_h) / N_r`` (``R lam / (T_h N_r)`` for the linear law), which shortens the
        stretch by ``R lag(lam)`` (``e0`` then holds the rest lag's ``+ R lag(lam_0)``). ``None``: the spool
        itself is held.
    """

    lam: np.ndarray
    e0: np.ndarray
    kinv: np.ndarray
    motor: tuple | None = None

    @property
    def tension_controlled(self) -> np.ndarray:
        """Mask of the tendons with a prescribed tension."""
        return np.isfinite(self.lam)


class SpatialChain:
    """The spatial arm's geometry, potential and matrices for coordinates ``q`` (3N: ``a, b, c`` per element).

    Every function accepts leading batch dimensions and complex arrays.

    Parameters
    ----------
    rig : SpatialRig
        The rig.
    """

    def __init__(self, rig: SpatialRig) -> None:
        p = rig.arm
        self.rig = rig
        self.N = p.n_elements
        self.nq = 3 * self.N
        self.nt = rig.n_tendons
        self.l = p.element_length
        self.m_nodes = p.node_masses()
        Jd = p.node_inertias().copy()
        Jp = np.zeros(self.N)
        Jp[p.disc_nodes() - 1] = rig.disc_polar_inertia
        wire_polar = p.rho * math.pi * p.d**4 / 32.0 * self.l  # the wire's own polar inertia per element
        Jp += wire_polar * np.where(np.arange(self.N) == self.N - 1, 0.5, 1.0)
        Jd[-1] *= rig.tip_inertia_scale
        self.Jd_nodes = Jd
        self.Jp_nodes = Jp
        self.disc_nodes = p.disc_nodes()
        self.eye_nodes = np.concatenate([[0], p.eyelet_nodes()])  # the clamp guide first
        self.n_runs = len(self.eye_nodes) - 1
        self.element_run = np.searchsorted(self.eye_nodes, np.arange(1, self.N + 1), side="left") - 1
        self.rho = rig.offsets
        self.kb = p.EI / self.l
        self.kt = rig.GJ / self.l
        self.gvec = rig.gravity
        self.bow_scale = self.l**3 / p.EI if p.bowing else 0.0
        self.base = np.eye(3)

    # --- kinematics ---------------------------------------------------------------------------------
    def kinematics(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """Frames, nodes and the element Jacobians.

        Returns
        -------
        dict
            ``R`` (..., N+1, 3, 3) node frames (clamp first); ``p`` (..., N+1, 3) node positions; per element
            (..., N, ...): ``phi``, ``x`` (= |phi|^2), ``xb`` (bending part ``a^2 + b^2``), ``E``, ``Jl``,
            ``chi`` (chord in the start frame), ``dchi`` (d chi / d phi, columns); ``Jv`` = ``R_{e-1} dchi``
            and ``Jw`` = ``R_{e-1} J_l`` (node e's velocity and frame e's angular velocity per phi_e rate,
            world).
        """
        q = np.asarray(q)
        Q = q.reshape(q.shape[:-1] + (self.N, 3))
        a, b, c = Q[..., 0], Q[..., 1], Q[..., 2]
        x = a * a + b * b + c * c
        A, B, C, _, Bx, Cx = so3_functions(x)
        K = skew(Q)
        K2 = K @ K
        eye = np.eye(3)
        E = eye + A[..., None, None] * K + B[..., None, None] * K2
        Jl = eye + B[..., None, None] * K + C[..., None, None] * K2
        zero = np.zeros_like(a)
        w = np.stack([b, -a, zero], -1)  # phi x e3
        z = np.stack([c * a, c * b, c * c - x], -1)  # phi x (phi x e3)
        e3 = np.array([0.0, 0.0, 1.0])
        chi = self.l * (e3 + B[..., None] * w + C[..., None] * z)
        # d chi / d phi_k = l (2 B_x phi_k w + B dw_k + 2 C_x phi_k z + C dz_k)
        dw = np.zeros(Q.shape + (3,), dtype=Q.dtype)  # (..., N, 3 comps, 3 k)
        dw[..., 1, 0] = -1.0
        dw[..., 0, 1] = 1.0
        dz = c[..., None, None] * np.broadcast_to(eye, Q.shape + (3,)).astype(Q.dtype)
        dz = dz.copy()
        dz[..., :, 2] += Q  # d(c phi)/dc = phi
        dz[..., 2, :] -= 2.0 * Q
        dchi = self.l * (2.0 * Bx[..., None, None] * w[..., :, None] * Q[..., None, :]
                         + B[..., None, None] * dw
                         + 2.0 * Cx[..., None, None] * z[..., :, None] * Q[..., None, :]
                         + C[..., None, None] * dz)  # fmt: skip
        shape = q.shape[:-1]
        R = np.empty(shape + (self.N + 1, 3, 3), dtype=E.dtype)
        pos = np.empty(shape + (self.N + 1, 3), dtype=E.dtype)
        R[..., 0, :, :] = self.base
        pos[..., 0, :] = 0.0
        for e in range(self.N):
            Rp = R[..., e, :, :]
            pos[..., e + 1, :] = pos[..., e, :] + (Rp @ chi[..., e, :, None])[..., 0]
            R[..., e + 1, :, :] = Rp @ E[..., e, :, :]
        Rprev = R[..., :-1, :, :]
        return {"phi": Q, "x": x, "xb": a * a + b * b, "E": E, "Jl": Jl, "chi": chi, "dchi": dchi, "R": R,
                "p": pos, "Jv": Rprev @ dchi, "Jw": Rprev @ Jl}  # fmt: skip

    def positions(self, q: np.ndarray) -> np.ndarray:
        """Node positions (..., N+1, 3), clamp first, m."""
        return self.kinematics(q)["p"]

    def tip(self, q: np.ndarray) -> np.ndarray:
        """Tip node position (..., 3), m."""
        return self.kinematics(q)["p"][..., -1, :]

    def eyelets(self, q: np.ndarray, kin: dict | None = None) -> np.ndarray:
        """Eyelet positions (..., n_tendons, n_eyelets + 1, 3), the clamp guide first."""
        kin = self.kinematics(q) if kin is None else kin
        R = kin["R"][..., self.eye_nodes, :, :]  # (..., Q+1, 3, 3)
        off = np.einsum("...kab,tb->...tka", R, self.rho)
        return kin["p"][..., None, self.eye_nodes, :] + off

    def _runs(self, kin: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        R = kin["R"][..., self.eye_nodes, :, :]
        off = np.einsum("...kab,tb->...tka", R, self.rho)  # (..., nt, Q+1, 3) = R rho
        E = kin["p"][..., None, self.eye_nodes, :] + off
        d = E[..., 1:, :] - E[..., :-1, :]
        L = np.sqrt(_dot(d, d))
        return off, d, L, d / L[..., None]

    # --- generalised forces from point forces -------------------------------------------------------------
    def _generalised(self, kin: dict, F: np.ndarray, M: np.ndarray) -> np.ndarray:
        """``dV/dq`` (..., 3N) from loads on the frames.

        ``F_k = sum dV/dx`` over the points fixed to frame k (..., N+1, 3) and ``M_k = sum (x - p_k) x dV/dx``
        (plus pure moments) about node k. ``F`` and ``M`` may carry extra axes before the node axis (e.g.
        one per tendon). Element ``e`` turns everything beyond node ``e - 1``: ``dV/dphi_e = Jv_e^T F_tot +
        Jw_e^T M_tot``, the totals over frames ``k >= e`` (moments about node ``e``), as suffix sums.
        """
        extra = F.ndim - kin["p"].ndim
        p = kin["p"].reshape(kin["p"].shape[:-2] + (1,) * extra + kin["p"].shape[-2:])
        Jv = kin["Jv"].reshape(kin["Jv"].shape[:-3] + (1,) * extra + kin["Jv"].shape[-3:])
        Jw = kin["Jw"].reshape(kin["Jw"].shape[:-3] + (1,) * extra + kin["Jw"].shape[-3:])

        def suffix(a: np.ndarray) -> np.ndarray:
            return np.flip(np.cumsum(np.flip(a, -2), -2), -2)

        Ft = suffix(F)
        Mt = suffix(M + _cross(p, F)) - _cross(p, Ft)  # about each node
        out = np.einsum("...eab,...ea->...eb", Jv, Ft[..., 1:, :]) + np.einsum(
            "...eab,...ea->...eb", Jw, Mt[..., 1:, :]
        )
        return out.reshape(out.shape[:-2] + (self.nq,))

    def _eyelet_loads(self, kin: dict, G: np.ndarray, off: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Frame loads ``F``, ``M`` (..., N+1, 3) from gradients ``G`` (..., nt, Q+1, 3) at the eyelets.

        The tendon axis (-3) is summed; pass ``G[..., :, None, :, :]`` to keep one load set per tendon.
        """
        shape = G.shape[:-3] + (self.N + 1, 3)
        F = np.zeros(shape, dtype=np.result_type(G, off))
        M = np.zeros(shape, dtype=np.result_type(G, off))
        Fk = G.sum(-3)  # over the tendon axis: (..., Q+1, 3)
        Mk = _cross(off, G).sum(-3)
        F[..., self.eye_nodes, :] += Fk
        M[..., self.eye_nodes, :] += Mk
        return F, M

    # --- tendons ----------------------------------------------------------------------------------------
    def tendon_lengths(self, q: np.ndarray, kin: dict | None = None) -> np.ndarray:
        """Path of each tendon from the clamp's guide to the knot (..., n_tendons), m."""
        kin = self.kinematics(q) if kin is None else kin
        return self._runs(kin)[2].sum(-1)

    def length_grad(self, q: np.ndarray, kin: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Tendon paths (..., nt) and their gradients (..., nt, 3N)."""
        kin = self.kinematics(q) if kin is None else kin
        off, d, L, u = self._runs(kin)
        G = np.zeros(off.shape, dtype=u.dtype)  # dl/d(eyelet): u_k - u_{k+1}; the guide is fixed
        G[..., 1:, :] += u
        G[..., 1:-1, :] -= u[..., 1:, :]
        G[..., 0, :] = 0.0
        # one load set per tendon
        F, M = self._eyelet_loads(kin, G[..., :, None, :, :], off[..., :, None, :, :])
        return L.sum(-1), self._generalised(kin, F, M)

    def _bow_parts(self, kin: dict) -> dict[str, np.ndarray]:
        off, d, L, u = self._runs(kin)
        ch = kin["p"][..., 1:, :] - kin["p"][..., :-1, :]
        Lc = np.sqrt(_dot(ch, ch))
        chat = ch / Lc[..., None]
        ue = u[..., self.element_run, :]  # (..., nt, N, 3): each element's run
        sig = ue - _dot(ue, chat[..., None, :, :])[..., None] * chat[..., None, :, :]
        P, Q, Px, Qx = bow_functions_x(kin["xb"])
        if self.rig.arm.elements_per_disc == 1:  # one element per run: no tilt term (module docstring)
            Q, Qx = 0.0 * Q, 0.0 * Qx
        return {"off": off, "L": L, "u": u, "Lc": Lc, "chat": chat, "ue": ue, "sig": sig, "P": P, "Q": Q,
                "Px": Px, "Qx": Qx}  # fmt: skip

    def bow_matrix(self, q: np.ndarray, kin: dict | None = None) -> np.ndarray:
        """The tendon-coupled bowing compliance ``H`` (..., nt, nt), m/N (zero if the bowing is off)."""
        kin = self.kinematics(q) if kin is None else kin
        bp = self._bow_parts(kin)
        sig = bp["sig"]
        h = self.bow_scale
        Pn = h * bp["P"].sum(-1)
        ss = np.einsum("...ieh,...jeh,...e->...ij", sig, sig, h * bp["Q"])
        return Pn[..., None, None] + ss

    def bow_grad(self, q: np.ndarray, lam: np.ndarray, kin: dict | None = None) -> np.ndarray:
        """``d(lam^T H(q) lam)/dq`` at fixed tensions ``lam`` (..., nt), (..., 3N)."""
        kin = self.kinematics(q) if kin is None else kin
        if self.bow_scale == 0.0:
            return np.zeros(np.shape(q), dtype=np.result_type(q, lam))
        bp = self._bow_parts(kin)
        h = self.bow_scale
        lam = np.asarray(lam)
        S = lam.sum(-1)
        s = np.einsum("...i,...ieh->...eh", lam, bp["sig"])  # (..., N, 3)
        s2 = _dot(s, s)
        Q = bp["Q"]
        # direct: d/d(xb) through P and Q, xb = a^2 + b^2
        dxb = h * (bp["Px"] * (S * S)[..., None] + bp["Qx"] * s2)
        Qe = kin["phi"]
        direct = np.stack([2.0 * Qe[..., 0] * dxb, 2.0 * Qe[..., 1] * dxb, np.zeros_like(dxb)], -1)
        # through the runs' directions: d|s|^2/du_i = 2 lam_i s, summed over the run's elements
        gu_e = (
            2.0 * h * Q[..., None, :, None] * lam[..., :, None, None] * s[..., None, :, :]
        )  # (..., nt, N, 3)
        gu = np.zeros(bp["u"].shape, dtype=gu_e.dtype)
        for e in range(self.N):
            gu[..., self.element_run[e], :] += gu_e[..., e, :]
        u = bp["u"]
        gd = (gu - _dot(gu, u)[..., None] * u) / bp["L"][..., None]  # d/d(run vector)
        G = np.zeros(bp["off"].shape, dtype=gd.dtype)
        G[..., 1:, :] += gd
        G[..., :-1, :] -= gd
        G[..., 0, :] = 0.0
        F, M = self._eyelet_loads(kin, G, bp["off"])
        # through the chords' directions: d|s|^2/d(chord) = -2 mu s / |chord|, mu = sum lam_i (u_i . c)
        mu = np.einsum("...i,...ie->...e", lam, _dot(bp["ue"], bp["chat"][..., None, :, :]))
        gc = -2.0 * h * (Q * mu / bp["Lc"])[..., None] * s
        F = F.copy()
        F[..., 1:, :] += gc
        F[..., :-1, :] -= gc
        return self._generalised(kin, F, M) + direct.reshape(direct.shape[:-2] + (self.nq,))

    # --- potential ---------------------------------------------------------------------------------------
    def elastic_grad(self, q: np.ndarray) -> np.ndarray:
        """Gradient of ``sum (EI (a^2 + b^2) + GJ c^2) / (2 l)``."""
        q = np.asarray(q)
        k = np.tile(np.array([self.kb, self.kb, self.kt]), self.N)
        return k * q

    def elastic_energy(self, q: np.ndarray) -> np.ndarray:
        """``sum (EI (a^2 + b^2) + GJ c^2) / (2 l)``, J."""
        q = np.asarray(q)
        k = np.tile(np.array([self.kb, self.kb, self.kt]), self.N)
        return 0.5 * (k * q * q).sum(-1)

    def gravity_grad(self, q: np.ndarray, kin: dict | None = None, g: np.ndarray | None = None) -> np.ndarray:
        """Gradient of ``-sum m_j g . p_j``."""
        kin = self.kinematics(q) if kin is None else kin
        g = self.gvec if g is None else np.asarray(g)
        F = np.zeros(kin["p"].shape, dtype=kin["p"].dtype)
        F[..., 1:, :] = -self.m_nodes[:, None] * g
        return self._generalised(kin, F, np.zeros_like(F))

    def gravity_energy(self, q: np.ndarray) -> np.ndarray:
        """``-sum m_j g . p_j``, J."""
        p = self.positions(q)[..., 1:, :]
        return -(self.m_nodes * _dot(p, self.gvec)).sum(-1)

    def tensions(self, ctrl: Control, ell: np.ndarray, H: np.ndarray) -> np.ndarray:
        """Tendon tensions (..., nt) for the control ``ctrl`` at paths ``ell`` and bowing ``H``.

        Tension-controlled tendons carry their prescribed tension. The others solve the small
        complementarity problem ``lam = argmax_{lam >= 0} lam . e - lam^T C lam / 2 - lam^T H_DT lam_T``,
        ``C = diag(kinv) + H_DD``, ``e = e0 + ell`` (a taut tendon's net stretch equals its tension over its
        stiffness; a slack one carries nothing and its net stretch is <= 0); with ``ctrl.motor`` each
        rotor's lag takes ``R lag(lam)`` off the stretch (Newton, from the linearised lag). The active set is
        found from the real parts, so complex steps pass through.
        """
        lamT = np.where(ctrl.tension_controlled, np.nan_to_num(ctrl.lam), 0.0)
        D = ~ctrl.tension_controlled
        e = ctrl.e0 + ell
        rhs = e - np.einsum("...ij,j->...i", H, lamT)
        C0 = H + np.diag(np.where(D, ctrl.kinv, 0.0))
        if ctrl.motor is not None:  # first pass with the microstep spring at zero lag
            R, Th, Nr, sin_law = ctrl.motor
            C = C0 + np.diag(np.where(D, R * R / (Th * Nr), 0.0))
        else:
            C = C0
        mask = D & (np.real(rhs) > 0)
        mask = np.broadcast_to(mask, rhs.shape).copy()
        eye = np.eye(self.nt)
        lam = np.zeros_like(rhs)
        for _ in range(4 * self.nt + 2):
            mm = mask[..., :, None] & mask[..., None, :]
            Cm = np.where(mm, C, 0.0) + eye * (~mask)[..., None, :]
            lam = np.linalg.solve(Cm, np.where(mask, rhs, 0.0)[..., None])[..., 0]
            net = rhs - np.einsum("...ij,...j->...i", np.where(D[None, :], H, 0.0), lam)  # for slack ones
            drop = mask & (np.real(lam) < 0)
            add = D & ~mask & (np.real(net) > 0)
            if not (drop.any() or add.any()):
                break
            mask = (mask & ~drop) | (add & ~drop.any(-1, keepdims=True))
        if ctrl.motor is not None:  # Newton on the rotors' nonlinear lag, same active set
            mm = mask[..., :, None] & mask[..., None, :]
            xc = 0.99  # beyond, the sine law is continued by its tangent (a trial state; never an answer)
            for _ in range(8):
                x = R * lam / Th
                if sin_law:
                    big = np.abs(np.real(x)) > xc
                    xs = np.where(big, 0.0, x)
                    sgn = np.sign(np.real(x))
                    lag = np.where(big, sgn * np.arcsin(xc) + (x - sgn * xc) / np.sqrt(1.0 - xc * xc),
                                   np.arcsin(xs)) / Nr  # fmt: skip
                    dlag = R / (Th * Nr * np.sqrt(1.0 - np.where(big, xc * xc, xs * xs)))
                else:
                    lag, dlag = x / Nr, R / (Th * Nr) + 0.0 * x
                F = np.einsum("...ij,...j->...i", C0, lam) + R * lag - rhs
                J = np.where(mm, C0 + (R * dlag)[..., :, None] * eye, 0.0) + eye * (~mask)[..., None, :]
                lam = lam - np.linalg.solve(J, np.where(mask, F, 0.0)[..., None])[..., 0]
        return np.where(ctrl.tension_controlled, lamT, np.where(mask, lam, 0.0))

    def force_grad(self, q: np.ndarray, forces: dict[int, np.ndarray], kin: dict | None = None) -> np.ndarray:
        """Gradient of ``-sum F_k . p_k``: constant forces ``{node k (1..N): F_k (N, clamp frame)}``."""
        kin = self.kinematics(q) if kin is None else kin
        F = np.zeros(kin["p"].shape, dtype=kin["p"].dtype)
        for node, force in forces.items():
            if not 1 <= node <= self.N:
                raise ValueError(f"a force's node must be 1..{self.N}, got {node!r}")
            F[..., node, :] -= np.asarray(force, dtype=float)
        return self._generalised(kin, F, np.zeros_like(F))

    def potential_grad(
        self, q: np.ndarray, ctrl: Control, g: np.ndarray | None = None, forces: dict | None = None
    ) -> tuple[np.ndarray, ...]:
        """Gradient of the potential and the tensions, for the control ``ctrl``.

        ``V = elastic + gravity + Phi``, with the tendons' part ``Phi`` having the gradient
        ``sum lam_i d ell_i/dq - (1/2) d(lam^T H lam)/dq`` at the tensions ``lam`` (envelope theorem);
        ``forces`` adds constant point forces on nodes (:meth:`force_grad`).

        Returns
        -------
        (grad, lam, ell)
        """
        q = np.asarray(q)
        kin = self.kinematics(q)
        ell, dl = self.length_grad(q, kin)
        H = self.bow_matrix(q, kin)
        lam = self.tensions(ctrl, ell, H)
        grad = (self.elastic_grad(q) + self.gravity_grad(q, kin, g) + np.einsum("...i,...ik->...k", lam, dl)
                - 0.5 * self.bow_grad(q, lam, kin))  # fmt: skip
        if forces:
            grad = grad + self.force_grad(q, forces, kin)
        return grad, lam, ell

    def hessian(
        self, q: np.ndarray, ctrl: Control, g: np.ndarray | None = None, forces: dict | None = None
    ) -> np.ndarray:
        """Exact Hessian of the potential (complex step on the gradient, one batched call), symmetrised."""
        n = q.size
        h = 1e-30
        Qb = q[None, :] + 1j * h * np.eye(n)
        grad, _, _ = self.potential_grad(Qb, ctrl, g, forces)
        Hs = grad.imag / h
        return 0.5 * (Hs + Hs.T)

    # --- inertia and damping ----------------------------------------------------------------------------
    def node_jacobians(self, q: np.ndarray, kin: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Velocity and angular-velocity Jacobians of nodes 1..N, (N, 3, 3N) each (world)."""
        kin = self.kinematics(np.asarray(q)) if kin is None else kin
        N = self.N
        dt = np.result_type(kin["Jv"], float)
        Jv = np.zeros((N, 3, self.nq), dtype=dt)
        Jw = np.zeros((N, 3, self.nq), dtype=dt)
        p = kin["p"]
        for e in range(N):  # element e+1 moves nodes e+1..N
            cols = slice(3 * e, 3 * e + 3)
            Jw[e:, :, cols] = kin["Jw"][e]
            r = p[e + 1 :] - p[e + 1]  # (N-e, 3)
            Jv[e:, :, cols] = kin["Jv"][e] - skew(r) @ kin["Jw"][e]
        return Jv, Jw

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """``M(q) = sum_j m_j Jv_j^T Jv_j + Jw_j^T J_j Jw_j`` (the discs' inertia turned into the world)."""
        q = np.asarray(q)
        kin = self.kinematics(q)
        Jv, Jw = self.node_jacobians(q, kin)
        t = kin["R"][1:, :, 2]  # node tangents
        Jrot = self.Jd_nodes[:, None, None] * np.eye(3) + (self.Jp_nodes - self.Jd_nodes)[:, None, None] * (
            t[:, :, None] * t[:, None, :]
        )
        M = np.einsum("j,jai,jak->ik", self.m_nodes, Jv, Jv) + np.einsum("jai,jab,jbk->ik", Jw, Jrot, Jw)
        return 0.5 * (M + M.T)

    def chord_damping(self) -> np.ndarray:
        """The wire's material damping: dashpots on the disc chords' relative rotation (constant, 3N x 3N).

        ``d_0 = (1/2) sum_{I_1} phi'``, ``d_k = (1/2) sum_{I_k + I_{k+1}} phi'`` (``I_k``: the elements of
        disc interval k), each component with ``beta_chord EI / l_d`` (bending) or ``beta_chord GJ / l_d``
        (twist):
        the planar rig's chord dashpots, in space.
        """
        p = self.rig.arm
        nd = p.n_discs
        m = p.elements_per_disc
        Dc = np.zeros((nd, self.N))
        for k in range(nd):
            lo = max(0, (k - 1) * m)
            Dc[k, lo : (k + 1) * m] = 0.5
        cb = p.beta_chord * p.EI / p.disc_interval
        ct = p.beta_chord * self.rig.GJ / p.disc_interval
        return np.kron(Dc.T @ Dc, np.diag([cb, cb, ct]))

    def damping_matrix(self, M: np.ndarray, floor: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """Linear damping: ``alpha M`` (air drag on every mass and disc) + chord dashpots + the floor."""
        C = self.rig.arm.alpha * M + self.chord_damping()
        if floor is not None and floor[1].size:
            W, cw = floor
            C = C + (W.T * cw) @ W
        return C
