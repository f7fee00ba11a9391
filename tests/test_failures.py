"""Every way a run can end, tried as a user would: through the command line and the pseudo-terminal server.

A ``serve-virtual-rig`` process (paced at 10x real time) stands in for the two boards; ``python -m helpers
record`` runs against its device paths in another process. The tests send signals, kill the server, open the
ports twice, and check what the user sees (one line, an exit status from docs/faults.md) and what is on disk.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from helpers import recordings, rigfile
from helpers.base.paths import DATA_DIR, REPO_ROOT
from helpers.board.programmes import Programme, Segment
from helpers.commands.home import PositionUnknown, home
from helpers.rig import PortBusy, Rig
from helpers.rig.driver import SILENCE_S
from helpers.rig.link import BoardTimeout, Link, ints, served_clock

PAPER = rigfile.default_rig()

PY = sys.executable

READY_S = 60.0
"""Deadline (s) for a board or a process to become ready: generous, since waits end on readiness (a board's
greeting, a line printed) and only a failure runs to the deadline; a busy machine may take seconds."""

PROCESS_S = 300.0
"""Deadline (s) for a command-line process to finish: a fresh environment compiles the virtual rig first."""

PROGRESS = re.compile(r"(\d+\.\d)/\d+\.\d s")
"""The recorder's progress bar: device seconds since GO."""


class Server:
    """``python -m helpers serve-virtual-rig`` in a subprocess, with its two device paths."""

    def __init__(self, speed: float = 10.0, *extra: str, ready: tuple[str, ...] = ("daq", "stepper")) -> None:
        self.proc = subprocess.Popen(
            [
                PY,
                "-m",
                "helpers",
                "serve-virtual-rig",
                "--speed",
                str(speed),
                "--rig-name",
                "failures",
                *extra,
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=REPO_ROOT,
        )
        paths: dict[str, str] = {}
        deadline = time.monotonic() + PROCESS_S  # the first start compiles the plant
        while len(paths) < 2 and time.monotonic() < deadline:
            line = self.proc.stdout.readline()
            if not line:
                break
            kind, _, path = line.strip().partition(" ")
            paths[kind] = path
        assert set(paths) == {"daq", "stepper"}, self.proc.stderr.read()[-500:]
        self.daq, self.stepper = paths["daq"], paths["stepper"]
        # ready when both boards answer (on a loaded machine the server's first answers can take seconds)
        for kind in ready:
            _board(getattr(self, kind), kind).close()

    @property
    def ports(self) -> str:
        return f"{self.daq},{self.stepper}"

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            self.proc.wait(timeout=READY_S)


@pytest.fixture(scope="module")
def server():
    """One server for the tests that leave the boards idle and the cable at 0 (it takes 2 s to start)."""
    s = Server()
    yield s
    s.stop()


@pytest.fixture
def own_server():
    """A server a test may kill or leave in any state."""
    s = Server()
    yield s
    s.stop()


@pytest.fixture
def data_dir(tmp_path):
    """A data folder with the load-cell calibration every run needs."""
    (tmp_path / "calibration").mkdir()
    shutil.copy(DATA_DIR / "calibration" / "calibration.json", tmp_path / "calibration" / "calibration.json")
    return tmp_path


def _record(data_dir: Path, ports: str, *extra: str, quiet: bool = True) -> subprocess.Popen:
    cmd = [PY, "-m", "helpers", "record", "pulse", "--ports", ports, "--v-in", "200", "--x-f", "20",
           "--data-dir", str(data_dir), "--group", "g", "--name", "p", *(["--quiet"] if quiet else []),
           *extra]  # fmt: skip
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO_ROOT)


def _run_until(proc: subprocess.Popen, device_s: float) -> str:
    """Wait until a recorder (started with ``quiet=False``) shows ``device_s`` s of its run since GO.

    Readiness, not a delay: the recorder prints 'connected' once both boards answer, then its progress bar in
    device time; whatever the machine's load, the run is then at least that far. Returns stderr read so far.
    """
    line = proc.stdout.readline()
    assert line.startswith("connected"), line + proc.stderr.read()
    fd, seen = proc.stderr.fileno(), b""
    deadline = time.monotonic() + READY_S
    while time.monotonic() < deadline:
        chunk = os.read(fd, 4096)  # blocks until the bar moves (or the recorder ends)
        if not chunk:
            break
        seen += chunk
        shown = PROGRESS.findall(seen.decode(errors="replace"))
        if shown and float(shown[-1]) >= device_s:
            return seen.decode(errors="replace")
    text = seen.decode(errors="replace")
    raise AssertionError(f"the run did not reach {device_s} s of device time: {text}")


