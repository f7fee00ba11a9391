"""A straightforward numpy + ``scipy.integrate.solve_ivp`` implementation of the same equations.

Two uses: the oracle that the compiled fixed-step integrator is checked against (tight tolerances, the
integration restarted at every stepper step and at every taut/slack transition of either cable, located by
``solve_ivp``'s event detection), and the baseline of the speed benchmark.

The equations are written again here from the Lagrangian, independently of the O(N) articulated-body kernel
(:mod:`helpers.virtual._kernel`): node positions as sums of arc chords, the dense mass matrix
``M = sum m_j J_j^T J_j + diag(J)`` from the node Jacobians, the velocity-product terms
``sum m_j J_j^T (dJ_j/dt q')`` by a complex step of the Jacobian along ``q'``, the cable's gradient by a
complex step of its length, the bowing compliance ``H`` in series with the arm-side cable
(``docs/virtual_rig.md``) by Gauss-Legendre quadrature of the distances of the elements' points from their
cable runs and its gradient by a complex step, and the amplifier as one more state (``tau y' = lambda - y``).
Only the rest state, the cables' reference lengths and the constant high-mode damping matrix are taken from
:func:`helpers.virtual.statics.model_arrays` (they are parameters of the equations, fixed by the same rules).
The eyelet friction law is not implemented here (the rig is frictionless).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from scipy.integrate import solve_ivp

from helpers.virtual import _kernel as kern
from helpers.virtual.parameters import RigParameters
from helpers.virtual.statics import model_arrays

__all__ = ["ReferenceArm", "reference_tension"]


def _chord(D: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``sin D / D``, ``(1 - cos D) / D`` and their derivatives; complex-safe (series near 0)."""
    D = np.asarray(D)
    near = np.abs(D) < 0.05
    Dn = np.where(near, D, 0.0)
    Df = np.where(near, 1.0, D)
    x = Dn * Dn
    f1n = 1 - x / 6 + x**2 / 120 - x**3 / 5040 + x**4 / 362880
    f2n = Dn * (0.5 - x / 24 + x**2 / 720 - x**3 / 40320 + x**4 / 3628800)
    f1pn = Dn * (-1 / 3 + x / 30 - x**2 / 840 + x**3 / 45360)
    f2pn = 0.5 - x / 8 + x**2 / 144 - x**3 / 5760 + x**4 / 403200
    s, c = np.sin(Df), np.cos(Df)
    f1f, f2f = s / Df, (1 - c) / Df
    f1pf = (c - f1f) / Df
    f2pf = (s - f2f) / Df
    return (np.where(near, f1n, f1f), np.where(near, f2n, f2f), np.where(near, f1pn, f1pf),
            np.where(near, f2pn, f2pf))  # fmt: skip


