"""Speed of the spatial twin's plant: the implicit step against the RK4 reference, CPU time of one core.

Two scenarios, each 12 s sampled at 1 kHz, best of ``repeats`` runs in CPU time (``time.process_time``; the
first call also pays the JIT cache load, timed separately):

- **four tendons**: the four-tendon extension of the paper's rig (horizontal, every tendon at its
  pretension at rest), a 20 mm bend towards 45 degrees at 200 mm/s (tendons 1 and 2 pulled by 14.1 mm each
  in 0.1 s, tendons 3 and 4 paying out what the statics says keeps them at their pretension, each on its own
  step programme), up at 1 s, down at 8 s. The RK4 reference runs at the rig's stable step
  (:func:`helpers.virtual.spatial.statics.stable_max_step`: the tip disc rocking against two taut
  antagonistic pairs at 13.5 krad/s sets it, 1/6 ms), the implicit step (``integrator="rosw"``: the rod's
  and the tendons' stiffness implicit) at its own step; their real-time factors, ratio and the largest
  difference of every recorded signal (each amplifier's output, each tension, the coordinates, the tip);
- **one tendon**: the paper's rig through the spatial twin on the planar benchmark's scenario (200 mm/s,
  20 mm, unshaped), RK4 at the planar rig's 0.25 ms, with the planar plant timed in the same call;
- **four tendons in lanes**: eight runs of the first scenario's kind, 20 mm bends towards 0, 45, ..., 315
  degrees (each its own step programmes), with the implicit step: four-tendon runs per CPU second one run
  per kernel call (:class:`~helpers.virtual.spatial.plant.SpatialPlant`) and with 4 and 8 runs in the SIMD
  lanes of one call (:class:`~helpers.virtual.spatial.plant.SpatialLanes`), taking turns so that a change in
  the machine's load hits each alike; every lane is checked bit for bit against its run alone.
"""

from __future__ import annotations

import dataclasses
import os
import time

import numpy as np

from helpers.board.programmes import experiment_programme
from helpers.virtual import ArmPlant, RigParameters
from helpers.virtual.integrators import bend_programmes
from helpers.virtual.spatial.plant import SpatialLanes, SpatialPlant
from helpers.virtual.spatial.rig import SpatialRig, four_tendon_rig, paper_rig
from helpers.virtual.spatial.simulate import merge_programmes
from helpers.virtual.spatial.statics import stable_max_step

__all__ = ["run_spatial_benchmark"]


def _with(rig: SpatialRig, integrator: str) -> SpatialRig:
    return dataclasses.replace(rig, arm=rig.arm.with_integrator(integrator))


def _time_run(plant: SpatialPlant, t: np.ndarray, steps: tuple, repeats: int) -> tuple[float, dict]:
    best = np.inf
    out = {}
    for _ in range(repeats):
        plant.reset()
        c0 = time.process_time()
        out = plant.advance(t, *steps)
        best = min(best, time.process_time() - c0)
    return best, out


def _lanes_rates(t: np.ndarray, repeats: int) -> dict:
    """Four-tendon runs per CPU second alone and with 4 and 8 per kernel call (module docstring)."""
    rig = four_tendon_rig()  # the default integrator (the implicit step)
    progs = []
    for direction in range(0, 360, 45):
        times, tendons, signs, _ = merge_programmes(bend_programmes(rig, float(direction), 20.0, 200.0), 4)
        keep = times <= t[-1]
        progs.append((times[keep], tendons[keep], signs[keep]))
    SpatialPlant(rig).advance(t[:2])  # the kernels compiled or loaded before timing
    for width in (4, 8):
        SpatialLanes([rig] * width).advance_all(t[:2], [[]] * width, [[]] * width, [[]] * width)
    cpu = {1: np.inf, 4: np.inf, 8: np.inf}
    same = True
    for _ in range(repeats):
        c0 = time.process_time()
        alone = [SpatialPlant(rig).advance(t, *p) for p in progs]
        cpu[1] = min(cpu[1], time.process_time() - c0)
        for width in (4, 8):
            c0 = time.process_time()
            outs = []
            for j in range(0, len(progs), width):
                part = progs[j : j + width]
                steps = ([p[i] for p in part] for i in range(3))
                got = SpatialLanes([rig] * len(part)).advance_all(t, *steps)
                outs += [{k: v[m] for k, v in got.items()} for m in range(len(part))]
            cpu[width] = min(cpu[width], time.process_time() - c0)
            same &= all(np.array_equal(o[k], a[k]) for o, a in zip(outs, alone, strict=True) for k in a)
    rates = {w: len(progs) / c for w, c in cpu.items()}
    return {"runs": len(progs), "runs_per_cpu_s": rates, "ratio_4": rates[4] / rates[1],
            "ratio_8": rates[8] / rates[1], "bitwise": bool(same)}  # fmt: skip