def _message_lines(err: str) -> list[str]:
    """What the recorder said on stderr besides its progress bar (redrawn with carriage returns)."""
    parts = (p.strip() for p in re.split(r"[\r\n]", err))
    return [p for p in parts if p and not PROGRESS.search(p)]


def _boards_idle(server: Server) -> tuple[str, str]:
    """Ask both boards, as a new client, whether anything is still running: (CLEAR reply, RATE reply)."""
    rig = Rig(server.ports, PAPER, recordings_calibration(), hello_timeout=READY_S)
    try:
        return rig.stepper.command("CLEAR"), rig.daq.command("RATE 1000")
    finally:
        rig.close()


def _board(path: str, kind: str = "stepper", **kwargs) -> Link:
    """One board of the server, as a client opens it (the paper's rig)."""
    baud = getattr(PAPER.hardware, f"{kind}_baud")
    return Link.open(path, kind, PAPER, baud, hello_timeout=READY_S, **kwargs)


def _position(stepper: Link) -> int:
    return ints(stepper.command("POS"))[0]


def _pull(stepper: Link, steps: int) -> None:
    """Another client pulls the cable in by ``steps`` and leaves it there."""
    stepper.send_all(Programme((Segment(1, steps, 2000),)).commands())
    stepper.command("EN 1")
    stepper.command("GO")
    while stepper.done is None:
        stepper.read()


def recordings_calibration() -> dict:
    return {"newtons_per_count": 0.02, "offset_counts": 50.0, "mm_per_step": 0.25525, "origin": "test"}


@pytest.mark.parametrize(
    "sig, status",
    [
        # the default suite's signal checks are in-process (tests/test_run_signals.py, test_cli_signals.py)
        pytest.param(signal.SIGTERM, 143, marks=pytest.mark.slow),
        pytest.param(signal.SIGHUP, 129, marks=pytest.mark.slow),
        pytest.param(signal.SIGINT, 130, marks=pytest.mark.slow),
    ],
)
def test_a_signal_mid_run_stops_the_boards_and_saves_a_loadable_partial_recording(data_dir, sig, status):
    server = Server(speed=3.0)  # the 12 s run lasts about 4 s of wall time
    try:
        _signal_mid_run(server, data_dir, sig, status)
    finally:
        server.stop()


def _signal_mid_run(server: Server, data_dir: Path, sig: int, status: int) -> None:
    proc = _record(data_dir, server.ports, quiet=False)
    seen = _run_until(proc, 1.5)  # the cable is pulled in (1.0-1.1 s after GO) and held until 8 s
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=PROCESS_S)
    err = seen + err
    assert proc.returncode == status, err
    lines = _message_lines(err)
    assert len(lines) == 1 and "Traceback" not in err, err  # one line, no traceback
    assert "partial recording saved to" in lines[0] and "stepper was stopped and disabled" in lines[0]
    saved = list((data_dir / "g").glob("p_aborted_*.csv"))
    assert len(saved) == 1 and not (data_dir / "g" / "p.csv").exists()
    rec = recordings.load(saved[0])
    assert rec.status == "aborted" and len(rec.frame) > 0
    # the boards are idle: no programme running (CLEAR is accepted), no stream running (RATE is accepted)
    assert _boards_idle(server) == ("OK CLEAR", "OK RATE 1000")
    # the cable stopped part-way: home brings it back from where the board says it is
    stepper = _board(server.stepper)
    try:
        assert _position(stepper) > 0
        assert "back to position 0" in home(stepper, PAPER)
        assert _position(stepper) == 0
    finally:
        stepper.close()


@pytest.mark.slow
def test_a_server_the_host_does_not_run_pauses_its_boards_and_is_no_silent_board(own_server, data_dir):
    """A machine too busy to run the server, made certain: the server is stopped (SIGSTOP) mid-run for three
    times the 2 s silence interval. Its boards pause with it (the host counts their silence on the server's
    awake clock), so the run completes; on the wall clock the recorder ended with "sent no sample"."""
    proc = _record(data_dir, own_server.ports, quiet=False)
    seen = _run_until(proc, 1.5)
    own_server.proc.send_signal(signal.SIGSTOP)
    try:
        time.sleep(3 * SILENCE_S)  # the stop's length, not a deadline: any longer stop is the same
    finally:
        own_server.proc.send_signal(signal.SIGCONT)
    out, err = proc.communicate(timeout=PROCESS_S)
    assert proc.returncode == 0, seen + err
    rec = recordings.load(data_dir / "g" / "p.csv")
    assert rec.status == "complete" and rec.meta["source"]["via"] == "pseudo-terminal server"


