"""``python -m helpers bench``: the project's speed figures, printed, never asserted in unit tests.

- ``plant``: the virtual rig's plant in real-time factors of CPU time, the implicit step and the RK4
  reference on the same scenario (and a plain ``solve_ivp`` implementation of the same equations);
- ``serial``: sustained DAQ rate over the pseudo-terminal server for the paper's one tendon and
  ``four-tendon`` (every channel, the data lines' bytes against the build's baud rate), and the wall time to
  record one scenario on the in-process virtual rig with its CPU time over the bare plant's (aim <= 1.3x);
- ``playground``: CPU time of one update of notebook 03's interactive shaper study (target <= 0.3 s);
- ``sweep``: runs per second of a sweep's tasks on 1 and 2 workers of a local Dask cluster, the scaling
  ratio, Dask's overhead against a bare loop, the per-run overhead outside the integration;
- ``spatial``: the spatial twin's real-time factors in CPU time, a 12 s four-tendon scenario with the implicit
  step and the RK4 reference, and the paper's one tendon beside the planar plant;
- ``segments``: the planar twin's cost per simulated second with 12, 24, 36 and 48 arc elements, each
  integrator, and the modes that set each one's step;
- ``convergence``: the implicit step against RK4 at a quarter of its step, Table I and four tendons;
- ``tune-lanes``: runs per CPU second of ``tune``'s verification runs of one Table I condition, each alone in
  a world of its own and 8 worlds in lockstep (their plants in one kernel call), the ratio, and whether every
  recording in lanes is byte-identical to the same run alone;
- ``tune-tendons-lanes``: the same for ``tune``'s verification moves on ``four-tendon`` (one bend, every
  design), their twins ``SpatialLanes`` in lanes.
"""

from __future__ import annotations

import argparse
import platform
import time
from collections.abc import Callable
from typing import Any

from helpers.commands.benchmarks.convergence import run_convergence_benchmark
from helpers.commands.benchmarks.plant import run_plant_benchmark
from helpers.commands.benchmarks.playground import run_playground_benchmark
from helpers.commands.benchmarks.segments import run_segments_benchmark
from helpers.commands.benchmarks.serial import run_serial_benchmark
from helpers.commands.benchmarks.spatial import run_spatial_benchmark
from helpers.commands.benchmarks.sweep import run_sweep_benchmark
from helpers.commands.benchmarks.tune_lanes import run_tune_lanes_benchmark, run_tune_tendons_lanes_benchmark

SUITES: dict[str, Callable[[], dict[str, Any]]] = {
    "plant": run_plant_benchmark,
    "playground": run_playground_benchmark,
    "serial": run_serial_benchmark,
    "sweep": run_sweep_benchmark,
    "spatial": run_spatial_benchmark,
    "segments": run_segments_benchmark,
    "convergence": run_convergence_benchmark,
    "tune-lanes": run_tune_lanes_benchmark,
    "tune-tendons-lanes": run_tune_tendons_lanes_benchmark,
}
"""suite name -> function; each prints its figures and returns them as a dict."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``bench`` command's options."""
    parser.add_argument(
        "suites", nargs="*", metavar="suite", help=f"any of {', '.join(SUITES)} (default: all)"
    )


def run(args: argparse.Namespace) -> int:
    """Run the chosen benchmark suites and print their figures."""
    chosen = args.suites or list(SUITES)
    unknown = sorted(set(chosen) - set(SUITES))
    if unknown:
        print(f"unknown benchmark suite(s): {', '.join(unknown)}; choose from {', '.join(SUITES)}")
        return 2
    print(f"python {platform.python_version()} on {platform.machine()}, {time.strftime('%Y-%m-%d')}")
    for name in chosen:
        print(f"\n== {name} ==")
        SUITES[name]()
    return 0
