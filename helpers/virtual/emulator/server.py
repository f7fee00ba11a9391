"""``python -m helpers serve-virtual-rig --rig FILE``: a rig file's two emulated boards on pseudo-terminals.

Builds the world of the rig file (:func:`helpers.virtual.emulator.world.build_world`: the boards built for
its tendons, the planar or the spatial twin), creates two pseudo-terminals (``os.openpty``, raw mode),
prints their device paths::

    daq /dev/pts/5
    stepper /dev/pts/6

and serves the emulated boards (:mod:`helpers.virtual.emulator.boards`) on them until interrupted, so that any
program, including a notebook's live cells, can connect by device path exactly as to the hardware
(``Rig(("/dev/pts/5", "/dev/pts/6"), rig)``).

A reader on a pseudo-terminal cannot pull device time forward, so the server paces it to the wall clock:
device time = ``speed`` x wall time (``--speed 1`` is real time, the default; ``--speed 4`` runs four times
faster; ``--speed 0`` advances only as fast as the reader drains the DAQ's output). On a machine too busy to
keep that pace the device clock slips (the boards run slower, and keep answering every few milliseconds)
rather than falling ever further behind. Lines that the reader does
not collect pile up in the server; beyond ``--buffer`` bytes the oldest are dropped, as a real USB-serial link
would lose them (the host then sees gaps in ``seq``).

While it runs, the server announces itself in :data:`helpers.base.paths.VIRTUAL_RIG_REGISTRY` so that
recordings made through its ports are labelled ``virtual-rig``, never ``hardware``, and keeps an awake clock
beside the announcement: the seconds its loop has run, a turn counted at most :data:`AWAKE_TURN_S`. A host's
timeouts on these ports count on it (``helpers.rig.link.served_clock``), so a machine too busy to run the
server (it was starved of the CPU, or stopped) pauses its boards, as a slow host pauses the in-process rig's,
instead of making them look silent; a board that is served and sends nothing is silent on it as on the wall
clock.
"""

from __future__ import annotations

import argparse
import contextlib
import fcntl
import json
import mmap
import os
import re
import select
import sys
import threading
import time
import tty
import urllib.parse
from collections import deque
from pathlib import Path
from typing import Any

from helpers import rigfile
from helpers.base.cli import DefaultsHelp, arg_number
from helpers.base.paths import VIRTUAL_RIG_REGISTRY
from helpers.rig.link import SERVER_CLOCK, running
from helpers.virtual.emulator.boards import FAULT_OPTIONS, EmulatedBoard, Faults
from helpers.virtual.emulator.world import VirtualWorld, build_world

CATCH_UP_S = 0.02
"""Wall seconds the server integrates at most before it reads and answers the ports again."""

AWAKE_TURN_S = 0.05
"""Wall seconds one turn of the server's loop counts at most on its awake clock. A turn takes a few
milliseconds (a 2 ms poll, then at most :data:`CATCH_UP_S` of integration); a longer one is a host that did
not run the server."""

MAX_LAG_S = 0.1
"""Wall seconds the device clock may fall behind ``speed`` x wall time before it slips (the pace is a
target, not a promise)."""


class _PtyPort:
    """One pseudo-terminal serving one emulated board."""

    def __init__(self, board: EmulatedBoard, buffer_bytes: int) -> None:
        self.board = board
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)
        self.pending: deque[bytes] = deque()
        self.pending_bytes = 0
        self.buffer_bytes = buffer_bytes
        self.dropped_lines = 0

    def collect(self) -> None:
        """Move the board's queued lines into the server's buffer, dropping the oldest beyond its size."""
        while self.board.out:
            line = self.board.out.popleft()
            self.pending.append(line)
            self.pending_bytes += len(line)
        while self.pending_bytes > self.buffer_bytes and self.pending:
            self.pending_bytes -= len(self.pending.popleft())
            self.dropped_lines += 1

    def flush(self) -> None:
        """Write as much as the pseudo-terminal takes now."""
        while self.pending:
            chunk = b"".join(list(self.pending)[:64])
            try:
                n = os.write(self.master, chunk)
            except (BlockingIOError, OSError):
                return
            # drop the whole lines written; keep a partly written line's tail
            while n > 0 and self.pending:
                first = self.pending[0]
                if n >= len(first):
                    n -= len(first)
                    self.pending_bytes -= len(first)
                    self.pending.popleft()
                else:
                    self.pending[0] = first[n:]
                    self.pending_bytes -= n
                    n = 0

    def read_commands(self) -> None:
        """Feed whatever the host wrote to the board."""
        try:
            data = os.read(self.master, 4096)
        except (BlockingIOError, OSError):
            return
        if data:
            self.board.receive(data)

    def close(self) -> None:
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass


