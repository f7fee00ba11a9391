"""Which ports a rig's two boards are on: the in-process virtual rig, the boards found by USB id, or given.

``ports`` is ``"virtual"`` (the in-process virtual rig: ``virtual://daq?world=<name>`` and
``virtual://stepper?world=<name>``, the world built from the rig file the port is given), ``"auto"`` (the
boards found by USB VID:PID, :func:`find_rig_ports`) or ``"DAQ,STEPPER"`` (device paths or pyserial URLs).

Known USB identities (:data:`KNOWN_BOARDS`): a genuine board's role follows from its PID; a CH340 clone's
port is opened at each board's baud rate and asked ``PING`` (``PONG daq ...`` or ``PONG stepper ...``).

Ports served by a running ``serve-virtual-rig`` (pseudo-terminals) are told apart from hardware by its
announcement (:func:`virtual_source_for`), so that what they record is labelled ``virtual-rig`` (their
silences are counted on the server's awake clock: :func:`helpers.rig.link.open_port`).
"""

from __future__ import annotations

from typing import Any

from serial.tools import list_ports

from helpers.base.validate import RIG_NAME
from helpers.rig.link import BoardError, Link, OldFirmware, WrongRig, announcement

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


def rig_urls(ports: Any, rig: Any, world: str, options: tuple[str, str] = ("", "")) -> tuple[str, str]:
    """``(daq, stepper)`` ports of ``ports`` (module docstring); ``options``: the virtual boards' URL options.

    Raises
    ------
    ValueError
        Not one of the three forms, or a world name that is not a plain name.
    """
    if ports == "virtual":
        if not (isinstance(world, str) and RIG_NAME.match(world)):
            raise ValueError(f"invalid virtual rig name {world!r}: letters, digits, _ - . (at most 64)")
        return f"virtual://daq?world={world}{options[0]}", f"virtual://stepper?world={world}{options[1]}"
    if ports == "auto":
        return find_rig_ports(rig)
    pair = ports.split(",") if isinstance(ports, str) else list(ports)
    if len(pair) != 2 or not all(str(p).strip() for p in pair):
        raise ValueError(f"ports must be 'virtual', 'auto' or two ports 'DAQ,STEPPER', got {ports!r}")
    return str(pair[0]).strip(), str(pair[1]).strip()


def find_rig_ports(rig: Any) -> tuple[str, str]:
    """Return ``(daq_device, stepper_device)`` found by VID:PID (and ``PING`` for clones).

    Raises
    ------
    BoardsNotFound
        When not exactly one DAQ and one stepper board are found; the message lists what was seen.
    """
    seen, roles = [], {"daq": [], "stepper": []}
    for p in sorted(list_ports.comports(), key=lambda p: p.device):
        role, what = KNOWN_BOARDS.get((p.vid, p.pid), (None, ""))
        if role is None:
            continue
        seen.append(f"{p.device} ({p.vid:04x}:{p.pid:04x} {what})")
        for kind in (role,) if role != "either" else ("daq", "stepper"):
            try:  # a genuine board's role is its PID's; a clone is asked, at each board's baud rate
                if role == "either":
                    Link.open(p.device, kind, rig, getattr(rig.hardware, f"{kind}_baud")).close()
            except (OldFirmware, WrongRig):
                raise  # a board of ours with other firmware: say so rather than "not found"
            except BoardError:
                continue
            roles[kind].append(p.device)
            break
    if len(roles["daq"]) != 1 or len(roles["stepper"]) != 1:
        raise BoardsNotFound(
            f"expected one DAQ board (Mega) and one stepper board (Uno); found daq={roles['daq']}, "
            f"stepper={roles['stepper']}. Known-board ports: {', '.join(seen) or 'none'}. "
            "Pass the ports explicitly: 'DAQ,STEPPER'."
        )
    return roles["daq"][0], roles["stepper"][0]


def virtual_source_for(paths: tuple[str, str]) -> dict[str, Any] | None:
    """Provenance of a running ``serve-virtual-rig`` serving either of ``paths``, or None (it is hardware).

    The servers announce themselves in :data:`helpers.base.paths.VIRTUAL_RIG_REGISTRY`; a dead one's
    announcement is ignored (:func:`helpers.rig.link.announcement`).
    """
    info = announcement(paths)
    return None if info is None else {"kind": "virtual-rig", "via": "pseudo-terminal server",
                                      **info.get("source", {})}  # fmt: skip
