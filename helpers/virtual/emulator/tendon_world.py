"""A virtual rig with several tendons: the spatial twin driven by the emulated boards' step streams.

:class:`TendonWorld` is a :class:`~helpers.virtual.emulator.world.VirtualWorld` whose boards are the
firmware's builds for several tendons (:mod:`helpers.virtual.emulator.tendon_boards`) and whose plant is the
spatial twin (:class:`helpers.virtual.spatial.plant.SpatialPlant`): each interval of device time takes every
axis's steps at their firmware ticks, integrates the twin with them (tendon ``a`` is axis ``a``), samples each
tendon's amplifier output through its own load cell (channel ``c`` is tendon ``c``, its
``load_cell_range_n``, read ``c`` conversions of 104 us after channel 0, as the firmware converts them one
after the other) and each axis's step count at channel 0's instant (``t_us``). A sample is sent once its last
channel is read; one still converting when ``STOP`` arrives is not taken (the firmware finishes and sends it:
a difference within the last 312 us of a stream).

:func:`build_world` builds the world the selected rig file describes: this one for a rig with several
tendons, the planar virtual rig (:func:`~helpers.virtual.emulator.world.default_world`) for one.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from helpers import __version__, rigfile
from helpers.board.protocol import WRAP_US
from helpers.rigfile import RigFile
from helpers.virtual.emulator.tendon_boards import (
    BuildLimits,
    TendonDaqEmulator,
    TendonStepperEmulator,
    build_limits,
)
from helpers.virtual.emulator.world import VirtualWorld, default_world
from helpers.virtual.sensor import LoadCell
from helpers.virtual.spatial.from_rig import spatial_rig
from helpers.virtual.spatial.plant import SpatialPlant

__all__ = ["TendonWorld", "tendon_world", "build_world", "ADC_CONVERSION_S"]

ADC_CONVERSION_S = 104e-6
"""One conversion of the Mega's ADC at clk/128 (13 ADC clocks of 8 us): channel c of a sample is read c of
them after channel 0 (``firmware/PROTOCOL.md``, *several tendons*)."""


@dataclass
class TendonWorld(VirtualWorld):
    """The spatial twin, one load cell per tendon and the boards built for several tendons.

    ``plant`` is a :class:`~helpers.virtual.spatial.plant.SpatialPlant` (or a double with its ``advance``),
    ``sensor`` a list of one sensor per channel; ``limits`` the boards' build.
    """

    limits: BuildLimits | None = None
    tendon_tip: list[np.ndarray] = field(default_factory=list)
    """The tip positions (m, clamp frame) at the samples, in chunks (for checks against the twin)."""
    tendon_tip_t_us: list[np.ndarray] = field(default_factory=list)
    """The ``t_us`` of the samples of each chunk of :attr:`tendon_tip` (as the data lines carry it)."""
    _converting: dict = field(default_factory=dict, repr=False)
    """(stream start, slot, channel) -> (amplifier output, tip): the channels read of samples not yet sent."""

    def __post_init__(self) -> None:
        if self.limits is None:
            raise ValueError("a TendonWorld needs the boards' build limits")
        self.t = float(getattr(self.plant, "t", 0.0))
        self.load_n: float | None = None
        self.go_times: list[float] = []
        self.daq = TendonDaqEmulator(self, self.limits, self.daq_faults)
        self.stepper = TendonStepperEmulator(self, self.limits, self.stepper_faults)
        self.daq.reset()
        self.stepper.reset()
        self.listeners = []

    def tip_um(self, t_us: np.ndarray) -> np.ndarray | None:
        """The tip's position (integer micrometres, clamp frame) at the samples sent with these ``t_us``.

        At channel 0's instant of each sample; None if the twin gave no tip for one of them.
        """
        if not self.tendon_tip:
            return None
        known = np.concatenate(self.tendon_tip_t_us)
        tips = np.concatenate(self.tendon_tip)
        want = np.asarray(t_us, dtype=np.int64)
        order = np.argsort(known, kind="stable")
        i = np.clip(np.searchsorted(known[order], want), 0, len(known) - 1)
        if not np.array_equal(known[order][i], want):
            return None
        return np.rint(tips[order][i] * 1e6).astype(np.int64)

    def reseed(self, seed: int) -> None:
        """Restart every load cell's noise (channel 0 from ``seed``, channel c from ``(seed, c)``)."""
        for c, cell in enumerate(self.sensor):
            cell.reseed(seed if c == 0 else [seed, c])

    def _advance_plain(self, t1: float) -> None:
        daq, stepper = self.daq, self.stepper
        channels = len(self.sensor)
        step_t, step_a, step_s = stepper.axis_steps_until(t1)
        # channel c is converted c conversions after channel 0 (t_us): a sample is complete, and sent, once
        # its last channel is read. The interval (self.t, t1] reads every channel due in it, of the samples it
        # completes and of the one it leaves converting (kept in _converting until its last channel is read):
        # the twin is never asked for a past instant, wherever the interval ends (the pseudo-terminal
        # server's intervals end at wall-clock instants, the in-process rig's on whole samples).
        lag = np.arange(channels) * ADC_CONVERSION_S
        started = daq.sample_slots(self.t, t1)
        done = daq.sample_slots(self.t, t1 - lag[-1])
        times = daq._t_start + started / daq.rate
        key = daq._t_start
        converting = {k: v for k, v in self._converting.items() if k[0] == key}
        due = [(i, c) for i in range(len(started)) for c in range(channels)
               if (key, int(started[i]), c) not in converting]  # fmt: skip
        reads = np.array([times[i] + lag[c] for i, c in due], dtype=float)
        keep = (reads > self.t - 1e-12) & (reads <= t1 + 1e-12)  # a channel read later waits for its interval
        due = [d for d, k in zip(due, keep, strict=True) if k]
        reads = reads[keep]
        plant_times = reads if len(reads) and reads[-1] >= t1 - 1e-12 else np.append(reads, t1)
        out = self.plant.advance(plant_times, step_t, step_a, step_s)
        every = np.asarray(out["output"], dtype=float)
        tip = np.asarray(out["tip"]) if "tip" in out else None
        for j, (i, c) in enumerate(due):
            converting[(key, int(started[i]), c)] = (every[j, c], None if tip is None or c else tip[j])
        n_done = len(done)
        if n_done:
            slots = started[:n_done]
            got = [[converting.pop((key, int(k), c)) for c in range(channels)] for k in slots]
            output = np.array([[v for v, _ in row] for row in got], dtype=float)
            if tip is not None:
                self.tendon_tip.append(np.array([row[0][1] for row in got], dtype=float))
                t_us = (np.rint(times[:n_done] * 1e6).astype(np.int64) + self.t0_us) % WRAP_US
                self.tendon_tip_t_us.append(t_us)
            if self.load_n is not None:
                output = np.full_like(output, self.load_n)
            counts = np.column_stack(
                [np.asarray(cell.counts(output[:, c]), dtype=np.int64) for c, cell in enumerate(self.sensor)]
            )
            steps = daq.steps_at(times[:n_done], step_t, step_a, step_s)
            daq.emit_samples(slots, times[:n_done], counts, steps)
        self._converting = converting
        daq.count(step_a, step_s)
        self.t = t1
        stepper.finish_if_due(t1)
        for fn in self.listeners:
            fn(self)


