"""What a design is, as data: a shaper, an Up/Down pair or a map-following schedule, and its JSON file.

Three kinds of shaping can drive a pulse experiment (an Up move of ``x_f`` mm at ``v_in`` mm/s, a hold, the
Down move back):

- ``"shaper"``: one :class:`~helpers.paper.shapers.Shaper` convolved with both moves (the paper's TDFs);
- ``"pair"``: a :class:`ShaperPair`, one shaper for the Up move and one for the Down move;
- ``"schedule"``: a :class:`Schedule`, each move made of **sub-moves** (a sub-move is a constant-velocity
  piece ``amplitude * v_in`` that starts at ``start_s`` after the move's start and lasts ``duration_s``).
  A convolution with a shaper is the special case where every sub-move lasts ``x_f / v_in`` and starts at an
  impulse time; a map-following design lets starts and durations follow the frequency map during the move.
  A schedule belongs to the move (``v_in``, ``x_f``) it was computed for.

A :class:`Design` wraps one of them with its **system** name (:data:`SYSTEMS`, the vocabulary of a
recording's ``scenario.system``) and its provenance. :func:`save_design` and :func:`load_design` write and
read the versioned JSON format documented in ``docs/shaper_design.md`` (``format`` = :data:`DESIGN_FORMAT`,
``version`` = :data:`DESIGN_VERSION`); a malformed file raises one
:class:`~helpers.base.jsonfile.DataFileError`
line naming the file and the field. Floats are written with ``repr`` precision, so a design read back is
bit-for-bit the one saved.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from helpers.base.jsonfile import DataFileError, json_safe, read_json, write_json
from helpers.paper.profiles import VelocityProfile, single_pulse
from helpers.paper.shapers import SUM_TOLERANCE, Shaper
from helpers.recordings.shaping import DESIGN_FORMAT, DESIGN_VERSION, SYSTEMS, shaper_to_dict
from helpers.research.versioned import check_versioned

PAPER_SYSTEMS = ("unshaped", "zv", "zvd")
"""The paper's three systems (Table I)."""

KINDS = ("shaper", "pair", "schedule")
"""The kinds of shaping a design file holds."""

_TOP_KEYS = {"format", "version", "kind", "system", "shaper", "up", "down", "schedule", "provenance"}


# -- the shaping objects ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class ShaperPair:
    """One shaper for the Up move and one for the Down move.

    Parameters
    ----------
    up, down : Shaper
        The two shapers.
    """

    up: Shaper
    down: Shaper

    def __post_init__(self) -> None:
        for name in ("up", "down"):
            if not isinstance(getattr(self, name), Shaper):
                got = type(getattr(self, name)).__name__
                raise ValueError(f"ShaperPair.{name} must be a Shaper, got {got}")

    @property
    def duration(self) -> float:
        """The longer of the two shapers' durations (s)."""
        return max(self.up.duration, self.down.duration)

    def up_down(self) -> tuple[Shaper, Shaper]:
        """The Up and the Down move's shaper."""
        return self.up, self.down

    def moves(
        self, v_in_mm_s: float, x_f_mm: float, t_up: float, t_down: float
    ) -> tuple[VelocityProfile, VelocityProfile]:
        """The shaped Up move (its shaper) and Down move (the other), before quantisation."""
        up = single_pulse(v_in_mm_s, x_f_mm, t_up, +1).shaped(self.up)
        down = single_pulse(v_in_mm_s, x_f_mm, t_down, -1).shaped(self.down)
        return up, down

    def design_document(self, system: str | None = None) -> dict[str, Any]:
        """The pair as a design-file document (``custom`` unless ``system`` is given)."""
        return as_design(self, system).to_dict()


@dataclass(frozen=True)
class SubMove:
    """A constant-velocity piece of a move: ``amplitude * v_in`` from ``start_s`` for ``duration_s``.

    Parameters
    ----------
    amplitude : float
        Fraction of the move's speed, > 0.
    start_s : float
        Start after the move's start (s), >= 0.
    duration_s : float
        Length (s), > 0.
    """

    amplitude: float
    start_s: float
    duration_s: float

    def __post_init__(self) -> None:
        for name, strict in (("amplitude", True), ("start_s", False), ("duration_s", True)):
            value = getattr(self, name)
            ok = isinstance(value, int | float | np.floating) and not isinstance(value, bool)
            if not ok or not math.isfinite(value) or (value <= 0.0 if strict else value < 0.0):
                rule = "> 0" if strict else ">= 0"
                raise ValueError(f"sub-move {name} must be a finite number {rule}, got {value!r}")
            object.__setattr__(self, name, float(value))

    @property
    def end_s(self) -> float:
        """``start_s + duration_s``."""
        return self.start_s + self.duration_s


