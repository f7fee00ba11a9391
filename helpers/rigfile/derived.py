"""What follows from a rig file, and the rigs it refuses (standard library only; ``docs/rig_file.md``).

Derived: cable per step, the limits in steps and step intervals, the ADC chain in counts and newtons, the
stepper's pull-out tension and an estimate of the static tension at full travel. Refused (one line naming the
file, the key and the reason): a speed limit that needs more steps per second than the step-rate cap, a
load-cell chain the ADC cannot read, a travel the stepper cannot hold, and inconsistent settings.

This module works on any object with the attributes of :class:`helpers.rigfile.model.RigFile` (it does not
import it: the model calls :func:`check` while loading).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from helpers.rigfile.errors import RigFileError

MIN_SPAN_COUNTS = 100
"""A load-cell chain must spread its range (zero to full load) over at least this many ADC counts."""

_EPS = 1e-9


@dataclass(frozen=True)
class Derived:
    """The values that follow from a rig file (units in the names; per axis/channel = per tendon).

    Attributes
    ----------
    mm_per_step : tuple of float
        Cable per microstep of each axis, mm (``pi d / steps_per_rev``).
    travel_steps : tuple of int
        Each axis's travel in whole steps, ``floor(travel_mm / mm_per_step)``.
    release_steps : tuple of int
        How far each axis may pay out below position 0 (the rest) in whole steps,
        ``floor(release_mm / mm_per_step)``: its positions are ``-release_steps..travel_steps``.
    max_rate_steps_s : tuple of float
        Each axis's fastest step rate, ``min(step_rate_cap_hz, speed_limit_mm_s / mm_per_step)``.
    min_interval_us : int
        Fastest step interval every axis can take, ``ceil(1e6 / max_rate)`` (the largest over the axes).
    max_interval_us : int
        Slowest step interval (``[hardware] max_interval_us``).
    adc_max : int
        Largest ADC reading, ``2^bits - 1``.
    offset_counts : float
        ADC reading at zero load (``loop_zero_ma``).
    gain_counts_per_n : tuple of float
        ADC counts per newton of each load-cell channel.
    clip_low_counts, clip_high_counts : int
        Readings at or beyond these are clipped (the loop's saturation; the high one less the margin,
        or the ADC's top).
    readable_n : tuple of float
        Each channel's largest tension read before clipping, N.
    hold_n : tuple of float
        Estimate of each tendon's static tension at full travel, N (:func:`hold_tension_n`).
    """

    mm_per_step: tuple[float, ...]
    travel_steps: tuple[int, ...]
    release_steps: tuple[int, ...]
    max_rate_steps_s: tuple[float, ...]
    min_interval_us: int
    max_interval_us: int
    adc_max: int
    offset_counts: float
    gain_counts_per_n: tuple[float, ...]
    clip_low_counts: int
    clip_high_counts: int
    readable_n: tuple[float, ...]
    hold_n: tuple[float, ...]


def loop_counts(hw: Any, current_ma: float) -> float:
    """ADC reading (counts, not rounded) of a loop current through the shunt: ``2^bits I R / V_ref``."""
    return 2**hw.adc_bits * current_ma * 1e-3 * hw.shunt_ohm / hw.adc_vref_v


def hold_tension_n(rig: Any, i: int) -> float:
    """Estimate of tendon ``i``'s static tension at full travel, N (the documented hold criterion).

    ``T = T_0 + u / (r^2 L / EI + 1 / k_cable) + W / r``: the pretension, the cable pulled by the travel
    ``u`` against the rod bent by a tip moment ``T r`` (linear Euler-Bernoulli, ``theta_tip = T r L / EI``,
    cable shortening ``r theta_tip``) in series with the cable's stretch, plus the weight's moment about the
    clamp ``W = g_perp (m_rod L / 2 + m_disc sum of the disc stations)`` carried at the offset ``r`` (the arm
    lifted against gravity's component across the backbone). Geometric stiffening and the microstep spring
    are left out (both lower the tension), so the estimate errs on the safe side for moderate bends.
    """
    a = rig.arm
    t = rig.tendons[i]
    r = t.offset_mm * 1e-3
    L = a.length_mm * 1e-3
    d = a.backbone_diameter_mm * 1e-3
    EI = a.youngs_modulus_gpa * 1e9 * math.pi * d**4 / 64.0
    u = rig.hardware.travel_mm * 1e-3
    elastic = u / (r**2 * L / EI + 1.0 / t.cable_stiffness_n_m)
    gx, gy, gz = a.gravity_direction
    g_perp = a.gravity_m_s2 * math.hypot(gx, gy) / math.sqrt(gx * gx + gy * gy + gz * gz)
    rod_mass = a.density_kg_m3 * math.pi * d**2 / 4.0 * L
    stations = L / a.discs * a.discs * (a.discs + 1) / 2.0
    weight = g_perp * (rod_mass * L / 2.0 + a.disc_mass_g * 1e-3 * stations)
    return t.pretension_n + elastic + weight / r


def derived(rig: Any) -> Derived:
    """The derived values of a rig (not checked: :func:`check` refuses what is unsafe)."""
    hw = rig.hardware
    mm = tuple(t.mm_per_step for t in rig.tendons)
    travel = tuple(int(math.floor(hw.travel_mm / m + _EPS)) for m in mm)
    release = tuple(int(math.floor(hw.release_mm / m + _EPS)) for m in mm)
    rates = tuple(min(hw.step_rate_cap_hz, hw.speed_limit_mm_s / m) for m in mm)
    min_interval = max(int(math.ceil(1e6 / rate - _EPS)) for rate in rates)
    adc_max = 2**hw.adc_bits - 1
    offset = loop_counts(hw, hw.loop_zero_ma)
    span = loop_counts(hw, hw.loop_full_ma) - offset
    gains = tuple(span / t.load_cell_range_n for t in rig.tendons)
    clip_low = int(math.floor(loop_counts(hw, hw.loop_min_ma)))
    clip_high = min(adc_max, round(loop_counts(hw, hw.loop_max_ma)) - hw.adc_clip_margin_counts)
    readable = tuple((clip_high - offset) / g for g in gains)
    return Derived(
        mm_per_step=mm, travel_steps=travel, release_steps=release, max_rate_steps_s=rates,
        min_interval_us=min_interval, max_interval_us=hw.max_interval_us, adc_max=adc_max,
        offset_counts=offset, gain_counts_per_n=gains,
        clip_low_counts=clip_low, clip_high_counts=clip_high, readable_n=readable,
        hold_n=tuple(hold_tension_n(rig, i) for i in range(len(rig.tendons))),
    )  # fmt: skip


def check(rig: Any) -> Derived:
    """Refuse an unsafe or impossible rig (one :class:`RigFileError` line); return its derived values."""
    src, hw = rig.source, rig.hardware

    def refuse(where: str, why: str) -> RigFileError:
        return RigFileError(f"{src}: {where}: {why}")

    many = len(rig.tendons) > 1

    def axis(i: int, key: str) -> str:
        return f"[[tendon]] #{i + 1} {key}" if many or rig.explicit_tendons else f"[hardware] {key}"

    if not hw.loop_min_ma < hw.loop_zero_ma < hw.loop_full_ma < hw.loop_max_ma:
        raise refuse("[hardware] loop_*_ma", "need loop_min_ma < loop_zero_ma < loop_full_ma < loop_max_ma")
    if not hw.daq_rate_min_hz <= hw.daq_rate_default_hz <= hw.daq_rate_max_hz:
        raise refuse(
            "[hardware] daq_rate_default_hz", "need daq_rate_min_hz <= daq_rate_default_hz <= daq_rate_max_hz"
        )
    angles = [t.angle_deg % 360.0 for t in rig.tendons]
    for i in range(len(angles)):
        for j in range(i):
            if abs((angles[i] - angles[j] + 180.0) % 360.0 - 180.0) < 1.0:
                raise refuse(f"[[tendon]] #{i + 1} angle_deg", f"the same angle as tendon {j + 1}")
    d = derived(rig)
    for i, t in enumerate(rig.tendons):
        need = hw.speed_limit_mm_s / t.mm_per_step
        if need > hw.step_rate_cap_hz * (1.0 + _EPS):
            raise refuse(
                "[hardware] speed_limit_mm_s",
                f"{hw.speed_limit_mm_s:g} mm/s needs {need:.0f} steps/s at {t.mm_per_step:.5f} mm/step"
                f"{f' (tendon {i + 1})' if many else ''}, above step_rate_cap_hz = {hw.step_rate_cap_hz:g}:"
                f" at most {hw.step_rate_cap_hz * t.mm_per_step:.1f} mm/s",
            )
        if d.travel_steps[i] < 1:
            raise refuse("[hardware] travel_mm", f"{hw.travel_mm:g} mm is less than one step")
        if hw.release_mm > 0.0 and not many:
            raise refuse(
                "[hardware] release_mm",
                f"{hw.release_mm:g} mm on a rig of one tendon: its position 0 is the end of its travel (the "
                "paper's programmes and streams count from there); a release below it is for rigs of several "
                "tendons, whose rest holds every tendon taut",
            )
        if hw.release_mm > 0.0 and d.release_steps[i] < 1:
            raise refuse(
                "[hardware] release_mm",
                f"{hw.release_mm:g} mm is less than one step ({t.mm_per_step:.5f} mm): 0 means no paying out",
            )
        if t.pretension_n >= t.pull_out_n:
            raise refuse(
                axis(i, "pretension_n") if rig.explicit_tendons else "[arm] pretension_n",
                f"{t.pretension_n:g} N is beyond the stepper's pull-out tension {t.pull_out_n:.2f} N",
            )
        if d.hold_n[i] > t.pull_out_n:
            raise refuse(
                "[hardware] travel_mm",
                f"the stepper cannot hold {hw.travel_mm:g} mm of travel"
                f"{f' (tendon {i + 1})' if many else ''}:"
                f" the static tension there is about {d.hold_n[i]:.1f} N (docs/rig_file.md, the hold "
                f"criterion), above its pull-out tension {t.pull_out_n:.1f} N "
                "(holding_torque_n_m / spool radius)",
            )
    full_v = hw.loop_full_ma * 1e-3 * hw.shunt_ohm
    if loop_counts(hw, hw.loop_full_ma) > d.adc_max - hw.adc_clip_margin_counts:
        raise refuse(
            "[hardware] shunt_ohm",
            f"the ADC cannot read the load cell's range: {hw.loop_full_ma:g} mA through {hw.shunt_ohm:g} "
            f"ohm is "
            f"{full_v:.2f} V, at or above the ADC's {hw.adc_vref_v:g} V reference",
        )
    span = loop_counts(hw, hw.loop_full_ma) - d.offset_counts
    if span < MIN_SPAN_COUNTS:
        raise refuse(
            "[hardware] shunt_ohm",
            f"the ADC cannot resolve the load cell's range: zero to full load spans {span:.0f} counts "
            f"(at least {MIN_SPAN_COUNTS})",
        )
    if not d.clip_low_counts < d.offset_counts < d.clip_high_counts:
        raise refuse("[hardware] loop_min_ma", "the zero-load reading lies outside the unclipped counts")
    for i, t in enumerate(rig.tendons):
        if t.pretension_n >= d.readable_n[i]:
            raise refuse(
                axis(i, "load_cell_range_n"),
                f"the ADC cannot read the pretension {t.pretension_n:g} N: the chain clips at "
                f"{d.readable_n[i]:.2f} N",
            )
        if d.hold_n[i] > d.readable_n[i]:
            raise refuse(
                axis(i, "load_cell_range_n"),
                f"the ADC cannot read the tension at full travel (about {d.hold_n[i]:.1f} N, the hold "
                f"criterion): the chain clips at {d.readable_n[i]:.2f} N",
            )
    if d.min_interval_us > hw.max_interval_us:
        raise refuse("[hardware] max_interval_us", f"below the fastest step interval {d.min_interval_us} us")
    return d


def lead_tendon(tendons: Any, direction_deg: float) -> int:
    """The tendon (0-based) that pulls most towards a bend in ``direction_deg`` (deg around the backbone).

    The largest ``(r_i / r_mean) cos(beta - a_i)``, the direction map's pull; of pulls within 1e-9 of the
    largest, the lowest index. The planner, the shapers' modes, the twin's map and the analysis of a move all
    take their lead from here. ``tendons``: a rig file's or the spatial twin's (``angle_deg``, ``offset_mm``).
    """
    mean = sum(float(t.offset_mm) for t in tendons) / len(tendons)
    pull = [t.offset_mm / mean * math.cos(math.radians(float(direction_deg) - t.angle_deg)) for t in tendons]
    top = max(pull)
    return next(i for i, p in enumerate(pull) if p >= top - 1e-9 * max(abs(top), 1.0))
