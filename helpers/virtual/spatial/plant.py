"""The spatial twin as a plant to drive in time: each tendon's stepper steps in, each load cell's output out.

:class:`SpatialPlant` wraps the compiled integrator of :mod:`helpers.virtual.spatial._kernel` as
:class:`helpers.virtual.plant.ArmPlant` wraps the planar one: it starts at rest (every tendon at its
pretension, every stepper at position 0), keeps its state between calls, and integrates from the present
time through the requested samples, splitting at every step of every tendon, every sample and every
taut/slack transition of any cable. The amplifiers are part of the state, so chunked calls give the same
samples as one call. :class:`SpatialLanes` drives several rigs in one kernel call (one per SIMD lane), each
lane bitwise the same as its rig alone.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from helpers.virtual import _driver as drv
from helpers.virtual._kernel import SCHEME_RK4, SCHEMES
from helpers.virtual.lanes import LaneArray
from helpers.virtual.plant import LANE_WIDTHS
from helpers.virtual.spatial import _kernel as kern
from helpers.virtual.spatial.rig import SpatialRig
from helpers.virtual.spatial.statics import spatial_model, stable_max_step

__all__ = ["SpatialKernelArrays", "kernel_arrays", "SpatialPlant", "SpatialLanes", "lane_group"]


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


def _checked(
    sample_times: npt.ArrayLike, step_times: npt.ArrayLike, step_tendons: npt.ArrayLike,
    step_signs: npt.ArrayLike, t_now: float, nt: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The times, tendons and signs of one :meth:`SpatialPlant.advance` as arrays, checked.

    Raises ``ValueError`` naming the fault.
    """
    ts = np.ascontiguousarray(sample_times, dtype=float).reshape(-1)
    st = np.ascontiguousarray(step_times, dtype=float).reshape(-1)
    sk = np.ascontiguousarray(step_tendons, dtype=np.int64).reshape(-1)
    sg = np.ascontiguousarray(step_signs, dtype=float).reshape(-1)
    if ts.size == 0:
        return ts, st, sk, sg
    if not np.all(np.isfinite(ts)) or np.any(np.diff(ts) <= 0):
        raise ValueError("sample_times must be finite and strictly increasing")
    if ts[0] < t_now - 1e-12:
        raise ValueError(f"sample_times must not precede the plant's time {t_now:.6f} s (got {ts[0]:.6f})")
    if not (st.shape == sk.shape == sg.shape):
        raise ValueError("step_times, step_tendons and step_signs must have the same length")
    if st.size:
        if not np.all(np.isfinite(st)) or np.any(np.diff(st) < 0):
            raise ValueError("step_times must be finite and sorted")
        if st[0] < t_now - 1e-12 or st[-1] > ts[-1] + 1e-12:
            raise ValueError(f"step_times must lie in (t, last sample] = ({t_now:.6f}, {ts[-1]:.6f}] s")
        if not np.all(np.abs(sg) == 1):
            raise ValueError("step_signs must be +1 (pull) or -1 (release)")
        if np.any((sk < 0) | (sk >= nt)):
            raise ValueError(f"step_tendons must name tendons 0..{nt - 1}")
    return ts, st, sk, sg


def unstable_error(t_end: float, max_step: float) -> FloatingPointError:
    """What :meth:`SpatialPlant.advance` raises when its call to ``t_end`` (s) became unstable."""
    return FloatingPointError(
        f"the integration became unstable before t = {t_end:.4f} s: max_step {max_step:.2e} s is too large "
        "for this rig (helpers.virtual.spatial.statics.stable_max_step)"
    )


def _max_step(rig: SpatialRig, max_step: float | None) -> float:
    """:class:`SpatialPlant`'s largest step for ``rig`` (``max_step`` given, or its default), checked."""
    if max_step is None:
        max_step = rig.arm.max_step
        if rig.n_tendons > 1 and SCHEMES.index(rig.arm.integrator) == SCHEME_RK4:
            max_step = min(max_step, stable_max_step(rig))
    h = float(max_step)
    if not (math.isfinite(h) and h > 0):
        raise ValueError(f"max_step must be positive, got {max_step!r}")
    return h


