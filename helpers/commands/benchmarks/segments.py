"""Cost of the planar twin per simulated second with 12, 24, 36 and 48 arc elements, and what sets the step.

For each element count and integrator (RK4, and the implicit step with bending and cables implicit): the
linear stability limit of one step about rest through the kernel itself, the mode of the right-hand side's
Jacobian the step's growing eigenvector has there (:mod:`helpers.virtual.integrators`), the step used (the
largest ``1 ms / n`` within 90 % of the limit; the implicit step at most at its own step, 0.5 ms) and the
CPU seconds per simulated second of the plant benchmark's up move (0.9-1.4 s of 200 mm/s, 20 mm).
"""

from __future__ import annotations

import os

import pandas as pd

from helpers.virtual.integrators import segment_costs
from helpers.virtual.parameters import INTEGRATOR_STEPS

__all__ = ["run_segments_benchmark"]


def run_segments_benchmark(elements_per_disc: tuple[int, ...] = (1, 2, 3, 4), quiet: bool = False) -> dict:
    """Measure and print the cost per simulated second against the element count (module docstring).

    Returns
    -------
    dict
        ``table``: the rows of :func:`helpers.virtual.integrators.segment_costs`.
    """
    df = segment_costs(elements_per_disc, rosw_step=INTEGRATOR_STEPS["rosw"])
    if not quiet:
        load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
        print(f"planar twin, 0.9-1.4 s of 200 mm/s 20 mm, one core, CPU time (best of 2); load average "
              f"{load}")
        base = df[df.elements == df.elements.min()].set_index("integrator").cpu_s_per_s
        rows = []
        for r in df.itertuples():
            mode = (f"{r.mode_rad_s:.0f} rad/s, zeta {r.mode_zeta:.2f}, {r.mode_where}"
                    if r.mode_where != "none below 2 ms" else "none below 2 ms")  # fmt: skip
            rows.append({"elements": r.elements, "integrator": r.integrator, "limit ms": f"{r.limit_ms:.4f}",
                         "step ms": f"{r.step_ms:.4f}", "CPU s per s": f"{r.cpu_s_per_s:.3f}",
                         "x 12 elements": f"{r.cpu_s_per_s / base[r.integrator]:.1f}", "steps": r.steps,
                         "mode at the limit": mode})  # fmt: skip
        with pd.option_context("display.width", 200, "display.max_colwidth", 60):
            print(pd.DataFrame(rows).to_string(index=False))
    return {"table": df}


if __name__ == "__main__":  # pragma: no cover
    run_segments_benchmark()
