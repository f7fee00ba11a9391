"""The rig as a plant to drive in time: stepper steps in, amplifier output out, state kept between calls.

:class:`ArmPlant` is what the emulated boards of the virtual rig stream from. It wraps the compiled
fixed-step integrator of :mod:`helpers.virtual._kernel`: each call integrates from the present time to the
last requested sample, splitting the integration at every stepper step and every sample instant (and,
inside the integrator, at every taut/slack transition of either cable). The amplifier's low-pass filter is
part of the state, so chunked calls give the same samples as one call.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from helpers.virtual import _kernel as kern
from helpers.virtual.parameters import RigParameters
from helpers.virtual.statics import ArcChain, model_arrays, node_positions

__all__ = ["ArmPlant"]


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
        self._stats = np.zeros(2, dtype=np.int64)
        self._health = np.zeros(1)
        fc = params.amp_bandwidth_hz
        self._tau = 1.0 / (2.0 * math.pi * fc) if fc > 0 else 0.0
        self.reset()

    # --- state -----------------------------------------------------------------------------------
    def reset(self) -> None:
        """Back to rest at cable position 0 and ``t = 0``."""
        self._y = np.array(self._arr.y_rest, dtype=float)
        self._t = 0.0
        self._drive = 0.0
        self._steps = 0
        self._filt = np.array([self._tau, self.params.pretension])
        self._stats[:] = 0
        self._health[:] = 0.0

    @property
    def t(self) -> float:
        """Current simulated time, s."""
        return self._t

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
            self._drive = self._steps * self._arr.d_drive

    @property
    def integrator_steps(self) -> int:
        """Integrator steps taken since the last reset (a cost measure; transition searches included)."""
        return int(self._stats[0])

    @property
    def transitions(self) -> int:
        """Taut/slack transitions of the cables since the last reset."""
        return int(self._stats[1])

    @property
    def max_rotor_lag_steps(self) -> float:
        """Largest lag of the rotor behind its commanded angle since the last reset, in microsteps.

        A health figure: the sinusoidal torque law pulls out at a quarter of a tooth pitch, one full step =
        4 of these at 800 steps/rev; 0 for the ideal actuator.
        """
        return float(self._health[0] / self.params.step_angle)

    @property
    def rotor_lag_steps(self) -> float:
        """The rotor's lag behind its commanded angle now, in microsteps; 0 for the ideal actuator.

        After a run, at rest: the steps lost (16 per tooth the rotor slipped) plus the small static lag that
        holds the tension.
        """
        if self.params.actuator == "ideal":
            return 0.0
        n = self.n_elements
        return float((self._drive - self._y[2 * n]) / self.params.step_angle)

    def tension(self) -> float:
        """Tension of the measured cable now (true, not filtered), N."""
        a = self._arr
        _, _, _, lam1, lam2 = kern.rhs(self._y, self._drive, a.P, a.mb, a.Jb, a.disc, a.W, a.cw)
        spool = self.params.actuator == "stepper+carriage" and self.params.load_cell_side == "spool"
        return float(lam1 if spool else lam2)

    def amplifier_output(self) -> float:
        """The amplifier's output now, N (the tension through its low-pass filter)."""
        return float(self._filt[1])

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

        def spring(k: float, e: float) -> float:
            return 0.5 * k * e * e if e > 0 else 0.0

        def arm_side(e: float) -> float:
            return 0.5 * e * e / c2 if e > 0 else 0.0

        P = a.P
        if p.actuator == "ideal":
            return kinetic + bending + gravity + arm_side(self.u + ell - P[kern.I_ELLREF])
        if p.torque_law == "sin":
            motor = p.holding_torque / p.rotor_teeth * (1.0 - math.cos(p.rotor_teeth * (self._drive - psi)))
        else:
            motor = 0.5 * p.motor_stiffness * (self._drive - psi) ** 2
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
        ts = np.ascontiguousarray(sample_times, dtype=float).reshape(-1)
        st = np.ascontiguousarray(step_times, dtype=float).reshape(-1)
        sg = np.ascontiguousarray(step_signs, dtype=float).reshape(-1)
        n = self._arr.n
        if ts.size == 0:
            return np.empty(0), np.empty(0), np.empty((0, n))
        if not np.all(np.isfinite(ts)):
            raise ValueError("sample_times must be finite")
        if np.any(np.diff(ts) <= 0):
            raise ValueError("sample_times must be strictly increasing")
        if ts[0] < self._t - 1e-12:
            raise ValueError(
                f"sample_times must not precede the plant's time {self._t:.6f} s (got {ts[0]:.6f})"
            )
        if st.shape != sg.shape:
            raise ValueError(f"step_times ({st.size}) and step_signs ({sg.size}) differ in length")
        if st.size:
            if not np.all(np.isfinite(st)):
                raise ValueError("step_times must be finite")
            if np.any(np.diff(st) < 0):
                raise ValueError("step_times must be sorted")
            if st[0] < self._t - 1e-12 or st[-1] > ts[-1] + 1e-12:
                raise ValueError(
                    f"step_times must lie in (t, last sample] = ({self._t:.6f}, {ts[-1]:.6f}] s, "
                    f"got {st[0]:.6f} .. {st[-1]:.6f}"
                )
            if not np.all(np.abs(sg) == 1):
                raise ValueError("step_signs must be +1 (pull) or -1 (release)")
        out_raw = np.empty(ts.size)
        out_filt = np.empty(ts.size)
        angles = np.empty((ts.size, n))
        a = self._arr
        t, drive = kern.advance(
            self._scheme, self._y, self._t, self._drive, a.d_drive, ts, st, sg, self.params.max_step, a.P,
            a.mb, a.Jb, a.disc, a.W, a.cw, self._filt, out_raw, out_filt, angles, self._stats, self._health,
        )  # fmt: skip
        if not (np.all(np.isfinite(self._y)) and math.isfinite(self._filt[1])):
            raise FloatingPointError(
                f"the integration became unstable before t = {ts[-1]:.4f} s: max_step = "
                f"{self.params.max_step:.2e} s is too large for these parameters"
            )
        self._t = float(max(t, ts[-1]))
        self._drive = float(drive)
        self._steps += int(np.sum(sg)) if sg.size else 0
        return out_filt, out_raw, angles
