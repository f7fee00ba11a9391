"""The rig file's keys: one table of specifications (type, unit, check, default, meaning) per TOML table.

Validation, the documentation (``docs/rig_file.md``) and the template (``python -m helpers rig new``) all read
these tables, so a key exists in exactly one place. Standard library only.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

RIG_SCHEMA_VERSION = 1
"""The rig file format this code writes and reads (``docs/rig_file.md``, the version policy)."""

MAX_TENDONS = 4
"""A rig has one to four tendons (``[[tendon]]`` tables)."""

REQUIRED = object()
"""Marker: the key has no default."""


@dataclass(frozen=True)
class Key:
    """One key of a table.

    Attributes
    ----------
    name : str
        The TOML key (its unit in the name where it has one).
    kind : str
        ``float``, ``int``, ``str`` or ``vector3`` (three floats).
    unit : str
        Unit (``-`` for counts and pure numbers).
    default : object
        The value when absent, or :data:`REQUIRED`.
    doc : str
        What it means (one sentence for the docs and the template).
    lo, hi : float or None
        The allowed range (``lo`` exclusive if ``lo_open``).
    lo_open : bool
        ``lo`` excluded (a positive quantity).
    plausible : tuple of two floats or None
        A plausible range: a value outside it is refused as a probable wrong unit.
    """

    name: str
    kind: str
    unit: str
    default: Any
    doc: str
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    plausible: tuple[float, float] | None = None


def _pos(name: str, unit: str, default: Any, doc: str, plausible: tuple[float, float]) -> Key:
    return Key(name, "float", unit, default, doc, lo=0.0, lo_open=True, plausible=plausible)


def _nonneg(name: str, unit: str, default: Any, doc: str, plausible_max: float) -> Key:
    return Key(name, "float", unit, default, doc, lo=0.0, plausible=(0.0, plausible_max))


def _int(name: str, default: Any, doc: str, lo: int = 1, hi: int | None = None, unit: str = "-") -> Key:
    return Key(name, "int", unit, default, doc, lo=lo, hi=hi)


TOP: tuple[Key, ...] = (
    Key("schema_version", "int", "-", REQUIRED, "the rig file format (1)", lo=1),
    Key("name", "str", "-", REQUIRED, "the rig's name: letters, digits, '_', '-', '.' (at most 32)"),
    Key("description", "str", "-", "", "free text: who built it, where, what is assumed"),
)

HARDWARE: tuple[Key, ...] = (
    _pos("spool_diameter_mm", "mm", REQUIRED, "diameter of the stepper's cable spool", (2.0, 500.0)),
    _int(
        "steps_per_rev", REQUIRED, "microsteps per revolution of the stepper (driver setting)", hi=1_000_000
    ),
    _pos(
        "travel_mm",
        "mm",
        REQUIRED,
        "cable travel from position 0 (the host's and the firmware's limit)",
        (0.1, 2000.0),
    ),  # fmt: skip
    _nonneg(
        "release_mm",
        "mm",
        0.0,
        "how far a tendon may pay out below position 0 (the rest: every tendon at its pretension); its "
        "travel is -release_mm..travel_mm (0: none, position 0 is the end of the travel)",
        2000.0,
    ),
    _pos("speed_limit_mm_s", "mm/s", REQUIRED, "cable speed limit", (0.1, 10_000.0)),
    _pos("step_rate_cap_hz", "steps/s", REQUIRED, "step-rate cap of the driver chain", (1.0, 200_000.0)),
    _int("max_interval_us", 1_000_000, "slowest step interval; slower is a dwell", unit="us", lo=1000),
    _int("max_dwell_ms", 60_000, "longest single dwell of a programme", unit="ms"),
    _int("programme_max_items", 64, "programme length (a RAM table on the stepper board)", hi=4096),
    _pos(
        "max_programme_s",
        "s",
        600.0,
        "longest programme the host runs (a recording is held in memory)",
        (1.0, 86_400.0),
    ),  # fmt: skip
    _pos(
        "holding_torque_n_m",
        "N m",
        REQUIRED,
        "amplitude of the stepper's torque law (holding torque)",
        (0.001, 100.0),
    ),  # fmt: skip
    _int("adc_bits", 10, "resolution of the DAQ board's ADC", hi=24, unit="bits"),
    _pos("adc_vref_v", "V", 5.0, "ADC reference voltage", (0.1, 50.0)),
    _int(
        "adc_clip_margin_counts",
        2,
        "a reading this close to the loop's saturation counts as clipped",
        lo=0,
        unit="counts",
    ),  # fmt: skip
    _pos(
        "shunt_ohm",
        "ohm",
        150.0,
        "resistor turning the amplifier's loop current into the ADC's voltage",
        (1.0, 100_000.0),
    ),  # fmt: skip
    _nonneg("loop_zero_ma", "mA", 4.0, "the amplifier's loop current at zero load", 100.0),
    _pos("loop_full_ma", "mA", 20.0, "the loop current at full-scale load (load_cell_range_n)", (0.1, 100.0)),
    _nonneg("loop_min_ma", "mA", 3.8, "the loop's lower saturation (NAMUR NE 43: 3.8 mA)", 100.0),
    _pos("loop_max_ma", "mA", 20.5, "the loop's upper saturation (NAMUR NE 43: 20.5 mA)", (0.1, 100.0)),
    _pos(
        "load_cell_range_n",
        "N",
        REQUIRED,
        "load that drives the loop to loop_full_ma (the chain's span)",
        (0.01, 100_000.0),
    ),  # fmt: skip
    _int("daq_rate_min_hz", 100, "the DAQ board's lowest sample rate", unit="Hz"),
    _int("daq_rate_max_hz", 2000, "the DAQ board's highest sample rate", unit="Hz"),
    _int("daq_rate_default_hz", 1000, "the DAQ board's sample rate after reset", unit="Hz"),
    _int("daq_baud", 500_000, "the DAQ board's serial line rate (8N1)", unit="baud", lo=300),
    _int("stepper_baud", 115_200, "the stepper board's serial line rate (8N1)", unit="baud", lo=300),
)

ARM: tuple[Key, ...] = (
    _pos(
        "length_mm", "mm", REQUIRED, "backbone length from the clamp to the last (tip) disc", (10.0, 5000.0)
    ),
    _int(
        "discs",
        REQUIRED,
        "number of cable-support discs, the last at the tip where the cables are knotted",
        hi=200,
    ),  # fmt: skip
    _pos("backbone_diameter_mm", "mm", REQUIRED, "diameter of the backbone rod", (0.05, 50.0)),
    _pos("youngs_modulus_gpa", "GPa", REQUIRED, "Young's modulus of the rod", (0.001, 1000.0)),
    _pos("density_kg_m3", "kg/m^3", REQUIRED, "density of the rod", (10.0, 30_000.0)),
    _pos(
        "shear_modulus_gpa", "GPa", 79.3, "shear modulus of the rod (torsion, spatial twin)", (0.0005, 500.0)
    ),
    _pos("disc_mass_g", "g", REQUIRED, "mass of each disc with its eyelets and glue", (0.001, 1000.0)),
    _pos("disc_radius_mm", "mm", 12.0, "disc radius (its rotary inertia)", (0.1, 500.0)),
    _pos("disc_thickness_mm", "mm", 4.0, "disc thickness (its rotary inertia)", (0.01, 100.0)),
    _pos("cable_offset_mm", "mm", REQUIRED, "distance of the eyelets from the backbone's axis", (0.1, 500.0)),
    _nonneg("pretension_n", "N", REQUIRED, "cable tension at rest, stepper at position 0", 10_000.0),
    _nonneg(
        "tension_floor_n",
        "N",
        1.0,
        "the least static tension every tendon keeps in a move planned "
        "in task space (record move; below it a tendon is close to slack and stops controlling the arm)",
        10_000.0,
    ),
    _int(
        "floor_watch_ms",
        20,
        "during a run of several tendons, a tendon whose measured tension stays below tension_floor_n for "
        "longer than this stops the run (saved aborted, the tendon named; device time, counted in samples); "
        "longer than a pay-out step's dip (3 ms at the median)",
        hi=60_000,
        unit="ms",
    ),
    _pos(
        "cable_stiffness_n_m",
        "N/m",
        71700.0,
        "cables and load cell between spool and arm in series (the microstep spring is added from the "
        "stepper); absent: the paper rig's tuned value, an assumption",
        (1.0, 1e9),
    ),  # fmt: skip
    _nonneg(
        "damping_alpha_per_s",
        "1/s",
        1.887944,
        "mass-proportional damping of the twin (air drag); absent: the paper rig's tuned value, "
        "an assumption",
        1000.0,
    ),
    _nonneg(
        "damping_beta_chord_s",
        "s",
        5.753788e-04,
        "wire material damping of the twin (dashpots beta EI / l between disc chords); absent: the paper "
        "rig's tuned value, an assumption",
        1.0,
    ),
    Key(
        "gravity_direction",
        "vector3",
        "-",
        (-1.0, 0.0, 0.0),
        "direction of gravity in the clamp frame (z along the backbone, x towards tendon 1): [-1, 0, 0] "
        "horizontal with tendon 1 on top, [0, 0, 1] hanging; components at most 1e6 in magnitude",
    ),  # fmt: skip
    _nonneg("gravity_m_s2", "m/s^2", 9.81, "gravity's magnitude (0 switches it off)", 30.0),
)

BOARDS: tuple[Key, ...] = (
    Key("daq_board", "str", "-", "Arduino Mega 2560", "the DAQ board (load-cell ADC, step counter)"),
    Key("stepper_board", "str", "-", "Arduino Uno", "the stepper board (programmes, streams)"),
    Key("stepper_driver", "str", "-", "TB6600", "the stepper driver"),
    Key("load_cell", "str", "-", "", "the load cell and its amplifier"),
)

TENDON_FALLBACK: dict[str, tuple[str, str, str]] = {
    "offset_mm": ("arm", "cable_offset_mm", "eyelet offset from the backbone's axis"),
    "spool_diameter_mm": ("hardware", "spool_diameter_mm", "its spool"),
    "steps_per_rev": ("hardware", "steps_per_rev", "its microsteps per revolution"),
    "holding_torque_n_m": ("hardware", "holding_torque_n_m", "its stepper's holding torque"),
    "load_cell_range_n": ("hardware", "load_cell_range_n", "its load cell's span"),
    "pretension_n": ("arm", "pretension_n", "its tension at rest"),
    "cable_stiffness_n_m": ("arm", "cable_stiffness_n_m", "its cables and load cell"),
}
"""A ``[[tendon]]`` key -> the ``[hardware]`` or ``[arm]`` key whose value it takes when absent, and what it
means. It is that key again (the same kind, unit, checks and plausible range) under its own name."""


def _tendon_key(name: str, table: str, source: str, meaning: str) -> Key:
    key = next(k for k in {"hardware": HARDWARE, "arm": ARM}[table] if k.name == source)
    absent = "[hardware]'s" if table == "hardware" else f"[arm] {source}"
    return replace(key, name=name, default=None, doc=f"{meaning} (absent: {absent})")


TENDON: tuple[Key, ...] = (
    Key(
        "angle_deg",
        "float",
        "deg",
        REQUIRED,
        "angle of the tendon around the backbone, counter-clockwise seen from the tip's side, 0 = tendon 1",
    ),
    *(_tendon_key(name, *fallback) for name, fallback in TENDON_FALLBACK.items()),
    Key(
        "twin_eyelet_error_mm",
        "float",
        "mm",
        0.0,
        "the virtual rig only (the spatial twin of helpers.virtual.spatial.from_rig; no planner reads it): "
        "this tendon's cable path at rest off the geometry the planners know by this much, in the direction "
        "that lowers its tension (an eyelet misplaced; the twin's arm holds it as if its cable were paid out "
        "by this much at position 0); 0: the geometry as planned",
        lo=0.0,
        plausible=(0.0, 5.0),
    ),
)
