"""Compiled (numba) right-hand side and fixed-step integrator of the arc-chain arm with its actuator.

No ``fastmath`` anywhere: plain IEEE arithmetic, the same bits on every x86-64 CPU
(``docs/reproducibility.md``).

Model (``docs/virtual_rig.md``; :mod:`helpers.virtual.statics` has the statics of the same arm)
---------------------------------------------------------------------------------------------
The rod is a chain of ``N`` circular arcs of length ``l`` (constant curvature inside each). The coordinates
are the tangent angles ``theta_1..theta_N`` at the element ends (``theta_0`` = the clamp direction). Body
``i`` is node ``i``: a point mass ``m_i`` (wire halves and, at a disc, the disc) and a rotary inertia ``J_i``
(the disc's, about a diameter); it turns with the rod tangent ``theta_i``. Joint ``i`` (one degree of
freedom, ``D_i = theta_i - theta_{i-1}``) places body ``i`` at ``p_{i-1} + l R(theta_{i-1}) (f1(D_i),
f2(D_i))`` with ``f1 = sin D / D``, ``f2 = (1 - cos D) / D``: the exact chord of the arc, a curved 1-DOF
joint. The equations of motion are solved in O(N) by the articulated-body algorithm in planar form
(3-vectors ``(omega, v_x, v_y)`` about each node, 3x3 articulated inertias); the bias term ``kappa`` holds
the velocity-product terms of the curved joint.

Loads: bending springs ``EI/l`` on each ``D_i`` (exact for an arc); gravity along -y; drag ``-alpha m v``
on every mass and ``-alpha J omega`` on every disc; dashpots between the *chords* of consecutive disc
intervals (``c_chord`` on ``d_0 = w_1 / 2``, ``d_k = (w_{k+1} - w_{k-1}) / 2``, ``w_k`` the disc rotation
rates, clamp = 0); optional dashpots on the relative rotation of consecutive discs (``c_disc``, only for the
damping-layout comparison); a constant full-rank damping ``-sum_k c_k W_k (W_k . theta')`` (the high-mode
floor); the cable through the clamp guide and the disc eyelets (force on eyelet ``q``:
``-T_q u_q + T_{q+1} u_{q+1}``, moment ``r n x F``). The run tensions ``T_q`` all equal the arm-side tension
``lambda_2`` unless eyelet friction is on: capstan law ``T_{q+1} = T_q exp(-mu beta_q tanh(v_q / v0))`` at
the guide and each eyelet (wrap angle ``beta_q`` between the incoming and outgoing runs, ``v_q`` the speed at
which the cable slides through that eyelet towards the guide: the rate at which the runs beyond it shorten).

Bowing between eyelets (``P[I_BOW] = l^3 / EI``, 0 = off): the arm-side cable's tension is
``lambda_2 = e2 / (1/k2 + H(theta))`` with the compliance ``H = (l^3/EI) sum_e (P(D_e) + Q(D_e) sin^2 c_e)``
of the part of the cable's moment that the arcs cannot carry (``c_e``: the angle between element e's chord and
its cable run; 0 when a run is one element, ``P[I_BOWRUN] = 0``), i.e. the potential
``e2^2 / (2 (1/k2 + H))``, whose ``theta``-gradient adds the generalised force ``(lambda_2^2 / 2) dH/dtheta``
(with friction on, the bowing uses the tension at the guide).

Actuator modes (``P[I_MODE]``):

0. ideal: arm-side stretch ``e2 = u + ell - ell_ref``; ``u`` jumps by one step's cable at each step;
1. stepper: rotor + spool angle ``psi``, ``J psi'' = T_m(psi_cmd - psi) - c_r psi' - R lambda``,
   ``e2 = R psi + ell - ell_ref``; ``psi_cmd`` jumps by ``2 pi / steps_per_rev`` at each step;
2. stepper + load-cell carriage (mass ``m_c`` on rails between the spool-side cable ``k1`` and the arm-side
   cable ``k2``): ``e1 = R psi - x_c - s1_ref``, ``e2 = x_c + ell - ell_ref``,
   ``m_c x_c'' = lambda_1 - lambda_2 - c_c x_c'``.

Motor torque ``T_m``: linear ``T_h N_r delta`` or sinusoidal ``T_h sin(N_r delta)`` (``P[I_TLAW]``). The
load cell reads ``lambda_2`` (arm side) or ``lambda_1`` (spool side, ``P[I_MEAS] = 1``); its amplifier is a
first-order low-pass integrated exactly for a tension linear over each step (``filt = [tau, y]``).

State ``y = [theta (N), theta' (N), psi, psi', x_c, x_c']``.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from helpers.virtual._driver import (
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
from helpers.virtual.lanes import (
    BLOCK,
    LaneArray,
    all_lane,
    any_lane,
    block_load,
    block_store,
    block_width,
    lane,
    lane_count,
    lnot,
    select,
    set_lane,
    vatan2,
    vexp,
    vsin,
    vsqrt,
    vtanh,
)

# packed parameter indices
(I_L, I_R, I_TH0, I_G, I_ALPHA, I_KAP, I_K2, I_ELLREF, I_MODE, I_RSP, I_JR, I_TH, I_NR, I_CR, I_K1,
 I_S1REF, I_MC, I_CC, I_CDISC, I_MU, I_V0, I_TLAW, I_BILAT, I_MEAS, I_CCHORD, I_BOW,
 I_BOWRUN) = range(27)  # fmt: skip
N_PACKED = 27

# series coefficients of the chord functions for |D| < 0.2, in x = D^2 (truncation < 1e-18)
_NS = 8
_A1 = np.array([(-1.0) ** k / math.factorial(2 * k + 1) for k in range(_NS)])  # f1
_B2 = np.array([(-1.0) ** k / math.factorial(2 * k + 2) for k in range(_NS)])  # f2 / D
_A1P = np.array([(-1.0) ** k * 2 * k / math.factorial(2 * k + 1) for k in range(1, _NS + 1)])  # f1' / D
_B2P = np.array([(-1.0) ** k * (2 * k + 1) / math.factorial(2 * k + 2) for k in range(_NS)])  # f2'
_A1PP = np.array([(-1.0) ** k * 2 * k * (2 * k - 1) / math.factorial(2 * k + 1) for k in range(1, _NS + 1)])
_B2PP = np.array([(-1.0) ** k * (2 * k + 1) * 2 * k / math.factorial(2 * k + 2) for k in range(1, _NS + 1)])
# bowing shape factors P(D) = (1 + S1 - 2 S2) / (2 D^2), Q(D) = (S2 - S1) / D^2 (S1 = sin D / D,
# S2 = 2 (1 - cos D) / D^2) as series in x = D^2 for |D| < 1 (truncation < 1e-14 relative)
_NB = 9
_S1C = np.array([(-1.0) ** j / math.factorial(2 * j + 1) for j in range(_NB + 1)])
_S2C = np.array([2.0 * (-1.0) ** j / math.factorial(2 * j + 2) for j in range(_NB + 1)])
_BP = 0.5 * (_S1C[1:] - 2.0 * _S2C[1:])  # P
_BQ = _S2C[1:] - _S1C[1:]  # Q
_BPD = np.array([2.0 * j * _BP[j] for j in range(1, _NB)])  # P' / D
_BQD = np.array([2.0 * j * _BQ[j] for j in range(1, _NB)])  # Q' / D
_BP7 = _BP[:7].copy()
_BPD6 = _BPD[:6].copy()
_SIN = np.array([(-1.0) ** k / math.factorial(2 * k + 1) for k in range(_NS)])  # sin D / D
_COS = np.array([(-1.0) ** k / math.factorial(2 * k) for k in range(_NS)])  # cos D

N_WS_PER = 40
"""Work floats per body."""


N_BLOCK_ROWS = 13
"""Rows of the per-joint terms (:func:`rhs_ws`), each padded to whole blocks."""


def workspace_size(n: int, n_eye: int) -> int:
    """Floats needed by :func:`rhs_ws` for ``n`` bodies and ``n_eye`` eyelets (guide included)."""
    return N_WS_PER * n + 12 * n_eye + 16 + N_BLOCK_ROWS * (n + BLOCK)


UNIFORM = (I_TH0, I_MODE, I_TLAW, I_MEAS, I_BILAT, I_BOWRUN, I_MU)
"""Packed scalars that steer the kernel's branches: equal in every lane of a call (``U``, below). The rest of
``P`` may differ from lane to lane, except whether ``P[I_BOW]``, ``P[I_CDISC]``, ``P[I_CCHORD]`` are zero."""


def lane_key(P: np.ndarray) -> tuple[float, ...]:
    """What scenarios run in the lanes of one call must share, of their packed scalars ``P``."""
    return tuple(float(P[i]) for i in UNIFORM) + tuple(float(P[i] != 0.0) for i in (I_BOW, I_CDISC, I_CCHORD))


@njit(cache=True, error_model="numpy", nogil=True)
def _horner(c, x):
    acc = 0.0
    for k in range(c.shape[0] - 1, -1, -1):
        acc = acc * x + c[k]
    return acc


@njit(cache=True, error_model="numpy", nogil=True)
def _chord_series(D):
    x = D * D
    return (_horner(_A1, x), D * _horner(_B2, x), D * _horner(_A1P, x), _horner(_B2P, x), _horner(_A1PP, x),
            D * _horner(_B2PP, x))  # fmt: skip


@njit(cache=True, error_model="numpy", nogil=True)
def _chord_closed(D, sD, cD):
    iD = 1.0 / D
    omc = 1.0 - cD
    f1 = sD * iD
    f2 = omc * iD
    f1p = (cD - f1) * iD
    f2p = (sD - f2) * iD
    f1pp = (-sD - 2.0 * f1p) * iD
    f2pp = (cD - 2.0 * f2p) * iD
    return f1, f2, f1p, f2p, f1pp, f2pp


@njit(cache=True, error_model="numpy", nogil=True)
def chord_funcs(D, sD, cD):
    """``f1, f2, f1', f2', f1'', f2''`` of an arc turning by ``D`` (``sD, cD`` = sin D, cos D).

    Series for ``|D| < 0.2``, closed forms beyond; lanes on both sides take both and keep their own.
    """
    small = abs(D) < 0.2
    if all_lane(small):
        return _chord_series(D)
    if not any_lane(small):
        return _chord_closed(D, sD, cD)
    a = _chord_series(D)
    b = _chord_closed(D, sD, cD)
    return (select(small, a[0], b[0]), select(small, a[1], b[1]), select(small, a[2], b[2]),
            select(small, a[3], b[3]), select(small, a[4], b[4]), select(small, a[5], b[5]))  # fmt: skip


@njit(cache=True, error_model="numpy", nogil=True)
def _bow_series(D):
    x = D * D
    return _horner(_BP, x), D * _horner(_BPD, x), _horner(_BQ, x), D * _horner(_BQD, x)


@njit(cache=True, error_model="numpy", nogil=True)
def _bow_closed(D, sD, cD):
    iD = 1.0 / D
    S1 = sD * iD
    S2 = 2.0 * (1.0 - cD) * iD * iD
    dS1 = (cD - S1) * iD
    dS2 = 2.0 * sD * iD * iD - 2.0 * S2 * iD
    P = 0.5 * (1.0 + S1 - 2.0 * S2) * iD * iD
    Q = (S2 - S1) * iD * iD
    dP = 0.5 * (dS1 - 2.0 * dS2) * iD * iD - 2.0 * P * iD
    dQ = (dS2 - dS1) * iD * iD - 2.0 * Q * iD
    return P, dP, Q, dQ


@njit(cache=True, error_model="numpy", nogil=True)
def bow_funcs(D, sD, cD):
    """``P, P', Q, Q'``: shape factors of the bowing compliance of an arc turning by ``D``.

    ``sD, cD`` = sin D, cos D. The arc's mean square distance from a line, about its mean, is
    ``l^2 (P + Q sin^2 c)``, ``c`` the angle between its chord and the line.
    """
    small = abs(D) < 1.0
    if all_lane(small):
        return _bow_series(D)
    if not any_lane(small):
        return _bow_closed(D, sD, cD)
    a = _bow_series(D)
    b = _bow_closed(D, sD, cD)
    return (select(small, a[0], b[0]), select(small, a[1], b[1]), select(small, a[2], b[2]),
            select(small, a[3], b[3]))  # fmt: skip


@njit(cache=True, error_model="numpy", nogil=True)
def _bow_p_series(D):
    x = D * D
    return _horner(_BP7, x), D * _horner(_BPD6, x)


@njit(cache=True, error_model="numpy", nogil=True)
def _bow_p_closed(D, sD, cD):
    iD = 1.0 / D
    S1 = sD * iD
    S2 = 2.0 * (1.0 - cD) * iD * iD
    dS1 = (cD - S1) * iD
    dS2 = 2.0 * sD * iD * iD - 2.0 * S2 * iD
    P = 0.5 * (1.0 + S1 - 2.0 * S2) * iD * iD
    return P, 0.5 * (dS1 - 2.0 * dS2) * iD * iD - 2.0 * P * iD


@njit(cache=True, error_model="numpy", nogil=True)
def bow_p(D, sD, cD):
    """``P, P'`` of :func:`bow_funcs` alone (a cable run of one element: ``c = 0``).

    Shorter series, for ``|D| < 0.8``: relative truncation and the closed form's cancellation beyond < 1e-12.
    """
    small = abs(D) < 0.8
    if all_lane(small):
        return _bow_p_series(D)
    if not any_lane(small):
        return _bow_p_closed(D, sD, cD)
    a = _bow_p_series(D)
    b = _bow_p_closed(D, sD, cD)
    return select(small, a[0], b[0]), select(small, a[1], b[1])


@njit(cache=True, error_model="numpy", nogil=True)
def _rotate_series(D, cp, sp):
    """The tangent ``(cos, sin)`` at ``theta_{i-1} + D`` from the one before; ``sin D, cos D`` (series)."""
    x = D * D
    sD = D * _horner(_SIN, x)
    cD = _horner(_COS, x)
    return cp * cD - sp * sD, sp * cD + cp * sD, sD, cD


@njit(cache=True, error_model="numpy", nogil=True)
def _rotate_mixed(small, D, th, cp, sp):
    """:func:`_rotate_series` where ``small``, libm's ``cos, sin`` of ``theta`` in the other lanes."""
    ci, si, sD, cD = _rotate_series(D, cp, sp)
    for k in range(lane_count(D)):
        if not lane(small, k):
            c = math.cos(lane(th, k))
            s = math.sin(lane(th, k))
            c0 = lane(cp, k)
            s0 = lane(sp, k)
            ci = set_lane(ci, k, c)
            si = set_lane(si, k, s)
            sD = set_lane(sD, k, s * c0 - c * s0)
            cD = set_lane(cD, k, c * c0 + s * s0)
    return ci, si, sD, cD


