"""The spatial twin's description: the arm, up to four tendons and the direction of gravity.

Dataclasses whose field names are the rig file's keys (``docs/rig_file.md``): one :class:`TendonSpec`
per ``[[tendon]]`` table (``angle_deg``, ``offset_mm``, ``spool_diameter_mm``, ``steps_per_rev``,
``holding_torque_n_m``, ``load_cell_range_n``, ``pretension_n``, ``cable_stiffness_n_m``) and a
:class:`SpatialRig` holding the arm (the planar rig's :class:`~helpers.virtual.parameters.RigParameters`,
tuned values included: rod, discs, damping, the stepper's rotor and the load-cell carriage), the tendons,
``gravity_direction`` (a vector in the clamp frame) and the rod's ``shear_modulus_gpa``.

The clamp frame: ``z`` along the backbone at the clamp (towards the tip), ``x`` towards tendon 1 (angle 0),
``y`` at 90 degrees, so a tendon at ``angle_deg`` sits at ``offset (cos a, sin a, 0)`` in each disc's plane.
Three rigs are built in (:data:`PRESETS`): the paper's one-tendon rig (the default; the planar rig seen in
space), a four-tendon extension of it (its rod and discs, horizontal, four tendons at 90 degrees with the
paper's stepper and load cell on each: an *assumption*, no such rig was published) and the same arm hanging
with gravity along the backbone. ``docs/spatial_twin.md`` lists every parameter with its source.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from helpers.virtual.parameters import RigParameters

__all__ = [
    "TendonSpec",
    "SpatialRig",
    "MAX_TENDONS",
    "G_A228_GPA",
    "paper_rig",
    "four_tendon_rig",
    "hanging_rig",
    "PRESETS",
    "preset",
    "spatial_parameter_table",
]

MAX_TENDONS = 4
"""Tendons a rig may have."""

G_A228_GPA = 79.3
"""Shear modulus of ASTM A228 music wire, GPa (11.5e6 psi, the value spring-wire tables give beside
E = 30e6 psi; E / (2 (1 + nu)) with nu = 0.30 gives 79.5)."""


def _finite(value: object, name: str, lo: float | None = None, positive: bool = False) -> float:
    ok = isinstance(value, int | float | np.floating) and not isinstance(value, bool) and math.isfinite(value)
    if ok and positive:
        ok = value > 0
    if ok and lo is not None:
        ok = value >= lo
    if not ok:
        need = "a positive finite number" if positive else (f"a finite number >= {lo}" if lo is not None
                                                            else "a finite number")  # fmt: skip
        raise ValueError(f"{name} must be {need}, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class TendonSpec:
    """One tendon with its stepper and load cell (a ``[[tendon]]`` table of the rig file; units in the names).

    Attributes
    ----------
    angle_deg : float
        Angle of the tendon around the backbone, degrees, counter-clockwise seen from the tip's side of the
        clamp, 0 = tendon 1's direction (the clamp frame's ``x``).
    offset_mm : float
        Distance of the eyelets from the backbone's axis, mm (the planar rig's tuned ``r`` by default).
    spool_diameter_mm : float
        The stepper's cable spool, mm (paper: 65).
    steps_per_rev : int
        Microsteps per revolution (paper: 800).
    holding_torque_n_m : float
        Amplitude of the stepper's torque law, N m (the planar rig's assumed 1.5 x 4.3 kg cm by default).
    load_cell_range_n : float
        Load that drives the load cell's 4-20 mA loop to 20 mA, N (the planar rig's ``span_n``).
    pretension_n : float
        Tension of this tendon with the arm at rest and every tendon at position 0, N.
    cable_stiffness_n_m : float or None
        Stiffness of the cables and the load cell between the spool and the arm, N/m (the microstep spring
        is added from the stepper); ``None``: the planar rig's tuned value, ``RigParameters().k_cable``.
    """

    angle_deg: float = 0.0
    offset_mm: float = RigParameters().r * 1e3
    spool_diameter_mm: float = RigParameters().spool_diameter * 1e3
    steps_per_rev: int = RigParameters().steps_per_rev
    holding_torque_n_m: float = RigParameters().holding_torque
    load_cell_range_n: float = RigParameters().span_n
    pretension_n: float = RigParameters().pretension
    cable_stiffness_n_m: float | None = None

    def __post_init__(self) -> None:
        _finite(self.angle_deg, "TendonSpec.angle_deg")
        for name in ("offset_mm", "spool_diameter_mm", "holding_torque_n_m", "load_cell_range_n"):
            _finite(getattr(self, name), f"TendonSpec.{name}", positive=True)
        _finite(self.pretension_n, "TendonSpec.pretension_n", lo=0.0)
        if self.cable_stiffness_n_m is not None:
            _finite(self.cable_stiffness_n_m, "TendonSpec.cable_stiffness_n_m", positive=True)
        n = self.steps_per_rev
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
            raise ValueError(f"TendonSpec.steps_per_rev must be a positive integer, got {n!r}")

    @classmethod
    def from_arm(cls, arm: RigParameters, angle_deg: float = 0.0, **changes: Any) -> TendonSpec:
        """The planar rig's tendon (offset, spool, steps, motor, load cell, pretension, cable) at an angle."""
        base = {
            "angle_deg": angle_deg,
            "offset_mm": arm.r * 1e3,
            "spool_diameter_mm": arm.spool_diameter * 1e3,
            "steps_per_rev": arm.steps_per_rev,
            "holding_torque_n_m": arm.holding_torque,
            "load_cell_range_n": arm.span_n,
            "pretension_n": arm.pretension,
            "cable_stiffness_n_m": arm.k_cable,
        }
        base.update(changes)
        return cls(**base)

    def replace(self, **changes: Any) -> TendonSpec:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """The fields as the ``[[tendon]]`` table's keys and values."""
        return dataclasses.asdict(self)


