"""Ending a run cleanly however it ends: SIGTERM and SIGHUP as interrupts, and no interrupt mid-save.

:func:`interrupts_from_signals` turns SIGTERM and SIGHUP into :class:`Interrupted` (a ``KeyboardInterrupt``),
so that the same guard that handles Ctrl-C aborts the stepper, disables the driver, stops the DAQ and saves
what was recorded. :func:`signals_held` blocks SIGINT, SIGTERM and SIGHUP while that cleanup and the save run,
so a second Ctrl-C cannot cut a save in half; a signal that arrives meanwhile is delivered afterwards.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

HELD = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class Interrupted(KeyboardInterrupt):
    """A run was interrupted by a signal (``signum``): treated exactly like Ctrl-C."""

    def __init__(self, signum: int) -> None:
        super().__init__(f"interrupted by {signal.Signals(signum).name}")
        self.signum = signum


def _raise(signum: int, frame: object) -> None:
    raise Interrupted(signum)


@contextmanager
def interrupts_from_signals() -> Iterator[None]:
    """Within the block, SIGTERM and SIGHUP raise :class:`Interrupted` (main thread only; else a no-op)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.signal(s, _raise) for s in (signal.SIGTERM, signal.SIGHUP)}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


@contextmanager
def signals_held() -> Iterator[None]:
    """Block SIGINT, SIGTERM and SIGHUP for the block; any that arrived are delivered when it ends."""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, HELD)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
