"""The rig as a plant to drive in time: stepper steps in, amplifier output out, state kept between calls.

:class:`ArmPlant` is what the emulated boards of the virtual rig stream from. It wraps the compiled
fixed-step integrator of :mod:`helpers.virtual._kernel`: each call integrates from the present time to the
last requested sample, splitting the integration at every stepper step and every sample instant (and,
inside the integrator, at every taut/slack transition of either cable). The amplifier's low-pass filter is
part of the state, so chunked calls give the same samples as one call.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from helpers.virtual import _kernel as kern
from helpers.virtual.lanes import LaneArray
from helpers.virtual.parameters import RigParameters
from helpers.virtual.statics import ArcChain, model_arrays, node_positions

__all__ = ["ArmPlant", "ArmLanes", "LANE_WIDTHS", "lane_group", "unstable_error"]

LANE_WIDTHS = (4, 8)
"""Lanes of one kernel call (:class:`ArmLanes`): four (256-bit registers) or eight (512-bit)."""


def _checked_times(
    sample_times: npt.ArrayLike, step_times: npt.ArrayLike, step_signs: npt.ArrayLike, t_now: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The times of one :meth:`ArmPlant.advance` as float arrays, checked (``ValueError`` naming a fault)."""
    ts = np.ascontiguousarray(sample_times, dtype=float).reshape(-1)
    st = np.ascontiguousarray(step_times, dtype=float).reshape(-1)
    sg = np.ascontiguousarray(step_signs, dtype=float).reshape(-1)
    if ts.size == 0:
        return ts, st, sg
    if not np.all(np.isfinite(ts)):
        raise ValueError("sample_times must be finite")
    if np.any(np.diff(ts) <= 0):
        raise ValueError("sample_times must be strictly increasing")
    if ts[0] < t_now - 1e-12:
        raise ValueError(f"sample_times must not precede the plant's time {t_now:.6f} s (got {ts[0]:.6f})")
    if st.shape != sg.shape:
        raise ValueError(f"step_times ({st.size}) and step_signs ({sg.size}) differ in length")
    if st.size:
        if not np.all(np.isfinite(st)):
            raise ValueError("step_times must be finite")
        if np.any(np.diff(st) < 0):
            raise ValueError("step_times must be sorted")
        if st[0] < t_now - 1e-12 or st[-1] > ts[-1] + 1e-12:
            raise ValueError(
                f"step_times must lie in (t, last sample] = ({t_now:.6f}, {ts[-1]:.6f}] s, "
                f"got {st[0]:.6f} .. {st[-1]:.6f}"
            )
        if not np.all(np.abs(sg) == 1):
            raise ValueError("step_signs must be +1 (pull) or -1 (release)")
    return ts, st, sg


def unstable_error(t_end: float, max_step: float) -> FloatingPointError:
    """What :meth:`ArmPlant.advance` raises when its call to ``t_end`` (s) became unstable."""
    return FloatingPointError(
        f"the integration became unstable before t = {t_end:.4f} s: max_step = {max_step:.2e} s is too large "
        "for these parameters"
    )


def _reset_state(S: np.ndarray, arr: Any, params: RigParameters) -> None:
    """A lane's driver state at rest at ``t = 0`` (:data:`helpers.virtual._kernel.N_STATE` rows)."""
    fc = params.amp_bandwidth_hz
    S[:] = 0.0
    S[kern.S_DDRIVE] = arr.d_drive
    S[kern.S_HMAX] = params.max_step
    S[kern.S_TAU] = 1.0 / (2.0 * math.pi * fc) if fc > 0 else 0.0
    S[kern.S_FILT] = params.pretension


def lane_group(params: RigParameters) -> tuple:
    """What rigs must share to run in the lanes of one :class:`ArmLanes`.

    The integrator, the elements, the eyelets, the damping's rank and the packed scalars that steer the
    kernel's branches (:func:`helpers.virtual._kernel.lane_key`).
    """
    a = model_arrays(params)
    return (params.integrator, a.n, tuple(int(d) for d in a.disc), a.cw.shape[0], kern.lane_key(a.P))


