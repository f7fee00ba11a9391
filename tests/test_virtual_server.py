"""``serve-virtual-rig --rig FILE --speed 0.5`` serves every shipped rig: its boards on pseudo-terminals,
answering as the firmware built for that rig file, a programme run to ``DONE`` at half real time.

Every wait ends on readiness (a line the server or a board sends); the deadline only bounds a failure. The
pacing is checked as a bound a slow machine cannot break: the device clock never runs ahead of half the wall
time since the server started (a busy host only makes it slower).
"""

from __future__ import annotations

import argparse
import fcntl
import io
import json
import os
import subprocess
import sys
import threading
import time

import pytest
import serial

from helpers import rigfile
from helpers.board.protocol import checksum, frame
from helpers.rig import link
from helpers.rig.ports import virtual_source_for
from helpers.virtual.emulator import server
from helpers.virtual.emulator.world import build_world

READY_S = 120.0
"""Deadline (s) for a line the server or a board will send: only a failure reaches it."""

SHIPPED = sorted(rigfile.RIGS_DIR.glob("*.toml"))


def _lines_until(port: serial.Serial, want) -> list[str]:
    """Every line's body (its CRC-8 checked) up to and including the first that starts with ``want`` (a str)
    or that ``want`` accepts (a callable)."""
    accepts = want if callable(want) else lambda body: body.startswith(want)
    out: list[str] = []
    deadline = time.monotonic() + READY_S
    while time.monotonic() < deadline:
        raw = port.readline()
        if not raw.endswith(b"\n"):
            continue  # nothing yet (or half a line: readline takes the rest next time)
        body, star, given = raw.rstrip(b"\n").rpartition(b"*")
        assert star and given.decode() == checksum(body), raw
        out.append(body.decode())
        if accepts(out[-1]):
            return out
    raise AssertionError(f"no {want!r} within {READY_S} s; got {out[-5:]}")


def _ask(port: serial.Serial, command: str, want: str) -> str:
    port.write(frame(command))
    return _lines_until(port, want)[-1]


@pytest.mark.parametrize("path", SHIPPED, ids=[p.stem for p in SHIPPED])
def test_the_server_serves_every_shipped_rig_at_half_speed(path) -> None:
    rig = rigfile.load(path)
    n = rig.n_tendons
    world = build_world(rig, f"pty-{rig.name}")
    clock: list[tuple[float, float]] = []  # (wall, device) after every advance of the world
    world.listeners.append(lambda w: clock.append((time.monotonic(), w.t)))
    out, stop = io.StringIO(), threading.Event()
    started = time.monotonic()
    thread = threading.Thread(target=server.serve, args=(world,), daemon=True,
                              kwargs={"speed": 0.5, "out": out, "stop": stop})  # fmt: skip
    thread.start()
    deadline = time.monotonic() + READY_S
    while out.getvalue().count("\n") < 2 and thread.is_alive() and time.monotonic() < deadline:
        time.sleep(0.01)  # the server prints its two device paths when it is ready
    paths = dict(line.split() for line in out.getvalue().splitlines())
    try:
        ports = serial.Serial(paths["daq"], timeout=0.05), serial.Serial(paths["stepper"], timeout=0.05)
        with ports[0] as daq, ports[1] as st:
            version = f"2.3.0+{rig.hash}"  # the boards were built for this rig file
            assert _ask(st, "PING", "PONG") == f"PONG stepper {version}"
            assert _ask(daq, "PING", "PONG") == f"PONG daq {version}"
            assert _ask(daq, "CONFIG", "OK CONFIG") == f"OK CONFIG {n} {n} 100 2000"
            config = _ask(st, "CONFIG", "OK CONFIG").split()[2:]  # axes, items, intervals, travels (releases)
            assert config[:2] == [str(n), "64"] and len(config) in (4 + n, 4 + 2 * n)
            assert _ask(daq, "START", "OK START") == "OK START 1000"
            steps = [10 + 2 * a for a in range(n)]
            there = "MSEG 200000 " + " ".join(map(str, steps))
            back = "MSEG 200000 " + " ".join(str(-s) for s in steps)
            for c in ("EN 1", there, "WAIT 100", back, "GO"):
                assert _ask(st, c, "OK").startswith("OK")
            assert _lines_until(st, "DONE")[-1] == "DONE " + " ".join(["0"] * n)
            moved: list[bool] = []

            def back_home(body: str) -> bool:  # a sample after the last step: every count back at 0
                if not body.startswith("D,"):
                    return False
                counts = [int(x) for x in body.split(",")[-n:]]
                moved.append(any(counts))
                return any(moved) and not any(counts)

            got = _lines_until(daq, back_home)
            daq.write(frame("STOP"))
            got += _lines_until(daq, "OK STOP")
    finally:
        stop.set()
        thread.join(timeout=READY_S)
    data = [[int(x) for x in body.split(",")[1:]] for body in got if body.startswith("D,")]
    assert int(got[-1].split()[2]) == len(data) >= 500  # 0.5 s of programme at 1 kHz, at least; none lost
    assert {len(row) for row in data} == {2 + 2 * n}  # seq, t_us, every channel, every axis
    assert [max(row[2 + n + a] for row in data) for a in range(n)] == steps and data[-1][2 + n :] == [0] * n
    assert not thread.is_alive()
    first = clock[0][1]  # the server's warm-up, before it starts its clock
    ahead = [t - first - 0.5 * (w - started) for w, t in clock]
    assert max(ahead) <= 1e-9, "the device clock ran ahead of half the wall time"


