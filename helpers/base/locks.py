"""Advisory folder locks (``fcntl.flock``): one writer at a time, and never stuck after a crash.

The kernel releases a ``flock`` when its process ends, however it ends, so a crashed recorder leaves no stale
lock behind. The lock file (``.lock`` in the folder, ignored by git) holds the owner's pid for the message a
second process sees. :func:`take_lock` takes every lock of the package's files: a folder's lock here, and the
recordings' store's shared reader lock and name reservations.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

LOCK_NAME = ".lock"


class FolderBusy(RuntimeError):
    """Another process holds the folder's lock; the message names the folder and that process."""


def _holder(path: Path) -> str:
    try:
        pid = path.read_text().strip()
    except OSError:
        return "another process"
    return f"process {pid}" if pid.isdigit() else "another process"


def take_lock(path: Path, busy: Callable[[str], Exception], wait_s: float = 0.0, shared: bool = False) -> int:
    """Open ``path`` (created if missing), hold its ``flock`` and return its descriptor (close it to let go).

    Parameters
    ----------
    path : pathlib.Path
        The lock file.
    busy : callable
        Makes the error raised when another process still holds the lock after ``wait_s``, from who holds it
        (``"process <pid>"``, or ``"another process"``).
    wait_s : float
        How long to wait for another holder to finish (0: refuse at once).
    shared : bool
        Hold it shared (readers do not block each other; a writer waits for them); an exclusive holder writes
        its pid into the file.

    A holder may remove the file when it lets go (the store's reservations do): a lock taken on a file that is
    no longer at ``path`` is dropped and taken again on the new one.
    """
    deadline = time.monotonic() + max(0.0, wait_s)
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, (fcntl.LOCK_SH if shared else fcntl.LOCK_EX) | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            if time.monotonic() >= deadline:
                raise busy(_holder(path)) from None
            time.sleep(0.02)
            continue
        with contextlib.suppress(FileNotFoundError):  # removed meanwhile by a holder letting go: try again
            if os.path.samestat(os.fstat(fd), os.stat(path)):
                break
        os.close(fd)
    if not shared:
        os.ftruncate(fd, 0)
        os.write(fd, str(os.getpid()).encode())
    return fd


@contextmanager
def folder_lock(
    folder: str | os.PathLike,
    wait_s: float = 0.0,
    what: str = "writing",
    name: str = LOCK_NAME,
    beside: bool = False,
) -> Iterator[Path]:
    """Hold ``folder``'s lock for the ``with`` block (created if missing).

    Parameters
    ----------
    folder : path-like
        The folder to lock.
    wait_s : float
        How long to wait for another holder to finish (0: refuse at once).
    what : str
        What the holder is doing, for the message.
    name : str
        The lock file's name (one folder may carry independent locks for different purposes).
    beside : bool
        Keep the lock file beside the folder (``.<folder><name>`` in its parent) rather than in it, so that
        deleting the folder while it is held does not let a second holder in.

    Raises
    ------
    FolderBusy
        If another process still holds the lock after ``wait_s``.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder.parent / f".{folder.name}{name}" if beside else folder / name

    def busy(who: str) -> FolderBusy:
        return FolderBusy(f"{folder} is busy: {who} is {what} there; wait for it or use another folder")

    fd = take_lock(path, busy, wait_s)
    try:
        yield path
    finally:
        os.close(fd)  # releases the lock
