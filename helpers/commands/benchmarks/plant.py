"""Speed of the virtual rig's plant: the implicit step against the RK4 reference, and against solve_ivp.

Scenario: the tuned rig (12-disc arc chain, stepper, load-cell carriage, amplifier) running the Table I
condition 200 mm/s, 20 mm, unshaped, for the full 12 s programme, sampled at 1 kHz, on one core. In one call:

- the **RK4 reference** (0.25 ms) and the **implicit step** (``integrator="rosw"``, the elastic stiffness
  implicit, at its own step: the default, which made the stored data): real-time factors in CPU time
  (``time.process_time``, best of ``repeats``), their ratio, and the largest difference of every signal the
  plant records (amplifier output, true tension, every node angle, the tip's position);
- the straightforward numpy + ``solve_ivp`` implementation of the same equations
  (``helpers.virtual.reference``) on a window of the same scenario (by default 0.95-1.25 s: the up move and
  its first swing; the full 12 s would take over ten minutes), from the RK4 run's state at the window's
  start, and the two compared there.
"""

from __future__ import annotations

import os
import time

import numpy as np

from helpers.board.programmes import experiment_programme
from helpers.virtual import ArmPlant, RigParameters
from helpers.virtual.reference import ReferenceArm
from helpers.virtual.statics import node_positions

__all__ = ["run_plant_benchmark"]


