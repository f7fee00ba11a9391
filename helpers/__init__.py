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

# ``python -m helpers ...``: while the package is imported to find the command, sys.argv[0] is "-m" (the
# interpreter's documented behaviour). Before anything else loads, a signal gives one line and its status.
if sys.argv[:1] == ["-m"]:
    from helpers.base.signals import end_at_once_on_signals

    end_at_once_on_signals()

from helpers.base.notebook import interactive, setup  # noqa: E402

__version__ = "0.1.0"

__all__ = ["__version__", "interactive", "setup"]