@njit(cache=True, error_model="numpy", nogil=True)
def _rotor_acceleration(P, U, drive, psi, psid, lam_sp):
    """The rotor's angular acceleration: the motor's torque on its lag, its damping, the cable's pull."""
    delta = drive - psi
    if U[I_TLAW] == 0.0:
        tm = P[I_TH] * P[I_NR] * delta
    else:
        tm = P[I_TH] * vsin(P[I_NR] * delta)
    return (tm - P[I_CR] * psid - P[I_RSP] * lam_sp) / P[I_JR]


@njit(cache=True, error_model="numpy", nogil=True)
def rhs_ws(y, dy, drive, P, U, mb, Jb, disc, W, cw, ws):  # noqa: C901 - one pass per stage, kept together
    """Write ``dy = f(y)``; return ``(e1, e2, lam1, lam2)`` (stretches and tensions of the two cables).

    Every array holds either scalars (one scenario) or :class:`helpers.virtual.lanes.Lanes` (one scenario
    per lane, the same arithmetic on each): ``y``, ``dy``, ``P``, ``mb``, ``Jb``, ``W``, ``cw``, ``ws`` and
    ``drive`` alike.

    Parameters
    ----------
    y, dy : float64[2 N + 4]
        State and its derivative (written).
    drive : float
        Cable displacement ``u`` (mode 0) or commanded rotor angle (modes 1, 2).
    P : float64[N_PACKED]
        Packed scalars (indices ``I_*``).
    U : float64[N_PACKED]
        The packed scalars that steer branches (:data:`UNIFORM`): ``P`` itself for one scenario, its first
        lane for several.
    mb, Jb : float64[N]
        Node masses and rotary inertias.
    disc : int64[n_eyelets]
        Node indices (1-based) of the eyelet discs, increasing, last = N (tip, knot).
    W : float64[r, N]
        Rows of the constant damping: generalised force ``-sum_k cw_k W_k (W_k . theta')``.
    cw : float64[r]
        Its coefficients.
    ws : float64[workspace_size]
        Work array.
    """
    n = mb.shape[0]
    nd = disc.shape[0]
    l_ = P[I_L]
    r = P[I_R]
    g = P[I_G]
    alpha = P[I_ALPHA]
    kap = P[I_KAP]
    o_c = 0
    o_s = n
    o_wx = 2 * n  # the chord rotated by 90 deg (the X transform)
    o_wy = 3 * n
    o_ex = 4 * n  # d chord / d D
    o_ey = 5 * n
    o_kx = 6 * n  # bias acceleration
    o_ky = 7 * n
    o_px = 8 * n  # node position
    o_py = 9 * n
    o_vx = 10 * n  # node velocity
    o_vy = 11 * n
    o_fx = 12 * n  # external force on the body
    o_fy = 13 * n
    o_fn = 14 * n  # external moment
    o_q = 15 * n  # joint generalised force
    o_u = 25 * n  # U (3), 1/D, u  (25n .. 30n)
    o_qt = 30 * n  # generalised forces on theta (constant and chord damping, bowing)
    o_bgt = 35 * n  # bowing: d H / d(chord direction)
    o_e = 40 * n  # eyelets: Ex, Ey, ux, uy, L, T, Evx, Evy (12 per eyelet)
    ne = nd + 1
    # what depends on each joint's D alone, in rows padded to whole blocks (one scenario: BLOCK bodies per
    # vector; lanes: one body, every lane): D, its sine and cosine, the chord functions, the bowing's factors
    nb = block_width(ws)
    npad = (n + nb - 1) // nb * nb
    o_d = N_WS_PER * n + 12 * ne + 16
    o_sd = o_d + npad
    o_cd = o_sd + npad
    o_f = o_cd + npad  # f1, f2, f1', f2', f1'', f2'' (six rows)
    o_bp = o_f + 6 * npad  # bowing: P, P', Q, Q' of each element
    o_bdp = o_bp + npad
    o_bq = o_bdp + npad
    o_bdq = o_bq + npad
    bow = P[I_BOW]  # l^3 / EI, or 0: no bowing
    bowing = U[I_BOW] != 0.0
    bowrun = U[I_BOWRUN] != 0.0  # some cable run spans several elements
    # ---- outward pass 1: kinematics ----
    th0 = U[I_TH0]
    thp = th0
    for i in range(n):
        th = y[i]
        ws[o_d + i] = th - thp
        thp = th
    for i in range(n, npad):
        ws[o_d + i] = 0.0
    for i in range(0, npad, nb):
        D = block_load(ws, o_d + i)
        # sin D, cos D by series (error < 2e-17: two libm calls fewer; |D| >= 0.6 is redone below)
        x = D * D
        sD = D * _horner(_SIN, x)
        cD = _horner(_COS, x)
        block_store(ws, o_sd + i, sD)
        block_store(ws, o_cd + i, cD)
        f1, f2, f1p, f2p, f1pp, f2pp = chord_funcs(D, sD, cD)
        block_store(ws, o_f + i, f1)
        block_store(ws, o_f + npad + i, f2)
        block_store(ws, o_f + 2 * npad + i, f1p)
        block_store(ws, o_f + 3 * npad + i, f2p)
        block_store(ws, o_f + 4 * npad + i, f1pp)
        block_store(ws, o_f + 5 * npad + i, f2pp)
        if bowing:
            if bowrun:
                bP, bdP, bQ, bdQ = bow_funcs(D, sD, cD)
                block_store(ws, o_bq + i, bQ)
                block_store(ws, o_bdq + i, bdQ)
            else:
                bP, bdP = bow_p(D, sD, cD)
            block_store(ws, o_bp + i, bP)
            block_store(ws, o_bdp + i, bdP)
    cp = math.cos(th0)
    sp = math.sin(th0)
    wp = 0.0
    px = 0.0
    py = 0.0
    vx = 0.0
    vy = 0.0
    for i in range(n):
        th = y[i]
        w = y[n + i]
        D = ws[o_d + i]
        Dd = w - wp
        small = abs(D) < 0.6
        if all_lane(small):  # rotate the previous tangent by D
            sD = ws[o_sd + i]
            cD = ws[o_cd + i]
            ci = cp * cD - sp * sD
            si = sp * cD + cp * sD
            f1 = ws[o_f + i]
            f2 = ws[o_f + npad + i]
            f1p = ws[o_f + 2 * npad + i]
            f2p = ws[o_f + 3 * npad + i]
            f1pp = ws[o_f + 4 * npad + i]
            f2pp = ws[o_f + 5 * npad + i]
        else:  # libm's sin and cos of theta where |D| >= 0.6, and what follows from them (the rest as above)
            ci, si, sD, cD = _rotate_mixed(small, D, th, cp, sp)
            f1, f2, f1p, f2p, f1pp, f2pp = chord_funcs(D, sD, cD)
            if bowing:
                if bowrun:
                    bP, bdP, bQ, bdQ = bow_funcs(D, sD, cD)
                    ws[o_bq + i] = bQ
                    ws[o_bdq + i] = bdQ
                else:
                    bP, bdP = bow_p(D, sD, cD)
                ws[o_bp + i] = bP
                ws[o_bdp + i] = bdP
        ws[o_c + i] = ci
        ws[o_s + i] = si
        chx = l_ * (cp * f1 - sp * f2)
        chy = l_ * (sp * f1 + cp * f2)
        ex = l_ * (cp * f1p - sp * f2p)
        ey = l_ * (sp * f1p + cp * f2p)
        ddx = l_ * (cp * f1pp - sp * f2pp)
        ddy = l_ * (sp * f1pp + cp * f2pp)
        ws[o_wx + i] = -chy
        ws[o_wy + i] = chx
        ws[o_ex + i] = ex
        ws[o_ey + i] = ey
        # bias: -wp^2 c + 2 wp Dd e_perp + Dd^2 d2(chord)/dD^2
        ws[o_kx + i] = -wp * wp * chx - 2.0 * wp * Dd * ey + Dd * Dd * ddx
        ws[o_ky + i] = -wp * wp * chy + 2.0 * wp * Dd * ex + Dd * Dd * ddy
        vx = vx - wp * chy + ex * Dd
        vy = vy + wp * chx + ey * Dd
        px += chx
        py += chy
        ws[o_px + i] = px
        ws[o_py + i] = py
        ws[o_vx + i] = vx
        ws[o_vy + i] = vy
        ws[o_fx + i] = -alpha * mb[i] * vx
        ws[o_fy + i] = -mb[i] * g - alpha * mb[i] * vy
        ws[o_fn + i] = -alpha * Jb[i] * w
        ws[o_q + i] = -kap * D
        ws[o_qt + i] = 0.0
        cp = ci
        sp = si
        thp = th
        wp = w
    # ---- cable geometry ----
    ax = -r * math.sin(th0)
    ay = r * math.cos(th0)
    ell = 0.0
    for qq in range(1, ne):
        b = disc[qq - 1] - 1
        bx = ws[o_px + b] - r * ws[o_s + b]
        by = ws[o_py + b] + r * ws[o_c + b]
        dx = bx - ax
        dyy = by - ay
        Lq = vsqrt(dx * dx + dyy * dyy)
        ell += Lq
        base = o_e + 12 * qq
        ws[base + 0] = bx
        ws[base + 1] = by
        ws[base + 2] = dx / Lq
        ws[base + 3] = dyy / Lq
        ws[base + 4] = Lq
        ax = bx
        ay = by
    # ---- bowing between eyelets: compliance H in series with the arm-side cable ----
    # H = bow * sum_e (P(D_e) + Q(D_e) sin^2 c_e), c_e the angle between element e's chord and its run. A run
    # of one element is symmetric (c = 0): H depends on its D alone. Otherwise d H / d c turns the run (forces
    # on its two eyelets) and the element's chord (a force on theta_{e-1} and half of it on D_e).
    hb = 0.0
    if bowing:
        if not bowrun:
            for i in range(n):
                hb += ws[o_bp + i]
                ws[o_bdp + i] *= bow
        else:
            i = 0
            for qq in range(1, ne):
                base = o_e + 12 * qq
                ux = ws[base + 2]
                uy = ws[base + 3]
                gam = 0.0
                while i < disc[qq - 1]:
                    cx = ws[o_wy + i]
                    cy = -ws[o_wx + i]
                    ic = 1.0 / vsqrt(cx * cx + cy * cy)
                    sc = (cx * uy - cy * ux) * ic
                    cc = (cx * ux + cy * uy) * ic
                    hb += ws[o_bp + i] + ws[o_bq + i] * sc * sc
                    ws[o_bdp + i] = bow * (ws[o_bdp + i] + ws[o_bdq + i] * sc * sc)
                    gt = -2.0 * bow * ws[o_bq + i] * sc * cc
                    ws[o_bgt + i] = gt
                    gam -= gt
                    i += 1
                ws[base + 9] = gam / ws[base + 4]  # d H / d gamma_q over the run's length
        hb *= bow
    ws[o_e] = hb  # (eyelet block 0 is free: the guide bears no force) for the implicit step's cable stiffness
    # ---- actuator and tensions ----
    mode = U[I_MODE]
    e1 = 0.0
    lam1 = 0.0
    if mode == 0.0:
        e2 = drive + ell - P[I_ELLREF]
    elif mode == 1.0:
        e2 = P[I_RSP] * y[2 * n] + ell - P[I_ELLREF]
    else:
        e1 = P[I_RSP] * y[2 * n] - y[2 * n + 2] - P[I_S1REF]
        lam1 = select(e1 > 0.0, P[I_K1] * e1, 0.0)
        e2 = y[2 * n + 2] + ell - P[I_ELLREF]
    lam_taut = select(hb == 0.0, P[I_K2] * e2, e2 / (1.0 / P[I_K2] + hb))
    lam2 = lam_taut if U[I_BILAT] != 0.0 else select(e2 > 0.0, lam_taut, 0.0)
    # run tensions (capstan friction at the guide and the eyelets, regularised)
    if U[I_MU] == 0.0 or all_lane(lam2 == 0.0):
        for qq in range(1, ne):
            ws[o_e + 12 * qq + 5] = lam2
    else:  # (a slack lane gets 0 * its friction factors: 0, as above)
        mu = P[I_MU]
        T = lam2
        for qq in range(1, ne):
            b = disc[qq - 1] - 1
            w = y[n + b]
            base = o_e + 12 * qq
            ws[base + 6] = ws[o_vx + b] - r * ws[o_c + b] * w
            ws[base + 7] = ws[o_vy + b] - r * ws[o_s + b] * w
        # the cable slides out through the eyelet before run qq (towards the guide) at the rate at which the
        # runs from qq to the knot shorten: v = -sum_{j >= qq} dL_j/dt (each eyelet's own sliding speed, so
        # the friction only dissipates: sum (T_before - T_after) v >= 0)
        ldot = 0.0
        for qq in range(ne - 1, 0, -1):
            base = o_e + 12 * qq
            evx = ws[base + 6]
            evy = ws[base + 7]
            if qq > 1:
                evx -= ws[base - 12 + 6]
                evy -= ws[base - 12 + 7]
            ldot += ws[base + 2] * evx + ws[base + 3] * evy
            ws[base + 8] = ldot
        tx = math.cos(th0)
        ty = math.sin(th0)
        for qq in range(1, ne):
            base = o_e + 12 * qq
            ux = ws[base + 2]
            uy = ws[base + 3]
            cosb = tx * ux + ty * uy
            cosb = select(cosb > 1.0, 1.0, select(cosb < -1.0, -1.0, cosb))
            sinb = abs(tx * uy - ty * ux)
            wrap = vatan2(sinb, cosb)
            T = T * vexp(-mu * wrap * vtanh(-ws[base + 8] / P[I_V0]))
            ws[base + 5] = T
            tx = ux
            ty = uy
    # eyelet forces and moments
    for qq in range(1, ne):
        b = disc[qq - 1] - 1
        base = o_e + 12 * qq
        Fx = -ws[base + 5] * ws[base + 2]
        Fy = -ws[base + 5] * ws[base + 3]
        if qq + 1 < ne:
            Fx += ws[base + 12 + 5] * ws[base + 12 + 2]
            Fy += ws[base + 12 + 5] * ws[base + 12 + 3]
        ws[o_fx + b] += Fx
        ws[o_fy + b] += Fy
        ws[o_fn + b] += -r * (ws[o_c + b] * Fx + ws[o_s + b] * Fy)
    # bowing: generalised forces (lam2^2 / 2) dH (its potential is -lam2^2 H / 2 at the tension lam2)
    on = (hb != 0.0) & (lam2 != 0.0)
    if bowing and any_lane(on):
        hl = 0.5 * lam2 * lam2
        if not bowrun:
            for i in range(n):
                ws[o_q + i] = select(on, ws[o_q + i] + hl * ws[o_bdp + i], ws[o_q + i])
        else:
            for i in range(n):
                gt = ws[o_bgt + i]
                ws[o_q + i] = select(on, ws[o_q + i] + hl * (ws[o_bdp + i] + 0.5 * gt), ws[o_q + i])
                if i > 0:
                    ws[o_qt + i - 1] = select(on, ws[o_qt + i - 1] + hl * gt, ws[o_qt + i - 1])
            # the runs' directions: d gamma_q = perp_q . (dE_q - dE_{q-1}) / L_q, perp = (-u_y, u_x)
            for qq in range(1, ne):
                b = disc[qq - 1] - 1
                base = o_e + 12 * qq
                g = hl * ws[base + 9]
                Fx = -g * ws[base + 3]
                Fy = g * ws[base + 2]
                if qq + 1 < ne:
                    g = hl * ws[base + 12 + 9]
                    Fx += g * ws[base + 12 + 3]
                    Fy -= g * ws[base + 12 + 2]
                ws[o_fx + b] = select(on, ws[o_fx + b] + Fx, ws[o_fx + b])
                ws[o_fy + b] = select(on, ws[o_fy + b] + Fy, ws[o_fy + b])
                fn = ws[o_fn + b] + -r * (ws[o_c + b] * Fx + ws[o_s + b] * Fy)
                ws[o_fn + b] = select(on, fn, ws[o_fn + b])
    # dashpots on the relative rotation of consecutive discs (clamp = disc 0)
    if U[I_CDISC] != 0.0:
        cd = P[I_CDISC]
        prev_b = 0
        wprev = 0.0
        for k in range(nd):
            b = disc[k]
            tau = -cd * (y[n + b - 1] - wprev)
            for j in range(prev_b, b):
                ws[o_q + j] += tau
            prev_b = b
            wprev = y[n + b - 1]
    # dashpots between disc chords: d_0 = w_1 / 2, d_k = (w_{k+1} - w_{k-1}) / 2 (disc rates, clamp = 0)
    chords = U[I_CCHORD] != 0.0
    if chords:
        cc_ = P[I_CCHORD]
        wm = 0.0
        w0 = y[n + disc[0] - 1]
        ws[o_qt + disc[0] - 1] -= cc_ * 0.25 * w0
        for k in range(1, nd):
            wpk = y[n + disc[k] - 1]
            dk = 0.5 * (wpk - wm)
            ws[o_qt + disc[k] - 1] -= cc_ * 0.5 * dk
            if k >= 2:
                ws[o_qt + disc[k - 2] - 1] += cc_ * 0.5 * dk
            wm = w0
            w0 = wpk
    # constant damping on theta' (the high-mode floor)
    nr = cw.shape[0]
    for k in range(nr):
        acc = 0.0
        for i in range(n):
            acc += W[k, i] * y[n + i]
        acc *= cw[k]
        for i in range(n):
            ws[o_qt + i] -= acc * W[k, i]
    # a force on theta_i acts on every joint j <= i (theta_i = sum_{j <= i} D_j)
    if nr > 0 or chords:
        acc = 0.0
        for i in range(n - 1, -1, -1):
            acc += ws[o_qt + i]
            ws[o_q + i] += acc
    elif bowing and bowrun:
        keep = hb != 0.0
        if any_lane(keep):
            acc = 0.0
            for i in range(n - 1, -1, -1):
                acc += ws[o_qt + i]
                ws[o_q + i] = select(keep, ws[o_q + i] + acc, ws[o_q + i])
    # ---- inward pass ---- (what each body passes to its parent: c.. its articulated inertia, cp. its bias
    # force; 0.0 + x as the parent's accumulator held it, so a -0.0 becomes +0.0 as it did)
    c00 = 0.0
    c01 = 0.0
    c02 = 0.0
    c11 = 0.0
    c12 = 0.0
    c22 = 0.0
    cp0 = 0.0
    cp1 = 0.0
    cp2 = 0.0
    for i in range(n - 1, -1, -1):
        I00 = Jb[i] + c00
        I01 = c01
        I02 = c02
        I11 = mb[i] + c11
        I12 = c12
        I22 = mb[i] + c22
        p0 = -ws[o_fn + i] + cp0
        p1 = -ws[o_fx + i] + cp1
        p2 = -ws[o_fy + i] + cp2
        ex = ws[o_ex + i]
        ey = ws[o_ey + i]
        U0 = I00 + I01 * ex + I02 * ey
        U1 = I01 + I11 * ex + I12 * ey
        U2 = I02 + I12 * ex + I22 * ey
        Dv = U0 + ex * U1 + ey * U2
        uu = ws[o_q + i] - (p0 + ex * p1 + ey * p2)
        ws[o_u + i] = U0
        ws[o_u + n + i] = U1
        ws[o_u + 2 * n + i] = U2
        ws[o_u + 3 * n + i] = 1.0 / Dv
        ws[o_u + 4 * n + i] = uu
        if i > 0:
            iD = 1.0 / Dv
            a00 = I00 - U0 * U0 * iD
            a01 = I01 - U0 * U1 * iD
            a02 = I02 - U0 * U2 * iD
            a11 = I11 - U1 * U1 * iD
            a12 = I12 - U1 * U2 * iD
            a22 = I22 - U2 * U2 * iD
            kx = ws[o_kx + i]
            ky = ws[o_ky + i]
            ud = uu * iD
            q0 = p0 + a01 * kx + a02 * ky + U0 * ud
            q1 = p1 + a11 * kx + a12 * ky + U1 * ud
            q2 = p2 + a12 * kx + a22 * ky + U2 * ud
            wx = ws[o_wx + i]
            wy = ws[o_wy + i]
            Mwx = a11 * wx + a12 * wy
            Mwy = a12 * wx + a22 * wy
            c00 = 0.0 + (a00 + 2.0 * (a01 * wx + a02 * wy) + wx * Mwx + wy * Mwy)
            c01 = 0.0 + (a01 + Mwx)
            c02 = 0.0 + (a02 + Mwy)
            c11 = 0.0 + a11
            c12 = 0.0 + a12
            c22 = 0.0 + a22
            cp0 = 0.0 + (q0 + wx * q1 + wy * q2)
            cp1 = 0.0 + q1
            cp2 = 0.0 + q2
    # ---- outward pass 2: accelerations ----
    A0 = 0.0
    A1 = 0.0
    A2 = 0.0
    for i in range(n):
        b0 = A0
        b1 = A1 + A0 * ws[o_wx + i] + ws[o_kx + i]
        b2 = A2 + A0 * ws[o_wy + i] + ws[o_ky + i]
        dd = (ws[o_u + 4 * n + i] - (ws[o_u + i] * b0 + ws[o_u + n + i] * b1 + ws[o_u + 2 * n + i] * b2)) \
            * ws[o_u + 3 * n + i]  # fmt: skip
        A0 = b0 + dd
        A1 = b1 + ws[o_ex + i] * dd
        A2 = b2 + ws[o_ey + i] * dd
        dy[i] = y[n + i]
        dy[n + i] = A0
    # ---- actuator dynamics ----
    m2 = 2 * n
    if mode == 0.0:
        dy[m2] = 0.0
        dy[m2 + 1] = 0.0
        dy[m2 + 2] = 0.0
        dy[m2 + 3] = 0.0
    else:
        lam_sp = lam2 if mode == 1.0 else lam1
        dy[m2] = y[m2 + 1]
        dy[m2 + 1] = _rotor_acceleration(P, U, drive, y[m2], y[m2 + 1], lam_sp)
        if mode == 2.0:
            dy[m2 + 2] = y[m2 + 3]
            dy[m2 + 3] = (lam1 - lam2 - P[I_CC] * y[m2 + 3]) / P[I_MC]
        else:
            dy[m2 + 2] = 0.0
            dy[m2 + 3] = 0.0
    return e1, e2, lam1, lam2


