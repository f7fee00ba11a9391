"""End to end on the virtual rig, for every shipped rig file and ten rig files generated with a fixed seed
(slow: ``python -m pytest -m slow tests/test_every_rig.py``; about an hour on two shared cores).

The generated rigs (:func:`generate`, seed :data:`SEED`) have 1 to 4 tendons at random angles, at least
:data:`MIN_GAP_DEG` apart (the rig file refuses two tendons within 1 deg; closer than that the arm's statics
leave a held tendon slack): one tendon from the template a user starts from (``python -m helpers rig new``,
the paper's rig, its tendon turned), several from the shipped ``rigs/four-tendon.toml`` (a release below
rest and the DAQ at 1 Mbaud, as a rig of several tendons needs) with its ``[[tendon]]`` tables replaced.
Every rig is written to ``tmp_path``; every command writes under ``tmp_path``, nothing into the working tree.

Each rig, through the command line (``helpers.__main__.main``) as a user types it:

- ``rig check FILE``;
- one tendon: ``record calibration``, ``record all --repetitions 1`` (the identification and Table I), a
  reduced ``tune --repetitions 1``, then ``record pulse`` unshaped and with every system the identification
  designs (``zv``, ``zvd``, ``ei``) and every design the tune wrote (``--design``: ``multi-mode``,
  ``scheduled``, ``map-following``, ``auto`` ...);
- several tendons: ``record move`` 10 mm towards tendon 1 with every ``--shaper``, ``record tip-stream`` (a
  line towards tendon 1, 5 mm at 50 mm/s, ZVD; the square as well where the tendons surround the backbone on
  a shipped rig; refused at the board's whole steps, again with the ``--prepull`` the refusal names, or not
  at all on an arm a pre-pull would bend), a reduced ``tune --directions A --bends 10 --repetitions 1``;
- ``metrics`` of what was recorded: one tendon, the Table II rows of every pulse; several, the lead tendon's
  rows (tendon 1, the one that pulls most towards the bend) and a finite tip row of every move;
- ``home`` over the pseudo-terminals of ``serve-virtual-rig`` after a programme left the tendons off zero;
- ``rig firmware FILE --dry-run``, and the real build into ``tmp_path`` where ``avr-gcc`` is installed.

Every figure is the twin's (simulated).
"""

from __future__ import annotations

import io
import json
import math
import re
import shutil
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from helpers import recordings, rigfile
from helpers.__main__ import main
from helpers.board.programmes import Dwell, Move, Programme
from helpers.commands.metrics_report import move_tables
from helpers.recordings import nominal_calibration
from helpers.research.task_shaping import SHAPERS as MOVE_SHAPERS
from helpers.rig import Rig
from helpers.rig.trim import TensionGuard
from helpers.virtual.emulator import server
from helpers.virtual.emulator.world import build_world

SEED = 36
"""The generator's seed."""

GENERATED = 10
"""How many rig files are generated."""

MIN_GAP_DEG = 30.0
"""Least angle between two generated tendons."""

SHIPPED = sorted(rigfile.RIGS_DIR.glob("*.toml"))
CASES = [f"shipped-{p.stem}" for p in SHIPPED] + [f"generated-{k}" for k in range(GENERATED)]

STREAMS = {
    "shipped-four-tendon": ("prepull 1", "prepull 1"),
    "shipped-hanging": ("as is", "as is"),
    "shipped-three-tendon": ("prepull 1", "prepull 1"),
    "generated-9": ("as is",),
}
"""What ``record tip-stream`` does with the line (and the square, on a shipped rig that surrounds the
backbone) of every rig of several tendons, as the user follows its refusal (:func:`_tip_stream`): recorded
as asked, recorded with the ``--prepull`` the refusal names, or refused with no pre-pull to offer (the arm's
tendons do not balance); every case not named is refused (``docs/task_space.md``: seven of the eight
generated rigs of several tendons)."""

READY_S = 120.0
"""Deadline for the pseudo-terminal server to print its ports: only a failure reaches it."""


