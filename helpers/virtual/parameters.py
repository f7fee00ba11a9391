"""Physical parameters of the virtual rig: the one place they are defined, tuned values included.

Every field says its unit, its value and where the value comes from: *paper* (stated in the paper),
*handbook* (a material constant), *datasheet* (a typical catalogue value of the part the paper names),
*assumed* (a plausible value nobody measured, with the reason), *tuned* (chosen by the rig tuning,
:mod:`helpers.virtual.tuning`, so that the simulated rig reproduces the paper's identified mode and its
unshaped
Table II rows) or *numerical* (a discretisation choice, checked by a convergence study). ``RigParameters()``
is the tuned rig. The backbone's fields come from :class:`helpers.paper.backbone.Backbone`, shared with the
linear
model. ``docs/virtual_rig.md`` carries the same table with more words; :func:`parameter_table` prints it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from helpers.paper import numbers as paper
from helpers.paper.backbone import SOURCES as BACKBONE_SOURCES
from helpers.paper.backbone import Backbone
from helpers.rigfile.units import si

__all__ = [
    "RigParameters", "TUNED", "ACTUATORS", "INTEGRATORS", "INTEGRATOR_STEPS", "DEFAULT_INTEGRATOR", "KG_CM",
    "parameter_table",
]  # fmt: skip

KG_CM: float = 0.0980665
"""One kilogram-force centimetre in N m."""

ACTUATORS = ("ideal", "stepper", "stepper+carriage")
"""Actuator models: the cable moved instantly by each step (``ideal``, for comparison); the rotor and spool
on the motor's microstep spring (``stepper``); the same plus the load-cell carriage between its two cables
(``stepper+carriage``, the rig)."""

TUNED: dict[str, float] = {
    "disc_mass": 1.109951e-03,
    "r": 7.78330e-03,
    "k": 21122.3,
    "pretension": 2.3554,
    "alpha": 1.887944,
    "beta_chord": 5.753788e-04,
}
"""The values the rig tuning chose (the defaults of :class:`RigParameters`; ``docs/virtual_rig.md``)."""

INTEGRATORS = ("rk4", "rosw")
"""The twin's integrators (``docs/virtual_rig.md``, section 2): classical RK4, every term explicit; and the
Rosenbrock-W step (built on RK4) with the elastic stiffness (bending, cables) implicit and everything else
explicit."""

INTEGRATOR_STEPS: dict[str, float] = {"rk4": 2.5e-4, "rosw": 5e-4}
"""Each integrator's largest step (s) for the rig: RK4 within 90 % of its stability limit (the tip disc
rocking against the cable), the implicit step where its convergence band is met (``docs/virtual_rig.md``,
section 2)."""

DEFAULT_INTEGRATOR: tuple[str, float] = ("rosw", INTEGRATOR_STEPS["rosw"])
"""The integrator and largest step of :class:`RigParameters` (``integrator``, ``max_step``).

