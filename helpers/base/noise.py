"""The white-noise level of a sampled signal, robust to slow motion (shared by the metrics and the rig)."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt


def white_noise_std(y: npt.ArrayLike) -> float:
    """Robust standard deviation of the white noise on ``y``, from its second difference.

    The second difference of white noise has 6 times its variance, while a smooth signal (a slow drift or the
    ringing of a motion that has not settled) contributes almost nothing to it, so this measures the sensor's
    noise, not the signal. Median absolute deviation scaled to a standard deviation (1.4826).
    """
    y = np.asarray(y, dtype=float)
    if y.size < 3:
        return 0.0
    d2 = np.diff(y, 2)
    return 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / math.sqrt(6.0)