@dataclass(frozen=True)
class MoveSchedule:
    """One move as sub-moves (times from the move's start).

    Parameters
    ----------
    sub_moves : tuple of SubMove
        Amplitudes summing to 1, the first starting at 0, starts non-decreasing.
    """

    sub_moves: tuple[SubMove, ...]

    def __post_init__(self) -> None:
        subs = tuple(self.sub_moves)
        if not subs:
            raise ValueError("a move schedule needs at least one sub-move")
        if not all(isinstance(s, SubMove) for s in subs):
            raise ValueError("a move schedule's sub_moves must be SubMove objects")
        total = sum(s.amplitude for s in subs)
        if abs(total - 1.0) > SUM_TOLERANCE:
            raise ValueError(f"a move schedule's amplitudes must sum to 1, they sum to {total:.12g}")
        if subs[0].start_s != 0.0:
            raise ValueError(f"a move schedule's first sub-move must start at 0, got {subs[0].start_s!r}")
        starts = [s.start_s for s in subs]
        if any(b < a for a, b in zip(starts, starts[1:], strict=False)):
            raise ValueError(f"a move schedule's starts must not decrease, got {starts}")
        object.__setattr__(self, "sub_moves", subs)

    @property
    def end_s(self) -> float:
        """When the last sub-move ends (s after the move's start)."""
        return max(s.end_s for s in self.sub_moves)

    @property
    def mean_duration_s(self) -> float:
        """``sum(amplitude * duration_s)``: the move's displacement divided by ``v_in``."""
        return math.fsum(s.amplitude * s.duration_s for s in self.sub_moves)

    def edges(self, v_in_mm_s: float, direction: int) -> tuple[np.ndarray, np.ndarray]:
        """Velocity jumps of the move: times (s from its start, sorted) and jumps (mm/s)."""
        t = np.array([[s.start_s, s.end_s] for s in self.sub_moves]).ravel()
        dv = np.array([[s.amplitude, -s.amplitude] for s in self.sub_moves]).ravel() * direction * v_in_mm_s
        order = np.argsort(t, kind="stable")
        return t[order], dv[order]

    def pieces(self, v_in_mm_s: float, direction: int, t_start: float) -> tuple[np.ndarray, np.ndarray]:
        """The move as exact piecewise-constant velocity: breakpoints (s) and velocities (mm/s).

        Parameters
        ----------
        v_in_mm_s : float
            The move's speed.
        direction : int
            +1 (pull, the Up move) or -1 (release).
        t_start : float
            When the move starts (s).

        Returns
        -------
        (numpy.ndarray, numpy.ndarray)
            ``n + 1`` breakpoints and ``n`` velocities (0 between sub-moves if they leave a gap).
        """
        b = np.unique(np.array([[s.start_s, s.end_s] for s in self.sub_moves]).ravel())
        mid = 0.5 * (b[:-1] + b[1:])
        v = np.zeros(mid.size)
        for s in self.sub_moves:
            v += np.where((mid >= s.start_s) & (mid < s.end_s), s.amplitude, 0.0)
        return b + t_start, v * direction * float(v_in_mm_s)


