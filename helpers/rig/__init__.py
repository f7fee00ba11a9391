"""Serial I/O to the rig's two boards (real hardware or the virtual rig) with pyserial.

- :mod:`helpers.rig.framing`: the line protocol (CRC-8 checksums, parsing, exact fault counting);
- :mod:`helpers.rig.boards`: the link shared by both drivers (commands, replies, timeouts, resets);
- :mod:`helpers.rig.daq`, :mod:`helpers.rig.stepper`: the DAQ and stepper drivers;
- :mod:`helpers.rig.safety`: the limits checked before any byte is sent;
- :mod:`helpers.rig.discovery`: finding the boards by USB VID:PID;
- :mod:`helpers.rig.experiment`: :class:`Rig`, one board-timed experiment per call, safe on any error;
- :mod:`helpers.rig.calibration`: load-cell calibration (recording and the linear fit);
- :mod:`helpers.rig.record`: the ``python -m helpers record`` command.

Importing this package registers the ``virtual://`` URL scheme with pyserial.
"""

import serial

if "helpers.virtual" not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append("helpers.virtual")

from helpers.rig.boards import (  # noqa: E402
    BoardDisconnected,
    BoardError,
    BoardReset,
    BoardTimeout,
    CommandRefused,
    OldFirmware,
)
from helpers.rig.daq import DaqBoard  # noqa: E402
from helpers.rig.experiment import Rig, RunAborted  # noqa: E402
from helpers.rig.safety import SafetyError, check_programme, check_request  # noqa: E402
from helpers.rig.stepper import StepperBoard  # noqa: E402

__all__ = [
    "BoardDisconnected",
    "BoardError",
    "BoardReset",
    "BoardTimeout",
    "CommandRefused",
    "DaqBoard",
    "OldFirmware",
    "Rig",
    "RunAborted",
    "SafetyError",
    "StepperBoard",
    "check_programme",
    "check_request",
]