def generate(folder: Path, seed: int = SEED, count: int = GENERATED) -> list[Path]:
    """``count`` rig files of 1-4 tendons at random angles (module docstring), written into ``folder``."""
    template = folder / "template.toml"
    assert main(["rig", "new", str(template)]) == 0
    one = template.read_text()
    four = (rigfile.RIGS_DIR / "four-tendon.toml").read_text()
    head, tail = four[: four.index("[[tendon]]")], four[four.index("[boards]") :]
    rng = np.random.default_rng(seed)
    out = []
    for k in range(count):
        n = int(rng.integers(1, 5))
        while True:
            angles = np.round(rng.uniform(0.0, 360.0, n), 1)
            gaps = [abs((a - b + 180.0) % 360.0 - 180.0) for i, a in enumerate(angles) for b in angles[:i]]
            if all(g >= MIN_GAP_DEG for g in gaps):
                break
        name = f"generated-{k}-{n}t"
        tendons = "".join(f"[[tendon]]\nangle_deg = {float(a)!r}\n\n" for a in angles)
        if n == 1:
            text = one.replace('name = "template"', f'name = "{name}"') + "\n" + tendons
        else:
            text = re.sub(r'^name = ".*"$', f'name = "{name}"', head, flags=re.M) + tendons + tail
        path = folder / f"{name}.toml"
        path.write_text(text)
        out.append(path)
    return out


@pytest.fixture(scope="module")
def generated(tmp_path_factory) -> list[Path]:
    return generate(tmp_path_factory.mktemp("generated-rigs"))


def _surrounds(rig: rigfile.RigFile) -> bool:
    """Every gap between neighbouring tendons below 180 deg: a tendon faces every direction."""
    a = sorted(t.angle_deg % 360.0 for t in rig.tendons)
    gaps = [b - c for b, c in zip(a[1:], a[:-1], strict=False)] + [a[0] + 360.0 - a[-1]]
    return len(a) > 2 and max(gaps) < 180.0


class Cli:
    """``python -m helpers --rig FILE ...`` in this process, its output captured."""

    def __init__(self, path: Path, data: Path, capsys) -> None:
        self.path, self.data, self.capsys = path, data, capsys

    def __call__(self, *argv: str, rig: bool = True, data: bool = True) -> str:
        rc, out, err, args = self.returning(*argv, rig=rig, data=data)
        assert rc == 0, f"{' '.join(args)} -> {rc}: {err[-2000:]}"
        return out

    def returning(self, *argv: str, rig: bool = True, data: bool = True) -> tuple[int, str, str, list[str]]:
        """The command's exit code, output, error output and arguments, whatever it returns."""
        args = (["--rig", str(self.path)] if rig else []) + list(argv)
        args += ["--data-dir", str(self.data)] if data else []
        rc = main(args)
        out, err = self.capsys.readouterr()
        return rc, out, err, args


def _one_tendon(cli: Cli, data: Path) -> list[Path]:
    cli("record", "calibration", "--quiet")
    cli("record", "all", "--repetitions", "1", "--quiet")
    cli("tune", "--repetitions", "1", "--quiet")
    designs = sorted((data / "tuning" / "designs").glob("*.json"))
    first = re.search(r"_v([\dp]+)_x([\dp]+)\.json$", designs[0].name)  # 7.5 mm is written x7p5
    v, x = (first.group(k).replace("p", ".") for k in (1, 2))
    condition = designs[0].name[designs[0].name.index("_v") :]
    chosen = [p for p in designs if p.name.endswith(condition)]
    systems = {json.loads(p.read_text())["system"] for p in chosen}
    assert {"zv", "zvd", "ei", "multi-mode", "scheduled", "map-following", "auto"} <= systems
    for system in ("unshaped", "zv", "zvd", "ei"):  # designed from the identification
        cli("record", "pulse", "--v-in", v, "--x-f", x, "--system", system, "--group", "pulses", "--quiet")
    for p in chosen:  # every design the tune wrote for that condition
        cli("record", "pulse", "--design", str(p), "--v-in", v, "--x-f", x, "--group", "pulses", "--name",
            f"design_{p.stem}", "--quiet")  # fmt: skip
    pulses = sorted((data / "pulses").glob("*.csv"))
    assert len(pulses) == 4 + len(chosen)
    out = cli("metrics", str(data / "pulses"), data=False, rig=False)
    assert "Skipped: none." in out
    for p in pulses:
        rec = recordings.load(p)
        assert rec.status == "complete" and rec.tendons == 1
        assert rec.frame["steps"].iloc[-1] == 0 and rec.frame["steps"].max() > 0
    return pulses


