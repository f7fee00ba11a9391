"""The rig's hardware constants and the limits both boards enforce: the one home of these numbers.

Everything here follows from the paper's hardware (``helpers.paper.numbers``: 800 steps per revolution, a 65
mm spool)
or from the firmware's compiled-in limits (``firmware/PROTOCOL.md``, which states the same numbers). The host
(``helpers.rig``), the emulated boards (``helpers.virtual.emulator``), the programme builder
(``helpers.board.programmes``)
and the virtual rig's actuator (``helpers.virtual``) import them from here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from helpers.paper import numbers as paper

MM_PER_STEP: float = math.pi * (paper.SPOOL_DIAMETER_M * 1e3) / paper.STEPS_PER_REV
"""Cable travel per motor step, mm: pi x 65 mm / 800 steps = 0.25525 mm."""

MAX_TRAVEL_MM: float = 40.0
"""Cable travel limit from zero, mm (the host's and the firmware's)."""

MAX_SPEED_MM_S: float = 400.0
"""Cable speed limit, mm/s."""

MAX_STEP_RATE_HZ: float = 2000.0
"""Step-rate cap of the driver chain, steps/s."""


@dataclass(frozen=True)
class Limits:
    """The stepper board's compiled-in limits; the host checks the same before sending anything."""

    min_interval_us: int = 639
    """Fastest step: 639 us/step = 1565 steps/s = 399.4 mm/s (<= ``MAX_SPEED_MM_S``, < 2000 steps/s)."""
    max_interval_us: int = 1_000_000
    """Slowest step (one per second); slower is a dwell."""
    min_position_steps: int = 0
    """Travel lower bound (steps from zero)."""
    max_position_steps: int = int(MAX_TRAVEL_MM / MM_PER_STEP)
    """Travel upper bound: 156 steps = 39.8 mm <= ``MAX_TRAVEL_MM``."""
    max_items: int = 64
    """Programme length (a RAM table on the Uno)."""
    max_dwell_ms: int = 60_000
    """Longest single dwell."""
    max_speed_mm_s: float = MAX_SPEED_MM_S
    """Cable speed limit that sets ``min_interval_us``."""
    max_step_rate_hz: float = MAX_STEP_RATE_HZ
    """Step-rate cap of the driver chain."""


LIMITS = Limits()
"""The limits every programme must respect."""

DAQ_RATE_MIN_HZ: int = 100
DAQ_RATE_MAX_HZ: int = 2000
DAQ_RATE_DEFAULT_HZ: int = 1000
"""The DAQ board's sample-rate range and its rate after reset."""

ADC_MAX: int = 1023
"""Largest reading of the DAQ board's 10-bit ADC."""

# --- the load-cell signal chain: amplifier current loop -> shunt -> 10-bit ADC -----------------------------
LOOP_ZERO_A: float = 4.0e-3
LOOP_FULL_A: float = 20.0e-3
"""The amplifier's current-loop output at zero and at full-scale load, A. The paper says the LCA-RTC's
"current-loop output signal of 0.6 mA" is turned into a voltage by a 150 ohm resistor; we read it as a
standard 4-20 mA loop (4 mA through 150 ohm is 0.6 V, the smallest reading), an assumption."""

LOOP_SATURATION_A: tuple[float, float] = (3.8e-3, 20.5e-3)
"""The loop's linear range, A: the NAMUR NE 43 measuring range of 4-20 mA transmitters (3.8-20.5 mA); beyond
it the output saturates. Assumed for the LCA-RTC (its datasheet figure is not known to us)."""

SHUNT_OHM: float = paper.SHUNT_OHM
"""Loop resistor, ohm (paper)."""

ADC_VREF_V: float = 5.0
"""ADC reference voltage, V: the Arduino Mega's default reference (its 5 V supply); assumed."""

CLIP_MARGIN_COUNTS: int = 2
"""A reading this close to the loop's upper saturation level (or beyond it) counts as clipped: the ADC's
noise (about 1 count rms) spreads a saturated reading by a few counts."""


def loop_counts(current_a: float) -> float:
    """ADC reading (counts, not rounded) of a loop current through the shunt: ``1024 I R / V_ref``."""
    return 1024.0 * current_a * SHUNT_OHM / ADC_VREF_V


CLIP_LOW_COUNTS: int = math.floor(loop_counts(LOOP_SATURATION_A[0]))
"""Readings at or below this are clipped: the loop's lower saturation (3.8 mA = 116.7 counts, floored)."""

CLIP_HIGH_COUNTS: int = min(ADC_MAX, round(loop_counts(LOOP_SATURATION_A[1])) - CLIP_MARGIN_COUNTS)
"""Readings at or above this are clipped: the loop's upper saturation (20.5 mA = 629.8 counts) less the
noise margin, or the ADC's own top (whichever is lower)."""

DAQ_BAUD: int = 500_000
STEPPER_BAUD: int = 115_200
"""Serial line rates of the two boards (8N1)."""

MAX_PROGRAMME_S: float = 600.0
"""Longest programme the host runs, s (a recording is held in memory: 10 min at 2 kHz is 1.2 M rows)."""


MAX_PULSE_MM: float = LIMITS.max_position_steps * MM_PER_STEP
"""The longest pulse: the travel's 156 steps, 39.82 mm (a pulse moves round(x_f / MM_PER_STEP) steps)."""