@pytest.mark.slow  # a server process of its own and 2 s of silence (the default suite's budget)
def test_a_hung_board_of_the_server_is_still_silent_on_its_awake_clock():
    """The server runs and its DAQ stops answering 1 s of device time after it starts (``hang_at``): the awake
    clock runs on, and the host's wait for a reply ends in one clear error (whether the board hangs before the
    host has connected or after)."""
    hung = Server(1.0, "--daq-faults", "hang_at=1", ready=("stepper",))
    try:
        assert served_clock(hung.daq) is not None  # the clock the wait counts on
        with pytest.raises(BoardTimeout, match=r"no daq board answered|daq board did not answer 'PING'"):
            link = Link.open(hung.daq, "daq", PAPER, PAPER.hardware.daq_baud, hello_timeout=SILENCE_S)
            try:
                while True:  # answered until the board hangs
                    link.command("PING", timeout=SILENCE_S)
            finally:
                link.close()
    finally:
        hung.stop()


def test_a_second_client_on_the_same_ports_gets_port_busy(server, data_dir):
    first = Rig(server.ports, PAPER, recordings_calibration(), hello_timeout=READY_S)
    try:
        with pytest.raises(PortBusy, match="port busy"):
            Rig(server.ports, PAPER, recordings_calibration(), hello_timeout=READY_S)
        proc = _record(data_dir, server.ports)
        _, err = proc.communicate(timeout=PROCESS_S)
        assert proc.returncode == 4 and err.count("\n") == 1 and "port busy" in err
    finally:
        first.close()


@pytest.mark.slow  # a disconnect mid-run in-process: tests/test_faults.py (default suite)
def test_a_server_killed_mid_run_is_reported_and_the_data_kept(own_server, data_dir):
    server = own_server
    proc = _record(data_dir, server.ports, quiet=False)
    seen = _run_until(proc, 0.5)
    server.proc.kill()
    _, err = proc.communicate(timeout=PROCESS_S)
    err = seen + err
    assert proc.returncode == 4, err
    lines = _message_lines(err)
    assert len(lines) == 1 and "partial recording saved to" in lines[0], err
    assert "cleanup failed" in err and "driver may be on" in err  # the host could not reach the boards
    saved = list((data_dir / "g").glob("p_aborted_*.csv"))
    assert len(saved) == 1 and recordings.load(saved[0]).status == "aborted"


def test_home_returns_the_cable_from_where_the_board_says_it_is(server):
    stepper = _board(server.stepper)
    try:  # another client leaves the cable pulled in by 40 steps
        _pull(stepper, 40)
        assert _position(stepper) == 40
    finally:
        stepper.close()
    # a pulse refuses to start from there ...
    cmd = [PY, "-m", "helpers", "home", "--ports", server.ports]
    done = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO_ROOT, timeout=PROCESS_S)
    assert done.returncode == 0, done.stderr
    assert "moved 40 steps" in done.stdout
    stepper = _board(server.stepper)
    try:
        assert _position(stepper) == 0
    finally:
        stepper.close()


@pytest.mark.slow
def test_a_pulse_refuses_to_start_away_from_zero(own_server, data_dir):
    server = own_server
    stepper = _board(server.stepper, timeout=10.0)
    try:
        _pull(stepper, 10)
    finally:
        stepper.close()
    proc = _record(data_dir, server.ports)
    _, err = proc.communicate(timeout=PROCESS_S)
    assert proc.returncode == 3 and "not at 0" in err and "helpers home" in err
    assert not (data_dir / "g").exists() or not list((data_dir / "g").glob("*.csv"))


@pytest.mark.slow
def test_home_after_a_board_reset_asks_for_confirmation():
    # the in-process virtual stepper restarts when its port opens, as an Arduino does (`home --ports virtual`
    # itself makes a new rig at 0 and says there is nothing to home: tests/test_cli_refusals.py)
    stepper = _board("virtual://stepper?world=home-after-reset")
    try:
        assert stepper.booted_on_open
        with pytest.raises(PositionUnknown, match="position is unknown.*--confirm-slack"):
            home(stepper, PAPER)
        assert "confirmed slack" in home(stepper, PAPER, confirm_slack=True)
    finally:
        stepper.close()


