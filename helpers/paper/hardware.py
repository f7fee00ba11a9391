"""The rig's hardware constants and the limits both boards enforce: the one home of these numbers.

Everything here follows from the rig file the host runs (``helpers.rigfile.selected()``: ``HELPERS_RIG``, or
``--rig FILE`` on the command line, else the paper's ``rigs/paper.toml``: 800 steps per revolution, a 65 mm
spool; ``docs/rig_file.md``), whose limits the firmware is built with (``firmware/PROTOCOL.md`` states the
paper's). The numbers in the comments below are the paper's rig's. The host
(``helpers.rig``), the emulated boards (``helpers.virtual.emulator``), the programme builder
(``helpers.board.programmes``)
and the virtual rig's actuator (``helpers.virtual``) import them from here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from helpers import rigfile
from helpers.rigfile.units import si

RIG: rigfile.RigFile = rigfile.in_use()
"""The rig file these constants come from (checked; its ``hash`` identifies it)."""
_HW = RIG.hardware
_DERIVED = rigfile.derived(RIG)

MM_PER_STEP: float = math.pi * _HW.spool_diameter_mm / _HW.steps_per_rev
"""Cable travel per motor step, mm: pi x 65 mm / 800 steps = 0.25525 mm."""

MAX_TRAVEL_MM: float = _HW.travel_mm
"""Cable travel limit from zero, mm (the host's and the firmware's)."""

MAX_SPEED_MM_S: float = _HW.speed_limit_mm_s
"""Cable speed limit, mm/s."""

MAX_STEP_RATE_HZ: float = _HW.step_rate_cap_hz
"""Step-rate cap of the driver chain, steps/s."""


@dataclass(frozen=True)
class Limits:
    """The stepper board's compiled-in limits; the host checks the same before sending anything."""

    min_interval_us: int = _DERIVED.min_interval_us
    """Fastest step: 639 us/step = 1565 steps/s = 399.4 mm/s (<= ``MAX_SPEED_MM_S``, < 2000 steps/s)."""
    max_interval_us: int = _HW.max_interval_us
    """Slowest step (one per second); slower is a dwell."""
    min_position_steps: int = 0
    """Travel lower bound (steps from zero)."""
    max_position_steps: int = int(MAX_TRAVEL_MM / MM_PER_STEP)
    """Travel upper bound: 156 steps = 39.8 mm <= ``MAX_TRAVEL_MM``."""
    max_items: int = _HW.programme_max_items
    """Programme length (a RAM table on the Uno)."""
    max_dwell_ms: int = _HW.max_dwell_ms
    """Longest single dwell."""
    max_speed_mm_s: float = MAX_SPEED_MM_S
    """Cable speed limit that sets ``min_interval_us``."""
    max_step_rate_hz: float = MAX_STEP_RATE_HZ
    """Step-rate cap of the driver chain."""


LIMITS = Limits()
"""The limits every programme must respect."""

DAQ_RATE_MIN_HZ: int = _HW.daq_rate_min_hz
DAQ_RATE_MAX_HZ: int = _HW.daq_rate_max_hz
DAQ_RATE_DEFAULT_HZ: int = _HW.daq_rate_default_hz
"""The DAQ board's sample-rate range and its rate after reset."""

ADC_MAX: int = 2**_HW.adc_bits - 1
"""Largest reading of the DAQ board's 10-bit ADC."""

# --- the load-cell signal chain: amplifier current loop -> shunt -> 10-bit ADC -----------------------------
LOOP_ZERO_A: float = si(_HW.loop_zero_ma, -3)
LOOP_FULL_A: float = si(_HW.loop_full_ma, -3)
"""The amplifier's current-loop output at zero and at full-scale load, A. The paper says the LCA-RTC's
"current-loop output signal of 0.6 mA" is turned into a voltage by a 150 ohm resistor; we read it as a
standard 4-20 mA loop (4 mA through 150 ohm is 0.6 V, the smallest reading), an assumption."""

LOOP_SATURATION_A: tuple[float, float] = (si(_HW.loop_min_ma, -3), si(_HW.loop_max_ma, -3))
"""The loop's linear range, A: the NAMUR NE 43 measuring range of 4-20 mA transmitters (3.8-20.5 mA); beyond
it the output saturates. Assumed for the LCA-RTC (its datasheet figure is not known to us)."""

SHUNT_OHM: float = _HW.shunt_ohm
"""Loop resistor, ohm (paper)."""

ADC_VREF_V: float = _HW.adc_vref_v
"""ADC reference voltage, V: the Arduino Mega's default reference (its 5 V supply); assumed."""

CLIP_MARGIN_COUNTS: int = _HW.adc_clip_margin_counts
"""A reading this close to the loop's upper saturation level (or beyond it) counts as clipped: the ADC's
noise (about 1 count rms) spreads a saturated reading by a few counts."""


def loop_counts(current_a: float) -> float:
    """ADC reading (counts, not rounded) of a loop current through the shunt: ``1024 I R / V_ref``."""
    return (ADC_MAX + 1.0) * current_a * SHUNT_OHM / ADC_VREF_V


CLIP_LOW_COUNTS: int = math.floor(loop_counts(LOOP_SATURATION_A[0]))
"""Readings at or below this are clipped: the loop's lower saturation (3.8 mA = 116.7 counts, floored)."""

CLIP_HIGH_COUNTS: int = min(ADC_MAX, round(loop_counts(LOOP_SATURATION_A[1])) - CLIP_MARGIN_COUNTS)
"""Readings at or above this are clipped: the loop's upper saturation (20.5 mA = 629.8 counts) less the
noise margin, or the ADC's own top (whichever is lower)."""

DAQ_BAUD: int = _HW.daq_baud
STEPPER_BAUD: int = _HW.stepper_baud
"""Serial line rates of the two boards (8N1)."""

MAX_PROGRAMME_S: float = _HW.max_programme_s
"""Longest programme the host runs, s (a recording is held in memory: 10 min at 2 kHz is 1.2 M rows)."""


MAX_PULSE_MM: float = LIMITS.max_position_steps * MM_PER_STEP
"""The longest pulse: the travel's 156 steps, 39.82 mm (a pulse moves round(x_f / MM_PER_STEP) steps)."""
