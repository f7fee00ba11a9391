"""Driver of the stepper board (Arduino Uno + TB6600, 115200 baud): programmes and streams.

Programme mode: clear, segments, dwells, go, abort, enable, position. Streaming mode: load a shaper, start a
stream, send set-points, end it; its notices are collected.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from helpers.board.programmes import Dwell, Programme, Segment
from helpers.paper.hardware import STEPPER_BAUD
from helpers.rig.boards import SEND_ATTEMPTS, BoardError, BoardLink, CommandRefused, LinkCorrupted
from helpers.rig.safety import check_programme

if TYPE_CHECKING:  # a type only: the streaming reference loads where a stream runs
    from helpers.board.stream_reference import StreamShaper


def _last_int(reply: str, what: str) -> int:
    words = reply.split()
    try:
        return int(words[-1])
    except (IndexError, ValueError):
        raise BoardError(f"malformed reply to {what} from the stepper board: {reply!r}") from None


class StepperBoard(BoardLink):
    """The stepper board. ``done_position`` is set when the unsolicited ``DONE <position>`` arrives.

    The streaming mode's unsolicited notices (``N,LIMIT,SPEED,<period>``, ``N,LIMIT,TRAVEL,<position>``,
    ``N,WATCHDOG,<period>``) are appended to ``notices`` as they arrive.
    """

    kind = "stepper"
    baudrate = STEPPER_BAUD

    def __init__(self, port, timeout: float = 2.0) -> None:
        super().__init__(port, timeout)
        self.notices: list[str] = []

    def _message(self, msg: str) -> None:
        if msg.startswith("N,"):
            self.notices.append(msg)
        else:
            super()._message(msg)

    def clear(self) -> None:
        """``CLEAR`` the programme."""
        self.command("CLEAR")

    def seg(self, direction: int, n_steps: int, interval_us: int) -> int:
        """Append ``SEG``; return the number of items."""
        return _last_int(self.command(Segment(direction, n_steps, interval_us).command()), "SEG")

    def wait(self, ms: int) -> int:
        """Append ``WAIT``; return the number of items."""
        return _last_int(self.command(Dwell(ms).command()), "WAIT")

    def load(self, programme: Programme, start_position: int = 0) -> int:
        """Check ``programme`` against the limits (nothing is sent if it fails), then ``CLEAR`` and load it.

        Returns
        -------
        int
            Items on the board.
        """
        check_programme(programme, start_position)
        for attempt in range(1, SEND_ATTEMPTS + 1):
            n = 0
            try:
                for line in programme.commands():  # CLEAR first: loading again starts from nothing
                    reply = self.command(line)
                    if line != "CLEAR":
                        n = _last_int(reply, line.split()[0])
            except LinkCorrupted:
                if attempt == SEND_ATTEMPTS:
                    raise
                continue  # a reply to SEG or WAIT was lost on the link: load the whole programme again
            break
        if n != len(programme):
            raise BoardError(f"the stepper board holds {n} items, the programme has {len(programme)}")
        return n

    def go(self) -> int:
        """``GO``: start the loaded programme (``DONE`` arrives when it ends)."""
        self.done_position = None
        return _last_int(self.command("GO"), "GO")

    def abort(self, timeout: float | None = None) -> int:
        """``ABORT``: stop at once and disable the driver; return the position."""
        return _last_int(self.command("ABORT", timeout=timeout), "ABORT")

    def enable(self, on: bool, timeout: float | None = None) -> None:
        """``EN 1`` / ``EN 0`` (``EN 0`` while running aborts first)."""
        self.command(f"EN {1 if on else 0}", timeout=timeout)

    def position(self) -> int:
        """``POS``: the present position in steps."""
        return _last_int(self.command("POS"), "POS")

    def poll(self) -> None:
        """Read whatever has arrived without waiting (picks up ``DONE``, ``HELLO``)."""
        self.pump(block=False)

    # --- streaming mode (PROTOCOL.md "Stepper board: streaming mode") --------------------------------
    def load_shaper(self, shaper: StreamShaper) -> None:
        """``SHAPER`` and one ``IMP`` per impulse: load the shaper the next streams use."""
        for attempt in range(1, SEND_ATTEMPTS + 1):
            try:
                for line in shaper.commands():  # SHAPER first: loading again discards what was loaded
                    self.command(line)
            except LinkCorrupted:
                if attempt == SEND_ATTEMPTS:
                    raise
                continue
            return

    def start_stream(self) -> int:
        """``STREAM``: start streaming from the present position (returned); the notices list is emptied."""
        self.done_position = None
        self.notices.clear()
        return _last_int(self.command("STREAM"), "STREAM")

    def set_point(self, units: int) -> int | None:
        """``V <units>``: queue a set-point; return the period it drives, or None if the FIFO was full.

        A full FIFO (``ERR FULL``) drops the set-point: send it again later. Any other refusal raises
        :class:`helpers.rig.CommandRefused`.
        """
        try:
            return _last_int(self.command(f"V {units}"), "V")
        except CommandRefused as exc:
            if exc.code == "FULL":
                return None
            raise

    def end_stream(self) -> int:
        """``END``: the stream ends after the queued set-points; return the first period fed with zero."""
        return _last_int(self.command("END"), "END")
