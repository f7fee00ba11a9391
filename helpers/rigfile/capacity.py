"""What the boards can hold: the one source of the rules that refuse a rig the firmware cannot serve.

A rig file can be valid (``helpers.rigfile.model``) and still ask for more than the two boards have: a
programme table the Uno's 2 KB of RAM cannot hold beside the stream's state and the stack, more channels than
the DAQ can convert in one sample period, data lines its serial link cannot carry at the sample rate, limits
wider than the firmware's fixed-size fields. :func:`firmware_problem` names the first such problem (one line:
table, key, numbers, what would fit); ``rig check``, the header generator and ``make`` refuse with it.

**One source for the stepper's RAM rule.** The rule (:func:`stepper_ram`) and its numbers live here only. The
header generator writes what it computed into the firmware's rig header (``RIG_STEPPER_TABLES_BYTES``: the
programme table, the stream's state and the shaper of this rig; ``RIG_STEPPER_TABLES_MAX_BYTES``: what the
Uno's RAM leaves them), and the stepper sketch asserts at compile time that its tables are exactly the size
this model says and fit within that limit. So the host's check and the firmware's static assertion are one
computation, and a change to the sketch's tables that the model does not follow stops the build with a line
naming this module. The sizes below are avr-gcc's (1-byte alignment): ``firmware/stepper_uno/stepper_uno.ino``
(``Item``, ``StreamMem``), ``firmware/common/stream_plan.h`` (``Planner``, ``SpAxis``, ``SpShaper``); the rest
of the sketch's static data was measured with avr-size (gcc-avr 5.4.0, arduino-core-avr 1.8.7), and the
firmware tests check, for every build they make, that the build's data + bss is this model's total.

Standard library only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from helpers.rigfile.derived import derived
from helpers.rigfile.errors import RigFileError

__all__ = [
    "StepperRam", "DaqLink", "stepper_ram", "daq_link", "daq_line_bytes", "daq_max_rate_for_channels",
    "firmware_problem", "require_fit", "UNO_RAM_BYTES", "STEPPER_STACK_BYTES", "STEPPER_OTHER_STATIC_BYTES",
    "DAQ_LINK_SHARE", "MAX_TRAVEL_STEPS", "MAX_PROGRAMME_ITEMS",
]  # fmt: skip

UNO_RAM_BYTES = 2048
"""The stepper board's SRAM (ATmega328P: ``RAMEND + 1 - RAMSTART``)."""

STEPPER_STACK_BYTES = 320
"""Stack the stepper sketch keeps free beyond its static data. The deepest stack measured in simavr
(``MEM``): 239 bytes on the four-tendon build's random streams (508 free, 269 never touched), about 150 on the
one-axis build; 320 leaves a third more than the deepest."""

STEPPER_OTHER_STATIC_BYTES = {1: 460, 2: 539, 3: 557, 4: 575}
"""The stepper sketch's static data (data + bss) beside the tables this module sizes, per number of axes
(serial and line buffers, run state, per-axis positions), measured with avr-size: the build's data + bss less
:attr:`StepperRam.tables_bytes` (paper 1338 - 878; 2, 3, 4 axes 1128 - 589, 1301 - 744, 1540 - 965; the
same with 100 items, with 64-step queues and without a release table)."""

SHAPER_BYTES = 77
"""``SpShaper``: 1 + 8 x 2 + 8 x 2 + 8 + 8 x 2 + 1 + 1 + 9 x 2 bytes (the loaded shaper, kept apart)."""

QUEUE_32_MIN_INTERVAL_US = 626
"""The stepper's step queues hold 32 steps when a 10 ms period holds at most 16 (``10000 // interval + 1 <=
16``: a fastest step of at least 626 us), else 64."""

MAX_TRAVEL_STEPS = 255
"""Each axis's travel, and its release and travel together, are 8-bit counts on the boards."""

MAX_PROGRAMME_ITEMS = 255
"""The stepper's programme table is indexed by 8 bits."""

MIN_INTERVAL_US = 500
"""The stepper board's shortest step interval."""

MAX_INTERVAL_US = 1_000_000
"""The stepper board's longest step interval (one step per second)."""

MAX_DWELL_MS = 60_000
"""The stepper's longest ``WAIT`` (``DWELL_MAX_MS`` of the sketch)."""

ADC_BITS = 10
"""The DAQ board's ADC (ATmega2560) converts 10 bits."""

DAQ_RATE_RANGE_HZ = (31, 4000)
"""The DAQ's sample rates: Timer1 at /8 is 16-bit (31 Hz), and 4 kHz is the fastest the sketch allows."""