def test_serve_virtual_rig_builds_the_boards_of_the_rig_named_by_rig() -> None:
    parser = argparse.ArgumentParser()
    server.add_arguments(parser)

    def args(rig: str, *argv: str) -> argparse.Namespace:  # as python -m helpers passes --rig: a value
        parsed = parser.parse_args(list(argv))
        parsed.rig = rigfile.load(rigfile.resolve(rig))
        return parsed

    four = rigfile.load(rigfile.resolve("four-tendon"))
    world = server.world_of(args("four-tendon", "--speed", "0.5", "--seed", "3"))
    assert (world.rig_hash, world.limits.axes, world.limits.channels) == (four.hash, 4, 4)
    assert world.info["tendons"] == 4 and world.info["seed"] == 3 and world.name == "pty"
    path = rigfile.RIGS_DIR / "long-arm.toml"
    world = server.world_of(args(str(path), "--stepper-faults", "hang_at=2"))
    assert world.rig_hash == rigfile.load(path).hash and world.limits.travel_steps == (254,)
    assert world.stepper.faults.hang_at == 2.0
    with pytest.raises(SystemExit, match="unknown hang"):
        server.world_of(args("paper", "--daq-faults", "hang=1"))


@pytest.mark.slow
def test_the_command_line_serves_the_rig_file_it_is_given() -> None:
    """``python -m helpers serve-virtual-rig --rig four-tendon --speed 0.5`` as a user types it."""
    argv = [sys.executable, "-m", "helpers", "serve-virtual-rig", "--rig", "four-tendon", "--speed", "0.5",
            "--virtual-instance", "cli", "--duration", str(READY_S)]  # fmt: skip
    env = dict(os.environ)
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        paths = dict(proc.stdout.readline().split() for _ in range(2))
        with serial.Serial(paths["stepper"], timeout=0.05) as stepper:
            four = rigfile.load(rigfile.resolve("four-tendon"))
            assert _ask(stepper, "PING", "PONG") == f"PONG stepper 2.3.0+{four.hash}"
            assert _ask(stepper, "POS", "OK POS") == "OK POS 0 0 0 0"
    finally:
        proc.terminate()
        proc.wait(timeout=READY_S)


def test_an_announcement_its_server_left_is_ignored_even_where_its_pid_lives_again(tmp_path, monkeypatch):
    """A killed server leaves its announcement, and on a busy machine its pid may be another process's by now
    (here: this test's own). The lock on its clock file went with it, so the ports are hardware again (a CI
    run once labelled simavr's pseudo-terminals ``virtual-rig`` through such a leftover); held: virtual."""
    monkeypatch.setattr(link, "VIRTUAL_RIG_REGISTRY", tmp_path)
    clock = tmp_path / "1_0.clock"
    clock.write_bytes(bytes(link.SERVER_CLOCK.size))
    note = {"pid": os.getpid(), "daq": "/dev/pts/990", "stepper": "/dev/pts/991", "clock": str(clock)}
    (tmp_path / "1_0.json").write_text(json.dumps(note))
    assert virtual_source_for(("/dev/pts/990", "/dev/pts/991")) is None
    assert link.served_clock("/dev/pts/990") is None
    with open(clock, "r+b") as f:
        fcntl.flock(f.fileno(), fcntl.LOCK_EX)  # as a running server holds it
        assert virtual_source_for(("/dev/pts/990", "/dev/pts/991"))["kind"] == "virtual-rig"
        assert link.served_clock("/dev/pts/990")() == 0.0


def test_a_starting_server_removes_what_killed_servers_left_and_nothing_else(tmp_path):
    """Leftovers pile up in the registry otherwise: a dead server's announcement and clock (its lock gone),
    an older one without a clock whose pid is gone, one whose clock file is gone. A running server's (its
    clock locked) and one that cannot be read yet (being written) stay."""
    dead_clock = tmp_path / "1_0.clock"
    dead_clock.write_bytes(bytes(link.SERVER_CLOCK.size))
    (tmp_path / "1_0.json").write_text(json.dumps({"pid": os.getpid(), "clock": str(dead_clock)}))
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True, check=True)  # fmt: skip
    (tmp_path / "2_0.json").write_text(json.dumps({"pid": int(gone.stdout)}))  # an older server's note
    (tmp_path / "3_0.json").write_text(json.dumps({"pid": os.getpid(), "clock": str(tmp_path / "3_0.clock")}))
    live_clock = tmp_path / "4_0.clock"
    live_clock.write_bytes(bytes(link.SERVER_CLOCK.size))
    (tmp_path / "4_0.json").write_text(json.dumps({"pid": os.getpid(), "clock": str(live_clock)}))
    (tmp_path / "5_0.json").write_text('{"pid": ')  # being written
    with open(live_clock, "r+b") as f:
        fcntl.flock(f.fileno(), fcntl.LOCK_EX)  # as a running server holds it
        removed = server.sweep_leftovers(tmp_path)
    assert sorted(p.name for p in removed) == ["1_0.clock", "1_0.json", "2_0.json", "3_0.json"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["4_0.clock", "4_0.json", "5_0.json"]
