"""Physical parameters of the virtual rig's plant and sensor: the one place they are defined.

Every field says its unit, its value and where the value comes from: *paper* (stated in the paper),
*handbook* (a material constant), *assumed* (a plausible value nobody measured, with the reason) or
*calibrated* (chosen in :mod:`helpers.virtual.calibration` so that the simulated rig reproduces the paper's
identified mode and Table II magnitudes). ``docs/virtual_rig.md`` carries the same table with more words.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

__all__ = ["RigParameters", "MM_PER_STEP"]

MM_PER_STEP: float = math.pi * 65.0 / 800.0
"""Cable travel per stepper step, mm: spool diameter 65 mm, 800 steps/rev (paper). Same as
``helpers.profiles.MM_PER_STEP``; repeated here so that the physics does not import the command layer."""


@dataclass(frozen=True)
class RigParameters:
    """Parameters of the nonlinear arm, the cable and the load cell (SI units unless a name says otherwise).

    Attributes
    ----------
    E : float
        Young's modulus of the backbone, Pa. 206.8e9 (30e6 psi), the value spring-wire makers tabulate for
        ASTM A228 music wire (*handbook*; the same value as ``helpers.model``).
    rho : float
        Density of the backbone, kg/m^3. 7850 (carbon steel, *handbook*).
    d : float
        Backbone diameter, m. 0.82e-3 (*paper*).
    L : float
        Length of the arm from the clamp to the last disc, m. 0.24 (*paper*).
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
        Mass of each disc (with its share of eyelet, glue and knot), kg. *Calibrated* so that the dominant
        mode of the simulated identification run has omega_d = 25.085 rad/s.
    disc_mass_uniform : bool
        If True, the total disc mass is spread over *every* node (uniform mass per length, as the paper's
        linear model assumes) instead of concentrated at the 12 stations. Only for validation.
    eyelets_every_node : bool
        If True, the cable passes an eyelet at every node (the cable then follows the backbone polygon, as the
        continuum formula assumes); otherwise only at the disc stations (the real rig). Only for validation.
    r : float
        Offset of the cable eyelets from the backbone's neutral axis, m. *Calibrated* (paper hint: ~7 mm).
    k : float
        Series stiffness of the cable, the pulleys and the load cell, N/m. *Calibrated* to Table II's Up
        peaks.
    pretension : float
        Cable tension with the arm at rest at cable position 0 (the "down position"), N. *Calibrated* to the
        Down overshoots of Table II (their peaks read 0 N: the cable goes slack on the way down).
    base_angle_deg : float
        Direction of the backbone's tangent at the clamp, degrees counter-clockwise from the horizontal;
        gravity points along -y and the cable runs on the left (+normal) side, so pulling bends the arm
        counter-clockwise. 0 = horizontal arm bending up, -90 = hanging arm, 90 = upright arm. *Calibrated*
        / *assumed*, see ``docs/virtual_rig.md``.
    g : float
        Gravitational acceleration, m/s^2. 9.81; 0 switches gravity off (validation).
    alpha : float
        Mass-proportional damping, 1/s: a viscous drag ``-alpha m_j v_j`` on every point mass (air drag and
        support losses). *Calibrated* with ``beta`` to zeta = 0.044 of the dominant mode.
    beta : float
        Stiffness-proportional damping, s: a dashpot ``beta * EI/l`` in parallel with every joint spring
        (material damping of the wire). *Calibrated* with ``alpha``.
    max_step : float
        Largest integration step of the fixed-step integrator, s. Chosen by measured convergence against a
        tight solve_ivp reference (``docs/virtual_rig.md``).
    """

    E: float = 206.8e9
    rho: float = 7850.0
    d: float = 0.82e-3
    L: float = 0.24
    n_discs: int = 12
    segments_per_disc: int = 1
    disc_mass: float = 2.0e-3
    disc_mass_uniform: bool = False
    eyelets_every_node: bool = False
    r: float = 7.2e-3
    k: float = 5000.0
    pretension: float = 1.5
    base_angle_deg: float = 0.0
    g: float = 9.81
    alpha: float = 0.0
    beta: float = 0.0
    max_step: float = 5.0e-4

    def __post_init__(self) -> None:
        for name in ("E", "rho", "d", "L", "r", "k", "max_step"):
            value = getattr(self, name)
            if not (isinstance(value, int | float | np.floating) and math.isfinite(value) and value > 0):
                raise ValueError(f"RigParameters.{name} must be a positive finite number, got {value!r}")
        for name in ("disc_mass", "pretension", "g", "alpha", "beta"):
            value = getattr(self, name)
            if not (isinstance(value, int | float | np.floating) and math.isfinite(value) and value >= 0):
                raise ValueError(f"RigParameters.{name} must be a finite number >= 0, got {value!r}")
        if not math.isfinite(self.base_angle_deg):
            raise ValueError(f"RigParameters.base_angle_deg must be finite, got {self.base_angle_deg!r}")
        for name in ("n_discs", "segments_per_disc"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
                raise ValueError(f"RigParameters.{name} must be a positive integer, got {value!r}")

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
    def area(self) -> float:
        """Backbone cross-section, m^2."""
        return math.pi * self.d**2 / 4.0

    @property
    def EI(self) -> float:  # noqa: N802 - the conventional symbol
        """Bending stiffness of the backbone, N m^2."""
        return self.E * math.pi * self.d**4 / 64.0

    @property
    def rod_mass(self) -> float:
        """Mass of the backbone wire, kg."""
        return self.rho * self.area * self.L

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
