"""What the paper's live cells run: a small driver of the two boards, and the link the full rig is built on.

- :mod:`helpers.live.ports`: opening a port (a device path, a pyserial URL or ``virtual://``), and telling a
  served virtual rig from hardware;
- :mod:`helpers.live.link`: one board: open it exclusively, wait for it, check its firmware, commands and
  replies, the boards' errors;
- :mod:`helpers.live.safety`: the limits checked before any byte is sent;
- :mod:`helpers.live.driver`: :class:`LiveRig`, both boards, one pulse of the paper per call -> a recording.

The full rig (:mod:`helpers.rig`: streams, USB discovery, resending over a noisy line, the calibration
procedure; what ``python -m helpers record`` runs) is built on the same link and writes the same metadata.
"""

from helpers.live.driver import LiveRig

__all__ = ["LiveRig"]