def _several(cli: Cli, rig: rigfile.RigFile, data: Path, case: str) -> None:
    shipped = case.startswith("shipped-")
    a1 = f"{rig.tendons[0].angle_deg:g}"
    for shaper in MOVE_SHAPERS:
        move = ["record", "move", "--direction-deg", a1, "--bend-mm", "10", "--shaper", shaper]
        if shaper == "none":  # it slackens a tendon for longer than the floor watch allows (four-tendon,
            cli(*move, "--quiet", "--no-floor-watch")  # 10 mm: stopped at 1.05 s)
            continue
        rc, out, err, args = cli.returning(*move)
        if rc != 0:  # only where the twin foresaw the slack: the watch stops the run, saved aborted
            assert rc == 3 and "warning: the twin foresees a tendon below the floor" in out, (args, rc, err)
            line = err.rstrip("\n").split("\n")[-1]  # one line after the progress bar's
            assert line.startswith("error: tendon ") and " below the floor " in line, err
            assert "floor_watch_ms)" in line and "partial recording saved to " in line, err
            aborted = sorted((data / "moves").glob(f"move_{shaper}_*_aborted_*"))
            assert [p.suffix for p in aborted] == [".csv", ".json"], aborted
            meta = recordings.load(aborted[0]).meta
            assert meta["abort_reason"].startswith("BelowFloor: tendon ")
            assert meta["scenario"]["floor_check"]["ok"] is False  # foreseen by the twin before the run
            for p in aborted:  # recorded again whole, for the figures below
                p.unlink()
            cli(*move, "--quiet", "--no-floor-watch")
    moves = sorted((data / "moves").glob("*.csv"))
    assert len(moves) == len(MOVE_SHAPERS)
    stream = ["record", "tip-stream", "--bend-mm", "5", "--v-in", "50", "--shaper", "zvd", "--quiet"]
    outcomes = [_tip_stream(cli, *stream, "--path", "line", "--direction-deg", a1)]
    if shipped and _surrounds(rig):
        outcomes.append(_tip_stream(cli, *stream, "--path", "square"))
    assert tuple(outcomes) == STREAMS.get(case, ("refused",)), outcomes
    streams = sorted((data / "tip_streams").glob("*.csv"))
    assert len(streams) == sum(o != "refused" for o in outcomes)
    for p in streams:
        rec = recordings.load(p)
        assert rec.status == "complete" and rec.tendons == rig.n_tendons
        prepull = rec.meta["scenario"]["prepull_steps"]
        assert p.stem.endswith("_pre1") == (prepull == 1) and prepull in (0, 1)
        assert [int(rec.frame[f"steps_{i}"].iloc[-1]) for i in range(rig.n_tendons)] == [0] * rig.n_tendons
    cli("tune", "--directions", a1, "--bends", "10", "--repetitions", "1", "--quiet")
    doc = json.loads((data / "tuning" / "tendons" / rig.name / "verification.json").read_text())
    assert {r["system"] for r in doc["summary"]} == {"unshaped", "zv", "zvd", "scheduled-zv", "scheduled-zvd",
                                                     "zvd-zv34", "auto"}  # fmt: skip
    assert all(math.isfinite(r["lead_residual_n"]) for r in doc["summary"])
    out = cli("metrics", str(data / "moves"), data=False, rig=False)
    assert f"lead tendon 1 (pulls most towards {a1} deg)" in out
    tables = move_tables([recordings.load(p) for p in moves], 0.05)
    assert len(tables.lines) == len(moves) and not any("no Table II rows" in x for x in tables.lines)
    lead = tables.tendons[tables.tendons["role"] == "lead"]
    assert len(lead) == 2 * len(moves) and set(lead["tendon"]) == {1}
    assert lead["peak_n"].notna().all()
    tip = tables.tip
    assert len(tip) == 2 * len(moves) and np.isfinite(tip["peak_mm"].to_numpy(float)).all()
    for p in moves:
        rec = recordings.load(p)
        assert rec.status == "complete"
        assert [int(rec.frame[f"steps_{i}"].iloc[-1]) for i in range(rig.n_tendons)] == [0] * rig.n_tendons


