"""How a recording states the shaping of its moves: the system vocabulary and the shaping's metadata.

A pulse recording's scenario holds ``system`` (a name of :data:`SYSTEMS`), ``shaper`` and ``shaper_down``
(``{"name", "amplitudes", "times"}`` of the Up and the Down move's shaper, or None) and ``shaping`` (the whole
shaping as a design-file document: ``format``, ``version``, ``kind``, ``system``, ``provenance`` and the
impulses; ``docs/recording_format.md``, ``docs/shaper_design.md``). :func:`pulse_metadata` writes them.

The core states a bare :class:`~helpers.paper.shapers.Shaper` itself. Any other shaping (the designs of the
research wing: an Up/Down pair, a map-following schedule, a design with its provenance) states itself
through the :class:`StatedShaping` interface, so this module never needs to know the designs.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

from helpers.paper.shapers import Shaper

DESIGN_FORMAT = "continuum-arm-shaper-design"
"""The ``format`` tag of a design file (and of a recording's ``scenario.shaping``)."""

DESIGN_VERSION = 1
"""Version of the design file layout; a loader refuses any other."""

SYSTEMS = (
    "unshaped", "zv", "zvd", "ei", "multi-mode", "scheduled", "map-following", "minimax", "auto", "custom",
)  # fmt: skip
"""The vocabulary of ``scenario.system`` (``docs/shaper_design.md``'s table says the same):

- ``unshaped``: the paper's pulse, no shaping;
- ``zv``: the paper's non-robust TDF: a ZV shaper designed from one mode identified at rest;
- ``zvd``: the paper's robust TDF: a ZVD shaper designed from one mode identified at rest;
- ``ei``: an extra-insensitive shaper (EI, 2-hump or 3-hump EI; ``scenario.shaper.name`` says which): at the
  identified mode, or centred on the frequency band a move sweeps when designed from a mode map;
- ``multi-mode``: the dominant mode's shaper convolved with a shaper on the second mode (from a mode map);
- ``scheduled``: an Up/Down pair from a mode map: each move's shaper designed for the configuration where its
  residual vibration happens (Up: its destination; Down: the rest position);
- ``map-following``: a schedule from a mode map: each move made of sub-moves whose starts and stops are
  spaced by the phase the mode accumulates at the configurations the arm passes through;
- ``minimax``: impulses chosen to minimise the worst predicted residual over a mode map's points in the band
  a move sweeps and over their uncertainty;
- ``auto``: the shortest candidate whose predicted residual stays within a tolerance over the band a move
  sweeps and the map's uncertainty;
- ``custom``: any other saved shaper or pair (e.g. ZVDD, MZV, UM-ZV), named by ``scenario.shaper.name``.
"""


@runtime_checkable
class StatedShaping(Protocol):
    """A shaping that states itself in a recording (the research wing's designs implement it)."""

    def up_down(self) -> tuple[Shaper | None, Shaper | None]:
        """The Up and the Down move's shaper (``(None, None)`` when the moves are not one shaper each)."""
        ...

    def design_document(self, system: str | None) -> dict[str, Any]:
        """The shaping as a design-file document, named ``system`` (None: its own name)."""
        ...


def shaper_to_dict(shaper: Shaper) -> dict[str, Any]:
    """``{"name", "amplitudes", "times"}`` of a shaper (the recordings' ``scenario.shaper`` layout)."""
    return {
        "name": shaper.name,
        "amplitudes": [float(a) for a in shaper.amplitudes],
        "times": [float(t) for t in shaper.times],
    }


def design_system(system: str | None) -> str | None:
    """``system`` if it can name a design (a name of :data:`SYSTEMS` other than unshaped), else None."""
    return system if system in SYSTEMS and system != "unshaped" else None


def shaper_document(shaper: Shaper, system: str | None = None) -> dict[str, Any]:
    """A bare shaper as a design-file document (no provenance).

    A shaper named ``zv`` or ``zvd`` (as :func:`helpers.paper.shapers.design_tdfs` names them) keeps that
    system; any other is ``custom`` unless ``system`` is given.
    """
    if system is None:
        system = shaper.name if shaper.name in ("zv", "zvd") else "custom"
    if design_system(system) is None:
        names = ", ".join(s for s in SYSTEMS if s != "unshaped")
        raise ValueError(f"design system must be one of {names}; got {system!r}")
    return {
        "format": DESIGN_FORMAT,
        "version": DESIGN_VERSION,
        "kind": "shaper",
        "system": system,
        "provenance": {},
        "shaper": shaper_to_dict(shaper),
    }


def pulse_metadata(shaping: Shaper | StatedShaping | None, system: str | None = None) -> dict[str, Any]:
    """The scenario keys ``system``, ``shaper``, ``shaper_down`` and ``shaping`` of a pulse's shaping.

    Parameters
    ----------
    shaping : Shaper, StatedShaping or None
        None for the unshaped pulse, a bare shaper for both moves, or a shaping that states itself.
    system : str, optional
        A name of :data:`SYSTEMS`. Default: the shaping's own system (``shaping.system``) if it has one, else
        the shaper's name (``"unshaped"`` for None).
    """
    if system is None:
        system = getattr(shaping, "system", None)
    if shaping is None:
        up = down = document = None
    elif isinstance(shaping, Shaper):
        up = down = shaping
        document = shaper_document(shaping, design_system(system))
    elif isinstance(shaping, StatedShaping):
        up, down = shaping.up_down()
        document = shaping.design_document(design_system(system))
    else:
        raise ValueError(f"not a shaping (a Shaper, a design or None): {shaping!r}")
    name = getattr(shaping, "name", None)
    return {
        "system": system or ("unshaped" if shaping is None else str(name or "shaped")),
        "shaper": None if up is None else shaper_to_dict(up),
        "shaper_down": None if down is None else shaper_to_dict(down),
        "shaping": document,
    }