@njit(cache=True, error_model="numpy", nogil=True)
def rhs(y, drive, P, mb, Jb, disc, W, cw):
    """Allocating wrapper of :func:`rhs_ws` (one scenario): returns ``(dy, e1, e2, lam1, lam2)``."""
    n = mb.shape[0]
    ws = np.empty(N_WS_PER * n + 12 * (disc.shape[0] + 1) + 16 + N_BLOCK_ROWS * (n + BLOCK))
    dy = np.empty(y.shape[0])
    e1, e2, l1, l2 = rhs_ws(y, dy, drive, P, P, mb, Jb, disc, W, cw, ws)
    return dy, e1, e2, l1, l2


@njit(cache=True, error_model="numpy", nogil=True)
def _measured(U, lam1, lam2):
    return lam1 if (U[I_MODE] == 2.0 and U[I_MEAS] == 1.0) else lam2


# ---- the linearly implicit step: the elastic stiffness implicit, everything else explicit ------------------
# A four-stage Rosenbrock-W method built on classical RK4 (docs/virtual_rig.md, section 2). In its usual form
#   (I - gamma h T) k_i = h f(y + sum_j a_ij k_j) + h T sum_j g_ij k_j,   y_1 = y + sum_i b_i k_i,
# with RK4's a_ij and b_i (what T leaves out is integrated as RK4 would), and g_ij, gamma chosen so that the
# method is of third order for *any* T (the W-method conditions up to order 3: sum b_i g_i = 0,
# sum b_i a_ij g_j = 0, sum b_i g_ij c_j = 0, sum b_i g_ij g_j = 0, with g_i = sum_{j<=i} g_ij, c_j = sum_k
# a_jk), L-stable (R(inf) = 0) and A-stable (gamma = 0.44) on what T holds; g_43 = -0.56 gives the smallest
# fourth-order error on test problems. tests/test_integrators.py checks all of it. The kernel runs the
# equivalent form with u_i = sum_{j<=i} g_ij k_j, which needs no product with T:
#   (I - gamma h T) u_i = gamma h f(y + sum_j A_ij u_j) + sum_j E_ij u_j,   y_1 = y + sum_i m_i u_i,
# A = a G^-1, E = -gamma (G^-1 below its diagonal), m = b G^-1 (G the lower-triangular g_ij, gamma on the
# diagonal).
_RW_GAM = 0.44
_RW_G = (
    (0.44, 0.0, 0.0, 0.0),
    (-0.27789473684210519, 0.44, 0.0, 0.0),
    (-0.60376971813419789, -0.43833554502369693, 0.44, 0.0),
    (1.7633289099526062, -1.2033289099526061, -0.56, 0.44),
)
_RW_A = ((0.0, 0.0, 0.0, 0.0), (0.5, 0.0, 0.0, 0.0), (0.0, 0.5, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0))
_RW_B = (1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0)


