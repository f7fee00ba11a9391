"""Compiled (numba) right-hand side and fixed-step integrator of the arm: the fast path of the plant.

Coordinates: the *absolute* angles ``phi_i`` of the rigid segments (i = 0..N-1, zero-based) and their rates.
Node ``j`` (0 = clamp) is at ``p_j = sum_{i<j} l (cos phi_i, sin phi_i)``; segment ``i`` runs from node ``i``
to node ``i + 1`` and its joint spring sits at node ``i`` (relative angle ``phi_i - phi_{i-1}``,
``phi_{-1}`` = the base angle). An eyelet at node ``j`` belongs to segment ``j - 1`` (the clamp plate for
``j = 0``) and sits at ``p_j + r n_j`` with ``n = (-sin phi, cos phi)``.

Packed parameters ``P`` (floats): ``l, r, phi0, g, alpha, k, ell_ref, j_seg, bilateral``
(``bilateral`` = 1 lets the cable push: only for linearising about a just-taut cable); arrays ``mu`` (mass at
and
beyond node i + 1), ``kap`` (joint stiffness), ``cj`` (joint damping), ``eye`` (eyelet nodes).

Equations (Lagrange, point masses at the nodes, rod inertia correction ``j_seg`` per segment)::

    M(phi) phi'' + C(phi, phi') = Q_spring + Q_damp + Q_gravity - alpha M phi' - lambda d ell / d phi
    M_ik = l^2 mu_max(i,k) cos(phi_i - phi_k) + j_seg delta_ik
    C_i  = sum_k l^2 mu_max(i,k) sin(phi_i - phi_k) phi_k'^2
    lambda = k max(0, u + ell(phi) - ell_ref)
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

I_L, I_R, I_PHI0, I_G, I_ALPHA, I_K, I_ELLREF, I_JSEG, I_BILATERAL = range(9)
N_PACKED = 9


@njit(cache=True, error_model="numpy")
def cable_length(phi, P, eye):  # noqa: D103 - see module docstring
    return cable_length_ws(phi, P, eye, np.empty(2 * phi.shape[0] + 2))


@njit(cache=True, error_model="numpy")
def cable_length_ws(phi, P, eye, ws):
    """Cable path length through the eyelets (``ws``: at least 2 n + 2 floats)."""
    l_ = P[I_L]
    r = P[I_R]
    n = phi.shape[0]
    px = ws[: n + 1]
    py = ws[n + 1 : 2 * n + 2]
    px[0] = 0.0
    py[0] = 0.0
    for i in range(n):
        px[i + 1] = px[i] + l_ * math.cos(phi[i])
        py[i + 1] = py[i] + l_ * math.sin(phi[i])
    total = 0.0
    ang = P[I_PHI0]
    ax = px[0] - r * math.sin(ang)
    ay = py[0] + r * math.cos(ang)
    for q in range(1, eye.shape[0]):
        b = eye[q]
        ang = phi[b - 1]
        bx = px[b] - r * math.sin(ang)
        by = py[b] + r * math.cos(ang)
        total += math.sqrt((bx - ax) ** 2 + (by - ay) ** 2)
        ax = bx
        ay = by
    return total


@njit(cache=True, error_model="numpy")
def cable_length_grad(phi, P, eye, grad):
    """Cable path length through the eyelets and its gradient (written into ``grad``) w.r.t. ``phi``."""
    n = phi.shape[0]
    ws = np.empty(4 * n + 2)
    return cable_length_grad_ws(phi, P, eye, grad, ws)


@njit(cache=True, error_model="numpy")
def cable_length_grad_ws(phi, P, eye, grad, ws):
    """As :func:`cable_length_grad`, with a work array of at least ``4 n + 2`` floats."""
    n = phi.shape[0]
    c = ws[:n]
    s = ws[n : 2 * n]
    for i in range(n):
        c[i] = math.cos(phi[i])
        s[i] = math.sin(phi[i])
    return cable_grad_cs(c, s, P, eye, grad, ws[2 * n :])


@njit(cache=True, error_model="numpy")
def cable_grad_cs(c, s, P, eye, grad, ws):
    """Cable length and gradient from the segments' cosines ``c`` and sines ``s`` (``ws``: 2 n + 2 floats)."""
    l_ = P[I_L]
    r = P[I_R]
    n = c.shape[0]
    px = ws[: n + 1]
    py = ws[n + 1 : 2 * n + 2]
    px[0] = 0.0
    py[0] = 0.0
    for i in range(n):
        px[i + 1] = px[i] + l_ * c[i]
        py[i + 1] = py[i] + l_ * s[i]
        grad[i] = 0.0
    total = 0.0
    ang = P[I_PHI0]
    ax = px[0] - r * math.sin(ang)
    ay = py[0] + r * math.cos(ang)
    for q in range(1, eye.shape[0]):
        a = eye[q - 1]
        b = eye[q]
        bx = px[b] - r * s[b - 1]
        by = py[b] + r * c[b - 1]
        dx = bx - ax
        dy = by - ay
        dist = math.sqrt(dx * dx + dy * dy)
        total += dist
        inv = 1.0 / dist
        ux = dx * inv
        uy = dy * inv
        for i in range(a, b):
            # rotating segment i translates everything distal to node i + 1 by l n_i
            grad[i] += l_ * (-ux * s[i] + uy * c[i])
        # the eyelet at node b turns with segment b - 1: d(r n)/d phi = -r t
        grad[b - 1] -= r * (ux * c[b - 1] + uy * s[b - 1])
        if a >= 1:
            grad[a - 1] += r * (ux * c[a - 1] + uy * s[a - 1])
        ax = bx
        ay = by
    return total


