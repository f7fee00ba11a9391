"""One emulated board set built from the rig file (``helpers.virtual.emulator``), for 1 to 4 tendons.

- the paper's world (and every world) sends the bytes it sent before the one-tendon and several-tendon boards
  were merged into one set: digests of one protocol-level session, computed with main's code (8d910bb);
- the rig is a value: a port given ``port.rig`` opens the world ``(name, rig.hash)``, so the paper's rig and
  ``rigs/four-tendon.toml`` in one process are two worlds, and driven interleaved each sends the bytes it
  sends alone;
- every fault of :class:`~helpers.virtual.emulator.boards.Faults` at every axis count (a stepper that hangs, a
  board that resets, one that disconnects, corrupted lines, overruns).
"""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest
import serial
from serial.serialutil import SerialException
from twins import integrated_by

from helpers import rigfile
from helpers.board.protocol import checksum, frame
from helpers.virtual import LoadCell, RigParameters
from helpers.virtual.emulator.boards import Faults, build_limits
from helpers.virtual.emulator.world import (
    VirtualWorld,
    build_world,
    find_world,
    forget_world,
    get_world,
)


def load(name: str) -> rigfile.RigFile:
    return rigfile.load(rigfile.resolve(name))


def tendons(n: int) -> rigfile.RigFile:
    """A rig of ``n`` tendons made from the four-tendon file as a user would: 360/n degrees apart."""
    text = load("four-tendon").text
    head, _, _ = text.partition("[[tendon]]")
    _, _, boards = text.partition("[boards]")
    head = head.replace('name = "four-tendon"', f'name = "tendons-{n}"')
    blocks = "".join(f"[[tendon]]\nangle_deg = {360.0 * i / n}\n\n" for i in range(n))
    return rigfile.loads(head + blocks + "[boards]" + boards, f"tendons-{n}.toml")


# --- one session at the protocol level ------------------------------------------------------------------
class RecordingPlant:
    """Forwards to a plant and hashes what it was asked (sample instants, step instants, axes, signs)."""

    def __init__(self, inner, calls) -> None:
        self.inner, self.calls = inner, calls

    @property
    def t(self):
        return self.inner.t

    def advance(self, *args):
        for a in args:
            self.calls.update(np.ascontiguousarray(np.asarray(a, dtype=float)).tobytes() + b"|")
        return self.inner.advance(*args)


class TimePlant:
    """A plant double: every channel's output is a function of the time and its axis's count (no physics)."""

    def __init__(self, axes: int) -> None:
        self.t, self.axes, self.pos = 0.0, axes, np.zeros(axes)

    def advance(self, times, step_t, *rest):
        times, step_t = np.asarray(times, float), np.asarray(step_t, float)
        step_a, step_s = (np.zeros(len(step_t)), rest[0]) if len(rest) == 1 else rest
        step_a, step_s = np.asarray(step_a, int), np.asarray(step_s, float)
        out = np.empty((len(times), self.axes))
        for a in range(self.axes):
            sel = step_a == a
            csum = np.concatenate([[0.0], np.cumsum(step_s[sel])])
            pos = self.pos[a] + csum[np.searchsorted(step_t[sel], times, side="right")]
            out[:, a] = 2.0 + 0.05 * pos + 0.3 * np.sin(37.0 * times + a)
            self.pos[a] += step_s[sel].sum()
        self.t = float(times[-1])
        return out[:, 0] if len(rest) == 1 else {"output": out}


def _talk(board, *cmds: str) -> None:
    for c in cmds:
        board.receive(frame(c))


def _ragged(t0: float, t1: float) -> list[float]:
    """Interval ends from t0 to t1 as the pseudo-terminal server makes them: anywhere, mid-conversion too."""
    ends = t0 + np.cumsum(np.tile([0.0137, 0.0021, 0.05, 0.0003, 0.0311], 400))
    return [*ends[ends < t1].tolist(), t1]