def run_spatial_benchmark(repeats: int = 3, quiet: bool = False) -> dict:
    """Measure and print the spatial plant's speed (see the module docstring).

    Returns
    -------
    dict
        ``four_x_realtime`` (RK4), ``four_cpu_s``, ``four_max_step_s``, ``four_rk4_steps``,
        ``four_transitions``, ``four_implicit_x_realtime``, ``four_implicit_over_rk4``,
        ``four_implicit_max_step_s``, ``four_implicit_steps``, ``four_max_diff`` (per signal),
        ``one_x_realtime``, ``one_cpu_s``, ``planar_x_realtime``, ``one_planar_diff_n``,
        ``jit_first_call_s``, ``lanes`` (``runs``, ``runs_per_cpu_s`` per runs per kernel call 1, 4, 8,
        ``ratio_4``, ``ratio_8``, ``bitwise``: every lane its run alone).
    """
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats!r}")
    t = np.arange(1, 12001) * 1e-3
    rig4 = _with(four_tendon_rig(), "rk4")
    h4 = stable_max_step(rig4)
    times, tendons, signs, _ = merge_programmes(bend_programmes(rig4, 45.0, 20.0, 200.0), 4)
    steps4 = (times, tendons, signs)
    first = (a[times <= t[4]] for a in steps4)
    t0 = time.perf_counter()
    SpatialPlant(rig4, max_step=h4).advance(t[:5], *first)
    jit_s = time.perf_counter() - t0
    plant4 = SpatialPlant(rig4, max_step=h4)
    cpu4, out4 = _time_run(plant4, t, steps4, repeats)
    rigw = _with(rig4, "rosw")
    plantw = SpatialPlant(rigw)
    plantw.advance(t[:5], *(a[times <= t[4]] for a in steps4))
    cpuw, outw = _time_run(plantw, t, steps4, repeats)
    diffs = {
        "output_n": float(np.max(np.abs(outw["output"] - out4["output"]))),
        "tension_n": float(np.max(np.abs(outw["tension"] - out4["tension"]))),
        "q_rad": float(np.max(np.abs(outw["q"] - out4["q"]))),
        "tip_mm": 1e3 * float(np.max(np.linalg.norm(outw["tip"] - out4["tip"], axis=1))),
    }

    prog, _ = experiment_programme(200.0, 20.0)
    st, sg = prog.step_times()
    sel = st <= t[-1]
    rig1 = _with(paper_rig(), "rk4")
    plant1 = SpatialPlant(rig1)
    steps1 = (st[sel], np.zeros(int(sel.sum()), dtype=np.int64), sg[sel])
    cpu1, out1 = _time_run(plant1, t, steps1, repeats)
    planar = ArmPlant(RigParameters().with_integrator("rk4"))
    cpup = np.inf
    for _ in range(repeats):
        planar.reset()
        c0 = time.process_time()
        tension = planar.advance(t, st[sel], sg[sel])
        cpup = min(cpup, time.process_time() - c0)
    out = {
        "four_x_realtime": float(t[-1] / cpu4),
        "four_cpu_s": float(cpu4),
        "four_max_step_s": float(h4),
        "four_rk4_steps": int(plant4.integrator_steps),
        "four_transitions": int(plant4.transitions),
        "four_implicit_x_realtime": float(t[-1] / cpuw),
        "four_implicit_over_rk4": float(cpu4 / cpuw),
        "four_implicit_max_step_s": float(plantw.max_step),
        "four_implicit_steps": int(plantw.integrator_steps),
        "four_max_diff": diffs,
        "one_x_realtime": float(t[-1] / cpu1),
        "one_cpu_s": float(cpu1),
        "planar_x_realtime": float(t[-1] / cpup),
        "one_planar_diff_n": float(np.max(np.abs(out1["output"][:, 0] - tension))),
        "jit_first_call_s": float(jit_s),
        "lanes": _lanes_rates(t, max(1, repeats - 1)),
    }
    if not quiet:
        load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
        print(f"spatial twin, four tendons (horizontal, 20 mm bend towards 45 deg at 200 mm/s, 12 s at "
              f"1 kHz, one core, CPU time, best of {repeats}; load average {load}):")
        print(f"  RK4 reference at {h4 * 1e3:.4f} ms: {cpu4:.2f} s -> {out['four_x_realtime']:.1f} x real "
              f"time ({out['four_rk4_steps']} steps, {out['four_transitions']} taut/slack transitions)")
        print(f"  implicit step (rosw) at {plantw.max_step * 1e3:.4f} ms: {cpuw:.2f} s -> "
              f"{out['four_implicit_x_realtime']:.1f} x real time ({plantw.integrator_steps} steps, "
              f"{plantw.transitions} transitions); ratio implicit / RK4: {cpu4 / cpuw:.2f}x (goal >= 25x "
              "real time)")
        print(f"  largest difference implicit - RK4: outputs {diffs['output_n']:.4f} N, tensions "
              f"{diffs['tension_n']:.4f} N, coordinates {diffs['q_rad']:.2e} rad, tip "
              f"{diffs['tip_mm']:.3f} mm")
        print(f"spatial twin, one tendon (200 mm/s, 20 mm, RK4 at {rig1.arm.max_step * 1e3:.2f} ms): "
              f"{cpu1:.2f} s -> {out['one_x_realtime']:.1f} x real time; the planar plant on the same run: "
              f"{cpup:.2f} s -> {out['planar_x_realtime']:.1f} x (ratio {cpu1 / cpup:.2f}); "
              f"largest difference {out['one_planar_diff_n']:.1e} N")
        print(f"  first call (JIT cache load or compile): {jit_s:.2f} s")
        ln = out["lanes"]
        r = ln["runs_per_cpu_s"]
        load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
        print(f"spatial twin, four tendons in lanes ({ln['runs']} bends of 20 mm towards 0, 45, ..., 315 "
              f"deg, 12 s each, the implicit step; runs per CPU second of one core, best of "
              f"{max(1, repeats - 1)}; load average {load}):")
        print(f"  one run per kernel call {r[1]:.3f}, 4 per call {r[4]:.3f} ({ln['ratio_4']:.2f}x), 8 per "
              f"call {r[8]:.3f} ({ln['ratio_8']:.2f}x per core; aim >= 3x); every lane bit for bit its run "
              f"alone: {'yes' if ln['bitwise'] else 'NO'}")
    return out


if __name__ == "__main__":  # pragma: no cover
    run_spatial_benchmark()
