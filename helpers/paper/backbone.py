"""The arm's backbone, shared by the linear model (``helpers.paper.model``) and the virtual rig (``virtual``).

The paper states the geometry (A228 music wire, d = 0.82 mm, L = 0.24 m, 12 cable-support discs); the material
constants are handbook values. Both models build on :class:`Backbone`, so these numbers have one home.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from helpers.paper import numbers as paper

E_A228: float = 206.8e9
"""Young's modulus of ASTM A228 music wire, Pa: 30e6 psi, the value spring-wire makers tabulate (reference
values range from about 190 to 210 GPa)."""

RHO_STEEL: float = 7850.0
"""Density of carbon steel, kg/m^3 (0.284 lb/in^3 is tabulated for A228)."""

SOURCES: dict[str, tuple[str, str, str]] = {
    # field: (unit, source, reason)
    "E": ("Pa", "handbook", "ASTM A228 music wire, 30e6 psi (range 190-210 GPa)"),
    "rho": ("kg/m^3", "handbook", "carbon steel"),
    "d": ("m", "paper", "backbone diameter 0.82 mm"),
    "L": ("m", "paper", "arm length 0.24 m"),
    "n_discs": ("-", "paper", "12 cable-support discs, the last at the tip where the cable is knotted"),
}
"""Unit, source and reason of each backbone field (used by the parameter tables of both models)."""


def _positive(value: object, name: str) -> None:
    if not (isinstance(value, int | float | np.floating) and math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")


@dataclass(frozen=True)
class Backbone:
    """The elastic backbone: a uniform circular wire of length ``L`` carrying ``n_discs`` discs (SI units).

    Attributes
    ----------
    E : float
        Young's modulus, Pa (handbook, :data:`E_A228`).
    rho : float
        Density, kg/m^3 (handbook, :data:`RHO_STEEL`).
    d : float
        Wire diameter, m (paper).
    L : float
        Length from the clamp to the last disc, m (paper).
    n_discs : int
        Number of cable-support discs (paper).
    """

    E: float = E_A228
    rho: float = RHO_STEEL
    d: float = float(paper.BACKBONE["d_m"])
    L: float = float(paper.BACKBONE["L_m"])
    n_discs: int = int(paper.BACKBONE["n_discs"])

    def __post_init__(self) -> None:
        cls = type(self).__name__
        for name in ("E", "rho", "d", "L"):
            _positive(getattr(self, name), f"{cls}.{name}")
        n = self.n_discs
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
            raise ValueError(f"{cls}.n_discs must be a positive integer, got {n!r}")

    @property
    def area(self) -> float:
        """Cross-section, m^2."""
        return math.pi * self.d**2 / 4.0

    @property
    def second_moment(self) -> float:
        """Second moment of area, m^4."""
        return math.pi * self.d**4 / 64.0

    @property
    def EI(self) -> float:  # noqa: N802 - the conventional symbol
        """Bending stiffness, N m^2."""
        return self.E * math.pi * self.d**4 / 64.0

    @property
    def rod_mass(self) -> float:
        """Mass of the wire, kg."""
        return self.rho * self.area * self.L
