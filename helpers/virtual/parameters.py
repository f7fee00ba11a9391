"""Physical parameters of the virtual rig's plant: the one place they are defined, tuned values included.

Every field says its unit, its value and where the value comes from: *paper* (stated in the paper),
*handbook* (a material constant), *assumed* (a plausible value nobody measured, with the reason) or *tuned*
(chosen by the rig tuning, :mod:`helpers.rig_tuning`, so that the simulated rig reproduces the paper's
identified mode and Table II magnitudes). ``RigParameters()`` is the tuned rig. The backbone's fields come
from :class:`helpers.backbone.Backbone`, shared with the linear model. ``docs/virtual_rig.md`` carries the
same table with more words.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from helpers.backbone import SOURCES as BACKBONE_SOURCES
from helpers.backbone import Backbone

__all__ = ["RigParameters", "TUNED", "parameter_table"]

TUNED: dict[str, float] = {
    "disc_mass": 1.1333e-3,
    "r": 7.8e-3,
    "k": 6000.0,
    "pretension": 2.3,
    "base_angle_deg": 0.0,
    "alpha": 1.8688,
    "beta": 5.821e-4,
}
"""The values the rig tuning chose (the defaults of :class:`RigParameters`; ``docs/virtual_rig.md``)."""


@dataclass(frozen=True)
class RigParameters(Backbone):
    """Parameters of the nonlinear arm, the cable and the load cell (SI units unless a name says otherwise).

    The defaults are the tuned virtual rig. The backbone (``E``, ``rho``, ``d``, ``L``, ``n_discs``) is
    :class:`helpers.backbone.Backbone`'s.

    Attributes
    ----------
    n_discs : int
        Number of cable-support discs, 12 (*paper*). Disc ``k`` (1..n_discs) sits at arc length
        ``k L / n_discs``; the last one is at the tip, where the cable is knotted (*paper*). The cable
        enters the arm through a guide hole in the clamp plate at the same offset ``r`` (*assumed*: the
        paper routes the cable "into the proximal end" over pulleys; a guide at the clamp is the simplest
        reading).
    segments_per_disc : int
        Rigid segments between consecutive discs (1 by default: one segment per disc station). Larger values
        refine the rod for the convergence test while keeping the eyelets at the disc stations.
    disc_mass : float
        Mass of each disc (with its share of eyelet, glue and knot), kg. *Tuned* so that the dominant
        mode of the simulated identification run has omega_d = 25.085 rad/s.
    disc_mass_uniform : bool
        If True, the total disc mass is spread over *every* node (uniform mass per length, as the paper's
        linear model assumes) instead of concentrated at the 12 stations. Only for validation.
    eyelets_every_node : bool
        If True, the cable passes an eyelet at every node (the cable then follows the backbone polygon, as the
        continuum formula assumes); otherwise only at the disc stations (the real rig). Only for validation.
    r : float
        Offset of the cable eyelets from the backbone's neutral axis, m. *Assumed* (paper hint: ~7 mm).
    k : float
        Series stiffness of the cable, the pulleys and the load cell, N/m. *Tuned* to Table II's Up peaks.
    pretension : float
        Cable tension with the arm at rest at cable position 0 (the "down position"), N. *Calibrated* to the
        Down overshoots of Table II (their peaks read 0 N: the cable goes slack on the way down).
    base_angle_deg : float
        Direction of the backbone's tangent at the clamp, degrees counter-clockwise from the horizontal;
        gravity points along -y and the cable runs on the left (+normal) side, so pulling bends the arm
        counter-clockwise. 0 = horizontal arm bending up, -90 = hanging arm, 90 = upright arm. *Assumed*,
        see ``docs/virtual_rig.md``.
    g : float
        Gravitational acceleration, m/s^2. 9.81; 0 switches gravity off (validation).
    alpha : float
        Mass-proportional damping, 1/s: a viscous drag ``-alpha m_j v_j`` on every point mass (air drag and
        support losses). *Tuned* with ``beta`` to zeta = 0.044 of the dominant mode.
    beta : float
        Stiffness-proportional damping, s: a dashpot ``beta * EI/l`` in parallel with every joint spring
        (material damping of the wire). *Tuned* with ``alpha``.
    max_step : float
        Largest integration step of the fixed-step integrator, s. Chosen by measured convergence against a
        tight solve_ivp reference (``docs/virtual_rig.md``).
    """

    segments_per_disc: int = 1
    disc_mass: float = TUNED["disc_mass"]
    disc_mass_uniform: bool = False
    eyelets_every_node: bool = False
    r: float = TUNED["r"]
    k: float = TUNED["k"]
    pretension: float = TUNED["pretension"]
    base_angle_deg: float = TUNED["base_angle_deg"]
    g: float = 9.81
    alpha: float = TUNED["alpha"]
    beta: float = TUNED["beta"]
    max_step: float = 5.0e-4

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in ("r", "k", "max_step"):
            value = getattr(self, name)
            if not (isinstance(value, int | float | np.floating) and math.isfinite(value) and value > 0):
                raise ValueError(f"RigParameters.{name} must be a positive finite number, got {value!r}")
        for name in ("disc_mass", "pretension", "g", "alpha", "beta"):
            value = getattr(self, name)
            if not (isinstance(value, int | float | np.floating) and math.isfinite(value) and value >= 0):
                raise ValueError(f"RigParameters.{name} must be a finite number >= 0, got {value!r}")
        if not math.isfinite(self.base_angle_deg):
            raise ValueError(f"RigParameters.base_angle_deg must be finite, got {self.base_angle_deg!r}")
        value = self.segments_per_disc
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
            raise ValueError(f"RigParameters.segments_per_disc must be a positive integer, got {value!r}")

    def replace(self, **changes: object) -> RigParameters:
        """Return a copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    @property
    def n_segments(self) -> int:
        """Number of rigid segments (= joints = nodes after the clamp)."""
        return int(self.n_discs * self.segments_per_disc)

    @property
    def segment_length(self) -> float:
        """Length of one rigid segment, m."""
        return self.L / self.n_segments

    @property
    def total_mass(self) -> float:
        """Wire plus discs, kg."""
        return self.rod_mass + self.n_discs * self.disc_mass

    @property
    def joint_stiffness(self) -> float:
        """Rotational stiffness EI / l of the joint springs, N m/rad (the clamp's is 2 EI / l)."""
        return self.EI / self.segment_length

    @property
    def base_angle(self) -> float:
        """Base tangent direction, rad."""
        return math.radians(self.base_angle_deg)

    def line_density(self) -> float:
        """Mass per length of the uniform rod, kg/m: the wire, plus the discs if ``disc_mass_uniform``."""
        mu = self.rho * self.area
        if self.disc_mass_uniform:
            mu += self.n_discs * self.disc_mass / self.L
        return mu

    def node_masses(self) -> np.ndarray:
        """Point masses at the nodes 1..n_segments, kg.

        Each segment is a uniform rigid rod (:meth:`line_density`): half its mass at each end node (the clamp
        keeps the half at node 0); the rod's rotary-inertia correction is in :meth:`segment_inertia`. Each
        disc is a point mass at its station (its own rotary inertia, ~5e-8 kg m^2, is 0.3 % of its
        translational inertia about the clamp and is neglected).
        """
        n = self.n_segments
        m_seg = self.line_density() * self.segment_length
        m = np.full(n, m_seg)
        m[-1] = 0.5 * m_seg
        if not self.disc_mass_uniform:
            m[self.segments_per_disc - 1 :: self.segments_per_disc] += self.disc_mass
        return m

    def segment_inertia(self) -> float:
        """Rotary-inertia correction of each segment, kg m^2.

        Two half masses at the ends of a segment give it ``m l^2 / 4`` about its centre; a uniform rod has
        ``m l^2 / 12``: the difference ``-m l^2 / 6`` is added to the segment's own rotational inertia.
        """
        m_seg = self.line_density() * self.segment_length
        return -m_seg * self.segment_length**2 / 6.0

    def eyelet_nodes(self) -> np.ndarray:
        """Node indices of the eyelets (0 = the guide at the clamp), increasing, last = tip."""
        step = 1 if self.eyelets_every_node else self.segments_per_disc
        return np.arange(0, self.n_segments + 1, step, dtype=np.int64)


