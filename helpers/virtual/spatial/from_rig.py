"""The spatial twin built from a rig file (``docs/rig_file.md``): :func:`spatial_rig`.

One :class:`~helpers.virtual.spatial.rig.TendonSpec` per ``[[tendon]]`` (or the one tendon of a file without
them), the arm from ``[arm]`` (:func:`helpers.virtual.from_rig.rig_parameters`), ``gravity_direction`` and
``shear_modulus_gpa`` from ``[arm]``. The shipped ``rigs/paper.toml``, ``rigs/four-tendon.toml`` and
``rigs/hanging.toml`` give the built-in presets (to round-off in the arm's series stiffness).

``as_built=True`` is the arm the virtual rig's boards drive
(:func:`helpers.virtual.emulator.world.build_world`), the one place the ``[[tendon]] twin_eyelet_error_mm``
keys are read: each tendon's cable path is then that much off the geometry the planners know, in the direction
that lowers its tension, and the arm holds the tendon as if its cable were paid out by that much at position
0. That twin is the nominal one with each tendon's rest tension the nominal arm's with every stepper commanded
to minus its error (the same rest lengths, so the same arm; :func:`as_built_pretensions`). Every planner calls
:func:`spatial_rig` without it and keeps the nominal geometry; with every error 0 (or absent) the two twins
are equal, and every output is byte-identical.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from helpers.rigfile import RigFile
from helpers.virtual.from_rig import rig_parameters
from helpers.virtual.spatial.rig import SpatialRig, TendonSpec
from helpers.virtual.spatial.statics import equilibrium

__all__ = ["as_built_pretensions", "spatial_rig"]


def as_built_pretensions(rig: RigFile, twin: SpatialRig) -> np.ndarray | None:
    """Each tendon's rest tension on the arm as built (``twin_eyelet_error_mm``), N; None without errors.

    The nominal ``twin`` with every stepper commanded to minus its tendon's error (``rotor="free"``: the rotor
    at the lag its load needs): the tensions at which the arm as built rests at position 0.

    Raises
    ------
    ValueError
        An error that leaves a tendon slack at rest (named).
    """
    errors = np.array([t.twin_eyelet_error_mm for t in rig.tendons], dtype=float)
    if not np.any(errors):
        return None
    tension = equilibrium(twin, -errors * 1e-3, rotor="free").tension
    for i, (t, e) in enumerate(zip(tension, errors, strict=True)):
        if not t > 0.0:
            raise ValueError(
                f"{rig.source}: [[tendon]] #{i + 1} twin_eyelet_error_mm: {e:g} mm leaves tendon {i + 1} "
                f"slack at rest ({t:.3f} N): the twin needs every tendon taut at position 0"
            )
    return tension


def spatial_rig(rig: RigFile, *, as_built: bool = False, **changes: Any) -> SpatialRig:
    """The spatial twin of ``rig`` (``changes``: fields of :class:`SpatialRig`).

    ``as_built``: the arm the virtual rig's boards drive, with each tendon's ``twin_eyelet_error_mm``
    (module docstring); the default is the geometry the planners know.
    """
    arm = rig_parameters(rig, planar_gravity=False)
    tendons = tuple(
        TendonSpec(
            angle_deg=t.angle_deg,
            offset_mm=t.offset_mm,
            spool_diameter_mm=t.spool_diameter_mm,
            steps_per_rev=t.steps_per_rev,
            holding_torque_n_m=t.holding_torque_n_m,
            load_cell_range_n=t.load_cell_range_n,
            pretension_n=t.pretension_n,
            cable_stiffness_n_m=t.cable_stiffness_n_m,
        )  # fmt: skip
        for t in rig.tendons
    )
    fields: dict[str, Any] = {
        "arm": arm,
        "tendons": tendons,
        "gravity_direction": rig.arm.gravity_direction,
        "shear_modulus_gpa": rig.arm.shear_modulus_gpa,
        "name": rig.name,
    }
    fields.update(changes)
    twin = SpatialRig(**fields)
    tension = as_built_pretensions(rig, twin) if as_built else None
    if tension is None:
        return twin
    built = tuple(t.replace(pretension_n=float(v)) for t, v in zip(twin.tendons, tension, strict=True))
    return twin.replace(tendons=built)
