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
from helpers.board.programmes import Programme, Segment
from helpers.paper.hardware import MAX_SPEED_MM_S, MM_PER_STEP
from helpers.rig.boards import BoardError, BoardTimeout
from helpers.rig.discovery import find_rig_ports
from helpers.rig.safety import SafetyError, check_programme
from helpers.rig.stepper import StepperBoard
from helpers.rig.tendon_safety import TendonItem, TendonProgramme, check_tendon_programme

HOME_SPEED_MM_S = 50.0
"""Cable speed of the way home, mm/s (gentle: a quarter of the experiments' slowest move)."""


class PositionUnknown(SafetyError):
    """The stepper board rebooted, so nobody knows where the cable is; the user must confirm it is slack."""


def home_programme(position: int, speed_mm_s: float = HOME_SPEED_MM_S) -> Programme:
    """The programme that moves the cable from ``position`` (steps) to 0 at ``speed_mm_s``."""
    if position == 0:
        raise ValueError("the cable is at 0 already: there is nothing to move")
    interval = max(1, round(MM_PER_STEP / speed_mm_s * 1e6))
    return Programme((Segment(-1 if position > 0 else 1, abs(position), interval),))


def _rest_state(tendons: int) -> str:
    """What the rest (position 0) is, for the user to set up by hand.

    The paper's one cable slack, or several tendons at their pretension.
    """
    if tendons > 1:
        return "every tendon is at its rest pretension (the arm straight, at rest)"
    return "the cable is slack and the arm down at rest"


def home(stepper: StepperBoard, confirm_slack: bool = False, speed_mm_s: float = HOME_SPEED_MM_S) -> str:
    """Return the cable to 0 (or accept 0 where the user confirmed the rest state); return what happened.

    The rest state to confirm is the selected rig file's: on a rig of several tendons every tendon at its
    rest pretension, else the cable slack.

    Raises
    ------
    PositionUnknown
        The board rebooted as its port opened and ``confirm_slack`` is False.
    helpers.rig.BoardError
        The board refused or stopped answering (the driver is disabled on the way out either way).
    """
    if stepper.booted_on_open:
        tendons = rigfile.selected().n_tendons
        what = "every tendon's" if tendons > 1 else "the cable's"
        if not confirm_slack:
            raise PositionUnknown(
                f"the stepper board restarted when its port opened, so {what} position is unknown (there "
                f"is no limit switch): make sure {_rest_state(tendons)}, then run "
                "`python -m helpers home --confirm-slack` to count from there"
            )
        stepper.enable(False)
        if tendons > 1:
            return (
                "every tendon was confirmed at its rest pretension: the stepper counts from 0 here "
                "(driver disabled)"
            )
        return "the cable was confirmed slack: the stepper counts from 0 here (driver disabled)"
    # ABORT first: a programme or stream an earlier session left running stops (CLEAR would be refused while
    # it runs), the driver goes off, and the reply says where the cable is
    reply = stepper.command("ABORT")
    words = reply.split()[1:]
    if not words or not all(w.lstrip("-").isdigit() for w in words):
        raise BoardError(f"the stepper board's reply to ABORT is malformed: {reply!r}")
    positions = tuple(int(w) for w in words)
    if len(positions) > 1:  # a build for several tendons: every axis's position, every axis homed at once
        return _home_every_axis(stepper, positions, speed_mm_s)
    position = positions[0]
    if position == 0:
        stepper.enable(False)
        return "the cable is at position 0 already (driver disabled)"
    programme = home_programme(position, speed_mm_s)
    check_programme(programme, start_position=position)
    stepper.load(programme, start_position=position)
    _run_home(stepper, programme.duration_s)
    return (
        f"moved {abs(position)} steps ({abs(position) * MM_PER_STEP:.2f} mm) back to position "
        f"{stepper.done_position} at {speed_mm_s:g} mm/s (driver disabled)"
    )


def _run_home(stepper: StepperBoard, duration_s: float) -> None:
    """Run the loaded homing programme of ``duration_s`` until ``DONE``; the driver off afterwards, always."""
    try:
        stepper.enable(True)
        stepper.go()
        wait = stepper.waiter(duration_s + 2.0)
        while stepper.done_position is None:
            stepper.pump()
            stepper.check_reset()
            if wait.expired:
                raise BoardTimeout("the stepper board did not report DONE on its way home")
            wait.idle(stepper.port.timeout or 0.0)
    finally:
        try:
            stepper.enable(False)
        except BoardError:
            pass


def _home_every_axis(stepper: StepperBoard, positions: tuple[int, ...], speed_mm_s: float) -> str:
    """Every axis back to 0 in one ``MSEG`` at ``speed_mm_s`` for the farthest one (the others slower)."""
    if not any(positions):
        stepper.enable(False)
        return f"every tendon is at position 0 already ({len(positions)} axes; driver disabled)"
    interval = max(1, round(MM_PER_STEP / speed_mm_s * 1e6))
    rig = rigfile.selected()  # transitional: the one driver (issue 36) carries the rig
    window = interval * max(map(abs, positions))
    if rig.n_tendons == len(positions):  # the per-tendon limits (docs/safety.md), homing to the rest state
        back = TendonProgramme((TendonItem(window, tuple(-p for p in positions)),))
        check_tendon_programme(back, rig, positions, rest_ok=True)
    stepper.send_all(["CLEAR", f"MSEG {window} " + " ".join(str(-p) for p in positions)])
    _run_home(stepper, window * 1e-6)
    now = stepper.command("POS").split()[2:]
    moved = ", ".join(f"tendon {i + 1} {abs(p)}" for i, p in enumerate(positions) if p)
    return (
        f"moved every tendon back to position 0 ({moved} steps; the farthest at {speed_mm_s:g} mm/s): "
        f"positions {' '.join(now)} (driver disabled)"
    )


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
        type=arg_number(0, MAX_SPEED_MM_S, lo_open=True),
        default=HOME_SPEED_MM_S,
        help="cable speed on the way home, mm/s",
    )


def _stepper_url(ports: str, rig_name: str) -> str:
    if ports == "virtual":
        return f"virtual://stepper?rig={rig_name}"
    if ports == "auto":
        return find_rig_ports()[1]
    parts = [p.strip() for p in ports.split(",")]
    return parts[-1]


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
    stepper = StepperBoard.open(_stepper_url(args.ports, args.rig_name), rig=args.rig)
    try:
        print(home(stepper, confirm_slack=args.confirm_slack, speed_mm_s=args.speed))
    finally:
        stepper.close()
    return 0


__all__ = ["HOME_SPEED_MM_S", "PositionUnknown", "home", "home_programme"]
