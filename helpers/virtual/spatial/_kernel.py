"""Compiled (numba) right-hand side and fixed-step integrator of the spatial twin.

No ``fastmath``: plain IEEE arithmetic, the same bits on every x86-64 CPU (``docs/reproducibility.md``).

The equations are :mod:`helpers.virtual.spatial.chain`'s, written again for speed (the tests compare the
two). The arm is a chain of ``N`` constant-strain elements; element ``e``'s rotation vector
``phi_e = (a, b, c)`` turns node ``e``'s frame against node ``e-1``'s (``E = exp([phi])``) and places node
``e`` at the chord ``l J_l(phi) e3``. Body ``e`` is node ``e``: a point mass and, in its frame, the rotary
inertia ``diag(J_d, J_d, J_p)``. Joint ``e`` is a three-degree-of-freedom curved joint. The accelerations
come from the articulated-body algorithm in ground coordinates (spatial vectors ``[omega; v_O]`` about the
clamp's origin, so no transform between bodies): motion subspace ``S_e = [R_{e-1} J_l; R_{e-1} dchi - (R_{e-1}
J_l) x p_e]``, bias ``c_e = dS_e/dt phi'_e`` (the element's second derivatives along ``phi'``), gravity as the
base's acceleration ``-g``.

Loads: bending and twisting springs ``EI/l``, ``GJ/l``; drag ``-alpha m v`` and ``-alpha J omega``; chord
dashpots (the planar rig's, on every component); the constant high-mode floor ``-C_f phi'``;
the tendons, straight from eyelet to eyelet (force ``T (u_{k+1} - u_k)`` on eyelet ``k``, its moment about
the origin); the tendon-coupled bowing (generalised forces ``(1/2) d(lam^T H lam)/dq`` at the tensions; with
one element per run ``H = (l^3/EI) sum_e P(D_e)`` on every entry, :mod:`helpers.virtual.spatial.chain` says
why).

Each tendon has the planar rig's actuator: rotor + spool ``J psi'' = T_m(psi_cmd - psi) - c_r psi' - R lam_1``
(``psi_cmd`` jumps by one step angle at each of *its* steps), the load-cell carriage ``m_c x'' = lam_1 -
lam_2 - c_c x'``, ``lam_1 = k1 max(0, R psi - x - s1)``, and the arm-side tensions from the small
complementarity problem ``(diag(1/k2) + H)_AA lam_A = e2_A`` (``e2 = x + ell(q) - ell_ref``, active set ``A``
the taut tendons, whose net stretch ``g_i = e2_i - (H lam)_i`` is positive). Its amplifier is a first-order
low-pass integrated exactly for a tension linear over each step.

State ``y = [phi (3N), phi' (3N), psi (nt), psi' (nt), x (nt), x' (nt)]``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# scalar parameters (``geo``)
(G_L, G_KB, G_KT, G_ALPHA, G_CB, G_CT, G_BOW, G_GX, G_GY, G_GZ, G_NR, G_TLAW) = range(12)
N_GEO = 12
# per-tendon parameters (``tp`` columns)
(T_R, T_JR, T_TH, T_CR, T_K1, T_K2, T_MC, T_CC, T_S1, T_ELL, T_RX, T_RY, T_RZ) = range(13)
N_TP = 13
# per-body workspace columns
(W_R, W_P, W_S, W_C, W_V, W_IA, W_PA, W_U, W_DI, W_UU, W_TAU, W_F, W_VN, W_BOW, W_CH, W_QDD) = (
    0, 9, 12, 30, 36, 42, 78, 84, 102, 111, 114, 117, 123, 126, 131, 135)  # fmt: skip
N_WB = 140
# per-tendon, per-eyelet workspace: E (3), off = R rho (3), u (3) of the run ending here, L, spare
N_WT = 12

_NS = 10  # series terms in x = |phi|^2 (x < 1: truncation below 2e-19)
_FA = np.array([(-1.0) ** k / math.factorial(2 * k + 1) for k in range(_NS + 2)])
_FB = np.array([(-1.0) ** k / math.factorial(2 * k + 2) for k in range(_NS + 2)])
_FC = np.array([(-1.0) ** k / math.factorial(2 * k + 3) for k in range(_NS + 2)])
# bowing shape factors P, Q in x = D^2 (the planar rig's series, |D| < 1.5)
_NB = 12
_S1C = np.array([(-1.0) ** j / math.factorial(2 * j + 1) for j in range(_NB + 2)])
_S2C = np.array([2.0 * (-1.0) ** j / math.factorial(2 * j + 2) for j in range(_NB + 2)])
_BP = 0.5 * (_S1C[1:] - 2.0 * _S2C[1:])


# scratch (``sp``) offsets: bowing matrix, tension system, its right-hand side and active set, Cholesky, the
# inward pass's U D^-1 and articulated inertia, the small solver's indices and vector
(S_H, S_C, S_E2, S_MASK, S_CHOL, S_UD, S_IA, S_IDX, S_Z, S_SIG) = (0, 16, 32, 36, 40, 56, 74, 110, 114, 120)
N_SP = 136  # then 3 N floats: the joint torques of the constant damping


def workspaces(n: int, nt: int, n_eye: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Work arrays of :func:`rhs`: per body, per tendon and eyelet, and a small scratch."""
    return np.zeros((n, N_WB)), np.zeros((nt, n_eye + 1, N_WT)), np.zeros(N_SP + 3 * n)


@njit(cache=True, error_model="numpy", nogil=True)
def _series(c, x, n):
    """``sum_k c_k x^k`` (k < n), its first and second x-derivatives."""
    f = 0.0
    d1 = 0.0
    d2 = 0.0
    for k in range(n - 1, -1, -1):
        d2 = d2 * x + 2.0 * d1
        d1 = d1 * x + f
        f = f * x + c[k]
    return f, d1, d2