_SOURCES: dict[str, tuple[str, str, str]] = {
    # field: (unit, source, reason)
    **BACKBONE_SOURCES,
    "segments_per_disc": ("-", "numerical", "one rigid segment per disc interval; convergence checked"),
    "disc_mass": ("kg", "tuned", "identification run gives omega_d = 25.085 rad/s via helpers.identify"),
    "disc_mass_uniform": ("-", "numerical", "False: discs are point masses at their stations"),
    "eyelets_every_node": ("-", "numerical", "False: cable straight between disc eyelets (True: validation)"),
    "r": ("m", "assumed", "paper hint r ~ 7 mm; 7.8 mm puts the static Up tensions near Table II"),
    "k": ("N/m", "tuned", "cable + load cell stiffness: sets the Up peaks/overshoots of Table II"),
    "pretension": ("N", "tuned", "Down overshoots of Table II with a slack cable at the Down peak"),
    "base_angle_deg": ("deg", "assumed", "clamp horizontal, arm bends up against gravity (Fig. 7 caption)"),
    "g": ("m/s^2", "handbook", "standard gravity"),
    "alpha": ("1/s", "tuned", "mass-proportional (air-drag) damping; Rayleigh pair gives zeta = 0.044"),
    "beta": ("s", "tuned", "stiffness-proportional (wire) damping; Rayleigh pair gives zeta = 0.044"),
    "max_step": ("s", "numerical", "RK4 step: max 0.01 N error vs 0.05 ms steps over a 12 s scenario"),
}


def parameter_table(params: RigParameters | None = None) -> pd.DataFrame:
    """Every parameter of the rig with its value, unit, source and reason (for notebooks and docs).

    Returns
    -------
    pandas.DataFrame
        Index: field name; columns ``value``, ``unit``, ``source``, ``reason``.
    """
    params = RigParameters() if params is None else params
    rows = []
    for f in dataclasses.fields(params):
        unit, source, reason = _SOURCES.get(f.name, ("", "", ""))
        rows.append({"parameter": f.name, "value": getattr(params, f.name), "unit": unit, "source": source,
                     "reason": reason})  # fmt: skip
    return pd.DataFrame(rows).set_index("parameter")
