"""One board over pyserial: open it exclusively, wait for it, send a command and take its reply; the errors.

:class:`Link` is the one link to a board (DAQ or stepper, built for any number of tendons). Every line goes
through a :class:`helpers.board.protocol.StreamParser`: data lines become samples (``rows``), other lines
messages: replies (``OK``, ``ERR``, ``PONG``, ``ABORTED``) answer the pending command, ``DONE <p_0> ...``
is kept in ``done`` (every axis's position), the stepper's stream notices (``N,...``) in ``notices``,
``HELLO`` means the board rebooted (an error unless it was expected).

A bit error on the link is not a silent board: a command the board refused as damaged (``ERR CHECKSUM``,
``ERR NOCRC``: it executed nothing) is sent again, and so is one of :data:`RESENDABLE` whose reply did not
come while a corrupted line did (up to :data:`SEND_ATTEMPTS` times); any other command whose reply was lost
that way raises :class:`LinkCorrupted`.

Timeouts are counted by :class:`Waiter`: on the in-process virtual rig in its device time only (its port's
``device_time()``: the emulated boards' time moves only when the host reads, so a slow host never makes a
spurious timeout), over ``serve-virtual-rig``'s pseudo-terminals on the server's awake clock
(:func:`served_clock`: a host too busy to run the server makes no spurious timeout either), elsewhere the
larger of wall time and the read timeouts that expired.

Connecting: an Arduino resets when its USB port opens (DTR), and its bootloader listens for about 1.5-2 s
before the sketch starts and sends ``HELLO``. The host sends nothing for :data:`BOOTLOADER_QUIET_S` (a
pseudo-terminal or an emulated board has no bootloader: it is asked at once), then ``PING`` every 0.25 s,
and gives up after :data:`BOOT_TIMEOUT_S`: five times the bootloader's wait. The firmware must speak this
host's protocol and have been built for the rig file the host runs (its hash in the version token).
"""

from __future__ import annotations

import fcntl
import json
import mmap
import os
import struct
import time
from collections import deque
from collections.abc import Callable
from contextlib import suppress
from typing import Any

import serial

from helpers.base.paths import VIRTUAL_RIG_REGISTRY
from helpers.base.signals import signals_held
from helpers.board.protocol import PAPER_RIG_HASH, PROTOCOL_MAJOR, StreamParser, frame

BOOT_TIMEOUT_S = 10.0
"""Seconds a board has to answer after its port opens (``HELLO``, or ``PONG`` to a ``PING``)."""

BOOTLOADER_QUIET_S = 2.5
"""Seconds the host stays silent after opening a USB serial port, past the bootloader's 1.5-2 s window."""

REPLY_PREFIXES = ("OK", "ERR", "PONG", "ABORTED")

RESENDABLE = frozenset({"PING", "POS", "MEM", "ABORT", "EN", "RATE", "ZERO", "STOP", "CLEAR", "CONFIG"})
"""Commands whose second execution changes nothing: sent again when their reply was corrupted on the link."""

SEND_ATTEMPTS = 3
"""How often a command is sent when the board refused it as damaged in transit or its reply was damaged."""

VIRTUAL_SCHEME = "virtual://"
EMULATOR_PACKAGE = "helpers.virtual.emulator"
"""The package holding ``protocol_virtual`` (pyserial imports ``<package>.protocol_<scheme>`` by name)."""


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
    """The board's firmware was built for another rig file (or tendon count) than the one the host runs."""


class LinkCorrupted(BoardError):
    """A board answered, but its reply failed its checksum, and the command cannot safely be sent again."""


class CommandRefused(BoardError):
    """A board answered ``ERR <code> <text>``."""

    def __init__(self, message: str, code: str) -> None:
        super().__init__(message)
        self.code = code