def _default_tendons() -> tuple[TendonSpec, ...]:
    return (TendonSpec.from_arm(RigParameters()),)


@dataclass(frozen=True)
class SpatialRig:
    """The spatial twin: the arm, its tendons (1 to 4) and gravity (SI inside, units in the field names).

    The defaults are the paper's rig: the tuned planar arm with its one tendon at angle 0, horizontal, the
    tendon on top (gravity along ``-x`` of the clamp frame).

    Attributes
    ----------
    arm : RigParameters
        The rod, the discs, the damping, the stepper's rotor and spool inertia, its torque law, the
        load-cell carriage and the amplifier (the planar rig's fields, tuned values included). Its ``r``,
        ``k``, ``pretension``, ``spool_diameter``, ``steps_per_rev``, ``holding_torque`` and ``span_n`` are
        each tendon's own in :attr:`tendons`; ``base_angle_deg`` is replaced by :attr:`gravity_direction`.
        The spatial twin supports the ``stepper+carriage`` actuator with the load cell on the arm side.
    tendons : tuple of TendonSpec
        One to :data:`MAX_TENDONS` tendons; the first is tendon 1. All run straight from eyelet to eyelet
        through the clamp's guide and every disc and are knotted at the tip disc. None: a bare rod
        (:mod:`helpers.virtual.spatial.bare_rod`).
    gravity_direction : tuple of 3 floats
        Direction of gravity in the clamp frame (normalised; its size ``arm.g``): ``(-1, 0, 0)`` for the
        paper's horizontal arm with tendon 1 on top, ``(0, 0, 1)`` for an arm hanging from its clamp.
    shear_modulus_gpa : float
        The rod's shear modulus (torsion), GPa (*handbook*, :data:`G_A228_GPA`).
    tip_inertia_scale : float
        Factor on the tip disc's rotary inertia about its diameters (*numerical*, 1 = the physical disc):
        a device that slows the tip disc rocking against the tendons, the mode that limits the integrator's
        step (``docs/spatial_twin.md``, section 7); not used unless asked for.
    name : str
        A label (the preset's name).
    """

    arm: RigParameters = field(default_factory=RigParameters)
    tendons: tuple[TendonSpec, ...] = field(default_factory=_default_tendons)
    gravity_direction: tuple[float, float, float] = (-1.0, 0.0, 0.0)
    shear_modulus_gpa: float = G_A228_GPA
    tip_inertia_scale: float = 1.0
    name: str = "paper"

    def __post_init__(self) -> None:
        if not isinstance(self.arm, RigParameters):
            raise TypeError(f"SpatialRig.arm must be a RigParameters, got {type(self.arm).__name__}")
        if self.arm.actuator != "stepper+carriage" or self.arm.load_cell_side != "arm":
            raise ValueError(
                "the spatial twin models the stepper+carriage actuator with the load cell on the arm "
                f"side, got actuator {self.arm.actuator!r}, load_cell_side {self.arm.load_cell_side!r}"
            )
        if self.arm.eyelet_mu != 0.0 or self.arm.eyelets_every_node or self.arm.disc_mass_uniform:
            raise ValueError(
                "the spatial twin is frictionless with eyelets on the discs (eyelet_mu = 0, "
                "eyelets_every_node and disc_mass_uniform off)"
            )
        tendons = tuple(self.tendons)
        object.__setattr__(self, "tendons", tendons)
        if not 0 <= len(tendons) <= MAX_TENDONS or not all(isinstance(t, TendonSpec) for t in tendons):
            raise ValueError(
                f"SpatialRig.tendons must hold 1 to {MAX_TENDONS} TendonSpec (none: a bare rod), "
                f"got {len(tendons)}"
            )
        angles = [t.angle_deg % 360.0 for t in tendons]
        for i in range(len(angles)):
            for j in range(i):
                gap = abs((angles[i] - angles[j] + 180.0) % 360.0 - 180.0)
                if gap < 1.0:
                    raise ValueError(
                        f"tendons {j + 1} and {i + 1} sit at the same angle ({angles[i]:.1f} deg)"
                    )
        g = np.asarray(self.gravity_direction, dtype=float)
        if g.shape != (3,) or not np.all(np.isfinite(g)) or np.linalg.norm(g) < 1e-12:
            raise ValueError(
                f"SpatialRig.gravity_direction must be a nonzero 3-vector, got {self.gravity_direction!r}"
            )
        object.__setattr__(self, "gravity_direction", tuple(float(v) for v in g / np.linalg.norm(g)))
        _finite(self.shear_modulus_gpa, "SpatialRig.shear_modulus_gpa", positive=True)
        _finite(self.tip_inertia_scale, "SpatialRig.tip_inertia_scale", positive=True)
        for i, t in enumerate(tendons):
            R = 0.5e-3 * t.spool_diameter_mm
            if t.pretension_n * R >= t.holding_torque_n_m:
                raise ValueError(
                    f"tendon {i + 1}: pretension {t.pretension_n} N exceeds the motor's pull-out tension "
                    f"{t.holding_torque_n_m / R:.2f} N"
                )

    def replace(self, **changes: Any) -> SpatialRig:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def with_tendons(self, **changes: Any) -> SpatialRig:
        """A copy with the same change applied to every tendon (e.g. ``pretension_n=1.0``)."""
        return self.replace(tendons=tuple(t.replace(**changes) for t in self.tendons))

    # --- the arm -----------------------------------------------------------------------------------
    @property
    def n_tendons(self) -> int:
        """Number of tendons."""
        return len(self.tendons)

    @property
    def G(self) -> float:  # noqa: N802 - the conventional symbol
        """Shear modulus, Pa."""
        return self.shear_modulus_gpa * 1e9

    @property
    def GJ(self) -> float:  # noqa: N802 - the conventional symbol
        """Torsional stiffness of the rod, N m^2 (``G pi d^4 / 32``)."""
        return self.G * math.pi * self.arm.d**4 / 32.0

    @property
    def gravity(self) -> np.ndarray:
        """Gravity's acceleration in the clamp frame, m/s^2."""
        return self.arm.g * np.asarray(self.gravity_direction)

    @property
    def angles(self) -> np.ndarray:
        """Tendon angles, rad."""
        return np.radians([t.angle_deg for t in self.tendons])

    @property
    def offsets(self) -> np.ndarray:
        """Eyelet offset vectors of the tendons in a disc's frame, m, shape (n_tendons, 3)."""
        a = self.angles
        r = np.array([t.offset_mm * 1e-3 for t in self.tendons])
        return np.stack([r * np.cos(a), r * np.sin(a), np.zeros_like(a)], axis=-1)

    @property
    def disc_polar_inertia(self) -> float:
        """Rotary inertia of a disc about the backbone, kg m^2 (``m R^2 / 2``)."""
        return 0.5 * self.arm.disc_mass * self.arm.disc_radius**2

    @property
    def pretensions(self) -> np.ndarray:
        """Pretension of each tendon, N."""
        return np.array([t.pretension_n for t in self.tendons])

    # --- each tendon's actuator ------------------------------------------------------------------------
    def spool_radius(self, i: int) -> float:
        """Spool radius of tendon ``i`` (0-based), m."""
        return 0.5e-3 * self.tendons[i].spool_diameter_mm

    def cable_per_step(self, i: int) -> float:
        """Cable per microstep of tendon ``i``, m."""
        t = self.tendons[i]
        return math.pi * t.spool_diameter_mm * 1e-3 / t.steps_per_rev

    def step_angle(self, i: int) -> float:
        """Commanded rotor increment per microstep of tendon ``i``, rad."""
        return 2.0 * math.pi / self.tendons[i].steps_per_rev

    def motor_stiffness(self, i: int) -> float:
        """Small-angle microstep stiffness ``T_h N_r`` of tendon ``i``'s stepper, N m/rad."""
        return self.tendons[i].holding_torque_n_m * self.arm.rotor_teeth

    def k_cable(self, i: int) -> float:
        """Cables and load cell of tendon ``i`` between spool and arm, N/m."""
        k = self.tendons[i].cable_stiffness_n_m
        return self.arm.k_cable if k is None else float(k)

    def k_series(self, i: int) -> float:
        """Everything between tendon ``i``'s commanded rotor angle and the arm, N/m (microstep spring too)."""
        R = self.spool_radius(i)
        return 1.0 / (1.0 / self.k_cable(i) + R**2 / self.motor_stiffness(i))

    def k_spool_side(self, i: int) -> float:
        """Tendon ``i``'s cable between spool and carriage, N/m."""
        return self.k_cable(i) / self.arm.spool_side_share

    def k_arm_side(self, i: int) -> float:
        """Tendon ``i``'s cable between carriage and arm (with the load cell), N/m."""
        return self.k_cable(i) / (1.0 - self.arm.spool_side_share)

    def rotor_damping(self, i: int) -> float:
        """Rotor viscous coefficient of tendon ``i`` from ``arm.rotor_zeta`` (the planar rule), N m s/rad."""
        R = self.spool_radius(i)
        return (
            2.0
            * self.arm.rotor_zeta
            * math.sqrt((self.motor_stiffness(i) + self.k_spool_side(i) * R**2) * self.arm.drive_inertia)
        )

    def carriage_damping(self, i: int) -> float:
        """Carriage viscous coefficient of tendon ``i`` from ``arm.carriage_zeta``, N s/m."""
        return (
            2.0
            * self.arm.carriage_zeta
            * math.sqrt((self.k_spool_side(i) + self.k_arm_side(i)) * self.arm.carriage_mass)
        )

    def static_lag(self, i: int, tension: float) -> float:
        """Rotor lag (rad) of tendon ``i``'s stepper carrying ``tension``; NaN beyond its pull-out tension."""
        torque = self.spool_radius(i) * tension
        th = self.tendons[i].holding_torque_n_m
        if self.arm.torque_law == "sin":
            x = torque / th
            return math.asin(x) / self.arm.rotor_teeth if abs(x) <= 1.0 else math.nan
        return torque / self.motor_stiffness(i)

    def tangent_motor_stiffness(self, i: int, delta: float) -> float:
        """d(torque)/d(lag) of tendon ``i``'s stepper at lag ``delta``, N m/rad."""
        if self.arm.torque_law == "sin":
            return self.motor_stiffness(i) * math.cos(self.arm.rotor_teeth * delta)
        return self.motor_stiffness(i)

    def gain_counts_per_n(self, i: int) -> float:
        """ADC counts per newton of tendon ``i``'s load-cell chain."""
        zero, full, _, _ = self.arm.loop_a
        return self.arm.loop_counts(full - zero) / self.tendons[i].load_cell_range_n

    def metadata(self) -> dict[str, Any]:
        """Every field as flat JSON values (the arm's under ``arm``, one dict per tendon)."""
        return {
            "name": self.name,
            "gravity_direction": list(self.gravity_direction),
            "shear_modulus_gpa": self.shear_modulus_gpa,
            "tip_inertia_scale": self.tip_inertia_scale,
            "tendon": [
                t.to_dict() | {"cable_stiffness_n_m": self.k_cable(i)} for i, t in enumerate(self.tendons)
            ],
            "arm": self.arm.metadata(),
        }


