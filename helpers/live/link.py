"""One board over pyserial: open it exclusively, wait for it, send a command and take its reply; the errors.

Every line goes through a :class:`helpers.board.protocol.StreamParser`: data lines become samples
(``rows``), other lines messages: replies (``OK``, ``ERR``, ``PONG``, ``ABORTED``) answer the pending
command, ``DONE <position>`` is kept in ``done_position``, ``HELLO`` means the board rebooted (an error
unless it was expected).
A timeout is counted by :class:`Waiter`: in device time on the in-process virtual rig, else the larger of wall
time and the read timeouts that expired. Reading the port, resets and closing are :class:`PortLink`'s; the
full rig's link (:class:`helpers.rig.boards.BoardLink`) is built on it too and adds resending over a noisy
line and the bootloader's quiet time, with the same errors.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from contextlib import suppress
from typing import Any

import serial

from helpers.base.signals import signals_held
from helpers.board.protocol import PAPER_RIG_HASH, PROTOCOL_MAJOR, StreamParser, frame
from helpers.live.ports import open_port
from helpers.paper.hardware import MAX_STEP_RATE_HZ, RIG

REPLY_PREFIXES = ("OK", "ERR", "PONG", "ABORTED")

BOOT_TIMEOUT_S = 10.0
"""Seconds a board has to answer after its port opens (``HELLO``, or ``PONG`` to a ``PING``): an Arduino's
reset and bootloader take about 1.5-2 s, so five times that, for a slow USB hub or a busy host."""


class BoardError(RuntimeError):
    """A board misbehaved; the message names the board and what happened."""


class BoardTimeout(BoardError):
    """A board stopped answering within its timeout."""


class BoardReset(BoardError):
    """A board sent ``HELLO`` unexpectedly: it rebooted (power glitch, USB reset, watchdog)."""


class OldFirmware(BoardError):
    """The board runs firmware of another protocol MAJOR version (1.x: XOR checksums): flash this one."""


class BoardDisconnected(BoardError):
    """The serial port vanished (pyserial raised ``SerialException``)."""


class PortBusy(BoardError):
    """The port is open in another program (ports are opened exclusively)."""


class WrongRig(BoardError):
    """The board's firmware was built for another rig file than the one the host runs: rebuild it."""


class CommandRefused(BoardError):
    """A board answered ``ERR <code> <text>``."""

    def __init__(self, message: str, code: str) -> None:
        super().__init__(message)
        self.code = code


def check_firmware(kind: str, version: str, rig: Any = None) -> None:
    """Raise unless ``version`` is of this host's protocol MAJOR and the board was built for this host's rig.

    Raises
    ------
    OldFirmware
        The board speaks another protocol MAJOR version.
    WrongRig
        The version's build metadata (``+<rig hash>``) names another rig than the one the host runs
        (``rig``, default ``helpers.paper.hardware.RIG``). A version without it (firmware 2.0-2.1) is the
        paper's rig's.
    """
    rig = RIG if rig is None else rig
    if version.split(".")[0] != str(PROTOCOL_MAJOR):
        raise OldFirmware(
            f"the {kind} board runs firmware {version}; this host speaks protocol {PROTOCOL_MAJOR} "
            f"(firmware {PROTOCOL_MAJOR}.x, CRC-8 checksums): flash the firmware of this repository"
        )
    built_for = version.partition("+")[2] or PAPER_RIG_HASH
    if built_for != rig.hash:
        raise WrongRig(
            f"the {kind} board was built for rig {built_for}, but this host runs rig '{rig.name}' "
            f"({rig.source or 'rig file'}, hash {rig.hash}): rebuild and flash it with "
            f"make -C firmware RIG={rig.source or 'FILE'} upload-{kind} PORT=..."
        )


def expected_reply(command: str) -> str:
    """The start of the reply a command gets besides ``ERR``: ``PONG``, ``ABORTED`` or ``OK <WORD>``."""
    word = command.split(" ", 1)[0]
    return {"PING": "PONG", "ABORT": "ABORTED"}.get(word, f"OK {word}")