@dataclass(frozen=True)
class Schedule:
    """A map-following pair of moves, valid for the one move it was computed for.

    Parameters
    ----------
    up, down : MoveSchedule
        The Up move (direction +1) and the Down move (direction -1).
    v_in_mm_s, x_f_mm : float
        The move: each move's displacement ``v_in * mean_duration_s`` must equal ``x_f`` (1e-9 relative).
    """

    up: MoveSchedule
    down: MoveSchedule
    v_in_mm_s: float
    x_f_mm: float

    def __post_init__(self) -> None:
        for name in ("v_in_mm_s", "x_f_mm"):
            value = getattr(self, name)
            ok = isinstance(value, int | float | np.floating) and not isinstance(value, bool)
            if not ok or not math.isfinite(value) or value <= 0:
                raise ValueError(f"schedule {name} must be a finite number > 0, got {value!r}")
            object.__setattr__(self, name, float(value))
        for name in ("up", "down"):
            move = getattr(self, name)
            if not isinstance(move, MoveSchedule):
                raise ValueError(f"schedule {name} must be a MoveSchedule, got {type(move).__name__}")
            moved = self.v_in_mm_s * move.mean_duration_s
            if abs(moved - self.x_f_mm) > 1e-9 * self.x_f_mm:
                raise ValueError(
                    f"schedule {name}: its sub-moves move {moved:.9g} mm at {self.v_in_mm_s:g} mm/s, "
                    f"not x_f = {self.x_f_mm:g} mm"
                )

    @property
    def duration(self) -> float:
        """The longer move's extra time over the unshaped move, ``end_s - x_f / v_in`` (s)."""
        t_p = self.x_f_mm / self.v_in_mm_s
        return max(self.up.end_s, self.down.end_s) - t_p

    def check_move(self, v_in_mm_s: float, x_f_mm: float) -> None:
        """Raise ``ValueError`` unless ``(v_in, x_f)`` is the move this schedule was computed for."""
        if not (
            math.isclose(v_in_mm_s, self.v_in_mm_s, rel_tol=1e-9)
            and math.isclose(x_f_mm, self.x_f_mm, rel_tol=1e-9)
        ):
            raise ValueError(
                f"this map-following schedule was computed for {self.x_f_mm:g} mm at "
                f"{self.v_in_mm_s:g} mm/s, not {x_f_mm:g} mm at {v_in_mm_s:g} mm/s: compute one for this move"
            )

    def up_down(self) -> tuple[None, None]:
        """A schedule's moves are sub-moves, not one shaper each."""
        return None, None

    def moves(
        self, v_in_mm_s: float, x_f_mm: float, t_up: float, t_down: float
    ) -> tuple[VelocityProfile, VelocityProfile]:
        """The Up and Down moves of sub-moves (this schedule's move only), before quantisation."""
        self.check_move(float(v_in_mm_s), float(x_f_mm))
        up = VelocityProfile(*self.up.pieces(v_in_mm_s, +1, t_up))
        down = VelocityProfile(*self.down.pieces(v_in_mm_s, -1, t_down))
        return up.simplified(), down.simplified()

    def design_document(self, system: str | None = None) -> dict[str, Any]:
        """The schedule as a design-file document (``custom`` unless ``system`` is given)."""
        return as_design(self, system).to_dict()


Shaping = Shaper | ShaperPair | Schedule
"""Anything that shapes a pulse experiment."""