def _commands(axes: int) -> tuple[list[str], list[str]]:
    """A programme of every item kind and the set-points of a stream, for a build of ``axes`` axes."""
    if axes == 1:
        programme = ["WAIT 100", "SEG 1 39 1282", "WAIT 300", "MSEG 50000 -20", "SEG -1 19 2000"]
        return programme, ["V 400", "V 800", "MV 800", "V -300", "V -900", "V 0", "V 0", "MV 0"]
    programme = ["WAIT 100", "MSEG 40000 20 -10 5 0", "SEG 1 7 1282", "WAIT 200", "MSEG 50000 -27 10 -5 3"]
    zeros = " 0" * (axes - 3)
    setpoints = [f"MV 400 -200 0{zeros}", f"MV 800 0 300{zeros}", f"MV 800 100 -300{zeros}",
                 f"MV -300 0 0{zeros}", f"MV -900 0 0{zeros}", "V 0", "V 0", f"MV 0 0 0{zeros}"]  # fmt: skip
    return programme, setpoints


def session(world: VirtualWorld, axes: int) -> bytes:
    """Drive ``world``'s boards through a programme, a stream and their replies: every byte they sent."""
    out = []

    def collect() -> None:
        out.append(world.daq.take_output() + b"#" + world.stepper.take_output() + b"#")

    d, s = world.daq, world.stepper
    programme, setpoints = _commands(axes)
    collect()
    _talk(d, "CONFIG", "RATE 1000", "ZERO", "START")
    _talk(s, "CONFIG", "CLEAR", *programme, "EN 1", "GO")
    collect()
    for t in _ragged(world.t, world.t + 1.0):
        world.advance_to(t)
        collect()
    _talk(s, "POS", "SHAPER 2 0", "IMP 0 2048 0", "IMP 1 2048 40000", "STREAM")
    t0 = world.t
    for i, v in enumerate(setpoints):
        world.advance_to(t0 + 0.004 + 0.01 * i)
        collect()
        _talk(s, v)
    _talk(s, "END")
    for t in _ragged(world.t, t0 + 0.7):
        world.advance_to(t)
        collect()
    _talk(d, "STOP")
    _talk(s, "POS", "ABORT", "PING")
    collect()
    return b"".join(out)


CHAIN = {"loop_zero_ma": 4.0, "loop_full_ma": 20.0, "loop_min_ma": 3.8, "loop_max_ma": 20.5,
         "shunt_ohm": 150.0,
         "adc_vref_v": 5.0, "adc_bits": 10}  # fmt: skip
"""The fields the twin's parameters gained since the pins: the sensor chain's when the rig became a value
(every shipped rig's ``[hardware]`` chain, by hand) and the integrator (RK4, as pinned); the rest of the
provenance is as pinned."""
ADDED = {**CHAIN, "integrator": "rk4"}


def _without_chain(info: dict) -> dict:
    """``info`` with :data:`CHAIN`'s fields checked and taken out of its parameters (and their arm's)."""
    out = json.loads(json.dumps(info, default=str))
    for holder in (out.get("parameters", {}), out.get("parameters", {}).get("arm", {})):
        if isinstance(holder, dict) and "loop_zero_ma" in holder:
            assert {k: holder.pop(k) for k in ADDED} == ADDED
    return out


def _digests(world: VirtualWorld, axes: int, integrator: str = "rk4") -> tuple[str, str, str]:
    calls = hashlib.sha256()
    world.plant = RecordingPlant(world.plant, calls)
    data = session(world, axes)
    info = world.info if integrator != "rk4" else _without_chain(world.info)
    info = json.dumps(info, sort_keys=True, default=str).encode()
    return tuple(h.hexdigest()[:16] for h in (calls, hashlib.sha256(data), hashlib.sha256(info)))


def _world(rig: rigfile.RigFile, variant: str) -> VirtualWorld:
    if variant in ("twin", "twin-rosw"):  # the rig's world as a port builds it, 0.5 s before the wrap
        return build_world(rig, "pinned", {"seed": "7", "t0_us": str(2**32 - 500_000)})
    if variant == "faults":  # every transport fault of the DAQ's data lines
        world = build_world(rig, "pinned", {"seed": "3"})
        world.daq.faults = Faults(drop=0.02, corrupt=0.02, garbage=0.02, overrun_every=7)
        return world
    n = rig.n_tendons  # "double": no physics, the real load cells' noise
    cells = [LoadCell(RigParameters(), seed=5 if c == 0 else [5, c]) for c in range(n)]
    return VirtualWorld(TimePlant(n), cells[0] if n == 1 else cells, name="pinned", seed=2,
                        limits=build_limits(rig))  # fmt: skip


