"""Helpers for reproducing *Input Shaping for Point-to-Point Motion with a Continuum Robot Arm*.

The notebooks in ``notebooks/`` hold the narrative; this package holds every computation a notebook needs, one
room per job (``docs/architecture.md``). Imports flow one way, from base facts up to procedures::

    paper, paths, hardware, backbone           base facts
    model, recordings, protocol                the linear model, the recording format, the serial protocol
    loadcell, identify, shapers                calibration file, identification, input shapers
    profiles, programmes                       velocity profiles, stepper programmes
    rig | virtual -> emulator                  serial drivers | the virtual rig's physics and emulated boards
    metrics, tables, plotting                  analysis
    rig_tuning, record, reproduce, __main__    procedures and the command line

**Convention for a vibration mode**: every function takes the frequency first, then the damping ratio,
``f(omega, zeta)``; the argument's name says which frequency (``omega_n`` undamped natural, ``omega_d``
damped), both in rad/s. ``helpers.modes`` holds the conversion ``omega_n = omega_d / sqrt(1 - zeta^2)``.
"""

from helpers.notebook import interactive, setup

__version__ = "0.1.0"

__all__ = ["__version__", "interactive", "setup"]
