"""What a sweep measures per run: the variables, their units and meaning, the moves, the status codes.

The measurements themselves are made by :mod:`helpers.research.sweep.runs`; this module holds only their
names, so
that code reading stored results needs neither the virtual rig nor Dask.
"""

from __future__ import annotations

__all__ = ["VARIABLES", "MOVES", "STATUS"]

MOVES = ("up", "down")
"""The moves of a pulse, the last dimension of the per-move variables."""

STATUS = {0: "done", 1: "design or programme refused at this point", 2: "integration failed"}
"""Meaning of ``status``."""

VARIABLES: dict[str, tuple[str, str, str]] = {
    "residual_pct": ("move", "%", "residual vibration of the true tension, % of the step"),
    "step_n": ("move", "N", "the step yf - y0 of the true tension"),
    "move_duration_s": ("move", "s", "from the move's start to its last step (shaper + t_p, quantised)"),
    "shaper_duration_s": ("move", "s", "move duration minus t_p = x_f / v_in"),
    "residual_adc_pct": ("seed,move", "%", "residual vibration read from the ADC, % of the step"),
    "peak_n": ("seed,move", "N", "Table II peak read from the ADC"),
    "overshoot_pct": ("seed,move", "%", "Table II overshoot read from the ADC"),
    "settling_ms": ("seed,move", "ms", "Table II settling time (5 % band) read from the ADC"),
    "max_rotor_lag_steps": ("", "microsteps", "largest rotor lag behind its command (health)"),
    "status": ("", "1", "0 done, 1 design or programme refused, 2 integration failed"),
    "rig_omega_d_rad_s": ("", "rad/s", "the rig's lowest mode at rest (linearised, rotor free): omega_d"),
    "rig_zeta": ("", "1", "the rig's lowest mode at rest: damping ratio"),
}
"""Result variable -> (extra dimensions after the run's, unit, meaning)."""
