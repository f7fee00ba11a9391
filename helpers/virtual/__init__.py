"""The virtual rig's physics: a tuned nonlinear simulation of the arm, cable, stepper and load cell.

Physics only (parameters, plant, sensor, statics, simulation, the ``solve_ivp`` reference); it imports
neither pyserial nor anything of the serial side. The emulated boards that put it behind the firmware's
protocol live in :mod:`helpers.virtual.emulator`, and the procedure that tunes its unknown parameters in
:mod:`helpers.virtual.tuning`. ``RigParameters()`` is the tuned rig. See ``docs/virtual_rig.md`` for every
assumption and the validation.
"""

from helpers.virtual.parameters import RigParameters, parameter_table
from helpers.virtual.plant import ArmPlant
from helpers.virtual.sensor import LoadCell
from helpers.virtual.simulate import SimResult, simulate
from helpers.virtual.statics import ArcChain, equilibrium, frequency_map, linearise

__all__ = [
    "RigParameters",
    "parameter_table",
    "ArmPlant",
    "LoadCell",
    "SimResult",
    "simulate",
    "equilibrium",
    "linearise",
    "frequency_map",
    "ArcChain",
]
