"""Serial I/O to the rig's two boards (real hardware or the virtual rig) with pyserial.

- :mod:`helpers.live`: what the full rig is built on (opening a port, one board's link, the safety limits);
- :mod:`helpers.rig.boards`: the link shared by both drivers (commands, replies, timeouts, resets);
- :mod:`helpers.rig.daq`, :mod:`helpers.rig.stepper`: the DAQ and stepper drivers;
- :mod:`helpers.rig.safety`: the limits checked before any byte is sent;
- :mod:`helpers.rig.discovery`: finding the boards by USB VID:PID, and announced virtual rigs;
- :mod:`helpers.rig.experiment`: :class:`Rig`, one board-timed experiment per call (a programme, or a stream
  of set-points through the board's shaper), safe on any error;
- :mod:`helpers.rig.stream`: a stream's set-points, their checks, the pacing and what the recording says;
- :mod:`helpers.rig.loadcell`: recording the load-cell calibration under known loads.

The line protocol itself is :mod:`helpers.board.protocol`. Nothing here needs numba or the virtual rig's
physics:
the in-process virtual rig is reached through its ``virtual://`` URL (:mod:`helpers.virtual.emulator`).
"""

from helpers.rig.boards import (
    BoardDisconnected,
    BoardError,
    BoardReset,
    BoardTimeout,
    CommandRefused,
    LinkCorrupted,
    OldFirmware,
    PortBusy,
    WrongRig,
)
from helpers.rig.daq import DaqBoard
from helpers.rig.experiment import Rig, RunAborted
from helpers.rig.safety import SafetyError, check_programme, check_request
from helpers.rig.stepper import StepperBoard

__all__ = [
    "BoardDisconnected",
    "BoardError",
    "BoardReset",
    "BoardTimeout",
    "CommandRefused",
    "DaqBoard",
    "LinkCorrupted",
    "OldFirmware",
    "WrongRig",
    "PortBusy",
    "Rig",
    "RunAborted",
    "SafetyError",
    "StepperBoard",
    "check_programme",
    "check_request",
]