class _AwakeClock:
    """The server's awake clock, in a mapped file of :data:`helpers.rig.link.SERVER_CLOCK`."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.file = open(path, "w+b")  # held open, and locked, while the server runs
        self.file.write(bytes(SERVER_CLOCK.size))
        self.file.flush()
        fcntl.flock(self.file.fileno(), fcntl.LOCK_EX)  # the announcement's liveness (link.announcement)
        self.view = mmap.mmap(self.file.fileno(), SERVER_CLOCK.size)
        self.seconds, self.last = 0.0, time.monotonic()

    def tick(self) -> None:
        """Count the turn since the last tick (at most :data:`AWAKE_TURN_S`)."""
        now = time.monotonic()
        self.seconds += min(now - self.last, AWAKE_TURN_S)
        self.last = now
        SERVER_CLOCK.pack_into(self.view, 0, self.seconds)

    def close(self) -> None:
        self.view.close()
        self.path.unlink(missing_ok=True)
        self.file.close()


def sweep_leftovers(registry: Path) -> list[Path]:
    """Remove the announcements (and clocks) that servers no longer running left in ``registry``.

    A killed server leaves both; they are ignored by every reader (:func:`helpers.rig.link.running`) and
    removed here, when a server starts, so that they do not pile up. An announcement that cannot be read
    (one being written) is left alone. Returns the paths removed.
    """
    removed = []
    for note in sorted(registry.glob("*.json")):
        try:
            info = json.loads(note.read_text())
            if running(info):
                continue
        except (FileNotFoundError, ProcessLookupError):  # its clock, or its pid, is gone: it ended
            info = {}
        except (OSError, ValueError, KeyError, TypeError):
            continue
        for f in (note, Path(str(info.get("clock", note.with_suffix(".clock"))))):
            with contextlib.suppress(FileNotFoundError):
                f.unlink()
                removed.append(f)
    return removed


def announce(world: VirtualWorld, ports: dict[str, str], speed: float) -> tuple[Path, _AwakeClock]:
    """Write this server's awake clock and announcement (pid, device paths, clock, provenance); both back.

    Announcements their servers left (killed) are removed first (:func:`sweep_leftovers`).
    """
    VIRTUAL_RIG_REGISTRY.mkdir(parents=True, exist_ok=True)
    sweep_leftovers(VIRTUAL_RIG_REGISTRY)
    path = VIRTUAL_RIG_REGISTRY / f"{os.getpid()}_{Path(ports['daq']).name}.json"  # one per server and port
    clock = _AwakeClock(path.with_suffix(".clock"))
    info: dict[str, Any] = {
        "pid": os.getpid(),
        "rig": world.name,
        "rig_hash": world.rig_hash,
        "speed": speed,
        **ports,
        "clock": str(clock.path),
        "source": {"rig": world.name, "speed": speed, **world.info},
    }
    path.write_text(json.dumps(info, default=str))
    return path, clock


def serve(
    world: VirtualWorld,
    speed: float = 1.0,
    duration: float | None = None,
    buffer_bytes: int = 1 << 20,
    out=sys.stdout,
    stop: threading.Event | None = None,
) -> dict[str, int]:
    """Serve ``world``'s two boards on pseudo-terminals until interrupted (or ``duration`` wall seconds).

    Parameters
    ----------
    world : VirtualWorld
        The virtual rig.
    speed : float
        Device seconds per wall second; 0 advances only as fast as the DAQ's output is read.
    duration : float, optional
        Stop after this many wall seconds.
    buffer_bytes : int
        Bytes the server holds per port for a slow reader before dropping the oldest lines.
    out : file
        Where the device paths are printed.
    stop : threading.Event, optional
        Serve until it is set (for tests and embedding).

    Returns
    -------
    dict
        ``dropped_lines`` per board.
    """
    if speed < 0:
        raise ValueError(f"speed must be >= 0, got {speed}")
    world.advance_to(world.t + 0.01)  # compile and warm the plant before anyone connects (numba JIT)
    world.daq.out.clear()
    world.stepper.out.clear()
    world.daq.reset()
    world.stepper.reset()
    ports = [_PtyPort(world.daq, buffer_bytes), _PtyPort(world.stepper, buffer_bytes)]
    note, clock = announce(world, {"daq": ports[0].path, "stepper": ports[1].path}, speed)
    print(f"daq {ports[0].path}", file=out, flush=True)
    print(f"stepper {ports[1].path}", file=out, flush=True)
    for p in ports:
        p.collect()
        p.flush()
    wall0 = time.monotonic()
    dev0 = world.t
    step = world.chunk_s / 5
    try:
        while (duration is None or time.monotonic() - wall0 < duration) and not (stop and stop.is_set()):
            clock.tick()
            fds = [p.master for p in ports]
            readable, _, _ = select.select(fds, [], [], 0.002)
            for p in ports:
                if p.master in readable:
                    p.read_commands()
            if speed > 0:
                now = time.monotonic()
                target = dev0 + (now - wall0) * speed
                # catch up for at most CATCH_UP_S of wall time before serving the ports again, and let the
                # device clock slip when the machine cannot keep the pace (a busy host): the boards stay
                # responsive and run slower instead of going silent while the plant catches up
                while world.t < target - 1e-9 and time.monotonic() - now < CATCH_UP_S:
                    world.advance_to(min(target, world.t + step))
                    for p in ports:
                        p.collect()
                behind = target - world.t - MAX_LAG_S * speed
                if behind > 0:
                    dev0 -= behind
            elif ports[0].pending_bytes < 4096:
                world.advance_to(world.t + step)
                for p in ports:
                    p.collect()
            for p in ports:
                p.collect()
                p.flush()
    finally:
        for p in ports:
            p.close()
        note.unlink(missing_ok=True)
        clock.close()
    return {"daq": ports[0].dropped_lines, "stepper": ports[1].dropped_lines}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``serve-virtual-rig`` options (every range refused up front)."""
    parser.formatter_class = DefaultsHelp
    parser.add_argument(
        "--speed",
        type=arg_number(0, 1000),
        default=1.0,
        help="device seconds per wall second, 0-1000 (1 = real time; 0 = as fast as the reader reads)",
    )
    parser.add_argument("--seed", type=arg_number(0, 2**32 - 1, int), default=0, help="sensor noise seed")
    parser.add_argument("--virtual-instance", "--rig-name", dest="rig_name", default="pty", type=_rig_name,
                        help="the virtual rig instance's name (provenance; old spelling: --rig-name)")
    parser.add_argument(
        "--load-n",
        type=arg_number(0, 1000),
        default=None,
        help="VIRTUAL calibration fixture: a known load (N) hung on the load cell",
    )
    parser.add_argument("--daq-faults", default="", help="fault options for the DAQ board, e.g. 'drop=0.01' "
                        "(docs/faults.md, 'Faults the virtual rig injects')")  # fmt: skip
    parser.add_argument("--stepper-faults", default="", help="fault options for the stepper board")
    parser.add_argument(
        "--duration", type=arg_number(0, 1e7, lo_open=True), default=None, help="stop after so many wall s"
    )


