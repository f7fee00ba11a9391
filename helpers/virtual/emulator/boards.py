"""Emulated DAQ and stepper boards: the firmware built for a rig file, as Python objects on the protocol.

The boards follow ``firmware/PROTOCOL.md`` for a build of C load-cell channels and A stepper axes (1-4 each;
the paper's build is C = A = 1): the same replies, error codes and limits (:class:`BuildLimits`, what the
firmware header generated from the rig file holds: :func:`build_limits`), ``HELLO`` on reset, ``W,OVERRUN``
reporting, CRC-8 checksums and the version token ``<FW_VERSION>+<rig hash>`` (:func:`board_version`). They
live in a :class:`helpers.virtual.emulator.world.VirtualWorld`, which owns the device clock and the plant; a
board sees the world only through the attributes it reads (``t``, ``seed``, ``t0_us``, ``go_times``).

:class:`StepperEmulator` runs a programme of ``SEG`` (axis 0), ``MSEG <window_us> <n_0> ... <n_{A-1}>``
(every axis in one window, step k of an axis making n steps on the 0.5 us tick ``ceil(k * 2 W / n)`` from the
item's start) and ``WAIT`` items; ``CONFIG`` reports the axes, the programme length, the interval limits and
each axis's travel (then each axis's release, on a build with one); ``DONE``, ``ABORTED`` and ``OK POS`` list
every axis's position; ``GO`` refuses the first axis (in axis order) that the programme would take outside
``-release..travel``. Streams (``SHAPER``, ``IMP``, ``STREAM``, ``V``, ``MV``, ``END``) run in
:mod:`helpers.virtual.emulator.stream_mode`: one axis as the paper's build, every axis with the one shaper on
a build with several (``STREAM`` then empties the programme, whose table the firmware's stream state takes,
and ``CLEAR``, ``SEG``, ``MSEG`` and ``WAIT`` get ``ERR STATE streaming`` while streaming).

:class:`DaqEmulator` answers ``OK CONFIG <C> <A> <min> <max>`` and sends data lines
``D,<seq>,<t_us>,<adc_0>,...,<adc_{C-1}>,<steps_0>,...,<steps_{A-1}>``.

Fault injection (per board, :class:`Faults`; for tests, any axis count): ``drop`` / ``corrupt`` / ``garbage``
probabilities per data line, ``drop_replies`` / ``corrupt_replies`` per other line a board sends (replies,
``HELLO``, ``DONE``, notices), ``reset_at`` (the board reboots and sends ``HELLO``), ``hang_at`` (the board
stops answering: a stepper never sends ``DONE``), ``disconnect_at`` (the port disappears), ``overrun_every``
(the DAQ misses one sample period every n samples and reports it). Everything emitted here is simulation;
recordings made from it say ``virtual-rig``.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np

from helpers.board.protocol import FW_VERSION, MAX_LINE, WRAP_US, checksum, frame
from helpers.board.stream_reference import MAX_DELAY_US, MAX_DELAY_US_AXES, v_max
from helpers.rigfile import RigFile
from helpers.rigfile.derived import derived
from helpers.virtual.emulator.framing import frame_data_lines
from helpers.virtual.emulator.stream_mode import ShaperLoader, StreamMode

__all__ = ["BuildLimits", "build_limits", "board_version", "Faults", "Disconnected", "EmulatedBoard",
           "DaqEmulator", "StepperEmulator", "MEM_FREE_BYTES"]  # fmt: skip

INT32_MAX = 2**31 - 1
MEM_FREE_BYTES = 560
"""What the emulated stepper answers to ``MEM``: the least free stack measured for the firmware in simavr
(``firmware/README.md``); the emulated board has no stack of its own."""


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


def board_version(rig_hash: str) -> str:
    """The version token of ``HELLO``/``PONG``: ``<FW_VERSION>+<rig hash>`` (semantic-version build metadata).

    Parameters
    ----------
    rig_hash : str
        The 8 hex characters of the rig the board was built for.

    Returns
    -------
    str
        E.g. ``"2.3.0+481e87e3"``.
    """
    return f"{FW_VERSION}+{rig_hash}"


@dataclass
class Faults:
    """Fault injection settings of one emulated board (all off by default).

    Attributes
    ----------
    drop, corrupt, garbage : float
        Probability per data line that it is lost in transport, has one byte altered, or is preceded by a line
        of random garbage bytes.
    drop_replies, corrupt_replies : float
        Probability per other line the board sends (a reply, ``HELLO``, ``DONE``, a notice) that it is lost or
        has one byte altered.
    reset_at, hang_at, disconnect_at : float or None
        Device time (s) at which the board reboots (``HELLO``), stops answering, or its port vanishes.
    overrun_every : int
        Every n-th sample period the DAQ is late: the sample is not taken and ``W,OVERRUN,1`` is sent.
    """

    drop: float = 0.0
    corrupt: float = 0.0
    garbage: float = 0.0
    drop_replies: float = 0.0
    corrupt_replies: float = 0.0
    reset_at: float | None = None
    hang_at: float | None = None
    disconnect_at: float | None = None
    overrun_every: int = 0

    @classmethod
    def from_options(cls, options: dict[str, str]) -> Faults:
        """Build from URL query options (unknown keys are ignored here)."""
        kw: dict[str, Any] = {}
        for name in ("drop", "corrupt", "garbage", "drop_replies", "corrupt_replies"):
            if name in options:
                kw[name] = float(options[name])
                if not 0.0 <= kw[name] <= 1.0:
                    raise ValueError(f"fault probability {name}={kw[name]} is not within 0..1")
        for name in ("reset_at", "hang_at", "disconnect_at"):
            if name in options:
                kw[name] = float(options[name])
        if "overrun_every" in options:
            kw["overrun_every"] = int(options["overrun_every"])
        return cls(**kw)


FAULT_OPTIONS = ("drop", "corrupt", "garbage", "drop_replies", "corrupt_replies", "reset_at", "hang_at",
                 "disconnect_at", "overrun_every")  # fmt: skip
"""The URL query options and ``--*-faults`` keys of :class:`Faults`."""


class Disconnected(Exception):
    """The emulated port vanished (fault ``disconnect_at``); the URL handler turns it into SerialException."""


@dataclass
class _Command:
    word: str
    args: list[int]
    bad: bool


def _damaged(line: bytes, rng: np.random.Generator) -> bytes:
    """``line`` with one byte (not its newline) changed into another printable one."""
    pos = int(rng.integers(0, len(line) - 1))
    b = bytearray(line)
    new = b[pos]
    while new in (b[pos], 0x0A, 0x0D):
        new = int(rng.integers(32, 127))
    b[pos] = new
    return bytes(b)


class EmulatedBoard:
    """Line handling shared by both boards: framing, checksums, ``TOOLONG``, faults, the output queue.

    Parameters
    ----------
    world : object
        What the board reads of its world: ``t``, ``seed``, ``t0_us``, ``go_times``.
    limits : BuildLimits
        The build the board emulates.
    faults : Faults, optional
        Fault injection (none by default).
    """

    kind = "board"

    def __init__(self, world: Any, limits: BuildLimits, faults: Faults | None = None) -> None:
        self.world = world
        self.limits = limits
        self.faults = faults or Faults()
        self.max_args = max(3, limits.axes + 1)
        """Arguments parsed per command (the firmware's ``PROTO_MAX_ARGS``: 3, or 1 + the axes of a build)."""
        self.out: deque[bytes] = deque()
        self.received: list[str] = []
        """Every command line the board accepted (checksum stripped), for tests and diagnostics."""
        self._inbuf = bytearray()
        self._overflow = False
        self._cr = False
        self.hung = False
        self.disconnected = False
        self.resets = 0
        self._rng = np.random.default_rng(world.seed + (1 if self.kind == "daq" else 2))
        self.injected = {"dropped": 0, "corrupted": 0, "garbage": 0, "overrun_periods": 0,
                         "replies_dropped": 0, "replies_corrupted": 0}  # fmt: skip
        """Faults injected so far (tests compare the host's counts with these)."""
        self.port: Any = None
        """The pyserial port that has this board open (one at a time), or None."""

    @property
    def rig_hash(self) -> str:
        """The rig hash of the build the board emulates."""
        return self.limits.rig_hash

    # --- output -------------------------------------------------------------------------------------
    def send(self, body: str) -> None:
        """Queue one line (lost if the board hangs or is disconnected, or by the fault ``drop_replies``)."""
        if self.hung or self.disconnected:
            return
        line = frame(body)
        f = self.faults
        if f.drop_replies or f.corrupt_replies:
            if f.drop_replies and self._rng.random() < f.drop_replies:
                self.injected["replies_dropped"] += 1
                return
            if f.corrupt_replies and self._rng.random() < f.corrupt_replies:
                line = _damaged(line, self._rng)
                self.injected["replies_corrupted"] += 1
        self.out.append(line)

    def take_output(self, max_bytes: int | None = None) -> bytes:
        """Remove and return queued bytes (whole lines, at least one line if any is queued)."""
        if self.disconnected:
            raise Disconnected(f"virtual {self.kind} board disconnected")
        if not self.out:
            return b""
        if max_bytes is None:
            data = b"".join(self.out)
            self.out.clear()
            return data
        parts, n = [], 0
        while self.out and (n == 0 or n + len(self.out[0]) <= max_bytes):
            line = self.out.popleft()
            parts.append(line)
            n += len(line)
        return b"".join(parts)

    @property
    def pending_bytes(self) -> int:
        """Bytes queued for the host."""
        return sum(len(x) for x in self.out)

    # --- input --------------------------------------------------------------------------------------
    def receive(self, data: bytes) -> None:
        """Feed bytes written by the host; complete lines are executed at the present device time."""
        if self.disconnected:
            raise Disconnected(f"virtual {self.kind} board disconnected")
        if self.hung:
            return
        for c in data:
            if self._cr:  # a held '\r' not followed by '\n' is part of the line (as the firmware)
                self._cr = False
                if c != 0x0A:
                    self._place(0x0D)
            if c == 0x0D:
                self._cr = True
                continue
            if c == 0x0A:
                if self._overflow:
                    self._overflow = False
                    self._inbuf.clear()
                    self.send("ERR TOOLONG line over 63 characters")
                else:
                    line = bytes(self._inbuf)
                    self._inbuf.clear()
                    self._line(line)
                continue
            self._place(c)

    def _place(self, c: int) -> None:
        if self._overflow:
            return
        if len(self._inbuf) >= MAX_LINE:
            self._overflow = True
            self._inbuf.clear()
            return
        self._inbuf.append(c)

    def _parse(self, line: bytes) -> _Command | str | None:
        """Return a command, an error reply body, or None for a blank line (as ``proto_parse``)."""
        text = line.decode("latin-1")
        if not text:
            return None
        star = text.find("*")
        if star < 0:
            return "ERR NOCRC every command needs its CRC-8 suffix"
        given = text[star + 1 :]
        if len(given) != 2 or any(c not in "0123456789ABCDEFabcdef" for c in given):
            return "ERR CHECKSUM bad checksum"
        if int(given, 16) != int(checksum(line[:star]), 16):
            return "ERR CHECKSUM bad checksum"
        text = text[:star]
        if not text:
            return None
        tokens = text.split(" ")
        bad = any(t == "" for t in tokens)
        args: list[int] = []
        for tok in tokens[1 : 1 + self.max_args]:
            if bad:
                break
            digits = tok[1:] if tok.startswith("-") else tok
            if not digits or not digits.isascii() or not digits.isdigit():
                bad = True
                break
            v = int(tok)
            args.append(max(-INT32_MAX - 1, min(INT32_MAX, v)))
        nargs = len(tokens) - 1
        if nargs > self.max_args:
            args.extend([0] * (nargs - self.max_args))
        return _Command(tokens[0], args if not bad else [0] * nargs, bad)

    def _line(self, line: bytes) -> None:
        parsed = self._parse(line)
        if parsed is None:
            return
        if isinstance(parsed, str):
            self.send(parsed)
            return
        self.received.append(" ".join([parsed.word, *map(str, parsed.args)]))
        if parsed.word == "PING":
            self.send(self._arg_error(parsed, 0) or f"PONG {self.kind} {self.version_token()}")
            return
        handler = getattr(self, f"cmd_{parsed.word}", None) if parsed.word.isupper() else None
        if handler is None:
            self.send("ERR UNKNOWN command")
            return
        self.send(handler(parsed))

    @staticmethod
    def _arg_error(cmd: _Command, n: int) -> str | None:
        """``ERR ARG`` with the firmware's text unless the command has exactly ``n`` integer arguments."""
        if cmd.bad or len(cmd.args) != n:
            if n == 0:
                return f"ERR ARG {cmd.word} takes no argument"
            return f"ERR ARG {cmd.word} needs {n} integer{'s' if n != 1 else ''}"
        return None

    def _refusal(self, cmd: _Command, n: int, running: bool = False) -> str | None:
        """The firmware's refusals in its order, or None: ``ERR ARG``, ``ERR STATE running``, ``streaming``.

        ``ERR STATE running`` only if ``running`` is asked for (the commands that start something).
        """
        if err := self._arg_error(cmd, n):
            return err
        if running and self.running:
            return "ERR STATE running"
        if self.stream is not None:
            return "ERR STATE streaming"
        return None

    def version_token(self) -> str:
        """``<version>+<rig hash>`` of ``HELLO``/``PONG``: the build's."""
        return board_version(self.rig_hash)

    # --- lifecycle ----------------------------------------------------------------------------------
    def reset(self) -> None:
        """Reboot: forget the state, send ``HELLO``."""
        self.resets += 1
        self._inbuf.clear()
        self._overflow = False
        self._cr = False
        self.hung = False
        self.send(f"HELLO {self.kind} {self.version_token()}")


class DaqEmulator(EmulatedBoard):
    """The DAQ board (Arduino Mega 2560): every load cell through its sensor, every axis's step count."""

    kind = "daq"

    def __init__(self, world: Any, limits: BuildLimits, faults: Faults | None = None) -> None:
        super().__init__(world, limits, faults)
        self.rate = limits.rate_default_hz
        self.streaming = False
        self.step_counts = np.zeros(limits.axes, dtype=np.int64)
        self.n_sent = 0
        self._next_slot = 0
        self._t_start = 0.0
        self._pending_overrun = 0
        self.converting: dict[str, np.ndarray] | None = None
        """The samples whose channel 0 was read but not yet their last (the world keeps them here)."""

    def reset(self) -> None:  # noqa: D102
        self.rate = self.limits.rate_default_hz
        self.streaming = False
        self.step_counts = np.zeros(self.limits.axes, dtype=np.int64)
        self.n_sent = 0
        self.converting = None
        super().reset()

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

    def cmd_CONFIG(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        lim = self.limits
        return f"OK CONFIG {lim.channels} {lim.axes} {lim.rate_min_hz} {lim.rate_max_hz}"

    def cmd_ZERO(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        self.step_counts[:] = 0
        return "OK ZERO"

    def cmd_START(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        if self.streaming:
            return "ERR STATE streaming"
        self.streaming = True
        self.n_sent = 0
        self._next_slot = 1
        self._t_start = self.world.t
        self._pending_overrun = 0
        self.converting = None
        return f"OK START {self.rate}"

    def cmd_STOP(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        n = self.n_sent if self.streaming else 0
        if self.streaming and self._pending_overrun:  # a missed period is never dropped silently
            self.send(f"W,OVERRUN,{self._pending_overrun}")
            self._pending_overrun = 0
        self.streaming = False
        self.converting = None  # a sample still converting is not taken (the firmware sends it)
        return f"OK STOP {n}"

    def sample_slots(self, t0: float, t1: float) -> np.ndarray:
        """Slot numbers k (sample at ``t_start + k / rate``) not yet sent, with time <= t1."""
        if not self.streaming or self.hung or self.disconnected:
            return np.zeros(0, dtype=np.int64)
        period = 1.0 / self.rate
        k_last = math.floor((t1 - self._t_start) / period + 1e-9)
        if k_last < self._next_slot:
            return np.zeros(0, dtype=np.int64)
        return np.arange(self._next_slot, k_last + 1, dtype=np.int64)

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

    def emit_samples(
        self, slots: np.ndarray, times: np.ndarray, counts: np.ndarray, steps: np.ndarray
    ) -> None:
        """Queue the data lines of the given slots (with overruns and transport faults applied)."""
        if len(slots) == 0:
            return
        self._next_slot = int(slots[-1]) + 1
        f = self.faults
        t_us = (np.rint(times * 1e6).astype(np.int64) + self.world.t0_us) % WRAP_US
        rng = self._rng
        transport = f.drop > 0 or f.corrupt > 0 or f.garbage > 0
        late = np.zeros(len(slots), dtype=bool)  # the periods the board misses (not sampled, no seq)
        if f.overrun_every:
            late = slots % f.overrun_every == 0
        fields = np.column_stack([np.zeros(len(slots), dtype=np.int64), t_us, counts, steps])[~late]
        fields[:, 0] = np.arange(self.n_sent, self.n_sent + len(fields))
        block = frame_data_lines(fields)  # every data line, framed at once
        self.n_sent += len(fields)
        if not (transport or f.overrun_every or self._pending_overrun):  # the common case
            if not (self.hung or self.disconnected):
                self.out.append(block)
            return
        framed = iter(block.splitlines(keepends=True))
        lines = []
        for i in range(len(slots)):
            if late[i]:
                self._pending_overrun += 1
                self.injected["overrun_periods"] += 1
                continue
            if self._pending_overrun:
                lines.append(frame(f"W,OVERRUN,{self._pending_overrun}"))
                self._pending_overrun = 0
            line = next(framed)
            if transport:
                if f.garbage and rng.random() < f.garbage:
                    junk = bytes(rng.integers(0, 256, size=int(rng.integers(1, 40)), dtype=np.uint8))
                    lines.append(junk.replace(b"\n", b"?").replace(b"\r", b"?") + b"\n")
                    self.injected["garbage"] += 1
                if f.drop and rng.random() < f.drop:
                    self.injected["dropped"] += 1
                    continue
                if f.corrupt and rng.random() < f.corrupt:
                    line = _damaged(line, rng)
                    self.injected["corrupted"] += 1
            lines.append(line)
        if not (self.hung or self.disconnected):
            self.out.extend(lines)


@dataclass
class _Item:
    """One programme item: every axis's signed steps in a window (us), or a dwell (``steps`` None)."""

    window_us: int
    steps: tuple[int, ...] | None

    def step_times_us(self, axis: int) -> np.ndarray:
        """Axis ``axis``'s step instants from the item's start, us (on the firmware's 0.5 us ticks)."""
        n = abs(self.steps[axis]) if self.steps else 0
        k = np.arange(1, n + 1, dtype=np.int64)
        return -(-k * (2 * self.window_us) // max(n, 1)) / 2.0


_NO_STEPS = (np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))


class StepperEmulator(EmulatedBoard):
    """The stepper board (Arduino Uno + TB6600 per axis), in device time (see the module's docstring)."""

    kind = "stepper"

    def __init__(self, world: Any, limits: BuildLimits, faults: Faults | None = None) -> None:
        super().__init__(world, limits, faults)
        self.items: list[_Item] = []
        self.enabled = False
        self.positions = [0] * limits.axes
        """Every axis's step count (the board's position)."""
        self.running = False
        self._step_times, self._step_axes, self._step_signs = _NO_STEPS
        self._next = 0
        self._end_t = 0.0
        self.stream_max_delay_us = MAX_DELAY_US_AXES if limits.axes > 1 else MAX_DELAY_US
        """The longest shaper delay ``IMP`` accepts (1 s on a one-axis build, 0.62 s on one of several)."""
        self.shaper = ShaperLoader(self.stream_max_delay_us)
        self.stream: StreamMode | None = None
        """The stream in progress (None when not streaming)."""

    @property
    def position(self) -> int:
        """Axis 0's step count."""
        return self.positions[0]

    def reset(self) -> None:  # noqa: D102
        self._stop()
        self.items = []
        self.enabled = False
        self.positions = [0] * self.limits.axes
        self.shaper = ShaperLoader(self.stream_max_delay_us)
        super().reset()

    def _stop(self) -> None:
        self.running = False
        self._step_times, self._step_axes, self._step_signs = _NO_STEPS
        self._next = 0
        self.stream = None

    def _positions(self, word: str) -> str:
        return f"{word} " + " ".join(map(str, self.positions))

    # --- the programme ------------------------------------------------------------------------------
    def _locked(self) -> str | None:
        """The firmware's ``editable()``: no programme edit while it runs or a stream holds its table."""
        if self.running:
            return "ERR STATE running"
        if self.stream is not None and self.limits.axes > 1:
            return "ERR STATE streaming"
        return None

    def _add(self, item: _Item) -> str | None:
        if len(self.items) >= self.limits.programme_max:
            return f"ERR FULL {self.limits.programme_max} items"
        self.items.append(item)
        return None

    def cmd_CLEAR(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0) or self._locked():
            return err
        self.items = []
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
        return self._add(_Item(n * iv, steps)) or f"OK SEG {len(self.items)}"

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
        return self._add(_Item(window, tuple(ns))) or f"OK MSEG {len(self.items)}"

    def cmd_WAIT(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 1) or self._locked():
            return err
        if not 0 <= cmd.args[0] <= self.limits.max_dwell_ms:
            return f"ERR RANGE dwell 0-{self.limits.max_dwell_ms} ms"
        return self._add(_Item(1000 * cmd.args[0], None)) or f"OK WAIT {len(self.items)}"

    def cmd_CONFIG(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        lim = self.limits
        travel = " ".join(map(str, lim.travel_steps + lim.release_steps))  # releases only when built with
        return (
            f"OK CONFIG {lim.axes} {lim.programme_max} {lim.min_interval_us} {lim.max_interval_us} {travel}"
        )

    def cmd_GO(self, cmd: _Command) -> str:  # noqa: N802, D102
        # the refusals in the firmware's order: arguments, running, streaming, empty, disabled, travel
        if err := self._refusal(cmd, 0, running=True):
            return err
        if not self.items:
            return "ERR STATE programme empty"
        if not self.enabled:
            return "ERR STATE driver disabled"
        lim = self.limits
        for a, (travel, release) in enumerate(zip(lim.travel_steps, lim.releases, strict=True)):
            pos = self.positions[a]  # the firmware checks axis by axis
            for it in self.items:
                pos += it.steps[a] if it.steps else 0
                if not -release <= pos <= travel:
                    where = f"axis {a} " if lim.axes > 1 else ""
                    return f"ERR RANGE {where}travel {lim.travel_text(a)} steps"
        times, axes, signs, t0_us = [], [], [], 0.0
        for it in self.items:
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
            self._step_times, self._step_axes, self._step_signs = _NO_STEPS
        self._next = 0
        self._end_t = go + t0_us * 1e-6
        self.running = True
        self.world.go_times.append(go)
        return f"OK GO {len(self.items)}"

    def cmd_ABORT(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        self._stop()
        self.enabled = False
        return self._positions("ABORTED")

    def cmd_EN(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 1):
            return err
        if cmd.args[0] not in (0, 1):
            return "ERR RANGE EN 0 or 1"
        if cmd.args[0] == 0:
            self._stop()
        self.enabled = bool(cmd.args[0])
        return f"OK EN {cmd.args[0]}"

    def cmd_POS(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        return self._positions("OK POS")

    def cmd_MEM(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        return f"OK MEM {MEM_FREE_BYTES}"

    # --- streaming (PROTOCOL.md "Stepper board: streaming mode") -----------------------------------
    def cmd_SHAPER(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._refusal(cmd, 2):
            return err
        return self.shaper.begin(*cmd.args)

    def cmd_IMP(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._refusal(cmd, 3):
            return err
        return self.shaper.impulse(*cmd.args)

    def cmd_STREAM(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._refusal(cmd, 0, running=True):
            return err
        if self.shaper.ready is None:
            return "ERR STATE no shaper"
        if not self.enabled:
            return "ERR STATE driver disabled"
        lim = self.limits
        if lim.axes > 1:
            self.items = []  # the stream's state takes the programme table's RAM
        self.stream = StreamMode(self.shaper.ready, list(self.positions), lim.travel_steps, self.world.t,
                                 self.send, lim.releases, v_max(lim.min_interval_us))  # fmt: skip
        return f"OK STREAM {self.positions[0]}"

    def cmd_V(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 1):
            return err
        if self.stream is None:
            return "ERR STATE not streaming"
        return self.stream.setpoint(cmd.args[0])

    def cmd_MV(self, cmd: _Command) -> str:  # noqa: N802, D102
        # one axis (the paper's build): MV <v_0> is V <v_0>, answered OK MV
        axes = self.limits.axes
        if cmd.bad or len(cmd.args) != axes:
            return f"ERR ARG MV needs {axes} integer{'s' if axes > 1 else ''}"
        if self.stream is None:
            return "ERR STATE not streaming"
        return self.stream.setpoints(cmd.args)

    def cmd_END(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        if self.stream is None:
            return "ERR STATE not streaming"
        return self.stream.end()

    # --- device time --------------------------------------------------------------------------------
    def steps_until(self, t1: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Take the steps due at or before ``t1``: ``(times, axes, signs)`` (the positions updated).

        A programme's ``DONE`` is queued by the world (:meth:`finish_if_due`); a stream's control ticks run
        here, and its notices and ``DONE`` are queued at the tick that produces them.
        """
        if self.hung or self.disconnected:
            return _NO_STEPS
        stream = self.stream
        if stream is not None:
            times, axes, signs = stream.steps_until(t1)
        elif self.running:
            j = int(np.searchsorted(self._step_times, t1 + 1e-12, side="right"))
            sl = slice(self._next, j)
            times, axes, signs = self._step_times[sl], self._step_axes[sl], self._step_signs[sl]
            self._next = j
        else:
            return _NO_STEPS
        for a in range(self.limits.axes):
            self.positions[a] += int(signs[axes == a].sum())
        if stream is not None and stream.finished:
            if stream.session.watchdog:  # the watchdog's stream ends with the driver disabled
                self.enabled = False
            self.stream = None
            self.send(self._positions("DONE"))
        return times, axes, signs

    def next_event(self) -> float:
        """Device time of the next event (a programme's ``DONE``, a stream's control tick), or inf."""
        if self.stream is not None:
            return self.stream.next_tick
        return self._end_t if self.running else math.inf

    def finish_if_due(self, t1: float) -> None:
        """Send ``DONE <position> ...`` once the programme's last item has finished."""
        if self.running and self._end_t <= t1 + 1e-12:
            self.running = False
            self.send(self._positions("DONE"))
