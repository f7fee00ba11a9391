"""Opening a serial port: a device path, a pyserial URL, or the in-process virtual rig (``virtual://``).

The ``virtual://`` scheme is served by :mod:`helpers.virtual.emulator.protocol_virtual`. pyserial finds URL
handlers by package name in ``serial.protocol_handler_packages``; :func:`open_port` adds
``"helpers.virtual.emulator"`` there when, and only when, it is asked to open a ``virtual://`` URL (importing
:mod:`helpers.live` or :mod:`helpers.rig` registers nothing). Ports served by a running ``serve-virtual-rig``
(pseudo-terminals) are told apart from hardware by its announcement (:func:`virtual_source_for`), so that
what they record is labelled ``virtual-rig``, never ``hardware``.
"""

from __future__ import annotations

import json
import os
from typing import Any

import serial

from helpers.base.paths import VIRTUAL_RIG_REGISTRY

VIRTUAL_SCHEME = "virtual://"
EMULATOR_PACKAGE = "helpers.virtual.emulator"
"""The package holding ``protocol_virtual`` (pyserial imports ``<package>.protocol_<scheme>`` by name)."""


def open_port(url: str, baudrate: int, timeout: float, write_timeout: float) -> serial.SerialBase:
    """Open ``url`` with pyserial, exclusively, and return the port.

    Exclusive: a second program (or a second notebook) opening the same port gets an error instead of
    stealing samples from the first (a ``flock`` on the device for real ports and pseudo-terminals; the
    emulated boards refuse a second open themselves).

    Parameters
    ----------
    url : str
        ``/dev/ttyACM0``, ``/dev/pts/5``, ``virtual://daq?rig=lab`` or any pyserial URL.
    baudrate : int
        Line rate.
    timeout, write_timeout : float
        pyserial's read and write timeouts (s).

    Raises
    ------
    serial.SerialException
        If the port cannot be opened.
    """
    if str(url).startswith(VIRTUAL_SCHEME) and EMULATOR_PACKAGE not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append(EMULATOR_PACKAGE)
    return serial.serial_for_url(
        url, baudrate=baudrate, timeout=timeout, write_timeout=write_timeout, exclusive=True
    )


def announced_virtual_rigs() -> list[dict[str, Any]]:
    """Return the announcements of running ``serve-virtual-rig`` processes (dead ones are ignored)."""
    out = []
    for f in VIRTUAL_RIG_REGISTRY.glob("*.json"):
        try:
            info = json.loads(f.read_text())
            os.kill(int(info["pid"]), 0)
        except (OSError, ValueError, KeyError, TypeError, json.JSONDecodeError):
            continue
        out.append(info)
    return out


def virtual_source_for(paths: tuple[str, str]) -> dict[str, Any] | None:
    """Provenance of a ``serve-virtual-rig`` serving either of ``paths``, or None (then it is hardware)."""
    real = {os.path.realpath(p) for p in paths}
    for info in announced_virtual_rigs():
        if {os.path.realpath(info["daq"]), os.path.realpath(info["stepper"])} & real:
            return {"kind": "virtual-rig", "via": "pseudo-terminal server", **info.get("source", {})}
    return None