def lane_group(rig: SpatialRig) -> tuple:
    """What rigs must share to run in the lanes of one :class:`SpatialLanes`.

    The integrator, the elements, the tendons and what steers the kernel's branches
    (:func:`helpers.virtual.spatial._kernel.lane_key`: whether the bowing, the chord dashpots and the constant
    damping are on, the motor's torque law).
    """
    a = kernel_arrays(rig)
    return (rig.arm.integrator, a.n, a.nt, kern.lane_key(a.geo, a.W))


def _reset_state(S: np.ndarray, arr: SpatialKernelArrays, max_step: float) -> None:
    """A lane's driver state at rest at ``t = 0`` (:data:`helpers.virtual.spatial._kernel.N_STATE` rows)."""
    S[:] = 0.0
    S[drv.D_HMAX] = max_step
    S[drv.D_TAU] = arr.tau


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
        self.max_step = _max_step(rig, max_step)
        self._arr = kernel_arrays(rig)
        self._S = np.zeros(kern.N_STATE)
        self._L = np.zeros((1, kern.N_LANE_INTS), dtype=np.int64)
        self._health = np.zeros(rig.n_tendons)
        self._work = kern.make_work(self._arr.n, self._arr.nt)
        self.reset()

    def reset(self) -> None:
        """Back to rest at every stepper's position 0 and ``t = 0``."""
        a = self._arr
        self._y = np.array(a.y_rest, dtype=float)
        self._drive = np.zeros(a.nt)
        self._steps = np.zeros(a.nt, dtype=np.int64)
        self._filt = np.array(self.rig.pretensions, dtype=float)
        _reset_state(self._S, a, self.max_step)
        self._health[:] = 0.0

    @property
    def t(self) -> float:
        """Current simulated time, s."""
        return float(self._S[drv.D_T])

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
        return int(self._S[drv.D_NSTEP])

    @property
    def transitions(self) -> int:
        """Taut/slack transitions since the last reset."""
        return int(self._S[drv.D_NTRANS])

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
        a = self._arr
        n, nt = a.n, a.nt
        ts, st, sk, sg = _checked(sample_times, step_times, step_tendons, step_signs, self.t, nt)
        if ts.size == 0:
            return {"output": np.empty((0, nt)), "tension": np.empty((0, nt)), "q": np.empty((0, 3 * n)),
                    "tip": np.empty((0, 3))}  # fmt: skip
        out_raw = np.empty((1, ts.size, nt))
        out_filt = np.empty((1, ts.size, nt))
        out_q = np.empty((1, ts.size, 3 * n))
        out_tip = np.empty((1, ts.size, 3))
        self._S[drv.D_HMAX] = self.max_step
        steps = (st, sk, sg) if st.size else (np.zeros(1), np.zeros(1, np.int64), np.zeros(1))
        kern.advance(
            self._scheme, self._y, self._S, self._L, self._drive, a.d_drive, self._filt, self._health,
            ts[None], *(x[None] for x in steps), np.array([st.size]), a.geo, a.mb, a.Jd, a.Jp, a.tp, a.W,
            a.cw, *self._work, out_raw, out_filt, out_q, out_tip,
        )  # fmt: skip
        if not (np.all(np.isfinite(self._y)) and np.all(np.isfinite(self._filt))):
            raise unstable_error(ts[-1], self.max_step)
        self._S[drv.D_T] = max(self._S[drv.D_T], ts[-1])
        if sg.size:
            np.add.at(self._steps, sk, sg.astype(np.int64))
        return {"output": out_filt[0], "tension": out_raw[0], "q": out_q[0], "tip": out_tip[0]}