@njit(cache=True, error_model="numpy")
def tension_of(phi, u, P, eye):  # noqa: D103
    e = u + cable_length(phi, P, eye) - P[I_ELLREF]
    return P[I_K] * e if e > 0.0 else 0.0


@njit(cache=True, error_model="numpy")
def stretch_of(phi, u, P, eye):  # noqa: D103
    return u + cable_length(phi, P, eye) - P[I_ELLREF]


@njit(cache=True, error_model="numpy")
def rhs(y, u, P, mu, kap, cj, eye, dy):
    """Write d/dt of the state ``y = [phi, omega]`` into ``dy``; return the cable tension."""
    n = mu.shape[0]
    ws = np.empty(workspace_size(n))
    return rhs_ws(y, u, P, mu, kap, cj, eye, dy, ws)


@njit(cache=True, error_model="numpy")
def rhs_dense(y, u, P, mu, kap, cj, eye, dy):
    """Allocating wrapper of :func:`rhs_dense_ws`."""
    n = mu.shape[0]
    ws = np.empty(workspace_size(n))
    return rhs_dense_ws(y, u, P, mu, kap, cj, eye, dy, ws)


@njit(cache=True, error_model="numpy")
def workspace_size(n):  # noqa: D103
    return n * n + 12 * n + 2


