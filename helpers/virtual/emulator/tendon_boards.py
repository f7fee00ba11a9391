"""Emulated boards of a rig with several tendons: the firmware built for ``RIG_AXES``, ``RIG_CHANNELS`` > 1.

:class:`TendonStepperEmulator` is the stepper firmware built for A axes (``firmware/PROTOCOL.md``, *several
tendons*): ``MSEG <window_us> <n_0> ... <n_{A-1}>`` moves every axis in one window, step k of an axis making
n steps on the 0.5 us tick ``ceil(k * 2 W / n)`` from the item's start (the firmware's remainder recurrence);
``SEG`` moves axis 0, ``WAIT`` is a dwell of every axis; ``CONFIG`` reports the axes, the programme length,
the interval limits and each axis's travel (then each axis's release, on a build with one); ``DONE``,
``ABORTED`` and ``OK POS`` list every axis's position; ``GO`` refuses the first axis (in axis order) that the
programme would take outside ``-release..travel``. An item moves an axis at most ``release + travel`` steps.

Streams shape every axis with the one loaded shaper, as the firmware's multi-axis stream mode does
(:class:`~helpers.virtual.emulator.stream_mode.AxesStreamMode`, on
:class:`helpers.board.stream_reference.AxesSession`): ``MV <v_0> ... <v_{A-1}>`` -> ``OK MV <period>``,
``V <v>`` axis 0's set-point (the others zero), each axis clamped at its own travel with its notices
(``N,LIMIT,TRAVEL,156,1``: axes 1.. append ``,<axis>``), the longest delay 0.62 s (``IMP`` refuses longer);
``STREAM`` empties the programme (whose table the firmware's stream state takes) and ``CLEAR``, ``SEG``,
``MSEG`` and ``WAIT`` get ``ERR STATE streaming`` while streaming. ``OK STREAM`` names axis 0's position,
``DONE`` every axis's.

:class:`TendonDaqEmulator` is the DAQ firmware built for C channels and A axes: ``OK CONFIG <C> <A> <min>
<max>`` and data lines ``D,<seq>,<t_us>,<adc_0>,...,<adc_{C-1}>,<steps_0>,...,<steps_{A-1}>``.

A board's limits come from a :class:`BuildLimits` (what the firmware header generated from the rig file
holds: :func:`build_limits`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from helpers.board.stream_reference import MAX_DELAY_US, MAX_DELAY_US_AXES
from helpers.rigfile import RigFile
from helpers.rigfile.derived import derived
from helpers.virtual.emulator.boards import DaqEmulator, Faults, StepperEmulator, _Command
from helpers.virtual.emulator.stream_mode import AxesStreamMode

__all__ = ["BuildLimits", "build_limits", "TendonStepperEmulator", "TendonDaqEmulator"]


@dataclass(frozen=True)
class BuildLimits:
    """The compiled-in values of one firmware build (``firmware/common/rig_config.h``'s macros).

    Attributes
    ----------
    rig_hash : str
        ``RIG_HASH``: the 8 hex characters in ``HELLO``/``PONG``.
    travel_steps : tuple of int
        ``RIG_AXIS_TRAVEL_STEPS``: one per axis (``RIG_AXES`` = its length).
    channels : int
        ``RIG_CHANNELS``.
    min_interval_us, max_interval_us, programme_max, max_dwell_ms : int
        The stepper's limits.
    rate_min_hz, rate_max_hz, rate_default_hz : int
        The DAQ's rates.
    release_steps : tuple of int
        ``RIG_AXIS_RELEASE_STEPS``: how far each axis may pay out below zero; empty (the macro absent): none.
    """

    rig_hash: str
    travel_steps: tuple[int, ...]
    channels: int
    min_interval_us: int = 639
    max_interval_us: int = 1_000_000
    programme_max: int = 64
    max_dwell_ms: int = 60_000
    rate_min_hz: int = 100
    rate_max_hz: int = 2000
    rate_default_hz: int = 1000
    release_steps: tuple[int, ...] = ()

    @property
    def axes(self) -> int:
        """``RIG_AXES``."""
        return len(self.travel_steps)

    @property
    def releases(self) -> tuple[int, ...]:
        """Each axis's release (0 each without ``RIG_AXIS_RELEASE_STEPS``)."""
        return self.release_steps or (0,) * self.axes

    def span(self, axis: int) -> int:
        """The most steps one item moves ``axis``: its release and travel together."""
        return self.travel_steps[axis] + self.releases[axis]

    def travel_text(self, axis: int) -> str:
        """``GO``'s range of ``axis``: ``0-156``, or ``-78-156`` with a release."""
        r = self.releases[axis]
        return f"{-r if r else 0}-{self.travel_steps[axis]}"


def build_limits(rig: RigFile) -> BuildLimits:
    """The limits the firmware header of ``rig`` holds (``helpers.rigfile.firmware_header``)."""
    d = derived(rig)
    hw = rig.hardware
    return BuildLimits(
        rig_hash=rig.hash, travel_steps=tuple(d.travel_steps), channels=rig.n_tendons,
        min_interval_us=d.min_interval_us, max_interval_us=d.max_interval_us,
        programme_max=hw.programme_max_items, max_dwell_ms=hw.max_dwell_ms, rate_min_hz=hw.daq_rate_min_hz,
        rate_max_hz=hw.daq_rate_max_hz, rate_default_hz=hw.daq_rate_default_hz,
        release_steps=tuple(d.release_steps) if any(d.release_steps) else (),
    )  # fmt: skip


@dataclass
class _Window:
    """One programme item: every axis's signed steps in a window (us), or a dwell (``steps`` None)."""

    window_us: int
    steps: tuple[int, ...] | None

    def step_times_us(self, axis: int) -> np.ndarray:
        """Axis ``axis``'s step instants from the item's start, us (on the firmware's 0.5 us ticks)."""
        n = abs(self.steps[axis]) if self.steps else 0
        k = np.arange(1, n + 1, dtype=np.int64)
        return -(-k * (2 * self.window_us) // max(n, 1)) / 2.0


class TendonStepperEmulator(StepperEmulator):
    """The stepper board built for several axes (see the module's docstring)."""

    def __init__(self, world: Any, limits: BuildLimits, faults: Faults | None = None) -> None:
        self.limits = limits
        self.rig_hash = limits.rig_hash
        self.max_args = max(3, limits.axes + 1)
        self.windows: list[_Window] = []
        self.positions = [0] * limits.axes
        self._step_axes = np.zeros(0, dtype=np.int64)
        super().__init__(world, faults)

    @property
    def stream_max_delay_us(self) -> int:  # type: ignore[override]  # noqa: D102
        return MAX_DELAY_US_AXES if self.limits.axes > 1 else MAX_DELAY_US

    # --- replies ------------------------------------------------------------------------------------
    def _positions(self, word: str) -> str:
        return f"{word} " + " ".join(map(str, self.positions))

    def send(self, body: str) -> None:  # noqa: D102 - positions of every axis in DONE
        if body.startswith("DONE ") and len(body.split()) == 2:
            self.positions[0] = self.position
            body = self._positions("DONE")
        super().send(body)

    def reset(self) -> None:  # noqa: D102
        self.windows = []
        self.positions = [0] * self.limits.axes
        self._step_axes = np.zeros(0, dtype=np.int64)
        super().reset()

    # --- commands -----------------------------------------------------------------------------------
    def cmd_CONFIG(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        lim = self.limits
        travel = " ".join(map(str, lim.travel_steps + lim.release_steps))  # releases only when built with
        return (
            f"OK CONFIG {lim.axes} {lim.programme_max} {lim.min_interval_us} {lim.max_interval_us} {travel}"
        )

    def _locked(self) -> str | None:
        """The firmware's ``editable()``: no programme edit while it runs or a stream holds its table."""
        if self.running:
            return "ERR STATE running"
        if self.stream is not None and self.limits.axes > 1:
            return "ERR STATE streaming"
        return None

    def _add(self, item: _Window) -> str | None:
        if len(self.windows) >= self.limits.programme_max:
            return f"ERR FULL {self.limits.programme_max} items"
        self.windows.append(item)
        return None

    def cmd_CLEAR(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0) or self._locked():
            return err
        self.items, self.windows = [], []
        return "OK CLEAR"

    def cmd_SEG(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 3) or self._locked():
            return err
        lim = self.limits
        d, n, iv = cmd.args
        if d not in (1, -1):
            return "ERR RANGE dir must be 1 or -1"
        if not 1 <= n <= lim.span(0):
            return f"ERR RANGE n_steps 1-{lim.span(0)}"
        if not lim.min_interval_us <= iv <= lim.max_interval_us:
            return f"ERR RANGE interval {lim.min_interval_us}-{lim.max_interval_us} us"
        steps = (d * n,) + (0,) * (lim.axes - 1)
        return self._add(_Window(n * iv, steps)) or f"OK SEG {len(self.windows)}"

    def cmd_MSEG(self, cmd: _Command) -> str:  # noqa: N802, D102
        lim = self.limits
        if cmd.bad or len(cmd.args) != 1 + lim.axes:
            return f"ERR ARG MSEG needs {1 + lim.axes} integers"
        if err := self._locked():
            return err
        window, *ns = cmd.args
        if not 1 <= window <= 255 * lim.max_interval_us:
            return f"ERR RANGE window 1-{255 * lim.max_interval_us} us"
        for a, n in enumerate(ns):
            span, m = lim.span(a), abs(n)
            if m > span:
                return f"ERR RANGE axis {a} steps -{span}..{span}"
            if m and not m * lim.min_interval_us <= window <= m * lim.max_interval_us:
                return f"ERR RANGE axis {a} interval {lim.min_interval_us}-{lim.max_interval_us} us"
        if not any(ns):
            return "ERR RANGE no axis moves (a dwell is WAIT)"
        return self._add(_Window(window, tuple(ns))) or f"OK MSEG {len(self.windows)}"

    def cmd_WAIT(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 1) or self._locked():
            return err
        if not 0 <= cmd.args[0] <= self.limits.max_dwell_ms:
            return f"ERR RANGE dwell 0-{self.limits.max_dwell_ms} ms"
        return self._add(_Window(1000 * cmd.args[0], None)) or f"OK WAIT {len(self.windows)}"

    def cmd_GO(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._go_refusal(cmd, bool(self.windows)):
            return err
        self.positions[0] = self.position
        lim = self.limits
        for a, (travel, release) in enumerate(zip(lim.travel_steps, lim.releases, strict=True)):
            pos = self.positions[a]  # the firmware checks axis by axis
            for it in self.windows:
                pos += it.steps[a] if it.steps else 0
                if not -release <= pos <= travel:
                    where = f"axis {a} " if lim.axes > 1 else ""
                    return f"ERR RANGE {where}travel {lim.travel_text(a)} steps"
        times, axes, signs, t0_us = [], [], [], 0.0
        for it in self.windows:
            if it.steps:
                for a, n in enumerate(it.steps):
                    if n:
                        times.append(t0_us + it.step_times_us(a))
                        axes.append(np.full(abs(n), a, dtype=np.int64))
                        signs.append(np.full(abs(n), 1 if n > 0 else -1, dtype=np.int64))
            t0_us += it.window_us
        go = self.world.t
        if times:
            t = np.concatenate(times)
            order = np.argsort(t, kind="stable")  # steps on one tick keep the axes' order
            self._step_times = go + t[order] * 1e-6
            self._step_axes = np.concatenate(axes)[order]
            self._step_signs = np.concatenate(signs)[order]
        else:
            self._step_times, self._step_axes = np.zeros(0), np.zeros(0, dtype=np.int64)
            self._step_signs = np.zeros(0, dtype=np.int64)
        self._next = 0
        self._end_t = go + t0_us * 1e-6
        self.running = True
        self.world.go_times.append(go)
        return f"OK GO {len(self.windows)}"

    # --- streaming: every axis (firmware/PROTOCOL.md, the end of "Stepper board: streaming mode") ---------
    def cmd_STREAM(self, cmd: _Command) -> str:  # noqa: N802, D102
        reply = super().cmd_STREAM(cmd)  # the checks, and one axis's stream
        if not reply.startswith("OK") or self.limits.axes == 1:
            return reply
        self.windows = []  # the stream's state takes the programme table's RAM
        self.positions[0] = self.position
        assert self.shaper.ready is not None
        self.stream = AxesStreamMode(self.shaper.ready, list(self.positions), self.limits.travel_steps,
                                     self.world.t, self.send, self.limits.releases)  # fmt: skip
        return reply

    def cmd_MV(self, cmd: _Command) -> str:  # noqa: N802, D102
        axes = self.limits.axes
        if cmd.bad or len(cmd.args) != axes:
            return f"ERR ARG MV needs {axes} integer{'s' if axes > 1 else ''}"
        if self.stream is None:
            return "ERR STATE not streaming"
        return self.stream.setpoints(cmd.args)

    def cmd_ABORT(self, cmd: _Command) -> str:  # noqa: N802, D102
        reply = super().cmd_ABORT(cmd)
        if reply.startswith("ABORTED"):
            self.positions[0] = self.position
            return self._positions("ABORTED")
        return reply

    def cmd_POS(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        self.positions[0] = self.position
        return self._positions("OK POS")

    # --- device time --------------------------------------------------------------------------------
    def axis_steps_until(self, t1: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Take the steps due at or before ``t1``: ``(times, axes, signs)`` (positions updated)."""
        if self.hung or self.disconnected or (self.stream is None and not self.running):
            return np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        if isinstance(self.stream, AxesStreamMode):
            return self._stream_steps_until(t1)
        if self.stream is not None:  # one axis
            times, signs = self.steps_until(t1)
            self.positions[0] = self.position
            return times, np.zeros(len(times), dtype=np.int64), signs
        j = int(np.searchsorted(self._step_times, t1 + 1e-12, side="right"))
        sl = slice(self._next, j)
        times, axes, signs = self._step_times[sl], self._step_axes[sl], self._step_signs[sl]
        self._next = j
        for a in range(self.limits.axes):
            self.positions[a] += int(signs[axes == a].sum())
        self.position = self.positions[0]
        return times, axes, signs

    def _stream_steps_until(self, t1: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        stream = self.stream
        assert isinstance(stream, AxesStreamMode)
        times, axes, signs = stream.axis_steps_until(t1)
        for a in range(self.limits.axes):
            self.positions[a] += int(signs[axes == a].sum())
        self.position = self.positions[0]
        if stream.finished:
            if stream.session.watchdog:  # the watchdog's stream ends with the driver disabled
                self.enabled = False
            self.stream = None
            self.send(self._positions("DONE"))
        return times, axes, signs


class TendonDaqEmulator(DaqEmulator):
    """The DAQ board built for several channels and axes (see the module's docstring)."""

    def __init__(self, world: Any, limits: BuildLimits, faults: Faults | None = None) -> None:
        self.limits = limits
        self.rig_hash = limits.rig_hash
        self.step_counts = np.zeros(limits.axes, dtype=np.int64)
        super().__init__(world, faults)

    def reset(self) -> None:  # noqa: D102
        self.step_counts = np.zeros(self.limits.axes, dtype=np.int64)
        super().reset()
        self.rate = self.limits.rate_default_hz

    def cmd_CONFIG(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        lim = self.limits
        return f"OK CONFIG {lim.channels} {lim.axes} {lim.rate_min_hz} {lim.rate_max_hz}"

    def cmd_RATE(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 1):
            return err
        if self.streaming:
            return "ERR STATE streaming"
        lo, hi = self.limits.rate_min_hz, self.limits.rate_max_hz
        if not lo <= cmd.args[0] <= hi:
            return f"ERR RANGE rate {lo}-{hi} Hz"
        self.rate = cmd.args[0]
        return f"OK RATE {self.rate}"

    def cmd_ZERO(self, cmd: _Command) -> str:  # noqa: N802, D102
        reply = super().cmd_ZERO(cmd)
        if reply == "OK ZERO":
            self.step_counts[:] = 0
        return reply

    @staticmethod
    def payload(counts: np.ndarray, steps: np.ndarray) -> list[str]:
        """``<adc_0>,...,<adc_{C-1}>,<steps_0>,...,<steps_{A-1}>`` per row of ``counts``, ``steps``."""
        both = np.concatenate([np.atleast_2d(counts), np.atleast_2d(steps)], axis=1).astype(np.int64)
        return [",".join(map(str, row)) for row in both.tolist()]

    def steps_at(self, times: np.ndarray, step_t: np.ndarray, step_axes: np.ndarray,
                 step_signs: np.ndarray) -> np.ndarray:  # fmt: skip
        """Each axis's count at the sample instants (a step at a sample's instant counts), shape (n, A)."""
        out = np.empty((len(times), self.limits.axes), dtype=np.int64)
        for a in range(self.limits.axes):
            sel = step_axes == a
            csum = np.concatenate([[0], np.cumsum(step_signs[sel])])
            out[:, a] = self.step_counts[a] + csum[np.searchsorted(step_t[sel], times, side="right")]
        return out

    def count(self, step_axes: np.ndarray, step_signs: np.ndarray) -> None:
        """Add the steps of an interval to each axis's count."""
        for a in range(self.limits.axes):
            self.step_counts[a] += int(step_signs[step_axes == a].sum())
        self.step_count = int(self.step_counts[0])