@dataclass(frozen=True)
class Design:
    """A shaping with its system name (:data:`SYSTEMS`) and provenance (how it was designed).

    Parameters
    ----------
    system : str
        A name of :data:`SYSTEMS` other than ``"unshaped"``.
    shaping : Shaper, ShaperPair or Schedule
        What drives the moves.
    provenance : dict
        JSON-safe description of how it was designed (mode map, family, options, predictions).
    """

    system: str
    shaping: Shaping
    provenance: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.system not in SYSTEMS or self.system == "unshaped":
            names = ", ".join(s for s in SYSTEMS if s != "unshaped")
            raise ValueError(f"design system must be one of {names}; got {self.system!r}")
        if not isinstance(self.shaping, Shaper | ShaperPair | Schedule):
            raise ValueError(f"design shaping must be a Shaper, ShaperPair or Schedule, got {self.shaping!r}")
        if not isinstance(self.provenance, Mapping):
            raise ValueError(f"design provenance must be an object, got {type(self.provenance).__name__}")
        object.__setattr__(self, "provenance", json_safe(dict(self.provenance)))

    @property
    def kind(self) -> str:
        """``"shaper"``, ``"pair"`` or ``"schedule"``."""
        return kind_of(self.shaping)

    @property
    def up_shaper(self) -> Shaper | None:
        """The Up move's shaper (None for a schedule)."""
        return up_down(self.shaping)[0]

    @property
    def down_shaper(self) -> Shaper | None:
        """The Down move's shaper (None for a schedule)."""
        return up_down(self.shaping)[1]

    @property
    def duration(self) -> float:
        """Time the shaping adds to the longer move (s)."""
        return float(self.shaping.duration)

    def up_down(self) -> tuple[Shaper | None, Shaper | None]:
        """The Up and the Down move's shaper (None for a schedule)."""
        return up_down(self.shaping)

    def moves(
        self, v_in_mm_s: float, x_f_mm: float, t_up: float, t_down: float
    ) -> tuple[VelocityProfile, VelocityProfile]:
        """The shaped Up and Down moves of this design's shaping, before quantisation."""
        if isinstance(self.shaping, Shaper):  # both moves by the one shaper
            up = single_pulse(v_in_mm_s, x_f_mm, t_up, +1).shaped(self.shaping)
            return up, single_pulse(v_in_mm_s, x_f_mm, t_down, -1).shaped(self.shaping)
        return self.shaping.moves(v_in_mm_s, x_f_mm, t_up, t_down)

    def design_document(self, system: str | None = None) -> dict[str, Any]:
        """The design-file document, under ``system`` if it differs (:func:`as_design`)."""
        return as_design(self, system).to_dict()

    def to_dict(self) -> dict[str, Any]:
        """The design-file document (see ``docs/shaper_design.md``)."""
        doc: dict[str, Any] = {
            "format": DESIGN_FORMAT,
            "version": DESIGN_VERSION,
            "kind": self.kind,
            "system": self.system,
            "provenance": dict(self.provenance),
        }
        s = self.shaping
        if isinstance(s, Shaper):
            doc["shaper"] = shaper_to_dict(s)
        elif isinstance(s, ShaperPair):
            doc["up"], doc["down"] = shaper_to_dict(s.up), shaper_to_dict(s.down)
        else:
            doc["schedule"] = {
                "v_in_mm_s": s.v_in_mm_s,
                "x_f_mm": s.x_f_mm,
                "up": _move_to_dict(s.up),
                "down": _move_to_dict(s.down),
            }
        return doc

    @classmethod
    def from_dict(cls, doc: Any, where: str = "design") -> Design:
        """Rebuild a design from :meth:`to_dict`'s document; one ``ValueError`` naming the field otherwise."""
        doc = check_versioned(doc, where, DESIGN_FORMAT, DESIGN_VERSION)
        unknown = sorted(set(doc) - _TOP_KEYS)
        if unknown:
            raise ValueError(f"{where}: {unknown[0]}: unknown key")
        kind = doc.get("kind")
        if kind not in KINDS:
            raise ValueError(f"{where}: kind: expected one of {', '.join(KINDS)}, got {kind!r}")
        system = doc.get("system")
        if system not in SYSTEMS or system == "unshaped":
            raise ValueError(f"{where}: system: {system!r} is not a design system of the vocabulary")
        provenance = doc.get("provenance", {})
        if not isinstance(provenance, dict):
            raise ValueError(f"{where}: provenance: expected an object")
        expected = {"shaper": ("shaper",), "pair": ("up", "down"), "schedule": ("schedule",)}[kind]
        for key in expected:
            if key not in doc:
                raise ValueError(f"{where}: {key}: missing (kind {kind!r})")
        for key in ("shaper", "up", "down", "schedule"):
            if key not in expected and key in doc:
                raise ValueError(f"{where}: {key}: not allowed for kind {kind!r}")
        if kind == "shaper":
            shaping: Shaping = shaper_from_dict(doc["shaper"], f"{where}: shaper")
        elif kind == "pair":
            up = shaper_from_dict(doc["up"], f"{where}: up")
            shaping = ShaperPair(up, shaper_from_dict(doc["down"], f"{where}: down"))
        else:
            shaping = _schedule_from_dict(doc["schedule"], f"{where}: schedule")
        return cls(system, shaping, provenance)


def kind_of(shaping: Any) -> str:
    """``"shaper"``, ``"pair"`` or ``"schedule"`` for a shaping object (``ValueError`` otherwise)."""
    if isinstance(shaping, Shaper):
        return "shaper"
    if isinstance(shaping, ShaperPair):
        return "pair"
    if isinstance(shaping, Schedule):
        return "schedule"
    raise ValueError(f"not a shaping (Shaper, ShaperPair or Schedule): {shaping!r}")


def up_down(shaping: Shaping | Design | None) -> tuple[Shaper | None, Shaper | None]:
    """The Up and the Down move's shaper of a shaping (``(None, None)`` for None or a schedule)."""
    if isinstance(shaping, Design):
        shaping = shaping.shaping
    if shaping is None or isinstance(shaping, Schedule):
        return None, None
    if isinstance(shaping, Shaper):
        return shaping, shaping
    if isinstance(shaping, ShaperPair):
        return shaping.up, shaping.down
    raise ValueError(f"not a shaping (Shaper, ShaperPair or Schedule): {shaping!r}")


def as_design(shaping: Shaping | Design, system: str | None = None, **provenance: Any) -> Design:
    """A :class:`Design` from a design (returned as is, renamed if ``system`` differs) or a bare shaping.

    A bare :class:`~helpers.paper.shapers.Shaper` named ``zv`` or ``zvd`` (as
    :func:`helpers.paper.shapers.design_tdfs` names them) keeps that system; any other bare shaping is
    ``custom``
    unless ``system`` is given.
    """
    if isinstance(shaping, Design):
        if system is None or system == shaping.system:
            return shaping
        return Design(system, shaping.shaping, shaping.provenance)
    if system is None:
        name = getattr(shaping, "name", None)
        system = name if isinstance(shaping, Shaper) and name in ("zv", "zvd") else "custom"
    return Design(system, shaping, provenance)