PINNED = {
    ("paper", "twin"): ("db16d46353958182", "9104fea41487d516", "83320b57c00f2e0d"),
    ("paper", "faults"): ("db16d46353958182", "da3594783d693414", "2dd326138f17dfb6"),
    ("paper", "double"): ("db16d46353958182", "8d8595b38807f9dc", "44136fa355b3678a"),
    ("long-arm", "twin"): ("db16d46353958182", "f37ad9cd345a46b6", "919ee2eae2a4cd04"),
    ("long-arm", "faults"): ("db16d46353958182", "daec2efc7508837e", "064f0d455a26c226"),
    ("long-arm", "double"): ("db16d46353958182", "de03880ab7d0981f", "44136fa355b3678a"),
    ("four-tendon", "twin"): ("193bc8638803bc36", "ca288b0218cf59fd", "761e036d1ea53ebc"),
    ("four-tendon", "faults"): ("193bc8638803bc36", "167c9973f73cfcaf", "611eb1b65b73c31e"),
    ("four-tendon", "double"): ("193bc8638803bc36", "fe439ec2bf38ef1f", "44136fa355b3678a"),
}
"""(what the boards asked of the plant, every byte they sent, the world's provenance), sha256 to 16 digits, of
:func:`session` on main at 8d910bb (``default_world`` for one tendon, ``tendon_world`` for four; the same
plants, sensors, faults and commands): computed there, never by the code under test."""


@pytest.mark.parametrize(("rig", "variant"), list(PINNED), ids=[f"{r}-{v}" for r, v in PINNED])
def test_every_world_sends_the_bytes_it_sent_before_the_boards_were_merged(rig, variant) -> None:
    """The paper's world records byte-identically to before: the same plant calls (sample and step
    instants: the emulator's timing, whatever the twin's numerics), the same lines from a plant double (the
    boards alone), the same lines from the tuned twin and the same provenance, with the twin integrated by
    RK4 at its step as when these were pinned (the default since is ``rosw``: :data:`PINNED_ROSW`)."""
    r = load(rig)
    with integrated_by("rk4"):
        assert _digests(_world(r, variant), r.n_tendons) == PINNED[(rig, variant)]


PINNED_ROSW = {
    "paper": ("db16d46353958182", "2e592acd665dae6e", "e54bdb6c0c7b53ba"),
    "long-arm": ("db16d46353958182", "03c15a34883d936c", "3c07723f2db7cb35"),
    "four-tendon": ("193bc8638803bc36", "30e0125f562127e9", "1a300612e17d57ba"),
}
"""The "twin" digests of :data:`PINNED` with the default integrator, the Rosenbrock-W step at 0.5 ms: pinned
when it became the default (the plant calls are :data:`PINNED`'s, the bytes and the provenance are
the new integrator's). They pin the twin's numerics: a deliberate change of them is re-pinned with its
reason."""


@pytest.mark.parametrize("rig", list(PINNED_ROSW))
def test_the_default_twin_sends_the_bytes_pinned_when_rosw_became_the_default(rig) -> None:
    r = load(rig)
    world = _world(r, "twin-rosw")
    parameters = world.info["parameters"]
    assert parameters.get("arm", parameters)["integrator"] == "rosw"
    digests = _digests(world, r.n_tendons, integrator="rosw")
    assert digests[0] == PINNED[(rig, "twin")][0]  # the emulator asked the plant the same as with RK4
    assert digests == PINNED_ROSW[rig]


# --- the rig as a value, through the in-process port ----------------------------------------------------
@pytest.fixture
def virtual_urls(monkeypatch):
    """pyserial finds ``virtual://`` (as ``helpers.rig.link.open_port`` arranges; undone after the test)."""
    monkeypatch.setattr(serial, "protocol_handler_packages", [*serial.protocol_handler_packages,
                                                              "helpers.virtual.emulator"])  # fmt: skip