def open_exclusive(
    url: str, kind: str, baudrate: int, read_timeout: float, timeout: float
) -> serial.SerialBase:
    """Open a board's port (:func:`~helpers.live.ports.open_port`); a busy or missing one: one clear error."""
    try:
        return open_port(url, baudrate=baudrate, timeout=read_timeout, write_timeout=timeout)
    except serial.SerialException as exc:
        if "exclusive" in str(exc) or "busy" in str(exc):
            raise PortBusy(
                f"port busy: the {kind} board at {url} is open in another program (another recorder, "
                "notebook or serve-virtual-rig client); close it first"
            ) from exc
        raise BoardDisconnected(f"cannot open the {kind} board at {url}: {exc}") from exc


class Waiter:
    """Elapsed waiting time: the larger of wall time and the sum of read timeouts that expired.

    Given a device ``clock`` (the in-process virtual rig's :meth:`device_time`), the elapsed time is that
    clock's alone: the emulated boards' time moves only when the host reads, so wall time says nothing there.
    """

    def __init__(self, timeout: float, clock: Callable[[], float] | None = None) -> None:
        self.timeout = timeout
        self._clock = clock
        self._t0 = time.monotonic() if clock is None else clock()
        self._virtual = 0.0

    def idle(self, seconds: float) -> None:
        """Record a read that returned without data after waiting ``seconds``."""
        self._virtual += seconds

    @property
    def elapsed(self) -> float:
        """Seconds waited so far."""
        if self._clock is not None:
            return self._clock() - self._t0
        return max(time.monotonic() - self._t0, self._virtual)

    @property
    def expired(self) -> bool:
        """True once ``timeout`` has passed."""
        return self.elapsed >= self.timeout


class PortLink:
    """What both drivers' links do alike: read a board's port through its parser, see resets, close.

    A subclass sets ``port``, ``kind``, ``parser``, ``rows``, ``replies``, ``hello`` and ``done_position``
    (:class:`Link`; the full rig's :class:`helpers.rig.boards.BoardLink`), and may take other messages in
    :meth:`_message`.
    """

    def waiter(self, timeout: float) -> Waiter:
        """A :class:`Waiter` in device time on the in-process virtual rig, else in wall time."""
        return Waiter(timeout, getattr(self.port, "device_time", None))

    def read(self, wait: Waiter | None = None, block: bool = True) -> int:
        """Read what the port has (if ``block``, waiting up to its read timeout); return the bytes read.

        Raises :class:`OldFirmware` once the parser saw a line of a protocol-1 board (firmware 1.x: XOR).
        """
        try:
            n = self.port.in_waiting
            data = self.port.read(max(n, 1)) if n or block else b""
            data += self.port.read(self.port.in_waiting) if data and self.port.in_waiting else b""
        except (serial.SerialException, OSError) as exc:
            raise BoardDisconnected(f"{self.kind} board disconnected ({self.port.port}): {exc}") from exc
        if not data and wait is not None:
            wait.idle(self.port.timeout or 0.0)
        with signals_held():  # the parser's counts and the kept rows change together
            rows, messages = self.parser.feed(data)
            self.rows += rows
        if self.parser.legacy is not None:
            raise OldFirmware(
                f"the board on {self.port.port} runs firmware 1.x (protocol 1, XOR checksums; it sent "
                f"{self.parser.legacy!r}); this host speaks protocol {PROTOCOL_MAJOR} (CRC-8 checksums): "
                f"flash firmware {PROTOCOL_MAJOR}.x (make -C firmware upload-daq / upload-stepper PORT=...)"
            )
        for msg in messages:
            self._message(msg)
        return len(data)

    def _message(self, msg: str) -> None:
        """``HELLO`` counts a reset, ``DONE`` keeps its position, a reply waits for its command."""
        if msg.startswith("HELLO"):
            self.hello += 1
        elif msg.startswith("DONE"):
            self.done_position = int(msg.split()[-1]) if msg.split()[-1].lstrip("-").isdigit() else 0
        elif msg.startswith(REPLY_PREFIXES):
            self.replies.append(msg)

    def check_reset(self) -> None:
        """Raise :class:`BoardReset` if the board sent ``HELLO`` since it was synchronised."""
        if self.hello:
            raise BoardReset(f"the {self.kind} board reset (it sent HELLO): its state is lost")

    def close(self) -> None:
        """Close the port."""
        with suppress(serial.SerialException, OSError):
            self.port.close()


