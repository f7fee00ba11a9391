"""A session on a rig with several tendons: the folder's lock, the boards connected and checked at rest.

``record move`` and ``record tip-stream`` both plan from rest; this is where they connect, refuse a stepper
that does not stand at rest and say which firmware answered.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from helpers.base.locks import folder_lock
from helpers.rig import Rig, SafetyError

SESSION_LOCK = ".recording.lock"
"""The lock beside a group's folder: one recording session per folder at a time."""


@contextmanager
def tendons_at_rest(args: argparse.Namespace, rig: Any, what: str) -> Iterator[tuple[Rig, int | None]]:
    """Lock ``args.group``, connect the boards and check every tendon stands at rest (position 0).

    Parameters
    ----------
    args : argparse.Namespace
        The command's arguments (``data_dir``, ``group``, ``ports``, ``rig_name``, ``seed``).
    rig : RigFile
        The rig file.
    what : str
        What is planned from rest (``a move``, ``a tip stream``), for the refusal.

    Yields
    ------
    tuple
        The connected :class:`~helpers.rig.Rig` and the virtual rig's noise seed for the run (None on
        hardware).

    Raises
    ------
    SafetyError
        If the stepper does not stand at rest.
    """
    with folder_lock(args.data_dir / args.group, what="recording", name=SESSION_LOCK, beside=True):
        with Rig(args.ports, rig, world=args.rig_name) as trig:
            at = trig.positions()
            if any(at):
                raise SafetyError(
                    f"tendons 1-{rig.n_tendons}: the stepper stands at {at}, not at rest (0): "
                    f"{what} is planned from rest; run python -m helpers home first"
                )
            print(f"connected: daq firmware {trig.daq.version}, stepper firmware {trig.stepper.version}")
            yield trig, (args.seed if trig.world is not None else None)
