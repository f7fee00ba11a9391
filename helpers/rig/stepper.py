"""Driver of the stepper board (Arduino Uno + TB6600, 115200 baud): programmes and streams.

Programme mode: load, go, abort, enable, position. The streaming mode's commands (load a shaper, start a
stream, send set-points, end it) are :mod:`helpers.rig.stream_rig`'s; the notices of a stream are collected
here, as they may arrive between any two replies.
"""

from __future__ import annotations

from typing import Any

from helpers.board.programmes import Dwell, Item, Programme, Segment
from helpers.paper.hardware import STEPPER_BAUD
from helpers.rig.boards import SEND_ATTEMPTS, BoardError, BoardLink, LinkCorrupted
from helpers.rig.safety import check_programme


def programme_from_dict(data: dict[str, Any]) -> Programme:
    """Rebuild a programme from :meth:`Programme.to_dict` output (``duration_s``/``net_steps`` are checked).

    Parameters
    ----------
    data : dict
        ``{"items": [{"kind": "SEG", ...} | {"kind": "WAIT", "ms": ...}, ...], ...}``, as a recording's
        ``scenario["programme"]``.

    Returns
    -------
    Programme
    """
    if not isinstance(data, dict) or not isinstance(data.get("items"), list):
        raise ValueError("a programme dict needs an 'items' list")
    items: list[Item] = []
    for i, d in enumerate(data["items"]):
        kind = d.get("kind") if isinstance(d, dict) else None
        if kind == "SEG":
            items.append(Segment(d.get("direction"), d.get("n_steps"), d.get("interval_us")))
        elif kind == "WAIT":
            items.append(Dwell(d.get("ms")))
        else:
            raise ValueError(f"programme item {i}: unknown kind {kind!r} (expected 'SEG' or 'WAIT')")
    prog = Programme(tuple(items))
    if "net_steps" in data and data["net_steps"] != prog.net_steps:
        raise ValueError(
            f"programme dict says net_steps={data['net_steps']}, its items give {prog.net_steps}"
        )
    if "duration_s" in data and abs(float(data["duration_s"]) - prog.duration_s) > 1e-9:
        raise ValueError(
            f"programme dict says duration_s={data['duration_s']}, its items give {prog.duration_s}"
        )
    return prog


def last_int(reply: str, what: str) -> int:
    """The integer a stepper board's reply ends with (``OK SEG 3`` -> 3); ``BoardError`` if it has none."""
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

    def load(self, programme: Programme, start_position: int = 0) -> int:
        """Check ``programme`` against the limits (nothing is sent if it fails), then ``CLEAR`` and load it.

        Returns
        -------
        int
            Items on the board.
        """
        check_programme(programme, start_position)
        lines = programme.commands()
        replies = self.send_all(lines)  # CLEAR first: loading again starts from nothing
        n = [last_int(reply, line.split()[0]) for line, reply in zip(lines[1:], replies[1:], strict=True)][-1]
        if n != len(programme):
            raise BoardError(f"the stepper board holds {n} items, the programme has {len(programme)}")
        return n

    def go(self) -> int:
        """``GO``: start the loaded programme (``DONE`` arrives when it ends)."""
        self.done_position = None
        return last_int(self.command("GO"), "GO")

    def abort(self, timeout: float | None = None) -> int:
        """``ABORT``: stop at once and disable the driver; return the position."""
        return last_int(self.command("ABORT", timeout=timeout), "ABORT")

    def enable(self, on: bool, timeout: float | None = None) -> None:
        """``EN 1`` / ``EN 0`` (``EN 0`` while running aborts first)."""
        self.command(f"EN {1 if on else 0}", timeout=timeout)

    def position(self) -> int:
        """``POS``: the present position in steps."""
        return last_int(self.command("POS"), "POS")

    def poll(self) -> None:
        """Read whatever has arrived without waiting (picks up ``DONE``, ``HELLO``)."""
        self.pump(block=False)

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