@njit(cache=True, error_model="numpy")
def rhs_dense_ws(y, u, P, mu, kap, cj, eye, dy, ws):
    """The same right-hand side through the dense mass matrix and a Cholesky solve (O(n^3)).

    Kept as an independent check of the recursive :func:`rhs_ws` (tests compare the two).
    """
    n = mu.shape[0]
    l_ = P[I_L]
    l2 = l_ * l_
    g = P[I_G]
    alpha = P[I_ALPHA]
    jseg = P[I_JSEG]
    phi = y[:n]
    w = y[n:]
    M = ws[: n * n].reshape((n, n))
    c = ws[n * n : n * n + n]
    s = ws[n * n + n : n * n + 2 * n]
    rhs_ = ws[n * n + 2 * n : n * n + 3 * n]
    taus = ws[n * n + 3 * n : n * n + 4 * n]
    grad = ws[n * n + 4 * n : n * n + 5 * n]
    ws2 = ws[n * n + 5 * n :]
    for i in range(n):
        c[i] = math.cos(phi[i])
        s[i] = math.sin(phi[i])
    for i in range(n):
        M[i, i] = l2 * mu[i] + jseg
        for k in range(i + 1, n):
            v = l2 * mu[k] * (c[i] * c[k] + s[i] * s[k])
            M[i, k] = v
            M[k, i] = v
    # Coriolis/centrifugal terms, gravity
    for i in range(n):
        acc = 0.0
        for k in range(n):
            if k != i:
                m_ = mu[k] if k > i else mu[i]
                acc += l2 * m_ * (s[i] * c[k] - c[i] * s[k]) * w[k] * w[k]
        rhs_[i] = -acc - g * l_ * mu[i] * c[i]
    # joint springs and dashpots
    prev_phi = P[I_PHI0]
    prev_w = 0.0
    tau_next = 0.0
    for i in range(n):
        taus[i] = kap[i] * (phi[i] - prev_phi) + cj[i] * (w[i] - prev_w)
        prev_phi = phi[i]
        prev_w = w[i]
    for i in range(n - 1, -1, -1):
        rhs_[i] += -taus[i] + tau_next
        tau_next = taus[i]
    # air-drag-like mass-proportional damping
    if alpha != 0.0:
        for i in range(n):
            acc = 0.0
            for k in range(n):
                acc += M[i, k] * w[k]
            rhs_[i] -= alpha * acc
    # cable
    ell = cable_grad_cs(c, s, P, eye, grad, ws2)
    e = u + ell - P[I_ELLREF]
    lam = P[I_K] * e if (e > 0.0 or P[I_BILATERAL] != 0.0) else 0.0
    if lam != 0.0:
        for i in range(n):
            rhs_[i] -= lam * grad[i]
    # Cholesky solve M a = rhs_ (M is symmetric positive definite)
    for j in range(n):
        d = M[j, j]
        for k in range(j):
            d -= M[j, k] * M[j, k]
        d = math.sqrt(d)
        M[j, j] = d
        for i in range(j + 1, n):
            v = M[i, j]
            for k in range(j):
                v -= M[i, k] * M[j, k]
            M[i, j] = v / d
    for i in range(n):
        v = rhs_[i]
        for k in range(i):
            v -= M[i, k] * rhs_[k]
        rhs_[i] = v / M[i, i]
    for i in range(n - 1, -1, -1):
        v = rhs_[i]
        for k in range(i + 1, n):
            v -= M[k, i] * rhs_[k]
        rhs_[i] = v / M[i, i]
    for i in range(n):
        dy[i] = w[i]
        dy[n + i] = rhs_[i]
    return lam


@njit(cache=True, error_model="numpy")
def rhs_ws(y, u, P, mu, kap, cj, eye, dy, ws):
    """As :func:`rhs`, with a work array of :func:`workspace_size` floats.

    Solves ``M phi'' = Q - C`` in O(n) by the articulated-body recursion of a planar chain of point masses:
    with ``R_i`` the total inertial force ``sum_{j >= i} m_j a_j`` of the chain distal to link ``i``, the
    equation of ``phi_i`` reads ``J phi_i'' + l n_i . R_i = Q_i``, and ``R_i = K_i a_{i-1} + r_i`` is affine
    in the acceleration ``a_{i-1}`` of the link's proximal node. An inward pass builds ``K_i`` (2 x 2, the
    articulated mass) and ``r_i``; an outward pass from the clamp (``a = 0``) gives ``phi''``.
    Mass-proportional damping ``alpha M phi'`` contributes exactly ``-alpha phi'`` to ``phi''``.
    (A thin wrapper of :func:`rhs_rows`, the form the integrator calls.)
    """
    m = y.shape[0]
    S = np.empty((2, m))
    for i in range(m):
        S[0, i] = y[i]
    e = rhs_rows(S, 0, 1, u, P, mu, kap, cj, eye, ws)
    for i in range(m):
        dy[i] = S[1, i]
    return P[I_K] * e if (e > 0.0 or P[I_BILATERAL] != 0.0) else 0.0