# --- the three rigs ---------------------------------------------------------------------------------------
def paper_rig(arm: RigParameters | None = None) -> SpatialRig:
    """The paper's rig in space: the tuned arm, one tendon at 0 (on top), horizontal (the planar rig's twin).

    Gravity follows the planar rig's ``base_angle_deg`` (0: horizontal clamp): ``(-cos b, 0, -sin b)``.
    """
    arm = RigParameters() if arm is None else arm
    b = arm.base_angle
    return SpatialRig(arm=arm, tendons=(TendonSpec.from_arm(arm),),
                      gravity_direction=(-math.cos(b), 0.0, -math.sin(b)), name="paper")  # fmt: skip


def four_tendon_rig(arm: RigParameters | None = None, pretension_n: float | None = None) -> SpatialRig:
    """An assumed four-tendon extension of the paper's rig (no such rig was published).

    Its rod and discs, horizontal, tendons at 0, 90, 180 and 270 degrees (tendon 1 on top), each with the
    paper's stepper, spool, load cell and the tuned
    offset, cable and pretension.
    """
    arm = RigParameters() if arm is None else arm
    pre = arm.pretension if pretension_n is None else pretension_n
    tendons = tuple(
        TendonSpec.from_arm(arm, angle_deg=a, pretension_n=pre) for a in (0.0, 90.0, 180.0, 270.0)
    )
    return SpatialRig(arm=arm, tendons=tendons, gravity_direction=(-1.0, 0.0, 0.0), name="four-tendon")


