"""A rig file, read and checked: :class:`RigFile` and :func:`load` (standard library and numpy only).

Every problem is one :class:`RigFileError` line naming the file, the key and the problem (an unknown key with
the nearest known one, a wrong type, a wrong sign or an implausible size that is probably a wrong unit, a
missing key, more than four tendons, an unsafe or impossible rig: ``helpers.rigfile.derived``). A bare rod's
file (``[rod]``, ``helpers.virtual.spatial.rod_file``) is no rig: refused in one line.
"""

from __future__ import annotations

import dataclasses
import difflib
import hashlib
import math
import re
import reprlib
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from helpers.rigfile.derived import check
from helpers.rigfile.errors import RigFileError
from helpers.rigfile.schema import (
    ARM,
    BOARDS,
    HARDWARE,
    MAX_TENDONS,
    REQUIRED,
    RIG_SCHEMA_VERSION,
    TENDON,
    TENDON_FALLBACK,
    TOP,
    Key,
)

NAME = re.compile(r"[A-Za-z0-9_.-]{1,32}\Z")

_NOT_CODE = re.compile(r'"""(?:\\?[\s\S])*?"""' r"|'''[\s\S]*?'''" r'|"(?:\\.|[^"\\\n])*"' r"|'[^'\n]*'|#.*")
"""TOML strings and comments (their brackets are not nesting)."""


def _deepest(text: str) -> tuple[str, int, int]:
    """Where ``text`` nests arrays and inline tables deepest: ``("[table] key", depth, line)``.

    ``tomllib`` parses nesting by recursion, so a file nesting thousands deep ends in ``RecursionError``
    with no line; this scan needs no recursion (strings and comments blanked, table headers followed).
    """
    depth, best, table, key, tendons = 0, ("", 0, 0), "", "", 0
    bare = _NOT_CODE.sub(lambda m: "\n" * m[0].count("\n"), text)
    for number, line in enumerate(bare.split("\n"), 1):
        if depth == 0 and line.lstrip().startswith("["):  # a table header: [name] or [[name]]
            tendons += (header := line.replace(" ", "").strip()) == "[[tendon]]"
            table = f"[[tendon]] #{tendons}" if header == "[[tendon]]" else line.strip()
            continue
        key = line.split("=")[0].strip() if depth == 0 and "=" in line else key
        for c in line:
            depth += (c in "[{") - (c in "]}")
            if depth > best[1]:
                best = (f"{table} {key}".strip(), depth, number)
    return best


def rig_hash(data: bytes) -> str:
    """The rig's short hash: the first 8 hex digits of the sha256 of the file's bytes."""
    return hashlib.sha256(data).hexdigest()[:8]


def _fields(keys: tuple[Key, ...]) -> list[tuple[str, type, Any]]:
    types = {"float": float, "int": int, "str": str, "vector3": tuple}
    return [(k.name, types[k.kind]) for k in keys]  # type: ignore[misc]


Hardware = dataclasses.make_dataclass("Hardware", _fields(HARDWARE), frozen=True)
Hardware.__doc__ = "The ``[hardware]`` table, every key resolved (``helpers.rigfile.schema.HARDWARE``)."
Arm = dataclasses.make_dataclass("Arm", _fields(ARM), frozen=True)
Arm.__doc__ = "The ``[arm]`` table, every key resolved (``helpers.rigfile.schema.ARM``)."
Boards = dataclasses.make_dataclass("Boards", _fields(BOARDS), frozen=True)
Boards.__doc__ = "The ``[boards]`` table (``helpers.rigfile.schema.BOARDS``)."


@dataclass(frozen=True)
class Tendon(dataclasses.make_dataclass("TendonKeys", _fields(TENDON), frozen=True)):
    """One tendon with its stepper and load cell, every value resolved (absent keys: its tables).

    Its fields are the keys of ``helpers.rigfile.schema.TENDON``; units in the names; ``docs/rig_file.md``.
    """

    @property
    def mm_per_step(self) -> float:
        """Cable per microstep, mm: ``pi d / steps_per_rev``."""
        return math.pi * self.spool_diameter_mm / self.steps_per_rev

    @property
    def pull_out_n(self) -> float:
        """Largest cable tension its stepper holds, ``T_h / R``, N."""
        return self.holding_torque_n_m / (0.5e-3 * self.spool_diameter_mm)


