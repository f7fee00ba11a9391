"""Conformance: the same command scripts sent to the firmware (in simavr) and to the emulated boards of
helpers.virtual.emulator (through ``virtual://`` pyserial URLs) give the same replies.

Compared: every line except data lines, in order, grouped by the command window it arrived in (so an
unsolicited ``DONE`` or notice must come in the same window too). ``ERR`` lines are compared by their code
(the text is for humans), ``OK STOP <n>`` by whether ``n`` is zero (the number of samples depends on the
microseconds between two commands; each side's ``n`` is checked against its own data lines instead), and
``OK MEM <n>`` by its form (the emulated board has no stack to measure).

The scripts: every command and error of both boards (``fw_cases``), and the stepper's streaming mode
(``stream``: its commands and errors, notices, the set-point FIFO, the watchdog, ``DONE``). Each command
reaches the emulated board when its last byte would have reached the firmware over the wire (10 bits per byte
at the board's baud rate), as the harness feeds it to the simulated UART.
"""

from __future__ import annotations

import functools
import re

import fw_cases as cases
import fwsim
import pytest

pytestmark = pytest.mark.firmware

BOARD = {"daq": "daq", "stepper": "stepper", "stream": "stepper"}
BAUD = {"daq": 500_000, "stepper": 115_200}

serial = pytest.importorskip("serial")


def _boards_module():
    return pytest.importorskip("helpers.virtual.emulator.world", reason="the emulated boards are missing")


def _open(url: str, timeout: float):
    """The emulated board's URL opened with pyserial (the emulator's package registered, as the host does)."""
    if "helpers.virtual.emulator" not in serial.protocol_handler_packages:
        serial.protocol_handler_packages.append("helpers.virtual.emulator")
    return serial.serial_for_url(url, baudrate=115200, timeout=timeout, write_timeout=1.0, exclusive=True)


class _FlatPlant:
    """A plant double: no physics, constant tension; the protocol does not depend on it."""

    t = 0.0

    def advance(self, sample_times, step_times, step_signs):
        import numpy as np

        self.t = float(sample_times[-1]) if len(sample_times) else self.t
        return np.full(len(sample_times), 1.0)


class _FlatSensor:
    def counts(self, tension):
        import numpy as np

        return np.full(len(tension), 512, dtype=np.int64)


def _script(board: str) -> list[tuple[bytes, float]]:
    if board == "daq":
        return [(c, 1e-4 * len(c)) for c, _ in cases.framing_cases("daq") + cases.daq_cases()]
    if board == "stream":
        return [(c, p) for c, _, p in cases.stream_cases()] + cases.stream_conformance_cases()
    return [(c, 1e-4 * len(c)) for c, _ in cases.framing_cases("stepper")] + [
        (c, p) for c, _, p, _ in cases.stepper_cases()
    ]


def _normalise(body: str) -> str:
    if body.startswith("ERR"):
        return " ".join(body.split()[:2])
    if re.fullmatch(r"OK STOP [1-9]\d*", body):
        return "OK STOP <n>"
    if re.fullmatch(r"OK MEM \d+", body):
        return "OK MEM <n>"
    return body


def _grouped_bodies(lines_by_window: list[list[str]]) -> list[list[str]]:
    return [[_normalise(b) for b in w if not b.startswith("D,")] for w in lines_by_window]


def _check_stop_counts(lines_by_window: list[list[str]]) -> None:
    n = 0
    for window in lines_by_window:
        for b in window:
            if b.startswith("OK START"):
                n = 0
            elif b.startswith("D,"):
                n += 1
            elif b.startswith("OK STOP") and b != "OK STOP 0":
                assert b == f"OK STOP {n}"


@functools.cache
def _firmware(board: str) -> tuple[list[str], list[list[str]]]:
    script = _script(board)
    run, groups = fwsim.command_session(BOARD[board], [c for c, _ in script], [p for _, p in script])
    assert all(ln.checksum_ok for ln in run.lines)
    first = fwsim.schedule(len(script), [p for _, p in script])[0] * fwsim.F_CPU
    before = [ln.body for ln in run.lines if ln.cycle < first]
    return before, [[ln.body for ln in g] for g in groups]


def _virtual(board: str) -> tuple[list[str], list[list[str]]]:
    boards = _boards_module()
    name = f"conformance-{board}"
    world = boards.VirtualWorld(_FlatPlant(), _FlatSensor(), name=name)
    boards.register_world(world)
    byte_s = 10 / BAUD[BOARD[board]]
    try:
        port = _open(f"virtual://{BOARD[board]}?world={name}", timeout=0.001)
        script = _script(board)
        times = fwsim.schedule(len(script), [p for _, p in script])

        def read_until(t: float) -> list[str]:
            data = b""
            while port.world.t < t - 1e-9:
                port.timeout = t - port.world.t
                data += port.read(1 << 24)
            data += port.read(port.in_waiting) if port.in_waiting else b""
            out = []
            for raw in data.split(b"\n")[:-1] if data else []:
                text = raw.decode("ascii")
                body, star, given = text.rpartition("*")
                assert star and given == fwsim.checksum(body.encode()), f"bad checksum in {text!r}"
                out.append(body)
            return out

        before = read_until(times[0])
        groups = []
        for i, (cmd, _) in enumerate(script):
            lines = cmd.split(b"\n")
            window, sent = [], 0
            for j, part in enumerate(lines):  # each line as its '\n' arrives
                if j == len(lines) - 1 and not part:
                    break
                sent += len(part) + (1 if j < len(lines) - 1 else 0)
                window += read_until(times[i] + sent * byte_s)
                port.write(part + b"\n" if j < len(lines) - 1 else part)
            groups.append(window + read_until(times[i + 1]))
        port.close()
        return before, groups
    finally:
        boards.forget_world(name)


@pytest.mark.parametrize("board", ["daq", "stepper", pytest.param("stream", marks=pytest.mark.streaming)])
def test_firmware_and_emulated_board_reply_alike(board, firmware_build):
    fw_before, fw_groups = _firmware(board)
    vb_before, vb_groups = _virtual(board)
    assert fw_before == vb_before == [f"HELLO {BOARD[board]} 2.3.0+481e87e3"]
    _check_stop_counts(fw_groups)
    _check_stop_counts(vb_groups)
    fw, vb = _grouped_bodies(fw_groups), _grouped_bodies(vb_groups)
    script = _script(board)
    diffs = [
        f"{script[i][0][:40]!r}: firmware {fw[i]!r}, emulated {vb[i]!r}"
        for i in range(len(script))
        if fw[i] != vb[i]
    ]
    assert not diffs, "the emulated board diverges from the firmware:\n" + "\n".join(diffs)
    if board == "stream":  # the script reached what it is about
        lines = [b for w in fw for b in w]
        for what in ("N,LIMIT,SPEED,", "N,LIMIT,TRAVEL,156", "N,LIMIT,TRAVEL,0", "N,WATCHDOG,", "ERR FULL"):
            assert any(b.startswith(what) for b in lines), what
        assert sum(b.startswith("DONE") for b in lines) == 4
