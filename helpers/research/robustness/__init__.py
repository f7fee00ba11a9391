"""Robustness of shapers under the uncertainty a user faces, and shapers designed for it (``docs/sweeps.md``).

- :mod:`~helpers.research.robustness.model`: the distribution of the mode a shaper meets (the frequency over
the
  mode map across the moves' range, the identification's standard errors, a stated damping prior),
  :func:`uncertainty_model` (the one function that chooses the map) and the residual on the linear model;
- :mod:`~helpers.research.robustness.optimise`: the families tuned on a percentile of that residual, a
free-impulse
  shaper optimised on it, and the design-set file the sweeps read.
"""

from helpers.research.robustness.model import (
    MEASURED_MAP,
    PREDICTED_MAP_TABLE,
    UncertaintyModel,
    UncertaintySample,
    default_map,
    linear_residual_pct,
    percentile_pct,
    predicted_map,
    uncertainty_model,
)
from helpers.research.robustness.optimise import (
    COMPARED_FAMILIES,
    DesignSet,
    TunedShaper,
    at_duration,
    load_designs,
    optimise_shaper,
    robust_designs,
    save_designs,
    tune_family,
)

__all__ = [
    "COMPARED_FAMILIES",
    "MEASURED_MAP",
    "PREDICTED_MAP_TABLE",
    "DesignSet",
    "TunedShaper",
    "UncertaintyModel",
    "at_duration",
    "default_map",
    "UncertaintySample",
    "linear_residual_pct",
    "load_designs",
    "optimise_shaper",
    "percentile_pct",
    "predicted_map",
    "robust_designs",
    "save_designs",
    "tune_family",
    "uncertainty_model",
]