@njit(cache=True, error_model="numpy")
def rhs_rows(S, iy, idy, u, P, mu, kap, cj, eye, ws):
    """The right-hand side of :func:`rhs_ws` from row ``iy`` of ``S`` into row ``idy``; returns the stretch.

    The stretch ``u + ell - ell_ref`` serves the integrator both for the taut/slack test and for the sampled
    tension, so the cable geometry is evaluated once per state. Hot path: the state vectors are rows of one
    2-D array and the work array is indexed by offsets (``ws``: :func:`workspace_size` floats), because
    every array slice costs an atomic reference count in numba; the cable geometry is that of
    :func:`cable_grad_cs`, written out here.
    """
    n = mu.shape[0]
    l_ = P[I_L]
    l2 = l_ * l_
    r = P[I_R]
    g = P[I_G]
    jseg = P[I_JSEG]
    alpha = P[I_ALPHA]
    # ws layout: c 0, s n, q 2n, grad 3n, p00 4n, p01 5n, p11 6n, wx 7n, wy 8n, 1/d 9n
    o_s = n
    o_q = 2 * n
    o_g = 3 * n
    o_00 = 4 * n
    o_01 = 5 * n
    o_11 = 6 * n
    o_wx = 7 * n
    o_wy = 8 * n
    o_d = 9 * n
    # sines and cosines; generalised forces of the joint springs and dashpots and of gravity
    prev_phi = P[I_PHI0]
    prev_w = 0.0
    q_prev = 0.0
    for i in range(n):
        ph = S[iy, i]
        wi = S[iy, n + i]
        ci = math.cos(ph)
        ws[i] = ci
        ws[o_s + i] = math.sin(ph)
        tau = kap[i] * (ph - prev_phi) + cj[i] * (wi - prev_w)
        if i > 0:
            ws[o_q + i - 1] = q_prev + tau
        q_prev = -tau - g * l_ * mu[i] * ci
        prev_phi = ph
        prev_w = wi
        ws[o_g + i] = 0.0
    ws[o_q + n - 1] = q_prev
    # cable: straight runs between eyelets, the arithmetic of cable_grad_cs with the gradient of each
    # run's last segment kept in a register until the next run adds its share (eyelet nodes strictly
    # increasing from 0, as RigParameters.eyelet_nodes makes them)
    px = 0.0
    py = 0.0
    j = 0
    ell = 0.0
    ang = P[I_PHI0]
    ax = -r * math.sin(ang)
    ay = r * math.cos(ang)
    pend = 0.0
    b = 0
    for qq in range(1, eye.shape[0]):
        a = eye[qq - 1]
        b = eye[qq]
        while j < b:
            px += l_ * ws[j]
            py += l_ * ws[o_s + j]
            j += 1
        cb = ws[b - 1]
        sb = ws[o_s + b - 1]
        bx = px - r * sb
        by = py + r * cb
        dx = bx - ax
        dy = by - ay
        dist = math.sqrt(dx * dx + dy * dy)
        ell += dist
        inv = 1.0 / dist
        ux = dx * inv
        uy = dy * inv
        if a >= 1:
            ws[o_g + a - 1] = pend + r * (ux * ws[a - 1] + uy * ws[o_s + a - 1])
        for i in range(a, b - 1):
            ws[o_g + i] = l_ * (-ux * ws[o_s + i] + uy * ws[i])
        pend = l_ * (-ux * sb + uy * cb) - r * (ux * cb + uy * sb)
        ax = bx
        ay = by
    if b >= 1:
        ws[o_g + b - 1] = pend
    e = u + ell - P[I_ELLREF]
    lam = P[I_K] * e if (e > 0.0 or P[I_BILATERAL] != 0.0) else 0.0
    if lam != 0.0:
        for i in range(n):
            ws[o_q + i] -= lam * ws[o_g + i]
    # inward pass
    k00 = 0.0
    k01 = 0.0
    k11 = 0.0
    rx = 0.0
    ry = 0.0
    m_next = 0.0
    for i in range(n - 1, -1, -1):
        m_i = mu[i] - m_next
        m_next = mu[i]
        a00 = m_i + k00
        a01 = k01
        a11 = m_i + k11
        nx = -ws[o_s + i]
        ny = ws[i]
        wi = S[iy, n + i]
        lw2 = l_ * wi * wi
        bx = -lw2 * ny
        by = lw2 * nx
        pnx = a00 * nx + a01 * ny
        pny = a01 * nx + a11 * ny
        invd = 1.0 / (jseg + l2 * (nx * pnx + ny * pny))
        vx = a00 * bx + a01 * by + rx
        vy = a01 * bx + a11 * by + ry
        ws[o_00 + i] = a00
        ws[o_01 + i] = a01
        ws[o_11 + i] = a11
        ws[o_wx + i] = vx
        ws[o_wy + i] = vy
        ws[o_d + i] = invd
        # (products grouped so that they run alongside the division)
        k00 = a00 - (l2 * pnx * pnx) * invd
        k01 = a01 - (l2 * pnx * pny) * invd
        k11 = a11 - (l2 * pny * pny) * invd
        coef = l_ * (ws[o_q + i] - l_ * (nx * vx + ny * vy)) * invd
        rx = vx + coef * pnx
        ry = vy + coef * pny
    # outward pass
    ax = 0.0
    ay = 0.0
    for i in range(n):
        nx = -ws[o_s + i]
        ny = ws[i]
        wi = S[iy, n + i]
        fx = ws[o_00 + i] * ax + ws[o_01 + i] * ay + ws[o_wx + i]
        fy = ws[o_01 + i] * ax + ws[o_11 + i] * ay + ws[o_wy + i]
        acc = (ws[o_q + i] - l_ * (nx * fx + ny * fy)) * ws[o_d + i]
        lw2 = l_ * wi * wi
        ax += l_ * nx * acc - lw2 * ny
        ay += l_ * ny * acc + lw2 * nx
        S[idy, i] = wi
        S[idy, n + i] = acc - alpha * wi
    return e