@dataclass(frozen=True)
class RigFile:
    """A checked rig file.

    Attributes
    ----------
    name, description : str
        The rig's name and free text.
    schema_version : int
        The file's format version.
    hardware, arm, boards : Hardware, Arm, Boards
        The tables, defaults filled in.
    tendons : tuple of Tendon
        One to four; a file without ``[[tendon]]`` has one tendon at 0 degrees at the arm's cable offset.
    explicit_tendons : bool
        The file has ``[[tendon]]`` tables.
    text : str
        The file's content (recordings keep it).
    source : str
        Where it came from (a path, or ``<string>``).
    hash : str
        :func:`rig_hash` of the file's bytes (UTF-8).
    rod : helpers.virtual.spatial.rod_file.Rod or None
        A bare rod's ``[rod]`` table, read by the twin (``helpers.virtual.spatial.rod_file``: then no
        hardware, arm, boards or tendons).
    """

    name: str
    description: str
    schema_version: int
    hardware: Any
    arm: Any
    boards: Any
    tendons: tuple[Tendon, ...]
    explicit_tendons: bool
    text: str = field(repr=False)
    source: str = "<string>"
    hash: str = ""
    rod: Any = None

    @property
    def n_tendons(self) -> int:
        """Number of tendons (axes and load-cell channels)."""
        return len(self.tendons)


def _problem(source: str, where: str, problem: str) -> RigFileError:
    return RigFileError(f"{source}: {where}: {problem}")


def _value(source: str, where: str, key: Key, value: Any) -> Any:
    """Check one value against its key; return it converted (int -> float for floats, list -> tuple)."""
    unit = "" if key.unit == "-" else f" {key.unit}"
    if key.kind == "str":
        if not isinstance(value, str):
            raise _problem(source, where, f"must be a string, got {reprlib.repr(value)}")
        return value
    if key.kind == "vector3":
        ok = isinstance(value, list) and len(value) == 3
        ok = ok and all(
            isinstance(v, int | float) and not isinstance(v, bool) and abs(v) <= 1e6 for v in value
        )  # at most 1e6: the norm stays finite; NaN fails the comparison too
        if not ok or math.sqrt(sum(float(v) ** 2 for v in value)) < 1e-12:
            why = "must be a nonzero vector of three numbers of at most 1e+06 in magnitude"
            raise _problem(source, where, f"{why}, got {reprlib.repr(value)}")
        return tuple(float(v) for v in value)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise _problem(source, where, f"must be a number{unit}, got {reprlib.repr(value)}")
    if isinstance(value, int) and not -(2**63) <= value < 2**63:  # TOML's integers are 64-bit
        raise _problem(source, where, f"{reprlib.repr(value)} is beyond TOML's 64-bit integers")
    if key.kind == "int":
        if isinstance(value, float):
            raise _problem(source, where, f"must be a whole number{unit}, got {value!r}")
    elif not math.isfinite(value):
        raise _problem(source, where, f"must be finite, got {value!r}")
    if key.lo is not None and (value <= key.lo if key.lo_open else value < key.lo):
        need = f"> {key.lo:g}" if key.lo_open else f">= {key.lo:g}"
        raise _problem(source, where, f"must be {need}{unit}, got {value!r}")
    if key.hi is not None and value > key.hi:
        raise _problem(source, where, f"must be <= {key.hi:g}{unit}, got {value!r}")
    if key.plausible is not None and not key.plausible[0] <= value <= key.plausible[1]:
        lo, hi = key.plausible
        raise _problem(
            source, where,
            f"{value!r}{unit} is outside the plausible {lo:g}-{hi:g}{unit}: is it in another unit?",
        )  # fmt: skip
    return float(value) if key.kind == "float" else int(value)


def _table(source: str, label: str, data: Any, keys: tuple[Key, ...]) -> dict[str, Any]:
    """Check a table: known keys only (with a suggestion), required keys present, every value valid."""
    if not isinstance(data, dict):
        raise _problem(source, label, f"must be a table, got {type(data).__name__}")
    known = {k.name: k for k in keys}
    for name in data:
        if name not in known:
            near = difflib.get_close_matches(name, list(known), n=1, cutoff=0.6)
            hint = f" (did you mean {near[0]!r}?)" if near else f" (known: {', '.join(known)})"
            raise _problem(source, f"{label} {name}", f"unknown key{hint}")
    out: dict[str, Any] = {}
    for key in keys:
        where = f"{label} {key.name}"
        if key.name not in data:
            if key.default is REQUIRED:
                raise _problem(source, where, f"missing ({key.doc}, {key.unit})")
            out[key.name] = key.default
            continue
        out[key.name] = _value(source, where, key, data[key.name])
    return out