@njit(cache=True, error_model="numpy", nogil=True)
def so3(x):
    """The SO(3) functions of ``x = t^2`` and derivatives.

    ``A, B, C`` = ``sin t/t``, ``(1-cos t)/t^2``, ``(t-sin t)/t^3``, then ``A_x`` (unused: 0 below
    ``x = 1``), ``B_x, C_x, B_xx, C_xx``.
    """
    if x < 1.0:
        A = 0.0
        for k in range(_NS - 1, -1, -1):
            A = A * x + _FA[k]
        B, Bx, Bxx = _series(_FB, x, _NS)
        C, Cx, Cxx = _series(_FC, x, _NS)
        return A, B, C, 0.0, Bx, Cx, Bxx, Cxx
    t = math.sqrt(x)
    s = math.sin(t)
    co = math.cos(t)
    A = s / t
    B = (1.0 - co) / x
    C = (t - s) / (x * t)
    Ax = (co - A) / (2.0 * x)
    Bx = (A - 2.0 * B) / (2.0 * x)
    Cx = (B - 3.0 * C) / (2.0 * x)
    return A, B, C, Ax, Bx, Cx, (Ax - 4.0 * Bx) / (2.0 * x), (Bx - 5.0 * Cx) / (2.0 * x)


@njit(cache=True, error_model="numpy", nogil=True)
def bow_p(x):
    """The bowing factor ``P`` of an element bent by ``D`` (``x = D^2``) and its x-derivative."""
    if x < 2.25:
        P, Px, _p = _series(_BP, x, _NB)
        return P, Px
    D = math.sqrt(x)
    iD = 1.0 / D
    sD = math.sin(D)
    cD = math.cos(D)
    S1 = sD * iD
    S2 = 2.0 * (1.0 - cD) * iD * iD
    dS1 = (cD - S1) * iD
    dS2 = 2.0 * sD * iD * iD - 2.0 * S2 * iD
    P = 0.5 * (1.0 + S1 - 2.0 * S2) * iD * iD
    dP = 0.5 * (dS1 - 2.0 * dS2) * iD * iD - 2.0 * P * iD
    return P, 0.5 * dP * iD


@njit(cache=True, error_model="numpy", nogil=True)
def _solve_small(sp, n, out):
    """Solve ``C[A, A] out[A] = e2[A]`` (symmetric positive definite, n <= 4); 0 outside ``A``.

    ``C``, ``e2`` and the active set ``A`` are in the scratch ``sp``.
    """
    m = 0
    for i in range(n):
        out[i] = 0.0
        if sp[S_MASK + i] != 0.0:
            sp[S_IDX + m] = i
            m += 1
    if m == 0:
        return
    w = S_CHOL
    for r in range(m):
        ir = int(sp[S_IDX + r])
        for c in range(r + 1):
            s = sp[S_C + 4 * ir + int(sp[S_IDX + c])]
            for k in range(c):
                s -= sp[w + 4 * r + k] * sp[w + 4 * c + k]
            if r == c:
                sp[w + 4 * r + r] = math.sqrt(s)
            else:
                sp[w + 4 * r + c] = s / sp[w + 4 * c + c]
    for r in range(m):
        s = sp[S_E2 + int(sp[S_IDX + r])]
        for k in range(r):
            s -= sp[w + 4 * r + k] * sp[S_Z + k]
        sp[S_Z + r] = s / sp[w + 4 * r + r]
    for r in range(m - 1, -1, -1):
        s = sp[S_Z + r]
        for k in range(r + 1, m):
            s -= sp[w + 4 * k + r] * sp[S_Z + k]
        sp[S_Z + r] = s / sp[w + 4 * r + r]
    for r in range(m):
        out[int(sp[S_IDX + r])] = sp[S_Z + r]


