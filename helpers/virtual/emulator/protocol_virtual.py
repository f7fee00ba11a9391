"""pyserial URL handler ``virtual://``: the emulated boards of the virtual rig, in-process.

A driver gives the world its rig as a value: it opens ``virtual://daq?world=<name>`` and
``virtual://stepper?world=<name>`` with ``serial.serial_for_url(url, do_not_open=True)``, sets ``port.rig =
rig`` (a :class:`helpers.rigfile.RigFile`), then calls ``port.open()``. The port finds, or builds
(:func:`helpers.virtual.emulator.world.build_world`), the world keyed by ``(name, rig.hash)``: one plant and
one device clock for both boards; the default name is the rig's name. So two rigs in one process are two
worlds. ``rig=<name>`` is the old spelling of ``world=<name>``; a port opened without ``port.rig`` finds the
one world of that name, or builds one of the paper's rig. Query options:

- ``seed`` (sensor noise and fault generators), ``t0_us`` (clock offset), ``load_n`` (VIRTUAL calibration
  fixture: a known load in N hung on the load cells) -- used when the world is created;
- ``reset_on_open`` (default 1: opening the port reboots the board and it sends ``HELLO``, as an Arduino does
  when DTR toggles; 0 keeps it running, like a board without auto-reset);
- faults of this board (:class:`helpers.virtual.emulator.boards.Faults`): ``drop``, ``corrupt``, ``garbage``
  (probabilities per data line), ``drop_replies``, ``corrupt_replies`` (per other line), ``reset_at``,
  ``hang_at``, ``disconnect_at`` (device seconds after the port is opened), ``overrun_every`` (samples).

pyserial finds this handler when ``"helpers.virtual.emulator"`` is in ``serial.protocol_handler_packages``;
:func:`helpers.rig.link.open_port` adds it when it opens a ``virtual://`` URL (not as an import side
effect). Device time runs as fast as the reader consumes it: a read waits, in device time, at most
the port's timeout, so a read that finds nothing advances the clock by the timeout (or to the next event such
as ``DONE``); a read of a streaming DAQ generates samples chunk by chunk until it has the bytes it asked for.
"""

from __future__ import annotations

import math
import urllib.parse
from typing import Any

from serial.serialutil import PortNotOpenError, SerialBase, SerialException

from helpers.virtual.emulator.boards import FAULT_OPTIONS, Disconnected, Faults
from helpers.virtual.emulator.world import VirtualWorld, get_world

_WORLD_OPTIONS = ("seed", "t0_us", "load_n")
_PORT_OPTIONS = ("world", "rig", "reset_on_open")


