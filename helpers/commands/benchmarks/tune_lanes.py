"""Speed of ``tune``'s verification runs in lanes: runs per CPU second alone and in lockstep, in one call.

One condition of the Table I grid (200 mm/s, 20 mm by default): every candidate design ``tune`` saved for it
in ``data/tuning/designs/``, :data:`~helpers.research.tune.REPETITIONS` runs each, as ``tune`` verifies them
(:func:`helpers.research.tune.verify`: 10 s at 500 Hz on the in-process virtual rig of one tendon, noise seed
1000 + k, the shipped calibration). Three ways, taking turns ``repeats`` times (the best of each is reported),
so that a change in the machine's load hits all alike:

- **alone** (``verify(lanes=1)``): each run in a fresh world of its own, its plant an ``ArmPlant``, one after
  the other;
- **in lanes** (``verify(lanes=N)``): the same runs, N worlds at a time in lockstep
  (:mod:`helpers.virtual.emulator.lockstep`: their plants in the lanes of one kernel call per round);
- **the chain** (``verify(lanes=0)``, the default, which made ``data/tuning``): every run in one world, each
  starting where the one before left the arm and the device clock; for reference only, its recordings are
  not those of the other two.

CPU time is the process's (``time.process_time``): the boards, the lines, the host, the saving and each
move's residuals as well as the plants. Every recording made in lanes is compared with the same run alone:
csv bytes, and the json but its ``started_utc``.

``tune-tendons-lanes`` does the same for ``tune`` on ``four-tendon``
(:func:`helpers.research.tune_tendons.verify`: every design of ``SYSTEMS`` at one bend, 20 mm towards 45
degrees, 3 runs each, at the pretension and from the map of the shipped ``data/tuning/tendons/four-tendon``;
8 s moves at 1 kHz, four channels), its plants ``SpatialPlant`` alone and ``SpatialLanes`` in lanes.
"""

from __future__ import annotations

import itertools
import json
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from helpers import rigfile
from helpers.base.paths import DATA_DIR
from helpers.paper.tension import load_calibration
from helpers.research import design, tune
from helpers.research import tune_tendons as tt
from helpers.rig import Rig
from helpers.rigfile import default_rig
from helpers.virtual.emulator.world import forget_world
from helpers.virtual.spatial.plant import SpatialLanes
from helpers.virtual.spatial.rig import four_tendon_rig

__all__ = ["run_tune_lanes_benchmark", "run_tune_tendons_lanes_benchmark"]

WORLD = "bench-tune-lanes"
"""The benchmark's world (the chain's; the runs alone and in lanes get ``<WORLD>.<run>``)."""
SEED = 1000
"""Noise seed of the first run (``tune``'s default)."""


def _load() -> str:
    try:
        return "load average " + ", ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:  # pragma: no cover - not on every platform
        return "load average unavailable"


def _say(lanes: int, repeats: int, quiet: bool) -> Callable[..., None]:
    """What prints the lines (nothing if ``quiet``), once ``lanes`` and ``repeats`` are checked."""
    if not 2 <= lanes <= 8:
        raise ValueError(f"lanes must be 2 to 8, got {lanes!r}")
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats!r}")
    return (lambda *a: None) if quiet else print


def _candidates(v: float, x: float) -> tune.Candidates:
    """Every design ``tune`` saved in ``data/tuning/designs/`` for the condition, in ``CANDIDATES`` order."""
    name = tune.condition_name(v, x)
    folder = DATA_DIR / "tuning" / "designs"
    made = {s: design.load_design(folder / f"{s}_{name}.json") for s in tune.CANDIDATES
            if (folder / f"{s}_{name}.json").is_file()}  # fmt: skip
    if not made:
        raise FileNotFoundError(f"no design for {name} in {folder}: run `python -m helpers tune` first")
    return tune.Candidates({(v, x): made}, {(v, x): {}})


def _verify(folder: Path, lanes: int, candidates: tune.Candidates, repetitions: int) -> float:
    """CPU time (s) of ``tune.verify`` of ``candidates`` with ``lanes``, recordings in ``folder``."""
    rig = default_rig()
    calibration = load_calibration(DATA_DIR / "calibration" / "calibration.json")
    seeds = itertools.count(SEED)
    forget_world(WORLD, rig)
    try:
        with Rig("virtual", rig, calibration=calibration, world=WORLD) as r:
            c0 = time.process_time()
            tune.verify(r, candidates, folder, repetitions, seeds=lambda: next(seeds), progress=False,
                        lanes=lanes)  # fmt: skip
            return time.process_time() - c0
    finally:
        forget_world(WORLD, rig)