@njit(cache=True, error_model="numpy")
def stretch_row(S, iy, u, P, eye):
    """Cable stretch ``u + ell - ell_ref`` of the state in row ``iy`` of ``S`` (as :func:`rhs_rows`)."""
    l_ = P[I_L]
    r = P[I_R]
    px = 0.0
    py = 0.0
    j = 0
    ell = 0.0
    ang = P[I_PHI0]
    ax = -r * math.sin(ang)
    ay = r * math.cos(ang)
    for qq in range(1, eye.shape[0]):
        b = eye[qq]
        while j < b:
            px += l_ * math.cos(S[iy, j])
            py += l_ * math.sin(S[iy, j])
            j += 1
        ang = S[iy, b - 1]
        bx = px - r * math.sin(ang)
        by = py + r * math.cos(ang)
        dx = bx - ax
        dy = by - ay
        ell += math.sqrt(dx * dx + dy * dy)
        ax = bx
        ay = by
    return u + ell - P[I_ELLREF]


# rows of the integrator's state array (see advance)
R_K2, R_K3, R_K4, R_TMP = 0, 1, 2, 3
N_ROWS = 9


@njit(cache=True, error_model="numpy")
def rk4_rows(S, iy, ik1, h, u, P, mu, kap, cj, eye, iout, ws):
    """RK4 step of size ``h`` from row ``iy`` of ``S``, given its slope in row ``ik1``, into row ``iout``.

    Rows ``R_K2 .. R_TMP`` hold the other stages.
    """
    m = S.shape[1]
    hh = 0.5 * h
    for i in range(m):
        S[R_TMP, i] = S[iy, i] + hh * S[ik1, i]
    rhs_rows(S, R_TMP, R_K2, u, P, mu, kap, cj, eye, ws)
    for i in range(m):
        S[R_TMP, i] = S[iy, i] + hh * S[R_K2, i]
    rhs_rows(S, R_TMP, R_K3, u, P, mu, kap, cj, eye, ws)
    for i in range(m):
        S[R_TMP, i] = S[iy, i] + h * S[R_K3, i]
    rhs_rows(S, R_TMP, R_K4, u, P, mu, kap, cj, eye, ws)
    h6 = h / 6.0
    for i in range(m):
        S[iout, i] = S[iy, i] + h6 * (S[ik1, i] + 2.0 * S[R_K2, i] + 2.0 * S[R_K3, i] + S[R_K4, i])


