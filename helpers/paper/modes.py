"""A vibration mode as a frequency and a damping ratio: the package's one argument convention.

Every function of the package that takes a mode takes the **frequency first, then the damping ratio**:
``f(omega, zeta)``. The argument's name says which frequency it is: ``omega_n`` is the undamped natural
frequency, ``omega_d = omega_n sqrt(1 - zeta^2)`` the damped one (what a free decay shows, and what the paper
identifies). Both are in rad/s. This module holds the conversion, computed nowhere else.
"""

from __future__ import annotations

import math
from typing import Any


def check_mode(omega: Any, zeta: Any, name: str = "omega_n") -> None:
    """Raise ``ValueError`` unless ``omega`` is a finite frequency > 0 and ``0 <= zeta < 1``.

    Parameters
    ----------
    omega : float
        A frequency in rad/s.
    zeta : float
        A damping ratio.
    name : str
        How the frequency is called in the message.
    """
    if _finite(omega, f"{name} must be a finite number (rad/s)") <= 0:
        raise ValueError(f"{name} must be > 0 rad/s, got {omega!r}")
    if not 0.0 <= _finite(zeta, "zeta must be a finite number") < 1.0:
        raise ValueError(f"zeta must lie in [0, 1), got {zeta!r}")


def _finite(value: Any, message: str) -> float:
    """``float(value)``; ``ValueError`` with ``message`` unless it is a finite number (a bool is not)."""
    number = not isinstance(value, bool) and (isinstance(value, int | float) or hasattr(value, "__float__"))
    if not (number and math.isfinite(float(value))):
        raise ValueError(f"{message}, got {value!r}")
    return float(value)


def omega_n_from_damped(omega_d: float, zeta: float) -> float:
    """Undamped natural frequency from the damped one: ``omega_n = omega_d / sqrt(1 - zeta^2)``.

    Parameters
    ----------
    omega_d : float
        Damped natural frequency (rad/s), e.g. the identified 25.085 rad/s.
    zeta : float
        Damping ratio in [0, 1).

    Returns
    -------
    float
        ``omega_n`` in rad/s.
    """
    check_mode(omega_d, zeta, "omega_d")
    return float(omega_d) / math.sqrt(1.0 - float(zeta) ** 2)


def omega_d_from_natural(omega_n: float, zeta: float) -> float:
    """Damped natural frequency from the undamped one: ``omega_d = omega_n sqrt(1 - zeta^2)``, rad/s.

    The inverse of :func:`omega_n_from_damped`, with the undamped ``omega_n`` (rad/s) and ``zeta`` in [0, 1).
    """
    check_mode(omega_n, zeta)
    return float(omega_n) * math.sqrt(1.0 - float(zeta) ** 2)