class ArmPlant:
    """The arm with its cable, stepper, load-cell carriage and amplifier, driven by stepper steps.

    Starts at rest at cable position 0 (tension = pretension, the rotor at its static lag), at ``t = 0``.

    Parameters
    ----------
    params : RigParameters
        The physical parameters (e.g. the tuned rig, ``RigParameters()``).
    """

    def __init__(self, params: RigParameters) -> None:
        if not isinstance(params, RigParameters):
            raise TypeError(f"params must be a RigParameters, got {type(params).__name__}")
        self.params = params
        self._arr = model_arrays(params)
        self._scheme = kern.SCHEMES.index(params.integrator)
        self._S = np.zeros(kern.N_STATE)
        self._L = np.zeros((1, kern.N_LANE_INTS), dtype=np.int64)
        self._work = kern.make_work(self._arr.n, self._arr.disc.shape[0])
        self.reset()

    # --- state -----------------------------------------------------------------------------------
    def reset(self) -> None:
        """Back to rest at cable position 0 and ``t = 0``."""
        self._y = np.array(self._arr.y_rest, dtype=float)
        self._steps = 0
        _reset_state(self._S, self._arr, self.params)

    @property
    def t(self) -> float:
        """Current simulated time, s."""
        return float(self._S[kern.S_T])

    @property
    def position_steps(self) -> int:
        """Commanded cable position in stepper steps (+ = pulled)."""
        return self._steps

    @property
    def u(self) -> float:
        """Commanded cable displacement from the rest position, m."""
        return self._steps * self.params.cable_per_step

    @property
    def n_elements(self) -> int:
        """Number of arc elements."""
        return self._arr.n

    @property
    def state(self) -> np.ndarray:
        """A copy of the state ``[theta (rad), theta' (rad/s), psi, psi', x_c, x_c']``."""
        return self._y.copy()

    def set_state(self, y: npt.ArrayLike, position_steps: int | None = None) -> None:
        """Overwrite the state (for tests and what-if runs); time and the amplifier are unchanged.

        ``position_steps`` also sets the commanded position (for a stepper, the commanded rotor angle).
        """
        y = np.asarray(y, dtype=float)
        if y.shape != self._y.shape or not np.all(np.isfinite(y)):
            raise ValueError(f"state must be {self._y.shape[0]} finite numbers")
        self._y = y.copy()
        if position_steps is not None:
            self._steps = int(position_steps)
            self._S[kern.S_DRIVE] = self._steps * self._arr.d_drive

    @property
    def integrator_steps(self) -> int:
        """Integrator steps taken since the last reset (a cost measure; transition searches included)."""
        return int(self._S[kern.S_NSTEP])

    @property
    def transitions(self) -> int:
        """Taut/slack transitions of the cables since the last reset."""
        return int(self._S[kern.S_NTRANS])

    @property
    def max_rotor_lag_steps(self) -> float:
        """Largest lag of the rotor behind its commanded angle since the last reset, in microsteps.

        A health figure: the sinusoidal torque law pulls out at a quarter of a tooth pitch, one full step =
        4 of these at 800 steps/rev; 0 for the ideal actuator.
        """
        return float(self._S[kern.S_HEALTH] / self.params.step_angle)

    @property
    def rotor_lag_steps(self) -> float:
        """The rotor's lag behind its commanded angle now, in microsteps; 0 for the ideal actuator.

        After a run, at rest: the steps lost (16 per tooth the rotor slipped) plus the small static lag that
        holds the tension.
        """
        if self.params.actuator == "ideal":
            return 0.0
        n = self.n_elements
        return float((self._S[kern.S_DRIVE] - self._y[2 * n]) / self.params.step_angle)

    def tension(self) -> float:
        """Tension of the measured cable now (true, not filtered), N."""
        a = self._arr
        _, _, _, lam1, lam2 = kern.rhs(self._y, self._S[kern.S_DRIVE], a.P, a.mb, a.Jb, a.disc, a.W, a.cw)
        spool = self.params.actuator == "stepper+carriage" and self.params.load_cell_side == "spool"
        return float(lam1 if spool else lam2)

    def amplifier_output(self) -> float:
        """The amplifier's output now, N (the tension through its low-pass filter)."""
        return float(self._S[kern.S_FILT])

    def energy(self) -> float:
        """Kinetic + bending + gravitational + cable + motor energy now, J (dissipated by damping).

        Computed from the state in numpy (:class:`~helpers.virtual.statics.ArcChain`), independently of
        the kernel: ``0.5 q'^T M(q) q' + sum EI/(2l) D^2 + g sum m y + the springs``; the arm-side cable's
        spring is ``e^2 / (2 (1/k + H(q)))`` with the bowing compliance ``H``.
        """
        p = self.params
        a = self._arr
        chain = ArcChain(p)
        n = a.n
        q, w = self._y[:n], self._y[n : 2 * n]
        th = chain.full_angles(q)
        kinetic = 0.5 * w @ chain.mass_matrix(q) @ w
        bending = 0.5 * chain.kap * float(np.sum(np.diff(th) ** 2))
        _, ypos = node_positions(p, q)
        gravity = p.g * float(np.sum(chain.m_nodes * ypos[1:]))
        ell = float(chain.cable_length(q))
        c2 = 1.0 / a.P[kern.I_K2] + float(chain.bow_compliance(q)[0])  # arm-side cable and the bowing
        R = p.spool_radius
        psi, psid, xc, xcd = self._y[2 * n :]
        drive = float(self._S[kern.S_DRIVE])

        def spring(k: float, e: float) -> float:
            return 0.5 * k * e * e if e > 0 else 0.0

        def arm_side(e: float) -> float:
            return 0.5 * e * e / c2 if e > 0 else 0.0

        P = a.P
        if p.actuator == "ideal":
            return kinetic + bending + gravity + arm_side(self.u + ell - P[kern.I_ELLREF])
        if p.torque_law == "sin":
            motor = p.holding_torque / p.rotor_teeth * (1.0 - math.cos(p.rotor_teeth * (drive - psi)))
        else:
            motor = 0.5 * p.motor_stiffness * (drive - psi) ** 2
        rest = kinetic + bending + gravity + motor + 0.5 * p.drive_inertia * psid**2
        if p.actuator == "stepper":
            return rest + arm_side(R * psi + ell - P[kern.I_ELLREF])
        return (rest + 0.5 * p.carriage_mass * xcd**2 + spring(P[kern.I_K1], R * psi - xc - P[kern.I_S1REF])
                + arm_side(xc + ell - P[kern.I_ELLREF]))  # fmt: skip

    def shape(self) -> tuple[np.ndarray, np.ndarray]:
        """Current backbone node positions ``(x, y)`` in m, clamp first."""
        return node_positions(self.params, self._y[: self._arr.n])

    # --- time ------------------------------------------------------------------------------------
    def advance(
        self,
        sample_times: npt.ArrayLike,
        step_times: npt.ArrayLike = (),
        step_signs: npt.ArrayLike = (),
        raw: bool = False,
        return_angles: bool = False,
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """Integrate to ``sample_times[-1]`` and return the amplifier's output (N) at each sample time.

        Parameters
        ----------
        sample_times : array_like
            Strictly increasing times (s), all >= :attr:`t`.
        step_times : array_like
            Times (s) of stepper steps in ``(t, sample_times[-1]]``, sorted. A step at exactly a sample time
            is applied before that sample.
        step_signs : array_like
            +1 (pull) or -1 (release) per step.
        raw : bool
            Return the true tension of the measured cable instead of the amplifier's output.
        return_angles : bool
            Also return the tangent angles at the samples, shape ``(n_samples, n_elements)``.

        Raises
        ------
        ValueError
            On unsorted, non-finite or out-of-range times, or signs other than +1/-1.
        FloatingPointError
            If the integration became unstable (``max_step`` too large for the parameters).
        """
        output, tension, angles = self.advance_all(sample_times, step_times, step_signs)
        out = tension if raw else output
        if return_angles:
            return out, angles
        return out

    def advance_all(
        self, sample_times: npt.ArrayLike, step_times: npt.ArrayLike = (), step_signs: npt.ArrayLike = ()
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """As :meth:`advance`, returning ``(amplifier output, true tension, angles)`` at the samples."""
        n = self._arr.n
        ts, st, sg = _checked_times(sample_times, step_times, step_signs, self.t)
        if ts.size == 0:
            return np.empty(0), np.empty(0), np.empty((0, n))
        out_raw = np.empty((1, ts.size))
        out_filt = np.empty((1, ts.size))
        angles = np.empty((1, ts.size, n))
        a = self._arr
        w = self._work
        kern.advance(
            self._scheme, self._y, self._S, self._L, ts[None], st[None], sg[None],
            np.array([st.size]), a.P, a.P, a.mb, a.Jb, a.disc, a.W, a.cw, *w, out_raw, out_filt, angles,
        )  # fmt: skip
        if not (np.all(np.isfinite(self._y)) and math.isfinite(self._S[kern.S_FILT])):
            raise unstable_error(ts[-1], self.params.max_step)
        self._S[kern.S_T] = max(self._S[kern.S_T], ts[-1])
        self._steps += int(np.sum(sg)) if sg.size else 0
        return out_filt[0], out_raw[0], angles[0]


class ArmLanes:
    """Several rigs driven together, one per lane of the compiled kernel, each as its :class:`ArmPlant`.

    The kernel's arithmetic runs on every lane at once (SIMD, :mod:`helpers.virtual.lanes`); each lane takes
    exactly the steps, splits and events its rig takes alone. The rigs must share :func:`lane_group`. They
    start at rest at ``t = 0``; lanes beyond the rigs given (up to :data:`LANE_WIDTHS`) repeat the last rig,
    and their results are dropped.

    Parameters
    ----------
    params : sequence of RigParameters
        One rig per lane, 1 to ``max(LANE_WIDTHS)``.
    """

    def __init__(self, params: Sequence[RigParameters]) -> None:
        params = list(params)
        if not 1 <= len(params) <= max(LANE_WIDTHS):
            raise ValueError(f"ArmLanes takes 1 to {max(LANE_WIDTHS)} rigs, got {len(params)}")
        for p in params:
            if not isinstance(p, RigParameters):
                raise TypeError(f"params must be RigParameters, got {type(p).__name__}")
        group = lane_group(params[0])
        for p in params[1:]:
            if lane_group(p) != group:
                raise ValueError("the rigs of one ArmLanes must share lane_group (integrator, elements, "
                                 "eyelets, damping rank, actuator and the kernel's switches)")  # fmt: skip
        self.params = tuple(params)
        width = min(w for w in LANE_WIDTHS if w >= len(params))
        self._rigs = params + [params[-1]] * (width - len(params))
        self._arrs = [model_arrays(p) for p in self._rigs]
        a0 = self._arrs[0]
        self._n = a0.n
        self._disc = a0.disc
        self._U = np.array(a0.P)
        self._scheme = kern.SCHEMES.index(params[0].integrator)

        def stacked(name: str) -> LaneArray:
            return LaneArray(np.ascontiguousarray(np.stack([getattr(a, name) for a in self._arrs], axis=-1)))

        self._P, self._mb, self._Jb, self._W, self._cw = (stacked(k) for k in ("P", "mb", "Jb", "W", "cw"))
        self._y = LaneArray(np.zeros((2 * self._n + 4, width)))
        self._S = LaneArray(np.zeros((kern.N_STATE, width)))
        self._L = np.zeros((width, kern.N_LANE_INTS), dtype=np.int64)
        self._work = kern.make_work(self._n, self._disc.shape[0], width)
        self.reset()

    @property
    def lanes(self) -> int:
        """Rigs driven (the lanes that count)."""
        return len(self.params)

    @property
    def width(self) -> int:
        """Lanes of the kernel call (the rigs, and the repeats that fill it)."""
        return len(self._rigs)

    def reset(self) -> None:
        """Every lane back to rest at cable position 0 and ``t = 0``."""
        for k, (a, p) in enumerate(zip(self._arrs, self._rigs, strict=True)):
            self._y.data[:, k] = a.y_rest
            _reset_state(self._S.data[:, k], a, p)

    @property
    def t(self) -> np.ndarray:
        """Each lane's simulated time, s."""
        return self._S.data[kern.S_T, : self.lanes].copy()

    @property
    def state(self) -> np.ndarray:
        """Each lane's state (rows: lanes), a copy."""
        return self._y.data[:, : self.lanes].T.copy()

    @property
    def integrator_steps(self) -> np.ndarray:
        """Each lane's integrator steps since the last reset (as :attr:`ArmPlant.integrator_steps`)."""
        return self._S.data[kern.S_NSTEP, : self.lanes].astype(np.int64)

    @property
    def transitions(self) -> np.ndarray:
        """Each lane's taut/slack transitions since the last reset."""
        return self._S.data[kern.S_NTRANS, : self.lanes].astype(np.int64)

    @property
    def max_rotor_lag_steps(self) -> np.ndarray:
        """Each lane's largest rotor lag since the last reset, microsteps (as :class:`ArmPlant`'s)."""
        lag = self._S.data[kern.S_HEALTH, : self.lanes]
        return np.array([lag[k] / p.step_angle for k, p in enumerate(self.params)])

    def save(self) -> tuple[np.ndarray, np.ndarray]:
        """Every lane's state and time, a copy (for :meth:`restore`)."""
        return self._y.data.copy(), self._S.data.copy()

    def restore(self, saved: tuple[np.ndarray, np.ndarray], lanes: Sequence[int]) -> None:
        """Put ``lanes`` back as they were when :meth:`save` gave ``saved`` (the others as they are)."""
        y, S = saved
        for k in lanes:
            self._y.data[:, k] = y[:, k]
            self._S.data[:, k] = S[:, k]

    def unstable(self) -> list[int]:
        """The lanes (of the rigs) whose state is no longer finite."""
        y, filt = self._y.data[:, : self.lanes], self._S.data[kern.S_FILT, : self.lanes]
        ok = np.all(np.isfinite(y), axis=0) & np.isfinite(filt)
        return [int(k) for k in np.flatnonzero(~ok)]

    def advance_all(
        self,
        sample_times: npt.ArrayLike,
        step_times: Sequence[npt.ArrayLike],
        step_signs: Sequence[npt.ArrayLike],
        check: bool = True,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Integrate every lane to ``sample_times[-1]``: :meth:`ArmPlant.advance_all` of each lane.

        Parameters
        ----------
        sample_times : array_like
            The samples, shared by every lane (strictly increasing, after every lane's time); or one row
            per rig ``(rigs, samples)``, each after that rig's own time (every rig the same number).
        step_times, step_signs : sequence of array_like
            Each rig's stepper steps and their signs (as :meth:`ArmPlant.advance`).
        check : bool
            Raise if a lane became unstable; False leaves that to the caller (:meth:`unstable`: those lanes'
            outputs are not finite, the others' are what they are alone).

        Returns
        -------
        (numpy.ndarray, numpy.ndarray, numpy.ndarray)
            Amplifier output and true tension ``(rigs, samples)``, angles ``(rigs, samples, elements)``.

        Raises
        ------
        ValueError
            As :meth:`ArmPlant.advance`, or not one step list per rig.
        FloatingPointError
            If a lane's integration became unstable (and ``check``).
        """
        if len(step_times) != self.lanes or len(step_signs) != self.lanes:
            raise ValueError(f"one step_times and step_signs per rig: {self.lanes}, got {len(step_times)}, "
                             f"{len(step_signs)}")  # fmt: skip
        n, width, lanes = self._n, self.width, self.lanes
        each = np.ndim(sample_times) == 2  # one row of samples per rig, each after that rig's own time
        if each and np.shape(sample_times)[0] != lanes:
            raise ValueError(f"one row of sample_times per rig: {lanes}, got {np.shape(sample_times)[0]}")
        rows = list(sample_times) if each else [sample_times] * lanes
        t_now = self._S.data[kern.S_T] if each else np.full(width, np.max(self._S.data[kern.S_T]))
        pairs = zip(rows, step_times, step_signs, strict=True)
        checked = [_checked_times(r, a, b, float(t_now[k])) for k, (r, a, b) in enumerate(pairs)]
        ts = checked[0][0]
        if ts.size == 0:
            return np.empty((lanes, 0)), np.empty((lanes, 0)), np.empty((lanes, 0, n))
        checked += [checked[-1]] * (width - lanes)
        # the lanes that fill the call repeat the last rig (from where it is: it may have been restored)
        self._y.data[:, lanes:] = self._y.data[:, lanes - 1 : lanes]
        self._S.data[:, lanes:] = self._S.data[:, lanes - 1 : lanes]
        samples = np.stack([c[0] for c in checked])
        counts = np.array([c[1].size for c in checked], dtype=np.int64)
        st = np.zeros((width, max(1, int(counts.max()))))
        sg = np.zeros_like(st)
        for k, (_, times, signs) in enumerate(checked):
            st[k, : times.size] = times
            sg[k, : signs.size] = signs
        out_raw = np.empty((width, ts.size))
        out_filt = np.empty((width, ts.size))
        angles = np.empty((width, ts.size, n))
        w = self._work
        kern.advance(
            self._scheme, self._y, self._S, self._L, samples, st, sg, counts,
            self._P, self._U, self._mb, self._Jb, self._disc, self._W, self._cw, *w, out_raw, out_filt,
            angles,
        )  # fmt: skip
        bad = self.unstable() if check else []
        if bad:
            raise FloatingPointError(
                f"the integration of lane(s) {bad} became unstable before t = {ts[-1]:.4f} s: max_step is "
                "too large for those parameters"
            )
        self._S.data[kern.S_T] = np.maximum(self._S.data[kern.S_T], samples[:, -1])
        return out_filt[:lanes], out_raw[:lanes], angles[:lanes]