The Rosenbrock-W step at 0.5 ms: every recording in ``data/`` is made with it (before it they were made
with RK4 at 0.25 ms; what the switch moved, and by how much: ``docs/virtual_rig.md``, section 2).
"""


def _check(value: object, name: str, positive: bool) -> None:
    ok = isinstance(value, int | float | np.floating) and not isinstance(value, bool) and math.isfinite(value)
    ok = ok and (value > 0 if positive else value >= 0)
    if not ok:
        kind = "a positive finite number" if positive else "a finite number >= 0"
        raise ValueError(f"RigParameters.{name} must be {kind}, got {value!r}")


@dataclass(frozen=True)
class RigParameters(Backbone):
    """Parameters of the arm, its cable, the stepper, the load-cell carriage and the sensor chain (SI units).

    The defaults are the tuned virtual rig. The backbone (``E``, ``rho``, ``d``, ``L``, ``n_discs``) is
    :class:`helpers.paper.backbone.Backbone`'s. Units and sources of every field: :func:`parameter_table`.

    Attributes
    ----------
    elements_per_disc : int
        Constant-curvature elements per disc interval (1: one arc between consecutive discs). Larger values
        refine the rod for the convergence study; the discs stay at their 12 stations.
    bowing : bool
        Include the rod's bowing between eyelets (:meth:`helpers.virtual.statics.ArcChain.bow_compliance`):
        the part of the cable's moment that a constant-curvature element cannot carry, as a compliance in
        series with the cable. *Numerical* (it vanishes as the elements shrink); off only for comparison.
    disc_mass : float
        Mass of each disc with its eyelet and glue, kg. *Tuned*: the identification run gives
        omega_d = 25.085 rad/s.
    disc_radius, disc_thickness : float
        Disc size for its rotary inertia about a diameter, ``J = m (R^2/4 + t^2/12)``, m. *Assumed*.
    disc_mass_uniform : bool
        Spread the discs' mass over every node as point masses (no rotary inertia), as the paper's linear
        model assumes. Validation only.
    eyelets_every_node : bool
        Put an eyelet at every node (the cable then follows the backbone). Validation only.
    r : float
        Offset of the eyelets from the backbone's neutral axis, m.
    k : float
        Series stiffness of everything between the arm and the motor's commanded position at low frequency
        (microstep spring, spool-side cable, load cell, arm-side cable), N/m. *Tuned*.
    pretension : float
        Cable tension with the arm at rest at cable position 0, N. *Tuned*.
    base_angle_deg : float
        Direction of the clamp tangent, degrees counter-clockwise from the horizontal (0: horizontal arm
        bending up against gravity). *Assumed*.
    g : float
        Gravity, m/s^2 (0 switches it off for validation).
    alpha : float
        Mass-proportional damping, 1/s: ``-alpha m v`` on every mass and ``-alpha J omega`` on every disc.
    beta_chord : float
        Wire material damping, s: rotational dashpots ``beta_chord EI / l_d`` on the relative rotation of
        consecutive inter-disc chords. With ``alpha`` *tuned* to zeta = 0.044 of the lowest mode.
    beta_disc : float
        Stiffness-proportional dashpots ``beta_disc EI / l_d`` on the relative rotation of consecutive discs
        (0 in the rig; the damping-layout comparison uses it).
    floor_zeta, floor_omega : float
        High-mode damping floor: every undamped mode at rest gets an added ``2 floor_zeta omega s(omega)``
        with ``s = 1 / (1 + (floor_omega / omega)^8)``: about ``floor_zeta`` above ``floor_omega`` (rad/s),
        nothing on the low modes. *Assumed*.
    eyelet_mu, eyelet_v0 : float
        Capstan friction coefficient of the cable in the guide and the eyelets (0: frictionless, the rig) and
        its regularisation speed, m/s.
    actuator : str
        One of :data:`ACTUATORS`.
    steps_per_rev, spool_diameter : int, float
        Microsteps per revolution and the spool's diameter, m (*paper*).
    rotor_inertia, spool_inertia : float
        kg m^2 (*datasheet*; *assumed*).
    holding_torque : float
        Amplitude of the motor's torque against rotor displacement, N m (*assumed*, see the table).
    rotor_teeth : int
        Rotor teeth of the 1.8 deg hybrid motor (200 full steps = 4 x 50).
    torque_law : str
        ``"sin"`` (``T = T_h sin(N_r delta)``) or ``"linear"`` (``T_h N_r delta``).
    rotor_zeta : float
        Damping ratio of the rotor mode (rotor + spool on the microstep spring and the cable), *assumed*.
    carriage_mass, carriage_zeta : float
        Load-cell carriage on its rails (kg) and the damping ratio of its mode, *assumed*.
    spool_side_share : float
        Share of the cable's compliance on the spool side of the carriage, *assumed*.
    load_cell_side : str
        ``"arm"``: the load cell reads the arm-side cable's tension; ``"spool"``: the spool side's.
    amp_bandwidth_hz : float
        -3 dB bandwidth of the load-cell amplifier, first order, Hz (0: no filter). *Assumed*.
    span_n : float
        Load that drives the amplifier's loop to 20 mA (its full-scale setting), N. *Assumed*.
    adc_noise_counts : float
        Gaussian noise of the reading, counts rms. *Assumed*.
    loop_zero_ma, loop_full_ma : float
        The amplifier's current loop at zero and at full-scale load (``span_n``), mA.
    loop_min_ma, loop_max_ma : float
        The loop's linear range, mA: beyond it the output saturates.
    shunt_ohm : float
        The resistor that turns the loop current into the ADC's voltage, ohm (paper).
    adc_vref_v : float
        The ADC's reference voltage, V.
    adc_bits : int
        The ADC's resolution, bits.
    integrator : str
        One of :data:`INTEGRATORS` (*numerical*): ``"rk4"`` (every term explicit; its step is limited by the
        tip disc rocking against the cable, 0.30 ms) or ``"rosw"`` (the cables' stiffness implicit, the step
        set by the remaining modes and by accuracy).
    max_step : float
        Largest integrator step, s (*numerical*).
    """

    elements_per_disc: int = 1
    bowing: bool = True
    disc_mass: float = TUNED["disc_mass"]
    disc_radius: float = 12.0e-3
    disc_thickness: float = 4.0e-3
    disc_mass_uniform: bool = False
    eyelets_every_node: bool = False
    r: float = TUNED["r"]
    k: float = TUNED["k"]
    pretension: float = TUNED["pretension"]
    base_angle_deg: float = 0.0
    g: float = 9.81
    alpha: float = TUNED["alpha"]
    beta_chord: float = TUNED["beta_chord"]
    beta_disc: float = 0.0
    floor_zeta: float = 0.2
    floor_omega: float = 1000.0
    eyelet_mu: float = 0.0
    eyelet_v0: float = 1.0e-3
    actuator: str = "stepper+carriage"
    steps_per_rev: int = paper.STEPS_PER_REV
    spool_diameter: float = paper.SPOOL_DIAMETER_M
    rotor_inertia: float = 5.4e-6
    spool_inertia: float = 1.6e-5
    holding_torque: float = 1.5 * paper.HOLDING_TORQUE_KG_CM * KG_CM
    rotor_teeth: int = 50
    torque_law: str = "sin"
    rotor_zeta: float = 0.1
    carriage_mass: float = 0.030
    carriage_zeta: float = 0.05
    spool_side_share: float = 0.25
    load_cell_side: str = "arm"
    amp_bandwidth_hz: float = 1000.0
    span_n: float = 20.0
    adc_noise_counts: float = 0.5
    loop_zero_ma: float = 4.0
    loop_full_ma: float = 20.0
    loop_min_ma: float = 3.8
    loop_max_ma: float = 20.5
    shunt_ohm: float = paper.SHUNT_OHM
    adc_vref_v: float = 5.0
    adc_bits: int = 10
    integrator: str = DEFAULT_INTEGRATOR[0]
    max_step: float = DEFAULT_INTEGRATOR[1]

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in ("r", "k", "max_step", "spool_diameter", "rotor_inertia", "holding_torque", "span_n",
                     "carriage_mass", "disc_radius", "eyelet_v0", "floor_omega", "loop_full_ma",
                     "loop_max_ma", "shunt_ohm", "adc_vref_v"):  # fmt: skip
            _check(getattr(self, name), name, positive=True)
        for name in ("disc_mass", "disc_thickness", "pretension", "g", "alpha", "beta_chord", "beta_disc",
                     "floor_zeta", "eyelet_mu", "spool_inertia", "rotor_zeta", "carriage_zeta",
                     "amp_bandwidth_hz", "adc_noise_counts", "loop_zero_ma", "loop_min_ma"):  # fmt: skip
            _check(getattr(self, name), name, positive=False)
        if not math.isfinite(self.base_angle_deg):
            raise ValueError(f"RigParameters.base_angle_deg must be finite, got {self.base_angle_deg!r}")
        if not self.loop_min_ma < self.loop_zero_ma < self.loop_full_ma < self.loop_max_ma:
            raise ValueError("RigParameters: need loop_min_ma < loop_zero_ma < loop_full_ma < loop_max_ma")
        for name in ("elements_per_disc", "steps_per_rev", "rotor_teeth", "adc_bits"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
                raise ValueError(f"RigParameters.{name} must be a positive integer, got {value!r}")
        if self.actuator not in ACTUATORS:
            raise ValueError(f"RigParameters.actuator must be one of {ACTUATORS}, got {self.actuator!r}")
        if self.integrator not in INTEGRATORS:
            raise ValueError(
                f"RigParameters.integrator must be one of {INTEGRATORS}, got {self.integrator!r}"
            )
        if self.torque_law not in ("sin", "linear"):
            raise ValueError(f"RigParameters.torque_law must be 'sin' or 'linear', got {self.torque_law!r}")
        if self.load_cell_side not in ("arm", "spool"):
            raise ValueError(
                f"RigParameters.load_cell_side must be 'arm' or 'spool', got {self.load_cell_side!r}"
            )
        if not 0.0 < self.spool_side_share < 1.0:
            raise ValueError(
                f"RigParameters.spool_side_share must lie in (0, 1), got {self.spool_side_share!r}"
            )
        if self.actuator != "ideal" and self.k * self.spool_radius**2 >= self.motor_stiffness:
            raise ValueError(
                f"RigParameters.k = {self.k:.0f} N/m is not below the microstep spring alone "
                f"({self.motor_stiffness / self.spool_radius**2:.0f} N/m at the cable): no cable stiffness "
                "is left"
            )

    def replace(self, **changes: object) -> RigParameters:
        """Return a copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    def with_integrator(self, integrator: str) -> RigParameters:
        """The same rig integrated by ``integrator`` at its step (:data:`INTEGRATOR_STEPS`)."""
        if integrator not in INTEGRATORS:
            raise ValueError(f"integrator must be one of {INTEGRATORS}, got {integrator!r}")
        return self.replace(integrator=integrator, max_step=INTEGRATOR_STEPS[integrator])

    # --- the arm --------------------------------------------------------------------------------------
    @property
    def n_elements(self) -> int:
        """Number of arc elements (= nodes after the clamp)."""
        return int(self.n_discs * self.elements_per_disc)

    @property
    def element_length(self) -> float:
        """Length of one arc element, m."""
        return self.L / self.n_elements

    @property
    def disc_interval(self) -> float:
        """Distance between consecutive discs along the rod, m."""
        return self.L / self.n_discs

    @property
    def disc_inertia(self) -> float:
        """Rotary inertia of one disc about a diameter, kg m^2."""
        return self.disc_mass * (self.disc_radius**2 / 4.0 + self.disc_thickness**2 / 12.0)

    @property
    def total_mass(self) -> float:
        """Wire plus discs, kg."""
        return self.rod_mass + self.n_discs * self.disc_mass

    @property
    def base_angle(self) -> float:
        """Clamp direction, rad."""
        return math.radians(self.base_angle_deg)

    def disc_nodes(self) -> np.ndarray:
        """Node indices (1-based) of the discs, the last at the tip."""
        m = self.elements_per_disc
        return np.arange(m, self.n_elements + 1, m, dtype=np.int64)

    def eyelet_nodes(self) -> np.ndarray:
        """Node indices (1-based) of the eyelets after the clamp guide: the discs, or every node."""
        if self.eyelets_every_node:
            return np.arange(1, self.n_elements + 1, dtype=np.int64)
        return self.disc_nodes()

    def node_masses(self) -> np.ndarray:
        """Point masses at nodes 1..N, kg.

        Half of each adjacent element's wire (the clamp keeps its half) and the disc at a disc node (or the
        discs' mass spread evenly if ``disc_mass_uniform``).
        """
        n = self.n_elements
        m_el = self.rho * self.area * self.element_length
        m = np.full(n, m_el)
        m[-1] = 0.5 * m_el
        if self.disc_mass_uniform:
            m += self.n_discs * self.disc_mass / n
        else:
            m[self.disc_nodes() - 1] += self.disc_mass
        return m

    def node_inertias(self) -> np.ndarray:
        """Rotary inertias at nodes 1..N, kg m^2 (the discs'; none if ``disc_mass_uniform``)."""
        J = np.zeros(self.n_elements)
        if not self.disc_mass_uniform:
            J[self.disc_nodes() - 1] = self.disc_inertia
        return J

    # --- the actuator ---------------------------------------------------------------------------------
    @property
    def spool_radius(self) -> float:
        """M."""
        return 0.5 * self.spool_diameter

    @property
    def cable_per_step(self) -> float:
        """Cable per microstep, m (pi x 65 mm / 800 = 0.25525 mm)."""
        return math.pi * self.spool_diameter / self.steps_per_rev

    @property
    def step_angle(self) -> float:
        """Commanded rotor increment per microstep, rad."""
        return 2.0 * math.pi / self.steps_per_rev

    @property
    def drive_inertia(self) -> float:
        """Rotor plus spool, kg m^2."""
        return self.rotor_inertia + self.spool_inertia

    @property
    def motor_stiffness(self) -> float:
        """Small-angle microstep stiffness ``T_h N_r``, N m/rad."""
        return self.holding_torque * self.rotor_teeth

    @property
    def pull_out_tension(self) -> float:
        """Largest cable tension the motor holds, ``T_h / R``, N."""
        return self.holding_torque / self.spool_radius

    @property
    def k_cable(self) -> float:
        """Stiffness of the cables and the load cell between the spool and the arm, N/m.

        ``1/k_cable = 1/k - R^2/K_motor`` (``k`` itself for the ideal actuator).
        """
        if self.actuator == "ideal":
            return self.k
        return 1.0 / (1.0 / self.k - self.spool_radius**2 / self.motor_stiffness)

    @property
    def k_spool_side(self) -> float:
        """Spool-side cable of the carriage, N/m."""
        return self.k_cable / self.spool_side_share

    @property
    def k_arm_side(self) -> float:
        """Arm-side cable of the carriage (with the load cell), N/m."""
        return self.k_cable / (1.0 - self.spool_side_share)

    def motor_torque(self, delta: float) -> float:
        """Motor torque for a rotor lag ``delta = psi_cmd - psi`` (rad), N m."""
        if self.torque_law == "sin":
            return self.holding_torque * math.sin(self.rotor_teeth * delta)
        return self.motor_stiffness * delta

    def tangent_motor_stiffness(self, delta: float) -> float:
        """d(torque)/d(delta) at lag ``delta``, N m/rad."""
        if self.torque_law == "sin":
            return self.motor_stiffness * math.cos(self.rotor_teeth * delta)
        return self.motor_stiffness

    def static_lag(self, tension: float) -> float:
        """Rotor lag (rad) that carries ``tension`` on the spool; NaN beyond the pull-out tension."""
        torque = self.spool_radius * tension
        if self.torque_law == "sin":
            x = torque / self.holding_torque
            return math.asin(x) / self.rotor_teeth if abs(x) <= 1.0 else math.nan
        return torque / self.motor_stiffness

    @property
    def rotor_damping(self) -> float:
        """Rotor viscous coefficient from ``rotor_zeta``, N m s/rad.

        The rotor on the microstep spring and the cable to a fixed arm.
        """
        R = self.spool_radius
        side = self.k_spool_side if self.actuator == "stepper+carriage" else self.k_cable
        return 2.0 * self.rotor_zeta * math.sqrt((self.motor_stiffness + side * R**2) * self.drive_inertia)

    @property
    def carriage_damping(self) -> float:
        """Carriage viscous coefficient from ``carriage_zeta``, N s/m."""
        return (
            2.0 * self.carriage_zeta * math.sqrt((self.k_spool_side + self.k_arm_side) * self.carriage_mass)
        )

    # --- the sensor chain -----------------------------------------------------------------------------
    @property
    def loop_a(self) -> tuple[float, float, float, float]:
        """The loop's currents in A: zero load, full-scale load, lower and upper saturation."""
        zero, full, lo, hi = (si(v, -3) for v in (self.loop_zero_ma, self.loop_full_ma, self.loop_min_ma,
                                                   self.loop_max_ma))  # fmt: skip
        return zero, full, lo, hi

    def loop_counts(self, current_a: float) -> float:
        """ADC reading (counts, unrounded) of a loop current (A) through the shunt, ``2^bits I R / V_ref``."""
        return float(2**self.adc_bits) * current_a * self.shunt_ohm / self.adc_vref_v

    @property
    def gain_counts_per_n(self) -> float:
        """ADC counts per newton of the chain: 16 mA per ``span_n``, through the shunt, 10 bits of V_ref."""
        zero, full, _, _ = self.loop_a
        return self.loop_counts(full - zero) / self.span_n

    @property
    def offset_counts(self) -> float:
        """ADC counts at zero tension (the loop's 4 mA)."""
        return self.loop_counts(self.loop_a[0])

    @property
    def saturation_n(self) -> float:
        """Tension at which the loop saturates (20.5 mA), N."""
        zero, full, _, hi = self.loop_a
        return (hi - zero) / (full - zero) * self.span_n

    def metadata(self) -> dict[str, Any]:
        """Every field and the main derived values as flat JSON values (recordings' ``source.parameters``)."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            out[f.name] = value.item() if isinstance(value, np.generic) else value
        derived = {
            "n_elements": self.n_elements,
            "disc_inertia": self.disc_inertia,
            "k_cable": self.k_cable,
            "k_spool_side": self.k_spool_side,
            "k_arm_side": self.k_arm_side,
            "motor_stiffness": self.motor_stiffness,
            "pull_out_tension": self.pull_out_tension,
            "rotor_damping": self.rotor_damping,
            "carriage_damping": self.carriage_damping,
            "cable_per_step": self.cable_per_step,
            "gain_counts_per_n": self.gain_counts_per_n,
            "offset_counts": self.offset_counts,
            "saturation_n": self.saturation_n,
            "loop_zero_a": self.loop_a[0],
            "loop_full_a": self.loop_a[1],
            "loop_min_a": self.loop_a[2],
            "loop_max_a": self.loop_a[3],
            "shunt_ohm": self.shunt_ohm,
            "adc_vref_v": self.adc_vref_v,
        }
        out.update({f"derived_{k}": v for k, v in derived.items()})
        return out


_SOURCES: dict[str, tuple[str, str, str]] = {
    # field: (unit, source, reason)
    **BACKBONE_SOURCES,
    "elements_per_disc": (
        "-",
        "numerical",
        "one constant-curvature arc per disc interval; converged (notebook 06)",
    ),
    "bowing": (
        "-",
        "numerical",
        "the rod bows away from the straight cable between eyelets: compliance in series with the cable",
    ),
    "disc_mass": (
        "kg", "tuned", "identification run gives omega_d = 25.085 rad/s via helpers.paper.identify"
    ),
    "disc_radius": ("m", "assumed", "eyelets at r need a disc of >= 10 mm radius; 1 g of PLA is ~24 x 2 mm"),
    "disc_thickness": ("m", "assumed", "printed disc; its term is 3 % of the disc's rotary inertia"),
    "disc_mass_uniform": ("-", "numerical", "False: discs at their stations (True: validation only)"),
    "eyelets_every_node": ("-", "numerical", "False: cable straight from disc to disc (True: validation)"),
    "r": ("m", "tuned", "eyelet offset: sets the static tensions; the paper's hint gives ~7 mm"),
    "k": ("N/m", "tuned", "microstep spring + cables + load cell in series: Up peaks/overshoots of Table II"),
    "pretension": (
        "N",
        "tuned",
        "tension at rest: the Down overshoots of Table II (slack cable at the peak)",
    ),
    "base_angle_deg": ("deg", "assumed", "clamp horizontal, arm bends up against gravity (Fig. 7 caption)"),
    "g": ("m/s^2", "handbook", "standard gravity"),
    "alpha": ("1/s", "tuned", "air drag on masses and discs; with beta_chord: zeta = 0.044 of mode 1"),
    "beta_chord": ("s", "tuned", "wire damping between disc chords; Rayleigh ratio through modes 1-2"),
    "beta_disc": ("s", "numerical", "0: disc-to-disc dashpots only in the damping-layout comparison"),
    "floor_zeta": (
        "-",
        "assumed",
        "no mode above ~1 krad/s (disc rocking) is left undamped; sample-level only",
    ),
    "floor_omega": ("rad/s", "assumed", "well above the modes that shape the tension (< 650 rad/s)"),
    "eyelet_mu": ("-", "assumed", "0: frictionless; capstan friction did not shorten the tail (notebook 06)"),
    "eyelet_v0": (
        "m/s",
        "numerical",
        "regularisation speed of the friction law (used only if eyelet_mu > 0)",
    ),
    "actuator": ("-", "assumed", "rotor, spool and load-cell carriage modelled (ideal: for comparison)"),
    "steps_per_rev": ("-", "paper", "800 steps/rev (quarter steps of the 1.8 deg motor)"),
    "spool_diameter": ("m", "paper", "65 mm spool"),
    "rotor_inertia": ("kg m^2", "datasheet", "17HS4401: 54 g cm^2 (typical catalogue value)"),
    "spool_inertia": ("kg m^2", "assumed", "printed PLA spool 65 x 12 mm at 60 % infill: 29.6 g, m R^2 / 2"),
    "holding_torque": (
        "N m",
        "assumed",
        "1.5 x the paper's 4.3 kg cm: 4.3 kg cm pulls out at 13.0 N, "
        "below Table II's 17.7 N peak (needs 0.58 N m); TB6600 current above the motor's rating",
    ),
    "rotor_teeth": ("-", "datasheet", "1.8 deg hybrid stepper: 50 rotor teeth (200 = 4 x 50)"),
    "torque_law": ("-", "assumed", "ideal sine/cosine microstepping: torque ~ sin of the electrical lag"),
    "rotor_zeta": ("-", "assumed", "chopper-driven steppers ring for several cycles after a step: 0.1"),
    "carriage_mass": ("kg", "assumed", "LSP-5 cell, miniature rail block and clamps"),
    "carriage_zeta": ("-", "assumed", "rail block on a linear guide: light damping"),
    "spool_side_share": ("-", "assumed", "short cable from the spool to the carriage"),
    "load_cell_side": ("-", "assumed", "the cell measures the arm-side cable (it sits between the two)"),
    "amp_bandwidth_hz": ("Hz", "assumed", "LCA-RTC bandwidth unknown to us: first order at 1 kHz"),
    "span_n": ("N", "assumed", "4-20 mA over 0-20 N: Table II's 17.7 N reads 558 counts, nothing clips"),
    "adc_noise_counts": ("counts", "assumed", "0.5 count rms: the paper's unshaped 10 mm settling (1.2 s "
                         "in a +-0.13 N band) rules out 1 count (0.04 N) rms on this chain"),
    "loop_zero_ma": ("mA", "assumed", "the paper's '0.6 mA' current-loop output read as a 4-20 mA loop (4 mA "
                     "through 150 ohm is 0.6 V); rigs/paper.toml's loop_zero_ma"),
    "loop_full_ma": ("mA", "assumed", "a standard 4-20 mA loop (rigs/paper.toml)"),
    "loop_min_ma": ("mA", "assumed", "NAMUR NE 43 lower saturation of 4-20 mA loops (rigs/paper.toml)"),
    "loop_max_ma": ("mA", "assumed", "NAMUR NE 43 upper saturation of 4-20 mA loops (rigs/paper.toml)"),
    "shunt_ohm": ("ohm", "paper", "the 150 ohm resistor that turns the loop into a voltage"),
    "adc_vref_v": ("V", "assumed", "the Arduino Mega's default reference, its 5 V supply (rigs/paper.toml)"),
    "adc_bits": ("bits", "datasheet", "the ATmega2560's 10-bit ADC"),
    "integrator": (
        "-",
        "numerical",
        "rk4: every term explicit; rosw: bending and cables implicit (docs/virtual_rig.md, section 2)",
    ),
    "max_step": (
        "s",
        "numerical",
        "rosw: 0.5 ms, where its convergence band is met; rk4: 0.25 ms, within 90 % of its stability limit "
        "(0.30 ms at rest)",
    ),
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