@njit(cache=True, error_model="numpy")
def integrate_interval(S, rows, e0, dt, u, h_max, P, mu, kap, cj, eye, stats, ws):
    """Integrate the state over ``dt`` with cable position ``u`` (constant), equal steps <= ``h_max``.

    ``rows`` (int array, updated in place) = row indices in ``S`` of the state, its slope, and three spare
    rows (the next state, a trial state, the next slope). On entry the slope row holds ``f(y)`` and ``e0``
    is the cable stretch at ``y``; on return the same holds at the new state, whose stretch is returned
    (each step's last evaluation is the next step's first stage). A step across which the cable changes
    between taut and slack is split at the transition, located by the Illinois (regula falsi) method on
    the step size, so that each RK4 step sees a smooth right-hand side. ``stats[0]`` counts steps,
    ``stats[1]`` counts taut/slack transitions.
    """
    if dt <= 0.0:
        return e0
    n_steps = int(math.ceil(dt / h_max - 1e-9))
    h = dt / n_steps
    m = S.shape[1]
    iy = rows[0]
    ik1 = rows[1]
    iy1 = rows[2]
    itry = rows[3]
    ik1n = rows[4]
    for _ in range(n_steps):
        rk4_rows(S, iy, ik1, h, u, P, mu, kap, cj, eye, iy1, ws)
        stats[0] += 1
        e1 = rhs_rows(S, iy1, ik1n, u, P, mu, kap, cj, eye, ws)
        if (e0 > 0.0) != (e1 > 0.0):
            stats[1] += 1
            # bracket the transition in the step size: f(0) = e0, f(h) = e1
            lo = 0.0
            hi = h
            f_lo = e0
            f_hi = e1
            side = 0
            hc = h
            for _it in range(30):
                den = f_hi - f_lo
                hc = (lo * f_hi - hi * f_lo) / den if den != 0.0 else 0.5 * (lo + hi)
                if not (hc > lo and hc < hi):
                    hc = 0.5 * (lo + hi)
                rk4_rows(S, iy, ik1, hc, u, P, mu, kap, cj, eye, itry, ws)
                stats[0] += 1
                fc = stretch_row(S, itry, u, P, eye)
                if abs(fc) < 1e-12 or hi - lo < 1e-10:
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
            # advance to the transition, then finish the step on the other branch
            for i in range(m):
                S[iy, i] = S[itry, i]
            rhs_rows(S, iy, ik1, u, P, mu, kap, cj, eye, ws)
            rk4_rows(S, iy, ik1, h - hc, u, P, mu, kap, cj, eye, iy1, ws)
            stats[0] += 1
            e1 = rhs_rows(S, iy1, ik1n, u, P, mu, kap, cj, eye, ws)
        iy, iy1 = iy1, iy
        ik1, ik1n = ik1n, ik1
        e0 = e1
    rows[0] = iy
    rows[1] = ik1
    rows[2] = iy1
    rows[4] = ik1n
    return e0