def loads(text: str, source: str = "<string>") -> RigFile:
    """Read a rig file from its text and check it (derived limits and refusals included).

    Raises
    ------
    RigFileError
        One line naming ``source``, the key and the problem.
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise RigFileError(f"{source}: not valid TOML: {exc}") from None
    except RecursionError:  # tomllib parses nested arrays and inline tables by recursion
        where, depth, line = _deepest(text)
        why = f"arrays or inline tables nested {depth} deep (line {line}): a rig file nests at most one"
        raise _problem(source, where or "(top level)", f"{why} (gravity_direction)") from None
    if "rod" in data:  # helpers.virtual.spatial.rod_file reads it
        raise _problem(source, "[rod]", "this file describes a bare rod (docs/rig_file.md), not a rig")
    allowed = {k.name for k in TOP} | {"hardware", "arm", "boards", "tendon"}
    for name in data:
        if name not in allowed:
            near = difflib.get_close_matches(name, sorted(allowed), n=1, cutoff=0.6)
            hint = f" (did you mean {near[0]!r}?)" if near else ""
            raise _problem(source, name, f"unknown key or table{hint}")
    top = _table(source, "(top level)", {k: v for k, v in data.items() if k in {t.name for t in TOP}}, TOP)
    if top["schema_version"] != RIG_SCHEMA_VERSION:
        raise _problem(
            source, "schema_version",
            f"{top['schema_version']} is not supported (this version reads {RIG_SCHEMA_VERSION}); "
            "see docs/rig_file.md",
        )  # fmt: skip
    if not NAME.match(top["name"]):
        raise _problem(source, "name", f"{top['name']!r}: letters, digits, '_', '-', '.' (at most 32)")
    for required in ("hardware", "arm"):
        if required not in data:
            raise _problem(source, f"[{required}]", "missing table")
    hw = _table(source, "[hardware]", data["hardware"], HARDWARE)
    arm = _table(source, "[arm]", data["arm"], ARM)
    boards = _table(source, "[boards]", data.get("boards", {}), BOARDS)
    explicit = "tendon" in data
    raw_tendons = data.get("tendon", [{"angle_deg": 0.0}])
    if not isinstance(raw_tendons, list) or not all(isinstance(t, dict) for t in raw_tendons):
        raise _problem(source, "[[tendon]]", "must be an array of tables ([[tendon]] blocks)")
    if not 1 <= len(raw_tendons) <= MAX_TENDONS:
        raise _problem(source, "[[tendon]]", f"{len(raw_tendons)} tendons: a rig has 1 to {MAX_TENDONS}")
    tables = {"hardware": hw, "arm": arm}
    fallback = {name: tables[table][key] for name, (table, key, _) in TENDON_FALLBACK.items()}
    tendons = []
    for i, raw in enumerate(raw_tendons):
        values = _table(source, f"[[tendon]] #{i + 1}", raw, TENDON)
        resolved = {k: (fallback[k] if v is None else v) for k, v in values.items()}
        tendons.append(Tendon(**resolved))
    rig = RigFile(
        name=top["name"], description=top["description"], schema_version=top["schema_version"],
        hardware=Hardware(**hw), arm=Arm(**arm), boards=Boards(**boards), tendons=tuple(tendons),
        explicit_tendons=explicit, text=text, source=source, hash=rig_hash(text.encode("utf-8")),
    )  # fmt: skip
    check(rig)  # the rig as a whole: safe and feasible
    return rig


def load(path: str | Path) -> RigFile:
    """Read and check the rig file at ``path`` (:func:`loads`); its hash is of the file's bytes."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise RigFileError(f"{p}: no such rig file") from None
    except OSError as exc:
        raise RigFileError(f"{p}: cannot be read ({exc.strerror})") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise RigFileError(f"{p}: not UTF-8 text") from None
    return loads(text, source=str(p))  # its hash: of the text's UTF-8 bytes, which are the file's
