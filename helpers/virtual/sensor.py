"""The load cell, its amplifier and the DAQ board's 10-bit ADC: tension (N) in, counts out.

``counts = clip(round(offset + gain * tension + noise), 0, 1023)``

Assumed values (the paper gives the parts, not their calibration):

- gain: the paper's load cell is an LSP-5 (0-5 N) but Table II reports peaks up to 17.7 N, so the chain
  must not saturate below ~20 N. With the offset below, 50 counts per N puts 19.4 N at full scale
  (``(1023 - 50) / 50``); 0.02 N per count is also about the resolution of the paper's Fig. 5 trace.
- offset: 50 counts at zero tension, so that a slack cable (0 N) reads above the ADC floor and small negative
  amplifier offsets would still be visible.
- noise: Gaussian, 1.0 count rms (amplifier noise plus ADC noise of a typical Arduino set-up).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from helpers.hardware import ADC_MAX
from helpers.virtual.parameters import RigParameters

__all__ = ["LoadCell", "GAIN_COUNTS_PER_N", "OFFSET_COUNTS", "NOISE_COUNTS_RMS"]

GAIN_COUNTS_PER_N: float = 50.0
"""Counts per newton (assumed, see module docstring)."""

OFFSET_COUNTS: float = 50.0
"""Counts at zero tension (assumed)."""

NOISE_COUNTS_RMS: float = 1.0
"""Gaussian noise before quantisation, counts rms (assumed)."""


class LoadCell:
    """Load cell + amplifier + 10-bit ADC with noise and quantisation.

    Parameters
    ----------
    params : RigParameters or None
        The rig (kept for provenance; the sensor constants are module constants).
    seed : int or None
        Seed of the noise generator.
    gain, offset, noise_rms : float
        Counts per N, counts at 0 N, noise in counts rms.
    """

    def __init__(
        self,
        params: RigParameters | None = None,
        seed: int | None = 0,
        gain: float = GAIN_COUNTS_PER_N,
        offset: float = OFFSET_COUNTS,
        noise_rms: float = NOISE_COUNTS_RMS,
    ) -> None:
        if not (np.isfinite(gain) and gain > 0):
            raise ValueError(f"gain must be positive, got {gain!r}")
        if not (np.isfinite(offset) and 0 <= offset <= ADC_MAX):
            raise ValueError(f"offset must lie in 0..{ADC_MAX}, got {offset!r}")
        if not (np.isfinite(noise_rms) and noise_rms >= 0):
            raise ValueError(f"noise_rms must be >= 0, got {noise_rms!r}")
        self.params = params
        self.gain = float(gain)
        self.offset = float(offset)
        self.noise_rms = float(noise_rms)
        self._rng = np.random.default_rng(seed)

    def reseed(self, seed: int | None) -> None:
        """Restart the noise generator from ``seed`` (one seed per recorded run)."""
        self._rng = np.random.default_rng(seed)

    @property
    def newtons_per_count(self) -> float:
        """The true calibration slope, N per count."""
        return 1.0 / self.gain

    @property
    def offset_counts(self) -> float:
        """The true reading at zero tension, counts."""
        return self.offset

    @property
    def full_scale_newtons(self) -> float:
        """Tension that reads 1023 counts, N."""
        return (ADC_MAX - self.offset) / self.gain

    def counts(self, tension: npt.ArrayLike) -> np.ndarray:
        """ADC counts (int64, 0..1023) for tensions in N."""
        lam = np.asarray(tension, dtype=float)
        if not np.all(np.isfinite(lam)):
            raise ValueError("tension must be finite")
        v = self.offset + self.gain * lam
        if self.noise_rms > 0:
            v = v + self._rng.normal(0.0, self.noise_rms, size=lam.shape)
        return np.clip(np.rint(v), 0, ADC_MAX).astype(np.int64)

    def tension(self, counts: npt.ArrayLike) -> np.ndarray:
        """Invert the true calibration: counts to N (what a calibrated user would compute)."""
        return (np.asarray(counts, dtype=float) - self.offset) / self.gain
