"""Ending a run cleanly however it ends: SIGTERM and SIGHUP as interrupts, and no interrupt mid-save.

:func:`interrupts_from_signals` turns SIGINT, SIGTERM and SIGHUP into :class:`Interrupted` (a
``KeyboardInterrupt``), so that the same guard that handles Ctrl-C aborts the stepper, disables the driver,
stops the DAQ and saves what was recorded.

:func:`signals_held` **defers** those signals for a block (a save, the parser's counts): the handler notes
a signal that arrives meanwhile and it is delivered when the block ends. The deferral is done by the
handler itself (installed for the block if it is not already), not by masking the thread: the kernel may
hand a process's signal to any thread, and Python then runs the handler in the main thread whatever the
main thread's mask is.

:func:`run_guard` is what an experiment runs in: signals are deferred except inside its
:meth:`Guard.interruptible` part (the run), and there only the **first** one raises; the handler itself
then defers every later one, so nothing can interrupt the cleanup and the save that follow, not even a
signal that arrives between the run's end and the save's start (the gap a ``with signals_held()`` written
after the run would leave open). The signals deferred during a guard are in :attr:`Guard.pending`.

All of this works in the main thread; elsewhere (where Python cannot install handlers) it does nothing.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

HELD = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class Interrupted(KeyboardInterrupt):
    """A run was interrupted by a signal (``signum``): treated exactly like Ctrl-C."""

    def __init__(self, signum: int) -> None:
        name = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
        super().__init__(f"interrupted by {name}")
        self.signum = signum


@dataclass
class _State:
    depth: int = 0
    """> 0: signals are deferred."""
    armed: bool = False
    """An interruptible part is running: the next signal raises (once) and latches the deferral."""
    pending: list[int] = field(default_factory=list)
    installed: bool = False
    """An :func:`interrupts_from_signals` block has put :func:`_handler` in place (and restores)."""


_state = _State()


def _handler(signum: int, frame: object) -> None:
    if _state.depth > 0:
        _state.pending.append(signum)
        return
    if _state.armed:  # the first signal of a guarded run: from now on, defer (the cleanup must not be cut)
        _state.armed = False
        _state.depth += 1
    raise Interrupted(signum)


def _at_once(signum: int, frame: object) -> None:
    sys.stderr.write(f"{Interrupted(signum)} (nothing was running)\n")  # stderr is line-buffered
    os._exit(128 + signum)


def end_at_once_on_signals() -> None:
    """SIGINT, SIGTERM and SIGHUP end the process at once: one line on stderr, status 130, 143 or 129.

    For a command line while it starts (its modules load, its arguments are parsed), when nothing is open
    yet: an exception raised by a handler could land in an import's clean-up callback, where Python ignores
    it and the command would run on. The command itself then runs under :func:`interrupts_from_signals`.
    Main thread only (elsewhere a no-op).
    """
    if threading.current_thread() is threading.main_thread():
        for s in HELD:
            signal.signal(s, _at_once)


@contextmanager
def interrupts_from_signals() -> Iterator[bool]:
    """Within the block, SIGINT, SIGTERM and SIGHUP raise :class:`Interrupted` (main thread; else a no-op).

    Installs :func:`_handler` for :data:`HELD` for the block; yields whether it could (only the main thread
    can).
    """
    if threading.current_thread() is not threading.main_thread():
        yield False
        return
    if _state.installed:  # inside such a block: the handler is in place (and is restored by that block)
        yield True
        return
    previous = {s: signal.signal(s, _handler) for s in HELD}
    _state.installed = True
    try:
        yield True
    finally:
        _state.installed = False
        for s, h in previous.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)


@contextmanager
def signals_held() -> Iterator[tuple[bool, int]]:
    """Defer SIGINT, SIGTERM and SIGHUP for the block; one that arrived is delivered when the block ends.

    If the block ends with an exception, that exception goes on and a deferred signal is dropped (it asked
    to stop, and the run is stopping). Only a signal deferred at the outermost level is delivered. Yields
    whether the handler is installed and the depth of deferral before the block (for :func:`run_guard`).
    """
    with interrupts_from_signals() as installed:
        if not installed:
            yield False, _state.depth
            return
        base = _state.depth
        _state.depth = base + 1
        failed = True
        try:
            yield True, base
            failed = False
        finally:
            _state.depth = base
            pending = [] if base else _state.pending[:]
            if not base:
                _state.pending.clear()
    if not failed and pending:  # delivered again to whatever handles it now (ours raises, the default kills)
        signal.raise_signal(pending[0])


@dataclass
class Guard:
    """A guarded run (:func:`run_guard`): where signals may interrupt, and which arrived while deferred."""

    installed: bool
    base: int = 0

    @contextmanager
    def interruptible(self) -> Iterator[None]:
        """The run: the first signal raises :class:`Interrupted`; every later one is deferred."""
        if not self.installed:
            yield
            return
        _state.depth = self.base
        _state.armed = True
        try:
            yield
        finally:  # defer again (a signal arriving right now latches the same way, then raises)
            _state.depth = self.base + 1
            _state.armed = False

    def take_pending(self) -> int | None:
        """The first signal deferred so far (None: none), and forget them (the caller reports it itself)."""
        signum = _state.pending[0] if _state.pending else None
        if not self.base:
            _state.pending.clear()
        return signum


@contextmanager
def run_guard() -> Iterator[Guard]:
    """Defer SIGINT, SIGTERM and SIGHUP except in the guard's :meth:`Guard.interruptible` part (module doc).

    A signal deferred in the guard and not taken (:meth:`Guard.take_pending`) is delivered when the guard
    ends without an exception; with one, that exception goes on.
    """
    with signals_held() as (installed, base):
        try:
            yield Guard(installed, base)
        finally:
            if installed:
                _state.armed = False