@pytest.mark.slow
def test_two_recorders_into_one_group_the_second_is_refused(data_dir):
    first = subprocess.Popen(
        [PY, "-m", "helpers", "record", "table-i", "--data-dir", str(data_dir), "--group", "g", "--quiet",
         "--zeta", "0.044", "--omega-d", "25.085", "--repetitions", "1"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO_ROOT,
    )  # fmt: skip
    try:
        assert first.stdout.readline().startswith("connected")
        proc = _record(data_dir, "virtual")
        _, err = proc.communicate(timeout=PROCESS_S)
        assert proc.returncode == 5 and "busy" in err and err.count("\n") == 1
    finally:
        first.terminate()
        first.communicate(timeout=PROCESS_S)


REFUSALS = [
    (["record", "pulse", "--v-in", "500", "--x-f", "10"], 3, "500.0 mm/s exceeds the limit of 400 mm/s"),
    (["record", "pulse", "--v-in", "nan", "--x-f", "10"], 2, "outside"),
    (["record", "pulse", "--v-in", "200", "--x-f", "10", "--group", "../../x"], 2, "invalid group"),
    (
        ["record", "pulse", "--v-in", "200", "--x-f", "10", "--name", "../../../x"],
        2,
        "invalid recording name",
    ),
    (["record", "pulse", "--v-in", "200", "--x-f", "10", "--name", "calibration"], 2, "reserved"),
    (
        ["record", "pulse", "--v-in", "200", "--x-f", "10", "--rig-name", "x&disconnect_at=0.5"],
        2,
        "invalid",
    ),
    (["record", "pulse", "--v-in", "200", "--x-f", "10", "--t-end", "1e10"], 2, "outside"),
    (["record", "pulse", "--v-in", "200", "--x-f", "10", "--repetitions", "-1"], 2, "outside"),
    (["record", "pulse", "--v-in", "200"], 2, "needs --v-in and --x-f"),
    (["serve-virtual-rig", "--speed", "inf"], 2, "outside"),
    (["serve-virtual-rig", "--speed", "nan"], 2, "outside"),
    (["reproduce", "--jobs", "0"], 2, "outside"),
    (
        [
            "record",
            "pulse",
            "--v-in",
            "200",
            "--x-f",
            "20",
            "--system",
            "zvd",
            "--zeta",
            "0.044",
            "--omega-d",
            "25.085",
            "--t-end",
            "8.1",
        ],
        3,
        "refused",
    ),  # fmt: skip
]


@pytest.mark.parametrize(("argv", "status", "message"), REFUSALS)
def test_every_refusal_is_one_line_with_its_exit_status(data_dir, capsys, argv, status, message):
    """In-process (quick); two of the cases run again below as real processes."""
    from helpers.__main__ import main

    if argv[0] == "record":
        argv = [*argv, "--data-dir", str(data_dir)]
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's own refusals
        code = exc.code
    err = capsys.readouterr().err
    assert code == status, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert message in err
    assert not list(Path(data_dir).rglob("*.csv"))


@pytest.mark.parametrize(("argv", "status"), [(REFUSALS[-1][0], 3)])
def test_refusals_end_to_end(data_dir, argv, status):
    cmd = [PY, "-m", "helpers", *argv, "--data-dir", str(data_dir)]
    done = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO_ROOT, timeout=PROCESS_S)
    assert done.returncode == status and done.stderr.count("\n") == 1 and "Traceback" not in done.stderr


def test_debug_shows_the_traceback(data_dir, capsys):
    from helpers.__main__ import main

    argv = ["--debug", *REFUSALS[-1][0], "--data-dir", str(data_dir)]
    assert main(argv) == 3
    err = capsys.readouterr().err
    assert "Traceback" in err and err.strip().splitlines()[-1].startswith("error:")


@pytest.mark.slow
def test_garbage_and_floods_through_the_server(data_dir):
    noisy = Server(10.0, "--daq-faults", "garbage=0.02,corrupt=0.02,drop=0.01")
    try:
        proc = _record(data_dir, noisy.ports)
        out, err = proc.communicate(timeout=PROCESS_S)
        assert proc.returncode == 0, err
        rec = recordings.load(data_dir / "g" / "p")
        c = rec.meta["counts"]
        assert c["corrupted"] > 0 and c["dropped"] > 0 and rec.status == "complete"
    finally:
        noisy.stop()
    flood = Server(10.0, "--daq-faults", "garbage=1.0,corrupt=0.9")
    try:
        proc = _record(data_dir, flood.ports, "--name", "q")
        _, err = proc.communicate(timeout=PROCESS_S)
        assert proc.returncode == 4 and err.count("\n") == 1, err
        assert "corrupted lines" in err or "did not come to rest" in err or "no sample" in err
    finally:
        flood.stop()


@pytest.mark.slow
def test_no_stale_lock_after_a_killed_recorder(data_dir):
    proc = subprocess.Popen(
        [PY, "-m", "helpers", "record", "table-i", "--data-dir", str(data_dir), "--group", "g", "--quiet",
         "--zeta", "0.044", "--omega-d", "25.085", "--repetitions", "1"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO_ROOT,
    )  # fmt: skip
    assert proc.stdout.readline().startswith("connected")
    os.kill(proc.pid, signal.SIGKILL)  # no cleanup at all: the kernel still releases the lock
    proc.communicate(timeout=PROCESS_S)
    done = _record(data_dir, "virtual", "--t-end", "9")
    _, err = done.communicate(timeout=PROCESS_S)
    assert done.returncode == 0, err