class Link(PortLink):
    """One board of ``kind`` (``"daq"`` or ``"stepper"``) on an open port, synchronised by :meth:`open`.

    Attributes
    ----------
    parser : helpers.board.protocol.StreamParser
        Its lines' parser, rejecting step counts that change faster than the step-rate limit allows.
    rows : list of (seq, t_us, adc, steps)
        The samples received (a DAQ board's), ``t_us`` unwrapped.
    done_position : int or None
        The position of the last ``DONE`` (a stepper board's programme ended), or None.
    version : str or None
        The firmware version from ``PONG``, checked by :func:`check_firmware`.
    """

    def __init__(self, port: serial.SerialBase, kind: str, timeout: float = 2.0) -> None:
        self.port, self.kind, self.timeout = port, kind, timeout
        self.parser = StreamParser(max_step_rate_hz=MAX_STEP_RATE_HZ)
        self.rows: list[tuple[int, int, int, int]] = []
        self.replies: list[str] = []
        self.hello = 0
        self.done_position: int | None = None
        self.version: str | None = None

    @classmethod
    def open(cls, url: str, kind: str, baudrate: int, timeout: float = 2.0) -> Link:
        """Open ``url`` (a device path or a pyserial URL) and wait for the board (:meth:`sync`)."""
        link = cls(open_exclusive(url, kind, baudrate, 0.05, timeout), kind, timeout)
        try:
            link.sync()
        except BaseException:
            link.close()
            raise
        return link

    def command(self, body: str, timeout: float | None = None) -> str:
        """Send ``body`` and return its reply; ``ERR`` raises :class:`CommandRefused`, silence a timeout."""
        self.replies.clear()
        try:
            self.port.write(frame(body))
        except serial.SerialException as exc:
            raise BoardDisconnected(f"{self.kind} board disconnected ({self.port.port}): {exc}") from exc
        wait = self.waiter(self.timeout if timeout is None else timeout)
        while True:
            replies, self.replies = self.replies, []
            for reply in replies:
                if reply.startswith("ERR"):
                    code = (reply.split() + ["?"])[1]
                    raise CommandRefused(f"the {self.kind} board refused {body!r}: {reply}", code)
                if reply.startswith(expected_reply(body)):
                    return reply
            self.check_reset()
            if wait.expired:
                raise BoardTimeout(
                    f"the {self.kind} board did not answer {body!r} within {wait.timeout:.1f} s"
                )
            self.read(wait)

    def sync(self, quiet_s: float = 2.5) -> str:
        """Wait for ``HELLO`` (the board resets as its port opens) for up to ``quiet_s``, then ``PING``.

        A pseudo-terminal or the in-process virtual rig has no bootloader: it is asked at once. Returns the
        firmware version, checked against this host's protocol and rig (:func:`check_firmware`).
        """
        if str(self.port.port).startswith(("virtual://", "/dev/pts/")):
            quiet_s = 0.0
        wait = self.waiter(BOOT_TIMEOUT_S)
        self.read(block=False)
        while not self.hello and wait.elapsed < quiet_s:
            self.read(wait)
        self.hello = 0
        reply = self.command("PING", timeout=BOOT_TIMEOUT_S - wait.elapsed)
        words = reply.split()
        if len(words) != 3 or words[1] != self.kind:
            raise BoardError(f"expected a {self.kind} board on {self.port.port}, got {reply!r}")
        check_firmware(self.kind, words[2])
        self.version = words[2]
        self.rows.clear()
        return self.version
