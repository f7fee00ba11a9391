"""The robustness atlas's sweeps (notebook 09), in two sizes: the stored one and the full one.

Three sweeps, each on the paper's pulse (up at 1 s, down at 8 s, 12 s at 1 kHz):

- ``atlas_freq_damping``: the design's frequency error (the design frequency over the rig's, minus 1) against
  the rig's damping (``damping_scale``: the tuned rig's damping times it; the design keeps the identified
  damping ratio, so the damping error is the rig's ratio minus 0.044), at 20 mm and 200 mm/s;
- ``atlas_amplitude_speed``: the move's amplitude against its speed, the designs without errors;
- ``atlas_uncertainty``: a random sample of the uncertainty model (:mod:`helpers.research.robustness.model`):
the
  amplitude and speed uniform over the commanded ranges, the rig's damping ratio uniform over the prior
  (as ``damping_scale`` = ratio / 0.044), the design frequency off by the identification's standard error.

The shapers: the paper's two TDFs, EI and 2-hump EI at the identified mode, the multi-mode design and the
scheduled ZVD pair, the families tuned on the 95th-percentile residual and the two robust designs of
:func:`helpers.research.robustness.robust_designs` (their file is ``robust_shapers.json`` beside the
definitions); the
uncertainty sample also runs every compared family compressed or stretched to each robust design's duration,
so that each design is judged against every family at the same duration.
"""

from __future__ import annotations

from helpers.paper import numbers as paper
from helpers.research.robustness import COMPARED_FAMILIES, UncertaintyModel
from helpers.research.sweep.definition import SweepDefinition

__all__ = [
    "ATLAS_SHAPERS", "DESIGNS_FILE", "EQUAL_DURATION_SHAPERS", "UNCERTAINTY_SHAPERS", "atlas_definitions"
]  # fmt: skip

DESIGNS_FILE = "robust_shapers.json"
"""The design-set file the atlas's definitions read (beside them)."""

ATLAS_SHAPERS = ("unshaped", "zv", "zvd", "ei", "2-hump-ei", "multi-mode", "scheduled-zvd", "robust",
                 "robust-short")  # fmt: skip
"""The shapers of the two grid sweeps."""

EQUAL_DURATION_SHAPERS = tuple(
    f"{family.lower().replace(' ', '-')}-at-{robust}" for robust in ("robust", "robust-short")
    for family in COMPARED_FAMILIES
)  # fmt: skip
"""The compared families compressed or stretched to each robust design's duration (the design set's
``equal_duration``; :func:`helpers.research.robustness.optimise.at_duration`)."""

UNCERTAINTY_SHAPERS = (*ATLAS_SHAPERS[:7], "zvd-tuned", "ei-tuned", "mzv-tuned", "2-hump-ei-tuned",
                       "zvdd-tuned", "robust", "robust-short", *EQUAL_DURATION_SHAPERS)  # fmt: skip
"""The shapers of the uncertainty sample: the atlas's, the tuned families, and the families at the robust
designs' durations."""

RIG_ZETA = paper.ZETA
"""The tuned rig's damping ratio at rest: ``damping_scale`` = damping ratio / this."""


def atlas_definitions(model: UncertaintyModel, full: bool = False) -> list[SweepDefinition]:
    """The atlas's three sweeps (module docstring): the stored size, or ``full`` (finer, larger, 3 seeds).

    Parameters
    ----------
    model : UncertaintyModel
        Gives the sample's distributions.
    full : bool
        The full atlas instead of the stored one.

    Returns
    -------
    list of SweepDefinition
        Unresolved: they name the design-set file :data:`DESIGNS_FILE` relative to their folder.
    """
    if full:
        errors = [round(-0.3 + 0.025 * i, 3) for i in range(25)]
        zetas = [0.02, 0.025, 0.03, 0.035, 0.04, 0.044, 0.05, 0.06, 0.07, 0.08]
        amplitudes = [2.5 * i for i in range(2, 15)]
        speeds = [50.0 * i for i in range(1, 7)]
        n, seeds = 1000, [0, 1, 2]
    else:
        errors = [-0.2, -0.1, -0.05, 0.0, 0.05, 0.1, 0.2]
        zetas = [0.02, 0.03, 0.044, 0.06, 0.08]
        amplitudes = [5.0, 10.0, 15.0, 20.0, 25.0, 30.0]
        speeds = [100.0, 150.0, 200.0, 250.0, 300.0]
        n, seeds = 64, [0]
    suffix = "_full" if full else ""
    z_lo, z_hi = model.zeta_prior
    common = {"designs_file": DESIGNS_FILE, "chunk_runs": 4}
    grid_seed = {"seed": seeds} if len(seeds) > 1 else {}
    freq_damping = SweepDefinition(
        name=f"atlas_freq_damping{suffix}",
        description="design frequency error x the rig's damping, 20 mm at 200 mm/s",
        shapers=ATLAS_SHAPERS,
        grid={"freq_error": errors, "damping_scale": [round(z / RIG_ZETA, 6) for z in zetas], **grid_seed},
        fixed={"amplitude_mm": 20.0, "speed_mm_s": 200.0},
        **common,
    )
    amplitude_speed = SweepDefinition(
        name=f"atlas_amplitude_speed{suffix}",
        description="move amplitude x speed, designs without errors",
        shapers=ATLAS_SHAPERS,
        grid={"amplitude_mm": amplitudes, "speed_mm_s": speeds, **grid_seed},
        **common,
    )
    sigma = model.identification_sigma
    uncertainty = SweepDefinition(
        name=f"atlas_uncertainty{suffix}",
        description=(
            "a random sample of the uncertainty model (helpers.research.robustness.uncertainty_model)"
        ),
        shapers=UNCERTAINTY_SHAPERS,
        sample={
            "n": n,
            "seed": 2026,
            "distributions": {
                "amplitude_mm": {"uniform": list(model.amplitude_mm)},
                "speed_mm_s": {"uniform": list(model.speed_mm_s)},
                "damping_scale": {"uniform": [round(z_lo / RIG_ZETA, 6), round(z_hi / RIG_ZETA, 6)]},
                "freq_error": {"normal": [0.0, sigma]},
            },
        },
        grid=grid_seed,
        **common,
    )
    return [freq_damping, amplitude_speed, uncertainty]