DAQ_CONVERSION_US = 104
"""One ADC conversion: 13 ADC clocks at 125 kHz (16 MHz / 128)."""

DAQ_SAMPLE_LEAD_US = 16
"""The sampling interrupt's busy-wait before channel 0's conversion starts."""

MAX_BAUD = 2_000_000
"""The fastest line rate the boards' 16 MHz UART makes (F_CPU / 8, double speed)."""

DAQ_LINK_SHARE = 0.9
"""The longest data line at the default sample rate may use at most this share of the DAQ's line rate: the
margin (10 %) is for the replies and ``W,OVERRUN`` lines that share the line and the UART's interrupt time
between bytes."""

T_US_DIGITS = 10
"""``t_us`` is the DAQ's 32-bit ``micros()``: up to 4294967295."""


@dataclass(frozen=True)
class StepperRam:
    """The stepper board's RAM for a rig: what the rig's tables take and what the Uno leaves them (bytes).

    Attributes
    ----------
    axes, items : int
        The rig's axes and ``programme_max_items``.
    item_bytes : int
        One programme item: window (4), one step count per axis, direction bits (1), kind (1).
    stream_bytes : int
        The stream's state: the planner (period, per-axis position and set-point history), the step queues
        and the set-point FIFO.
    tables_bytes : int
        Programme table, stream state and shaper (several axes: the programme and the stream share RAM).
    tables_max_bytes : int
        What the Uno's RAM leaves them: ``UNO_RAM_BYTES - other static data - STEPPER_STACK_BYTES``.
    max_items : int
        The longest programme that fits (at most 255).
    static_bytes : int
        The sketch's static data (data + bss) predicted: tables and the rest.
    """

    axes: int
    items: int
    item_bytes: int
    stream_bytes: int
    tables_bytes: int
    tables_max_bytes: int
    max_items: int
    static_bytes: int

    @property
    def fits(self) -> bool:
        """The tables fit the RAM the Uno leaves them."""
        return self.tables_bytes <= self.tables_max_bytes