def _same(a: Path, b: Path) -> bool:
    """Recording ``a`` is ``b``: csv bytes, json but ``started_utc``."""
    if a.with_suffix(".csv").read_bytes() != b.with_suffix(".csv").read_bytes():
        return False
    ja, jb = (json.loads(p.with_suffix(".json").read_text()) for p in (a, b))
    ja.pop("started_utc", None)
    jb.pop("started_utc", None)
    return ja == jb


def _take_turns(
    tmp: str, ways: dict[str, int], repeats: int, verify: Callable[[Path, int], float]
) -> tuple[dict[str, float], int, int]:
    """The ways (name: lanes) in turns ``repeats`` times: the best CPU time of each, recordings compared.

    ``verify(folder, lanes)`` makes one way's recordings in ``folder`` and returns its CPU time (s).

    Returns
    -------
    tuple
        ``(best, identical, compared)``: the best CPU time (s) of each way; the recordings in lanes equal to
        the same run alone, of those compared.
    """
    best = dict.fromkeys(ways, float("inf"))
    identical = compared = 0
    for turn in range(repeats):
        for way, n in ways.items():
            best[way] = min(best[way], verify(Path(tmp, f"{way}{turn}"), n))
        for path in sorted(Path(tmp, f"alone{turn}").glob("*.csv")):
            compared += 1
            identical += _same(path, Path(tmp, f"lanes{turn}", path.name))
    return best, identical, compared


def _report(
    say: Callable[..., None], runs: int, lanes: int, turns: tuple[dict[str, float], int, int], before: str,
    words: tuple[str, str, str], digits: tuple[int, int],
) -> dict[str, Any]:
    """Print the turns' figures (:func:`_take_turns`) and return them (as :func:`run_tune_lanes_benchmark`).

    ``words``: what one run is, what the lanes share a kernel call of, where the chain's recordings are;
    ``digits``: of the rates and of the CPU times.
    """
    best, identical, compared = turns
    item, plants, made = words
    dr, ds = digits
    after = _load()
    rate = {way: runs / cpu for way, cpu in best.items()}
    ratio = rate["lanes"] / rate["alone"]
    say(f"  alone (each {item} in a world of its own, one at a time): {rate['alone']:.{dr}f} runs per CPU "
        f"second ({best['alone']:.{ds}f} s)")
    say(f"  in lanes ({lanes} worlds in lockstep, their {plants} in one kernel call): {rate['lanes']:.{dr}f} "
        f"runs per CPU second ({best['lanes']:.{ds}f} s)")
    say(f"  the chain (every {item} in one world, as {made} was made; other recordings): "
        f"{rate['chain']:.{dr}f} runs per CPU second ({best['chain']:.{ds}f} s)")
    say(f"  recordings in lanes byte-identical to the same run alone (csv bytes; json but started_utc): "
        f"{identical} of {compared}")
    say(f"  after: {after}")
    say(f"runs per CPU second in lanes / alone: {ratio:.2f}x (lanes / the chain: "
        f"{rate['lanes'] / rate['chain']:.2f}x)")
    return {"runs": runs, "lanes": lanes, "runs_per_cpu_s": rate, "ratio": ratio, "identical": identical,
            "compared": compared, "load": (before, after)}  # fmt: skip