def _transformed() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``A = a G^-1``, ``E``, ``m = b G^-1`` of the solve-only form.

    Plain float arithmetic, no BLAS: the same bits everywhere.
    """
    gi = [[0.0] * 4 for _ in range(4)]  # G^-1 by forward substitution
    for c in range(4):
        for r in range(c, 4):
            acc = 1.0 if r == c else 0.0
            for k in range(c, r):
                acc -= _RW_G[r][k] * gi[k][c]
            gi[r][c] = acc / _RW_G[r][r]
    a = np.zeros((4, 4))
    e = np.zeros((4, 4))
    m = np.zeros(4)
    for i in range(4):
        for j in range(4):
            acc = 0.0
            for k in range(4):
                acc += _RW_A[i][k] * gi[k][j]
            a[i, j] = acc
            if j < i:
                e[i, j] = -_RW_GAM * gi[i][j]
        acc = 0.0
        for k in range(4):
            acc += _RW_B[k] * gi[k][i]
        m[i] = acc
    return a, e, m


_RW_TA, _RW_TE, _RW_TM = _transformed()

SCHEMES = ("rk4", "rosw")
"""The integrators: classical RK4 (every term explicit), and the Rosenbrock-W step with the elastic stiffness
(bending, cables) implicit (``SCHEME_*`` are their codes in the kernels)."""
SCHEME_RK4 = 0
SCHEME_ROSW = 1
# the implicit step's work array (``wf``), field by field (``F * n + i``): per body ex, ey, wx, wy (the
# joint's motion and the chord's transform), d ell/d D, d ell/d theta, then the factor's U (3), 1/D',
# M'^-1 d ell/dD; then the scalars
(WF_EX, WF_EY, WF_WX, WF_WY, WF_GD, WF_GT, WF_U0, WF_U1, WF_U2, WF_ID, WF_UA) = range(11)
N_WF_BODY = 11
(WS_K1, WS_K2, WS_G1P, WS_G1X, WS_G2P, WS_G2X, WS_JP, WS_JX, WS_S, WS_M11, WS_M12, WS_M21, WS_M22, WS_BETA,
 WS_DET) = range(15)  # fmt: skip
N_WF_SCAL = 16
MAX_SPLITS = 16
"""The implicit step splits a step at up to this many taut/slack transitions, in time order (RK4: at the
first only, as the stored data were made)."""


def wf_size(n: int) -> int:
    """Floats of the implicit step's work array for ``n`` bodies."""
    return N_WF_BODY * n + N_WF_SCAL


