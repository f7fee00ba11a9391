"""Test doubles for the tests of several tendons: a clock an emulated board reads, and a way to talk to it."""

from __future__ import annotations

from helpers.board.protocol import frame


class Clock:
    """The world's attributes an emulated board reads, with the device time held at 0."""

    def __init__(self) -> None:
        self.t, self.seed, self.t0_us, self.go_times = 0.0, 0, 0, []


def talk(board, *cmds: str) -> list[str]:
    """Send each command (framed) to an emulated board; its replies' bodies, in order."""
    out = []
    for c in cmds:
        board.receive(frame(c))
        out += [line.decode().rstrip("\n").rpartition("*")[0] for line in board.out]
        board.out.clear()
    return out
