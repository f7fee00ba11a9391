"""The load cell's signal chain after the amplifier's filter: current loop, shunt and the 10-bit ADC.

The amplifier's bandwidth is modelled inside the plant (:class:`~helpers.virtual.plant.ArmPlant` returns
the amplifier's output, a first-order low-pass of the tension integrated with the arm); this module turns
that output into ADC counts::

    I = 4 mA + 16 mA * output / span_n,   clipped to the loop's linear range [3.8, 20.5] mA
    counts = clip(round(1024 * I * 150 ohm / 5 V + noise), 0, 1023)

The loop, the shunt (paper), the ADC's reference and resolution, ``span_n`` (20 N) and the noise (0.5 count
rms) are :class:`~helpers.virtual.parameters.RigParameters` fields (from the rig file's ``[hardware]``:
:func:`helpers.virtual.from_rig.rig_parameters`). With the defaults: 24.58
counts per N (0.041 N per count), 122.9 counts at 0 N, saturation at 20.6 N (629.8 counts): the paper's
largest tension, 17.7 N, reads 558 counts. A reading at or beyond the loop's saturation (or the ADC's rails)
is *clipped*; :func:`helpers.paper.metrics.clipped_samples` flags it, for hardware recordings too.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from helpers.virtual.parameters import RigParameters

__all__ = ["LoadCell", "GAIN_COUNTS_PER_N", "OFFSET_COUNTS"]

GAIN_COUNTS_PER_N: float = RigParameters().gain_counts_per_n
"""Counts per newton of the tuned rig's chain (24.58)."""

OFFSET_COUNTS: float = RigParameters().offset_counts
"""Counts at zero tension (the loop's 4 mA: 122.88)."""


class LoadCell:
    """Current loop, shunt and 10-bit ADC, with noise and quantisation.

    Parameters
    ----------
    params : RigParameters or None
        The rig (``span_n`` and ``adc_noise_counts``); default the tuned rig.
    seed : int or None
        Seed of the noise generator.
    noise_rms : float, optional
        Override the noise, counts rms.
    span_n : float, optional
        Override the load that drives the loop to 20 mA (N), e.g. to make a recording that clips.
    """

    def __init__(
        self,
        params: RigParameters | None = None,
        seed: int | None = 0,
        noise_rms: float | None = None,
        span_n: float | None = None,
    ) -> None:
        params = RigParameters() if params is None else params
        noise = params.adc_noise_counts if noise_rms is None else float(noise_rms)
        span = params.span_n if span_n is None else float(span_n)
        if not (np.isfinite(noise) and noise >= 0):
            raise ValueError(f"noise_rms must be >= 0, got {noise!r}")
        if not (np.isfinite(span) and span > 0):
            raise ValueError(f"span_n must be positive, got {span!r}")
        self.params = params
        self.noise_rms = noise
        self.span_n = span
        self._rng = np.random.default_rng(seed)

    def reseed(self, seed: int | None) -> None:
        """Restart the noise generator from ``seed`` (one seed per recorded run)."""
        self._rng = np.random.default_rng(seed)

    @property
    def gain(self) -> float:
        """Counts per newton."""
        zero, full, _, _ = self.params.loop_a
        return self.params.loop_counts(full - zero) / self.span_n

    @property
    def offset(self) -> float:
        """Counts at zero tension."""
        return self.params.offset_counts

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
        """Tension at which the loop saturates (20.5 mA), N."""
        zero, full, _, hi = self.params.loop_a
        return (hi - zero) / (full - zero) * self.span_n

    def current(self, output_n: npt.ArrayLike) -> np.ndarray:
        """Loop current (A) for amplifier outputs in N, clipped to the loop's linear range."""
        lam = np.asarray(output_n, dtype=float)
        zero, full, lo, hi = self.params.loop_a
        return np.clip(zero + (full - zero) * lam / self.span_n, lo, hi)

    def counts(self, output_n: npt.ArrayLike) -> np.ndarray:
        """ADC counts (int64, 0..1023) for amplifier outputs in N."""
        lam = np.asarray(output_n, dtype=float)
        if not np.all(np.isfinite(lam)):
            raise ValueError("tension must be finite")
        v = self.params.loop_counts(1.0) * self.current(lam)
        if self.noise_rms > 0:
            v = v + self._rng.normal(0.0, self.noise_rms, size=lam.shape)
        return np.clip(np.rint(v), 0, 2**self.params.adc_bits - 1).astype(np.int64)

    def tension(self, counts: npt.ArrayLike) -> np.ndarray:
        """Invert the true calibration: counts to N (what a calibrated user would compute)."""
        return (np.asarray(counts, dtype=float) - self.offset) / self.gain