@njit(cache=True, error_model="numpy", nogil=True)
def wgeom(P, U, mb, disc, ws, taut1, taut2, wf):
    """Store what ``T`` needs of the state whose right-hand side :func:`rhs_ws` left in ``ws``.

    ``T = [[0, I], [-M^-1 K, 0]]`` in the coordinates ``z = (theta, psi, x_c)``, ``K`` the elastic stiffness:
    the bending springs ``EI/l`` on every ``D_i = theta_i - theta_{i-1}`` (diagonal in the joint
    coordinates), and each taut cable as a spring ``k_j G_j G_j^T`` along the gradient of its stretch: the
    arm side ``G_2 = (d ell/d theta, 0, 1)`` (stepper: ``(d ell/d theta, R)``; ideal: ``d ell/d theta``)
    with ``1/(1/k_2 + H)`` (the bowing's compliance in series), the spool side ``G_1 = (0, R, -1)``, ``k_1``.
    A slack cable (``taut`` False, per lane) has none. Stored: each joint's motion (``ex, ey``), the chord's
    transform (``wx, wy``), the cable's gradient in the joint coordinates (its unit tension's eyelet forces
    summed inwards) and in ``theta``; the actuator's ``G`` and inverse masses; the stiffnesses. Gravity,
    damping, eyelet friction, the tension's geometric stiffness and the bowing's gradients stay explicit (a
    W-method is third order with any ``T``).
    """
    n = mb.shape[0]
    nd = disc.shape[0]
    ne = nd + 1
    r = P[I_R]
    o_e = 40 * n
    pn = 0.0
    px = 0.0
    py = 0.0
    qq = nd
    gnext = 0.0
    for i in range(n - 1, -1, -1):
        ex = ws[4 * n + i]
        ey = ws[5 * n + i]
        wx = ws[2 * n + i]
        wy = ws[3 * n + i]
        wf[WF_EX * n + i] = ex
        wf[WF_EY * n + i] = ey
        wf[WF_WX * n + i] = wx
        wf[WF_WY * n + i] = wy
        if qq >= 1 and disc[qq - 1] - 1 == i:
            base = o_e + 12 * qq
            fx = -ws[base + 2]
            fy = -ws[base + 3]
            if qq + 1 < ne:
                fx += ws[base + 12 + 2]
                fy += ws[base + 12 + 3]
            pn += -r * (ws[i] * fx + ws[n + i] * fy)
            px += fx
            py += fy
            qq -= 1
        g = -(pn + ex * px + ey * py)  # d ell / d D_i: minus the unit tension's force on joint i
        wf[WF_GD * n + i] = g
        wf[WF_GT * n + i] = g - gnext  # d ell / d theta_i
        gnext = g
        pn += wx * px + wy * py
    x = N_WF_BODY * n
    for j in range(N_WF_SCAL):
        wf[x + j] = 0.0
    mode = U[I_MODE]
    k2 = 1.0 / (1.0 / P[I_K2] + ws[o_e])
    wf[x + WS_K2] = k2 if U[I_BILAT] != 0.0 else select(taut2, k2, 0.0)
    R = P[I_RSP]
    if mode == 1.0:
        wf[x + WS_G2P] = R
        wf[x + WS_JP] = 1.0 / P[I_JR]
    elif mode == 2.0:
        wf[x + WS_G1P] = R
        wf[x + WS_G1X] = -1.0
        wf[x + WS_G2X] = 1.0
        wf[x + WS_JP] = 1.0 / P[I_JR]
        wf[x + WS_JX] = 1.0 / P[I_MC]
        wf[x + WS_K1] = select(taut1, P[I_K1], 0.0)


