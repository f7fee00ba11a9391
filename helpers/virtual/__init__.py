"""The virtual rig: a calibrated nonlinear simulation of the arm, its cable and its load cell.

The physics lives here (parameters, plant, sensor, statics, simulation, reference, calibration); the emulated
serial boards that speak the firmware's protocol live in sibling modules (``boards``, ``protocol_virtual``,
``server``). See ``docs/virtual_rig.md`` for every assumption and the validation.
"""

from helpers.virtual.calibration import calibrated_parameters
from helpers.virtual.parameters import MM_PER_STEP, RigParameters
from helpers.virtual.plant import ArmPlant
from helpers.virtual.sensor import LoadCell
from helpers.virtual.simulate import SimResult, simulate
from helpers.virtual.statics import equilibrium, frequency_map, linearise

__all__ = [
    "MM_PER_STEP",
    "RigParameters",
    "ArmPlant",
    "LoadCell",
    "SimResult",
    "simulate",
    "calibrated_parameters",
    "equilibrium",
    "linearise",
    "frequency_map",
]