def tendon_world(rig: RigFile, name: str = "default", options: dict[str, str] | None = None) -> TendonWorld:
    """The virtual rig of a rig file with several tendons (``options`` as :func:`default_world`'s)."""
    options = options or {}
    seed = int(options.get("seed", 0))
    twin = spatial_rig(rig)
    plant = SpatialPlant(twin)  # at RK4's stable step for this rig (four tendons: 1/6 ms, not 0.25 ms)
    cells = [
        LoadCell(twin.arm, seed=seed if c == 0 else [seed, c], span_n=t.load_cell_range_n)
        for c, t in enumerate(twin.tendons)
    ]
    info = {"version": __version__, "parameters": twin.metadata(), "seed": seed, "tendons": rig.n_tendons}
    world = TendonWorld(plant, cells, name=name, seed=seed, t0_us=int(options.get("t0_us", 0)), info=info,
                        limits=build_limits(rig))  # fmt: skip
    if "load_n" in options:
        world.hang_load(float(options["load_n"]))
    return world


def build_world(name: str = "default", options: dict[str, str] | None = None) -> VirtualWorld:
    """The selected rig file's virtual rig: :func:`tendon_world` for several tendons, else the planar one."""
    chosen = rigfile.selected()
    if chosen.n_tendons > 1:
        return tendon_world(chosen, name, options)
    return default_world(name, options)