@njit(cache=True, error_model="numpy", nogil=True)
def _asolve(wf, n, tau):
    """``tau <- M'^-1 tau`` for the arm, ``M' = M + beta K_bend`` (:func:`wfactor`'s recursion).

    In: generalised forces on the joints ``D``; out: the absolute angles' response (``theta``).
    """
    c0 = 0.0
    c1 = 0.0
    c2 = 0.0
    for i in range(n - 1, -1, -1):
        uu = tau[i] - (c0 + wf[WF_EX * n + i] * c1 + wf[WF_EY * n + i] * c2)
        tau[i] = uu
        ud = uu * wf[WF_ID * n + i]
        q0 = c0 + wf[WF_U0 * n + i] * ud
        c1 = c1 + wf[WF_U1 * n + i] * ud
        c2 = c2 + wf[WF_U2 * n + i] * ud
        c0 = q0 + wf[WF_WX * n + i] * c1 + wf[WF_WY * n + i] * c2
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    for i in range(n):
        b1 = a1 + a0 * wf[WF_WX * n + i]
        b2 = a2 + a0 * wf[WF_WY * n + i]
        dd = (tau[i] - (wf[WF_U0 * n + i] * a0 + wf[WF_U1 * n + i] * b1 + wf[WF_U2 * n + i] * b2)) \
            * wf[WF_ID * n + i]  # fmt: skip
        a0 = a0 + dd
        a1 = b1 + wf[WF_EX * n + i] * dd
        a2 = b2 + wf[WF_EY * n + i] * dd
        tau[i] = a0


@njit(cache=True, error_model="numpy", nogil=True)
def wfactor(P, mb, Jb, h, wf):
    """Factor ``I - gamma h T`` for the step ``h`` (after :func:`wgeom`).

    ``(I - gamma h T) u = r`` reduces to ``(M + beta K) u_q = M c`` (``beta = (gamma h)^2``,
    ``c = r_q + gamma h r_v``). ``M' = M + beta K_bend`` is what the articulated-body recursion factors when
    each joint's ``D`` gains ``beta EI/l`` (the recursion's inward pass, here, at the stored geometry); the
    cables' rank-one or rank-two part is added by the Woodbury identity: ``M'^-1 G`` (one more pass) and the
    2 x 2 matrix ``I + beta K G^T M'^-1 G``.
    """
    n = mb.shape[0]
    gh = _RW_GAM * h
    beta = gh * gh
    kb = beta * P[I_KAP]
    i00 = 0.0
    i01 = 0.0
    i02 = 0.0
    i11 = 0.0
    i12 = 0.0
    i22 = 0.0
    for i in range(n - 1, -1, -1):
        I00 = Jb[i] + i00
        I11 = mb[i] + i11
        I22 = mb[i] + i22
        ex = wf[WF_EX * n + i]
        ey = wf[WF_EY * n + i]
        U0 = I00 + i01 * ex + i02 * ey
        U1 = i01 + I11 * ex + i12 * ey
        U2 = i02 + i12 * ex + I22 * ey
        iD = 1.0 / (U0 + ex * U1 + ey * U2 + kb)
        wf[WF_U0 * n + i] = U0
        wf[WF_U1 * n + i] = U1
        wf[WF_U2 * n + i] = U2
        wf[WF_ID * n + i] = iD
        wf[WF_UA * n + i] = wf[WF_GD * n + i]
        a00 = I00 - U0 * U0 * iD
        a01 = i01 - U0 * U1 * iD
        a02 = i02 - U0 * U2 * iD
        a11 = I11 - U1 * U1 * iD
        a12 = i12 - U1 * U2 * iD
        a22 = I22 - U2 * U2 * iD
        wx = wf[WF_WX * n + i]
        wy = wf[WF_WY * n + i]
        Mwx = a11 * wx + a12 * wy
        Mwy = a12 * wx + a22 * wy
        i00 = a00 + 2.0 * (a01 * wx + a02 * wy) + wx * Mwx + wy * Mwy
        i01 = a01 + Mwx
        i02 = a02 + Mwy
        i11 = a11
        i12 = a12
        i22 = a22
    ua = wf[WF_UA * n : (WF_UA + 1) * n]
    _asolve(wf, n, ua)
    x = N_WF_BODY * n
    s = 0.0
    for i in range(n):
        s += wf[WF_GT * n + i] * ua[i]
    g1p = wf[x + WS_G1P]
    g1x = wf[x + WS_G1X]
    g2p = wf[x + WS_G2P]
    g2x = wf[x + WS_G2X]
    jp = wf[x + WS_JP]
    jx = wf[x + WS_JX]
    s11 = g1p * g1p * jp + g1x * g1x * jx
    s12 = g1p * g2p * jp + g1x * g2x * jx
    s22 = s + g2p * g2p * jp + g2x * g2x * jx
    K1 = wf[x + WS_K1]
    K2 = wf[x + WS_K2]
    m11 = 1.0 + beta * K1 * s11
    m12 = beta * K1 * s12
    m21 = beta * K2 * s12
    m22 = 1.0 + beta * K2 * s22
    wf[x + WS_S] = s
    wf[x + WS_M11] = m11
    wf[x + WS_M12] = m12
    wf[x + WS_M21] = m21
    wf[x + WS_M22] = m22
    wf[x + WS_BETA] = beta
    wf[x + WS_DET] = 1.0 / (m11 * m22 - m12 * m21)


@njit(cache=True, error_model="numpy", nogil=True)
def _wsolve(P, wf, n, gh, u, tmp):
    """``u <- (I - gh T)^-1 u`` (``tmp``: n floats of work; :func:`wfactor` done for this step).

    Positions ``u_q = c - beta X``, velocities ``u_v = r_v - gh X``, ``X = (M + beta K)^-1 K c``
    (``c = r_q + gh r_v``): ``K c`` is the bending springs' joint forces on ``c`` plus ``G K G^T c``, and
    ``(M' + beta G K G^T)^-1`` follows from ``M'^-1`` (:func:`_asolve`) and ``M'^-1 G`` by Woodbury.
    """
    x = N_WF_BODY * n
    beta = wf[x + WS_BETA]
    kap = P[I_KAP]
    ip = 2 * n
    cp = u[ip] + gh * u[ip + 1]
    cx = u[ip + 2] + gh * u[ip + 3]
    g1p = wf[x + WS_G1P]
    g1x = wf[x + WS_G1X]
    g2p = wf[x + WS_G2P]
    g2x = wf[x + WS_G2X]
    K1 = wf[x + WS_K1]
    K2 = wf[x + WS_K2]
    jp = wf[x + WS_JP]
    jx = wf[x + WS_JX]
    w2 = g2p * cp + g2x * cx
    cprev = 0.0
    for i in range(n):
        c = u[i] + gh * u[n + i]
        w2 += wf[WF_GT * n + i] * c
        tmp[i] = kap * (c - cprev)
        cprev = c
    _asolve(wf, n, tmp)  # M'^-1 of the bending springs' forces
    kw1 = K1 * (g1p * cp + g1x * cx)
    kw2 = K2 * w2
    # M'^-1 K c = tmp + kw2 M'^-1 g (arm), (G K G^T c) / masses (actuator); then G^T of it
    yp = (g1p * kw1 + g2p * kw2) * jp
    yx = (g1x * kw1 + g2x * kw2) * jx
    v2 = g2p * yp + g2x * yx + kw2 * wf[x + WS_S]
    for i in range(n):
        v2 += wf[WF_GT * n + i] * tmp[i]
    v1 = g1p * yp + g1x * yx
    r1 = K1 * v1
    r2 = K2 * v2
    z1 = (r1 * wf[x + WS_M22] - wf[x + WS_M12] * r2) * wf[x + WS_DET]
    z2 = (wf[x + WS_M11] * r2 - wf[x + WS_M21] * r1) * wf[x + WS_DET]
    f2 = kw2 - beta * z2
    for i in range(n):
        X = tmp[i] + f2 * wf[WF_UA * n + i]
        c = u[i] + gh * u[n + i]
        u[n + i] = u[n + i] - gh * X
        u[i] = c - beta * X
    Xp = yp - beta * ((g1p * z1 + g2p * z2) * jp)
    Xx = yx - beta * ((g1x * z1 + g2x * z2) * jx)
    u[ip + 1] = u[ip + 1] - gh * Xp
    u[ip] = cp - beta * Xp
    u[ip + 3] = u[ip + 3] - gh * Xx
    u[ip + 2] = cx - beta * Xx


