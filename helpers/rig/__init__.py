"""The host side of the rig's two boards (hardware or the virtual rig, 1 to 4 tendons), with pyserial.

- :mod:`helpers.rig.driver`: :class:`Rig`, the one driver: both boards, their builds checked against the rig
  file, one board-timed run per call -> a recording, safe however it ends; homing;
- :mod:`helpers.rig.link`: :class:`~helpers.rig.link.Link`, one board's link (commands, replies, resending
  over a noisy line, timeouts, resets) and the boards' errors;
- :mod:`helpers.rig.ports`: which ports: the in-process virtual rig, USB discovery, announced virtual rigs;
- :mod:`helpers.rig.safety`: the limits checked before any byte is sent (``docs/safety.md``);
- :mod:`helpers.rig.stream`: streams of every tendon's set-points through the board's shaper (not imported
  here: the paper's live cells do not need it);
- :mod:`helpers.rig.static`: recording with the motor idle, the load-cell calibration's procedure;
- :mod:`helpers.rig.table_i`: the paper's Table I experiment on a rig.

The line protocol itself is :mod:`helpers.board.protocol`. Nothing here needs numba or the virtual rig's
physics: the in-process virtual rig is reached through its ``virtual://`` URL
(:mod:`helpers.virtual.emulator`).
"""

from helpers.rig.driver import NotAtRest, NotAtZero, Rig, RunAborted
from helpers.rig.link import (
    BoardDisconnected,
    BoardError,
    BoardReset,
    BoardTimeout,
    CommandRefused,
    LinkCorrupted,
    OldFirmware,
    PortBusy,
    WrongRig,
)  # fmt: skip
from helpers.rig.safety import SafetyError, check_programme, check_request

__all__ = [
    "BoardDisconnected", "BoardError", "BoardReset", "BoardTimeout", "CommandRefused", "LinkCorrupted",
    "NotAtRest", "NotAtZero", "OldFirmware", "PortBusy", "Rig", "RunAborted", "SafetyError", "WrongRig",
    "check_programme", "check_request",
]  # fmt: skip
