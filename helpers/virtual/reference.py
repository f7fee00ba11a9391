"""A straightforward numpy + ``scipy.integrate.solve_ivp`` implementation of the same equations.

Two uses: the oracle that the compiled fixed-step integrator is checked against (tight tolerances, the
integration restarted at every stepper step and at every taut/slack transition of the cable, located by
``solve_ivp``'s event detection), and the baseline of the speed benchmark. The equations are written again
here from the Lagrangian, in vectorised numpy, independently of :mod:`helpers.virtual._kernel`.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy.integrate import solve_ivp

from helpers.hardware import MM_PER_STEP
from helpers.virtual.parameters import RigParameters
from helpers.virtual.statics import model_arrays

__all__ = ["ReferenceArm", "reference_tension"]


class ReferenceArm:
    """The arm's equations of motion in plain numpy.

    Parameters
    ----------
    params : RigParameters
        The rig; the rest state and cable reference length are the plant's (same rule).
    """

    def __init__(self, params: RigParameters) -> None:
        arr = model_arrays(params)
        self.params = params
        self.n = params.n_segments
        self.l = params.segment_length
        self.m = params.node_masses()
        self.mu = np.cumsum(self.m[::-1])[::-1]
        self.mu_max = self.mu[np.maximum.outer(np.arange(self.n), np.arange(self.n))]
        self.j_seg = params.segment_inertia()
        self.kap = np.full(self.n, params.joint_stiffness)
        self.kap[0] *= 2.0  # clamp joint: half a cell
        self.eye = params.eyelet_nodes()
        self.phi0 = params.base_angle
        self.ell_ref = float(arr.P[6])
        self.y_rest = np.concatenate([np.array(arr.phi_rest), np.zeros(self.n)])
        # D maps segment angles to joint angles: theta = D phi - phi0 e_1
        self.D = np.eye(self.n) - np.eye(self.n, k=-1)

    def cable(self, phi: np.ndarray) -> tuple[float, np.ndarray]:
        """Cable length through the eyelets and its gradient, by explicit geometry."""
        p = self.params
        t = np.stack([np.cos(phi), np.sin(phi)], axis=1)
        nrm = np.stack([-np.sin(phi), np.cos(phi)], axis=1)
        nodes = np.vstack([[0.0, 0.0], np.cumsum(self.l * t, axis=0)])
        ang = np.concatenate([[self.phi0], phi])
        nvec = np.stack([-np.sin(ang), np.cos(ang)], axis=1)
        e = nodes[self.eye] + p.r * nvec[self.eye]
        chords = np.diff(e, axis=0)
        lengths = np.linalg.norm(chords, axis=1)
        u_hat = chords / lengths[:, None]
        # d e_j / d phi_i = l n_i [i < j] - r t_i [i == j - 1]  (segment i zero-based, node j)
        grad = np.zeros(self.n)
        for q in range(1, len(self.eye)):
            a, b = self.eye[q - 1], self.eye[q]
            grad[a:b] += self.l * nrm[a:b] @ u_hat[q - 1]
            grad[b - 1] -= p.r * t[b - 1] @ u_hat[q - 1]
            if a >= 1:
                grad[a - 1] += p.r * t[a - 1] @ u_hat[q - 1]
        return float(lengths.sum()), grad

    def stretch(self, y: np.ndarray, u: float) -> float:
        """Cable stretch (m); the cable is taut when it is positive."""
        return u + self.cable(y[: self.n])[0] - self.ell_ref

    def rhs(self, t: float, y: np.ndarray, u: float) -> np.ndarray:
        """d/dt of ``[phi, phi']`` with the cable pulled by ``u``."""
        p = self.params
        n = self.n
        phi, w = y[:n], y[n:]
        dphi = phi[:, None] - phi[None, :]
        M = self.l**2 * self.mu_max * np.cos(dphi) + self.j_seg * np.eye(n)
        coriolis = (self.l**2 * self.mu_max * np.sin(dphi)) @ (w**2)
        theta = self.D @ phi
        theta[0] -= self.phi0
        tau = self.kap * theta + p.beta * self.kap * (self.D @ w)
        q_el = -self.D.T @ tau
        q_g = -p.g * self.l * self.mu * np.cos(phi)
        ell, grad = self.cable(phi)
        lam = max(0.0, p.k * (u + ell - self.ell_ref))
        q = q_el + q_g - lam * grad - p.alpha * (M @ w) - coriolis
        return np.concatenate([w, np.linalg.solve(M, q)])

    def tension(self, y: np.ndarray, u: float) -> float:
        """Cable tension (N)."""
        return max(0.0, self.params.k * self.stretch(y, u))

    def run(
        self,
        sample_times: npt.ArrayLike,
        step_times: npt.ArrayLike = (),
        step_signs: npt.ArrayLike = (),
        rtol: float = 1e-9,
        atol: float = 1e-11,
        method: str = "DOP853",
        y0: np.ndarray | None = None,
        u0: float = 0.0,
        t0: float | None = None,
    ) -> np.ndarray:
        """Tension at ``sample_times`` from rest (or ``y0``), integrating piecewise between steps.

        Each interval between stepper steps is integrated by ``solve_ivp``; the integration is restarted at
        each taut/slack transition (a terminal event), so the solver never steps across the kink. ``y0``,
        ``u0`` (m) and ``t0`` (s) give another starting state and time (default: rest, 0, 0).
        """
        ts = np.asarray(sample_times, dtype=float)
        st = np.asarray(step_times, dtype=float)
        sg = np.asarray(step_signs, dtype=float)
        y = self.y_rest.copy() if y0 is None else np.array(y0, dtype=float)
        u = float(u0)
        du = MM_PER_STEP * 1e-3
        out = np.full(ts.size, np.nan)
        t = (0.0 if ts.size == 0 else min(0.0, ts[0])) if t0 is None else float(t0)
        breaks = np.concatenate([st, [ts[-1]]])
        signs = np.concatenate([sg, [0.0]])
        last = len(breaks) - 1
        for ib, (tb, sgn) in enumerate(zip(breaks, signs, strict=True)):
            while t < tb:

                def ev(_t: float, yy: np.ndarray, uu: float = u) -> float:
                    return self.stretch(yy, uu)

                ev.terminal = True  # type: ignore[attr-defined]
                sol = solve_ivp(
                    self.rhs, (t, tb), y, method=method, rtol=rtol, atol=atol, args=(u,),
                    dense_output=True, events=ev,
                )  # fmt: skip
                t_reached = float(sol.t[-1])
                t_next = min(tb, t_reached + 1e-9) if (sol.status == 1 and t_reached < tb) else tb
                # samples at a step instant see the step (they are evaluated after it, in the next interval)
                upper = (ts <= t_next) if (ib == last or t_next < tb) else (ts < tb)
                for i in np.flatnonzero((ts >= t) & upper):
                    out[i] = self.tension(sol.sol(ts[i]), u)
                y = sol.sol(t_next) if t_next != t_reached else sol.y[:, -1].copy()
                t = t_next
            u += sgn * du
        for i in np.flatnonzero(ts == t):
            out[i] = self.tension(y, u)
        return out


def reference_tension(
    params: RigParameters,
    sample_times: npt.ArrayLike,
    step_times: npt.ArrayLike = (),
    step_signs: npt.ArrayLike = (),
    **kwargs: object,
) -> np.ndarray:
    """Tension at ``sample_times`` computed by :class:`ReferenceArm` (see :meth:`ReferenceArm.run`)."""
    return ReferenceArm(params).run(sample_times, step_times, step_signs, **kwargs)