def check_firmware(kind: str, version: str, rig: Any) -> None:
    """Raise unless ``version`` is of this host's protocol MAJOR and the board was built for ``rig``.

    Raises
    ------
    OldFirmware
        The board speaks another protocol MAJOR version.
    WrongRig
        The version's build metadata (``+<rig hash>``) names another rig file than ``rig``. A version
        without it (firmware 2.0-2.1) is the paper's rig's.
    """
    if version.split(".")[0] != str(PROTOCOL_MAJOR):
        raise OldFirmware(
            f"the {kind} board runs firmware {version}; this host speaks protocol {PROTOCOL_MAJOR} "
            f"(firmware {PROTOCOL_MAJOR}.x, CRC-8 checksums): flash the firmware of this repository"
        )
    built_for = version.partition("+")[2] or PAPER_RIG_HASH
    if built_for != rig.hash:
        raise WrongRig(
            f"the {kind} board was built for rig {built_for}, but this host runs rig '{rig.name}' "
            f"({rig.source or 'rig file'}, hash {rig.hash}): " + rebuild_hint(rig, kind)
        )


def rebuild_hint(rig: Any, kind: str) -> str:
    """The command that builds and flashes ``kind``'s firmware for ``rig``."""
    return f"rebuild and flash it with make -C firmware RIG={rig.source or 'FILE'} upload-{kind} PORT=..."


def ints(reply: str, skip: int = 2) -> tuple[int, ...]:
    """The integers of a reply after its first ``skip`` words (``OK POS 3 -2``: ``(3, -2)``)."""
    words = reply.split()[skip:]
    if not words or not all(w.lstrip("-").isdigit() for w in words):
        raise BoardError(f"malformed reply {reply!r}: integers expected after {skip} word(s)")
    return tuple(int(w) for w in words)


def open_port(url: str, kind: str, baudrate: int, timeout: float, rig: Any = None) -> serial.SerialBase:
    """Open ``url`` exclusively (a device path or any pyserial URL); a busy or missing one: one clear error.

    Exclusive: a second program opening the same port gets an error instead of stealing samples (a ``flock``
    on real ports and pseudo-terminals; the emulated boards refuse a second open themselves). The port is
    given ``rig`` (the rig file) before it opens: the in-process virtual rig (``virtual://``, served by
    :mod:`helpers.virtual.emulator.protocol_virtual`, registered only when such a URL is opened) builds its
    world from it; other ports ignore it.
    """
    if str(url).startswith(VIRTUAL_SCHEME) and EMULATOR_PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(EMULATOR_PACKAGE)
    try:
        port = serial.serial_for_url(url, baudrate=baudrate, timeout=0.05, write_timeout=timeout,
                                     exclusive=True, do_not_open=True)  # fmt: skip
        port.rig = rig
        port.open()
        if (clock := served_clock(url)) is not None:
            port.device_time = clock  # a pseudo-terminal server's: its silences count on it
        return port
    except serial.SerialException as exc:
        if "exclusive" in str(exc) or "busy" in str(exc):
            raise PortBusy(
                f"port busy: the {kind} board at {url} is open in another program (another recorder, "
                "notebook or serve-virtual-rig client); close it first"
            ) from exc
        raise BoardDisconnected(f"cannot open the {kind} board at {url}: {exc}") from exc


SERVER_CLOCK = struct.Struct("<d")
"""The layout of a ``serve-virtual-rig``'s awake clock file (its announcement's ``clock``): one double, the
seconds its loop has run, each turn counted at most ``helpers.virtual.emulator.server.AWAKE_TURN_S``."""


def announcement(paths: tuple[str, ...]) -> dict[str, Any] | None:
    """The announcement of a running ``serve-virtual-rig`` serving any of ``paths`` (a dead one's ignored).

    Running: the server holds its clock file's lock, which the kernel drops however the server ends (a
    killed server leaves its announcement, and its pid may be another process's by now); an announcement
    without a clock (an older server): its pid is alive.
    """
    real = {os.path.realpath(p) for p in paths}
    for f in VIRTUAL_RIG_REGISTRY.glob("*.json"):
        try:
            info = json.loads(f.read_text())
            if not running(info):
                continue
            served = {os.path.realpath(info["daq"]), os.path.realpath(info["stepper"])}
        except (OSError, ValueError, KeyError, TypeError, json.JSONDecodeError):
            continue
        if served & real:
            return info
    return None


def running(info: dict[str, Any]) -> bool:
    """Whether the server of announcement ``info`` runs (:func:`announcement`'s rule; raises if unread)."""
    if "clock" in info:
        return _held(info["clock"])
    os.kill(int(info["pid"]), 0)  # an older server's (no clock): ProcessLookupError if it is gone
    return True


