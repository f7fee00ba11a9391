"""Speed of the spatial twin's plant: simulated seconds per wall-clock second, on one core.

Two scenarios, each 12 s sampled at 1 kHz, best of ``repeats`` runs (the first call also pays the JIT cache
load, timed separately):

- **four tendons**: the four-tendon extension of the paper's rig (horizontal, every tendon at its
  pretension at rest), a 20 mm bend towards 45 degrees at 200 mm/s (tendons 1 and 2 pulled by 14.1 mm each
  in 0.1 s, tendons 3 and 4 paying out what the statics says keeps them at their pretension, each on its own
  step programme), up at 1 s, down at 8 s; the integrator's step is the rig's stable step
  (:func:`helpers.virtual.spatial.statics.stable_max_step`: the tip disc rocking against two taut
  antagonistic pairs at 13.4 krad/s sets it), and the run is compared with one at half that step;
- **one tendon**: the paper's rig through the spatial twin on the planar benchmark's scenario (200 mm/s,
  20 mm, unshaped) at the planar rig's 0.25 ms, with the planar plant timed in the same call.
"""

from __future__ import annotations

import time

import numpy as np

from helpers.board.programmes import experiment_programme
from helpers.virtual import ArmPlant, RigParameters
from helpers.virtual.spatial.direction_map import bend_equilibrium
from helpers.virtual.spatial.plant import SpatialPlant
from helpers.virtual.spatial.rig import SpatialRig, four_tendon_rig, paper_rig
from helpers.virtual.spatial.simulate import merge_programmes
from helpers.virtual.spatial.statics import stable_max_step

__all__ = ["bend_programmes", "run_spatial_benchmark"]


def bend_programmes(rig: SpatialRig, direction_deg: float, bend_mm: float, v_mm_s: float) -> list:
    """Every tendon's up-hold-down programme for a bend: the paper's pulse timing, one time window.

    The bend's static spool displacements (:func:`~helpers.virtual.spatial.direction_map.bend_equilibrium`)
    each become a pulse (:func:`helpers.board.programmes.experiment_programme`) at the speed that makes it
    last
    ``bend_mm / v_mm_s``; a paying-out tendon runs the mirror image. A tendon that moves by less than a step
    gets no programme.
    """
    u = bend_equilibrium(rig, direction_deg, bend_mm).u * 1e3
    progs = []
    for i, ui in enumerate(u):
        n = round(abs(ui) / (rig.cable_per_step(i) * 1e3))
        if n == 0:
            progs.append(None)
            continue
        prog, _ = experiment_programme(v_mm_s * abs(ui) / bend_mm, abs(ui))
        t, s = prog.step_times()
        progs.append((t, s * np.sign(ui)))
    return progs


def _time_run(plant: SpatialPlant, t: np.ndarray, steps: tuple, repeats: int) -> tuple[float, dict]:
    best = np.inf
    out = {}
    for _ in range(repeats):
        plant.reset()
        t0 = time.perf_counter()
        out = plant.advance(t, *steps)
        best = min(best, time.perf_counter() - t0)
    return best, out


def run_spatial_benchmark(repeats: int = 3, quiet: bool = False) -> dict:
    """Measure and print the spatial plant's speed (see the module docstring).

    Returns
    -------
    dict
        ``four_x_realtime``, ``four_wall_s``, ``four_max_step_s``, ``four_rk4_steps``, ``four_transitions``,
        ``four_half_step_diff_n`` (largest tension difference against half the step), ``one_x_realtime``,
        ``one_wall_s``, ``planar_x_realtime``, ``one_planar_diff_n``, ``jit_first_call_s``.
    """
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats!r}")
    t = np.arange(1, 12001) * 1e-3
    rig4 = four_tendon_rig()
    h4 = stable_max_step(rig4)
    times, tendons, signs, _ = merge_programmes(bend_programmes(rig4, 45.0, 20.0, 200.0), 4)
    steps4 = (times, tendons, signs)
    t0 = time.perf_counter()
    SpatialPlant(rig4, max_step=h4).advance(t[:5], *(a[times <= t[4]] for a in steps4))
    jit_s = time.perf_counter() - t0
    plant4 = SpatialPlant(rig4, max_step=h4)
    wall4, out4 = _time_run(plant4, t, steps4, repeats)
    half = SpatialPlant(rig4, max_step=h4 / 2).advance(t, *steps4)
    diff4 = float(np.max(np.abs(half["output"] - out4["output"])))

    prog, _ = experiment_programme(200.0, 20.0)
    st, sg = prog.step_times()
    sel = st <= t[-1]
    rig1 = paper_rig()
    plant1 = SpatialPlant(rig1)
    steps1 = (st[sel], np.zeros(int(sel.sum()), dtype=np.int64), sg[sel])
    wall1, out1 = _time_run(plant1, t, steps1, repeats)
    planar = ArmPlant(RigParameters())
    wallp = np.inf
    for _ in range(repeats):
        planar.reset()
        t0 = time.perf_counter()
        tension = planar.advance(t, st[sel], sg[sel])
        wallp = min(wallp, time.perf_counter() - t0)
    out = {
        "four_x_realtime": float(t[-1] / wall4),
        "four_wall_s": float(wall4),
        "four_max_step_s": float(h4),
        "four_rk4_steps": int(plant4.integrator_steps),
        "four_transitions": int(plant4.transitions),
        "four_half_step_diff_n": diff4,
        "one_x_realtime": float(t[-1] / wall1),
        "one_wall_s": float(wall1),
        "planar_x_realtime": float(t[-1] / wallp),
        "one_planar_diff_n": float(np.max(np.abs(out1["output"][:, 0] - tension))),
        "jit_first_call_s": float(jit_s),
    }
    if not quiet:
        print(
            f"spatial twin, four tendons (horizontal, 20 mm bend towards 45 deg at 200 mm/s, 12 s at 1 kHz, "
            f"RK4 at {h4 * 1e3:.4f} ms, one core): {wall4:.2f} s -> {out['four_x_realtime']:.1f} x real time "
            f"({out['four_rk4_steps']} RK4 steps, {out['four_transitions']} taut/slack transitions; "
            f"goal >= 25x)"
        )
        print(f"  against half the step: largest tension difference {diff4:.4f} N")
        print(
            f"spatial twin, one tendon (200 mm/s, 20 mm, RK4 at {rig1.arm.max_step * 1e3:.2f} ms): "
            f"{wall1:.2f} s -> {out['one_x_realtime']:.1f} x real time; the planar plant on the same run: "
            f"{wallp:.2f} s -> {out['planar_x_realtime']:.1f} x (ratio {wall1 / wallp:.2f}); "
            f"largest difference {out['one_planar_diff_n']:.1e} N"
        )
        print(f"  first call (JIT cache load or compile): {jit_s:.2f} s")
    return out


if __name__ == "__main__":  # pragma: no cover
    run_spatial_benchmark()
