"""The spatial twin as a plant to drive in time: each tendon's stepper steps in, each load cell's output out.

:class:`SpatialPlant` wraps the compiled integrator of :mod:`helpers.virtual.spatial._kernel` as
:class:`helpers.virtual.plant.ArmPlant` wraps the planar one: it starts at rest (every tendon at its
pretension, every stepper at position 0), keeps its state between calls, and integrates from the present
time through the requested samples, splitting at every step of every tendon, every sample and every
taut/slack transition of any cable. The amplifiers are part of the state, so chunked calls give the same
samples as one call.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from helpers.virtual._kernel import SCHEME_RK4, SCHEMES
from helpers.virtual.spatial import _kernel as kern
from helpers.virtual.spatial.rig import SpatialRig
from helpers.virtual.spatial.statics import spatial_model, stable_max_step

__all__ = ["SpatialKernelArrays", "kernel_arrays", "SpatialPlant"]


@dataclass(frozen=True)
class SpatialKernelArrays:
    """What the compiled kernel integrates, and the rest state.

    Attributes
    ----------
    geo, mb, Jd, Jp, tp, W, cw : numpy.ndarray
        Scalars, node masses, diametral and polar rotary inertias, per-tendon parameters, the constant
        damping's matrix ``C_f = W^T diag(c) W`` (3N x 3N, or 0 x 3N without a floor) and an unused
        placeholder (:mod:`helpers.virtual.spatial._kernel`).
    y_rest : numpy.ndarray
        The rest state ``[phi, phi', psi, psi', x_c, x_c']``.
    d_drive : numpy.ndarray
        Commanded rotor increment per step of each tendon, rad.
    tau : float
        The amplifiers' time constant, s (0: no filter).
    """

    geo: np.ndarray
    mb: np.ndarray
    Jd: np.ndarray
    Jp: np.ndarray
    tp: np.ndarray
    W: np.ndarray
    cw: np.ndarray
    y_rest: np.ndarray
    d_drive: np.ndarray
    tau: float

    @property
    def n(self) -> int:
        """Number of elements."""
        return int(self.mb.shape[0])

    @property
    def nt(self) -> int:
        """Number of tendons."""
        return int(self.tp.shape[0])


@functools.lru_cache(maxsize=32)
def kernel_arrays(rig: SpatialRig) -> SpatialKernelArrays:
    """Pack ``rig`` for the kernel (one element per disc interval: an eyelet on every node)."""
    if rig.arm.elements_per_disc != 1:
        raise ValueError("the spatial kernel integrates one element per disc interval (elements_per_disc 1); "
                         "finer rods are for the statics")  # fmt: skip
    model = spatial_model(rig)
    ch = model.chain
    p = rig.arm
    nt = rig.n_tendons
    geo = np.zeros(kern.N_GEO)
    geo[kern.G_L] = ch.l
    geo[kern.G_KB] = ch.kb
    geo[kern.G_KT] = ch.kt
    geo[kern.G_ALPHA] = p.alpha
    geo[kern.G_CB] = p.beta_chord * p.EI / p.disc_interval
    geo[kern.G_CT] = p.beta_chord * rig.GJ / p.disc_interval
    geo[kern.G_BOW] = ch.bow_scale
    geo[kern.G_GX], geo[kern.G_GY], geo[kern.G_GZ] = ch.gvec
    geo[kern.G_NR] = p.rotor_teeth
    geo[kern.G_TLAW] = 1.0 if p.torque_law == "sin" else 0.0
    tp = np.zeros((nt, kern.N_TP))
    for i in range(nt):
        tp[i, kern.T_R] = rig.spool_radius(i)
        tp[i, kern.T_JR] = p.drive_inertia
        tp[i, kern.T_TH] = rig.tendons[i].holding_torque_n_m
        tp[i, kern.T_CR] = rig.rotor_damping(i)
        tp[i, kern.T_K1] = model.k1[i]
        tp[i, kern.T_K2] = model.k2[i]
        tp[i, kern.T_MC] = p.carriage_mass
        tp[i, kern.T_CC] = rig.carriage_damping(i)
        tp[i, kern.T_S1] = model.s1_ref[i]
        tp[i, kern.T_ELL] = model.ell_ref_arm[i]
        tp[i, kern.T_RX : kern.T_RZ + 1] = ch.rho[i]
    n = ch.N
    y = np.zeros(6 * n + 4 * nt)
    y[: 3 * n] = model.q_rest
    y[6 * n : 6 * n + nt] = model.psi0
    fc = p.amp_bandwidth_hz
    Wf, cf = model.floor_W, model.floor_c
    Cf = (Wf.T * cf) @ Wf if cf.size else np.zeros((0, ch.nq))
    arrays = SpatialKernelArrays(
        geo=geo, mb=ch.m_nodes.copy(), Jd=ch.Jd_nodes.copy(), Jp=ch.Jp_nodes.copy(), tp=tp,
        W=np.ascontiguousarray(Cf), cw=np.zeros(1), y_rest=y,
        d_drive=np.array([rig.step_angle(i) for i in range(nt)]),
        tau=1.0 / (2.0 * math.pi * fc) if fc > 0 else 0.0,
    )  # fmt: skip
    for a in (arrays.geo, arrays.mb, arrays.Jd, arrays.Jp, arrays.tp, arrays.W, arrays.cw, arrays.y_rest,
              arrays.d_drive):  # fmt: skip
        a.setflags(write=False)
    return arrays


class SpatialPlant:
    """The spatial arm with each tendon's stepper, load-cell carriage and amplifier, driven by steps.

    Parameters
    ----------
    rig : SpatialRig
        The rig (e.g. :func:`~helpers.virtual.spatial.rig.four_tendon_rig`).
    max_step : float, optional
        Largest integrator step, s (the integrator is ``rig.arm.integrator``). Default:
        ``rig.arm.max_step`` or, with RK4 where that is beyond its stability limit at rest (a rig whose
        tendons stiffen the discs' rocking: four tendons need 1/6 ms, not 0.25 ms),
        :func:`helpers.virtual.spatial.statics.stable_max_step`; integrated beyond it, the twin at rest rings
        up until tendons go slack. The implicit step (``"rosw"``) holds the tendons' and the rod's stiffness
        implicitly and needs no such limit.
    """

    def __init__(self, rig: SpatialRig, max_step: float | None = None) -> None:
        if not isinstance(rig, SpatialRig):
            raise TypeError(f"rig must be a SpatialRig, got {type(rig).__name__}")
        self.rig = rig
        self._scheme = SCHEMES.index(rig.arm.integrator)
        if max_step is None:
            max_step = rig.arm.max_step
            if rig.n_tendons > 1 and self._scheme == SCHEME_RK4:
                max_step = min(max_step, stable_max_step(rig))
        self.max_step = float(max_step)
        if not (math.isfinite(self.max_step) and self.max_step > 0):
            raise ValueError(f"max_step must be positive, got {max_step!r}")
        self._arr = kernel_arrays(rig)
        self._stats = np.zeros(2, dtype=np.int64)
        self._health = np.zeros(rig.n_tendons)
        self.reset()

    def reset(self) -> None:
        """Back to rest at every stepper's position 0 and ``t = 0``."""
        a = self._arr
        self._y = np.array(a.y_rest, dtype=float)
        self._t = 0.0
        self._drive = np.zeros(a.nt)
        self._steps = np.zeros(a.nt, dtype=np.int64)
        self._filt = np.array(self.rig.pretensions, dtype=float)
        self._stats[:] = 0
        self._health[:] = 0.0

    @property
    def t(self) -> float:
        """Current simulated time, s."""
        return self._t

    @property
    def position_steps(self) -> np.ndarray:
        """Each tendon's commanded position in steps (+ = pulled)."""
        return self._steps.copy()

    @property
    def state(self) -> np.ndarray:
        """A copy of the state ``[phi, phi', psi, psi', x_c, x_c']``."""
        return self._y.copy()

    def set_state(self, y: npt.ArrayLike, drive: npt.ArrayLike | None = None) -> None:
        """Overwrite the state (for tests and what-if runs); time and amplifiers unchanged.

        ``drive`` also sets each rotor's commanded angle (rad), e.g. from
        :func:`helpers.virtual.spatial.statics.equilibrium_state`.
        """
        y = np.asarray(y, dtype=float)
        if y.shape != self._y.shape or not np.all(np.isfinite(y)):
            raise ValueError(f"state must be {self._y.shape[0]} finite numbers")
        self._y = y.copy()
        if drive is not None:
            d = np.asarray(drive, dtype=float)
            if d.shape != self._drive.shape or not np.all(np.isfinite(d)):
                raise ValueError(f"drive must be {self._drive.size} finite angles")
            self._drive = d.copy()

    @property
    def integrator_steps(self) -> int:
        """Integrator steps taken since the last reset (transition searches included)."""
        return int(self._stats[0])

    @property
    def transitions(self) -> int:
        """Taut/slack transitions since the last reset."""
        return int(self._stats[1])

    @property
    def max_rotor_lag_steps(self) -> np.ndarray:
        """Largest lag of each rotor behind its commanded angle since the last reset, microsteps."""
        return self._health / self._arr.d_drive

    def tensions(self) -> np.ndarray:
        """Each tendon's arm-side tension now (true, not filtered), N."""
        a = self._arr
        wb, wt, sp = kern.workspaces(a.n, a.nt, a.n)
        st = np.zeros((4, a.nt))
        dy = np.empty_like(self._y)
        kern.rhs(self._y, dy, self._drive, a.geo, a.mb, a.Jd, a.Jp, a.tp, a.W, a.cw, wb, wt, sp, st)
        return st[3].copy()

    def advance(
        self,
        sample_times: npt.ArrayLike,
        step_times: npt.ArrayLike = (),
        step_tendons: npt.ArrayLike = (),
        step_signs: npt.ArrayLike = (),
    ) -> dict[str, np.ndarray]:
        """Integrate to ``sample_times[-1]``; return the samples.

        Parameters
        ----------
        sample_times : array_like
            Strictly increasing times (s), all >= :attr:`t`.
        step_times : array_like
            Times (s) of stepper steps in ``(t, sample_times[-1]]``, sorted (a step at exactly a sample time
            is applied before that sample).
        step_tendons : array_like
            The tendon (0-based) each step belongs to.
        step_signs : array_like
            +1 (pull) or -1 (release) per step.

        Returns
        -------
        dict
            ``output`` (n_samples, nt): each amplifier's output, N; ``tension`` (n_samples, nt): each
            arm-side tension, N; ``q`` (n_samples, 3N): the arm's coordinates; ``tip`` (n_samples, 3): the tip
            node's position in the clamp frame, m.
        """
        ts = np.ascontiguousarray(sample_times, dtype=float).reshape(-1)
        st = np.ascontiguousarray(step_times, dtype=float).reshape(-1)
        sk = np.ascontiguousarray(step_tendons, dtype=np.int64).reshape(-1)
        sg = np.ascontiguousarray(step_signs, dtype=float).reshape(-1)
        a = self._arr
        n, nt = a.n, a.nt
        if ts.size == 0:
            return {"output": np.empty((0, nt)), "tension": np.empty((0, nt)), "q": np.empty((0, 3 * n)),
                    "tip": np.empty((0, 3))}  # fmt: skip
        if not np.all(np.isfinite(ts)) or np.any(np.diff(ts) <= 0):
            raise ValueError("sample_times must be finite and strictly increasing")
        if ts[0] < self._t - 1e-12:
            raise ValueError(
                f"sample_times must not precede the plant's time {self._t:.6f} s (got {ts[0]:.6f})"
            )
        if not (st.shape == sk.shape == sg.shape):
            raise ValueError("step_times, step_tendons and step_signs must have the same length")
        if st.size:
            if not np.all(np.isfinite(st)) or np.any(np.diff(st) < 0):
                raise ValueError("step_times must be finite and sorted")
            if st[0] < self._t - 1e-12 or st[-1] > ts[-1] + 1e-12:
                raise ValueError(f"step_times must lie in (t, last sample] = ({self._t:.6f}, {ts[-1]:.6f}] s")
            if not np.all(np.abs(sg) == 1):
                raise ValueError("step_signs must be +1 (pull) or -1 (release)")
            if np.any((sk < 0) | (sk >= nt)):
                raise ValueError(f"step_tendons must name tendons 0..{nt - 1}")
        out_raw = np.empty((ts.size, nt))
        out_filt = np.empty((ts.size, nt))
        out_q = np.empty((ts.size, 3 * n))
        out_tip = np.empty((ts.size, 3))
        t = kern.advance(
            self._scheme, self._y, self._t, self._drive, a.d_drive, ts, st, sk, sg, self.max_step, a.geo,
            a.mb, a.Jd, a.Jp, a.tp, a.W, a.cw, self._filt, a.tau, out_raw, out_filt, out_q, out_tip,
            self._stats, self._health,
        )  # fmt: skip
        if not (np.all(np.isfinite(self._y)) and np.all(np.isfinite(self._filt))):
            raise FloatingPointError(
                f"the integration became unstable before t = {ts[-1]:.4f} s: max_step {self.max_step:.2e} s "
                "is too large for this rig (helpers.virtual.spatial.statics.stable_max_step)"
            )
        self._t = float(max(t, ts[-1]))
        if sg.size:
            np.add.at(self._steps, sk, sg.astype(np.int64))
        return {"output": out_filt, "tension": out_raw, "q": out_q, "tip": out_tip}
