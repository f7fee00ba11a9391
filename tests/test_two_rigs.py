"""Two rigs in one process: the paper's rig and ``rigs/four-tendon.toml``, each a value given to its own
``Rig(ports, rig)``, under one world name, driven in turns (a pulse on the paper's rig, a move on the
four-tendon rig, again), record what each records alone: the same CSV bytes, and the same JSON apart from the
wall-clock ``started_utc``.

Each sequence starts from fresh worlds (``build_world``), so the sensor noise and the twins' states are each
rig's own; the runs are short (a paper pulse of 9 s, a coordinated four-tendon move of 2.6 s).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from helpers import rigfile
from helpers.board.programmes import Dwell, Move, Programme
from helpers.recordings import nominal_calibration
from helpers.rig import Rig
from helpers.rig.trim import TensionGuard
from helpers.virtual.emulator.world import build_world, forget_world, register_world

WORLD = "two-rigs-test"

FOUR_MOVE = Programme((Dwell(500), Move(60_000, (8, 8, -7, -7)), Dwell(1000), Move(60_000, (-8, -8, 7, 7)),
                       Dwell(1000)))  # fmt: skip
"""A coordinated move of the four tendons towards 45 deg: tendons 1, 2 pulled 8 steps, 3, 4 paid out 7."""


@pytest.fixture(scope="module")
def rigs() -> dict[str, rigfile.RigFile]:
    names = {"paper": "paper", "four": "four-tendon"}
    return {key: rigfile.load(rigfile.resolve(name)) for key, name in names.items()}


def _open(rig: rigfile.RigFile) -> Rig:
    forget_world(WORLD, rig)
    register_world(build_world(rig, WORLD))
    return Rig("virtual", rig, calibration=nominal_calibration(rig), world=WORLD)


def _run(rig: Rig, k: int, folder: Path) -> Path:
    """Run ``k`` of a rig: a pulse (the paper's) or the coordinated move (four tendons)."""
    if rig.n == 1:
        rec = rig.run_pulse(200.0, 10.0, path=folder / f"pulse_{k}", t_end_s=9.0, progress=False,
                            noise_seed=10 + k)  # fmt: skip
    else:
        rec = rig.run(FOUR_MOVE, path=folder / f"move_{k}", scenario={"purpose": "two rigs"}, tail_s=0.3,
                      progress=False, noise_seed=20 + k, guard=TensionGuard())  # fmt: skip
    return rec.path


def _contents(path: Path) -> tuple[bytes, dict]:
    meta = json.loads(path.with_suffix(".json").read_text())
    assert meta.pop("started_utc")
    return path.read_bytes(), meta


def test_two_rigs_in_turns_record_what_each_records_alone(rigs, tmp_path) -> None:
    alone: dict[str, list[Path]] = {}
    try:
        for name, rig in rigs.items():  # each rig alone: two runs
            with _open(rig) as r:
                alone[name] = [_run(r, k, tmp_path / "alone" / name) for k in (1, 2)]
        turns: dict[str, list[Path]] = {name: [] for name in rigs}
        with _open(rigs["paper"]) as paper, _open(rigs["four"]) as four:
            assert paper.world is not four.world  # one name, two rig files: two worlds
            for k in (1, 2):  # a pulse on the paper's rig, a move on the four-tendon rig, alternating
                turns["paper"].append(_run(paper, k, tmp_path / "turns" / "paper"))
                turns["four"].append(_run(four, k, tmp_path / "turns" / "four"))
    finally:
        for rig in rigs.values():
            forget_world(WORLD, rig)
    for name in rigs:
        for a, b in zip(alone[name], turns[name], strict=True):
            csv_a, meta_a = _contents(a)
            csv_b, meta_b = _contents(b)
            assert csv_a == csv_b, f"{name}: {a.name} differs in turns"
            assert meta_a == meta_b
    # the runs did something: the paper's pulse moved its cable, the four tendons moved in their own ways
    assert b"\n" in csv_a and json.loads(alone["four"][0].with_suffix(".json").read_text())["tendons"] == 4
    first = alone["paper"][0].read_text().splitlines()
    assert first[0] == "seq,t_us,adc_0,steps_0" and max(int(r.split(",")[3]) for r in first[1:]) == 39