def run_plant_benchmark(
    reference_window_s: tuple[float, float] = (0.95, 1.25),
    repeats: int = 3,
    rtol: float = 1e-6,
    atol: float = 1e-9,
    quiet: bool = False,
) -> dict:
    """Measure and print the plant's speed.

    Parameters
    ----------
    reference_window_s : (float, float)
        Start and end (s) of the part of the scenario given to the solve_ivp implementation.
    repeats : int
        Repeats of the compiled run (the best is reported; the first call also pays the JIT cache load).
    rtol, atol : float
        Tolerances of the solve_ivp reference.
    quiet : bool
        Do not print.

    Returns
    -------
    dict
        ``compiled_x_realtime`` (RK4, CPU time), ``implicit_x_realtime``, ``implicit_over_rk4``,
        ``implicit_max_step_s``, ``implicit_steps``, ``implicit_max_diff`` (per signal),
        ``reference_x_realtime`` (solve_ivp), ``ratio`` (RK4 / solve_ivp), ``compiled_wall_s`` (the RK4
        run's CPU seconds), ``reference_wall_s``, ``reference_span_s`` (simulated seconds), ``max_step_s``,
        ``rk4_steps``, ``max_abs_diff_n`` (compiled vs reference on the window), ``jit_first_call_s``.
    """
    w0, w1 = (float(w) for w in reference_window_s)
    if not (0 <= w0 < w1 <= 12.0):
        raise ValueError(f"reference_window_s must satisfy 0 <= start < end <= 12, got {reference_window_s}")
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats!r}")
    params = RigParameters().with_integrator("rk4")
    prog, _ = experiment_programme(200.0, 20.0)
    st, sg = prog.step_times()
    t = np.arange(1, int(round(prog.duration_s * 1000)) + 1) * 1e-3
    t = t[t <= prog.duration_s]

    t0 = time.perf_counter()
    ArmPlant(params).advance(t[:10], st[st <= t[9]], sg[st <= t[9]])
    jit_s = time.perf_counter() - t0
    implicit = params.with_integrator("rosw")
    ArmPlant(implicit).advance(t[:10], st[st <= t[9]], sg[st <= t[9]])

    runs = {}
    for name, p in (("rk4", params.with_integrator("rk4")), ("rosw", implicit)):
        plant = ArmPlant(p)
        best = np.inf
        for _ in range(repeats):
            plant.reset()
            c0 = time.process_time()
            out, raw, angles = plant.advance_all(t, st, sg)
            best = min(best, time.process_time() - c0)
        runs[name] = (best, out, raw, angles, plant.integrator_steps, plant.transitions)
    best, tension = runs["rk4"][0], runs["rk4"][1]
    compiled_rate = t[-1] / best
    implicit_rate = t[-1] / runs["rosw"][0]
    tips = {k: np.stack(node_positions(params, v[3]), axis=-1)[:, -1] for k, v in runs.items()}
    diffs = {
        "output_n": float(np.max(np.abs(runs["rosw"][1] - runs["rk4"][1]))),
        "tension_n": float(np.max(np.abs(runs["rosw"][2] - runs["rk4"][2]))),
        "angles_rad": float(np.max(np.abs(runs["rosw"][3] - runs["rk4"][3]))),
        "tip_mm": 1e3 * float(np.max(np.linalg.norm(tips["rosw"] - tips["rk4"], axis=1))),
    }

    # the reference starts from the compiled run's state (and amplifier output) at the window's start
    start = ArmPlant(params)
    before = t < w0
    if np.any(before):
        start.advance(t[before], st[st <= t[before][-1]], sg[st <= t[before][-1]])
    sel_t = (t >= w0) & (t <= w1)
    sel_s = (st > start.t) & (st <= t[sel_t][-1])
    y0 = np.concatenate([start.state, [start.amplifier_output()]])
    c0 = time.process_time()
    ref = ReferenceArm(params).run(
        t[sel_t], st[sel_s], sg[sel_s], rtol=rtol, atol=atol, method="RK45",
        y0=y0, steps0=start.position_steps, t0=start.t,
    )  # fmt: skip
    ref_wall = time.process_time() - c0  # CPU time, as the compiled runs
    span = float(t[sel_t][-1] - start.t)
    ref_rate = span / ref_wall
    diff = float(np.max(np.abs(ref - tension[sel_t])))
    out = {
        "compiled_x_realtime": float(compiled_rate),
        "implicit_x_realtime": float(implicit_rate),
        "implicit_over_rk4": float(implicit_rate / compiled_rate),
        "implicit_max_step_s": float(implicit.max_step),
        "implicit_steps": int(runs["rosw"][4]),
        "implicit_max_diff": diffs,
        "reference_x_realtime": float(ref_rate),
        "ratio": float(compiled_rate / ref_rate),
        "compiled_wall_s": float(best),
        "reference_wall_s": float(ref_wall),
        "reference_span_s": span,
        "max_step_s": float(params.max_step),
        "rk4_steps": int(runs["rk4"][4]),
        "max_abs_diff_n": diff,
        "jit_first_call_s": float(jit_s),
    }
    if not quiet:
        load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
        print(f"Virtual rig plant, tuned rig ({params.n_elements} arc elements, actuator {params.actuator}), "
              f"200 mm/s 20 mm unshaped, 1 kHz samples, one core, CPU time (best of {repeats}); "
              f"load average {load}")
        print(f"  RK4 reference, h <= {params.max_step * 1e3:.2f} ms: {t[-1]:.1f} s simulated in "
              f"{best:.3f} s of CPU -> {compiled_rate:.1f} x real time ({runs['rk4'][4]} steps, "
              f"{runs['rk4'][5]} taut/slack transitions)")
        print(f"  implicit step (rosw: bending and cables implicit), h <= {implicit.max_step * 1e3:.2f} ms: "
              f"{runs['rosw'][0]:.3f} s of CPU -> {implicit_rate:.1f} x real time ({runs['rosw'][4]} steps, "
              f"{runs['rosw'][5]} transitions); ratio implicit / RK4: {implicit_rate / compiled_rate:.2f}x "
              "(goal >= 100x real time)")
        print(f"  largest difference implicit - RK4: amplifier output {diffs['output_n']:.4f} N, tension "
              f"{diffs['tension_n']:.4f} N, node angles {diffs['angles_rad']:.2e} rad, tip "
              f"{diffs['tip_mm']:.3f} mm (convergence band: docs/virtual_rig.md, section 2)")
        print(f"  solve_ivp RK45 (numpy), rtol {rtol:.0e}: {start.t:.2f}-{t[sel_t][-1]:.2f} s ({span:.2f} s) "
              f"in {ref_wall:.2f} s of CPU -> {ref_rate:.3f} x real time")
        print(f"  ratio compiled RK4 / solve_ivp: {compiled_rate / ref_rate:.0f}")
        print(f"  max |compiled RK4 - solve_ivp| amplifier output on that window: {diff:.4f} N")
        print(f"  first call (JIT cache load or compile): {jit_s:.2f} s")
    return out


if __name__ == "__main__":  # pragma: no cover
    run_plant_benchmark()