def _port(kind: str, rig: rigfile.RigFile | None, query: str = "", timeout: float = 0.0):
    """A port opened as a driver does: ``serial_for_url(url, do_not_open=True)``, ``port.rig``, ``open()``."""
    port = serial.serial_for_url(f"virtual://{kind}{query}", do_not_open=True, timeout=timeout)
    port.rig = rig
    port.open()
    return port


def test_a_port_given_the_rig_opens_that_rigs_world(virtual_urls) -> None:
    paper, four = load("paper"), load("four-tendon")
    for rig in (paper, four):
        forget_world("twins", rig)
        forget_world(rig.name, rig)
    try:
        a, b = _port("daq", paper, "?world=twins"), _port("daq", four, "?world=twins")
        assert a.world is not b.world  # one name, two rigs: two worlds
        assert (a.world.limits.axes, b.world.limits.axes) == (1, 4)
        assert a.read(100) == frame("HELLO daq 2.3.0+481e87e3")
        assert b.read(100) == frame(f"HELLO daq 2.3.0+{four.hash}")
        assert _port("stepper", four, "?world=twins").world is b.world  # both boards of one world
        assert find_world("twins", paper) is a.world and get_world("twins", four) is b.world
        with pytest.raises(SerialException, match="exists for several rig files"):
            _port("stepper", None, "?world=twins")  # a name alone is ambiguous then
        # without a name: the rig's own name; the world is built from the rig file
        c = _port("stepper", four)
        assert c.world.name == "four-tendon" and c.world is find_world("four-tendon", four)
        assert c.world.info["tendons"] == 4 and c.world.rig_hash == four.hash
    finally:
        for rig in (paper, four):
            forget_world("twins", rig)
            forget_world(rig.name, rig)


def _drive(daq, stepper, axes: int, out: list[bytes]):
    """The session's commands through the two ports, one operation per step (a generator)."""
    world = daq.world

    def until(t: float) -> None:
        data = b""
        while world.t < t - 1e-12:
            daq.timeout = t - world.t
            data += daq.read(1 << 20)  # reads advance the device clock, in device time
        out.append(data + b"#" + stepper.read(stepper.in_waiting) + b"#")

    programme, setpoints = _commands(axes)
    start = ((daq, ["RATE 1000", "ZERO", "START"]), (stepper, ["CLEAR", *programme, "EN 1", "GO"]))
    for board, cmds in start:
        for c in cmds:
            board.write(frame(c))
            yield
    for k in range(1, 11):
        until(0.1 * k)
        yield
    for c in ("POS", "SHAPER 2 0", "IMP 0 2048 0", "IMP 1 2048 40000", "STREAM"):
        stepper.write(frame(c))
        yield
    t0 = world.t
    for i, v in enumerate(setpoints):
        until(t0 + 0.004 + 0.01 * i)
        stepper.write(frame(v))
        yield
    stepper.write(frame("END"))
    until(t0 + 0.7)
    daq.write(frame("STOP"))
    stepper.write(frame("POS"))
    until(world.t + 0.01)


def _ports(rig: rigfile.RigFile, name: str):
    forget_world(name, rig)
    return _port("daq", rig, f"?world={name}&seed=4"), _port("stepper", rig, f"?world={name}")


