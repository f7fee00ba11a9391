"""Offline convenience: run one step programme per tendon on the spatial twin and sample every load cell.

The spatial counterpart of :func:`helpers.virtual.simulate`: the plant integrates every tendon's exact step
instants, each amplifier filters its tendon's arm-side tension and each tendon's ADC chain samples its
output at the DAQ rate (the planar rig's :class:`~helpers.virtual.sensor.LoadCell`, with that tendon's
``load_cell_range_n``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from helpers.recordings import counts_to_newtons
from helpers.virtual.sensor import LoadCell
from helpers.virtual.simulate import programme_steps
from helpers.virtual.spatial.plant import SpatialPlant
from helpers.virtual.spatial.rig import SpatialRig

__all__ = ["SpatialResult", "merge_programmes", "simulate_spatial"]


@dataclass(frozen=True)
class SpatialResult:
    """A simulated run of the spatial twin (never to be presented as a hardware measurement).

    Attributes
    ----------
    t : numpy.ndarray
        Sample times, s.
    tension, output : numpy.ndarray
        Each tendon's true arm-side tension and its amplifier's noise-free output, N, shape (n, nt).
    adc : numpy.ndarray
        Each tendon's ADC counts (loop saturation, noise and quantisation), shape (n, nt).
    steps : numpy.ndarray
        Each tendon's motor position at the samples, steps, shape (n, nt).
    q : numpy.ndarray
        The arm's coordinates at the samples, shape (n, 3N).
    tip : numpy.ndarray
        The tip node's position in the clamp frame, m, shape (n, 3).
    rig : SpatialRig
    newtons_per_count, offset_counts : numpy.ndarray
        Each load cell's true calibration.
    max_rotor_lag_steps : numpy.ndarray
        Each rotor's largest lag behind its command, microsteps.
    """

    t: np.ndarray
    tension: np.ndarray
    output: np.ndarray
    adc: np.ndarray
    steps: np.ndarray
    q: np.ndarray
    tip: np.ndarray
    rig: SpatialRig
    newtons_per_count: np.ndarray
    offset_counts: np.ndarray
    max_rotor_lag_steps: np.ndarray

    def frame(self, tendon: int = 0, signal: str = "output") -> pd.DataFrame:
        """Tendon ``tendon``'s run as a recording-like frame ``t_s``, ``steps``, ``adc``, ``tension_n``.

        ``signal`` as :meth:`helpers.virtual.simulate.SimResult.frame`: the amplifier's output, the true
        tension, or the ADC counts through the load cell's true calibration.
        """
        if signal == "output":
            tension = self.output[:, tendon]
        elif signal == "tension":
            tension = self.tension[:, tendon]
        elif signal == "adc":
            tension = counts_to_newtons(self.adc[:, tendon], self.newtons_per_count[tendon],
                                        self.offset_counts[tendon])  # fmt: skip
        else:
            raise ValueError(f"signal must be 'output', 'tension' or 'adc', got {signal!r}")
        return pd.DataFrame({"t_s": self.t, "steps": self.steps[:, tendon], "adc": self.adc[:, tendon],
                             "tension_n": tension})  # fmt: skip


def merge_programmes(
    programmes: Sequence[Any], n_tendons: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Every tendon's step instants as one sorted list: ``(times, tendons, signs, duration)``.

    ``programmes[i]`` is tendon ``i``'s programme (anything :func:`helpers.virtual.simulate.programme_steps`
    accepts) or ``None`` (no steps); steps at the same instant keep the tendons' order.
    """
    if len(programmes) != n_tendons:
        raise ValueError(f"one programme per tendon: {n_tendons} expected, got {len(programmes)}")
    times, tendons, signs = [], [], []
    duration = 0.0
    for i, prog in enumerate(programmes):
        if prog is None:
            continue
        t, s, d = programme_steps(prog)
        times.append(t)
        signs.append(s)
        tendons.append(np.full(t.size, i, dtype=np.int64))
        duration = max(duration, d)
    if not times:
        return np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0), duration
    t = np.concatenate(times)
    order = np.argsort(t, kind="stable")
    return t[order], np.concatenate(tendons)[order], np.concatenate(signs)[order], duration


def simulate_spatial(
    programmes: Sequence[Any],
    rig: SpatialRig | None = None,
    rate_hz: float = 1000.0,
    t_end: float | None = None,
    seed: int | None = 0,
    plant: SpatialPlant | None = None,
    max_step: float | None = None,
) -> SpatialResult:
    """Run one programme per tendon on the spatial twin and sample it at ``rate_hz``.

    Parameters
    ----------
    programmes : sequence
        Tendon ``i``'s programme (a :class:`helpers.board.programmes.Programme`, ``(times_s, signs)`` or
        ``None``).
    rig : SpatialRig, optional
        Default: the plant's, or the paper's rig.
    rate_hz : float
        DAQ sample rate; samples at ``k / rate_hz`` up to ``t_end``.
    t_end : float, optional
        End of the run, s (default: the end of the longest programme).
    seed : int, optional
        Seed of the load cells' noise (tendon 1 draws from ``seed`` as the planar rig's load cell does,
        tendon ``i`` from ``(seed, i)``).
    plant : SpatialPlant, optional
        Reuse a plant (it is reset first).
    max_step : float, optional
        Largest integrator step, s (a new plant's; default the arm's ``max_step``).
    """
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz must be positive, got {rate_hz!r}")
    if plant is None:
        plant = SpatialPlant(SpatialRig() if rig is None else rig, max_step=max_step)
    else:
        plant.reset()
    rig = plant.rig
    nt = rig.n_tendons
    times, tendons, signs, duration = merge_programmes(programmes, nt)
    t_end = duration if t_end is None else float(t_end)
    if not (math.isfinite(t_end) and t_end > 0):
        raise ValueError(f"t_end must be positive, got {t_end!r}")
    keep = times <= t_end
    times, tendons, signs = times[keep], tendons[keep], signs[keep]
    n = int(math.floor(t_end * rate_hz + 1e-9)) + 1
    t = np.arange(n) / rate_hz
    out = plant.advance(t, times, tendons, signs)
    idx = np.searchsorted(t, times, side="left")
    steps = np.zeros((n, nt))
    np.add.at(steps, (idx, tendons), signs)
    steps = np.rint(np.cumsum(steps, axis=0)).astype(np.int64)
    adc = np.empty((n, nt), dtype=np.int64)
    npc = np.empty(nt)
    off = np.empty(nt)
    for i in range(nt):
        cell = LoadCell(rig.arm, seed=seed if (seed is None or i == 0) else [seed, i],
                        span_n=rig.tendons[i].load_cell_range_n)  # fmt: skip
        adc[:, i] = cell.counts(out["output"][:, i])
        npc[i] = cell.newtons_per_count
        off[i] = cell.offset_counts
    return SpatialResult(t=t, tension=out["tension"], output=out["output"], adc=adc, steps=steps, q=out["q"],
                         tip=out["tip"], rig=rig, newtons_per_count=npc, offset_counts=off,
                         max_rotor_lag_steps=plant.max_rotor_lag_steps)  # fmt: skip
