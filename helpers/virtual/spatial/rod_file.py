"""A bare rod's file: the ``[rod]`` table, read as a :class:`~helpers.rigfile.model.RigFile` (standard lib.).

A file whose only table is ``[rod]`` describes a bare rod for the spatial twin (no discs, no cable, no
steppers or boards; ``docs/rig_file.md``, "A bare rod's file"): its length, radius and material, gravity,
the forces that hold it deflected until it is released at ``t = 0`` and its discretisation.
:func:`load_rod` and :func:`loads_rod` read it into a ``RigFile`` whose ``rod`` is the table (its
``hardware``, ``arm`` and ``boards`` None, no tendons); every rig's reader (:func:`helpers.rigfile.load`)
refuses such a file in one line. Every problem is one :class:`~helpers.rigfile.errors.RigFileError` line
naming the file and the key.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import replace
from pathlib import Path
from typing import Any

from helpers.rigfile.errors import RigFileError
from helpers.rigfile.model import NAME, RigFile, _fields, _problem, _table, rig_hash
from helpers.rigfile.schema import ARM, REQUIRED, RIG_SCHEMA_VERSION, TOP, Key, _pos

__all__ = ["ROD", "FORCES", "Rod", "loads_rod", "load_rod"]


def _arm_key(name: str, default: Any = REQUIRED, doc: str | None = None, plausible: Any = None) -> Key:
    """An ``[arm]`` key again (kind, unit, checks, plausible range unless given) for the ``[rod]`` table."""
    key = next(k for k in ARM if k.name == name)
    return replace(key, default=default, doc=doc or key.doc, plausible=plausible or key.plausible)


ROD: tuple[Key, ...] = (
    _arm_key("length_mm", doc="length of the rod from the clamp to its free tip"),
    _pos("radius_mm", "mm", REQUIRED, "radius of the rod's circular cross-section", (0.025, 100.0)),
    _arm_key("youngs_modulus_gpa", doc="Young's modulus of the rod (soft rods too: 1e-5 GPa is 10 kPa)",
             plausible=(1e-5, 1000.0)),  # fmt: skip
    _arm_key("density_kg_m3"),
    _arm_key("shear_modulus_gpa", doc="shear modulus of the rod (torsion)", plausible=(1e-6, 500.0)),
    _arm_key("gravity_direction", doc="direction of gravity in the clamp frame (z along the unloaded rod)"),
    _arm_key("gravity_m_s2", 9.81),
    Key("segments", "int", "-", 20, "constant-strain elements of the spatial twin's rod (the discretisation)",
        lo=1, hi=400),  # fmt: skip
    Key("held_mid_force_n", "vector3", "N", (0.0, 0.0, 0.0),
        "constant force on the rod's middle (clamp frame) holding it deflected until the release at t = 0; "
        "needs an even number of segments"),  # fmt: skip
    Key("held_tip_force_n", "vector3", "N", (0.0, 0.0, 0.0),
        "constant force on the rod's tip (clamp frame) holding it deflected until the release at t = 0"),
    _arm_key("damping_alpha_per_s", 0.0, "mass-proportional damping of the twin (0: none)"),
    _arm_key("damping_beta_chord_s", 0.0, "wire material damping of the twin, dashpots beta EI / l between "
             "elements (0: none)"),  # fmt: skip
    Key("damping_floor_zeta", "float", "-", 0.0, "the twin's high-mode damping floor: about this damping "
        "ratio on every mode above 1000 rad/s (0: none)", lo=0.0, hi=0.99),  # fmt: skip
)
"""The ``[rod]`` table's keys (``docs/rig_file.md``)."""

FORCES = ("held_mid_force_n", "held_tip_force_n")
"""The keys that are vectors of three numbers which may be zero (a force, not a direction)."""

Rod = dataclasses.make_dataclass("Rod", _fields(ROD), frozen=True)
Rod.__doc__ = "The ``[rod]`` table of a bare rod's file, every key resolved (:data:`ROD`)."


def _force(source: str, key: str, value: Any) -> tuple[float, float, float]:
    ok = isinstance(value, list) and len(value) == 3
    ok = ok and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)
    ok = ok and all(math.isfinite(v) for v in value)
    if not ok:
        raise _problem(source, f"[rod] {key}", f"must be a vector of three numbers (N), got {value!r}")
    return tuple(float(v) for v in value)  # type: ignore[return-value]


def loads_rod(text: str, source: str = "<string>") -> RigFile:
    """Read a bare rod's file from its text and check it.

    Raises
    ------
    RigFileError
        One line naming ``source``, the key and the problem (a rig's file, another table, a missing or bad
        key, a force on the middle with an odd number of segments).
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RigFileError(f"{source}: not valid TOML: {exc}") from None
    if "rod" not in data:
        raise _problem(source, "[rod]", "missing table (a bare rod's file: docs/rig_file.md)")
    for name in data:
        if name not in {k.name for k in TOP} | {"rod"}:
            raise _problem(source, name, "a bare rod's file holds only the top-level keys and [rod]")
    top = _table(source, "(top level)", {k: v for k, v in data.items() if k != "rod"}, TOP)
    if top["schema_version"] != RIG_SCHEMA_VERSION:
        raise _problem(source, "schema_version", f"{top['schema_version']} is not supported (this version "
                       f"reads {RIG_SCHEMA_VERSION}); see docs/rig_file.md")  # fmt: skip
    if not NAME.match(top["name"]):
        raise _problem(source, "name", f"{top['name']!r}: letters, digits, '_', '-', '.' (at most 32)")
    raw = data["rod"]
    if not isinstance(raw, dict):
        raise _problem(source, "[rod]", f"must be a table, got {type(raw).__name__}")
    forces = {k: _force(source, k, raw[k]) for k in FORCES if k in raw}
    values = _table(source, "[rod]", {k: v for k, v in raw.items() if k not in FORCES},
                    tuple(k for k in ROD if k.name not in FORCES))  # fmt: skip
    values.update({k: forces.get(k, next(key.default for key in ROD if key.name == k)) for k in FORCES})
    rod = Rod(**values)
    if any(rod.held_mid_force_n) and rod.segments % 2:
        raise _problem(source, "[rod] segments", f"{rod.segments} is odd: a force on the middle needs a node "
                       "there (an even number of segments)")  # fmt: skip
    return RigFile(
        name=top["name"], description=top["description"], schema_version=top["schema_version"],
        hardware=None, arm=None, boards=None, tendons=(), explicit_tendons=False, text=text, source=source,
        hash=rig_hash(text.encode("utf-8")), rod=rod,
    )  # fmt: skip


def load_rod(path: str | Path) -> RigFile:
    """Read and check the bare rod's file at ``path`` (:func:`loads_rod`)."""
    p = Path(path)
    try:
        text = p.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise RigFileError(f"{p}: no such rod file") from None
    except OSError as exc:
        raise RigFileError(f"{p}: cannot be read ({exc.strerror})") from None
    except UnicodeDecodeError:
        raise RigFileError(f"{p}: not UTF-8 text") from None
    return loads_rod(text, source=str(p))