def stepper_ram(axes: int, min_interval_us: int, items: int) -> StepperRam:
    """The stepper sketch's RAM for ``axes`` axes, the rig's fastest step interval and ``items`` items.

    The sketch's step queue holds two control periods: 32 steps when a 10 ms period holds at most 16
    (:data:`QUEUE_32_MIN_INTERVAL_US`), else 64. The set-point history is 128 periods on one axis, 64
    per axis on several.
    """
    queue = 32 if min_interval_us >= QUEUE_32_MIN_INTERVAL_US else 64
    history = 128 if axes == 1 else 64
    planner = 4 + axes * (2 + 4 + 3) + axes * 2 * history
    stream = planner + axes * queue * 2 + axes * (queue // 8) + 8 * axes * 2
    item = 4 + axes + 1 + 1
    other = STEPPER_OTHER_STATIC_BYTES[axes]
    room = UNO_RAM_BYTES - other - STEPPER_STACK_BYTES
    if axes > 1:  # the programme and the stream's state share one union
        tables = max(item * items, stream) + SHAPER_BYTES
        fit = (room - SHAPER_BYTES) // item if stream + SHAPER_BYTES <= room else 0
    else:
        tables = item * items + stream + SHAPER_BYTES
        fit = max(0, (room - stream - SHAPER_BYTES) // item)
    return StepperRam(
        axes=axes, items=items, item_bytes=item, stream_bytes=stream, tables_bytes=tables,
        tables_max_bytes=room, max_items=min(MAX_PROGRAMME_ITEMS, fit), static_bytes=tables + other,
    )  # fmt: skip


def daq_line_bytes(rig: Any, travel_steps: tuple[int, ...], release_steps: tuple[int, ...]) -> int:
    """The longest DAQ data line of ``rig``, bytes on the wire with its checksum and newline (PROTOCOL.md).

    ``D,<seq>,<t_us>,<adc_0>,...,<steps_0>,...*hh`` and a newline: ``seq`` as long as the longest
    recording's last sample at the highest rate (``max_programme_s x daq_rate_max_hz``), ``t_us`` 10 digits,
    each ADC count as many digits as the ADC's top, each step count a sign and the digits of the axis's
    release and travel together.
    """
    hw = rig.hardware
    seq = len(str(math.ceil(hw.max_programme_s * hw.daq_rate_max_hz)))
    adc = len(str(2**hw.adc_bits - 1))
    steps = sum(1 + 1 + len(str(t + r)) for t, r in zip(travel_steps, release_steps, strict=True))
    return 2 + seq + 1 + T_US_DIGITS + len(rig.tendons) * (1 + adc) + steps + 4


@dataclass(frozen=True)
class DaqLink:
    """The DAQ's serial link at the rig's default sample rate, the longest data line assumed.

    Attributes
    ----------
    line_bytes : int
        The longest data line (:func:`daq_line_bytes`).
    rate_hz : int
        ``daq_rate_default_hz``.
    bits_per_s : int
        ``line_bytes x 10 x rate_hz`` (8N1: 10 bits per byte).
    baud : int
        ``daq_baud``.
    share : float
        ``bits_per_s / baud``.
    min_baud : int
        The least line rate that carries it within :data:`DAQ_LINK_SHARE`.
    max_rate_hz : int
        The highest sample rate whose longest lines fit :data:`DAQ_LINK_SHARE` of ``daq_baud``.
    """

    line_bytes: int
    rate_hz: int
    bits_per_s: int
    baud: int
    share: float
    min_baud: int
    max_rate_hz: int

    @property
    def fits(self) -> bool:
        """The longest lines at the default rate use at most :data:`DAQ_LINK_SHARE` of the line."""
        return self.share <= DAQ_LINK_SHARE


def daq_link(rig: Any, travel_steps: tuple[int, ...], release_steps: tuple[int, ...]) -> DaqLink:
    """The DAQ's link budget of ``rig`` (:class:`DaqLink`)."""
    hw = rig.hardware
    line = daq_line_bytes(rig, travel_steps, release_steps)
    bits = line * 10 * hw.daq_rate_default_hz
    return DaqLink(
        line_bytes=line, rate_hz=hw.daq_rate_default_hz, bits_per_s=bits, baud=hw.daq_baud,
        share=bits / hw.daq_baud, min_baud=math.ceil(bits / DAQ_LINK_SHARE),
        max_rate_hz=int(DAQ_LINK_SHARE * hw.daq_baud // (line * 10)),
    )  # fmt: skip


def daq_max_rate_for_channels(channels: int) -> int:
    """The highest DAQ rate at which ``channels`` conversions fit one sample period.

    The DAQ sketch's static assertion: ``channels x 104 + 16 < 1000000 / rate`` (integer division), which
    holds exactly for ``rate <= 1000000 // (channels x 104 + 16 + 1)``.
    """
    return 1_000_000 // (channels * DAQ_CONVERSION_US + DAQ_SAMPLE_LEAD_US + 1)


def firmware_problem(rig: Any) -> str | None:
    """Why the boards' firmware cannot be built or run for ``rig``, as ``[table] key: problem``, or None.

    In order: each axis's travel (and release with it) within 255 steps (8-bit counts), the programme table
    within 255 items and within the Uno's RAM (:func:`stepper_ram`), the step intervals within 500 us to 1 s,
    dwells within 60 s, the ADC's 10 bits, the DAQ's rates within 31-4000 Hz and its conversions within one
    sample period, line rates within 2 Mbaud, and the DAQ's longest lines at its default rate within 90 % of
    its line rate (:func:`daq_link`).
    """
    d = derived(rig)
    hw = rig.hardware
    axes = len(rig.tendons)
    worst = max(d.travel_steps)
    if worst > MAX_TRAVEL_STEPS:
        axis = d.travel_steps.index(worst) + 1
        return (
            f"[hardware] travel_mm: {worst} steps on axis {axis}: the boards hold at most {MAX_TRAVEL_STEPS} "
            f"steps of travel per axis (at most {MAX_TRAVEL_STEPS * d.mm_per_step[axis - 1]:.2f} mm)"
        )
    span = [t + r for t, r in zip(d.travel_steps, d.release_steps, strict=True)]
    if max(span) > MAX_TRAVEL_STEPS:
        axis = span.index(max(span)) + 1
        room = MAX_TRAVEL_STEPS - d.travel_steps[axis - 1]
        return (
            f"[hardware] release_mm: {d.release_steps[axis - 1]} steps below position 0 and "
            f"{d.travel_steps[axis - 1]} of travel on axis {axis}: the boards hold at most "
            f"{MAX_TRAVEL_STEPS} steps of both together per axis (a release of at most "
            f"{room * d.mm_per_step[axis - 1]:.2f} mm)"
        )
    if d.min_interval_us < MIN_INTERVAL_US:
        return (
            f"[hardware] speed_limit_mm_s: the fastest step interval {d.min_interval_us} us is below the "
            f"firmware's {MIN_INTERVAL_US} us"
        )
    ram = stepper_ram(axes, d.min_interval_us, hw.programme_max_items)
    if ram.max_items == 0:  # four axes with 64-step queues: the stream's state alone leaves no room
        speed = math.floor(max(d.mm_per_step) * 1e6 / QUEUE_32_MIN_INTERVAL_US * 10) / 10
        return (
            f"[hardware] speed_limit_mm_s: with {axes} axes and a fastest step of {d.min_interval_us} us the "
            f"stream's state ({ram.stream_bytes} B: queues of 64 steps, since a 10 ms period holds more than "
            f"16 steps) and the shaper ({SHAPER_BYTES} B) leave no room for a programme in the "
            f"{ram.tables_max_bytes} B the Uno's RAM leaves these tables: a fastest step of at least "
            f"{QUEUE_32_MIN_INTERVAL_US} us (at most {speed:g} mm/s) halves the queues"
        )
    if hw.programme_max_items > MAX_PROGRAMME_ITEMS or not ram.fits:
        plural = "axis" if axes == 1 else "axes"
        return (
            f"[hardware] programme_max_items: {hw.programme_max_items} items do not fit the stepper board "
            f"(Arduino Uno, {UNO_RAM_BYTES} B of RAM) with {axes} {plural}: at most {ram.max_items} "
            f"({ram.item_bytes} B per item; the stream's state {ram.stream_bytes} B"
            f"{', sharing the programme' if axes > 1 else ''}, the shaper {SHAPER_BYTES} B, the rest of the "
            f"sketch {STEPPER_OTHER_STATIC_BYTES[axes]} B and {STEPPER_STACK_BYTES} B of stack; the table's "
            f"index is 8 bits)"
        )
    if d.max_interval_us > MAX_INTERVAL_US:
        return f"[hardware] max_interval_us: at most {MAX_INTERVAL_US} us on the boards"
    if hw.max_dwell_ms > MAX_DWELL_MS:
        return (
            f"[hardware] max_dwell_ms: {hw.max_dwell_ms} ms: the stepper board's WAIT takes at most "
            f"{MAX_DWELL_MS} ms"
        )
    if hw.adc_bits != ADC_BITS:
        return f"[hardware] adc_bits: {hw.adc_bits}: the DAQ board's ADC (ATmega2560) has {ADC_BITS} bits"
    lo, hi = DAQ_RATE_RANGE_HZ
    if hw.daq_rate_min_hz < lo or hw.daq_rate_max_hz > hi:
        return f"[hardware] daq_rate_*_hz: the DAQ board samples at {lo}-{hi} Hz"
    fastest = daq_max_rate_for_channels(axes)
    if hw.daq_rate_max_hz > fastest:
        return (
            f"[hardware] daq_rate_max_hz: {hw.daq_rate_max_hz} Hz: the DAQ board converts its {axes} "
            f"channel{'s' if axes > 1 else ''} one after the other ({axes} x {DAQ_CONVERSION_US} us + "
            f"{DAQ_SAMPLE_LEAD_US} us per sample): at most {fastest} Hz"
        )
    for key in ("daq_baud", "stepper_baud"):
        if getattr(hw, key) > MAX_BAUD:
            return (
                f"[hardware] {key}: {getattr(hw, key)} baud: the boards' 16 MHz UART runs at most {MAX_BAUD} "
                "baud"
            )
    link = daq_link(rig, d.travel_steps, d.release_steps)
    if not link.fits:
        plural = "s" if axes > 1 else ""
        return (
            f"[hardware] daq_baud: {hw.daq_baud} baud cannot carry the DAQ's data lines: {axes} load "
            f"cell{plural} and {axes} step count{plural} make lines of up to {link.line_bytes} bytes, "
            f"{link.bits_per_s} bit/s at daq_rate_default_hz = {link.rate_hz} Hz (10 bits per byte), "
            f"{100 * link.share:.0f} % of the line (at most {100 * DAQ_LINK_SHARE:.0f} %): at least "
            f"{link.min_baud} baud (500000, 1000000 and 2000000 are "
            "exact at 16 MHz)"
        )
    return None


def require_fit(rig: Any) -> None:
    """Raise :class:`RigFileError` (``FILE: [table] key: problem``) if the boards cannot serve ``rig``."""
    problem = firmware_problem(rig)
    if problem is not None:
        raise RigFileError(f"{rig.source}: {problem}")
