"""Emulated DAQ and stepper boards: Python objects that behave exactly as the firmware does on the protocol.

The boards follow ``firmware/PROTOCOL.md``: the same replies, error codes, limits
(:mod:`helpers.paper.hardware`),
``HELLO`` on reset, ``W,OVERRUN`` reporting, CRC-8 checksums and version
(:data:`helpers.board.protocol.FW_VERSION`, :func:`board_version`). They live in a
:class:`helpers.virtual.emulator.world.VirtualWorld`, which owns
the device clock and the plant; a board sees the world only through the attributes it reads (``t``, ``seed``,
``t0_us``, ``go_times``).

Fault injection (per board, for tests): ``drop`` / ``corrupt`` / ``garbage`` probabilities per data line,
``reset_at`` (the board reboots and sends ``HELLO``), ``hang_at`` (the board stops answering),
``disconnect_at`` (the port disappears), ``overrun_every`` (the DAQ misses one sample period every n samples
and reports it). Everything emitted here is simulation; recordings made from it say ``virtual-rig``.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from helpers.board.protocol import FW_VERSION, MAX_LINE, WRAP_US, checksum, frame
from helpers.board.stream_reference import MAX_DELAY_US
from helpers.paper.hardware import DAQ_RATE_DEFAULT_HZ, DAQ_RATE_MAX_HZ, DAQ_RATE_MIN_HZ, LIMITS, RIG
from helpers.virtual.emulator.framing import frame_many
from helpers.virtual.emulator.stream_mode import ShaperLoader, StreamMode

DAQ_RATE_MIN, DAQ_RATE_MAX, DAQ_RATE_DEFAULT = DAQ_RATE_MIN_HZ, DAQ_RATE_MAX_HZ, DAQ_RATE_DEFAULT_HZ
MIN_INTERVAL_US = LIMITS.min_interval_us
MAX_INTERVAL_US = LIMITS.max_interval_us
MAX_TRAVEL_STEPS = LIMITS.max_position_steps
MAX_ITEMS = LIMITS.max_items
MAX_DWELL_MS = LIMITS.max_dwell_ms
INT32_MAX = 2**31 - 1
MEM_FREE_BYTES = 560
"""What the emulated stepper answers to ``MEM``: the least free stack measured for the firmware in simavr
(``firmware/README.md``); the emulated board has no stack of its own."""


def board_version(rig_hash: str | None = None) -> str:
    """The version token of ``HELLO``/``PONG``: ``<FW_VERSION>+<rig hash>`` (semantic-version build metadata).

    Parameters
    ----------
    rig_hash : str, optional
        The 8 hex characters of the rig the board was built for; by default the rig the host runs
        (``helpers.paper.hardware.RIG``, the emulated boards' build).

    Returns
    -------
    str
        E.g. ``"2.3.0+481e87e3"``.
    """
    return f"{FW_VERSION}+{RIG.hash if rig_hash is None else rig_hash}"


class Plant(Protocol):
    """What the boards need from a plant (``helpers.virtual.ArmPlant`` or a test double)."""

    t: float

    def advance(self, sample_times: np.ndarray, step_times: np.ndarray, step_signs: np.ndarray) -> np.ndarray:
        """Integrate to ``sample_times[-1]``; return the cable tension (N) at the sample instants."""
        ...


class Sensor(Protocol):
    """What the DAQ needs from the sensor model (``helpers.virtual.LoadCell``)."""

    def counts(self, tension: np.ndarray) -> np.ndarray:
        """Return 10-bit ADC counts for tensions in N."""
        ...

    def reseed(self, seed: int) -> None:
        """Restart the noise from ``seed``."""
        ...


@dataclass
class Faults:
    """Fault injection settings of one emulated board (all off by default).

    Attributes
    ----------
    drop, corrupt, garbage : float
        Probability per data line that it is lost in transport, has one byte altered, or is preceded by a line
        of random garbage bytes.
    reset_at, hang_at, disconnect_at : float or None
        Device time (s) at which the board reboots (``HELLO``), stops answering, or its port vanishes.
    overrun_every : int
        Every n-th sample period the DAQ is late: the sample is not taken and ``W,OVERRUN,1`` is sent.
    """

    drop: float = 0.0
    corrupt: float = 0.0
    garbage: float = 0.0
    reset_at: float | None = None
    hang_at: float | None = None
    disconnect_at: float | None = None
    overrun_every: int = 0

    @classmethod
    def from_options(cls, options: dict[str, str]) -> Faults:
        """Build from URL query options (unknown keys are ignored here)."""
        kw: dict[str, Any] = {}
        for name in ("drop", "corrupt", "garbage"):
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


class Disconnected(Exception):
    """The emulated port vanished (fault ``disconnect_at``); the URL handler turns it into SerialException."""


@dataclass
class _Command:
    word: str
    args: list[int]
    bad: bool


class EmulatedBoard:
    """Line handling shared by both boards: framing, checksums, ``TOOLONG``, faults, the output queue."""

    kind = "board"
    max_args = 3
    """Arguments parsed per command (the firmware's ``PROTO_MAX_ARGS``: 3, or 1 + the axes of a build)."""
    rig_hash: str | None = None
    """The rig hash of the build the board emulates (None: the rig the host runs)."""

    def __init__(self, world: Any, faults: Faults | None = None) -> None:
        self.world = world
        self.faults = faults or Faults()
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
        self.port: Any = None
        """The pyserial port that has this board open (one at a time), or None."""

    # --- output -------------------------------------------------------------------------------------
    def send(self, body: str) -> None:
        """Queue one line (silently lost if the board hangs or is disconnected)."""
        if not (self.hung or self.disconnected):
            self.out.append(frame(body))

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

    def version_token(self) -> str:
        """``<version>+<rig hash>`` of ``HELLO``/``PONG`` (the build's hash, else the host's rig's)."""
        return board_version() if self.rig_hash is None else board_version(self.rig_hash)

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
    """The DAQ board (Arduino Mega 2560): samples the tension through the sensor and counts the steps."""

    kind = "daq"

    def __init__(self, world: Any, faults: Faults | None = None) -> None:
        super().__init__(world, faults)
        self.rate = DAQ_RATE_DEFAULT
        self.streaming = False
        self.step_count = 0
        self.n_sent = 0
        self._next_slot = 0
        self._t_start = 0.0
        self._pending_overrun = 0
        self.injected = {"dropped": 0, "corrupted": 0, "garbage": 0, "overrun_periods": 0}
        """Faults injected so far (tests compare the host's counts with these)."""

    def reset(self) -> None:  # noqa: D102
        self.rate = DAQ_RATE_DEFAULT
        self.streaming = False
        self.step_count = 0
        self.n_sent = 0
        super().reset()

    def cmd_RATE(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 1):
            return err
        if self.streaming:
            return "ERR STATE streaming"
        if not DAQ_RATE_MIN <= cmd.args[0] <= DAQ_RATE_MAX:
            return f"ERR RANGE rate {DAQ_RATE_MIN}-{DAQ_RATE_MAX} Hz"
        self.rate = cmd.args[0]
        return f"OK RATE {self.rate}"

    def cmd_CONFIG(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        return f"OK CONFIG 1 1 {DAQ_RATE_MIN} {DAQ_RATE_MAX}"

    def cmd_ZERO(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        self.step_count = 0
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
        return f"OK START {self.rate}"

    def cmd_STOP(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        n = self.n_sent if self.streaming else 0
        if self.streaming and self._pending_overrun:  # a missed period is never dropped silently
            self.send(f"W,OVERRUN,{self._pending_overrun}")
            self._pending_overrun = 0
        self.streaming = False
        return f"OK STOP {n}"

    def sample_slots(self, t0: float, t1: float) -> np.ndarray:
        """Slot numbers k (sample at ``t_start + k / rate``) with t0 < time <= t1."""
        if not self.streaming or self.hung or self.disconnected:
            return np.zeros(0, dtype=np.int64)
        period = 1.0 / self.rate
        k_last = math.floor((t1 - self._t_start) / period + 1e-9)
        if k_last < self._next_slot:
            return np.zeros(0, dtype=np.int64)
        return np.arange(self._next_slot, k_last + 1, dtype=np.int64)

    @staticmethod
    def payload(counts: np.ndarray, steps: np.ndarray) -> list[str]:
        """The fields after ``t_us`` of each data line: ``<adc>,<steps>`` (one channel, one axis)."""
        return [f"{c},{s}" for c, s in zip(counts.tolist(), steps.tolist(), strict=True)]

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
        payload = self.payload(counts, steps)
        if not (transport or f.overrun_every or self._pending_overrun):  # the common case, vectorised
            seq0 = self.n_sent
            seqs = range(seq0, seq0 + len(slots))
            columns = zip(seqs, t_us.tolist(), payload, strict=True)
            bodies = [f"D,{a},{b},{c}" for a, b, c in columns]
            self.n_sent = seq0 + len(slots)
            if not (self.hung or self.disconnected):
                self.out.append(frame_many(bodies))
            return
        lines = []
        seq = self.n_sent
        for i in range(len(slots)):
            if f.overrun_every and int(slots[i]) % f.overrun_every == 0:
                self._pending_overrun += 1
                self.injected["overrun_periods"] += 1
                continue
            if self._pending_overrun:
                lines.append(frame(f"W,OVERRUN,{self._pending_overrun}"))
                self._pending_overrun = 0
            body = f"D,{seq},{t_us[i]},{payload[i]}"
            seq += 1
            if transport:
                if f.garbage and rng.random() < f.garbage:
                    junk = bytes(rng.integers(0, 256, size=int(rng.integers(1, 40)), dtype=np.uint8))
                    lines.append(junk.replace(b"\n", b"?").replace(b"\r", b"?") + b"\n")
                    self.injected["garbage"] += 1
                if f.drop and rng.random() < f.drop:
                    self.injected["dropped"] += 1
                    continue
                line = frame(body)
                if f.corrupt and rng.random() < f.corrupt:
                    pos = int(rng.integers(0, len(line) - 1))
                    b = bytearray(line)
                    new = b[pos]
                    while new in (b[pos], 0x0A, 0x0D):
                        new = int(rng.integers(32, 127))
                    b[pos] = new
                    line = bytes(b)
                    self.injected["corrupted"] += 1
                lines.append(line)
            else:
                lines.append(frame(body))
        self.n_sent = seq
        if not (self.hung or self.disconnected):
            self.out.extend(lines)


@dataclass
class _Item:
    direction: int
    n_steps: int
    interval_us: int
    dwell_ms: int = -1
    window_us: int = -1
    """``MSEG``: the window in which the ``n_steps`` are spread (step k on tick ``ceil(k * 2 W / n)``)."""

    @property
    def duration_us(self) -> float:
        if self.window_us >= 0:
            return self.window_us
        return self.dwell_ms * 1000 if self.dwell_ms >= 0 else self.n_steps * self.interval_us

    def step_times_us(self) -> np.ndarray:
        """The item's step instants from its start (us; ``MSEG`` on the firmware's 0.5 us ticks)."""
        k = np.arange(1, self.n_steps + 1, dtype=np.int64)
        if self.window_us >= 0:
            return -(-k * (2 * self.window_us) // self.n_steps) / 2.0
        return self.interval_us * k


class StepperEmulator(EmulatedBoard):
    """The stepper board (Arduino Uno + TB6600), in device time.

    It runs a programme of up to 64 items, or a stream of set-points shaped by a loaded shaper
    (:mod:`helpers.virtual.emulator.stream_mode`).
    """

    kind = "stepper"
    stream_max_delay_us = MAX_DELAY_US
    """The longest shaper delay ``IMP`` accepts (1 s on a one-axis build)."""

    def __init__(self, world: Any, faults: Faults | None = None) -> None:
        super().__init__(world, faults)
        self.items: list[_Item] = []
        self.enabled = False
        self.position = 0
        self.running = False
        self._step_times = np.zeros(0)
        self._step_signs = np.zeros(0, dtype=np.int64)
        self._next = 0
        self._end_t = 0.0
        self.shaper = ShaperLoader(self.stream_max_delay_us)
        self.stream: StreamMode | None = None
        """The stream in progress (None when not streaming)."""

    def reset(self) -> None:  # noqa: D102
        self._stop()
        self.items = []
        self.enabled = False
        self.position = 0
        self.shaper = ShaperLoader(self.stream_max_delay_us)
        super().reset()

    def _stop(self) -> None:
        self.running = False
        self._step_times = np.zeros(0)
        self._step_signs = np.zeros(0, dtype=np.int64)
        self._next = 0
        self.stream = None

    def cmd_CLEAR(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        if self.running:
            return "ERR STATE running"
        self.items = []
        return "OK CLEAR"

    def cmd_SEG(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 3):
            return err
        if self.running:
            return "ERR STATE running"
        d, n, iv = cmd.args
        if d not in (1, -1):
            return "ERR RANGE dir must be 1 or -1"
        if not 1 <= n <= MAX_TRAVEL_STEPS:
            return f"ERR RANGE n_steps 1-{MAX_TRAVEL_STEPS}"
        if not MIN_INTERVAL_US <= iv <= MAX_INTERVAL_US:
            return f"ERR RANGE interval {MIN_INTERVAL_US}-{MAX_INTERVAL_US} us"
        if len(self.items) >= MAX_ITEMS:
            return f"ERR FULL {MAX_ITEMS} items"
        self.items.append(_Item(d, n, iv))
        return f"OK SEG {len(self.items)}"

    def cmd_MSEG(self, cmd: _Command) -> str:  # noqa: N802, D102
        # one axis (the paper's build): MSEG <window_us> <n_0>
        if err := self._arg_error(cmd, 2):
            return err
        if self.running:
            return "ERR STATE running"
        window, n = cmd.args
        if not 1 <= window <= 255 * MAX_INTERVAL_US:
            return f"ERR RANGE window 1-{255 * MAX_INTERVAL_US} us"
        if not -MAX_TRAVEL_STEPS <= n <= MAX_TRAVEL_STEPS:
            return f"ERR RANGE axis 0 steps -{MAX_TRAVEL_STEPS}..{MAX_TRAVEL_STEPS}"
        if n and not abs(n) * MIN_INTERVAL_US <= window <= abs(n) * MAX_INTERVAL_US:
            return f"ERR RANGE axis 0 interval {MIN_INTERVAL_US}-{MAX_INTERVAL_US} us"
        if n == 0:
            return "ERR RANGE no axis moves (a dwell is WAIT)"
        if len(self.items) >= MAX_ITEMS:
            return f"ERR FULL {MAX_ITEMS} items"
        self.items.append(_Item(1 if n > 0 else -1, abs(n), 0, window_us=window))
        return f"OK MSEG {len(self.items)}"

    def cmd_CONFIG(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        return f"OK CONFIG 1 {MAX_ITEMS} {MIN_INTERVAL_US} {MAX_INTERVAL_US} {MAX_TRAVEL_STEPS}"

    def cmd_WAIT(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 1):
            return err
        if self.running:
            return "ERR STATE running"
        if not 0 <= cmd.args[0] <= MAX_DWELL_MS:
            return f"ERR RANGE dwell 0-{MAX_DWELL_MS} ms"
        if len(self.items) >= MAX_ITEMS:
            return f"ERR FULL {MAX_ITEMS} items"
        self.items.append(_Item(0, 0, 0, cmd.args[0]))
        return f"OK WAIT {len(self.items)}"

    def _go_refusal(self, cmd: _Command, has_programme: bool) -> str | None:
        """``GO``'s refusals in the firmware's order (arguments, running, streaming, empty, disabled)."""
        if err := self._arg_error(cmd, 0):
            return err
        if self.running:
            return "ERR STATE running"
        if self.stream is not None:
            return "ERR STATE streaming"
        if not has_programme:
            return "ERR STATE programme empty"
        if not self.enabled:
            return "ERR STATE driver disabled"
        return None

    def cmd_GO(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._go_refusal(cmd, bool(self.items)):
            return err
        pos, lo, hi = self.position, self.position, self.position
        for it in self.items:
            if it.dwell_ms < 0:
                pos += it.direction * it.n_steps
                lo, hi = min(lo, pos), max(hi, pos)
        if lo < 0 or hi > MAX_TRAVEL_STEPS:
            return f"ERR RANGE travel 0-{MAX_TRAVEL_STEPS} steps"
        times, signs, t0_us = [], [], 0
        for it in self.items:
            if it.dwell_ms < 0:
                times.append(t0_us + it.step_times_us())
                signs.append(np.full(it.n_steps, it.direction, dtype=np.int64))
            t0_us += it.duration_us
        go = self.world.t
        self._step_times = go + (np.concatenate(times) * 1e-6 if times else np.zeros(0))
        self._step_signs = np.concatenate(signs) if signs else np.zeros(0, dtype=np.int64)
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
        return f"ABORTED {self.position}"

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
        return f"OK POS {self.position}"

    def cmd_MEM(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        return f"OK MEM {MEM_FREE_BYTES}"

    # --- streaming (PROTOCOL.md "Stepper board: streaming mode") -----------------------------------
    def cmd_SHAPER(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 2):
            return err
        if self.stream is not None:
            return "ERR STATE streaming"
        return self.shaper.begin(*cmd.args)

    def cmd_IMP(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 3):
            return err
        if self.stream is not None:
            return "ERR STATE streaming"
        return self.shaper.impulse(*cmd.args)

    def cmd_STREAM(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 0):
            return err
        if self.running:
            return "ERR STATE running"
        if self.stream is not None:
            return "ERR STATE streaming"
        if self.shaper.ready is None:
            return "ERR STATE no shaper"
        if not self.enabled:
            return "ERR STATE driver disabled"
        self.stream = StreamMode(self.shaper.ready, self.position, self.world.t, self.send)
        return f"OK STREAM {self.position}"

    def cmd_V(self, cmd: _Command) -> str:  # noqa: N802, D102
        if err := self._arg_error(cmd, 1):
            return err
        if self.stream is None:
            return "ERR STATE not streaming"
        return self.stream.setpoint(cmd.args[0])

    def cmd_MV(self, cmd: _Command) -> str:  # noqa: N802, D102
        # one axis (the paper's build): MV <v_0> is V <v_0>, answered OK MV
        if err := self._arg_error(cmd, 1):
            return err
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
    def steps_until(self, t1: float) -> tuple[np.ndarray, np.ndarray]:
        """Take the steps due at or before ``t1`` (updating the position).

        A programme's ``DONE`` is queued by the world (:meth:`finish_if_due`); a stream's control ticks run
        here, and its notices and ``DONE`` are queued at the tick that produces them.
        """
        if self.hung or self.disconnected:
            return np.zeros(0), np.zeros(0, dtype=np.int64)
        if self.stream is not None:
            times, signs = self.stream.steps_until(t1)
            self.position += int(signs.sum())
            if self.stream.finished:
                if self.stream.session.watchdog:  # the watchdog's stream ends with the driver disabled
                    self.enabled = False
                self.stream = None
                self.send(f"DONE {self.position}")
            return times, signs
        if not self.running:
            return np.zeros(0), np.zeros(0, dtype=np.int64)
        j = int(np.searchsorted(self._step_times, t1 + 1e-12, side="right"))
        times = self._step_times[self._next : j]
        signs = self._step_signs[self._next : j]
        self._next = j
        self.position += int(signs.sum())
        return times, signs

    def next_event(self) -> float:
        """Device time of the next event (a programme's ``DONE``, a stream's control tick), or inf."""
        if self.stream is not None:
            return self.stream.next_tick
        return self._end_t if self.running else math.inf

    def finish_if_due(self, t1: float) -> None:
        """Send ``DONE <position>`` once the programme's last item has finished."""
        if self.running and self._end_t <= t1 + 1e-12:
            self.running = False
            self.send(f"DONE {self.position}")
