"""The link to one board, shared by both drivers: framed commands, replies, timeouts, resets, disconnects.

Every read goes through :meth:`BoardLink.pump` (the live link's :meth:`helpers.live.link.PortLink.read`),
which feeds the bytes to a :class:`helpers.board.protocol.StreamParser`: data lines become samples (kept for
the DAQ driver), other lines become messages. Replies (``OK``, ``ERR``, ``PONG``, ``ABORTED``) answer the
pending command; unsolicited ``DONE`` is remembered; ``HELLO`` means the board rebooted, which is an error
whenever it was not expected.

Timeouts are counted in the port's own read timeouts (a pyserial read that returns early has waited its
``timeout``), or in wall time, whichever is larger, on hardware and on pseudo-terminals. The in-process
virtual rig has a device clock of its own (its port's ``device_time()``): there a timeout is counted in device
time only, so it reports the same errors instantly and never a spurious one when the host process is slow (a
busy machine, a first compilation).

Connecting (:data:`BOOT_TIMEOUT_S`, :data:`BOOTLOADER_QUIET_S`): an Arduino Uno or Mega resets when its
USB port opens (DTR), and its bootloader listens for an upload for about 1.5-2 s before the sketch starts and
sends ``HELLO``. The host sends nothing for the first :data:`BOOTLOADER_QUIET_S` s (bytes sent to a listening
bootloader can keep it from starting the sketch), then ``PING`` every 0.25 s, and gives up after
:data:`BOOT_TIMEOUT_S` s: five times the bootloader's wait, so a board on a slow USB hub or a host busy with
other work still connects, and a port with no board behind it is named within seconds.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import serial

from helpers.board.protocol import StreamParser, frame
from helpers.live.link import (
    BOOT_TIMEOUT_S,
    REPLY_PREFIXES,
    BoardDisconnected,
    BoardError,
    BoardReset,
    BoardTimeout,
    CommandRefused,
    OldFirmware,
    PortBusy,
    PortLink,
    Waiter,
    WrongRig,
    check_firmware,
    expected_reply,
    open_exclusive,
)

__all__ = [
    "BOOTLOADER_QUIET_S",
    "BOOT_TIMEOUT_S",
    "RESENDABLE",
    "SEND_ATTEMPTS",
    "BoardDisconnected",
    "BoardError",
    "BoardLink",
    "BoardReset",
    "BoardTimeout",
    "CommandRefused",
    "LinkCorrupted",
    "OldFirmware",
    "PortBusy",
    "Waiter",
    "WrongRig",
]

BOOTLOADER_QUIET_S = 2.5
"""Seconds the host stays silent after opening a USB serial port, past the bootloader's 1.5-2 s window (a
pseudo-terminal or an emulated board has no bootloader: it is asked at once)."""


class LinkCorrupted(BoardError):
    """A board answered, but its reply failed its checksum, and the command cannot safely be sent again."""


RESENDABLE = frozenset({"PING", "POS", "MEM", "ABORT", "EN", "RATE", "ZERO", "STOP", "CLEAR"})
"""Commands whose second execution changes nothing: sent again when their reply was corrupted on the link."""

SEND_ATTEMPTS = 3
"""How often a command is sent when the board refused it as damaged in transit or its reply was damaged."""


class BoardLink(PortLink):
    """One serial port speaking the protocol of ``firmware/PROTOCOL.md``.

    Parameters
    ----------
    port : serial.SerialBase
        An open port (``serial.Serial``, ``serial.serial_for_url("virtual://...")``, or a test double).
    kind : str
        ``"daq"`` or ``"stepper"`` (what ``PONG`` and ``HELLO`` must name).
    timeout : float
        Seconds a command may wait for its reply.
    """

    kind = "board"
    baudrate = 115200

    def __init__(self, port: serial.SerialBase, timeout: float = 2.0) -> None:
        self.port = port
        self.timeout = timeout
        self.parser = StreamParser()
        self.rows: list[tuple[int, int, int, int]] = []
        self.replies: deque[str] = deque()
        self.unexpected: list[str] = []
        self.done_position: int | None = None
        self.hello = 0
        self.version: str | None = None
        self.sent: list[str] = []
        self.expected_rig: Any = None
        """The rig file the board must be built for (None: ``helpers.paper.hardware.RIG``, the host's)."""
        self.booted_on_open = False
        """True when the board rebooted as its port opened (``HELLO``): its state (position too) is new."""

    @classmethod
    def open(
        cls,
        url: str,
        timeout: float = 2.0,
        read_timeout: float = 0.05,
        sync: bool = True,
        hello_timeout: float = BOOT_TIMEOUT_S,
        rig: Any = None,
    ) -> BoardLink:
        """Open ``url`` (a device path or a pyserial URL) and synchronise with the board.

        Parameters
        ----------
        url : str
            E.g. ``/dev/ttyACM0``, ``/dev/pts/5`` or ``virtual://daq?rig=lab``.
        timeout : float
            Command timeout (s).
        read_timeout : float
            The port's read timeout (s): how long one poll waits.
        sync : bool
            Wait for ``HELLO`` (the board resets when the port opens) or ``PING`` until ``PONG``.
        hello_timeout : float
            Seconds to wait for the board to boot (default :data:`BOOT_TIMEOUT_S`).
        rig : RigFile, optional
            The rig the board must be built for (default the host's, ``helpers.paper.hardware.RIG``).

        Returns
        -------
        BoardLink
        """
        port = open_exclusive(url, cls.kind, cls.baudrate, read_timeout, timeout)
        link = cls(port, timeout=timeout)
        link.expected_rig = rig
        if sync:
            link.sync(hello_timeout)
        return link

    # --- low level ----------------------------------------------------------------------------------
    def _fail_disconnected(self, exc: Exception) -> BoardDisconnected:
        return BoardDisconnected(f"{self.kind} board disconnected ({self.port.port}): {exc}")

    def write_line(self, body: str) -> None:
        """Send ``body`` with its checksum."""
        data = frame(body)
        try:
            self.port.write(data)
        except serial.SerialException as exc:
            raise self._fail_disconnected(exc) from exc
        self.sent.append(body)

    def pump(self, block: bool = True) -> int:
        """Read what the port has (waiting up to its read timeout if ``block``); return bytes read."""
        return self.read(block=block)

    def _message(self, msg: str) -> None:
        if msg.startswith(REPLY_PREFIXES):
            self.replies.append(msg)
        elif msg.startswith("DONE"):
            parts = msg.split()
            self.done_position = int(parts[1]) if len(parts) == 2 and parts[1].lstrip("-").isdigit() else 0
        elif msg.startswith("HELLO"):
            self.hello += 1
            self.version = msg.split()[-1] if len(msg.split()) == 3 else None
        else:
            self.unexpected.append(msg)

    def command(self, body: str, timeout: float | None = None) -> str:
        """Send one command and return its reply; ``ERR`` raises :class:`CommandRefused`.

        Data lines and ``DONE`` arriving meanwhile are kept; ``HELLO`` raises :class:`BoardReset`. A reply
        that cannot belong to this command (a late answer to an earlier one that timed out) is set aside in
        ``unexpected``. A bit error on the link is not a silent board: a command the board refused as damaged
        (``ERR CHECKSUM``, ``ERR NOCRC``: it executed nothing) is sent again, and so is one of
        :data:`RESENDABLE` whose reply did not come while a corrupted line did (up to :data:`SEND_ATTEMPTS`
        times); any other command whose reply was lost that way raises :class:`LinkCorrupted`.
        """
        for attempt in range(1, SEND_ATTEMPTS + 1):
            corrupted = self.parser.stats.corrupted
            try:
                reply = self._command_once(body, timeout)
            except BoardTimeout:
                if self.parser.stats.corrupted == corrupted:
                    raise  # nothing arrived at all: the board is silent
                if body.split(" ", 1)[0] not in RESENDABLE:
                    raise LinkCorrupted(
                        f"the {self.kind} board's reply to {body!r} was corrupted on the link (it failed its "
                        "checksum), and the command cannot safely be sent again"
                    ) from None
                if attempt == SEND_ATTEMPTS:
                    raise LinkCorrupted(
                        f"the {self.kind} board's replies to {body!r} were corrupted {attempt} times on the "
                        "link (a bad cable, or the wrong baud rate?)"
                    ) from None
                continue
            except CommandRefused as exc:
                if exc.code in ("CHECKSUM", "NOCRC") and attempt < SEND_ATTEMPTS:
                    continue  # the command was damaged on its way: the board executed nothing
                raise
            return reply
        raise AssertionError("unreachable")  # pragma: no cover

    def _command_once(self, body: str, timeout: float | None) -> str:
        self.replies.clear()
        self.write_line(body)
        expected = expected_reply(body)
        wait = self.waiter(self.timeout if timeout is None else timeout)
        reply = None
        while reply is None:
            while self.replies:
                candidate = self.replies.popleft()
                if candidate.startswith(("ERR", expected)):
                    reply = candidate
                    break
                self.unexpected.append(candidate)
            if reply is not None:
                break
            self.check_reset()
            if wait.expired:
                raise BoardTimeout(
                    f"the {self.kind} board did not answer {body!r} within {wait.timeout:.1f} s"
                )
            if self.pump() == 0:
                wait.idle(self.port.timeout or 0.0)
        self.check_reset()
        if reply.startswith("ERR"):
            code = reply.split()[1] if len(reply.split()) > 1 else "?"
            raise CommandRefused(f"the {self.kind} board refused {body!r}: {reply}", code)
        return reply

    def sync(self, hello_timeout: float = BOOT_TIMEOUT_S, ping_every: float = 0.25) -> str:
        """Wait for the board after opening: ``HELLO`` (reset-on-open) or else ``PING`` until ``PONG``.

        On a USB serial port nothing is sent for :data:`BOOTLOADER_QUIET_S` (at most half of
        ``hello_timeout``: a bootloader may be listening); then ``PING`` every ``ping_every`` s until a
        ``PONG`` naming this board's kind arrives or ``hello_timeout`` expires.

        Returns
        -------
        str
            The firmware version.
        """
        wait = self.waiter(hello_timeout)
        last_ping = -1.0
        port_name = str(getattr(self.port, "port", "") or "")
        # A pseudo-terminal or an emulated board has no bootloader to disturb: ask at once.
        quiet = 0.0 if port_name.startswith(("/dev/pts/", "virtual://", "loop://")) else BOOTLOADER_QUIET_S
        quiet = min(quiet, hello_timeout / 2)
        while True:
            if self.hello:
                break
            for reply in list(self.replies):
                if reply.startswith("PONG"):
                    self.replies.clear()
                    words = reply.split()
                    if len(words) != 3 or words[1] != self.kind:
                        raise BoardError(f"expected a {self.kind} board on {self.port.port}, got {reply!r}")
                    self.version = words[2]
                    check_firmware(self.kind, words[2], self.expected_rig)
                    break
            else:
                if wait.expired:
                    raise BoardTimeout(
                        f"no {self.kind} board answered on {self.port.port} within {hello_timeout:.1f} s "
                        "(no HELLO, no PONG)"
                    )
                if wait.elapsed >= quiet and (last_ping < 0 or wait.elapsed - last_ping >= ping_every):
                    self.write_line("PING")
                    last_ping = wait.elapsed
                if self.pump() == 0:
                    wait.idle(self.port.timeout or 0.0)
                continue
            break
        if self.hello:
            self.hello = 0
            self.booted_on_open = True
            self.version = self.ping()
        self.replies.clear()
        self.rows.clear()
        return self.version or "?"

    def ping(self) -> str:
        """``PING`` -> the firmware version from ``PONG <kind> <version>``."""
        reply = self.command("PING")
        words = reply.split()
        if len(words) != 3 or words[0] != "PONG" or words[1] != self.kind:
            raise BoardError(
                f"expected 'PONG {self.kind} <version>' from the {self.kind} board, got {reply!r}"
            )
        self.version = words[2]
        check_firmware(self.kind, words[2], self.expected_rig)
        return words[2]