class ReferenceArm:
    """The rig's equations of motion in plain numpy.

    Parameters
    ----------
    params : RigParameters
        The rig (frictionless: ``eyelet_mu`` must be 0).
    """

    def __init__(self, params: RigParameters) -> None:
        if params.eyelet_mu != 0.0:
            raise ValueError("the reference implementation is frictionless (eyelet_mu = 0)")
        arr = model_arrays(params)
        self.params = params
        self.n = params.n_elements
        self.l = params.element_length
        self.m = params.node_masses()
        self.J = params.node_inertias()
        self.eye = np.concatenate([[0], params.eyelet_nodes()])
        self.th0 = params.base_angle
        self.kap = params.EI / self.l
        self.bowing = params.bowing
        # the cable run (eyelet q-1 to eyelet q) of each element
        self.elem_run = np.searchsorted(self.eye, np.arange(1, self.n + 1), side="left") - 1
        self.gl_x, self.gl_w = np.polynomial.legendre.leggauss(10)
        self.P = np.array(arr.P)
        self.y_rest = np.array(arr.y_rest)
        self.d_drive = float(arr.d_drive)
        self.C_floor = (np.asarray(arr.W).T * np.asarray(arr.cw)) @ np.asarray(arr.W)
        # disc-rate rows (clamp first) for the chord and disc dashpots
        rates = np.zeros((len(self.eye), self.n))
        for row, node in enumerate(self.eye[1:], start=1):
            rates[row, node - 1] = 1.0
        c_d = params.EI / params.disc_interval
        C = np.zeros((self.n, self.n))
        if params.beta_disc:
            Dd = rates[1:] - rates[:-1]
            C += params.beta_disc * c_d * Dd.T @ Dd
        if params.beta_chord:
            Dc = np.vstack(
                [0.5 * rates[1]] + [0.5 * (rates[k + 1] - rates[k - 1]) for k in range(1, len(rates) - 1)]
            )
            C += params.beta_chord * c_d * Dc.T @ Dc
        self.C_struct = C + self.C_floor
        fc = params.amp_bandwidth_hz
        self.tau = 1.0 / (2.0 * math.pi * fc) if fc > 0 else 0.0

    # --- geometry ---------------------------------------------------------------------------------
    def _chords(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Chords, their derivatives with respect to their end and start angles; each (..., N, 2)."""
        base = np.full(np.shape(q)[:-1] + (1,), self.th0)
        th = np.concatenate([base, q], axis=-1)
        D = th[..., 1:] - th[..., :-1]
        f1, f2, f1p, f2p = _chord(D)
        c0, s0 = np.cos(th[..., :-1]), np.sin(th[..., :-1])
        ch = self.l * np.stack([c0 * f1 - s0 * f2, s0 * f1 + c0 * f2], axis=-1)
        d_end = self.l * np.stack([c0 * f1p - s0 * f2p, s0 * f1p + c0 * f2p], axis=-1)
        d_start = np.stack([-ch[..., 1], ch[..., 0]], axis=-1) - d_end
        return ch, d_end, d_start

    def nodes(self, q: np.ndarray) -> np.ndarray:
        """Node positions (..., N + 1, 2), clamp first."""
        ch, _, _ = self._chords(q)
        zero = np.zeros(ch.shape[:-2] + (1, 2), dtype=ch.dtype)
        return np.concatenate([zero, np.cumsum(ch, axis=-2)], axis=-2)

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """d(node j)/d(q_i), shape (N + 1, 2, N); complex-safe.

        ``q_i`` (the tangent at node i + 1) turns the end of chord i and the start of chord i + 1: it moves
        node j by ``d_end_i`` for j >= i + 1 and by ``d_start_{i+1}`` more for j >= i + 2.
        """
        n = self.n
        _, d_end, d_start = self._chords(q)
        nxt = np.zeros_like(d_start)
        nxt[:-1] = d_start[1:]
        j = np.arange(n + 1)[:, None]
        i = np.arange(n)[None, :]
        return ((j >= i + 1)[:, None, :] * d_end.T[None, :, :]
                + (j >= i + 2)[:, None, :] * nxt.T[None, :, :])  # fmt: skip

    def cable_length(self, q: np.ndarray) -> np.ndarray:
        """Cable path through the clamp guide and the eyelets (batch over leading dimensions)."""
        p = self.nodes(q)
        base = np.full(np.shape(q)[:-1] + (1,), self.th0)
        ang = np.concatenate([base, q], axis=-1)[..., self.eye]
        e = p[..., self.eye, :] + self.params.r * np.stack([-np.sin(ang), np.cos(ang)], axis=-1)
        d = np.diff(e, axis=-2)
        return np.sum(np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2), axis=-1)

    def bow_compliance(self, q: np.ndarray) -> np.ndarray:
        """The bowing compliance ``H = sum_e int_e (h - mean_e h)^2 ds / EI``, m/N.

        ``h`` is the distance of element e's points from its cable run (the line through the run's two
        eyelets), sampled at 10 Gauss-Legendre points per element. Batch over leading dimensions;
        complex-safe.
        """
        if not self.bowing:
            return np.zeros(np.shape(q)[:-1])
        base = np.full(np.shape(q)[:-1] + (1,), self.th0)
        th = np.concatenate([base, q], axis=-1)
        p = self.nodes(q)
        ang = th[..., self.eye]
        e = p[..., self.eye, :] + self.params.r * np.stack([-np.sin(ang), np.cos(ang)], axis=-1)
        d = np.diff(e, axis=-2)
        length = np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2)
        n_run = np.stack([-d[..., 1], d[..., 0]], axis=-1) / length[..., None]
        sig = 0.5 * (self.gl_x + 1.0)  # quadrature points along each element, s / l
        wts = 0.5 * self.gl_w
        D = (th[..., 1:] - th[..., :-1])[..., None] * sig  # turning up to each point
        f1, f2, _, _ = _chord(D)
        c0, s0 = np.cos(th[..., :-1])[..., None], np.sin(th[..., :-1])[..., None]
        px = p[..., :-1, 0, None] + self.l * sig * (c0 * f1 - s0 * f2)
        py = p[..., :-1, 1, None] + self.l * sig * (s0 * f1 + c0 * f2)
        start = e[..., :-1, :][..., self.elem_run, :]
        nr = n_run[..., self.elem_run, :]
        h = (px - start[..., 0, None]) * nr[..., 0, None] + (py - start[..., 1, None]) * nr[..., 1, None]
        dev = h - (h * wts).sum(-1)[..., None]
        return self.l * ((dev * dev) * wts).sum(-1).sum(-1) / self.params.EI

    def bow_grad(self, q: np.ndarray) -> tuple[float, np.ndarray]:
        """The bowing compliance and its gradient (complex step)."""
        h = 1e-30
        grad = self.bow_compliance(q[None, :] + 1j * h * np.eye(self.n)).imag / h
        return float(self.bow_compliance(q)), grad

    def cable_grad(self, q: np.ndarray) -> tuple[float, np.ndarray]:
        """Cable length and its gradient (complex step, exact to round-off)."""
        h = 1e-30
        grad = self.cable_length(q[None, :] + 1j * h * np.eye(self.n)).imag / h
        return float(self.cable_length(q)), grad

    # --- dynamics ---------------------------------------------------------------------------------
    def _tensions(
        self, y: np.ndarray, drive: float, ell: float, bow: float
    ) -> tuple[float, float, float, float]:
        P, n = self.P, self.n
        mode = P[kern.I_MODE]
        e1 = lam1 = 0.0
        if mode == 0.0:
            e2 = drive + ell - P[kern.I_ELLREF]
        elif mode == 1.0:
            e2 = P[kern.I_RSP] * y[2 * n] + ell - P[kern.I_ELLREF]
        else:
            e1 = P[kern.I_RSP] * y[2 * n] - y[2 * n + 2] - P[kern.I_S1REF]
            lam1 = P[kern.I_K1] * e1 if e1 > 0 else 0.0
            e2 = y[2 * n + 2] + ell - P[kern.I_ELLREF]
        lam2 = e2 / (1.0 / P[kern.I_K2] + bow) if e2 > 0 else 0.0
        return e1, e2, lam1, lam2

    def _measured(self, lam1: float, lam2: float) -> float:
        P = self.P
        return lam1 if (P[kern.I_MODE] == 2.0 and P[kern.I_MEAS] == 1.0) else lam2

    def rhs(self, t: float, y: np.ndarray, drive: float) -> np.ndarray:
        """d/dt of ``[q, q', psi, psi', x_c, x_c', amplifier]`` with the drive held."""
        p, P, n = self.params, self.P, self.n
        q, w = y[:n], y[n : 2 * n]
        J = self.jacobian(q)[1:]
        M = np.einsum("j,jai,jak->ik", self.m, J, J) + np.diag(self.J)
        h = 1e-30
        Jdot_w = (self.jacobian(q + 1j * h * w)[1:] @ w).imag / h  # (N, 2): d/dt(J) q'
        bias = np.einsum("j,jai,ja->i", self.m, J, Jdot_w)
        th = np.concatenate([[self.th0], q])
        tau_b = self.kap * (th[1:] - th[:-1])
        q_el = -tau_b.copy()
        q_el[:-1] += tau_b[1:]
        q_g = -p.g * np.einsum("j,ji->i", self.m, J[:, 1, :])
        ell, dl = self.cable_grad(q)
        bow, dbow = self.bow_grad(q)
        e1, e2, lam1, lam2 = self._tensions(y, drive, ell, bow)
        # the arm-side spring's energy is e2^2 / (2 (1/k2 + H)): -dV/dq = -lam2 dl + lam2^2 dH / 2
        Q = q_el + q_g - lam2 * dl + 0.5 * lam2**2 * dbow - p.alpha * (M @ w) - self.C_struct @ w
        acc = np.linalg.solve(M, Q - bias)
        out = np.zeros_like(y)
        out[:n] = w
        out[n : 2 * n] = acc
        mode = P[kern.I_MODE]
        if mode != 0.0:
            delta = drive - y[2 * n]
            tm = p.motor_torque(delta)
            lam_sp = lam2 if mode == 1.0 else lam1
            out[2 * n] = y[2 * n + 1]
            out[2 * n + 1] = (tm - P[kern.I_CR] * y[2 * n + 1] - P[kern.I_RSP] * lam_sp) / P[kern.I_JR]
            if mode == 2.0:
                out[2 * n + 2] = y[2 * n + 3]
                out[2 * n + 3] = (lam1 - lam2 - P[kern.I_CC] * y[2 * n + 3]) / P[kern.I_MC]
        meas = self._measured(lam1, lam2)
        out[-1] = (meas - y[-1]) / self.tau if self.tau > 0 else 0.0
        return out

    def stretches(self, y: np.ndarray, drive: float) -> tuple[float, float]:
        """Stretches ``(e1, e2)`` of the spool-side and the arm-side cable (taut when positive)."""
        q = y[: self.n]
        e1, e2, _, _ = self._tensions(y, drive, float(self.cable_length(q)), float(self.bow_compliance(q)))
        return e1, e2

    def measured(self, y: np.ndarray, drive: float) -> tuple[float, float]:
        """``(amplifier output, true measured tension)`` in state ``y``."""
        q = y[: self.n]
        ell, bow = float(self.cable_length(q)), float(self.bow_compliance(q))
        _, _, lam1, lam2 = self._tensions(y, drive, ell, bow)
        raw = self._measured(lam1, lam2)
        return (float(y[-1]) if self.tau > 0 else raw), raw

    def rest_state(self) -> np.ndarray:
        """The plant's rest state with the amplifier settled at the pretension."""
        return np.concatenate([self.y_rest, [self.params.pretension]])

    def run(
        self,
        sample_times: npt.ArrayLike,
        step_times: npt.ArrayLike = (),
        step_signs: npt.ArrayLike = (),
        rtol: float = 1e-9,
        atol: float = 1e-11,
        method: str = "DOP853",
        y0: np.ndarray | None = None,
        steps0: int = 0,
        t0: float | None = None,
        raw: bool = False,
    ) -> np.ndarray:
        """Amplifier output (or, with ``raw``, the true tension) at ``sample_times``, from rest or ``y0``.

        Each interval between stepper steps is integrated by ``solve_ivp``; the integration is restarted at
        each taut/slack transition of either cable (a terminal event), so the solver never steps across the
        kink. ``y0`` (the kernel's state plus the amplifier's output), ``steps0`` (the commanded position in
        steps) and ``t0`` (s) give another starting point (default: rest, 0, 0).
        """
        ts = np.asarray(sample_times, dtype=float)
        st = np.asarray(step_times, dtype=float)
        sg = np.asarray(step_signs, dtype=float)
        y = self.rest_state() if y0 is None else np.array(y0, dtype=float)
        drive = steps0 * self.d_drive
        out = np.full(ts.size, np.nan)
        t = (0.0 if ts.size == 0 else min(0.0, ts[0])) if t0 is None else float(t0)
        breaks = np.concatenate([st, [ts[-1]]])
        signs = np.concatenate([sg, [0.0]])
        last = len(breaks) - 1
        pick = 1 if raw else 0
        for ib, (tb, sgn) in enumerate(zip(breaks, signs, strict=True)):
            while t < tb:
                e_start = self.stretches(y, drive)

                def ev1(_t: float, yy: np.ndarray, dd: float = drive) -> float:
                    return self.stretches(yy, dd)[0]

                def ev2(_t: float, yy: np.ndarray, dd: float = drive) -> float:
                    return self.stretches(yy, dd)[1]

                events = [ev2] + ([ev1] if self.P[kern.I_MODE] == 2.0 else [])
                for ev in events:
                    ev.terminal = True  # type: ignore[attr-defined]
                sol = solve_ivp(
                    self.rhs, (t, tb), y, method=method, rtol=rtol, atol=atol, args=(drive,),
                    dense_output=True, events=events,
                )  # fmt: skip
                t_reached = float(sol.t[-1])
                t_next = min(tb, t_reached + 1e-9) if (sol.status == 1 and t_reached < tb) else tb
                upper = (ts <= t_next) if (ib == last or t_next < tb) else (ts < tb)
                for i in np.flatnonzero((ts >= t) & upper):
                    out[i] = self.measured(sol.sol(ts[i]), drive)[pick]
                y = sol.sol(t_next) if t_next != t_reached else sol.y[:, -1].copy()
                if e_start == self.stretches(y, drive) and t_next == t:  # pragma: no cover - no progress
                    raise RuntimeError(f"the reference integration made no progress at t = {t:.6f} s")
                t = t_next
            drive += sgn * self.d_drive
        for i in np.flatnonzero(ts == t):
            out[i] = self.measured(y, drive)[pick]
        return out


def reference_tension(
    params: RigParameters,
    sample_times: npt.ArrayLike,
    step_times: npt.ArrayLike = (),
    step_signs: npt.ArrayLike = (),
    **kwargs: object,
) -> np.ndarray:
    """Amplifier output at ``sample_times`` by :class:`ReferenceArm` (see :meth:`ReferenceArm.run`)."""
    return ReferenceArm(params).run(sample_times, step_times, step_signs, **kwargs)
