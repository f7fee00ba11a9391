"""Finding the two boards by USB VID:PID (``serial.tools.list_ports``) and telling them apart by ``PING``.

Known USB identities (:data:`KNOWN_BOARDS`):

============  =========  ===============================================  ============
VID:PID       role        device                                           note
============  =========  ===============================================  ============
2341:0042     daq         Arduino Mega 2560 R3 (ATmega16U2)
2341:0010     daq         Arduino Mega 2560 (ATmega8U2, first revision)
2341:0043     stepper     Arduino Uno R3 (ATmega16U2)
2341:0001     stepper     Arduino Uno (ATmega8U2, first revision)
1a86:7523     either      CH340 USB-serial (most Uno/Mega clones)          probed by PING
============  =========  ===============================================  ============

A genuine board's role follows from its PID; for a CH340 clone the port is opened at each board's baud rate
and asked ``PING`` (``PONG daq ...`` or ``PONG stepper ...``). Opening a port resets an Arduino (DTR), which
the drivers handle by waiting for ``HELLO`` (see :meth:`helpers.rig.boards.BoardLink.sync`).

Running ``serve-virtual-rig`` processes, whose pseudo-terminals record as ``virtual-rig`` and never as
``hardware``, are found by :mod:`helpers.live.ports` (:func:`~helpers.live.ports.virtual_source_for`).
"""

from __future__ import annotations

from dataclasses import dataclass

from serial.tools import list_ports

from helpers.rig.boards import BOOT_TIMEOUT_S, BoardError, OldFirmware
from helpers.rig.daq import DaqBoard
from helpers.rig.stepper import StepperBoard

KNOWN_BOARDS: dict[tuple[int, int], tuple[str, str]] = {
    (0x2341, 0x0042): ("daq", "Arduino Mega 2560 R3"),
    (0x2341, 0x0010): ("daq", "Arduino Mega 2560"),
    (0x2341, 0x0043): ("stepper", "Arduino Uno R3"),
    (0x2341, 0x0001): ("stepper", "Arduino Uno"),
    (0x1A86, 0x7523): ("either", "CH340 USB-serial (clone board)"),
}
"""(VID, PID) -> (role, description)."""


class BoardsNotFound(BoardError):
    """``--ports auto`` found no DAQ and stepper pair (a board fault for the command line: status 4)."""


@dataclass(frozen=True)
class Candidate:
    """A serial port whose USB identity matches a known board."""

    device: str
    vid: int
    pid: int
    role: str
    description: str


def candidate_ports() -> list[Candidate]:
    """List the serial ports that look like one of the rig's boards.

    Returns
    -------
    list of Candidate
        Sorted by device name.
    """
    out = []
    for p in list_ports.comports():
        if p.vid is None or p.pid is None:
            continue
        known = KNOWN_BOARDS.get((p.vid, p.pid))
        if known:
            out.append(Candidate(p.device, p.vid, p.pid, known[0], known[1]))
    return sorted(out, key=lambda c: c.device)


def identify(device: str, hello_timeout: float = BOOT_TIMEOUT_S) -> str | None:
    """Return ``"daq"`` or ``"stepper"`` for the board at ``device`` (asked by PING), or None.

    Parameters
    ----------
    device : str
        The port.
    hello_timeout : float
        Seconds to wait for each attempt (the board resets when the port opens).
    """
    for cls in (DaqBoard, StepperBoard):
        try:
            link = cls.open(device, hello_timeout=hello_timeout)
        except OldFirmware:
            raise  # a board of ours with old firmware: say so rather than "not found"
        except BoardError:
            continue
        link.close()
        return cls.kind
    return None


def find_rig_ports(hello_timeout: float = BOOT_TIMEOUT_S) -> tuple[str, str]:
    """Return ``(daq_device, stepper_device)`` found by VID:PID (and PING for clones).

    Raises
    ------
    BoardsNotFound
        When not exactly one DAQ and one stepper board are found; the message lists what was seen.
    """
    cands = candidate_ports()
    roles: dict[str, list[str]] = {"daq": [], "stepper": []}
    for c in cands:
        role = c.role if c.role != "either" else identify(c.device, hello_timeout)
        if role in roles:
            roles[role].append(c.device)
    if len(roles["daq"]) != 1 or len(roles["stepper"]) != 1:
        seen = ", ".join(f"{c.device} ({c.vid:04x}:{c.pid:04x} {c.description})" for c in cands) or "none"
        raise BoardsNotFound(
            f"expected one DAQ board (Mega) and one stepper board (Uno); found daq={roles['daq']}, "
            f"stepper={roles['stepper']}. Known-board ports: {seen}. "
            "Pass the ports explicitly: 'DAQ,STEPPER'."
        )
    return roles["daq"][0], roles["stepper"][0]
