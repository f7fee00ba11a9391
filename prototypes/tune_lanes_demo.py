"""PROTOTYPE: ``tune``'s one-tendon verification runs with their plants in lanes.

One scenario group (one condition of the Table I grid, every candidate design saved in
``data/tuning/designs/``), each run as ``tune``'s ``verify`` runs it (``Rig.run_pulse``, 10 s, 500 Hz, a noise
seed per run), each in its own in-process world:

1. alone, one after the other (each world's plant an ``ArmPlant``: today's code path);
2. together, in lockstep (``helpers.virtual.emulator.lockstep``: every world's plant one lane of an
   ``ArmLanes``, one kernel call per round);

then every recording of 2 is compared with its twin of 1 (csv bytes; json without ``started_utc``), and the
CPU time (``time.process_time``) of both is printed with the load. ``--chain`` also shows why today's
``tune`` (every run in one world, one after the other) cannot be laned as it is: the second run of a chained
world against the same run alone.

Run: ``PYTHONPATH=$PWD python prototypes/tune_lanes_demo.py [--condition v200_x20] [--lanes 8]``. Writes only
into a temporary folder.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

from helpers.base.paths import repo_path
from helpers.research.design import load_design
from helpers.rig import Rig
from helpers.rigfile import default_rig
from helpers.virtual.emulator.lockstep import Lockstep
from helpers.virtual.emulator.world import build_world, forget_world, register_world

T_END_S, RATE_HZ, SEED = 10.0, 500, 1000  # tune's verification runs (helpers.research.tune)


def jobs(condition: str, lanes: int) -> list[tuple[str, float, float, object, int, int]]:
    """(system, v, x, design, repetition, seed) of the group: every candidate, repeated to fill ``lanes``."""
    v, x = (float(p[1:].replace("p", ".")) for p in condition.split("_"))
    files = sorted(Path(repo_path("data/tuning/designs")).glob(f"*_{condition}.json"))
    designs = [(f.name.removesuffix(f"_{condition}.json"), load_design(f)) for f in files]
    out = []
    for i in range(lanes):
        system, d = designs[i % len(designs)]
        out.append((system, v, x, d, 1 + i // len(designs), SEED + i))
    return out


class Timed:
    """A world's plant, its ``advance`` calls' CPU time summed in ``Timed.cpu_s`` (the plants' share)."""

    cpu_s = 0.0

    def __init__(self, plant) -> None:
        self.plant = plant

    def __getattr__(self, name):
        return getattr(self.plant, name)

    def advance(self, *args):
        """The plant's ``advance``, timed."""
        c0 = time.process_time()
        out = self.plant.advance(*args)
        Timed.cpu_s += time.process_time() - c0
        return out


def session(k: int, job, folder: Path, plant=None, world_name: str | None = None, runs: int = 1,
            ends: tuple[float, ...] | None = None):  # fmt: skip
    """Job ``k`` recorded in its own world (``plant``: that world's plant instead of its ``ArmPlant``).

    ``runs`` > 1: the job again in the same world (a chain, as today's ``tune`` runs every job), run ``i``
    ``ends[i]`` s long (a short one leaves the arm ringing: the next run waits longer for rest).
    """
    rig = default_rig()
    name = world_name or f"lanes{k}"
    world = build_world(rig, name)
    world.plant = Timed(world.plant) if plant is None else plant
    register_world(world)
    system, v, x, d, rep, seed = job
    recs = []
    try:
        with Rig("virtual", rig, world=name) as r:
            for i in range(runs):
                recs.append(
                    r.run_pulse(
                        v,
                        x,
                        d,
                        system=system,
                        path=folder / f"{system}_r{rep}_{k}_{i}",
                        repetition=rep,
                        t_end_s=T_END_S if ends is None else ends[i],
                        rate_hz=RATE_HZ,
                        progress=False,
                        noise_seed=seed,
                    )
                )
    finally:
        forget_world(name, rig)
    return recs


def same(a: Path, b: Path) -> tuple[bool, bool, list[str]]:
    """(csv bytes equal, json equal but for started_utc, the json keys that differ)."""
    csv = a.with_suffix(".csv").read_bytes() == b.with_suffix(".csv").read_bytes()
    ja, jb = (json.loads(p.with_suffix(".json").read_text()) for p in (a, b))
    for j in (ja, jb):
        j.pop("started_utc", None)
    diff = sorted(k for k in set(ja) | set(jb) if ja.get(k) != jb.get(k))
    return csv, not diff, diff


def main() -> None:
    """Run the group alone and in lanes, compare the recordings, print the CPU times."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--condition", default="v200_x20")
    ap.add_argument("--lanes", type=int, default=8)
    ap.add_argument("--chain", action="store_true")
    ap.add_argument(
        "--ringing", action="store_true",
        help="each session two runs in its world, the first cut short after the down move (8.6-8.95 s): the "
        "second waits for rest, for as long as its own measured tension says",
    )  # fmt: skip
    args = ap.parse_args()
    group = jobs(args.condition, args.lanes)
    with tempfile.TemporaryDirectory() as tmp:
        alone, lanes = Path(tmp, "alone"), Path(tmp, "lanes")
        session(0, group[0], Path(tmp, "warm"))  # compiles the scalar kernel (not timed)
        warm = [build_world(default_rig(), "w").plant.params] * len(group)
        Lockstep(warm).lanes.advance_all([1e-3], [()] * len(group), [()] * len(group))  # compiles this width
        Timed.cpu_s = 0.0
        c0 = time.process_time()
        chain = {"runs": 2, "ends": None} if args.ringing else {}

        def ends(k: int) -> dict:
            return {**chain, "ends": (8.6 + 0.05 * k, T_END_S)} if chain else {}

        recs_alone = [r for k, job in enumerate(group) for r in session(k, job, alone, **ends(k))]
        cpu_alone, plant_alone = time.process_time() - c0, Timed.cpu_s
        load_a = os.getloadavg()
        params = [build_world(default_rig(), "w").plant.params for _ in group]
        ls = Lockstep(params)
        c0 = time.process_time()
        out = ls.run(
            [
                lambda k=k, job=job: session(k, job, lanes, ls.plant(k), **ends(k))
                for k, job in enumerate(group)
            ]
        )
        cpu_lanes = time.process_time() - c0
        load_l = os.getloadavg()
        recs_lanes = [r for o in out for r in o]
        ok = True
        for a, b in zip(recs_alone, recs_lanes, strict=True):
            system = Path(a.path).name
            csv, js, diff = same(Path(a.path), Path(b.path))
            ok &= csv and js
            print(
                f"{system:14s} {len(a.frame)} samples, rest waited "
                f"{a.meta['scenario']['rest']['waited_s']} s:"
                f" csv {'identical' if csv else 'DIFFERS'}, json {'identical' if js else f'DIFFERS {diff}'}"
            )
        print(f"{len(recs_alone)} runs of {args.condition}: all byte-identical: {ok}")
        print(
            f"plants' CPU: alone {plant_alone:.3f} s, in lanes {ls.serve_cpu_s:.3f} s: ratio "
            f"{plant_alone / ls.serve_cpu_s:.2f}x; the rest (boards, lines, host, saving, threads): "
            f"{cpu_alone - plant_alone:.2f} s alone, {cpu_lanes - ls.serve_cpu_s:.2f} s in lanes"
        )
        print(
            f"CPU alone {cpu_alone:.2f} s, in lanes {cpu_lanes:.2f} s: ratio {cpu_alone / cpu_lanes:.2f}x "
            f"(width {ls.lanes.width}, {ls.rounds} rounds, {ls.kernel_calls} kernel calls); load "
            f"{' '.join(f'{x:.2f}' for x in load_a)} / {' '.join(f'{x:.2f}' for x in load_l)}"
        )
        if args.chain:
            # the same job three times in one world (as tune runs every job) against once alone (world lanes0)
            chained = session(0, group[0], Path(tmp, "chain"), world_name="lanes0", runs=3)
            first = recs_alone[0].frame
            for i, rec in enumerate(chained):
                csv, js, diff = same(Path(rec.path), Path(recs_alone[0].path))
                n = min(len(first), len(rec.frame))
                adc = (first["adc_0"].to_numpy()[:n] != rec.frame["adc_0"].to_numpy()[:n]).sum()
                steps = bool((first["steps_0"].to_numpy()[:n] == rec.frame["steps_0"].to_numpy()[:n]).all())
                offset = int(rec.frame["t_us"].iloc[0] - first["t_us"].iloc[0])
                print(
                    f"run {i + 1} of a chain against alone: csv {'identical' if csv else 'DIFFERS'}, json "
                    f"differs in {diff}; device clock {offset} us later, {adc} of {n} ADC samples differ; "
                    f"steps equal: {steps}"
                )


if __name__ == "__main__":
    main()