def test_two_rigs_interleaved_in_one_process_send_what_each_sends_alone(virtual_urls) -> None:
    """The paper's rig and the four-tendon rig, one name for both: each session alone, then both with their
    operations interleaved one by one; every rig's boards send the same bytes."""
    rigs = {"paper": load("paper"), "four-tendon": load("four-tendon")}
    alone, mixed = {}, {name: [] for name in rigs}
    try:
        for name, rig in rigs.items():
            out: list[bytes] = []
            for _ in _drive(*_ports(rig, "alone"), rig.n_tendons, out):
                pass
            alone[name] = b"".join(out)
        runs = [_drive(*_ports(rig, "mixed"), rig.n_tendons, mixed[name]) for name, rig in rigs.items()]
        while runs:
            for run in list(runs):
                if next(run, StopIteration) is StopIteration:
                    runs.remove(run)
    finally:
        for rig in rigs.values():
            forget_world("alone", rig)
            forget_world("mixed", rig)
    for name, rig in rigs.items():
        got = b"".join(mixed[name])
        assert got == alone[name]
        lines = [ln for ln in got.replace(b"#", b"").split(b"\n") if ln]
        data = [ln for ln in lines if ln.startswith(b"D,")]
        assert len(data) > 1500 and {len(ln.split(b",")) for ln in data} == {3 + 2 * rig.n_tendons}
        assert sum(ln.startswith(b"DONE ") for ln in lines) == 2  # the programme's and the stream's


# --- every fault at every axis count --------------------------------------------------------------------
AXES = [1, 2, 3, 4]


def _rig(n: int) -> rigfile.RigFile:
    return load("paper") if n == 1 else tendons(n)


def _double_world(n: int, **faults: Faults) -> VirtualWorld:
    cells = [LoadCell(RigParameters(), seed=c) for c in range(n)]
    world = VirtualWorld(TimePlant(n), cells[0] if n == 1 else cells, name=f"faults-{n}",
                         limits=build_limits(_rig(n)), **faults)  # fmt: skip
    assert world.limits.axes == world.limits.channels == n
    for b in (world.daq, world.stepper):
        b.take_output()
    return world


def _checked(raw: bytes) -> str | None:
    """A line's body if its CRC-8 matches, else None."""
    body, star, given = raw.rpartition(b"*")
    return body.decode("ascii") if star and given.decode("latin-1") == checksum(body) else None


def _lines(board) -> list[str]:
    """Bodies of the lines a board sent since the last call, each checked against its CRC-8."""
    out = []
    for raw in board.take_output().split(b"\n")[:-1]:
        body = _checked(raw)
        assert body is not None, raw
        out.append(body)
    return out


def _move(n: int) -> str:
    return "MSEG 100000 " + " ".join(str(10 + a) for a in range(n))  # axis a: 10 + a steps in 100 ms


def _complete(k: int, n: int) -> int:
    """The samples sent of ``k`` taken at 1 kHz: with several channels the last is still converting."""
    return k if n == 1 else k - 1


def _data(lines: list[str]) -> list[list[int]]:
    return [[int(x) for x in body.split(",")[1:]] for body in lines if body.startswith("D,")]