def _tip_stream(cli: Cli, *argv: str) -> str:
    """``record tip-stream`` as a user follows its refusal at the board's whole steps.

    A tendon below the floor at the whole steps the board counts is refused in one line (exit 3, nothing
    written) that names the ``--prepull`` that passes, then run with it; on an arm a pre-pull would bend (its
    tendons do not balance) the refusal says so, and nothing is recorded. Returns ``as is``, ``prepull K`` or
    ``refused``.
    """
    args = ["--rig", str(cli.path), *argv, "--data-dir", str(cli.data)]
    rc = main(args)
    err = cli.capsys.readouterr().err
    if rc == 0:
        return "as is"
    assert rc == 3 and err.count("\n") == 1 and "by statics at the board's whole steps at " in err, err
    hint = re.search(r"; --prepull (\d+) passes \(", err)
    if hint is None:
        assert "; no --prepull can lift it on this rig: pulling every tendon in would bend" in err, err
        assert not (cli.data / "tip_streams").exists() or not any((cli.data / "tip_streams").iterdir())
        return "refused"
    cli(*argv, "--prepull", hint.group(1))
    return f"prepull {hint.group(1)}"


def _home_over_the_pty(rig: rigfile.RigFile, path: Path, folder: Path, capsys) -> None:
    """``serve-virtual-rig``'s boards; a programme leaves every tendon 3 steps in; ``home`` brings it back.

    The programme is no move: on an arm whose tendons do not balance, pulling every tendon in bends it and
    slackens one for longer than the floor watch allows, so it runs unwatched (``TensionGuard(watch=False)``).
    """
    world = build_world(rig, f"e2e-pty-{rig.name}")
    out, stop = io.StringIO(), threading.Event()
    thread = threading.Thread(target=server.serve, args=(world,), daemon=True,
                              kwargs={"speed": 1.0, "out": out, "stop": stop})  # fmt: skip
    thread.start()
    deadline = time.monotonic() + READY_S
    while out.getvalue().count("\n") < 2 and thread.is_alive() and time.monotonic() < deadline:
        time.sleep(0.01)  # the server prints its two device paths when it is ready
    ports = dict(line.split() for line in out.getvalue().splitlines())
    pair = f"{ports['daq']},{ports['stepper']}"
    n = rig.n_tendons
    try:
        with Rig(pair, rig, calibration=nominal_calibration(rig)) as r:
            r.run(Programme((Move(30_000, (3,) * n), Dwell(100))), path=folder / "off_zero", tail_s=0.1,
                  progress=False, guard=TensionGuard(watch=False) if n > 1 else None)  # fmt: skip
            assert r.positions() == (3,) * n
        assert main(["--rig", str(path), "home", "--ports", pair]) == 0
        capsys.readouterr()
        with Rig(pair, rig, calibration=nominal_calibration(rig)) as r:
            assert r.positions() == (0,) * n
    finally:
        stop.set()
        thread.join(timeout=READY_S)


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES)
def test_every_rig_works_end_to_end_on_the_virtual_rig(case, generated, tmp_path, capsys) -> None:
    kind, _, which = case.partition("-")
    path = rigfile.RIGS_DIR / f"{which}.toml" if kind == "shipped" else generated[int(which)]
    rig = rigfile.load(path)
    data = tmp_path / "data"
    cli = Cli(path, data, capsys)
    report = cli("rig", "check", str(path), rig=False, data=False)
    assert report.startswith(f"rig {rig.name} (") and f"hash {rig.hash}, schema 1: valid" in report
    if rig.n_tendons == 1:
        _one_tendon(cli, data)
    else:
        _several(cli, rig, data, case)
    _home_over_the_pty(rig, path, tmp_path / "pty", capsys)
    dry = cli("rig", "firmware", str(path), "--dry-run", rig=False, data=False)
    assert "make" in dry
    if shutil.which("avr-gcc") and shutil.which("make"):  # the real build, where the AVR toolchain is
        built = cli("rig", "firmware", str(path), "--out", str(tmp_path / "fw"), rig=False, data=False)
        assert f"firmware for rig {rig.name} (hash {rig.hash}" in built
        assert (tmp_path / "fw" / "daq_mega.hex").exists() and (tmp_path / "fw" / "stepper_uno.hex").exists()
