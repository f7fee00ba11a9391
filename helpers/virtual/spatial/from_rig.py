"""The spatial twin built from a rig file (``docs/rig_file.md``): :func:`spatial_rig`.

One :class:`~helpers.virtual.spatial.rig.TendonSpec` per ``[[tendon]]`` (or the one tendon of a file without
them), the arm from ``[arm]`` (:func:`helpers.virtual.from_rig.rig_parameters`), ``gravity_direction`` and
``shear_modulus_gpa`` from ``[arm]``. The shipped ``rigs/paper.toml``, ``rigs/four-tendon.toml`` and
``rigs/hanging.toml`` give the built-in presets (to round-off in the arm's series stiffness).
"""

from __future__ import annotations

from typing import Any

from helpers.rigfile import RigFile
from helpers.virtual.from_rig import rig_parameters
from helpers.virtual.spatial.rig import SpatialRig, TendonSpec

__all__ = ["spatial_rig"]


def spatial_rig(rig: RigFile, **changes: Any) -> SpatialRig:
    """The spatial twin of ``rig`` (``changes``: fields of :class:`SpatialRig`)."""
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
    return SpatialRig(**fields)
