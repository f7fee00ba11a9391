"""One recording session on a rig of 1 to 4 tendons: the groups' locks, the boards connected, the noise seed.

Every ``record`` command (``calibration``, ``pulse``, ``table-i``, ``all``, ``streams``, ``move``,
``tip-stream``) records inside :func:`recording_session`: one recorder per group folder at a time, the boards
opened through :class:`helpers.rig.Rig`, the firmware that answered printed, and the virtual rig's noise seed
for the run (None on hardware). Commands that plan from rest (``move``, ``tip-stream``) have the stepper's
positions checked before anything is sent, and are given their run's guard (:func:`tension_guard`).
"""

from __future__ import annotations

import argparse
from collections.abc import Iterable, Iterator
from contextlib import ExitStack, contextmanager

from helpers.base.locks import folder_lock
from helpers.rig import Rig, SafetyError
from helpers.rig.trim import TensionGuard
from helpers.rigfile import RigFile

SESSION_LOCK = ".recording.lock"
"""The lock beside a group's folder: one recording session per folder at a time."""


@contextmanager
def recording_session(
    args: argparse.Namespace, groups: Iterable[str] = (), *, calibration: object = None,
    from_rest: str | None = None,
) -> Iterator[tuple[Rig, int | None]]:  # fmt: skip
    """Lock the groups, connect the boards of ``args.rig`` and, if asked, check every tendon stands at rest.

    Parameters
    ----------
    args : argparse.Namespace
        The command's arguments (``data_dir``, ``group``, ``ports``, ``rig``, ``rig_name``, ``seed``).
    groups : iterable of str
        The group folders to lock (default ``args.group`` alone); each is locked beside its folder, so that
        deleting the folder cannot let a second recorder in.
    calibration : LoadCellCalibration or sequence of them, optional
        Passed to :class:`~helpers.rig.Rig` (default there: tendon 1's saved calibration for one tendon, the
        rig file's nominal chain for several).
    from_rest : str, optional
        What is planned from rest (``a move``, ``a tip stream``): if given, a stepper that does not stand at
        position 0 on every tendon is refused, naming it.

    Yields
    ------
    tuple
        The connected :class:`~helpers.rig.Rig` and the virtual rig's noise seed for the run (``args.seed``;
        None on hardware).

    Raises
    ------
    SafetyError
        If ``from_rest`` is given and the stepper does not stand at rest.
    """
    rig = args.rig
    with ExitStack() as stack:
        for group in sorted(set(groups) or {args.group}):  # one recorder per group at a time
            stack.enter_context(
                folder_lock(args.data_dir / group, what="recording", name=SESSION_LOCK, beside=True)
            )
        trig = stack.enter_context(Rig(args.ports, rig, calibration=calibration, world=args.rig_name))
        if from_rest is not None and any(at := trig.positions()):
            raise SafetyError(
                f"tendons 1-{rig.n_tendons}: the stepper stands at {at}, not at rest (0): "
                f"{from_rest} is planned from rest; run python -m helpers home first"
            )
        print(
            f"connected: daq firmware {trig.daq.version}, stepper firmware {trig.stepper.version}, "
            f"source {trig.source['kind']}"
        )
        yield trig, (args.seed if trig.world is not None else None)


def tension_guard(args: argparse.Namespace, rig: RigFile) -> TensionGuard:
    """The guard of a motion of several tendons that ``--trim`` and ``--no-floor-watch`` ask for.

    The trim's targets are the planner's static tension at the rest the motion starts from: each tendon's
    ``pretension_n`` (a pre-pull is part of the motion that follows the trim).
    """
    targets = [t.pretension_n for t in rig.tendons] if args.trim else None
    return TensionGuard(targets, watch=not args.no_floor_watch)