@njit(cache=True, error_model="numpy", nogil=True)
def rhs(y, dy, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, st):  # noqa: C901 - one pass per stage, kept together
    """Write ``dy = f(y)`` and the tendons' state into ``st`` (4 x nt: e1, net arm-side stretch, lam1, lam2).

    Parameters
    ----------
    y, dy : float64[6 N + 4 nt]
        State and its derivative (written).
    drive : float64[nt]
        Commanded rotor angles, rad.
    geo : float64[N_GEO]
        Scalars (``G_*``).
    mb, Jd, Jp : float64[N]
        Node masses, diametral and polar rotary inertias.
    tp : float64[nt, N_TP]
        Per-tendon parameters (``T_*``).
    W : float64[3N, 3N] or float64[0, 3N]
        The constant damping's matrix ``C_f`` (joint torques ``-C_f phi'``), or none.
    cw : float64[:]
        Unused (kept for the signature).
    wb, wt, sp : float64 arrays
        Work arrays (:func:`workspaces`); ``wb[:, W_P:W_P+3]`` holds the node positions afterwards.
    st : float64[4, nt]
        Written: spool-side stretch, net arm-side stretch, spool-side and arm-side tensions.
    """
    n = mb.shape[0]
    nq = 3 * n
    nt = tp.shape[0]
    l_ = geo[G_L]
    alpha = geo[G_ALPHA]
    bow = geo[G_BOW]
    # ---- pass 1: kinematics, velocities, bias, body inertias (ground coordinates) ----
    r00 = 1.0
    r01 = 0.0
    r02 = 0.0
    r10 = 0.0
    r11 = 1.0
    r12 = 0.0
    r20 = 0.0
    r21 = 0.0
    r22 = 1.0
    px = 0.0
    py = 0.0
    pz = 0.0
    wx = 0.0  # angular velocity of the previous frame
    wy = 0.0
    wz = 0.0
    vx = 0.0  # spatial velocity's linear part (velocity of the point at the origin)
    vy = 0.0
    vz = 0.0
    for e in range(n):
        a = y[3 * e]
        b = y[3 * e + 1]
        c = y[3 * e + 2]
        ad = y[nq + 3 * e]
        bd = y[nq + 3 * e + 1]
        cd = y[nq + 3 * e + 2]
        x = a * a + b * b + c * c
        A, B, C, _ax, Bx, Cx, Bxx, Cxx = so3(x)
        # E = (1 - B x) I + A [phi] + B phi phi^T ;  Jl = (1 - C x) I + B [phi] + C phi phi^T
        d0 = 1.0 - B * x
        e00 = d0 + B * a * a
        e01 = -A * c + B * a * b
        e02 = A * b + B * a * c
        e10 = A * c + B * b * a
        e11 = d0 + B * b * b
        e12 = -A * a + B * b * c
        e20 = -A * b + B * c * a
        e21 = A * a + B * c * b
        e22 = d0 + B * c * c
        d1 = 1.0 - C * x
        j00 = d1 + C * a * a
        j01 = -B * c + C * a * b
        j02 = B * b + C * a * c
        j10 = B * c + C * b * a
        j11 = d1 + C * b * b
        j12 = -B * a + C * b * c
        j20 = -B * b + C * c * a
        j21 = B * a + C * c * b
        j22 = d1 + C * c * c
        # chord chi / l = e3 + B w + C z, w = (b, -a, 0), z = (c a, c b, c^2 - x)
        chx = l_ * (B * b + C * c * a)
        chy = l_ * (-B * a + C * c * b)
        chz = l_ * (1.0 + C * (c * c - x))
        # d chi / d phi_k = l (2 B_x phi_k w + B dw_k + 2 C_x phi_k z + C dz_k)
        zx = c * a
        zy = c * b
        zz = c * c - x
        # k = 0 (a): dw = (0, -1, 0), dz = (c, 0, -2a)
        q00 = l_ * (2.0 * Bx * a * b + 2.0 * Cx * a * zx + C * c)
        q10 = l_ * (2.0 * Bx * a * (-a) - B + 2.0 * Cx * a * zy)
        q20 = l_ * (2.0 * Cx * a * zz - 2.0 * C * a)
        # k = 1 (b): dw = (1, 0, 0), dz = (0, c, -2b)
        q01 = l_ * (2.0 * Bx * b * b + B + 2.0 * Cx * b * zx)
        q11 = l_ * (2.0 * Bx * b * (-a) + 2.0 * Cx * b * zy + C * c)
        q21 = l_ * (2.0 * Cx * b * zz - 2.0 * C * b)
        # k = 2 (c): dw = 0, dz = (a, b, 2c - 2c) = (a + 0, b, 0) + c e3 - 2 c e3
        q02 = l_ * (2.0 * Bx * c * b + 2.0 * Cx * c * zx + C * a)
        q12 = l_ * (2.0 * Bx * c * (-a) + 2.0 * Cx * c * zy + C * b)
        q22 = l_ * (2.0 * Cx * c * zz + C * (c - 2.0 * c + c))
        # second derivative of chi along phi' and d/dt(J_l) phi' (phi' fixed)
        s_ = a * ad + b * bd + c * cd
        xd = 2.0 * s_
        xdd = 2.0 * (ad * ad + bd * bd + cd * cd)
        Bd = Bx * xd
        Cd = Cx * xd
        Bdd = Bxx * xd * xd + Bx * xdd
        Cdd = Cxx * xd * xd + Cx * xdd
        wX = b
        wY = -a
        wdX = bd
        wdY = -ad
        zdx = cd * a + c * ad
        zdy = cd * b + c * bd
        zdz = 2.0 * c * cd - xd
        zddx = 2.0 * cd * ad
        zddy = 2.0 * cd * bd
        zddz = 2.0 * cd * cd - xdd
        c2x = l_ * (Bdd * wX + 2.0 * Bd * wdX + Cdd * zx + 2.0 * Cd * zdx + C * zddx)
        c2y = l_ * (Bdd * wY + 2.0 * Bd * wdY + Cdd * zy + 2.0 * Cd * zdy + C * zddy)
        c2z = l_ * (Cdd * zz + 2.0 * Cd * zdz + C * zddz)
        # J_l' phi' = B' (phi x phi') + C' (s phi - x phi') + C (|phi'|^2 phi - s phi')
        pfx = b * cd - c * bd
        pfy = c * ad - a * cd
        pfz = a * bd - b * ad
        v2 = 0.5 * xdd
        jdx = Bd * pfx + Cd * (s_ * a - x * ad) + C * (v2 * a - s_ * ad)
        jdy = Bd * pfy + Cd * (s_ * b - x * bd) + C * (v2 * b - s_ * bd)
        jdz = Bd * pfz + Cd * (s_ * c - x * cd) + C * (v2 * c - s_ * cd)
        # world quantities: Jw = Rp Jl, Jv = Rp dchi, node position, new frame
        o = wb[e]
        Jw00 = r00 * j00 + r01 * j10 + r02 * j20
        Jw01 = r00 * j01 + r01 * j11 + r02 * j21
        Jw02 = r00 * j02 + r01 * j12 + r02 * j22
        Jw10 = r10 * j00 + r11 * j10 + r12 * j20
        Jw11 = r10 * j01 + r11 * j11 + r12 * j21
        Jw12 = r10 * j02 + r11 * j12 + r12 * j22
        Jw20 = r20 * j00 + r21 * j10 + r22 * j20
        Jw21 = r20 * j01 + r21 * j11 + r22 * j21
        Jw22 = r20 * j02 + r21 * j12 + r22 * j22
        Jv00 = r00 * q00 + r01 * q10 + r02 * q20
        Jv01 = r00 * q01 + r01 * q11 + r02 * q21
        Jv02 = r00 * q02 + r01 * q12 + r02 * q22
        Jv10 = r10 * q00 + r11 * q10 + r12 * q20
        Jv11 = r10 * q01 + r11 * q11 + r12 * q21
        Jv12 = r10 * q02 + r11 * q12 + r12 * q22
        Jv20 = r20 * q00 + r21 * q10 + r22 * q20
        Jv21 = r20 * q01 + r21 * q11 + r22 * q21
        Jv22 = r20 * q02 + r21 * q12 + r22 * q22
        npx = px + r00 * chx + r01 * chy + r02 * chz
        npy = py + r10 * chx + r11 * chy + r12 * chz
        npz = pz + r20 * chx + r21 * chy + r22 * chz
        # R_e = Rp E (and keep Rp for the bias)
        n00 = r00 * e00 + r01 * e10 + r02 * e20
        n01 = r00 * e01 + r01 * e11 + r02 * e21
        n02 = r00 * e02 + r01 * e12 + r02 * e22
        n10 = r10 * e00 + r11 * e10 + r12 * e20
        n11 = r10 * e01 + r11 * e11 + r12 * e21
        n12 = r10 * e02 + r11 * e12 + r12 * e22
        n20 = r20 * e00 + r21 * e10 + r22 * e20
        n21 = r20 * e01 + r21 * e11 + r22 * e21
        n22 = r20 * e02 + r21 * e12 + r22 * e22
        # joint velocity contributions (world): Omega = Jw phi', w1 = Jv phi'
        Ox = Jw00 * ad + Jw01 * bd + Jw02 * cd
        Oy = Jw10 * ad + Jw11 * bd + Jw12 * cd
        Oz = Jw20 * ad + Jw21 * bd + Jw22 * cd
        w1x = Jv00 * ad + Jv01 * bd + Jv02 * cd
        w1y = Jv10 * ad + Jv11 * bd + Jv12 * cd
        w1z = Jv20 * ad + Jv21 * bd + Jv22 * cd
        # motion subspace S (6x3), column k: [Jw_k ; Jv_k - Jw_k x p]
        o[W_S + 0] = Jw00
        o[W_S + 1] = Jw01
        o[W_S + 2] = Jw02
        o[W_S + 3] = Jw10
        o[W_S + 4] = Jw11
        o[W_S + 5] = Jw12
        o[W_S + 6] = Jw20
        o[W_S + 7] = Jw21
        o[W_S + 8] = Jw22
        o[W_S + 9] = Jv00 - (Jw10 * npz - Jw20 * npy)
        o[W_S + 10] = Jv01 - (Jw11 * npz - Jw21 * npy)
        o[W_S + 11] = Jv02 - (Jw12 * npz - Jw22 * npy)
        o[W_S + 12] = Jv10 - (Jw20 * npx - Jw00 * npz)
        o[W_S + 13] = Jv11 - (Jw21 * npx - Jw01 * npz)
        o[W_S + 14] = Jv12 - (Jw22 * npx - Jw02 * npz)
        o[W_S + 15] = Jv20 - (Jw00 * npy - Jw10 * npx)
        o[W_S + 16] = Jv21 - (Jw01 * npy - Jw11 * npx)
        o[W_S + 17] = Jv22 - (Jw02 * npy - Jw12 * npx)
        # spatial velocity of body e, its angular velocity and its node's velocity
        nwx = wx + Ox
        nwy = wy + Oy
        nwz = wz + Oz
        vOx = w1x - (Oy * npz - Oz * npy)
        vOy = w1y - (Oz * npx - Ox * npz)
        vOz = w1z - (Ox * npy - Oy * npx)
        vx += vOx
        vy += vOy
        vz += vOz
        vnx = vx + (nwy * npz - nwz * npy)
        vny = vy + (nwz * npx - nwx * npz)
        vnz = vz + (nwx * npy - nwy * npx)
        # bias c = [wp x Omega + Rp Jl'phi' ; wp x w1 + Rp chi'' - dOmega x p - Omega x pdot]
        dOx = (wy * Oz - wz * Oy) + r00 * jdx + r01 * jdy + r02 * jdz
        dOy = (wz * Ox - wx * Oz) + r10 * jdx + r11 * jdy + r12 * jdz
        dOz = (wx * Oy - wy * Ox) + r20 * jdx + r21 * jdy + r22 * jdz
        o[W_C + 0] = dOx
        o[W_C + 1] = dOy
        o[W_C + 2] = dOz
        o[W_C + 3] = ((wy * w1z - wz * w1y) + r00 * c2x + r01 * c2y + r02 * c2z - (dOy * npz - dOz * npy)
                      - (Oy * vnz - Oz * vny))  # fmt: skip
        o[W_C + 4] = ((wz * w1x - wx * w1z) + r10 * c2x + r11 * c2y + r12 * c2z - (dOz * npx - dOx * npz)
                      - (Oz * vnx - Ox * vnz))  # fmt: skip
        o[W_C + 5] = ((wx * w1y - wy * w1x) + r20 * c2x + r21 * c2y + r22 * c2z - (dOx * npy - dOy * npx)
                      - (Ox * vny - Oy * vnx))  # fmt: skip
        o[W_V + 0] = nwx
        o[W_V + 1] = nwy
        o[W_V + 2] = nwz
        o[W_V + 3] = vx
        o[W_V + 4] = vy
        o[W_V + 5] = vz
        o[W_VN + 0] = vnx
        o[W_VN + 1] = vny
        o[W_VN + 2] = vnz
        o[W_R + 0] = n00
        o[W_R + 1] = n01
        o[W_R + 2] = n02
        o[W_R + 3] = n10
        o[W_R + 4] = n11
        o[W_R + 5] = n12
        o[W_R + 6] = n20
        o[W_R + 7] = n21
        o[W_R + 8] = n22
        o[W_P + 0] = npx
        o[W_P + 1] = npy
        o[W_P + 2] = npz
        # chord of the element (for the bowing) and its bending
        chwx = npx - px
        chwy = npy - py
        chwz = npz - pz
        Lc = math.sqrt(chwx * chwx + chwy * chwy + chwz * chwz)
        o[W_CH + 0] = chwx / Lc
        o[W_CH + 1] = chwy / Lc
        o[W_CH + 2] = chwz / Lc
        o[W_CH + 3] = Lc
        if bow != 0.0:
            P, Px = bow_p(a * a + b * b)
            o[W_BOW + 0] = P
            o[W_BOW + 2] = Px
        # body inertia in ground coordinates: J_w = Jd I + (Jp - Jd) t t^T, t = R e3; point mass at p
        m = mb[e]
        tx = n02
        ty = n12
        tz = n22
        dj = Jp[e] - Jd[e]
        p2 = npx * npx + npy * npy + npz * npz
        Ib = o[W_IA : W_IA + 36]
        Ib[0] = Jd[e] + dj * tx * tx + m * (p2 - npx * npx)
        Ib[1] = dj * tx * ty - m * npx * npy
        Ib[2] = dj * tx * tz - m * npx * npz
        Ib[7] = Jd[e] + dj * ty * ty + m * (p2 - npy * npy)
        Ib[8] = dj * ty * tz - m * npy * npz
        Ib[14] = Jd[e] + dj * tz * tz + m * (p2 - npz * npz)
        Ib[6] = Ib[1]
        Ib[12] = Ib[2]
        Ib[13] = Ib[8]
        # m [p]x in the top right, its transpose bottom left, m I bottom right
        Ib[3] = 0.0
        Ib[4] = -m * npz
        Ib[5] = m * npy
        Ib[9] = m * npz
        Ib[10] = 0.0
        Ib[11] = -m * npx
        Ib[15] = -m * npy
        Ib[16] = m * npx
        Ib[17] = 0.0
        for i in range(3):
            for j in range(3):
                Ib[6 * (3 + i) + j] = Ib[6 * j + 3 + i]
        Ib[21] = m
        Ib[22] = 0.0
        Ib[23] = 0.0
        Ib[27] = 0.0
        Ib[28] = m
        Ib[29] = 0.0
        Ib[33] = 0.0
        Ib[34] = 0.0
        Ib[35] = m
        # external wrench so far: drag on the mass and the disc; velocity-product bias p = v x* I v - f_ext
        Jwx = Jd[e] * nwx + dj * tx * (tx * nwx + ty * nwy + tz * nwz)
        Jwy = Jd[e] * nwy + dj * ty * (tx * nwx + ty * nwy + tz * nwz)
        Jwz = Jd[e] * nwz + dj * tz * (tx * nwx + ty * nwy + tz * nwz)
        Fx = -alpha * m * vnx
        Fy = -alpha * m * vny
        Fz = -alpha * m * vnz
        o[W_F + 0] = (npy * Fz - npz * Fy) - alpha * Jwx
        o[W_F + 1] = (npz * Fx - npx * Fz) - alpha * Jwy
        o[W_F + 2] = (npx * Fy - npy * Fx) - alpha * Jwz
        o[W_F + 3] = Fx
        o[W_F + 4] = Fy
        o[W_F + 5] = Fz
        # h = I v (angular part about the origin: J_w w + m p x v_node; linear m v_node)
        hlx = m * vnx
        hly = m * vny
        hlz = m * vnz
        hax = Jwx + (npy * hlz - npz * hly)
        hay = Jwy + (npz * hlx - npx * hlz)
        haz = Jwz + (npx * hly - npy * hlx)
        # v x* h = [w x h_a + v_O x h_l ; w x h_l]
        o[W_PA + 0] = (nwy * haz - nwz * hay) + (vy * hlz - vz * hly)
        o[W_PA + 1] = (nwz * hax - nwx * haz) + (vz * hlx - vx * hlz)
        o[W_PA + 2] = (nwx * hay - nwy * hax) + (vx * hly - vy * hlx)
        o[W_PA + 3] = nwy * hlz - nwz * hly
        o[W_PA + 4] = nwz * hlx - nwx * hlz
        o[W_PA + 5] = nwx * hly - nwy * hlx
        # joint torques: springs
        o[W_TAU + 0] = -geo[G_KB] * a
        o[W_TAU + 1] = -geo[G_KB] * b
        o[W_TAU + 2] = -geo[G_KT] * c
        # next
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = n00, n01, n02, n10, n11, n12, n20, n21, n22
        px = npx
        py = npy
        pz = npz
        wx = nwx
        wy = nwy
        wz = nwz
    # ---- tendons: eyelets, runs, paths ----
    ne = n + 1  # eyelets: the guide (clamp) and every node (one element per disc)
    lam = st[3]
    sc = wt  # alias
    for i in range(nt):
        rx = tp[i, T_RX]
        ry = tp[i, T_RY]
        rz = tp[i, T_RZ]
        sc[i, 0, 0] = rx
        sc[i, 0, 1] = ry
        sc[i, 0, 2] = rz
        sc[i, 0, 3] = rx
        sc[i, 0, 4] = ry
        sc[i, 0, 5] = rz
        ell = 0.0
        for k in range(1, ne):
            o = wb[k - 1]
            ox = o[W_R + 0] * rx + o[W_R + 1] * ry + o[W_R + 2] * rz
            oy = o[W_R + 3] * rx + o[W_R + 4] * ry + o[W_R + 5] * rz
            oz = o[W_R + 6] * rx + o[W_R + 7] * ry + o[W_R + 8] * rz
            Ex = o[W_P + 0] + ox
            Ey = o[W_P + 1] + oy
            Ez = o[W_P + 2] + oz
            dx = Ex - sc[i, k - 1, 0]
            dyy = Ey - sc[i, k - 1, 1]
            dz = Ez - sc[i, k - 1, 2]
            L = math.sqrt(dx * dx + dyy * dyy + dz * dz)
            ell += L
            sc[i, k, 0] = Ex
            sc[i, k, 1] = Ey
            sc[i, k, 2] = Ez
            sc[i, k, 3] = ox
            sc[i, k, 4] = oy
            sc[i, k, 5] = oz
            sc[i, k, 6] = dx / L
            sc[i, k, 7] = dyy / L
            sc[i, k, 8] = dz / L
            sc[i, k, 9] = L
        sc[i, 0, 9] = ell
    # ---- bowing compliance H = h sum_e P(D_e) 11^T (one element per run: no tilt term) ----
    hP = 0.0
    if bow != 0.0:
        for e in range(n):
            hP += wb[e, W_BOW + 0]
        hP *= bow
    for i in range(16):
        sp[S_H + i] = hP
    # ---- tensions ----
    m2 = 2 * nq
    for i in range(nt):
        e1 = tp[i, T_R] * y[m2 + i] - y[m2 + 2 * nt + i] - tp[i, T_S1]
        st[0, i] = e1
        st[2, i] = tp[i, T_K1] * e1 if e1 > 0.0 else 0.0
        e2 = y[m2 + 2 * nt + i] + sc[i, 0, 9] - tp[i, T_ELL]
        sp[S_E2 + i] = e2
        sp[S_MASK + i] = 1.0 if e2 > 0.0 else 0.0
        for j in range(nt):
            sp[S_C + 4 * i + j] = sp[S_H + 4 * i + j]
        sp[S_C + 5 * i] += 1.0 / tp[i, T_K2]
    for _it in range(4 * nt + 2):
        _solve_small(sp, nt, lam)
        changed = False
        for i in range(nt):
            if sp[S_MASK + i] != 0.0 and lam[i] < 0.0:
                sp[S_MASK + i] = 0.0
                changed = True
        if changed:
            continue
        for i in range(nt):
            if sp[S_MASK + i] == 0.0:
                g = sp[S_E2 + i]
                for j in range(nt):
                    g -= sp[S_H + 4 * i + j] * lam[j]
                if g > 0.0:
                    sp[S_MASK + i] = 1.0
                    changed = True
        if not changed:
            break
    for i in range(nt):
        g = sp[S_E2 + i]
        for j in range(nt):
            g -= sp[S_H + 4 * i + j] * lam[j]
        st[1, i] = g
    # ---- tendon forces on the eyelets: T (u_{k+1} - u_k), the knot T (-u_last) ----
    for i in range(nt):
        T = lam[i]
        if T == 0.0:
            continue
        for k in range(1, ne):
            Fx = -T * sc[i, k, 6]
            Fy = -T * sc[i, k, 7]
            Fz = -T * sc[i, k, 8]
            if k + 1 < ne:
                Fx += T * sc[i, k + 1, 6]
                Fy += T * sc[i, k + 1, 7]
                Fz += T * sc[i, k + 1, 8]
            o = wb[k - 1]
            Ex = sc[i, k, 0]
            Ey = sc[i, k, 1]
            Ez = sc[i, k, 2]
            o[W_F + 0] += Ey * Fz - Ez * Fy
            o[W_F + 1] += Ez * Fx - Ex * Fz
            o[W_F + 2] += Ex * Fy - Ey * Fx
            o[W_F + 3] += Fx
            o[W_F + 4] += Fy
            o[W_F + 5] += Fz
    # ---- bowing: generalised forces (1/2) d(lam^T H lam)/dq = (1/2) h P_x(D_e^2) S^2 2 (a_e, b_e) ----
    if bow != 0.0:
        S = 0.0
        for i in range(nt):
            S += lam[i]
        if S != 0.0:
            hs = bow * S * S
            for e in range(n):
                dxb = hs * wb[e, W_BOW + 2]
                wb[e, W_TAU + 0] += dxb * y[3 * e]
                wb[e, W_TAU + 1] += dxb * y[3 * e + 1]
    # ---- chord dashpots and the constant floor on phi' ----
    cb = geo[G_CB]
    ct = geo[G_CT]
    if cb != 0.0 or ct != 0.0:
        for e in range(n):
            # d_{e-1} = (phi'_{e-1} + phi'_e)/2 (d_0 = phi'_1/2), d_e = (phi'_e + phi'_{e+1})/2
            for k in range(3):
                cc_ = ct if k == 2 else cb
                cur = y[nq + 3 * e + k]
                prv = y[nq + 3 * (e - 1) + k] if e > 0 else 0.0
                tq = 0.5 * (prv + cur)
                if e + 1 < n:
                    tq += 0.5 * (cur + y[nq + 3 * (e + 1) + k])
                wb[e, W_TAU + k] -= 0.5 * cc_ * tq
    if W.shape[0] == nq:  # the constant damping as one matrix (Cf = W^T diag(cw) W): joint torques -Cf phi'
        for i in range(nq):
            acc = 0.0
            for j in range(nq):
                acc += W[i, j] * y[nq + j]
            sp[N_SP + i] = acc
        for e in range(n):
            wb[e, W_TAU + 0] -= sp[N_SP + 3 * e]
            wb[e, W_TAU + 1] -= sp[N_SP + 3 * e + 1]
            wb[e, W_TAU + 2] -= sp[N_SP + 3 * e + 2]
    for e in range(n):
        for k in range(6):
            wb[e, W_PA + k] -= wb[e, W_F + k]
    # ---- inward pass ----
    for e in range(n - 1, -1, -1):
        o = wb[e]
        Ib = o[W_IA : W_IA + 36]
        Sv = o[W_S : W_S + 18]
        U = o[W_U : W_U + 18]
        for i in range(6):
            for k in range(3):
                acc = 0.0
                for j in range(6):
                    acc += Ib[6 * i + j] * Sv[3 * j + k]
                U[3 * i + k] = acc
        # D = S^T U (3x3), its inverse
        D00 = 0.0
        D01 = 0.0
        D02 = 0.0
        D11 = 0.0
        D12 = 0.0
        D22 = 0.0
        for j in range(6):
            D00 += Sv[3 * j] * U[3 * j]
            D01 += Sv[3 * j] * U[3 * j + 1]
            D02 += Sv[3 * j] * U[3 * j + 2]
            D11 += Sv[3 * j + 1] * U[3 * j + 1]
            D12 += Sv[3 * j + 1] * U[3 * j + 2]
            D22 += Sv[3 * j + 2] * U[3 * j + 2]
        c00 = D11 * D22 - D12 * D12
        c01 = D02 * D12 - D01 * D22
        c02 = D01 * D12 - D02 * D11
        det = D00 * c00 + D01 * c01 + D02 * c02
        idet = 1.0 / det
        Di = o[W_DI : W_DI + 9]
        Di[0] = c00 * idet
        Di[1] = c01 * idet
        Di[2] = c02 * idet
        Di[3] = Di[1]
        Di[4] = (D00 * D22 - D02 * D02) * idet
        Di[5] = (D01 * D02 - D00 * D12) * idet
        Di[6] = Di[2]
        Di[7] = Di[5]
        Di[8] = (D00 * D11 - D01 * D01) * idet
        pA = o[W_PA : W_PA + 6]
        uu = o[W_UU : W_UU + 3]
        for k in range(3):
            acc = o[W_TAU + k]
            for j in range(6):
                acc -= Sv[3 * j + k] * pA[j]
            uu[k] = acc
        if e > 0:
            op = wb[e - 1]
            IP = op[W_IA : W_IA + 36]
            cv = o[W_C : W_C + 6]
            # UD = U D^-1 (6x3); Ia = I - UD U^T; pa = pA + Ia c + UD u
            UD = sp[S_UD : S_UD + 18]
            for i in range(6):
                for k in range(3):
                    UD[3 * i + k] = U[3 * i] * Di[k] + U[3 * i + 1] * Di[3 + k] + U[3 * i + 2] * Di[6 + k]
            Ia = sp[S_IA : S_IA + 36]
            for i in range(6):
                for j in range(i, 6):
                    v_ = Ib[6 * i + j] - (UD[3 * i] * U[3 * j] + UD[3 * i + 1] * U[3 * j + 1]
                                         + UD[3 * i + 2] * U[3 * j + 2])  # fmt: skip
                    Ia[6 * i + j] = v_
                    Ia[6 * j + i] = v_
            for i in range(36):
                IP[i] += Ia[i]
            for i in range(6):
                acc = pA[i] + UD[3 * i] * uu[0] + UD[3 * i + 1] * uu[1] + UD[3 * i + 2] * uu[2]
                for j in range(6):
                    acc += Ia[6 * i + j] * cv[j]
                op[W_PA + i] += acc
    # ---- outward pass: accelerations (base acceleration -g) ----
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    a3 = -geo[G_GX]
    a4 = -geo[G_GY]
    a5 = -geo[G_GZ]
    for e in range(n):
        o = wb[e]
        ap0 = a0 + o[W_C + 0]
        ap1 = a1 + o[W_C + 1]
        ap2 = a2 + o[W_C + 2]
        ap3 = a3 + o[W_C + 3]
        ap4 = a4 + o[W_C + 4]
        ap5 = a5 + o[W_C + 5]
        U = o[W_U : W_U + 18]
        Di = o[W_DI : W_DI + 9]
        t0 = o[W_UU + 0] - (U[0] * ap0 + U[3] * ap1 + U[6] * ap2 + U[9] * ap3 + U[12] * ap4 + U[15] * ap5)
        t1 = o[W_UU + 1] - (U[1] * ap0 + U[4] * ap1 + U[7] * ap2 + U[10] * ap3 + U[13] * ap4 + U[16] * ap5)
        t2 = o[W_UU + 2] - (U[2] * ap0 + U[5] * ap1 + U[8] * ap2 + U[11] * ap3 + U[14] * ap4 + U[17] * ap5)
        qa = Di[0] * t0 + Di[1] * t1 + Di[2] * t2
        qb = Di[3] * t0 + Di[4] * t1 + Di[5] * t2
        qc = Di[6] * t0 + Di[7] * t1 + Di[8] * t2
        Sv = o[W_S : W_S + 18]
        a0 = ap0 + Sv[0] * qa + Sv[1] * qb + Sv[2] * qc
        a1 = ap1 + Sv[3] * qa + Sv[4] * qb + Sv[5] * qc
        a2 = ap2 + Sv[6] * qa + Sv[7] * qb + Sv[8] * qc
        a3 = ap3 + Sv[9] * qa + Sv[10] * qb + Sv[11] * qc
        a4 = ap4 + Sv[12] * qa + Sv[13] * qb + Sv[14] * qc
        a5 = ap5 + Sv[15] * qa + Sv[16] * qb + Sv[17] * qc
        dy[3 * e] = y[nq + 3 * e]
        dy[3 * e + 1] = y[nq + 3 * e + 1]
        dy[3 * e + 2] = y[nq + 3 * e + 2]
        dy[nq + 3 * e] = qa
        dy[nq + 3 * e + 1] = qb
        dy[nq + 3 * e + 2] = qc
    # ---- actuators ----
    Nr = geo[G_NR]
    for i in range(nt):
        psi = y[m2 + i]
        psid = y[m2 + nt + i]
        xd = y[m2 + 3 * nt + i]
        delta = drive[i] - psi
        if geo[G_TLAW] == 0.0:
            tm = tp[i, T_TH] * Nr * delta
        else:
            tm = tp[i, T_TH] * math.sin(Nr * delta)
        dy[m2 + i] = psid
        dy[m2 + nt + i] = (tm - tp[i, T_CR] * psid - tp[i, T_R] * st[2, i]) / tp[i, T_JR]
        dy[m2 + 2 * nt + i] = xd
        dy[m2 + 3 * nt + i] = (st[2, i] - lam[i] - tp[i, T_CC] * xd) / tp[i, T_MC]


