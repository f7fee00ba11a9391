"""One virtual rig: the plant, the sensor and both emulated boards on one device clock; and its registry.

:class:`VirtualWorld` owns the device clock ``t`` (seconds, shared by both boards). Nothing happens between
calls; time moves only when :meth:`VirtualWorld.advance_to` is called, which integrates the plant over the
interval with the stepper's steps at their exact programme times, takes the DAQ samples that fall in it and
queues every line the boards send. A reader (the pyserial URL handler or the pseudo-terminal server) decides
how far to advance: in-process, as far as the reader needs (so the virtual rig runs faster than real time); on
a pseudo-terminal, paced to the wall clock.

The boards drive a plant given to them (dependency injection: the virtual rig's
:class:`helpers.virtual.ArmPlant`, or a test double with the same ``advance`` signature) and read what the
plant returns (the virtual rig's amplifier output; its low-pass filter is part of the plant's state, so
chunked ``advance`` calls give the same samples as one call) through a sensor model (``LoadCell.counts``:
current loop, shunt and ADC). :func:`default_world` builds the tuned virtual rig.
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
from helpers.virtual import ArmPlant, LoadCell, RigParameters
from helpers.virtual.emulator.boards import DaqEmulator, EmulatedBoard, Faults, StepperEmulator
from helpers.virtual.from_rig import rig_parameters

__all__ = ["VirtualWorld", "register_world", "forget_world", "get_world", "default_world", "parameters_dict"]


@dataclass
class VirtualWorld:
    """One virtual rig: the plant, the sensor, both boards and their shared device clock.

    Parameters
    ----------
    plant : Plant
        Integrates the arm; ``advance(sample_times, step_times, step_signs)`` returns the load cell's
        amplifier output (N).
    sensor : Sensor
        ``counts(output)`` gives ADC counts (loop saturation, noise and quantisation included).
    name : str
        The rig's name in ``virtual://...?rig=<name>`` URLs.
    seed : int
        Seed of the fault generators.
    t0_us : int
        Offset of the boards' ``micros()`` (to exercise the 32-bit wrap).
    info : dict
        Provenance written into recordings: the virtual rig's version and parameters.
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

    def __post_init__(self) -> None:
        self.t = float(getattr(self.plant, "t", 0.0))
        self.load_n: float | None = None
        self.go_times: list[float] = []
        self.daq = DaqEmulator(self, self.daq_faults)
        self.stepper = StepperEmulator(self, self.stepper_faults)
        self.daq.reset()
        self.stepper.reset()
        self.listeners: list[Callable[[VirtualWorld], None]] = []

    # --- calibration fixture ----------------------------------------------------------------------------
    def hang_load(self, load_n: float | None) -> None:
        """VIRTUAL calibration fixture: hang a known load (N) on the load cell (``None``: the arm again).

        While a load hangs, the DAQ reads the sensor at that tension instead of the cable's.
        """
        if load_n is not None and (not math.isfinite(load_n) or load_n < 0):
            raise ValueError(f"calibration load must be a finite non-negative force in N, got {load_n}")
        self.load_n = None if load_n is None else float(load_n)

    def reseed(self, seed: int) -> None:
        """Restart the sensor's noise from ``seed`` (the rig does so before each run given a seed)."""
        self.sensor.reseed(seed)

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
                    elif what == "hang_at":
                        board.hung = True
                        if isinstance(board, StepperEmulator):
                            board._stop()
                    else:
                        board.disconnected = True
                        if isinstance(board, StepperEmulator):
                            board._stop()

    def _advance_plain(self, t1: float) -> None:
        t0 = self.t
        step_t, step_s = self.stepper.steps_until(t1)
        slots = self.daq.sample_slots(t0, t1)
        times = self.daq._t_start + slots / self.daq.rate
        plant_times = times if len(times) and times[-1] >= t1 - 1e-12 else np.append(times, t1)
        tension = np.asarray(self.plant.advance(plant_times, step_t, step_s), dtype=float)
        if len(slots):
            tension = tension[: len(times)]
            if self.load_n is not None:
                tension = np.full(len(times), self.load_n)
            counts = np.asarray(self.sensor.counts(tension), dtype=np.int64)
            k = np.searchsorted(step_t, times, side="right")
            csum = np.concatenate([[0], np.cumsum(step_s)])
            steps = self.daq.step_count + csum[k]
            self.daq.emit_samples(slots, times, counts, steps)
        self.daq.step_count += int(step_s.sum())
        self.t = t1
        self.stepper.finish_if_due(t1)
        for fn in self.listeners:
            fn(self)


# --- registry of named worlds (the URL handler and the server share it) ---------------------------------
_WORLDS: dict[str, VirtualWorld] = {}


def register_world(world: VirtualWorld) -> VirtualWorld:
    """Make ``world`` reachable as ``virtual://daq?rig=<world.name>`` (replacing any world of that name)."""
    _WORLDS[world.name] = world
    return world


def forget_world(name: str) -> None:
    """Remove a named world (the next URL with that name builds a fresh one)."""
    _WORLDS.pop(name, None)


def get_world(
    name: str,
    options: dict[str, str] | None = None,
    build: Callable[[str, dict[str, str]], VirtualWorld] | None = None,
) -> VirtualWorld:
    """Return the named world, building it from the virtual rig's calibrated parameters if it is new.

    Parameters
    ----------
    name : str
        The rig name.
    options : dict, optional
        URL query options used only when the world is created: ``seed``, ``t0_us``, ``load_n``.
    build : callable, optional
        Builds a new world from ``(name, options)`` (default :func:`default_world`; the URL handler and
        the server pass :func:`helpers.virtual.emulator.tendon_world.build_world`).
    """
    if name not in _WORLDS:
        register_world((build or default_world)(name, options or {}))
    return _WORLDS[name]


def default_world(name: str = "default", options: dict[str, str] | None = None) -> VirtualWorld:
    """Build a world around the virtual rig of the selected rig file (``helpers.virtual`` physics).

    The paper's rig file (the default) gives the tuned rig, ``RigParameters()``; another (``HELPERS_RIG``,
    ``--rig``) gives its planar twin (``helpers.virtual.from_rig``; untuned unless its file is).

    Parameters
    ----------
    name : str
        The rig name.
    options : dict, optional
        ``seed`` (sensor noise and faults, default 0), ``t0_us`` (clock offset), ``load_n`` (VIRTUAL
        calibration fixture: a known load hung on the load cell).
    """
    options = options or {}
    seed = int(options.get("seed", 0))
    chosen = rigfile.selected()
    params = RigParameters() if chosen.hash == rigfile.default_rig().hash else rig_parameters(chosen)
    plant = ArmPlant(params)
    sensor = LoadCell(params, seed=seed)
    info = {"version": __version__, "parameters": parameters_dict(params), "seed": seed}
    world = VirtualWorld(plant, sensor, name=name, seed=seed, t0_us=int(options.get("t0_us", 0)), info=info)
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
