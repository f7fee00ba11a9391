"""The arm as a plant to drive in time: stepper steps in, cable tension out, state kept between calls.

:class:`ArmPlant` is what the emulated boards of the virtual rig stream from. It wraps the compiled
fixed-step integrator of :mod:`helpers.virtual._kernel`: each call integrates from the present time to the
last requested sample, splitting the integration at every stepper step and every sample instant (and,
inside the integrator, at every taut/slack transition of the cable).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from helpers.hardware import MM_PER_STEP
from helpers.virtual import _kernel as kern
from helpers.virtual.parameters import RigParameters
from helpers.virtual.statics import model_arrays, node_positions

__all__ = ["ArmPlant"]


class ArmPlant:
    """The nonlinear arm with its cable, driven by stepper steps.

    Starts at rest in static equilibrium at cable position 0 (tension = pretension), at ``t = 0``.

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
        self._du = MM_PER_STEP * 1e-3
        self._stats = np.zeros(2, dtype=np.int64)
        self.reset()

    # --- state -----------------------------------------------------------------------------------
    def reset(self) -> None:
        """Back to rest at cable position 0 and ``t = 0``."""
        n = self._arr.n
        self._y = np.concatenate([np.array(self._arr.phi_rest, dtype=float), np.zeros(n)])
        self._t = 0.0
        self._steps = 0
        self._stats[:] = 0

    @property
    def t(self) -> float:
        """Current simulated time, s."""
        return self._t

    @property
    def position_steps(self) -> int:
        """Cable position in stepper steps (+ = pulled)."""
        return self._steps

    @property
    def u(self) -> float:
        """Cable displacement from the rest position, m."""
        return self._steps * self._du

    @property
    def state(self) -> np.ndarray:
        """A copy of the state ``[phi (rad), phi' (rad/s)]`` of the segments."""
        return self._y.copy()

    def set_state(self, y: npt.ArrayLike, position_steps: int | None = None) -> None:
        """Overwrite the state (for tests and what-if runs); time is unchanged."""
        y = np.asarray(y, dtype=float)
        if y.shape != self._y.shape or not np.all(np.isfinite(y)):
            raise ValueError(f"state must be {self._y.shape[0]} finite numbers")
        self._y = y.copy()
        if position_steps is not None:
            self._steps = int(position_steps)

    @property
    def integrator_steps(self) -> int:
        """RK4 steps taken since the last reset (a cost measure)."""
        return int(self._stats[0])

    @property
    def transitions(self) -> int:
        """Taut/slack transitions of the cable since the last reset."""
        return int(self._stats[1])

    def tension(self) -> float:
        """Cable tension now, N."""
        return float(kern.tension_of(self._y[: self._arr.n], self.u, self._arr.P, self._arr.eye))

    def energy(self) -> float:
        """Kinetic + elastic + gravitational + cable energy now, J (damping dissipates it)."""
        a = self._arr
        return float(kern.energy(self._y, self.u, a.P, a.mu, a.m_nodes, a.kap, a.eye))

    def shape(self) -> tuple[np.ndarray, np.ndarray]:
        """Current backbone node positions ``(x, y)`` in m, clamp first."""
        return node_positions(self.params, self._y[: self._arr.n])

    # --- time ------------------------------------------------------------------------------------
    def advance(
        self,
        sample_times: npt.ArrayLike,
        step_times: npt.ArrayLike = (),
        step_signs: npt.ArrayLike = (),
        return_angles: bool = False,
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """Integrate to ``sample_times[-1]`` and return the cable tension (N, >= 0) at each sample time.

        Parameters
        ----------
        sample_times : array_like
            Strictly increasing times (s), all >= :attr:`t`.
        step_times : array_like
            Times (s) of stepper steps in ``(t, sample_times[-1]]``, sorted. A step at exactly a sample time
            is applied before that sample.
        step_signs : array_like
            +1 (pull) or -1 (release) per step; each step moves the cable by ``MM_PER_STEP`` mm.
        return_angles : bool
            Also return the segment angles at the samples, shape ``(n_samples, n_segments)``.

        Raises
        ------
        ValueError
            On unsorted, non-finite or out-of-range times, or signs other than +1/-1.
        """
        ts = np.ascontiguousarray(sample_times, dtype=float).reshape(-1)
        st = np.ascontiguousarray(step_times, dtype=float).reshape(-1)
        sg = np.ascontiguousarray(step_signs, dtype=float).reshape(-1)
        n = self._arr.n
        if ts.size == 0:
            return (np.empty(0), np.empty((0, n))) if return_angles else np.empty(0)
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
        tension = np.empty(ts.size)
        angles = np.empty((ts.size, n))
        a = self._arr
        t, _u = kern.advance(
            self._y, self._t, self.u, self._du, ts, st, sg, self.params.max_step,
            a.P, a.mu, a.kap, a.cj, a.eye, tension, angles, self._stats,
        )  # fmt: skip
        if not np.all(np.isfinite(self._y)):
            raise FloatingPointError(
                f"the integration became unstable before t = {ts[-1]:.4f} s: max_step = "
                f"{self.params.max_step:.2e} s is too large for these parameters"
            )
        self._t = float(max(t, ts[-1]))
        self._steps += int(np.sum(sg)) if sg.size else 0
        if return_angles:
            return tension, angles
        return tension