@njit(cache=True, error_model="numpy", nogil=True)
def _rk4(y, k1, h, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, st, k2, k3, k4, tmp, out):
    m = y.shape[0]
    hh = 0.5 * h
    for i in range(m):
        tmp[i] = y[i] + hh * k1[i]
    rhs(tmp, k2, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, st)
    for i in range(m):
        tmp[i] = y[i] + hh * k2[i]
    rhs(tmp, k3, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, st)
    for i in range(m):
        tmp[i] = y[i] + h * k3[i]
    rhs(tmp, k4, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, st)
    h6 = h / 6.0
    for i in range(m):
        out[i] = y[i] + h6 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


@njit(cache=True, error_model="numpy", nogil=True)
def _first_flip(sa, sb, nt):
    """Index (0..2nt-1) of the first transition function that changed sign between ``sa`` and ``sb``, or -1.

    Functions ``2 i``: tendon i's spool-side stretch; ``2 i + 1``: its net arm-side stretch.
    """
    for i in range(nt):
        if (sa[0, i] > 0.0) != (sb[0, i] > 0.0):
            return 2 * i
        if (sa[1, i] > 0.0) != (sb[1, i] > 0.0):
            return 2 * i + 1
    return -1


@njit(cache=True, error_model="numpy", nogil=True)
def _filter(filt, tau, h, x0, x1):
    """First-order low-pass ``tau y' = x - y`` over ``h`` for an input linear from ``x0`` to ``x1``."""
    if tau <= 0.0:
        filt[0] = x1
        return
    a = math.exp(-h / tau)
    filt[0] = a * (filt[0] - x0) + x1 - (x1 - x0) * (tau / h) * (1.0 - a)