@njit(cache=True, error_model="numpy")
def advance(y, t0, u0, du, sample_times, step_times, step_signs, h_max, P, mu, kap, cj, eye,
            tension_out, phi_out, stats):
    """Advance the state ``y`` (in place) from ``t0`` through every sample time; return ``(t, u)``.

    Steps at ``step_times`` move the cable by ``du * step_signs`` instantly; a step at exactly a sample
    time is applied before that sample. Tension (N) and segment angles at the samples are written into
    ``tension_out`` and ``phi_out``. The slope at the current state is kept between intervals and
    re-evaluated only when the cable moves.
    """
    n = mu.shape[0]
    m = y.shape[0]
    S = np.empty((N_ROWS, m))
    ws = np.empty(workspace_size(n))
    rows = np.array([4, 5, 6, 7, 8])
    for i in range(m):
        S[4, i] = y[i]
    t = t0
    u = u0
    js = 0
    n_steps = step_times.shape[0]
    e = 0.0
    valid = False
    for q in range(sample_times.shape[0]):
        ts = sample_times[q]
        while js < n_steps and step_times[js] <= ts:
            dt = step_times[js] - t
            if dt > 0.0:
                if not valid:
                    e = rhs_rows(S, rows[0], rows[1], u, P, mu, kap, cj, eye, ws)
                    valid = True
                e = integrate_interval(S, rows, e, dt, u, h_max, P, mu, kap, cj, eye, stats, ws)
                t = step_times[js]
            u += du * step_signs[js]
            valid = False
            js += 1
        if not valid:
            e = rhs_rows(S, rows[0], rows[1], u, P, mu, kap, cj, eye, ws)
            valid = True
        e = integrate_interval(S, rows, e, ts - t, u, h_max, P, mu, kap, cj, eye, stats, ws)
        if ts > t:
            t = ts
        tension_out[q] = P[I_K] * e if e > 0.0 else 0.0
        iy = rows[0]
        for i in range(n):
            phi_out[q, i] = S[iy, i]
    iy = rows[0]
    for i in range(m):
        y[i] = S[iy, i]
    return t, u


@njit(cache=True, error_model="numpy")
def energy(y, u, P, mu, m_nodes, kap, eye):
    """Kinetic + elastic + gravitational + cable energy of the state (J), for the energy-balance test."""
    n = mu.shape[0]
    l_ = P[I_L]
    phi = y[:n]
    w = y[n:]
    kin = 0.0
    for i in range(n):
        kin += 0.5 * P[I_JSEG] * w[i] * w[i]
        for k in range(n):
            m_ = mu[k] if k > i else mu[i]
            kin += 0.5 * l_ * l_ * m_ * math.cos(phi[i] - phi[k]) * w[i] * w[k]
    el = 0.0
    prev = P[I_PHI0]
    for i in range(n):
        el += 0.5 * kap[i] * (phi[i] - prev) ** 2
        prev = phi[i]
    grav = 0.0
    yy = 0.0
    for i in range(n):
        yy += l_ * math.sin(phi[i])
        grav += P[I_G] * m_nodes[i] * yy
    e = u + cable_length(phi, P, eye) - P[I_ELLREF]
    cab = 0.5 * P[I_K] * e * e if e > 0.0 else 0.0
    return kin + el + grav + cab


@njit(cache=True, error_model="numpy")
def static_force(phi, u, lam_fixed, P, mu, kap, eye, out):
    """Generalised static force (springs, gravity, cable) at rest, written into ``out``; returns the tension.

    The tension is ``lam_fixed`` if it is >= 0 (tension-controlled statics), else it follows from ``u``.
    """
    n = mu.shape[0]
    l_ = P[I_L]
    g = P[I_G]
    grad = np.empty(n)
    ell = cable_length_grad(phi, P, eye, grad)
    if lam_fixed >= 0.0:
        lam = lam_fixed
    else:
        e = u + ell - P[I_ELLREF]
        lam = P[I_K] * e if (e > 0.0 or P[I_BILATERAL] != 0.0) else 0.0
    prev = P[I_PHI0]
    taus = np.empty(n)
    for i in range(n):
        taus[i] = kap[i] * (phi[i] - prev)
        prev = phi[i]
    for i in range(n):
        nxt = taus[i + 1] if i + 1 < n else 0.0
        out[i] = -taus[i] + nxt - g * l_ * mu[i] * math.cos(phi[i]) - lam * grad[i]
    return lam