@njit(cache=True, error_model="numpy", nogil=True)
def _step(scheme, y, k1, h, drive, P, U, mb, Jb, disc, W, cw, ws, wf, bufs, out):  # noqa: C901
    """One step of ``scheme`` from ``y`` (``k1 = f(y)``) over ``h`` into ``out``.

    Classical RK4, or the Rosenbrock-W step (after :func:`wgeom` at ``y``). The three right-hand sides of
    either are evaluated at one call site (one copy of :func:`rhs_ws` in the compiled code).
    """
    m = y.shape[0]
    n = mb.shape[0]
    implicit = scheme == SCHEME_ROSW
    tmp = bufs[7]
    fb = bufs[8]
    wk = bufs[9]
    hh = 0.5 * h
    gh = _RW_GAM * h
    if implicit:
        wfactor(P, mb, Jb, h, wf)
        u1 = bufs[0]
        for i in range(m):
            u1[i] = gh * k1[i]
        _wsolve(P, wf, n, gh, u1, wk)
    for s in range(1, 4):
        # the stage's argument
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
        kout = fb if implicit else bufs[s]  # RK4: k2, k3, k4 in bufs[1..3]
        rhs_ws(tmp, kout, drive, P, U, mb, Jb, disc, W, cw, ws)
        if implicit:
            u = bufs[s]
            for i in range(m):
                acc = gh * fb[i]
                for j in range(s):
                    acc += _RW_TE[s, j] * bufs[j, i]
                u[i] = acc
            _wsolve(P, wf, n, gh, u, wk)
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
def _flip(a0, a1, b0, b1):
    """True if the taut/slack pattern of the two cables changed."""
    return ((a0 > 0.0) != (a1 > 0.0)) or ((b0 > 0.0) != (b1 > 0.0))


@njit(cache=True, error_model="numpy", nogil=True)
def _filter(tau, y, h, x0, x1):
    """Low-pass ``tau y' = x - y`` over ``h`` for an input linear from ``x0`` to ``x1``: the new ``y``."""
    if tau <= 0.0:
        return x1
    a = math.exp(-h / tau)
    return a * (y - x0) + x1 - (x1 - x0) * (tau / h) * (1.0 - a)


# the driver's state of each lane, one row of ``S`` per quantity (lanes along it): the shared rows
# (:mod:`helpers.virtual._driver`), then what persists between calls here (drive, its increment, the
# amplifier's output, the largest rotor lag) and the present step's start (its transition functions); integers
# in ``L[lane]``
(S_T, S_HMAX, S_TAU, S_NSTEP, S_NTRANS, S_TARGET, S_H, S_REM, S_FLO, S_FHI, S_LO, S_HI, S_HC, S_HSTEP, S_FH,
 S_FA, S_ACTIVE, S_LEFT, S_SPLITS, S_SEARCH, S_GEOM, S_COMMIT, S_FULL, S_PEND) = range(N_DRIVER)  # fmt: skip
(S_DRIVE, S_DDRIVE, S_FILT, S_HEALTH, S_R0, S_R1) = range(N_DRIVER, N_DRIVER + 6)
N_STATE = N_DRIVER + 6
"""Rows of the driver's float state (:func:`advance`): the work rows are ``D_PERSIST .. N_DRIVER - 1``,
``S_R0``, ``S_R1``; the others carry over from one call to the next."""
L_USE1 = N_DRIVER_INTS
N_LANE_INTS = N_DRIVER_INTS + 1


@njit(cache=True, error_model="numpy", nogil=True)
def _start_steps(S, mask, implicit, mode2, st):
    """The lanes of ``mask`` begin a step of their piece's size from their present state."""
    start_steps(S, mask, implicit)
    S[S_R0] = select(mask, st[0] if mode2 else 1.0, S[S_R0])
    S[S_R1] = select(mask, st[1], S[S_R1])


@njit(cache=True, error_model="numpy", nogil=True)
def _events(S, L, k, y, st, U, sample_times, step_times, step_signs, n_steps, out_raw, out_filt, out_theta,
            implicit, mode2):  # fmt: skip
    """Lane ``k`` has reached its target: record the sample or apply the step, then aim at the next target.

    Stops at a step (its right-hand side must be evaluated again with the new drive: ``S_PEND``), at the
    first piece with steps to take, or when the last sample is recorded (the lane goes idle).
    """
    n = out_theta.shape[2]
    while True:
        if arrive(S, L, k):
            if L[k, L_TOSTEP] != 0:
                js = L[k, L_JS]
                drive = lane(S[S_DRIVE], k) + lane(S[S_DDRIVE], k) * step_signs[k, js]
                S[S_DRIVE] = set_lane(S[S_DRIVE], k, drive)
                L[k, L_JS] = js + 1
                S[S_PEND] = set_lane(S[S_PEND], k, 1.0)
                return
            qi = L[k, L_QI]
            out_raw[k, qi] = lane(_measured(U, st[2], st[3]), k)
            out_filt[k, qi] = lane(S[S_FILT], k)
            for i in range(n):
                out_theta[k, qi, i] = lane(y[i], k)
            L[k, L_QI] = qi + 1
        if not aim(S, L, k, sample_times, step_times, n_steps):
            return


@njit(cache=True, error_model="numpy", nogil=True)
def _decide(S, L, k, e1n, e2n, x0, x1, implicit, mode2, cap):
    """Lane ``k`` after a trial step that is not simply accepted: the first sign of a transition, or a search.

    A transition starts the search for it (:func:`~helpers.virtual._driver.search_step`). The search ends at
    the transition, which becomes the state (``S_COMMIT``, the step not complete: ``S_FULL`` 0), the rest of
    the step to follow on the branch just crossed into; otherwise the next trial's size is ``S_HSTEP``.
    ``x0``, ``x1``: the measured tension at the piece's start and at the trial's end.
    """
    if lane(S[S_SEARCH], k) == 0.0:
        r0 = lane(S[S_R0], k)
        r1 = lane(S[S_R1], k)
        a1 = e1n if mode2 else 1.0
        flip1 = (r0 > 0.0) != (a1 > 0.0)
        flip2 = (r1 > 0.0) != (e2n > 0.0)
        if implicit and flip1 and flip2:  # both: the one that comes first on the chord
            use1 = r0 / (r0 - a1) <= r1 / (r1 - e2n)
        else:
            use1 = mode2 and flip1
        L[k, L_USE1] = 1 if use1 else 0
        begin_search(S, L, k, r0 if use1 else r1, a1 if use1 else e2n)
        return
    use1 = L[k, L_USE1] != 0
    found, hc, f_hi = search_step(S, L, k, e1n if use1 else e2n)
    if found:
        # to the transition (the search's last point); the rest of the step from there, on the branch just
        # crossed into
        S[S_FILT] = set_lane(S[S_FILT], k, _filter(lane(S[S_TAU], k), lane(S[S_FILT], k), hc, x0, x1))
        r0 = e1n if mode2 else 1.0
        r1 = e2n
        if use1 and (r0 > 0.0) != (f_hi > 0.0):  # at the kink: count it as crossed
            r0 = 1e-300 if f_hi > 0.0 else -1e-300
        if not use1 and (r1 > 0.0) != (f_hi > 0.0):
            r1 = 1e-300 if f_hi > 0.0 else -1e-300
        S[S_R0] = set_lane(S[S_R0], k, r0)
        S[S_R1] = set_lane(S[S_R1], k, r1)
        split(S, k, hc, implicit)


@njit(cache=True, error_model="numpy", nogil=True)
def _accept(S, accept, x0, x1):
    """The amplifier's output over the accepted steps (``S_REM`` each): :func:`_filter`, lanes at once."""
    a, h, tau = filter_gain(S, accept)
    y = a * (S[S_FILT] - x0) + x1 - (x1 - x0) * (tau / h) * (1.0 - a)
    S[S_FILT] = select(accept, select(tau <= 0.0, x1, y), S[S_FILT])