@njit(cache=True, error_model="numpy", nogil=True)
def integrate(y, k1, st, dt, drive, h_max, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, bufs, sbuf, filt, tau,  # noqa: C901
              stats, health):  # fmt: skip
    """Integrate ``y`` over ``dt`` at constant ``drive``: equal RK4 steps ``<= h_max``, split at transitions.

    ``k1`` holds ``f(y)`` on entry and exit, ``st`` the tendons' state of ``y``. A step across which any
    tendon's spool-side or net arm-side stretch changes sign is split at the transition (Illinois method on
    the step size). ``filt[i]`` is tendon i's amplifier output (time constant ``tau``); ``stats`` counts RK4
    steps and transitions; ``health[i]`` is the largest rotor lag of tendon i (rad).
    """
    if dt <= 0.0:
        return
    nst = int(math.ceil(dt / h_max - 1e-9))
    h = dt / nst
    m = y.shape[0]
    n = mb.shape[0]
    nt = tp.shape[0]
    k2 = bufs[0]
    k3 = bufs[1]
    k4 = bufs[2]
    tmp = bufs[3]
    y1 = bufs[4]
    yt = bufs[5]
    k1n = bufs[6]
    s1 = sbuf[0]
    sc = sbuf[1]
    sk = sbuf[2]
    fv = np.empty(1)
    for _ in range(nst):
        _rk4(y, k1, h, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, sk, k2, k3, k4, tmp, y1)
        stats[0] += 1
        rhs(y1, k1n, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, s1)
        which = _first_flip(st, s1, nt)
        if which >= 0:
            stats[1] += 1
            row = which % 2
            ti = which // 2
            f_lo = st[row, ti]
            f_hi = s1[row, ti]
            lo = 0.0
            hi = h
            side = 0
            hc = h
            for _it in range(40):
                den = f_hi - f_lo
                hc = (lo * f_hi - hi * f_lo) / den if den != 0.0 else 0.5 * (lo + hi)
                if not (hc > lo and hc < hi):
                    hc = 0.5 * (lo + hi)
                _rk4(y, k1, hc, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, sk, k2, k3, k4, tmp, yt)
                stats[0] += 1
                rhs(yt, k2, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, sc)
                fc = sc[row, ti]
                if abs(fc) < 1e-13 or hi - lo < 1e-11:
                    break
                if (fc > 0.0) == (f_lo > 0.0):
                    lo = hc
                    f_lo = fc
                    if side == -1:
                        f_hi *= 0.5
                    side = -1
                else:
                    hi = hc
                    f_hi = fc
                    if side == 1:
                        f_lo *= 0.5
                    side = 1
            for i in range(m):
                y[i] = yt[i]
            rhs(y, k1, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, sc)
            for i in range(nt):
                fv[0] = filt[i]
                _filter(fv, tau, hc, st[3, i], sc[3, i])
                filt[i] = fv[0]
            _rk4(y, k1, h - hc, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, sk, k2, k3, k4, tmp, y1)
            stats[0] += 1
            rhs(y1, k1n, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, s1)
            for i in range(nt):
                fv[0] = filt[i]
                _filter(fv, tau, h - hc, sc[3, i], s1[3, i])
                filt[i] = fv[0]
        else:
            for i in range(nt):
                fv[0] = filt[i]
                _filter(fv, tau, h, st[3, i], s1[3, i])
                filt[i] = fv[0]
        for i in range(m):
            y[i] = y1[i]
            k1[i] = k1n[i]
        for r in range(4):
            for i in range(nt):
                st[r, i] = s1[r, i]
        m2 = 6 * n
        for i in range(nt):
            lag = abs(drive[i] - y[m2 + i])
            if lag > health[i]:
                health[i] = lag