class Serial(SerialBase):
    """A pyserial port connected to one emulated board of a virtual rig."""

    BAUDRATES = (9600, 19200, 38400, 57600, 115200, 230400, 250000, 500000, 1000000)

    def __init__(self, *args, **kwargs) -> None:
        self.rig: Any = None
        """The rig file (:class:`helpers.rigfile.RigFile`) whose world to open: set it before :meth:`open`."""
        self.world: VirtualWorld | None = None
        self.board = None
        self._rx = bytearray()
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        """Connect to the board named in the URL (building the world on first use)."""
        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        kind, options = self.from_url(self._port)
        world_options = {k: options[k] for k in _WORLD_OPTIONS if k in options}
        name = options.get("world", options.get("rig"))
        try:
            self.world = get_world(name, self.rig, world_options)
        except ValueError as exc:
            raise SerialException(f"virtual://{kind}: {exc}") from None
        board = self.world.daq if kind == "daq" else self.world.stepper
        holder = getattr(board, "port", None)
        if holder is not None and holder is not self and holder.is_open:
            raise SerialException(f"port busy: virtual://{kind}?world={self.world.name} is open elsewhere")
        board.port = self
        self.board = board
        faults = {k: options[k] for k in FAULT_OPTIONS if k in options}
        if faults:
            self.board.faults = Faults.from_options(faults)
            for name in ("reset_at", "hang_at", "disconnect_at"):  # relative to now
                at = getattr(self.board.faults, name)
                if at is not None:
                    setattr(self.board.faults, name, self.world.t + at)
        self.board.disconnected = False
        self._rx.clear()
        self.is_open = True
        if options.get("reset_on_open", "1") != "0":
            self.board.out.clear()
            self.board.reset()

    def from_url(self, url: str) -> tuple[str, dict[str, str]]:
        """Parse ``virtual://daq|stepper?option=value&...``."""
        parts = urllib.parse.urlsplit(url)
        if parts.scheme != "virtual":
            raise SerialException(f"expected a URL of the form virtual://daq?world=NAME, got {url!r}")
        kind = parts.netloc or parts.path.strip("/")
        if kind not in ("daq", "stepper"):
            raise SerialException(f"virtual board must be 'daq' or 'stepper', got {kind!r} in {url!r}")
        options = dict(urllib.parse.parse_qsl(parts.query, keep_blank_values=True))
        unknown = set(options) - set(_WORLD_OPTIONS) - set(_PORT_OPTIONS) - set(FAULT_OPTIONS)
        if unknown:
            raise SerialException(f"unknown option(s) {sorted(unknown)} in {url!r}")
        return kind, options

    def close(self) -> None:
        """Close the port (the world and the board keep running)."""
        self.is_open = False
        self._rx.clear()
        if self.board is not None and getattr(self.board, "port", None) is self:
            self.board.port = None

    def _reconfigure_port(self) -> None:
        pass

    def _check(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()

    def _disconnected(self) -> SerialException:
        self.is_open = False
        return SerialException(
            "device reports readiness to read but returned no data "
            "(device disconnected or multiple access on port?)"
        )

    def device_time(self) -> float:
        """The rig's device clock (s): what the host's timeouts count on this port (``rig.boards.Waiter``)."""
        return self.world.t if self.world is not None else 0.0

    def twin_tip_um(self, t_us: Any) -> Any:
        """The twin's tip (integer micrometres, clamp frame) at the samples with these ``t_us``, or None.

        Where the plant provides it (the spatial twin): what a recording's optional tip columns hold.
        """
        return self.world.tip_um(t_us) if self.world is not None else None

    @property
    def in_waiting(self) -> int:
        """Bytes available now (does not move device time)."""
        self._check()
        if self.board.disconnected:
            raise self._disconnected()
        return len(self._rx) + self.board.pending_bytes

    def read(self, size: int = 1) -> bytes:
        """Read up to ``size`` bytes, waiting at most ``timeout`` seconds of device time."""
        self._check()
        world, board = self.world, self.board
        deadline = world.t + (self._timeout if self._timeout is not None else math.inf)
        try:
            while True:
                if len(self._rx) < size:
                    self._rx += board.take_output(max(size - len(self._rx), 1))
                if len(self._rx) >= size or world.t >= deadline - 1e-12:
                    break
                streaming = world.daq.streaming and not (world.daq.hung or world.daq.disconnected)
                if board is world.daq and streaming:
                    t_next = min(deadline, world.t + world.chunk_s)
                else:
                    t_next = min(deadline, world.next_event())
                    if streaming:
                        t_next = min(t_next, world.t + 10 * world.chunk_s)
                if not math.isfinite(t_next):
                    break  # blocking read with nothing ever to come: do not hang the caller
                world.advance_to(t_next)
        except Disconnected:
            raise self._disconnected() from None
        data = bytes(self._rx[:size])
        del self._rx[:size]
        return data

    def write(self, data: bytes) -> int:
        """Deliver ``data`` to the board (executed at the present device time)."""
        self._check()
        try:
            self.board.receive(bytes(data))
        except Disconnected:
            raise self._disconnected() from None
        return len(data)

    def reset_input_buffer(self) -> None:
        """Discard bytes received but not read."""
        self._check()
        self._rx.clear()
        self.board.out.clear()

    def reset_output_buffer(self) -> None:
        """Nothing is buffered on the way out."""
        self._check()

    @property
    def out_waiting(self) -> int:
        """Always 0: writes are delivered at once."""
        return 0

    def _update_break_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass

    def _update_dtr_state(self) -> None:
        pass

    @property
    def cts(self) -> bool:  # noqa: D102
        return True

    @property
    def dsr(self) -> bool:  # noqa: D102
        return True

    @property
    def ri(self) -> bool:  # noqa: D102
        return False

    @property
    def cd(self) -> bool:  # noqa: D102
        return True
