"""Helpers for reproducing *Input Shaping for Point-to-Point Motion with a Continuum Robot Arm*.

The notebooks in ``notebooks/`` hold the narrative; this package holds the computations they need: a thin
core with the paper's part (``base``, ``paper``, ``recordings``, ``board``, ``rig``, ``plotting``) and three
wings on it (``virtual``: the twin; ``research``: beyond the paper; ``commands``: the command line). The one
map of what lives where, and of the one-way flow of imports, is ``docs/architecture.md``.

**Convention for a vibration mode**: every function takes the frequency first, then the damping ratio,
``f(omega, zeta)``; the argument's name says which frequency (``omega_n`` undamped natural, ``omega_d``
damped), both in rad/s. ``helpers.paper.modes`` holds the conversion ``omega_n = omega_d / sqrt(1 - zeta^2)``.
"""

import sys


def _run_as_command(argv: list[str]) -> bool:
    """Whether the interpreter was started as ``python [options] -m helpers ...`` (``sys.orig_argv``)."""
    with_value = ("-X", "-W", "-Q")
    i = 1
    while i < len(argv) and argv[i].startswith("-"):
        if argv[i] == "-m":
            return argv[i + 1 : i + 2] == ["helpers"]
        if argv[i] == "-c":
            return False
        i += 2 if argv[i] in with_value else 1
    return False


if _run_as_command(getattr(sys, "orig_argv", [])):  # before anything else loads: a signal gives one line
    from helpers.base.signals import end_at_once_on_signals

    end_at_once_on_signals()

from helpers.base.notebook import interactive, setup  # noqa: E402

__version__ = "0.1.0"

__all__ = ["__version__", "interactive", "setup"]