def _rig_name(text: str) -> str:
    if not re.fullmatch(r"[A-Za-z0-9_.-]{1,64}", text):
        raise argparse.ArgumentTypeError(f"invalid rig name {text!r}: letters, digits, '_', '-', '.'")
    return text


def _faults(text: str) -> Faults:
    options = dict(urllib.parse.parse_qsl(text.replace(",", "&")))
    unknown = sorted(set(options) - set(FAULT_OPTIONS))
    try:
        if unknown:
            raise ValueError(f"unknown {', '.join(unknown)} (known: {', '.join(FAULT_OPTIONS)})")
        return Faults.from_options(options)
    except (TypeError, ValueError) as exc:
        raise SystemExit(f"invalid fault options {text!r}: {exc}") from None


def world_of(args: argparse.Namespace) -> VirtualWorld:
    """The world ``serve-virtual-rig`` serves: the boards and twin of ``--rig``, its seed, load and faults."""
    options = {"seed": str(args.seed)}
    if args.load_n is not None:
        options["load_n"] = str(args.load_n)
    rig = args.rig if isinstance(args.rig, rigfile.RigFile) else rigfile.load(rigfile.resolve(args.rig))
    world = build_world(rig, args.rig_name, options)
    world.daq.faults = _faults(args.daq_faults)
    world.stepper.faults = _faults(args.stepper_faults)
    return world


def run(args: argparse.Namespace) -> int:
    """Run the server until Ctrl-C, SIGTERM or SIGHUP (``python -m helpers`` turns them into an interrupt)."""
    world = world_of(args)
    try:
        dropped = serve(world, speed=args.speed, duration=args.duration)
    except KeyboardInterrupt:
        return 0
    print(f"stopped; lines dropped for a slow reader: daq {dropped['daq']}, stepper {dropped['stepper']}")
    return 0