def _held(path: str) -> bool:
    """Whether a process holds ``path``'s exclusive lock (a running server holds its clock file's)."""
    with open(path, "rb") as f:
        try:
            fcntl.flock(f.fileno(), fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        return False


def served_clock(url: str) -> Callable[[], float] | None:
    """The awake clock of a running ``serve-virtual-rig`` serving ``url``, or None (hardware, or in-process).

    A board's silence over the server's pseudo-terminals is counted on it, as the in-process rig's on its
    device clock: a host too busy to run the server (starved of the CPU, or stopped) pauses the server's
    boards, and that is no silence. A served board that sends nothing (hung) is silent on it as on the wall
    clock.
    """
    info = announcement((url,)) if "://" not in url else None
    try:
        with open(info["clock"], "rb") as f:  # type: ignore[index]
            view = mmap.mmap(f.fileno(), SERVER_CLOCK.size, access=mmap.ACCESS_READ)
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return lambda: SERVER_CLOCK.unpack_from(view)[0]


class Waiter:
    """Elapsed waiting time: the larger of wall time and the sum of read timeouts that expired.

    Given a device ``clock`` (the in-process virtual rig's :meth:`device_time`), the elapsed time is that
    clock's alone.
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


class Link:
    """One board of ``kind`` (``"daq"`` or ``"stepper"``) on an open port.

    Attributes
    ----------
    parser : helpers.board.protocol.StreamParser
        Its lines' parser (the DAQ's is given its channels and axes by the driver after ``CONFIG``).
    rows : list of tuple
        The samples received (a DAQ board's) since they were last cleared, ``t_us`` unwrapped.
    done : tuple of int or None
        Every axis's position in the last ``DONE`` (a stepper's programme or stream ended), or None.
    notices : list of str
        The stepper's stream notices (``N,LIMIT,...``, ``N,WATCHDOG,...``) as they arrived.
    version : str or None
        The firmware version from ``PONG``, checked by :func:`check_firmware`.
    booted_on_open : bool
        True when the board rebooted as its port opened (``HELLO``): its state (position too) is new.
    """

    def __init__(self, port: serial.SerialBase, kind: str, rig: Any, timeout: float = 2.0) -> None:
        self.port, self.kind, self.rig, self.timeout = port, kind, rig, timeout
        self.parser = StreamParser()
        self.rows: list[tuple[int, ...]] = []
        self.replies: deque[str] = deque()
        self.unexpected: list[str] = []
        self.notices: list[str] = []
        self.done: tuple[int, ...] | None = None
        self.hello = 0
        self.version: str | None = None
        self.booted_on_open = False

    @classmethod
    def open(cls, url: str, kind: str, rig: Any, baudrate: int, timeout: float = 2.0,
             hello_timeout: float = BOOT_TIMEOUT_S) -> Link:  # fmt: skip
        """Open ``url`` (:func:`open_port`) and wait for the board (:meth:`sync`); its firmware checked."""
        link = cls(open_port(url, kind, baudrate, timeout, rig), kind, rig, timeout)
        try:
            link.sync(hello_timeout)
        except BaseException:
            link.close()
            raise
        return link

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
            if msg.startswith(REPLY_PREFIXES):
                self.replies.append(msg)
            elif msg.startswith("DONE"):
                self.done = tuple(int(w) for w in msg.split()[1:] if w.lstrip("-").isdigit())
            elif msg.startswith("N,"):
                self.notices.append(msg)
            elif msg.startswith("HELLO"):
                self.hello += 1
            else:
                self.unexpected.append(msg)
        return len(data)

    def check_reset(self) -> None:
        """Raise :class:`BoardReset` if the board sent ``HELLO`` since it was synchronised."""
        if self.hello:
            raise BoardReset(f"the {self.kind} board reset (it sent HELLO): its state is lost")

    def write_line(self, body: str) -> None:
        """Send ``body`` with its checksum."""
        try:
            self.port.write(frame(body))
        except (serial.SerialException, OSError) as exc:
            raise BoardDisconnected(f"{self.kind} board disconnected ({self.port.port}): {exc}") from exc

    def command(self, body: str, timeout: float | None = None) -> str:
        """Send one command and return its reply; ``ERR`` raises :class:`CommandRefused`, silence a timeout.

        Data lines, notices and ``DONE`` arriving meanwhile are kept; ``HELLO`` raises :class:`BoardReset`;
        a reply that cannot belong to this command (a late answer to an earlier one) is set aside in
        ``unexpected``. Resending over a noisy line: the module's docstring.
        """
        for attempt in range(1, SEND_ATTEMPTS + 1):
            corrupted = self.parser.stats.corrupted
            try:
                return self._command_once(body, timeout)
            except BoardTimeout:
                if self.parser.stats.corrupted == corrupted:
                    raise  # nothing arrived at all: the board is silent
                if body.split(" ", 1)[0] not in RESENDABLE or attempt == SEND_ATTEMPTS:
                    raise LinkCorrupted(
                        f"the {self.kind} board's reply to {body!r} was corrupted on the link ({attempt} "
                        "time(s); it failed its checksum: a bad cable, or the wrong baud rate?), and the "
                        "command cannot safely be sent again"
                    ) from None
            except CommandRefused as exc:
                if exc.code not in ("CHECKSUM", "NOCRC") or attempt == SEND_ATTEMPTS:
                    raise  # else the command was damaged on its way: the board executed nothing
        raise AssertionError("unreachable")  # pragma: no cover

    def _command_once(self, body: str, timeout: float | None) -> str:
        self.replies.clear()
        self.write_line(body)
        word = body.split(" ", 1)[0]  # the reply besides ERR: PONG, ABORTED or OK <WORD>
        expected = {"PING": "PONG", "ABORT": "ABORTED"}.get(word, f"OK {word}")
        wait = self.waiter(self.timeout if timeout is None else timeout)
        while True:
            while self.replies:
                reply = self.replies.popleft()
                if reply.startswith("ERR"):
                    code = (reply.split() + ["?"])[1]
                    raise CommandRefused(f"the {self.kind} board refused {body!r}: {reply}", code)
                if reply.startswith(expected):
                    self.check_reset()
                    return reply
                self.unexpected.append(reply)
            self.check_reset()
            if wait.expired:
                raise BoardTimeout(f"the {self.kind} board did not answer {body!r} in {wait.timeout:.1f} s")
            self.read(wait)

    def send_all(self, lines: list[str]) -> list[str]:
        """Send ``lines`` in order and return the replies; all of them again if a reply was lost on the link.

        The first line (``CLEAR``, ``SHAPER``) makes loading again start from nothing.
        """
        for attempt in range(1, SEND_ATTEMPTS + 1):
            try:
                return [self.command(line) for line in lines]
            except LinkCorrupted:
                if attempt == SEND_ATTEMPTS:
                    raise
        raise AssertionError("unreachable")  # pragma: no cover

    def sync(self, hello_timeout: float = BOOT_TIMEOUT_S) -> str:
        """Wait for the board after opening (``HELLO``, or ``PONG`` to a ``PING`` every 0.25 s); its version.

        The version is checked against this host's protocol and the rig (:func:`check_firmware`).
        """
        wait, last_ping = self.waiter(hello_timeout), -1.0
        no_bootloader = str(self.port.port).startswith(("/dev/pts/", VIRTUAL_SCHEME, "loop://"))
        quiet = 0.0 if no_bootloader else min(BOOTLOADER_QUIET_S, hello_timeout / 2)
        while not self.hello and not any(r.startswith("PONG") for r in self.replies):
            if wait.expired:
                raise BoardTimeout(
                    f"no {self.kind} board answered on {self.port.port} within {hello_timeout:.1f} s "
                    "(no HELLO, no PONG)"
                )
            if wait.elapsed >= quiet and (last_ping < 0 or wait.elapsed - last_ping >= 0.25):
                self.write_line("PING")
                last_ping = wait.elapsed
            self.read(wait)
        self.booted_on_open, self.hello = self.hello > 0, 0
        reply = self.command("PING", timeout=max(hello_timeout - wait.elapsed, self.timeout))
        words = reply.split()
        if len(words) != 3 or words[1] != self.kind:
            raise BoardError(f"expected a {self.kind} board on {self.port.port}, got {reply!r}")
        check_firmware(self.kind, words[2], self.rig)
        self.version = words[2]
        self.replies.clear()
        self.rows.clear()
        return self.version

    def close(self) -> None:
        """Close the port."""
        with suppress(serial.SerialException, OSError):
            self.port.close()
