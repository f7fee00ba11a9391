"""One virtual rig per rig file: the twin, its load cells and both boards on one device clock; the registry.

:class:`VirtualWorld` owns the device clock ``t`` (seconds, shared by both boards). Nothing happens between
calls; time moves only when :meth:`VirtualWorld.advance_to` is called, which integrates the plant over the
interval with every axis's steps at their firmware ticks, samples each channel's load cell and each axis's
step count, and queues every line the boards send. A reader (the pyserial URL handler or the pseudo-terminal
server) decides how far to advance: in-process, as far as the reader needs (so the virtual rig runs faster
than real time); on a pseudo-terminal, paced to the wall clock.

The boards drive a plant given to them (dependency injection: a twin, or a test double with the same
``advance``) and read what it returns (the amplifier outputs; their low-pass filters are part of the plant's
state, so chunked ``advance`` calls give the same samples as one call) through one sensor model per channel
(``LoadCell.counts``: current loop, shunt and ADC). Channel ``c`` is read ``c`` conversions of 104 us after
channel 0 (``t_us``), as the firmware converts them one after the other, and every axis's count at channel 0's
instant; a sample is sent once its last channel is read, and one still converting when ``STOP`` arrives is not
taken (the firmware finishes and sends it: a difference within the last 312 us of a stream).

:func:`build_world` builds the world of a rig file: the planar twin (:class:`helpers.virtual.ArmPlant`; the
paper's rig: the tuned ``RigParameters()``, another one-tendon rig: :func:`helpers.virtual.from_rig.
rig_parameters`) for one tendon whose plane holds gravity (:func:`helpers.virtual.from_rig.planar_holds`);
the spatial twin (:class:`helpers.virtual.spatial.plant.SpatialPlant`, one load cell per tendon, the tip at
every sample) for several, and for one tendon out of gravity's plane. Worlds are kept by ``(name, rig
hash)`` (:func:`get_world`), so two rigs in one process are two worlds, whatever their names.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from helpers import __version__, rigfile
from helpers.base.signals import signals_held
from helpers.board.protocol import WRAP_US
from helpers.rigfile import RigFile
from helpers.virtual import ArmPlant, LoadCell, RigParameters
from helpers.virtual.emulator.boards import (
    BuildLimits,
    DaqEmulator,
    EmulatedBoard,
    Faults,
    StepperEmulator,
    build_limits,
)
from helpers.virtual.from_rig import planar_holds, rig_parameters
from helpers.virtual.spatial.from_rig import spatial_rig
from helpers.virtual.spatial.plant import SpatialPlant

__all__ = ["VirtualWorld", "build_world", "register_world", "forget_world", "find_world", "get_world",
           "parameters_dict", "ADC_CONVERSION_S"]  # fmt: skip

ADC_CONVERSION_S = 104e-6
"""One conversion of the Mega's ADC at clk/128 (13 ADC clocks of 8 us): channel c of a sample is read c of
them after channel 0 (``firmware/PROTOCOL.md``, *several tendons*)."""


@dataclass
class VirtualWorld:
    """One virtual rig: the plant, one sensor per channel, both boards and their shared device clock.

    Parameters
    ----------
    plant : Plant
        Integrates the arm. With one ``sensor`` (one channel, one axis: the planar twin or its doubles),
        ``advance(sample_times, step_times, step_signs)`` returns the load cell's amplifier output (N) at the
        sample times; with a list of sensors (one per channel), ``advance(sample_times, step_times,
        step_axes, step_signs)`` returns a mapping with ``"output"`` (samples x channels, N) and optionally
        ``"tip"`` (samples x 3, m).
    sensor : Sensor or list of Sensor
        ``counts(output)`` gives ADC counts (loop saturation, noise and quantisation included).
    name : str
        The world's name (``virtual://daq?world=<name>``).
    seed : int
        Seed of the fault generators.
    t0_us : int
        Offset of the boards' ``micros()`` (to exercise the 32-bit wrap).
    info : dict
        Provenance written into recordings: the virtual rig's version and parameters.
    limits : BuildLimits, optional
        The boards' build (default: the paper's rig's, ``rigfile.default_rig()``).
    """

    plant: Any
    sensor: Any
    name: str = "default"
    seed: int = 0
    t0_us: int = 0
    info: dict[str, Any] = field(default_factory=dict)
    daq_faults: Faults = field(default_factory=Faults)
    stepper_faults: Faults = field(default_factory=Faults)
    chunk_s: float = 0.05
    """Device time generated per step when a reader pulls DAQ data."""
    limits: BuildLimits | None = None

    def __post_init__(self) -> None:
        if self.limits is None:
            self.limits = build_limits(rigfile.default_rig())
        self._one_channel = not isinstance(self.sensor, list | tuple)
        self.sensors: list[Any] = [self.sensor] if self._one_channel else list(self.sensor)
        """One sensor per channel (what the DAQ reads)."""
        self.t = float(getattr(self.plant, "t", 0.0))
        self.load_n: float | None = None
        self.go_times: list[float] = []
        self.tips: list[tuple[np.ndarray, np.ndarray]] = []
        """``(t_us, tip)`` of the samples sent, in chunks, where the plant gives the tip (m, clamp frame)."""
        self.daq = DaqEmulator(self, self.limits, self.daq_faults)
        self.stepper = StepperEmulator(self, self.limits, self.stepper_faults)
        self.daq.reset()
        self.stepper.reset()
        self.listeners: list[Callable[[VirtualWorld], None]] = []

    @property
    def rig_hash(self) -> str:
        """The hash of the rig file the boards were built for."""
        assert self.limits is not None
        return self.limits.rig_hash

    # --- calibration fixture ----------------------------------------------------------------------------
    def hang_load(self, load_n: float | None) -> None:
        """VIRTUAL calibration fixture: hang a known load (N) on every load cell (``None``: the arm again).

        While a load hangs, the DAQ reads the sensors at that tension instead of the cables'.
        """
        if load_n is not None and (not math.isfinite(load_n) or load_n < 0):
            raise ValueError(f"calibration load must be a finite non-negative force in N, got {load_n}")
        self.load_n = None if load_n is None else float(load_n)

    def reseed(self, seed: int) -> None:
        """Restart every load cell's noise (channel 0 from ``seed``, channel c from ``(seed, c)``)."""
        for c, cell in enumerate(self.sensors):
            cell.reseed(seed if c == 0 else [seed, c])

    def tip_um(self, t_us: np.ndarray) -> np.ndarray | None:
        """The tip's position (integer micrometres, clamp frame) at the samples sent with these ``t_us``.

        At channel 0's instant of each sample; None if the plant gave no tip for one of them.
        """
        if not self.tips:
            return None
        known = np.concatenate([k for k, _ in self.tips])
        tips = np.concatenate([p for _, p in self.tips])
        want = np.asarray(t_us, dtype=np.int64)
        order = np.argsort(known, kind="stable")
        i = np.clip(np.searchsorted(known[order], want), 0, len(known) - 1)
        if not np.array_equal(known[order][i], want):
            return None
        return np.rint(tips[order][i] * 1e6).astype(np.int64)

    # --- time ---------------------------------------------------------------------------------------
    def _fault_times(self) -> list[tuple[float, EmulatedBoard, str]]:
        out = []
        for board in (self.daq, self.stepper):
            for what in ("reset_at", "hang_at", "disconnect_at"):
                at = getattr(board.faults, what)
                if at is not None and at > self.t:
                    out.append((at, board, what))
        return sorted(out, key=lambda x: x[0])

    def next_event(self) -> float:
        """Device time of the next unsolicited non-data line or fault, or inf."""
        cands = [self.stepper.next_event()] + [t for t, _, _ in self._fault_times()]
        return min(cands)

    def advance_to(self, t_end: float) -> None:
        """Move the device clock to ``t_end`` (s): steps, plant, samples, DONE and faults in order.

        A signal that arrives meanwhile waits until the world is consistent again (the plant, the boards and
        the clock advanced together), then interrupts the caller.
        """
        with signals_held():
            self._advance_to(t_end)

    def _advance_to(self, t_end: float) -> None:
        while t_end > self.t + 1e-12:
            faults = self._fault_times()
            t1 = min([t_end] + [t for t, _, _ in faults if t <= t_end])
            self._advance_plain(t1)
            for at, board, what in faults:
                if at <= t1 + 1e-12:
                    setattr(board.faults, what, None)
                    if what == "reset_at":
                        board.reset()
                        continue
                    if what == "hang_at":
                        board.hung = True
                    else:
                        board.disconnected = True
                    if isinstance(board, StepperEmulator):
                        board._stop()

    def _read_plant(self, reads: np.ndarray, t1: float, step_t: np.ndarray, step_a: np.ndarray,
                    step_s: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:  # fmt: skip
        """Integrate to ``t1``: every channel's output at the read instants (n x C) and the tip, or None."""
        plant_times = reads if len(reads) and reads[-1] >= t1 - 1e-12 else np.append(reads, t1)
        if self._one_channel:
            out = np.asarray(self.plant.advance(plant_times, step_t, step_s), dtype=float)
            return out[: len(reads), None], None
        res = self.plant.advance(plant_times, step_t, step_a, step_s)
        tip = np.asarray(res["tip"])[: len(reads)] if "tip" in res else None
        return np.asarray(res["output"], dtype=float)[: len(reads)], tip

    def _advance_plain(self, t1: float) -> None:
        daq, stepper = self.daq, self.stepper
        channels = len(self.sensors)
        step_t, step_a, step_s = stepper.steps_until(t1)
        # the samples not yet sent whose channel 0 is read by t1, and how many of them have channel c read by
        # then: the interval (self.t, t1] reads every channel due in it, of the samples it completes and of
        # the one it leaves converting (kept in daq.converting until its last channel is read), so the twin
        # is never asked for a past instant, wherever the interval ends (the pseudo-terminal server's
        # intervals end at wall-clock instants, the in-process rig's on whole samples)
        lag = np.arange(channels) * ADC_CONVERSION_S
        started = daq.sample_slots(self.t, t1)
        n = len(started)
        read_by = np.array([n] + [len(daq.sample_slots(self.t, t1 - x)) for x in lag[1:]], dtype=np.int64)
        times = daq._t_start + started / daq.rate
        values, tips, read = np.zeros((n, channels)), np.full((n, 3), np.nan), np.zeros((n, channels), bool)
        held = daq.converting
        if held is not None:  # what the previous intervals read of these samples (the first rows)
            m = len(held["read"])
            values[:m], tips[:m], read[:m] = held["values"], held["tips"], held["read"]
        rows, chans = np.nonzero((np.arange(n)[:, None] < read_by[None, :]) & ~read)  # in order of time
        reads = times[rows] + lag[chans]
        output, tip = self._read_plant(reads, t1, step_t, step_a, step_s)
        values[rows, chans] = output[np.arange(len(rows)), chans]
        read[rows, chans] = True
        if tip is not None:
            tips[rows[chans == 0]] = tip[chans == 0]
        done = int(read_by[-1])
        held = {"values": values[done:], "tips": tips[done:], "read": read[done:]}
        daq.converting = held if done < n else None
        if done:
            t_done = times[:done]
            if tip is not None:
                t_us = (np.rint(t_done * 1e6).astype(np.int64) + self.t0_us) % WRAP_US
                self.tips.append((t_us, tips[:done]))
            output = values[:done] if self.load_n is None else np.full((done, channels), self.load_n)
            counts = np.column_stack(
                [np.asarray(cell.counts(output[:, c]), dtype=np.int64) for c, cell in enumerate(self.sensors)]
            )
            daq.emit_samples(started[:done], t_done, counts, daq.steps_at(t_done, step_t, step_a, step_s))
        daq.count(step_a, step_s)
        self.t = t1
        stepper.finish_if_due(t1)
        for fn in self.listeners:
            fn(self)


# --- building a rig file's world ------------------------------------------------------------------------
def build_world(rig: RigFile, name: str | None = None, options: dict[str, str] | None = None) -> VirtualWorld:
    """The virtual rig of ``rig``: the planar twin for one tendon in gravity's plane, else the spatial twin.

    Parameters
    ----------
    rig : RigFile
        The rig file the boards are built for and the twin is made from.
    name : str, optional
        The world's name (default the rig's name).
    options : dict, optional
        ``seed`` (sensor noise and faults, default 0), ``t0_us`` (clock offset), ``load_n`` (VIRTUAL
        calibration fixture: a known load hung on the load cells).
    """
    options = options or {}
    seed = int(options.get("seed", 0))
    common = {"name": name or rig.name, "seed": seed, "t0_us": int(options.get("t0_us", 0)),
              "limits": build_limits(rig)}  # fmt: skip
    if planar_holds(rig):
        params = RigParameters() if rig.hash == rigfile.default_rig().hash else rig_parameters(rig)
        info = {"version": __version__, "parameters": parameters_dict(params), "seed": seed}
        world = VirtualWorld(ArmPlant(params), LoadCell(params, seed=seed), info=info, **common)
    else:
        twin = spatial_rig(rig, as_built=True)  # [[tendon]] twin_eyelet_error_mm: the arm as built
        plant = SpatialPlant(twin)  # at the arm's step (RK4: within its stable step, 1/6 ms for four tendons)
        cells = [
            LoadCell(twin.arm, seed=seed if c == 0 else [seed, c], span_n=t.load_cell_range_n)
            for c, t in enumerate(twin.tendons)
        ]
        info = {"version": __version__, "parameters": twin.metadata(), "seed": seed, "tendons": rig.n_tendons}
        world = VirtualWorld(plant, cells, info=info, **common)
    if "load_n" in options:
        world.hang_load(float(options["load_n"]))
    return world


def parameters_dict(params: Any) -> dict[str, Any]:
    """The parameters as flat JSON values (the recording contract's ``source.parameters``).

    A :class:`~helpers.virtual.RigParameters` gives every field and its main derived values
    (``RigParameters.metadata()``); other dataclasses, dicts and objects give their fields.
    """
    if callable(getattr(params, "metadata", None)):
        raw = params.metadata()
    elif dataclasses.is_dataclass(params):
        raw = dataclasses.asdict(params)
    elif isinstance(params, dict):
        raw = dict(params)
    else:
        raw = {k: v for k, v in vars(params).items() if not k.startswith("_")}
    out = {}
    for k, v in raw.items():
        if isinstance(v, np.ndarray):
            v = v.tolist()
        elif isinstance(v, np.generic):
            v = v.item()
        if isinstance(v, (int, float, str, bool, list, tuple, dict)) or v is None:
            out[k] = v
    return out


# --- the worlds of this process, by (name, rig hash) (the URL handler and the server share them) ---------
_WORLDS: dict[tuple[str, str], VirtualWorld] = {}


def register_world(world: VirtualWorld) -> VirtualWorld:
    """Keep ``world`` as the world ``(world.name, its rig's hash)`` (replacing any world of that key)."""
    _WORLDS[(world.name, world.rig_hash)] = world
    return world


def forget_world(name: str, rig: RigFile | None = None) -> None:
    """Forget the world ``(name, rig)``, or every world named ``name`` (the next open builds a fresh one)."""
    for key in [k for k in _WORLDS if k[0] == name and (rig is None or k[1] == rig.hash)]:
        del _WORLDS[key]


def find_world(name: str, rig: RigFile | None = None) -> VirtualWorld | None:
    """The world ``(name, rig)``; without a rig, the one world named ``name``; None if there is none.

    Raises
    ------
    ValueError
        Without a rig, when several rigs have a world of that name.
    """
    if rig is not None:
        return _WORLDS.get((name, rig.hash))
    named = [w for (n, _), w in _WORLDS.items() if n == name]
    if len(named) > 1:
        hashes = ", ".join(w.rig_hash for w in named)
        raise ValueError(f"virtual rig {name!r} exists for several rig files ({hashes}): name the rig")
    return named[0] if named else None


def get_world(name: str | None = None, rig: RigFile | None = None,
              options: dict[str, str] | None = None) -> VirtualWorld:  # fmt: skip
    """The world ``(name, rig)``, built by :func:`build_world` if it is new.

    Parameters
    ----------
    name : str, optional
        The world's name (default the rig's name).
    rig : RigFile, optional
        The rig file. Without it: the one world named ``name`` if there is one, else a new world of the
        paper's rig (``rigfile.default_rig()``).
    options : dict, optional
        :func:`build_world`'s options, used only when the world is built: ``seed``, ``t0_us``, ``load_n``.
    """
    if rig is None:
        name = name or "default"
        found = find_world(name)
        if found is not None:
            return found
        rig = rigfile.default_rig()
    name = name or rig.name
    world = _WORLDS.get((name, rig.hash))
    return world if world is not None else register_world(build_world(rig, name, options))