def hanging_rig(arm: RigParameters | None = None, pretension_n: float | None = None) -> SpatialRig:
    """The four-tendon rig hanging from its clamp: gravity along the backbone (the symmetry oracle's rig)."""
    rig = four_tendon_rig(arm, pretension_n)
    return rig.replace(gravity_direction=(0.0, 0.0, 1.0), name="hanging")


PRESETS = {"paper": paper_rig, "four-tendon": four_tendon_rig, "hanging": hanging_rig}
"""Rig name -> constructor (``python -m helpers virtual-rig frequency-map --preset NAME``)."""


def preset(name: str) -> SpatialRig:
    """The built-in rig called ``name`` (one of :data:`PRESETS`)."""
    if name not in PRESETS:
        raise ValueError(f"unknown rig preset {name!r}; choose from {', '.join(PRESETS)}")
    return PRESETS[name]()


_SOURCES: dict[str, tuple[str, str, str]] = {
    "angle_deg": ("deg", "assumed", "four-tendon rigs: 0, 90, 180, 270 (tendon 1 on top); the paper's: 0"),
    "offset_mm": ("mm", "tuned", "the planar rig's tuned eyelet offset r, the same on every tendon"),
    "spool_diameter_mm": ("mm", "paper", "65 mm spool on every stepper"),
    "steps_per_rev": ("-", "paper", "800 microsteps per revolution"),
    "holding_torque_n_m": (
        "N m",
        "assumed",
        "the planar rig's 1.5 x 4.3 kg cm (its pull-out tension 19.5 N)",
    ),
    "load_cell_range_n": ("N", "assumed", "the planar rig's span_n: 4-20 mA over 0-20 N"),
    "pretension_n": (
        "N",
        "tuned/assumed",
        "the planar rig's tuned 2.355 N, on every tendon of the four-tendon rigs",
    ),
    "cable_stiffness_n_m": (
        "N/m",
        "tuned",
        "the planar rig's k_cable (cables + load cell), the same on every tendon",
    ),
    "gravity_direction": (
        "-",
        "paper/assumed",
        "horizontal, tendon 1 on top (Fig. 7: the arm bends up); hanging: +z",
    ),
    "shear_modulus_gpa": ("GPa", "handbook", "A228 music wire, 11.5e6 psi"),
    "tip_inertia_scale": (
        "-",
        "numerical",
        "1 (physical); a larger value slows the tip disc rocking (speed study)",
    ),
}


def spatial_parameter_table(rig: SpatialRig | None = None) -> pd.DataFrame:
    """The spatial fields of ``rig`` (per tendon and rig-wide) with unit, source and reason.

    The arm's own fields are :func:`helpers.virtual.parameters.parameter_table`'s.
    """
    rig = SpatialRig() if rig is None else rig
    rows = []
    for i, t in enumerate(rig.tendons):
        for name, value in t.to_dict().items():
            if name == "cable_stiffness_n_m":
                value = rig.k_cable(i)
            unit, source, reason = _SOURCES[name]
            rows.append({"parameter": f"tendon[{i + 1}].{name}", "value": value, "unit": unit,
                         "source": source, "reason": reason})  # fmt: skip
    for name in ("gravity_direction", "shear_modulus_gpa", "tip_inertia_scale"):
        unit, source, reason = _SOURCES[name]
        rows.append({"parameter": name, "value": getattr(rig, name), "unit": unit, "source": source,
                     "reason": reason})  # fmt: skip
    return pd.DataFrame(rows).set_index("parameter")
