"""``python -m helpers frame``: the command lines to type into a serial terminal, with their CRC-8.

Every command must carry its ``*hh`` (``firmware/PROTOCOL.md``); a person at a terminal cannot compute a
CRC-8 in their head. ``python -m helpers frame PING "RATE 500"`` prints ``PING*79`` and ``RATE 500*7A``,
ready to paste into a terminal such as ``python -m serial.tools.miniterm --eol LF /dev/ttyACM0 500000``.
Without arguments it frames every line read from standard input.
"""

from __future__ import annotations

import argparse
import sys

from helpers.board.protocol import frame


def framed_lines(bodies: list[str]) -> list[str]:
    """Each command body with its ``*hh`` appended (no newline).

    Raises
    ------
    ValueError
        For a body the protocol cannot carry (not printable ASCII, a ``*``, too long), naming it.
    """
    return [frame(body).decode("ascii").rstrip("\n") for body in bodies]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``frame`` arguments."""
    parser.add_argument("command", nargs="*", help="command bodies, e.g. PING 'RATE 500' (default: stdin)")


def run(args: argparse.Namespace) -> int:
    """Print each command with its CRC-8."""
    bodies = args.command or [line.rstrip("\r\n") for line in sys.stdin]
    for line in framed_lines([b for b in bodies if b]):
        print(line)
    return 0
