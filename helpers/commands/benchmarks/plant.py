"""Speed of the virtual rig's plant: simulated seconds per wall-clock second, compiled vs solve_ivp.

Scenario: the tuned rig (12-disc arc chain, stepper, load-cell carriage, amplifier) running the Table I
condition 200 mm/s, 20 mm, unshaped, for the full 12 s programme, sampled at 1 kHz, on one core. The compiled
(numba) fixed-step integrator runs the whole 12 s; the straightforward numpy + ``solve_ivp`` implementation
of the same equations (``helpers.virtual.reference``) runs a window of the same scenario (by default
0.95-1.25 s: the up move and its first swing; the full 12 s would take over ten minutes), starting from the
compiled run's state at the window's start. Both figures are rates (simulated s per wall s) measured in the
same run; their amplifier outputs are compared on the window.
"""

from __future__ import annotations

import time

import numpy as np

from helpers.board.programmes import experiment_programme
from helpers.virtual import ArmPlant, RigParameters
from helpers.virtual.reference import ReferenceArm

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
        ``compiled_x_realtime``, ``reference_x_realtime``, ``ratio``, ``compiled_wall_s``,
        ``reference_wall_s``, ``reference_span_s`` (simulated seconds), ``max_step_s``, ``rk4_steps``,
        ``max_abs_diff_n`` (compiled vs reference on the window), ``jit_first_call_s``.
    """
    w0, w1 = (float(w) for w in reference_window_s)
    if not (0 <= w0 < w1 <= 12.0):
        raise ValueError(f"reference_window_s must satisfy 0 <= start < end <= 12, got {reference_window_s}")
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats!r}")
    params = RigParameters()
    prog, _ = experiment_programme(200.0, 20.0)
    st, sg = prog.step_times()
    t = np.arange(1, int(round(prog.duration_s * 1000)) + 1) * 1e-3
    t = t[t <= prog.duration_s]

    t0 = time.perf_counter()
    ArmPlant(params).advance(t[:10], st[st <= t[9]], sg[st <= t[9]])
    jit_s = time.perf_counter() - t0

    best = np.inf
    plant = ArmPlant(params)
    for _ in range(repeats):
        plant.reset()
        t0 = time.perf_counter()
        tension = plant.advance(t, st, sg)
        best = min(best, time.perf_counter() - t0)
    compiled_rate = t[-1] / best

    # the reference starts from the compiled run's state (and amplifier output) at the window's start
    start = ArmPlant(params)
    before = t < w0
    if np.any(before):
        start.advance(t[before], st[st <= t[before][-1]], sg[st <= t[before][-1]])
    sel_t = (t >= w0) & (t <= w1)
    sel_s = (st > start.t) & (st <= t[sel_t][-1])
    y0 = np.concatenate([start.state, [start.amplifier_output()]])
    t0 = time.perf_counter()
    ref = ReferenceArm(params).run(
        t[sel_t], st[sel_s], sg[sel_s], rtol=rtol, atol=atol, method="RK45",
        y0=y0, steps0=start.position_steps, t0=start.t,
    )  # fmt: skip
    ref_wall = time.perf_counter() - t0
    span = float(t[sel_t][-1] - start.t)
    ref_rate = span / ref_wall
    diff = float(np.max(np.abs(ref - tension[sel_t])))
    out = {
        "compiled_x_realtime": float(compiled_rate),
        "reference_x_realtime": float(ref_rate),
        "ratio": float(compiled_rate / ref_rate),
        "compiled_wall_s": float(best),
        "reference_wall_s": float(ref_wall),
        "reference_span_s": span,
        "max_step_s": float(params.max_step),
        "rk4_steps": int(plant.integrator_steps),
        "max_abs_diff_n": diff,
        "jit_first_call_s": float(jit_s),
    }
    if not quiet:
        print(f"Virtual rig plant, tuned rig ({params.n_elements} arc elements, actuator {params.actuator}), "
              "200 mm/s 20 mm unshaped, 1 kHz samples, one core")
        print(f"  compiled RK4 (numba), h <= {params.max_step * 1e3:.2f} ms: {t[-1]:.1f} s simulated in "
              f"{best:.3f} s -> {compiled_rate:.1f} x real time ({plant.integrator_steps} RK4 steps)")
        print(f"  solve_ivp RK45 (numpy), rtol {rtol:.0e}: {start.t:.2f}-{t[sel_t][-1]:.2f} s ({span:.2f} s) "
              f"in {ref_wall:.2f} s -> {ref_rate:.3f} x real time")
        print(f"  ratio compiled / solve_ivp: {compiled_rate / ref_rate:.0f}")
        print(f"  max |compiled - solve_ivp| amplifier output on that window: {diff:.4f} N")
        print(f"  first call (JIT cache load or compile): {jit_s:.2f} s")
    return out


if __name__ == "__main__":  # pragma: no cover
    run_plant_benchmark()