class SpatialLanes:
    """Several spatial rigs driven together, one per lane of the compiled kernel, each as its own plant.

    The kernel's arithmetic runs on every lane at once (SIMD, :mod:`helpers.virtual.lanes`); each lane takes
    exactly the steps, splits and events its rig takes alone, so its outputs and state are bitwise those of
    :class:`SpatialPlant`. The rigs must share :func:`lane_group`. They start at rest at ``t = 0``; lanes
    beyond the rigs given (up to :data:`helpers.virtual.plant.LANE_WIDTHS`) repeat the last rig, and their
    results are dropped.

    Parameters
    ----------
    rigs : sequence of SpatialRig
        One rig per lane, 1 to ``max(LANE_WIDTHS)``.
    max_step : float, optional
        Largest integrator step, s, for every lane (default: each rig's, as :class:`SpatialPlant`).
    """

    def __init__(self, rigs: Sequence[SpatialRig], max_step: float | None = None) -> None:
        rigs = list(rigs)
        if not 1 <= len(rigs) <= max(LANE_WIDTHS):
            raise ValueError(f"SpatialLanes takes 1 to {max(LANE_WIDTHS)} rigs, got {len(rigs)}")
        for r in rigs:
            if not isinstance(r, SpatialRig):
                raise TypeError(f"rigs must be SpatialRig, got {type(r).__name__}")
        group = lane_group(rigs[0])
        for r in rigs[1:]:
            if lane_group(r) != group:
                raise ValueError("the rigs of one SpatialLanes must share lane_group (integrator, elements, "
                                 "tendons and the kernel's switches)")  # fmt: skip
        self.rigs = tuple(rigs)
        width = min(w for w in LANE_WIDTHS if w >= len(rigs))
        self._rigs = rigs + [rigs[-1]] * (width - len(rigs))
        self._steps_h = np.array([_max_step(r, max_step) for r in self._rigs])
        self._arrs = [kernel_arrays(r) for r in self._rigs]
        a0 = self._arrs[0]
        self._n, self._nt = a0.n, a0.nt
        self._scheme = SCHEMES.index(rigs[0].arm.integrator)

        def stacked(name: str) -> LaneArray:
            return LaneArray(np.ascontiguousarray(np.stack([getattr(a, name) for a in self._arrs], axis=-1)))

        self._geo, self._mb, self._Jd, self._Jp, self._tp, self._W, self._cw, self._d_drive = (
            stacked(k) for k in ("geo", "mb", "Jd", "Jp", "tp", "W", "cw", "d_drive"))  # fmt: skip
        nt = self._nt
        m = 6 * self._n + 4 * nt
        self._y = LaneArray(np.zeros((m, width)))
        self._S = LaneArray(np.zeros((kern.N_STATE, width)))
        self._L = np.zeros((width, kern.N_LANE_INTS), dtype=np.int64)
        self._drive = LaneArray(np.zeros((nt, width)))
        self._filt = LaneArray(np.zeros((nt, width)))
        self._health = LaneArray(np.zeros((nt, width)))
        self._steps = np.zeros((width, nt), dtype=np.int64)
        self._work = kern.make_work(self._n, nt, width)
        self.reset()

    @property
    def lanes(self) -> int:
        """Rigs driven (the lanes that count)."""
        return len(self.rigs)

    @property
    def width(self) -> int:
        """Lanes of the kernel call (the rigs, and the repeats that fill it)."""
        return len(self._rigs)

    def reset(self) -> None:
        """Every lane back to rest at every stepper's position 0 and ``t = 0``."""
        for k, (a, r) in enumerate(zip(self._arrs, self._rigs, strict=True)):
            self._y.data[:, k] = a.y_rest
            _reset_state(self._S.data[:, k], a, float(self._steps_h[k]))
            self._drive.data[:, k] = 0.0
            self._filt.data[: self._nt, k] = r.pretensions
            self._health.data[:, k] = 0.0
        self._steps[:] = 0

    @property
    def t(self) -> np.ndarray:
        """Each lane's simulated time, s."""
        return self._S.data[drv.D_T, : self.lanes].copy()

    @property
    def max_steps(self) -> np.ndarray:
        """Each lane's largest integrator step, s."""
        return self._steps_h[: self.lanes].copy()

    @property
    def state(self) -> np.ndarray:
        """Each lane's state (rows: lanes), a copy."""
        return self._y.data[:, : self.lanes].T.copy()

    @property
    def position_steps(self) -> np.ndarray:
        """Each lane's commanded position of every tendon in steps (rows: lanes)."""
        return self._steps[: self.lanes].copy()

    @property
    def integrator_steps(self) -> np.ndarray:
        """Each lane's integrator steps since the last reset (as :attr:`SpatialPlant.integrator_steps`)."""
        return self._S.data[drv.D_NSTEP, : self.lanes].astype(np.int64)

    @property
    def transitions(self) -> np.ndarray:
        """Each lane's taut/slack transitions since the last reset."""
        return self._S.data[drv.D_NTRANS, : self.lanes].astype(np.int64)

    @property
    def max_rotor_lag_steps(self) -> np.ndarray:
        """Each lane's largest lag of each rotor since the last reset, microsteps (rows: lanes)."""
        nt = self._nt
        return np.array([self._health.data[:nt, k] / self._arrs[k].d_drive for k in range(self.lanes)])

    def save(self) -> tuple[np.ndarray, ...]:
        """Every lane's state, time, drives, amplifiers and counters, a copy (for :meth:`restore`)."""
        return (self._y.data.copy(), self._S.data.copy(), self._drive.data.copy(), self._filt.data.copy(),
                self._health.data.copy(), self._steps.copy())  # fmt: skip

    def restore(self, saved: tuple[np.ndarray, ...], lanes: Sequence[int]) -> None:
        """Put ``lanes`` back as they were when :meth:`save` gave ``saved`` (the others as they are)."""
        y, S, drive, filt, health, steps = saved
        for k in lanes:
            self._y.data[:, k] = y[:, k]
            self._S.data[:, k] = S[:, k]
            self._drive.data[:, k] = drive[:, k]
            self._filt.data[:, k] = filt[:, k]
            self._health.data[:, k] = health[:, k]
            self._steps[k] = steps[k]

    def unstable(self) -> list[int]:
        """The lanes (of the rigs) whose state is no longer finite."""
        y, filt = self._y.data[:, : self.lanes], self._filt.data[:, : self.lanes]
        ok = np.all(np.isfinite(y), axis=0) & np.all(np.isfinite(filt), axis=0)
        return [int(k) for k in np.flatnonzero(~ok)]

    def advance_all(
        self,
        sample_times: npt.ArrayLike,
        step_times: Sequence[npt.ArrayLike],
        step_tendons: Sequence[npt.ArrayLike],
        step_signs: Sequence[npt.ArrayLike],
        check: bool = True,
    ) -> dict[str, np.ndarray]:
        """Integrate every lane to its last sample: :meth:`SpatialPlant.advance` of each lane.

        Parameters
        ----------
        sample_times : array_like
            The samples, shared by every lane (strictly increasing, after every lane's time); or one row
            per rig ``(rigs, samples)``, each after that rig's own time (every rig the same number).
        step_times, step_tendons, step_signs : sequence of array_like
            Each rig's stepper steps, their tendons and signs (as :meth:`SpatialPlant.advance`).
        check : bool
            Raise if a lane became unstable; False leaves that to the caller (:meth:`unstable`: those lanes'
            outputs are not finite, the others' are what they are alone).

        Returns
        -------
        dict
            As :meth:`SpatialPlant.advance`, each with a leading axis of rigs: ``output``, ``tension``
            ``(rigs, samples, nt)``, ``q`` ``(rigs, samples, 3N)``, ``tip`` ``(rigs, samples, 3)``.

        Raises
        ------
        ValueError
            As :meth:`SpatialPlant.advance`, or not one step list per rig.
        FloatingPointError
            If a lane's integration became unstable (and ``check``).
        """
        lanes, width, n, nt = self.lanes, self.width, self._n, self._nt
        if not (len(step_times) == len(step_tendons) == len(step_signs) == lanes):
            raise ValueError(f"one step_times, step_tendons and step_signs per rig: {lanes}, got "
                             f"{len(step_times)}, {len(step_tendons)}, {len(step_signs)}")  # fmt: skip
        each = np.ndim(sample_times) == 2  # one row of samples per rig, each after that rig's own time
        if each and np.shape(sample_times)[0] != lanes:
            raise ValueError(f"one row of sample_times per rig: {lanes}, got {np.shape(sample_times)[0]}")
        rows = list(sample_times) if each else [sample_times] * lanes
        t_now = self._S.data[drv.D_T] if each else np.full(width, np.max(self._S.data[drv.D_T, :lanes]))
        groups = zip(rows, step_times, step_tendons, step_signs, strict=True)
        checked = [_checked(r, a, b, c, float(t_now[k]), nt) for k, (r, a, b, c) in enumerate(groups)]
        ts = checked[0][0]
        if ts.size == 0:
            return {"output": np.empty((lanes, 0, nt)), "tension": np.empty((lanes, 0, nt)),
                    "q": np.empty((lanes, 0, 3 * n)), "tip": np.empty((lanes, 0, 3))}  # fmt: skip
        if any(c[0].shape != ts.shape for c in checked):
            raise ValueError("every rig's row of sample_times must hold the same number of samples")
        checked += [checked[-1]] * (width - lanes)
        # the lanes that fill the call repeat the last rig (from where it is: it may have been restored)
        for arr in (self._y, self._S, self._drive, self._filt, self._health):
            arr.data[:, lanes:] = arr.data[:, lanes - 1 : lanes]
        samples = np.stack([c[0] for c in checked])
        counts = np.array([c[1].size for c in checked], dtype=np.int64)
        st = np.zeros((width, max(1, int(counts.max()))))
        sk = np.zeros(st.shape, dtype=np.int64)
        sg = np.zeros_like(st)
        for k, (_, times, tendons, signs) in enumerate(checked):
            st[k, : times.size] = times
            sk[k, : tendons.size] = tendons
            sg[k, : signs.size] = signs
        out_raw = np.empty((width, ts.size, nt))
        out_filt = np.empty((width, ts.size, nt))
        out_q = np.empty((width, ts.size, 3 * n))
        out_tip = np.empty((width, ts.size, 3))
        kern.advance(
            self._scheme, self._y, self._S, self._L, self._drive, self._d_drive, self._filt, self._health,
            samples, st, sk, sg, counts, self._geo, self._mb, self._Jd, self._Jp, self._tp, self._W, self._cw,
            *self._work, out_raw, out_filt, out_q, out_tip,
        )  # fmt: skip
        bad = self.unstable() if check else []
        if bad:
            raise FloatingPointError(
                f"the integration of lane(s) {bad} became unstable before t = {ts[-1]:.4f} s: max_step is "
                "too large for those rigs (helpers.virtual.spatial.statics.stable_max_step)"
            )
        self._S.data[drv.D_T] = np.maximum(self._S.data[drv.D_T], samples[:, -1])
        for k in range(lanes):
            _, _, tendons, signs = checked[k]
            if signs.size:
                np.add.at(self._steps[k], tendons, signs.astype(np.int64))
        return {"output": out_filt[:lanes], "tension": out_raw[:lanes], "q": out_q[:lanes],
                "tip": out_tip[:lanes]}  # fmt: skip