@njit(cache=True, error_model="numpy", nogil=True)
def advance(y, t0, drive, d_drive, sample_times, step_times, step_tendon, step_signs, h_max, geo, mb, Jd, Jp,
            tp, W, cw, filt, tau, out_raw, out_filt, out_q, out_tip, stats, health):  # fmt: skip
    """Advance ``y`` from ``t0`` through every sample time; return the time reached.

    Tendon ``step_tendon[j]``'s commanded rotor angle ``drive`` jumps by ``d_drive[tendon] * step_signs[j]``
    at ``step_times[j]`` (sorted); a step at exactly a sample time is applied before that sample. At each
    sample every tendon's arm-side tension (raw and amplifier output), the coordinates and the tip are
    written.
    """
    n = mb.shape[0]
    nt = tp.shape[0]
    m = y.shape[0]
    wb = np.zeros((n, N_WB))
    wt = np.zeros((nt, n + 1, N_WT))
    sp = np.zeros(N_SP + 3 * n)
    bufs = np.empty((7, m))
    sbuf = np.zeros((3, 4, nt))
    k1 = np.empty(m)
    st = np.zeros((4, nt))
    t = t0
    js = 0
    nsteps = step_times.shape[0]
    rhs(y, k1, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, st)
    for qi in range(sample_times.shape[0]):
        ts = sample_times[qi]
        while js < nsteps and step_times[js] <= ts:
            integrate(y, k1, st, step_times[js] - t, drive, h_max, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp,
                      bufs, sbuf, filt, tau, stats, health)  # fmt: skip
            if step_times[js] > t:
                t = step_times[js]
            ti = step_tendon[js]
            drive[ti] += d_drive[ti] * step_signs[js]
            js += 1
            rhs(y, k1, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, st)
            if tau <= 0.0:
                for i in range(nt):
                    filt[i] = st[3, i]
        integrate(y, k1, st, ts - t, drive, h_max, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, bufs, sbuf, filt,
                  tau, stats, health)  # fmt: skip
        if ts > t:
            t = ts
        for i in range(nt):
            out_raw[qi, i] = st[3, i]
            out_filt[qi, i] = filt[i]
        for i in range(3 * n):
            out_q[qi, i] = y[i]
        out_tip[qi, 0] = wb[n - 1, W_P + 0]
        out_tip[qi, 1] = wb[n - 1, W_P + 1]
        out_tip[qi, 2] = wb[n - 1, W_P + 2]
    return t
