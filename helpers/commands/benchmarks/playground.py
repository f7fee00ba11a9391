"""CPU time of one update of notebook 03's interactive shaper study (the playground), redraw included.

The interactivity target is at most 0.3 s of CPU per slider move after the first (which draws the figure). It
is measured in CPU time of this process, not wall time (which other processes on a shared machine inflate),
on the Agg backend, over a fixed sequence of slider values; the median and the maximum are printed.
"""

from __future__ import annotations

import statistics
import time

import matplotlib

from helpers.paper.identify import load_identification
from helpers.research.playground import ShaperPlayground

__all__ = ["SLIDER_MOVES", "run_playground_benchmark"]

SLIDER_MOVES = ((1.1, 0.0), (0.9, 0.02), (1.3, -0.02), (1.2, 0.05), (0.8, 0.0))
"""(design_ratio, zeta_error) after the first update: the moves timed."""

TARGET_CPU_S = 0.3
"""The interactivity target (s of CPU per update), printed beside the measurement, never asserted."""


def run_playground_benchmark(repeats: int = 2, quiet: bool = False) -> dict:
    """Measure and print the CPU time of the playground's updates.

    Parameters
    ----------
    repeats : int
        Passes over :data:`SLIDER_MOVES`.
    quiet : bool
        Do not print.

    Returns
    -------
    dict
        ``median_cpu_s``, ``max_cpu_s``, ``first_cpu_s`` (the first update, which draws the figure),
        ``updates``.
    """
    if repeats < 1:
        raise ValueError(f"repeats must be >= 1, got {repeats!r}")
    matplotlib.use("Agg")
    mode = load_identification()
    playground = ShaperPlayground(mode.omega_d, mode.zeta)
    start = time.process_time()
    playground.update(1.0, 0.0)
    first = time.process_time() - start
    cpu = []
    for _ in range(repeats):
        for ratio, zeta_error in SLIDER_MOVES:
            start = time.process_time()
            playground.update(ratio, zeta_error)
            cpu.append(time.process_time() - start)
    out = {
        "median_cpu_s": statistics.median(cpu),
        "max_cpu_s": max(cpu),
        "first_cpu_s": first,
        "updates": len(cpu),
    }
    if not quiet:
        print(f"first update (draws the figure): {first:.3f} s of CPU")
        print(
            f"{len(cpu)} updates after it: median {out['median_cpu_s']:.3f} s, "
            f"max {out['max_cpu_s']:.3f} s of CPU (target <= {TARGET_CPU_S} s)"
        )
    return out