@njit(cache=True, error_model="numpy", nogil=True)
def advance(scheme, y, S, L, sample_times, step_times, step_signs, n_steps, P, U, mb, Jb, disc, W, cw,  # noqa: C901
            k1, st, ws, ws2, wf, wf2, bufs, out_raw, out_filt, out_theta):  # fmt: skip
    """Advance every lane's ``y`` from its time ``S[S_T]`` through its sample times with ``scheme``.

    One scenario (scalars) or several (lanes: one per scenario, the arrays of :func:`rhs_ws` and ``y``,
    ``S``, ``k1``, ``st``, ``ws``, ``ws2``, ``wf``, ``wf2``, ``bufs`` as lane arrays). Each lane takes equal
    steps ``<= S[S_HMAX]`` between its events (its stepper steps and its samples); a step across which a
    cable changes between taut and slack is split at the transition (Illinois method on the step size), so
    no step straddles the kink of ``max(0, .)``; with the implicit step (``SCHEME_ROSW``) each piece's cable
    stiffness ``T`` (:func:`wfactor`) is that of the branch it lies on. Every lane takes exactly the steps it
    takes alone: each pass of the loop below is one trial step of every lane (of its own size) and one
    right-hand side at its end, then each lane's own decision (accept, split, search, its next event), so a
    lane's arithmetic does not depend on the others.

    The drive (cable displacement or commanded rotor angle) jumps by ``S[S_DDRIVE] * sign`` at each step
    time; a step at exactly a sample time is applied before that sample. At each sample the measured
    tension (raw and through the amplifier, ``S[S_TAU]``, ``S[S_FILT]``: the low-pass integrated exactly for
    a tension linear over each step) and the node angles are written into ``out_*[lane]``. ``S[S_NSTEP]``,
    ``S[S_NTRANS]`` count steps and transitions, ``S[S_HEALTH]`` is the largest rotor lag ``|psi_cmd - psi|``
    seen (rad).

    Parameters (besides :func:`rhs_ws`'s)
    -------------------------------------
    sample_times : float64[lanes, samples]
        Strictly increasing, after ``S[S_T]``.
    step_times, step_signs : float64[lanes, steps]
        Each lane's stepper steps (its first ``n_steps[lane]``), sorted.
    L : int64[lanes, N_LANE_INTS]
        Work.
    k1, st, ws, ws2, wf, wf2, bufs
        Work: ``m``, 4, :func:`workspace_size` (twice), :func:`wf_size` (twice), ``(10, m)``.
    """
    # Each lane array enters as its own numba type (``LaneArray``); its full slice is a plain array of
    # lanes, the type of every row taken from one inside (``bufs[4]``). Passing only plain arrays down
    # compiles each function once per form (scalars, lanes) instead of once per mix of the two types: the
    # lanes' first compile costs about half. The same arrays, the same arithmetic.
    _advance(scheme, y[:], S[:], L, sample_times, step_times, step_signs, n_steps, P[:], U, mb[:], Jb[:],
             disc, W[:], cw[:], k1[:], st[:], ws[:], ws2[:], wf[:], wf2[:], bufs[:], out_raw, out_filt,
             out_theta)  # fmt: skip


@njit(cache=True, error_model="numpy", nogil=True)
def _advance(scheme, y, S, L, sample_times, step_times, step_signs, n_steps, P, U, mb, Jb, disc, W, cw,  # noqa: C901
             k1, st, ws, ws2, wf, wf2, bufs, out_raw, out_filt, out_theta):  # fmt: skip
    """:func:`advance` on plain arrays (of scalars or of lanes)."""
    nl = L.shape[0]
    n = mb.shape[0]
    m = y.shape[0]
    nws = ws.shape[0]
    nwf = wf.shape[0]
    implicit = scheme == SCHEME_ROSW
    mode2 = U[I_MODE] == 2.0
    lagging = U[I_MODE] != 0.0
    cap = MAX_SPLITS if implicit else 1
    y1 = bufs[4]
    k1e = bufs[5]
    k1n = bufs[6]
    e1, e2, l1, l2 = rhs_ws(y, k1, S[S_DRIVE], P, U, mb, Jb, disc, W, cw, ws)
    st[0] = e1
    st[1] = e2
    st[2] = l1
    st[3] = l2
    begin(S, L)
    S[S_R0] = 0.0
    S[S_R1] = 0.0
    pending = True  # lanes to move on to their next event
    while True:
        if pending:
            # the events of lanes that reached their targets; a step there evaluates the right-hand side
            # again with the new drive (in its lanes only)
            waiting = (S[S_ACTIVE] != 0.0) & (S[S_LEFT] == 0.0)
            while True:
                ready = (S[S_ACTIVE] != 0.0) & (S[S_LEFT] == 0.0)
                for k in range(nl):
                    if lane(ready, k):
                        _events(S, L, k, y, st, U, sample_times, step_times, step_signs, n_steps, out_raw,
                                out_filt, out_theta, implicit, mode2)  # fmt: skip
                pend = S[S_PEND] != 0.0
                if not any_lane(pend):
                    break
                if all_lane(pend):
                    e1, e2, l1, l2 = rhs_ws(y, k1, S[S_DRIVE], P, U, mb, Jb, disc, W, cw, ws)
                else:
                    e1, e2, l1, l2 = rhs_ws(y, k1e, S[S_DRIVE], P, U, mb, Jb, disc, W, cw, ws2)
                    blend(pend, k1, k1e, m)
                    blend(pend, ws, ws2, nws)
                st[0] = select(pend, e1, st[0])
                st[1] = select(pend, e2, st[1])
                st[2] = select(pend, l1, st[2])
                st[3] = select(pend, l2, st[3])
                S[S_FILT] = select(pend & (S[S_TAU] <= 0.0), _measured(U, l1, l2), S[S_FILT])
                S[S_PEND] = 0.0
            started = waiting & (S[S_ACTIVE] != 0.0) & (S[S_LEFT] > 0.0)
            _start_steps(S, started, implicit, mode2, st)
            pending = False
        active = S[S_ACTIVE] != 0.0
        if not any_lane(active):
            break
        # one trial step of every lane (idle lanes repeat a harmless step that nothing keeps)
        if implicit:
            geom = S[S_GEOM] != 0.0
            if all_lane(geom):
                wgeom(P, U, mb, disc, ws, S[S_R0] > 0.0, S[S_R1] > 0.0, wf)
            elif any_lane(geom):
                wgeom(P, U, mb, disc, ws, S[S_R0] > 0.0, S[S_R1] > 0.0, wf2)
                blend(geom, wf, wf2, nwf)
            S[S_GEOM] = 0.0
        _step(scheme, y, k1, S[S_HSTEP], S[S_DRIVE], P, U, mb, Jb, disc, W, cw, ws, wf, bufs, y1)
        e1n, e2n, l1n, l2n = rhs_ws(y1, k1n, S[S_DRIVE], P, U, mb, Jb, disc, W, cw, ws)
        S[S_NSTEP] = select(active, S[S_NSTEP] + 1.0, S[S_NSTEP])
        x0 = _measured(U, st[2], st[3])
        x1 = _measured(U, l1n, l2n)
        # the trial accepted where no cable changed between taut and slack (or no more splits are allowed)
        flip = (S[S_R1] > 0.0) ^ (e2n > 0.0)
        if mode2:
            flip = flip | ((S[S_R0] > 0.0) ^ (e1n > 0.0))
        search = S[S_SEARCH] != 0.0
        accept = active & lnot(search) & ((S[S_SPLITS] >= cap) | lnot(flip))
        _accept(S, accept, x0, x1)
        S[S_COMMIT] = select(accept, 1.0, 0.0)
        S[S_FULL] = S[S_COMMIT]
        other = active & lnot(accept)
        if any_lane(other):
            for k in range(nl):
                if lane(other, k):
                    e1k, e2k = lane(e1n, k), lane(e2n, k)
                    _decide(S, L, k, e1k, e2k, lane(x0, k), lane(x1, k), implicit, mode2, cap)
        commit = S[S_COMMIT] != 0.0
        if any_lane(commit):
            blend(commit, y, y1, m)
            blend(commit, k1, k1n, m)
            st[0] = select(commit, e1n, st[0])
            st[1] = select(commit, e2n, st[1])
            st[2] = select(commit, l1n, st[2])
            st[3] = select(commit, l2n, st[3])
        full = S[S_FULL] != 0.0
        if any_lane(full):
            if lagging:
                lag = abs(S[S_DRIVE] - y[2 * n])
                S[S_HEALTH] = select(full & (lag > S[S_HEALTH]), lag, S[S_HEALTH])
            S[S_LEFT] = select(full, S[S_LEFT] - 1.0, S[S_LEFT])
            _start_steps(S, full & (S[S_LEFT] > 0.0), implicit, mode2, st)
            pending = any_lane(full & (S[S_LEFT] == 0.0))


class Work(NamedTuple):
    """Work arrays of :func:`advance` (one set per plant, reused by every call)."""

    k1: Any
    st: Any
    ws: Any
    ws2: Any
    wf: Any
    wf2: Any
    bufs: Any


def make_work(n: int, n_eye: int, lanes: int = 0) -> Work:
    """:func:`advance`'s work arrays for ``n`` bodies and ``n_eye`` eyelets: scalars, or ``lanes`` lanes."""
    m = 2 * n + 4
    shapes = ((m,), (4,), (workspace_size(n, n_eye + 1),), (workspace_size(n, n_eye + 1),), (wf_size(n),),
              (wf_size(n),), (10, m))  # fmt: skip
    if lanes == 0:
        return Work(*(np.zeros(s) for s in shapes))
    return Work(*(LaneArray(np.zeros((*s, lanes))) for s in shapes))