def run_tune_lanes_benchmark(
    lanes: int = 8, v: float = 200.0, x: float = 20.0, repeats: int = 2, quiet: bool = False
) -> dict[str, Any]:
    """Measure and print the figures of the module docstring; the last line names the ratio.

    Parameters
    ----------
    lanes : int
        Runs in lockstep (2 to 8).
    v, x : float
        The condition (mm/s, mm), one of the Table I grid's.
    repeats : int
        Turns of the three ways (the best of each is reported).
    quiet : bool
        Do not print.

    Returns
    -------
    dict
        ``runs``, ``lanes``, ``runs_per_cpu_s`` (``"alone"``, ``"lanes"``, ``"chain"``), ``ratio`` (lanes /
        alone), ``identical`` and ``compared`` (recordings in lanes equal to the same run alone), ``load``
        (before, after).
    """
    say = _say(lanes, repeats, quiet)
    candidates = _candidates(v, x)
    systems = list(candidates.designs[(v, x)])
    repetitions = tune.REPETITIONS["table-i"]
    runs = len(systems) * repetitions
    before = _load()
    say(f"tune's verification runs, one Table I condition ({v:g} mm/s, {x:g} mm): {len(systems)} designs x "
        f"{repetitions} = {runs} runs of {tune.T_END_S:g} s at {tune.RATE_HZ} Hz, in-process virtual rig; "
        f"{os.cpu_count()} cores; {before}")  # fmt: skip
    ways = {"alone": 1, "lanes": lanes, "chain": 0}
    with tempfile.TemporaryDirectory() as tmp:
        warm = tune.Candidates({(v, x): {systems[0]: candidates.designs[(v, x)][systems[0]]}}, {(v, x): {}})
        for way, n in ways.items():  # every kernel (scalar, this lane width) compiled or loaded, not timed
            _verify(Path(tmp, f"warm-{way}"), n, warm, max(n, 1))
        turns = _take_turns(tmp, ways, repeats, lambda f, n: _verify(f, n, candidates, repetitions))
    return _report(say, runs, lanes, turns, before, ("run", "plants", "data/tuning"), (2, 2))


def _verify_tendons(
    folder: Path, lanes: int, doc: dict[str, Any], systems: tuple[str, ...], reps: int = 3
) -> float:
    """CPU time (s) of ``tune_tendons.verify`` of ``systems`` at 20 mm towards 45 deg with ``lanes``."""
    rig = rigfile.load(rigfile.resolve("four-tendon"))
    points = [tt.MapPoint(**{k: tuple(map(tuple, v)) if k == "predicted_higher" else
                             tuple(v) if k == "predicted_split" else v for k, v in p.items()})
              for p in doc["map"]]  # fmt: skip
    seeds = itertools.count(SEED)
    forget_world(WORLD, rig)
    try:
        with Rig("virtual", rig, world=WORLD) as r:
            c0 = time.process_time()
            tt.verify(r, points, folder, reps, (45.0,), (20.0,), systems, prepull=int(doc["prepull_steps"]),
                      seeds=lambda: next(seeds), reseed=r.world.reseed, lanes=lanes)  # fmt: skip
            return time.process_time() - c0
    finally:
        forget_world(WORLD, rig)


def run_tune_tendons_lanes_benchmark(lanes: int = 8, repeats: int = 1, quiet: bool = False) -> dict[str, Any]:
    """The four-tendon ``tune``'s verification runs alone, in lanes and chained (module docstring).

    Returns
    -------
    dict
        As :func:`run_tune_lanes_benchmark`'s.
    """
    say = _say(lanes, repeats, quiet)
    doc = json.loads((DATA_DIR / "tuning" / "tendons" / "four-tendon" / "verification.json").read_text())
    systems = tuple(tt.SYSTEMS)
    runs = len(systems) * 3
    before = _load()
    say(f"tune's verification runs on four-tendon, one bend (20 mm towards 45 deg): {len(systems)} designs "
        f"x 3 = {runs} moves of {tt.MOVE_TIMES_S[-1]:g} s at 1 kHz (four channels), in-process virtual rig; "
        f"{os.cpu_count()} cores; {before}")  # fmt: skip
    ways = {"alone": 1, "lanes": lanes, "chain": 0}
    with tempfile.TemporaryDirectory() as tmp:
        # every kernel (scalar, this lane width) compiled or loaded, the rig's statics made, not timed
        _verify_tendons(Path(tmp, "warm"), 0, doc, ("unshaped",), 1)
        SpatialLanes([four_tendon_rig()] * lanes).advance_all([1e-3], *([[]] * lanes,) * 3)
        turns = _take_turns(tmp, ways, repeats, lambda f, n: _verify_tendons(f, n, doc, systems))
    return _report(say, runs, lanes, turns, before, ("move", "twins", "data/"), (3, 1))


if __name__ == "__main__":  # pragma: no cover
    run_tune_lanes_benchmark()
