"""The implicit step at its step against RK4 at a quarter of it: Table I, the identification, four tendons.

- the twelve Table I scenarios (noise-free amplifier output, the Table II metrics of each move) and the
  identification run (``helpers.paper.identify`` on its ADC counts): the largest movement of each metric,
  the row where it happens, and the integrator steps both took (:func:`~helpers.virtual.integrators.
  table_i_convergence`);
- four-tendon bends (``rigs/four-tendon.toml``'s twin, 200 mm/s, up at 1 s, down at 8 s): each tendon's
  largest output difference, its peaks and hold, the tip, the steps and transitions
  (:func:`~helpers.virtual.integrators.four_tendon_convergence`).

The band these must meet is stated in ``docs/virtual_rig.md``, section 2.
"""

from __future__ import annotations

import dataclasses
import os

from helpers.virtual import RigParameters
from helpers.virtual.integrators import four_tendon_convergence, table_i_convergence
from helpers.virtual.spatial.rig import four_tendon_rig

__all__ = ["run_convergence_benchmark"]


def run_convergence_benchmark(quiet: bool = False) -> dict:
    """Run both studies and print their largest movements (module docstring)."""
    params = RigParameters().with_integrator("rosw")
    one = table_i_convergence(params)
    rig = four_tendon_rig()
    rig = dataclasses.replace(rig, arm=rig.arm.with_integrator("rosw"))
    four = four_tendon_convergence(rig)
    if not quiet:
        load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
        rows = one["rows"]
        print(f"implicit step at {params.max_step * 1e3:.2f} ms against RK4 at {params.max_step * 250:.4f} "
              f"ms (load average {load})")
        print("Table I, twelve scenarios, 24 moves (noise-free output):")
        for col, unit in (("d_peak_n", "N"), ("d_overshoot_pp", "pp"), ("d_settling_ms", "ms")):
            i = rows[col].abs().idxmax()
            r = rows.loc[i]
            print(f"  largest |{col}| {abs(r[col]):.4f} {unit} ({r.v_in_mm_s:.0f} mm/s, {r.x_f_mm:.0f} mm, "
                  f"{r.system}, {r.motion})")
        print(f"  identification: omega_d {one['omega_d']:.5f} against {one['ref_omega_d']:.5f} rad/s "
              f"({(one['omega_d'] / one['ref_omega_d'] - 1) * 1e6:+.1f} ppm), zeta {one['zeta']:.6f} against "
              f"{one['ref_zeta']:.6f} ({(one['zeta'] / one['ref_zeta'] - 1) * 1e6:+.0f} ppm)")
        print(f"  integrator steps, the twelve runs: {rows.steps.iloc[::2].sum()} against "
              f"{rows.ref_steps.iloc[::2].sum()}; CPU {one['cpu_s']:.2f} s against {one['ref_cpu_s']:.2f} s")
        print("four tendons, 200 mm/s (per bend: the largest over the tendons):")
        for (d, b), g in four.groupby(["direction_deg", "bend_mm"], sort=False):
            print(f"  {b:.0f} mm towards {d:.0f} deg: output {g.max_diff_n.max():.3f} N, up peak "
                  f"{g.d_up_peak_n.abs().max():.3f} N, down peak {g.d_down_peak_n.abs().max():.3f} N, hold "
                  f"{g.d_hold_n.abs().max():.4f} N, tip {g.tip_max_diff_mm.max():.3f} mm; steps "
                  f"{g.steps.iloc[0]} against {g.ref_steps.iloc[0]}, transitions {g.transitions.iloc[0]} "
                  f"against {g.ref_transitions.iloc[0]}")
    return {"table_i": one, "four_tendons": four}


if __name__ == "__main__":  # pragma: no cover
    run_convergence_benchmark()
