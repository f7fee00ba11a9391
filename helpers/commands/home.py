"""``python -m helpers home``: bring the cable back to position 0 safely, from where the stepper says it is.

A stepper built for several tendons (its ``ABORTED`` lists every axis) has every tendon brought back at once,
in one ``MSEG`` item (the farthest at the home speed), checked against every tendon's limits first. There
position 0 is the rest (every tendon at its pretension; a tendon paid out below it, a negative position, is
pulled back up to it).

The stepper board counts its position from zero since it booted; there is no limit switch. So:

- if the board kept running (a pseudo-terminal of ``serve-virtual-rig``, or hardware whose reset-on-open is
  disabled), ``POS`` is the cable's position and ``home`` moves it back to 0 at a gentle speed, then disables
  the driver;
- if the board rebooted when its port opened (an Arduino resets when the port opens; the in-process virtual
  rig does the same), the position is **unknown**: ``home`` says so and asks the user to make sure the cable
  is slack (the arm down, at rest; on a rig of several tendons: every tendon at its rest pretension, the arm
  straight) and to confirm with ``--confirm-slack``; the board's count then starts from 0 there.
"""

from __future__ import annotations

import argparse
import math

from helpers import rigfile
from helpers.base.cli import DefaultsHelp, arg_number, arg_rig_name
from helpers.board.programmes import Move, Programme, Segment
from helpers.rig.link import BoardError, Link, ints
from helpers.rig.ports import rig_urls
from helpers.rig.safety import SafetyError, check_programme
from helpers.rigfile import RigFile

HOME_SPEED_MM_S = 50.0
"""Cable speed of the way home, mm/s (gentle: a quarter of the experiments' slowest move)."""

SILENCE_S = 2.0
"""Seconds the stepper board may take to answer ``POS`` on its way home before it counts as gone."""


class PositionUnknown(SafetyError):
    """The stepper board rebooted, so nobody knows where the cable is; the user must confirm it is slack."""


def home_programme(
    positions: tuple[int, ...], mm_per_step: float, speed_mm_s: float = HOME_SPEED_MM_S
) -> Programme:
    """The programme that moves every tendon from ``positions`` (steps) to 0 in one item.

    The farthest at ``speed_mm_s`` (``mm_per_step`` is its); one tendon: a ``SEG``, several: one ``MSEG``.
    """
    if not any(positions):
        raise ValueError("every tendon is at 0 already: there is nothing to move")
    interval = max(1, round(mm_per_step / speed_mm_s * 1e6))
    if len(positions) == 1:
        return Programme((Segment(-1 if positions[0] > 0 else 1, abs(positions[0]), interval),))
    return Programme((Move(interval * max(map(abs, positions)), tuple(-p for p in positions)),))


def _rest_state(tendons: int) -> str:
    """What the rest (position 0) is, for the user to set up by hand: one cable slack, or every pretension."""
    if tendons > 1:
        return "every tendon is at its rest pretension (the arm straight, at rest)"
    return "the cable is slack and the arm down at rest"