# -- JSON pieces -------------------------------------------------------------------------------------------
def _numbers(value: Any, where: str) -> list[float]:
    ok = isinstance(value, list) and value and all(
        isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in value
    )
    if not ok:
        raise ValueError(f"{where}: expected a non-empty list of finite numbers, got {value!r}"[:200])
    return [float(v) for v in value]


def shaper_from_dict(doc: Any, where: str = "shaper") -> Shaper:
    """A :class:`~shapers.Shaper` from ``{"name", "amplitudes", "times"}`` (ValueError if bad)."""
    if not isinstance(doc, dict):
        raise ValueError(f"{where}: expected an object with name, amplitudes and times")
    unknown = sorted(set(doc) - {"name", "amplitudes", "times"})
    if unknown:
        raise ValueError(f"{where}.{unknown[0]}: unknown key")
    name = doc.get("name", "shaper")
    if not isinstance(name, str):
        raise ValueError(f"{where}.name: expected text, got {name!r}")
    for key in ("amplitudes", "times"):
        if key not in doc:
            raise ValueError(f"{where}.{key}: missing")
    a = _numbers(doc["amplitudes"], f"{where}.amplitudes")
    t = _numbers(doc["times"], f"{where}.times")
    try:
        return Shaper(np.array(a), np.array(t), name)
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None


def _move_to_dict(move: MoveSchedule) -> dict[str, Any]:
    return {
        "sub_moves": [
            {"amplitude": s.amplitude, "start_s": s.start_s, "duration_s": s.duration_s}
            for s in move.sub_moves
        ]
    }


def _move_from_dict(doc: Any, where: str) -> MoveSchedule:
    if not isinstance(doc, dict) or set(doc) != {"sub_moves"}:
        raise ValueError(f"{where}: expected an object with sub_moves only")
    subs = doc["sub_moves"]
    if not isinstance(subs, list) or not subs:
        raise ValueError(f"{where}.sub_moves: expected a non-empty list")
    out = []
    for i, s in enumerate(subs):
        here = f"{where}.sub_moves[{i}]"
        if not isinstance(s, dict) or set(s) != {"amplitude", "start_s", "duration_s"}:
            raise ValueError(f"{here}: expected an object with amplitude, start_s and duration_s")
        try:
            out.append(SubMove(s["amplitude"], s["start_s"], s["duration_s"]))
        except ValueError as exc:
            raise ValueError(f"{here}: {exc}") from None
    try:
        return MoveSchedule(tuple(out))
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None


def _schedule_from_dict(doc: Any, where: str) -> Schedule:
    if not isinstance(doc, dict):
        raise ValueError(f"{where}: expected an object")
    unknown = sorted(set(doc) - {"v_in_mm_s", "x_f_mm", "up", "down"})
    if unknown:
        raise ValueError(f"{where}.{unknown[0]}: unknown key")
    for key in ("v_in_mm_s", "x_f_mm", "up", "down"):
        if key not in doc:
            raise ValueError(f"{where}.{key}: missing")
    up = _move_from_dict(doc["up"], f"{where}.up")
    down = _move_from_dict(doc["down"], f"{where}.down")
    try:
        return Schedule(up, down, doc["v_in_mm_s"], doc["x_f_mm"])
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None


# -- files -------------------------------------------------------------------------------------------------
def save_design(design: Design | Shaping, path: str | os.PathLike, system: str | None = None) -> Path:
    """Write a design (or a bare shaper, pair or schedule: see :func:`as_design`) as a JSON design file.

    Parameters
    ----------
    design : Design, Shaper, ShaperPair or Schedule
        What to save.
    path : path-like
        Destination (``.json``); written atomically.
    system : str, optional
        The system name of a bare shaping.

    Returns
    -------
    pathlib.Path
    """
    path = Path(path)
    if path.suffix != ".json":
        raise ValueError(f"a design file's name must end in .json, got {path.name!r}")
    return write_json(path, as_design(design, system).to_dict())


def load_design(path: str | os.PathLike) -> Design:
    """Read a design file written by :func:`save_design`.

    Raises
    ------
    MissingDataError
        If the file does not exist.
    DataFileError
        If it is not a valid design: one line naming the file and the field.
    """
    path = Path(path)
    doc = read_json(
        path, "shaper design", "design one with helpers.research.design and save it with save_design"
    )
    try:
        return Design.from_dict(doc, where=str(path))
    except ValueError as exc:
        raise DataFileError(str(exc)) from None