@pytest.mark.parametrize("n", AXES)
def test_a_stepper_that_hangs_never_sends_done_at_any_axis_count(n) -> None:
    world = _double_world(n, stepper_faults=Faults(hang_at=0.05))
    _talk(world.daq, "START")
    _talk(world.stepper, "EN 1", _move(n), "GO")
    world.advance_to(0.5)  # the programme would end at 0.1 s
    assert _lines(world.stepper) == ["OK EN 1", "OK MSEG 1", "OK GO 1"]  # and never DONE
    _talk(world.stepper, "PING", "POS")
    world.advance_to(1.0)
    assert _lines(world.stepper) == [] and world.stepper.hung
    frozen = [5 + a // 2 for a in range(n)]  # axis a's steps of 10 + a in 100 ms by 50 ms
    assert world.stepper.positions == frozen
    rows = _data(_lines(world.daq))
    assert len(rows) == _complete(1000, n) and {len(r) for r in rows} == {2 + 2 * n}  # the DAQ goes on
    assert rows[-1][2 + n :] == frozen


@pytest.mark.parametrize("n", AXES)
@pytest.mark.parametrize("board", ["daq", "stepper"])
def test_a_board_that_resets_says_hello_and_forgets_at_any_axis_count(n, board) -> None:
    world = _double_world(n, **{f"{board}_faults": Faults(reset_at=0.05)})
    _talk(world.daq, "ZERO", "START")
    _talk(world.stepper, "EN 1", _move(n), "GO")
    world.advance_to(0.3)
    version = f"2.3.0+{world.rig_hash}"
    daq, stepper = _lines(world.daq), _lines(world.stepper)
    if board == "stepper":
        assert stepper == ["OK EN 1", "OK MSEG 1", "OK GO 1", f"HELLO stepper {version}"]  # never DONE
        assert world.stepper.positions == [0] * n and not world.stepper.enabled and not world.stepper.running
        assert len(_data(daq)) == _complete(300, n)  # the samples go on, counts where the reboot left them
        assert _data(daq)[-1][2 + n :] == [5 + a // 2 for a in range(n)]
    else:
        assert daq[:2] == ["OK ZERO", "OK START 1000"] and daq[-1] == f"HELLO daq {version}"
        assert len(_data(daq)) == _complete(50, n) and not world.daq.streaming
        assert stepper[-1] == "DONE " + " ".join(str(10 + a) for a in range(n))
        # the rebooted counters start from 0: they count the steps after the reboot only
        assert list(world.daq.step_counts) == [10 + a - (5 + a // 2) for a in range(n)]
    _talk(world.daq, "CONFIG")
    assert _lines(world.daq) == [f"OK CONFIG {n} {n} 100 2000"]


@pytest.mark.parametrize("n", AXES)
@pytest.mark.parametrize("board", ["daq", "stepper"])
def test_a_board_that_disconnects_is_gone_at_any_axis_count(n, board, virtual_urls) -> None:
    rig = _rig(n)
    forget_world("gone", rig)
    try:
        ports = {kind: _port(kind, rig, f"?world=gone{'&disconnect_at=0.2' if kind == board else ''}",
                             timeout=0.05) for kind in ("daq", "stepper")}  # fmt: skip
        ports["daq"].write(frame("START"))
        ports["stepper"].write(frame("EN 1") + frame(_move(n)) + frame("GO"))
        port, other = ports[board], ports["stepper" if board == "daq" else "daq"]
        got = b""
        with pytest.raises(SerialException, match="device disconnected"):
            while True:
                got += port.read(4096)  # each read waits 50 ms of device time, at most
        assert port.world.t >= 0.2 and not port.is_open
        assert got.startswith(b"HELLO " + board.encode()) and (board == "stepper" or b"\nD," in got)
        with pytest.raises(SerialException):
            port.write(frame("PING"))
        other.write(frame("PING"))
        assert b"PONG" in other.read(1 << 16)  # the other board is still there
    finally:
        forget_world("gone", rig)


@pytest.mark.parametrize("n", AXES)
def test_corrupted_dropped_and_late_lines_are_counted_at_any_axis_count(n) -> None:
    world = _double_world(n)
    world.daq.faults = Faults(corrupt=0.1, overrun_every=9, garbage=0.02, drop=0.02)
    world.stepper.faults = Faults(corrupt_replies=0.3, drop_replies=0.1)
    _talk(world.daq, "START")
    world.advance_to(1.0005)  # the sample of 1 s is complete: 1000 samples taken
    bad, data, overruns = 0, [], 0
    for raw in world.daq.take_output().split(b"\n")[:-1]:
        body = _checked(raw)
        if not body:
            bad += 1
        elif body.startswith("W,OVERRUN,"):
            overruns += int(body.split(",")[2])
        elif body.startswith("D,"):
            data.append(body.split(","))
    injected = world.daq.injected
    assert bad == injected["corrupted"] + injected["garbage"] and injected["corrupted"] > 0
    assert overruns == injected["overrun_periods"] == 1000 // 9
    assert len(data) == 1000 - overruns - injected["dropped"] - injected["corrupted"]
    assert {len(r) for r in data} == {3 + 2 * n}
    for _ in range(40):
        _talk(world.stepper, "PING")
    sent = world.stepper.take_output().split(b"\n")[:-1]
    intact = [body for body in map(_checked, sent) if body is not None]
    assert len(sent) - len(intact) == world.stepper.injected["replies_corrupted"] > 0
    assert len(sent) == 40 - world.stepper.injected["replies_dropped"] < 40
    assert set(intact) == {f"PONG stepper 2.3.0+{world.rig_hash}"}