def home(
    stepper: Link, rig: RigFile, confirm_slack: bool = False, speed_mm_s: float = HOME_SPEED_MM_S
) -> str:
    """Return every tendon to 0 (or accept 0 where the user confirmed the rest state); return what happened.

    ``ABORT`` first: a programme or stream an earlier session left running stops, the driver goes off, and the
    reply says where the tendons are. The way home is checked against every tendon's limits, then run until
    ``DONE``: while ``POS`` shows the board moving it is alive; a board that stops short fails, and one that
    does not answer ``POS`` within :data:`SILENCE_S` is gone. The driver is disabled on the way out, always.

    Raises
    ------
    PositionUnknown
        The board rebooted as its port opened and ``confirm_slack`` is False.
    helpers.rig.BoardError
        The board refused or stopped answering.
    """
    n = rig.n_tendons
    if stepper.booted_on_open:
        what = "every tendon's" if n > 1 else "the cable's"
        if not confirm_slack:
            raise PositionUnknown(
                f"the stepper board restarted when its port opened, so {what} position is unknown (there "
                f"is no limit switch): make sure {_rest_state(n)}, then run "
                "`python -m helpers home --confirm-slack` to count from there"
            )
        stepper.command("EN 0")
        if n > 1:
            return (
                "every tendon was confirmed at its rest pretension: the stepper counts from 0 here "
                "(driver disabled)"
            )
        return "the cable was confirmed slack: the stepper counts from 0 here (driver disabled)"
    positions = ints(stepper.command("ABORT"), 1)[:n]
    if not any(positions):
        stepper.command("EN 0")
        return "every tendon is at position 0 already (driver disabled)" if n > 1 else \
            "the cable is at position 0 already (driver disabled)"
    far = max(range(n), key=lambda i: abs(positions[i]))
    programme = home_programme(positions, rigfile.derived(rig).mm_per_step[far], speed_mm_s)
    check_programme(programme, rig, positions, rest_ok=True)
    try:
        stepper.send_all(programme.commands(len(positions)))
        stepper.command("EN 1")
        stepper.done = None
        stepper.command("GO")
        last = None
        while stepper.done is None:
            wait = stepper.waiter(0.25)
            while stepper.done is None and not wait.expired:
                stepper.read(wait)
                stepper.check_reset()
            where = ints(stepper.command("POS", timeout=SILENCE_S))[:n]
            if stepper.done is None and where == last:
                raise BoardError(f"the stepper board stopped at {where} steps on its way home, without DONE")
            last = where
    finally:
        try:
            stepper.command("EN 0")
        except BoardError:
            pass
    moved = ", ".join(f"tendon {i + 1} {abs(p)}" for i, p in enumerate(positions) if p) if n > 1 else None
    moved = moved or abs(positions[0])
    mm = abs(positions[far]) * rigfile.derived(rig).mm_per_step[far]
    at = " ".join(map(str, stepper.done))
    return (f"moved {moved} steps ({mm:.2f} mm{' the farthest' if n > 1 else ''}) back to position 0 at "
            f"{speed_mm_s:g} mm/s: positions {at} (driver disabled)")  # fmt: skip


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``home`` options."""
    parser.formatter_class = DefaultsHelp
    parser.add_argument(
        "--ports",
        default="virtual",
        help="'virtual' (in-process virtual rig), 'auto' (USB discovery), 'DAQ,STEPPER' or the stepper port",
    )
    parser.add_argument(
        "--virtual-instance",
        "--rig-name",
        dest="rig_name",
        default="record",
        type=arg_rig_name,
        help="name of the in-process virtual rig instance (--rig-name: its old spelling)",
    )
    parser.add_argument(
        "--confirm-slack",
        action="store_true",
        help="after a board restart: I checked the rest state (the cable slack and the arm down; several "
        "tendons: every tendon at its rest pretension); count from here",
    )
    parser.add_argument(
        "--speed",
        type=arg_number(0, 1e6, lo_open=True),
        default=HOME_SPEED_MM_S,
        help="cable speed on the way home, mm/s, in (0, the rig's speed_limit_mm_s]",
    )


def run(args: argparse.Namespace) -> int:
    """Run ``python -m helpers home``."""
    if not math.isfinite(args.speed):
        raise SystemExit("--speed must be finite")
    if args.ports == "virtual":  # a new in-process rig is made for this command: it is at 0 by construction
        print(
            "the in-process virtual rig is made anew by every command, at rest at position 0: nothing to "
            "home (a virtual rig that keeps running is serve-virtual-rig's: home --ports DAQ,STEPPER)"
        )
        return 0
    rig = args.rig
    if args.speed > rig.hardware.speed_limit_mm_s:
        raise ValueError(f"--speed {args.speed:g} mm/s: rig {rig.name!r} moves at most "
                         f"{rig.hardware.speed_limit_mm_s:g} mm/s (speed_limit_mm_s)")  # fmt: skip
    alone = "," not in args.ports and args.ports != "auto"  # the stepper's port
    try:
        url = args.ports if alone else rig_urls(args.ports, rig, "")[1]
    except ValueError:
        raise ValueError(f"--ports {args.ports!r}: home takes 'virtual', 'auto', 'DAQ,STEPPER' or the "
                         "stepper's port alone") from None  # fmt: skip
    stepper = Link.open(url, "stepper", rig, rig.hardware.stepper_baud)
    try:
        print(home(stepper, rig, confirm_slack=args.confirm_slack, speed_mm_s=args.speed))
    finally:
        stepper.close()
    return 0


__all__ = ["HOME_SPEED_MM_S", "PositionUnknown", "home", "home_programme"]
