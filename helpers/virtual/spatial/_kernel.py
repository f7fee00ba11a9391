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

Written once for one scenario (``float64`` arrays) and for several (:class:`helpers.virtual.lanes.Lanes`, one
scenario per SIMD lane: :class:`helpers.virtual.spatial.plant.SpatialLanes`), as the planar kernel is: a
branch that may differ between lanes is a :func:`~helpers.virtual.lanes.select` or a per-lane loop (the
tension problem's active set, the implicit step's active cables, each lane's splits, searches and events), so
every lane gets the bits of its scenario run alone.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from helpers.virtual._driver import (
    D_ACTIVE,
    D_COMMIT,
    D_FULL,
    D_GEOM,
    D_HSTEP,
    D_LEFT,
    D_NSTEP,
    D_PEND,
    D_REM,
    D_SEARCH,
    D_SPLITS,
    D_TAU,
    L_JS,
    L_QI,
    L_TOSTEP,
    N_DRIVER,
    N_DRIVER_INTS,
    aim,
    arrive,
    begin,
    begin_search,
    blend,
    filter_gain,
    search_step,
    split,
    start_steps,
)
from helpers.virtual._kernel import _RW_GAM, _RW_TA, _RW_TE, _RW_TM, SCHEME_ROSW
from helpers.virtual.lanes import (
    LaneArray,
    all_lane,
    any_lane,
    lane,
    lnot,
    select,
    set_lane,
    vcos,
    vsin,
    vsqrt,
)

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
def _so3_series(x):
    A = 0.0
    for k in range(_NS - 1, -1, -1):
        A = A * x + _FA[k]
    B, Bx, Bxx = _series(_FB, x, _NS)
    C, Cx, Cxx = _series(_FC, x, _NS)
    return A, B, C, 0.0 * x, Bx, Cx, Bxx, Cxx


@njit(cache=True, error_model="numpy", nogil=True)
def _so3_closed(x):
    t = vsqrt(x)
    s = vsin(t)
    co = vcos(t)
    A = s / t
    B = (1.0 - co) / x
    C = (t - s) / (x * t)
    Ax = (co - A) / (2.0 * x)
    Bx = (A - 2.0 * B) / (2.0 * x)
    Cx = (B - 3.0 * C) / (2.0 * x)
    return A, B, C, Ax, Bx, Cx, (Ax - 4.0 * Bx) / (2.0 * x), (Bx - 5.0 * Cx) / (2.0 * x)


@njit(cache=True, error_model="numpy", nogil=True)
def so3(x):
    """The SO(3) functions of ``x = t^2`` and derivatives.

    ``A, B, C`` = ``sin t/t``, ``(1-cos t)/t^2``, ``(t-sin t)/t^3``, then ``A_x`` (unused: 0 below
    ``x = 1``), ``B_x, C_x, B_xx, C_xx``. Series below ``x = 1``, closed forms beyond; lanes on both sides
    take both and keep their own.
    """
    small = x < 1.0
    if all_lane(small):
        return _so3_series(x)
    if not any_lane(small):
        return _so3_closed(x)
    a = _so3_series(x)
    b = _so3_closed(x)
    return (select(small, a[0], b[0]), select(small, a[1], b[1]), select(small, a[2], b[2]),
            select(small, a[3], b[3]), select(small, a[4], b[4]), select(small, a[5], b[5]),
            select(small, a[6], b[6]), select(small, a[7], b[7]))  # fmt: skip


@njit(cache=True, error_model="numpy", nogil=True)
def _bow_p_series(x):
    P, Px, _p = _series(_BP, x, _NB)
    return P, Px


@njit(cache=True, error_model="numpy", nogil=True)
def _bow_p_closed(x):
    D = vsqrt(x)
    iD = 1.0 / D
    sD = vsin(D)
    cD = vcos(D)
    S1 = sD * iD
    S2 = 2.0 * (1.0 - cD) * iD * iD
    dS1 = (cD - S1) * iD
    dS2 = 2.0 * sD * iD * iD - 2.0 * S2 * iD
    P = 0.5 * (1.0 + S1 - 2.0 * S2) * iD * iD
    dP = 0.5 * (dS1 - 2.0 * dS2) * iD * iD - 2.0 * P * iD
    return P, 0.5 * dP * iD


@njit(cache=True, error_model="numpy", nogil=True)
def bow_p(x):
    """The bowing factor ``P`` of an element bent by ``D`` (``x = D^2``) and its x-derivative."""
    small = x < 2.25
    if all_lane(small):
        return _bow_p_series(x)
    if not any_lane(small):
        return _bow_p_closed(x)
    a = _bow_p_series(x)
    b = _bow_p_closed(x)
    return select(small, a[0], b[0]), select(small, a[1], b[1])


@njit(cache=True, error_model="numpy", nogil=True)
def _solve_small(sp, n, out):
    """Solve ``C[A, A] out[A] = e2[A]`` (symmetric positive definite, n <= 4); 0 outside ``A``.

    ``C``, ``e2`` and the active set ``A`` are in the scratch ``sp``. Cholesky over the active tendons in
    their order, each term kept where (in the lanes where) its tendons are active: every lane solves over its
    own active set with the arithmetic of that set alone. The factor and the solution are stored by tendon
    (``S_CHOL + 4 i + j``, ``S_Z + i``).
    """
    w = S_CHOL
    for r in range(n):
        act_r = sp[S_MASK + r] != 0.0
        if not any_lane(act_r):
            continue
        for c in range(r + 1):
            if not any_lane(act_r & (sp[S_MASK + c] != 0.0)):
                continue
            s = sp[S_C + 4 * r + c]
            for k in range(c):
                act_k = sp[S_MASK + k] != 0.0
                if any_lane(act_k):
                    s = select(act_k, s - sp[w + 4 * r + k] * sp[w + 4 * c + k], s)
            if r == c:
                sp[w + 4 * r + r] = vsqrt(s)
            else:
                sp[w + 4 * r + c] = s / sp[w + 4 * c + c]
    for r in range(n):
        act_r = sp[S_MASK + r] != 0.0
        if not any_lane(act_r):
            continue
        s = sp[S_E2 + r]
        for k in range(r):
            act_k = sp[S_MASK + k] != 0.0
            if any_lane(act_k):
                s = select(act_k, s - sp[w + 4 * r + k] * sp[S_Z + k], s)
        sp[S_Z + r] = s / sp[w + 4 * r + r]
    for r in range(n - 1, -1, -1):
        act_r = sp[S_MASK + r] != 0.0
        if not any_lane(act_r):
            continue
        s = sp[S_Z + r]
        for k in range(r + 1, n):
            act_k = sp[S_MASK + k] != 0.0
            if any_lane(act_k):
                s = select(act_k, s - sp[w + 4 * k + r] * sp[S_Z + k], s)
        sp[S_Z + r] = s / sp[w + 4 * r + r]
    for r in range(n):
        out[r] = select(sp[S_MASK + r] != 0.0, sp[S_Z + r], 0.0)


@njit(cache=True, error_model="numpy", nogil=True)
def _tensions(sp, nt, lam):
    """The arm-side tensions ``lam``: the small complementarity problem by active sets.

    Each lane drops the active tendons its solve leaves in compression, or else adds the slack ones whose net
    stretch is positive, until nothing changes (a lane done solves again over the same set: the same bits).
    """
    done = sp[S_MASK] != sp[S_MASK]  # (False in every lane)
    for _it in range(4 * nt + 2):
        _solve_small(sp, nt, lam)
        dropped = done
        for i in range(nt):
            drop = lnot(done) & (sp[S_MASK + i] != 0.0) & (lam[i] < 0.0)
            sp[S_MASK + i] = select(drop, 0.0, sp[S_MASK + i])
            dropped = dropped | drop
        added = done
        rest = lnot(done | dropped)
        if any_lane(rest):
            for i in range(nt):
                slack = rest & (sp[S_MASK + i] == 0.0)
                if any_lane(slack):
                    g = sp[S_E2 + i]
                    for j in range(nt):
                        g -= sp[S_H + 4 * i + j] * lam[j]
                    add = slack & (g > 0.0)
                    sp[S_MASK + i] = select(add, 1.0, sp[S_MASK + i])
                    added = added | add
        done = done | lnot(dropped | added)
        if all_lane(done):
            break


@njit(cache=True, error_model="numpy", nogil=True)
def _rotor(y, drive, geo, tp, st, i):
    """Tendon i's rotor acceleration: the motor's torque on its lag, its damping, the spool-side cable's pull.

    The only term of :func:`rhs` that the drive enters (``st[2]``: the spool-side tensions).
    """
    m2 = y.shape[0] - 4 * tp.shape[0]
    psi = y[m2 + i]
    psid = y[m2 + tp.shape[0] + i]
    delta = drive[i] - psi
    if any_lane(geo[G_TLAW] == 0.0):  # (equal in every lane)
        tm = tp[i, T_TH] * geo[G_NR] * delta
    else:
        tm = tp[i, T_TH] * vsin(geo[G_NR] * delta)
    return (tm - tp[i, T_CR] * psid - tp[i, T_R] * st[2, i]) / tp[i, T_JR]


@njit(cache=True, error_model="numpy", nogil=True)
def _drive_moved(y, dy, drive, geo, tp, st):
    """``dy = f(y)`` again after the drive moved: the rotor accelerations (all that depends on the drive)."""
    m2 = y.shape[0] - 4 * tp.shape[0]
    for i in range(tp.shape[0]):
        dy[m2 + tp.shape[0] + i] = _rotor(y, drive, geo, tp, st, i)


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
    bowing = any_lane(bow != 0.0)  # (equal in every lane of a call: :func:`lane_key`)
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
        Lc = vsqrt(chwx * chwx + chwy * chwy + chwz * chwz)
        o[W_CH + 0] = chwx / Lc
        o[W_CH + 1] = chwy / Lc
        o[W_CH + 2] = chwz / Lc
        o[W_CH + 3] = Lc
        if bowing:
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
            L = vsqrt(dx * dx + dyy * dyy + dz * dz)
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
    if bowing:
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
        st[2, i] = select(e1 > 0.0, tp[i, T_K1] * e1, 0.0)
        e2 = y[m2 + 2 * nt + i] + sc[i, 0, 9] - tp[i, T_ELL]
        sp[S_E2 + i] = e2
        sp[S_MASK + i] = select(e2 > 0.0, 1.0, 0.0)
        for j in range(nt):
            sp[S_C + 4 * i + j] = sp[S_H + 4 * i + j]
        sp[S_C + 5 * i] += 1.0 / tp[i, T_K2]
    _tensions(sp, nt, lam)
    for i in range(nt):
        g = sp[S_E2 + i]
        for j in range(nt):
            g -= sp[S_H + 4 * i + j] * lam[j]
        st[1, i] = g
    # ---- tendon forces on the eyelets: T (u_{k+1} - u_k), the knot T (-u_last); none from a slack one ----
    for i in range(nt):
        T = lam[i]
        on = T != 0.0
        if not any_lane(on):
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
            o[W_F + 0] = select(on, o[W_F + 0] + (Ey * Fz - Ez * Fy), o[W_F + 0])
            o[W_F + 1] = select(on, o[W_F + 1] + (Ez * Fx - Ex * Fz), o[W_F + 1])
            o[W_F + 2] = select(on, o[W_F + 2] + (Ex * Fy - Ey * Fx), o[W_F + 2])
            o[W_F + 3] = select(on, o[W_F + 3] + Fx, o[W_F + 3])
            o[W_F + 4] = select(on, o[W_F + 4] + Fy, o[W_F + 4])
            o[W_F + 5] = select(on, o[W_F + 5] + Fz, o[W_F + 5])
    # ---- bowing: generalised forces (1/2) d(lam^T H lam)/dq = (1/2) h P_x(D_e^2) S^2 2 (a_e, b_e) ----
    if bowing:
        S = 0.0 * bow  # 0.0 (bow > 0), as lanes where they are
        for i in range(nt):
            S += lam[i]
        on = S != 0.0
        if any_lane(on):
            hs = bow * S * S
            for e in range(n):
                dxb = hs * wb[e, W_BOW + 2]
                wb[e, W_TAU + 0] = select(on, wb[e, W_TAU + 0] + dxb * y[3 * e], wb[e, W_TAU + 0])
                wb[e, W_TAU + 1] = select(on, wb[e, W_TAU + 1] + dxb * y[3 * e + 1], wb[e, W_TAU + 1])
    # ---- chord dashpots and the constant floor on phi' ----
    cb = geo[G_CB]
    ct = geo[G_CT]
    if any_lane((cb != 0.0) | (ct != 0.0)):  # (equal in every lane: :func:`lane_key`)
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
    for i in range(nt):
        psid = y[m2 + nt + i]
        xd = y[m2 + 3 * nt + i]
        dy[m2 + i] = psid
        dy[m2 + nt + i] = _rotor(y, drive, geo, tp, st, i)
        dy[m2 + 2 * nt + i] = xd
        dy[m2 + 3 * nt + i] = (st[2, i] - lam[i] - tp[i, T_CC] * xd) / tp[i, T_MC]


# ---- the linearly implicit step (helpers.virtual._kernel's Rosenbrock-W method, the same coefficients) -----
# ``T = [[0, I], [-M^-1 K, 0]]``, ``K`` the elastic stiffness: the bending and twisting springs (a 3 x 3
# diagonal block per joint) and every taut cable (spool side ``k1 G1 G1^T``, ``G1_i = R_i e_psi_i - e_x_i``;
# the taut arm sides through the tension problem's matrix, ``G2_A C_AA^-1 G2_A^T``,
# ``G2_i = (d ell_i/d phi, e_x_i)``).
# Per step ``M' = M + beta K_springs`` is factored by the articulated-body recursion (each joint's ``D`` gains
# ``beta diag(kb, kb, kt)``), and the cables enter by Woodbury with ``Q = K_a^-1 / beta + G_a^T M'^-1 G_a``
# (symmetric positive definite, at most 2 nt x 2 nt, Cholesky).
# per body (``wfb`` columns): S (18), node position (3), disc axis (3), U D'^-1 (18), D'^-1 (9)
(WB_S, WB_P, WB_T, WB_UD, WB_DI) = (0, 18, 21, 24, 42)
N_WFB = 51
# scalars (``wfs``): beta, the count of active cables, whether each cable is active (1.0 or 0.0; cable
# ``i < nt`` is tendon i's spool side, ``nt + i`` its arm side), the arm sides' C_AA (4 x 4), Q over the
# cables and its Cholesky factor (8 x 8, rows and columns by cable: only the active ones' entries are read, in
# cable order, so each lane solves over its own active set), work vectors
(WS_BETA, WS_NA, WS_ACT, WS_CAA, WS_Q, WS_V1, WS_V2, WS_V3, WS_HP, WS_IA, WS_U) = (
    0, 1, 2, 10, 26, 90, 98, 106, 114, 115, 151)  # fmt: skip
N_WFS = 169
MAX_SPLITS = 16
"""The implicit step splits a step at up to this many taut/slack transitions (RK4: at the first only, as the
stored data were made)."""


def w_workspaces(n: int, nt: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Work arrays of the implicit step: per body, per tendon (its gradient and ``M'^-1`` of it), scalars."""
    return np.zeros((n, N_WFB)), np.zeros((2, nt, 3 * n)), np.zeros(N_WFS)


@njit(cache=True, error_model="numpy", nogil=True)
def wgeom(geo, tp, wb, wt, sp, taut1, taut2, wfb, wft, wfs):
    """Store what ``T`` needs of the state whose right-hand side :func:`rhs` left in ``wb, wt, sp``.

    ``taut1[i]``, ``taut2[i]``: whether tendon i's spool side and arm side are taut on the step's branch
    (booleans; or a stretch, taut where positive: lanes pass the stretches ``sr`` at the piece's start).
    """
    n = wb.shape[0]
    nt = tp.shape[0]
    ne = n + 1
    for e in range(n):
        o = wb[e]
        q = wfb[e]
        for k in range(18):
            q[WB_S + k] = o[W_S + k]
        q[WB_P + 0] = o[W_P + 0]
        q[WB_P + 1] = o[W_P + 1]
        q[WB_P + 2] = o[W_P + 2]
        q[WB_T + 0] = o[W_R + 2]
        q[WB_T + 1] = o[W_R + 5]
        q[WB_T + 2] = o[W_R + 8]
    # each tendon's d ell / d phi: minus the joint forces of its unit tension (eyelet forces summed inwards)
    for i in range(nt):
        m0 = 0.0
        m1 = 0.0
        m2 = 0.0
        f0 = 0.0
        f1 = 0.0
        f2 = 0.0
        for k in range(ne - 1, 0, -1):
            Fx = -wt[i, k, 6]
            Fy = -wt[i, k, 7]
            Fz = -wt[i, k, 8]
            if k + 1 < ne:
                Fx += wt[i, k + 1, 6]
                Fy += wt[i, k + 1, 7]
                Fz += wt[i, k + 1, 8]
            Ex = wt[i, k, 0]
            Ey = wt[i, k, 1]
            Ez = wt[i, k, 2]
            m0 += Ey * Fz - Ez * Fy
            m1 += Ez * Fx - Ex * Fz
            m2 += Ex * Fy - Ey * Fx
            f0 += Fx
            f1 += Fy
            f2 += Fz
            Sv = wfb[k - 1]
            for c in range(3):
                wft[0, i, 3 * (k - 1) + c] = -(Sv[WB_S + c] * m0 + Sv[WB_S + 3 + c] * m1
                                               + Sv[WB_S + 6 + c] * m2 + Sv[WB_S + 9 + c] * f0
                                               + Sv[WB_S + 12 + c] * f1 + Sv[WB_S + 15 + c] * f2)  # fmt: skip
    # the active cables and the arm sides' tension matrix C_AA = diag(1/k2) + H (H = hP 11^T)
    hP = sp[S_H]
    na = 0.0
    for i in range(nt):
        on = taut1[i] > 0.0
        wfs[WS_ACT + i] = select(on, 1.0, 0.0)
        na = na + select(on, 1.0, 0.0)
    for i in range(nt):
        on = taut2[i] > 0.0
        wfs[WS_ACT + nt + i] = select(on, 1.0, 0.0)
        na = na + select(on, 1.0, 0.0)
    wfs[WS_NA] = na
    wfs[WS_HP] = hP
    for i in range(nt):
        for j in range(nt):
            wfs[WS_CAA + 4 * i + j] = hP + (1.0 / tp[i, T_K2] if i == j else 0.0)


@njit(cache=True, error_model="numpy", nogil=True)
def _gcol(c, nt, tp, wft, vec, nq):
    """``G_c^T vec`` for cable ``c`` (``vec``: a position-space vector ``(phi, psi, x)``)."""
    if c < nt:
        return tp[c, T_R] * vec[nq + c] - vec[nq + nt + c]
    i = c - nt
    acc = vec[nq + nt + i]
    g = wft[0, i]
    for j in range(nq):
        acc += g[j] * vec[j]
    return acc


@njit(cache=True, error_model="numpy", nogil=True)
def _asolve(wfb, tau):
    """``tau <- M'^-1 tau`` for the arm (joint forces in, joint accelerations out; :func:`wfactor`)."""
    n = wfb.shape[0]
    p0 = 0.0
    p1 = 0.0
    p2 = 0.0
    p3 = 0.0
    p4 = 0.0
    p5 = 0.0
    for e in range(n - 1, -1, -1):
        q = wfb[e]
        u0 = tau[3 * e] - (q[WB_S + 0] * p0 + q[WB_S + 3] * p1 + q[WB_S + 6] * p2 + q[WB_S + 9] * p3
                           + q[WB_S + 12] * p4 + q[WB_S + 15] * p5)  # fmt: skip
        u1 = tau[3 * e + 1] - (q[WB_S + 1] * p0 + q[WB_S + 4] * p1 + q[WB_S + 7] * p2 + q[WB_S + 10] * p3
                               + q[WB_S + 13] * p4 + q[WB_S + 16] * p5)  # fmt: skip
        u2 = tau[3 * e + 2] - (q[WB_S + 2] * p0 + q[WB_S + 5] * p1 + q[WB_S + 8] * p2 + q[WB_S + 11] * p3
                               + q[WB_S + 14] * p4 + q[WB_S + 17] * p5)  # fmt: skip
        tau[3 * e] = u0
        tau[3 * e + 1] = u1
        tau[3 * e + 2] = u2
        u = q[WB_UD:WB_UD + 18]
        p0 += u[0] * u0 + u[1] * u1 + u[2] * u2
        p1 += u[3] * u0 + u[4] * u1 + u[5] * u2
        p2 += u[6] * u0 + u[7] * u1 + u[8] * u2
        p3 += u[9] * u0 + u[10] * u1 + u[11] * u2
        p4 += u[12] * u0 + u[13] * u1 + u[14] * u2
        p5 += u[15] * u0 + u[16] * u1 + u[17] * u2
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    a3 = 0.0
    a4 = 0.0
    a5 = 0.0
    for e in range(n):
        q = wfb[e]
        u = q[WB_UD:WB_UD + 18]
        d = q[WB_DI:WB_DI + 9]
        u0 = tau[3 * e]
        u1 = tau[3 * e + 1]
        u2 = tau[3 * e + 2]
        t0 = u[0] * a0 + u[3] * a1 + u[6] * a2 + u[9] * a3 + u[12] * a4 + u[15] * a5
        t1 = u[1] * a0 + u[4] * a1 + u[7] * a2 + u[10] * a3 + u[13] * a4 + u[16] * a5
        t2 = u[2] * a0 + u[5] * a1 + u[8] * a2 + u[11] * a3 + u[14] * a4 + u[17] * a5
        qa = d[0] * u0 + d[1] * u1 + d[2] * u2 - t0
        qb = d[3] * u0 + d[4] * u1 + d[5] * u2 - t1
        qc = d[6] * u0 + d[7] * u1 + d[8] * u2 - t2
        Sv = q[WB_S:WB_S + 18]
        a0 += Sv[0] * qa + Sv[1] * qb + Sv[2] * qc
        a1 += Sv[3] * qa + Sv[4] * qb + Sv[5] * qc
        a2 += Sv[6] * qa + Sv[7] * qb + Sv[8] * qc
        a3 += Sv[9] * qa + Sv[10] * qb + Sv[11] * qc
        a4 += Sv[12] * qa + Sv[13] * qb + Sv[14] * qc
        a5 += Sv[15] * qa + Sv[16] * qb + Sv[17] * qc
        tau[3 * e] = qa
        tau[3 * e + 1] = qb
        tau[3 * e + 2] = qc


@njit(cache=True, error_model="numpy", nogil=True)
def wfactor(geo, mb, Jd, Jp, tp, h, wfb, wft, wfs):
    """Factor ``I - gamma h T`` for the step ``h`` (after :func:`wgeom`)."""
    n = wfb.shape[0]
    nt = tp.shape[0]
    nq = 3 * n
    gh = _RW_GAM * h
    beta = gh * gh
    # a sliver of a step at a transition: T = 0 (a W-method's order holds for any T); its Woodbury form
    # (K^-1 / beta) would divide by a beta that underflows to 0 (lanes: those lanes' solves keep u, _wsolve)
    sliver = gh < 1e-20
    if all_lane(sliver):
        wfs[WS_BETA] = 0.0
        return
    wfs[WS_BETA] = select(sliver, 0.0, beta)
    kd0 = beta * geo[G_KB]
    kd2 = beta * geo[G_KT]
    Ia = wfs[WS_IA:WS_IA + 36]
    U = wfs[WS_U:WS_U + 18]
    for k in range(36):
        Ia[k] = 0.0
    for e in range(n - 1, -1, -1):
        q = wfb[e]
        # the body's inertia about the origin (ground coordinates) plus what the child passed
        m = mb[e]
        px = q[WB_P + 0]
        py = q[WB_P + 1]
        pz = q[WB_P + 2]
        tx = q[WB_T + 0]
        ty = q[WB_T + 1]
        tz = q[WB_T + 2]
        dj = Jp[e] - Jd[e]
        p2 = px * px + py * py + pz * pz
        Ia[0] += Jd[e] + dj * tx * tx + m * (p2 - px * px)
        Ia[1] += dj * tx * ty - m * px * py
        Ia[2] += dj * tx * tz - m * px * pz
        Ia[7] += Jd[e] + dj * ty * ty + m * (p2 - py * py)
        Ia[8] += dj * ty * tz - m * py * pz
        Ia[14] += Jd[e] + dj * tz * tz + m * (p2 - pz * pz)
        Ia[4] += -m * pz
        Ia[5] += m * py
        Ia[9] += m * pz
        Ia[11] += -m * px
        Ia[15] += -m * py
        Ia[16] += m * px
        Ia[21] += m
        Ia[28] += m
        Ia[35] += m
        for i in range(6):
            for j in range(i):
                Ia[6 * i + j] = Ia[6 * j + i]
        Sv = q[WB_S:WB_S + 18]
        for i in range(6):
            for k in range(3):
                acc = 0.0
                for j in range(6):
                    acc += Ia[6 * i + j] * Sv[3 * j + k]
                U[3 * i + k] = acc
        D00 = kd0
        D01 = 0.0
        D02 = 0.0
        D11 = kd0
        D12 = 0.0
        D22 = kd2
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
        idet = 1.0 / (D00 * c00 + D01 * c01 + D02 * c02)
        Di = q[WB_DI:WB_DI + 9]
        Di[0] = c00 * idet
        Di[1] = c01 * idet
        Di[2] = c02 * idet
        Di[3] = Di[1]
        Di[4] = (D00 * D22 - D02 * D02) * idet
        Di[5] = (D01 * D02 - D00 * D12) * idet
        Di[6] = Di[2]
        Di[7] = Di[5]
        Di[8] = (D00 * D11 - D01 * D01) * idet
        UD = q[WB_UD:WB_UD + 18]
        for i in range(6):
            u0 = U[3 * i]
            u1 = U[3 * i + 1]
            u2 = U[3 * i + 2]
            UD[3 * i] = u0 * Di[0] + u1 * Di[3] + u2 * Di[6]
            UD[3 * i + 1] = u0 * Di[1] + u1 * Di[4] + u2 * Di[7]
            UD[3 * i + 2] = u0 * Di[2] + u1 * Di[5] + u2 * Di[8]
        if e == 0:
            break
        # the articulated inertia passed to the parent: Ia - U D'^-1 U^T (ground coordinates: no transform)
        for i in range(6):
            for j in range(i, 6):
                v_ = Ia[6 * i + j] - (UD[3 * i] * U[3 * j] + UD[3 * i + 1] * U[3 * j + 1]
                                      + UD[3 * i + 2] * U[3 * j + 2])  # fmt: skip
                Ia[6 * i + j] = v_
                Ia[6 * j + i] = v_
    # M'^-1 of each tendon's gradient, and Q over the active cables
    for i in range(nt):
        for j in range(nq):
            wft[1, i, j] = wft[0, i, j]
        _asolve(wfb, wft[1, i])
    nc = 2 * nt
    for cr in range(nc):
        act_r = wfs[WS_ACT + cr] != 0.0
        if not any_lane(act_r):
            continue
        for cc in range(cr + 1):
            if not any_lane(act_r & (wfs[WS_ACT + cc] != 0.0)):
                continue
            v = 0.0  # G_r^T A^-1 G_c
            if cr < nt and cc < nt:
                if cr == cc:
                    v = tp[cr, T_R] * tp[cr, T_R] / tp[cr, T_JR] + 1.0 / tp[cr, T_MC]
            elif cr >= nt and cc >= nt:
                ir = cr - nt
                ic = cc - nt
                for j in range(nq):
                    v += wft[0, ir, j] * wft[1, ic, j]
                if ir == ic:
                    v += 1.0 / tp[ir, T_MC]
            else:  # one spool side, one arm side: the carriage they share
                isp = cr if cr < nt else cc
                iar = (cc if cr < nt else cr) - nt
                if isp == iar:
                    v = -1.0 / tp[isp, T_MC]
            if cr == cc:  # K_a^-1 / beta: 1/k1, or C_AA
                if cr < nt:
                    v += 1.0 / (tp[cr, T_K1] * beta)
                else:
                    v += wfs[WS_CAA + 5 * (cr - nt)] / beta
            elif cr >= nt and cc >= nt:
                v += wfs[WS_CAA + 4 * (cr - nt) + (cc - nt)] / beta
            wfs[WS_Q + 8 * cr + cc] = v
    # Cholesky in place (lower triangle), over each lane's active cables
    for r in range(nc):
        act_r = wfs[WS_ACT + r] != 0.0
        if not any_lane(act_r):
            continue
        for c in range(r + 1):
            if not any_lane(act_r & (wfs[WS_ACT + c] != 0.0)):
                continue
            acc = wfs[WS_Q + 8 * r + c]
            for k in range(c):
                act_k = wfs[WS_ACT + k] != 0.0
                if any_lane(act_k):
                    acc = select(act_k, acc - wfs[WS_Q + 8 * r + k] * wfs[WS_Q + 8 * c + k], acc)
            if r == c:
                wfs[WS_Q + 8 * r + r] = vsqrt(acc)
            else:
                wfs[WS_Q + 8 * r + c] = acc / wfs[WS_Q + 8 * c + c]


@njit(cache=True, error_model="numpy", nogil=True)
def _wsolve(geo, tp, gh, wfb, wft, wfs, u, tmp):  # noqa: C901 - one solve, kept together
    """``u <- (I - gh T)^-1 u``: ``u_q = c - beta X``, ``u_v = u_v - gh X``, ``X = (M + beta K)^-1 K c``.

    ``X = y - M'^-1 G_a Q^-1 G_a^T y`` with ``y = M'^-1 K c`` (Woodbury; :func:`wfactor`); ``tmp``: a
    position-space vector of work. The sums over active cables run over every cable in order, each term
    kept where (in the lanes where) its cable is active.
    """
    beta = wfs[WS_BETA]
    keep = beta == 0.0  # T = 0 for this step (wfactor): u unchanged
    if all_lane(keep):
        return
    n = wfb.shape[0]
    nt = tp.shape[0]
    nq = 3 * n
    nc = 2 * nt
    kb = geo[G_KB]
    kt = geo[G_KT]
    # c (positions) into tmp; the springs' joint forces K_b c into tmp's arm part after the cable terms
    for j in range(nq):
        tmp[j] = u[j] + gh * u[nq + j]
    for i in range(nt):
        tmp[nq + i] = u[2 * nq + i] + gh * u[2 * nq + nt + i]
        tmp[nq + nt + i] = u[2 * nq + 2 * nt + i] + gh * u[2 * nq + 3 * nt + i]
    # w = G_a^T c, then K_a w (spool sides k1; arm sides C_AA^-1 w: solved below with the arm block)
    kw = wfs[WS_V1:WS_V1 + 8]
    for c in range(nc):
        if any_lane(wfs[WS_ACT + c] != 0.0):
            kw[c] = _gcol(c, nt, tp, wft, tmp, nq)
    # the arm sides' block: C_AA kw_A = w_A (C_AA = diag(1/k2) + hP 11^T: Sherman-Morrison)
    sk = 0.0
    sw = 0.0
    hP = wfs[WS_HP]
    for c in range(nt, nc):
        act = wfs[WS_ACT + c] != 0.0
        if any_lane(act):
            k2 = tp[c - nt, T_K2]
            sk = select(act, sk + k2, sk)
            sw = select(act, sw + k2 * kw[c], sw)
    corr = hP * sw / (1.0 + hP * sk)
    for c in range(nc):
        if any_lane(wfs[WS_ACT + c] != 0.0):
            if c < nt:
                kw[c] = tp[c, T_K1] * kw[c]
            else:
                k2 = tp[c - nt, T_K2]
                kw[c] = k2 * (kw[c] - corr)
    # y = M'^-1 K c: the springs' part by the recursion, the cables' part from the stored M'^-1 g
    cx = tmp  # reuse: keep c's actuator entries, overwrite the arm part with K_b c
    for e in range(n):
        cx[3 * e] = kb * tmp[3 * e]
        cx[3 * e + 1] = kb * tmp[3 * e + 1]
        cx[3 * e + 2] = kt * tmp[3 * e + 2]
    _asolve(wfb, cx)
    yv = wfs[WS_V2:WS_V2 + 8]  # actuator entries of y: per tendon psi, x (built from kw)
    for i in range(nt):
        yv[i] = 0.0
        yv[4 + i] = 0.0
    for c in range(nc):
        act = wfs[WS_ACT + c] != 0.0
        if not any_lane(act):
            continue
        if c < nt:
            yv[c] = select(act, yv[c] + tp[c, T_R] * kw[c], yv[c])
            yv[4 + c] = select(act, yv[4 + c] - kw[c], yv[4 + c])
        else:
            i = c - nt
            yv[4 + i] = select(act, yv[4 + i] + kw[c], yv[4 + i])
            g = wft[1, i]
            for j in range(nq):
                cx[j] = select(act, cx[j] + kw[c] * g[j], cx[j])
    for i in range(nt):
        yv[i] /= tp[i, T_JR]
        yv[4 + i] /= tp[i, T_MC]
    # z = Q^-1 G_a^T y
    z = wfs[WS_V3:WS_V3 + 8]
    for c in range(nc):
        act = wfs[WS_ACT + c] != 0.0
        if not any_lane(act):
            continue
        if c < nt:
            acc = tp[c, T_R] * yv[c] - yv[4 + c]
        else:
            i = c - nt
            acc = yv[4 + i]
            g = wft[0, i]
            for j in range(nq):
                acc += g[j] * cx[j]
        for k in range(c):
            act_k = wfs[WS_ACT + k] != 0.0
            if any_lane(act_k):
                acc = select(act_k, acc - wfs[WS_Q + 8 * c + k] * z[k], acc)
        z[c] = acc / wfs[WS_Q + 8 * c + c]
    for c in range(nc - 1, -1, -1):
        act = wfs[WS_ACT + c] != 0.0
        if not any_lane(act):
            continue
        acc = z[c]
        for k in range(c + 1, nc):
            act_k = wfs[WS_ACT + k] != 0.0
            if any_lane(act_k):
                acc = select(act_k, acc - wfs[WS_Q + 8 * k + c] * z[k], acc)
        z[c] = acc / wfs[WS_Q + 8 * c + c]
    # X = y - M'^-1 G_a z
    for c in range(nc):
        act = wfs[WS_ACT + c] != 0.0
        if not any_lane(act):
            continue
        if c < nt:
            yv[c] = select(act, yv[c] - tp[c, T_R] * z[c] / tp[c, T_JR], yv[c])
            yv[4 + c] = select(act, yv[4 + c] + z[c] / tp[c, T_MC], yv[4 + c])
        else:
            i = c - nt
            yv[4 + i] = select(act, yv[4 + i] - z[c] / tp[i, T_MC], yv[4 + i])
            g = wft[1, i]
            for j in range(nq):
                cx[j] = select(act, cx[j] - z[c] * g[j], cx[j])
    for j in range(nq):
        cj = u[j] + gh * u[nq + j]
        u[nq + j] = select(keep, u[nq + j], u[nq + j] - gh * cx[j])
        u[j] = select(keep, u[j], cj - beta * cx[j])
    for i in range(nt):
        ip = 2 * nq + i
        cp = u[ip] + gh * u[ip + nt]
        u[ip + nt] = select(keep, u[ip + nt], u[ip + nt] - gh * yv[i])
        u[ip] = select(keep, u[ip], cp - beta * yv[i])
        ix = 2 * nq + 2 * nt + i
        cxx = u[ix] + gh * u[ix + nt]
        u[ix + nt] = select(keep, u[ix + nt], u[ix + nt] - gh * yv[4 + i])
        u[ix] = select(keep, u[ix], cxx - beta * yv[4 + i])


@njit(cache=True, error_model="numpy", nogil=True)
def _which_flip(sa, sb, nt, k, earliest):
    """Lane ``k``: the index (0..2nt-1) of a transition function whose sign differs in ``sa``, ``sb``, or -1.

    Functions ``2 i``: tendon i's spool-side stretch; ``2 i + 1``: its net arm-side stretch. The first in that
    order (RK4), or (``earliest``, the implicit step's choice: each taut/slack change located in time order)
    the one whose sign change comes first on the chord ``sa`` to ``sb``.
    """
    if not earliest:
        for i in range(nt):
            if (lane(sa[0, i], k) > 0.0) != (lane(sb[0, i], k) > 0.0):
                return 2 * i
            if (lane(sa[1, i], k) > 0.0) != (lane(sb[1, i], k) > 0.0):
                return 2 * i + 1
        return -1
    best = -1
    frac = 2.0
    for r in range(2):
        for i in range(nt):
            a = lane(sa[r, i], k)
            b = lane(sb[r, i], k)
            if (a > 0.0) != (b > 0.0):
                f = a / (a - b) if a != b else 0.0
                if f < frac:
                    frac = f
                    best = 2 * i + r
    return best


@njit(cache=True, error_model="numpy", nogil=True)
def _filter_lane(filt, st, s1, tau, h, k):
    """Lane ``k``'s amplifiers ``tau y' = x - y`` over ``h``, each input linear from ``st[3]`` to ``s1[3]``.

    ``exp(-h / tau)`` once for every tendon (the same bits as once per tendon).
    """
    a = math.exp(-h / tau) if tau > 0.0 else 0.0
    for i in range(filt.shape[0]):
        x0 = lane(st[3, i], k)
        x1 = lane(s1[3, i], k)
        if tau <= 0.0:
            v = x1
        else:
            v = a * (lane(filt[i], k) - x0) + x1 - (x1 - x0) * (tau / h) * (1.0 - a)
        filt[i] = set_lane(filt[i], k, v)


@njit(cache=True, error_model="numpy", nogil=True)
def _step(scheme, y, k1, h, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, st, wfb, wft, wfs, bufs, out):  # noqa: C901
    """One step of ``scheme`` from ``y`` (``k1 = f(y)``) over ``h`` into ``out``.

    Classical RK4, or the Rosenbrock-W step (after :func:`wgeom` at ``y``); the three right-hand sides of
    either at one call site (one copy of :func:`rhs` in the compiled code).
    """
    m = y.shape[0]
    implicit = scheme == SCHEME_ROSW
    tmp = bufs[7]
    fb = bufs[8]
    wk = bufs[9]
    hh = 0.5 * h
    gh = _RW_GAM * h
    if implicit:
        wfactor(geo, mb, Jd, Jp, tp, h, wfb, wft, wfs)
        u1 = bufs[0]
        for i in range(m):
            u1[i] = gh * k1[i]
        _wsolve(geo, tp, gh, wfb, wft, wfs, u1, wk)
    for s in range(1, 4):
        if implicit:
            for i in range(m):
                acc = y[i]
                for j in range(s):
                    acc += _RW_TA[s, j] * bufs[j, i]
                tmp[i] = acc
        else:
            kp = k1 if s == 1 else bufs[s - 1]
            c = h if s == 3 else hh
            for i in range(m):
                tmp[i] = y[i] + c * kp[i]
        kout = fb if implicit else bufs[s]
        rhs(tmp, kout, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, st)
        if implicit:
            u = bufs[s]
            for i in range(m):
                acc = gh * fb[i]
                for j in range(s):
                    acc += _RW_TE[s, j] * bufs[j, i]
                u[i] = acc
            _wsolve(geo, tp, gh, wfb, wft, wfs, u, wk)
    if implicit:
        for i in range(m):
            acc = y[i]
            for j in range(4):
                acc += _RW_TM[j] * bufs[j, i]
            out[i] = acc
    else:
        h6 = h / 6.0
        for i in range(m):
            out[i] = y[i] + h6 * (k1[i] + 2.0 * bufs[1, i] + 2.0 * bufs[2, i] + bufs[3, i])


@njit(cache=True, error_model="numpy", nogil=True)
def _branch(sa, taut1, taut2, nt):
    """The taut flags of the tendons' state ``sa`` (spool-side stretch, net arm-side stretch)."""
    for i in range(nt):
        taut1[i] = sa[0, i] > 0.0
        taut2[i] = sa[1, i] > 0.0


# the driver's state of each lane, one row of ``S`` per quantity (lanes along it): the shared rows
# (:mod:`helpers.virtual._driver`); integers in ``L[lane]``, then the transition searched for. Each tendon's
# drive, amplifier output and largest rotor lag persist in arrays of their own (``drive``, ``filt``,
# ``health``).
N_STATE = N_DRIVER
"""Rows of the driver's float state (:func:`advance`)."""
(L_ROW, L_TI) = range(N_DRIVER_INTS, N_DRIVER_INTS + 2)
N_LANE_INTS = N_DRIVER_INTS + 2

UNIFORM = (G_BOW, G_CB, G_CT, G_TLAW)
"""Scalars (``geo``) whose zero-ness or value steers the kernel's branches: lanes of one call share them."""


def lane_key(geo: np.ndarray, W: np.ndarray) -> tuple[float, ...]:
    """What scenarios run in the lanes of one call must share, of their scalars ``geo`` and damping ``W``."""
    return (float(geo[G_BOW] != 0.0), float(geo[G_CB] != 0.0 or geo[G_CT] != 0.0), float(geo[G_TLAW]),
            float(W.shape[0]))  # fmt: skip


@njit(cache=True, error_model="numpy", nogil=True)
def _start_steps(S, mask, implicit, st, sr):
    """The lanes of ``mask`` begin a step of their piece's size from their present state."""
    start_steps(S, mask, implicit)
    for r in range(2):
        for i in range(st.shape[1]):
            sr[r, i] = select(mask, st[r, i], sr[r, i])


@njit(cache=True, error_model="numpy", nogil=True)
def _events(S, L, k, y, st, drive, d_drive, filt, wb, sample_times, step_times, step_tendon, step_signs,
            n_steps, out_raw, out_filt, out_q, out_tip):  # fmt: skip
    """Lane ``k`` has reached its target: record the sample or apply the step, then aim at the next target.

    Stops at a step (its right-hand side must be evaluated again with the new drive: ``D_PEND``), at the
    first piece with steps to take, or when the last sample is recorded (the lane goes idle).
    """
    n = wb.shape[0]
    nt = out_raw.shape[2]
    while True:
        if arrive(S, L, k):
            if L[k, L_TOSTEP] != 0:
                js = L[k, L_JS]
                ti = step_tendon[k, js]
                d = lane(drive[ti], k) + lane(d_drive[ti], k) * step_signs[k, js]
                drive[ti] = set_lane(drive[ti], k, d)
                L[k, L_JS] = js + 1
                S[D_PEND] = set_lane(S[D_PEND], k, 1.0)
                return
            qi = L[k, L_QI]
            for i in range(nt):
                out_raw[k, qi, i] = lane(st[3, i], k)
                out_filt[k, qi, i] = lane(filt[i], k)
            for i in range(3 * n):
                out_q[k, qi, i] = lane(y[i], k)
            for c in range(3):
                out_tip[k, qi, c] = lane(wb[n - 1, W_P + c], k)
            L[k, L_QI] = qi + 1
        if not aim(S, L, k, sample_times, step_times, n_steps):
            return


@njit(cache=True, error_model="numpy", nogil=True)
def _decide(S, L, k, sr, s1, st, filt, implicit, cap):
    """Lane ``k`` after a trial step that is not simply accepted: the first sign of a transition, or a search.

    A transition starts the search for it (:func:`~helpers.virtual._driver.search_step`). The search ends at
    the transition, which becomes the state (``D_COMMIT``, the step not complete: ``D_FULL`` 0), the rest of
    the step to follow on the branch just crossed into (``sr``: the cables taut from there, the one just
    crossed marked crossed at the kink); otherwise the next trial's size is ``D_HSTEP``.
    """
    nt = st.shape[1]
    tau = lane(S[D_TAU], k)
    if lane(S[D_SEARCH], k) == 0.0:
        which = _which_flip(sr, s1, nt, k, implicit)
        if which < 0:  # no sign change after all (a transition function not finite): the step as it is
            _filter_lane(filt, st, s1, tau, lane(S[D_REM], k), k)
            S[D_COMMIT] = set_lane(S[D_COMMIT], k, 1.0)
            S[D_FULL] = set_lane(S[D_FULL], k, 1.0)
            return
        row = which % 2
        ti = which // 2
        L[k, L_ROW] = row
        L[k, L_TI] = ti
        begin_search(S, L, k, lane(sr[row, ti], k), lane(s1[row, ti], k))
        return
    row = L[k, L_ROW]
    ti = L[k, L_TI]
    found, hc, f_hi = search_step(S, L, k, lane(s1[row, ti], k))
    if found:
        # to the transition (the search's last point); the rest of the step from there, on the branch just
        # crossed into (the implicit step's: the one just crossed into, the others as they are)
        _filter_lane(filt, st, s1, tau, hc, k)
        for r in range(2):
            for i in range(nt):
                sr[r, i] = set_lane(sr[r, i], k, lane(s1[r, i], k))
        if (lane(sr[row, ti], k) > 0.0) != (f_hi > 0.0):  # at the kink: count it as crossed
            sr[row, ti] = set_lane(sr[row, ti], k, 1e-300 if f_hi > 0.0 else -1e-300)
        split(S, k, hc, implicit)


@njit(cache=True, error_model="numpy", nogil=True)
def _accept(S, accept, st, s1, filt):
    """The amplifiers' outputs over the accepted steps (``D_REM`` each), lanes at once."""
    a, h, tau = filter_gain(S, accept)
    for i in range(filt.shape[0]):
        x0 = st[3, i]
        x1 = s1[3, i]
        v = a * (filt[i] - x0) + x1 - (x1 - x0) * (tau / h) * (1.0 - a)
        filt[i] = select(accept, select(tau <= 0.0, x1, v), filt[i])


@njit(cache=True, error_model="numpy", nogil=True)
def advance(scheme, y, S, L, drive, d_drive, filt, health, sample_times, step_times, step_tendon, step_signs,
            n_steps, geo, mb, Jd, Jp, tp, W, cw, k1, st, sbuf, wb, wt, sp, wfb, wft, wfs, wfb2, wft2, wfs2,
            bufs, out_raw, out_filt, out_q, out_tip):  # fmt: skip
    """Advance every lane's ``y`` from its time ``S[D_T]`` through its sample times with ``scheme``.

    One scenario (scalars) or several (lanes: one per scenario; ``y``, ``S``, ``drive``, ``d_drive``,
    ``filt``, ``health``, :func:`rhs`'s parameters and the work arrays as lane arrays). Each lane takes equal
    steps ``<= S[D_HMAX]`` between its events (its stepper steps and its samples). A step across which any
    tendon's spool-side or net arm-side stretch changes sign is split at the transition (Illinois method on
    the step size). With the implicit step (``SCHEME_ROSW``) each piece's stiffness ``T`` is that of the
    branch the piece lies on (the cables taut at its start, the one just crossed into counted so), and every
    transition in the step is located, in time order (up to :data:`MAX_SPLITS`); RK4 splits at the first
    only. Every lane takes exactly the steps it takes alone: each pass of the loop below is one trial step of
    every lane (of its own size) and one right-hand side at its end, then each lane's own decision (accept,
    split, search, its next event), so a lane's arithmetic does not depend on the others.

    Tendon ``step_tendon[lane, j]``'s commanded rotor angle ``drive`` jumps by ``d_drive[tendon] *
    step_signs[lane, j]`` at ``step_times[lane, j]`` (each lane's first ``n_steps[lane]``, sorted); a step at
    exactly a sample time is applied before that sample. At each sample every tendon's arm-side tension (raw
    and amplifier output ``filt``, time constant ``S[D_TAU]``: the low-pass integrated exactly for a tension
    linear over each step), the coordinates and the tip are written into ``out_*[lane]``. ``S[D_NSTEP]``,
    ``S[D_NTRANS]`` count steps and transitions, ``health[i]`` is tendon i's largest rotor lag (rad).

    Work: ``k1`` (m), ``st`` (4, nt), ``sbuf`` (3, 4, nt), ``wb, wt, sp`` (:func:`workspaces`), ``wfb, wft,
    wfs`` and ``wfb2, wft2, wfs2`` (:func:`w_workspaces`), ``bufs`` (10, m): :func:`make_work`.
    """
    # plain arrays down (a lane array's full slice), as the planar kernel's advance does: each function
    # compiles once per form instead of once per mix of a LaneArray and the arrays of lanes taken from it
    _advance(scheme, y[:], S[:], L, drive[:], d_drive[:], filt[:], health[:], sample_times, step_times,
             step_tendon, step_signs, n_steps, geo[:], mb[:], Jd[:], Jp[:], tp[:], W[:], cw[:], k1[:], st[:],
             sbuf[:], wb[:], wt[:], sp[:], wfb[:], wft[:], wfs[:], wfb2[:], wft2[:], wfs2[:], bufs[:],
             out_raw, out_filt, out_q, out_tip)  # fmt: skip


@njit(cache=True, error_model="numpy", nogil=True)
def _advance(scheme, y, S, L, drive, d_drive, filt, health, sample_times, step_times, step_tendon,  # noqa: C901
             step_signs, n_steps, geo, mb, Jd, Jp, tp, W, cw, k1, st, sbuf, wb, wt, sp, wfb, wft, wfs, wfb2,
             wft2, wfs2, bufs, out_raw, out_filt, out_q, out_tip):  # fmt: skip
    """:func:`advance` on plain arrays (of scalars or of lanes)."""
    nl = L.shape[0]
    n = mb.shape[0]
    nt = tp.shape[0]
    nq = 3 * n
    m = y.shape[0]
    implicit = scheme == SCHEME_ROSW
    cap = MAX_SPLITS if implicit else 1
    y1 = bufs[4]
    k1n = bufs[6]
    s1 = sbuf[0]
    sr = sbuf[1]
    sk = sbuf[2]
    rhs(y, k1, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, st)
    begin(S, L)
    pending = True  # lanes to move on to their next event
    while True:
        if pending:
            # the events of lanes that reached their targets; a step there evaluates the right-hand side
            # again with the new drive: the rotor accelerations, all the drive enters (the other lanes get
            # again what they hold)
            waiting = (S[D_ACTIVE] != 0.0) & (S[D_LEFT] == 0.0)
            while True:
                ready = (S[D_ACTIVE] != 0.0) & (S[D_LEFT] == 0.0)
                for k in range(nl):
                    if lane(ready, k):
                        _events(S, L, k, y, st, drive, d_drive, filt, wb, sample_times, step_times,
                                step_tendon, step_signs, n_steps, out_raw, out_filt, out_q,
                                out_tip)  # fmt: skip
                pend = S[D_PEND] != 0.0
                if not any_lane(pend):
                    break
                _drive_moved(y, k1, drive, geo, tp, st)
                now = pend & (S[D_TAU] <= 0.0)
                for i in range(nt):
                    filt[i] = select(now, st[3, i], filt[i])
                S[D_PEND] = 0.0
            started = waiting & (S[D_ACTIVE] != 0.0) & (S[D_LEFT] > 0.0)
            _start_steps(S, started, implicit, st, sr)
            pending = False
        active = S[D_ACTIVE] != 0.0
        if not any_lane(active):
            break
        # one trial step of every lane (idle lanes repeat a harmless step that nothing keeps)
        if implicit:
            geom = S[D_GEOM] != 0.0
            if all_lane(geom):
                wgeom(geo, tp, wb, wt, sp, sr[0], sr[1], wfb, wft, wfs)
            elif any_lane(geom):
                wgeom(geo, tp, wb, wt, sp, sr[0], sr[1], wfb2, wft2, wfs2)
                for e in range(n):
                    blend(geom, wfb[e], wfb2[e], N_WFB)
                for i in range(nt):
                    blend(geom, wft[0, i], wft2[0, i], nq)
                blend(geom, wfs, wfs2, N_WFS)
            S[D_GEOM] = 0.0
        _step(scheme, y, k1, S[D_HSTEP], drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, sk, wfb, wft, wfs,
              bufs, y1)  # fmt: skip
        rhs(y1, k1n, drive, geo, mb, Jd, Jp, tp, W, cw, wb, wt, sp, s1)
        S[D_NSTEP] = select(active, S[D_NSTEP] + 1.0, S[D_NSTEP])
        # the trial accepted where no cable changed between taut and slack (or no more splits are allowed)
        flip = active ^ active
        for r in range(2):
            for i in range(nt):
                flip = flip | ((sr[r, i] > 0.0) ^ (s1[r, i] > 0.0))
        search = S[D_SEARCH] != 0.0
        accept = active & lnot(search) & ((S[D_SPLITS] >= cap) | lnot(flip))
        _accept(S, accept, st, s1, filt)
        S[D_COMMIT] = select(accept, 1.0, 0.0)
        S[D_FULL] = S[D_COMMIT]
        other = active & lnot(accept)
        if any_lane(other):
            for k in range(nl):
                if lane(other, k):
                    _decide(S, L, k, sr, s1, st, filt, implicit, cap)
        commit = S[D_COMMIT] != 0.0
        if any_lane(commit):
            blend(commit, y, y1, m)
            blend(commit, k1, k1n, m)
            for r in range(4):
                for i in range(nt):
                    st[r, i] = select(commit, s1[r, i], st[r, i])
        full = S[D_FULL] != 0.0
        if any_lane(full):
            for i in range(nt):
                lag = abs(drive[i] - y[2 * nq + i])
                health[i] = select(full & (lag > health[i]), lag, health[i])
            S[D_LEFT] = select(full, S[D_LEFT] - 1.0, S[D_LEFT])
            _start_steps(S, full & (S[D_LEFT] > 0.0), implicit, st, sr)
            pending = any_lane(full & (S[D_LEFT] == 0.0))


class Work(NamedTuple):
    """Work arrays of :func:`advance` (one set per plant, reused by every call)."""

    k1: Any
    st: Any
    sbuf: Any
    wb: Any
    wt: Any
    sp: Any
    wfb: Any
    wft: Any
    wfs: Any
    wfb2: Any
    wft2: Any
    wfs2: Any
    bufs: Any


def make_work(n: int, nt: int, lanes: int = 0) -> Work:
    """:func:`advance`'s work arrays for ``n`` bodies and ``nt`` tendons: scalars, or ``lanes`` lanes."""
    m = 6 * n + 4 * nt
    shapes = ((m,), (4, nt), (3, 4, nt), (n, N_WB), (nt, n + 1, N_WT), (N_SP + 3 * n,), (n, N_WFB),
              (2, nt, 3 * n), (N_WFS,), (n, N_WFB), (2, nt, 3 * n), (N_WFS,), (10, m))  # fmt: skip
    if lanes == 0:
        return Work(*(np.zeros(s) for s in shapes))
    return Work(*(LaneArray(np.zeros((*s, lanes))) for s in shapes))
