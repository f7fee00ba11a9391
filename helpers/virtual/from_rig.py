"""The planar virtual rig built from a rig file (``docs/rig_file.md``): :func:`rig_parameters`.

The file's ``[arm]`` and ``[hardware]`` (tendon 1's stepper, spool and load cell, the ADC chain) become
:class:`~helpers.virtual.parameters.RigParameters`; the twin's parameters the file does not hold (the rotor's
and spool's inertia, the load-cell carriage, the amplifier's bandwidth, the ADC noise, the damping floor) keep
the paper rig's values, an assumption for any other rig. The paper's file gives ``RigParameters()`` (the
tuned rig) to the last digit but the series stiffness ``k``, which is rebuilt from the file's cable stiffness
and the microstep spring (to round-off).
"""

from __future__ import annotations

import math
from typing import Any

from helpers.rigfile import RigFile
from helpers.rigfile.units import si
from helpers.virtual.parameters import RigParameters

__all__ = ["rig_parameters", "base_angle_deg", "tendon_gravity", "planar_holds", "ROTOR_TEETH"]

ROTOR_TEETH = 50
"""Rotor teeth of a 1.8 degree hybrid stepper (the microstep spring ``T_h N_r``)."""


def base_angle_deg(gravity_direction: tuple[float, float, float]) -> float:
    """The planar rig's clamp direction for a gravity direction in the clamp's x-z plane, degrees.

    The planar rig's gravity is ``(-cos b, 0, -sin b)``; a direction with a ``y`` component is not planar.
    """
    gx, gy, gz = gravity_direction
    norm = math.sqrt(gx * gx + gy * gy + gz * gz)
    if abs(gy) > 1e-12 * norm:
        raise ValueError(
            f"gravity_direction {list(gravity_direction)} leaves the tendon's plane: the planar twin needs "
            "y = 0 (use the spatial twin)"
        )
    return math.degrees(math.atan2(-gz, -gx)) + 0.0


def tendon_gravity(rig: RigFile, tendon: int = 0) -> tuple[float, float, float]:
    """``[arm] gravity_direction`` in tendon ``tendon``'s frame: ``x`` towards the tendon, ``z`` the backbone.

    The planar twin bends in the plane of the backbone and its tendon; the rig file's frame has ``x`` towards
    angle 0, so a tendon at angle ``a`` sees gravity turned by ``-a`` about the backbone (a tendon at 180 deg
    on the horizontal paper arm hangs below it: gravity pulls the arm towards it).
    """
    gx, gy, gz = rig.arm.gravity_direction
    a = math.radians(rig.tendons[tendon].angle_deg)
    c, s = math.cos(a), math.sin(a)
    if s == 0.0 and c == 1.0:  # the paper's tendon at 0: the file's vector as it is, to the last digit
        return float(gx), float(gy), float(gz)
    return gx * c + gy * s, -gx * s + gy * c, float(gz)


def planar_holds(rig: RigFile) -> bool:
    """True for a rig the planar twin describes: one tendon, and gravity in the plane of it and the backbone.

    A one-tendon rig whose gravity has a component across that plane sags out of it: the virtual rig and the
    predictions use the spatial twin with its one tendon instead (``docs/rig_file.md``).
    """
    if rig.n_tendons != 1:
        return False
    gx, gy, gz = tendon_gravity(rig)
    return abs(gy) <= 1e-12 * math.sqrt(gx * gx + gy * gy + gz * gz)


def rig_parameters(
    rig: RigFile, tendon: int = 0, planar_gravity: bool = True, **changes: Any
) -> RigParameters:
    """The planar twin of ``rig``'s tendon ``tendon`` (0-based), with ``changes`` to any field.

    Parameters
    ----------
    rig : RigFile
        A checked rig file.
    tendon : int
        Which tendon's stepper, spool, load cell, offset, pretension and cable the planar twin carries.
    planar_gravity : bool
        Set ``base_angle_deg`` from ``[arm] gravity_direction`` seen from the tendon (:func:`tendon_gravity`,
        which must lie in the tendon's plane); False keeps 0 (the spatial twin, which reads
        ``gravity_direction`` itself).
    **changes
        Fields of :class:`RigParameters` to set instead.
    """
    a = rig.arm
    t = rig.tendons[tendon]
    spool = si(t.spool_diameter_mm, -3)
    R = 0.5 * spool
    k = 1.0 / (1.0 / t.cable_stiffness_n_m + R**2 / (t.holding_torque_n_m * ROTOR_TEETH))
    fields: dict[str, Any] = {
        "E": si(a.youngs_modulus_gpa, 9),
        "rho": float(a.density_kg_m3),
        "d": si(a.backbone_diameter_mm, -3),
        "L": si(a.length_mm, -3),
        "n_discs": int(a.discs),
        "disc_mass": si(a.disc_mass_g, -3),
        "disc_radius": si(a.disc_radius_mm, -3),
        "disc_thickness": si(a.disc_thickness_mm, -3),
        "r": si(t.offset_mm, -3),
        "k": k,
        "pretension": float(t.pretension_n),
        "base_angle_deg": base_angle_deg(tendon_gravity(rig, tendon)) if planar_gravity else 0.0,
        "g": float(a.gravity_m_s2),
        "alpha": float(a.damping_alpha_per_s),
        "beta_chord": float(a.damping_beta_chord_s),
        "steps_per_rev": int(t.steps_per_rev),
        "spool_diameter": spool,
        "holding_torque": float(t.holding_torque_n_m),
        "rotor_teeth": ROTOR_TEETH,
        "span_n": float(t.load_cell_range_n),
        "loop_zero_ma": float(rig.hardware.loop_zero_ma),
        "loop_full_ma": float(rig.hardware.loop_full_ma),
        "loop_min_ma": float(rig.hardware.loop_min_ma),
        "loop_max_ma": float(rig.hardware.loop_max_ma),
        "shunt_ohm": float(rig.hardware.shunt_ohm),
        "adc_vref_v": float(rig.hardware.adc_vref_v),
        "adc_bits": int(rig.hardware.adc_bits),
    }
    fields.update(changes)
    return RigParameters(**fields)
