"""Offline convenience: run a stepper programme on the virtual rig and return the sampled time series.

This is what the emulated boards do over the serial protocol, without the protocol: the plant integrates
the programme's exact step instants, the amplifier filters the tension and the ADC samples its output at the
DAQ rate.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from helpers.recordings import counts_to_newtons
from helpers.virtual.parameters import RigParameters
from helpers.virtual.plant import ArmLanes, ArmPlant
from helpers.virtual.sensor import LoadCell
from helpers.virtual.statics import node_positions

__all__ = ["SimResult", "simulate", "simulate_lanes", "programme_steps"]


@dataclass(frozen=True)
class SimResult:
    """A simulated run of the virtual rig (never to be presented as a hardware measurement).

    Attributes
    ----------
    t : numpy.ndarray
        Sample times, s (the DAQ clock; GO at ``t_go``).
    tension : numpy.ndarray
        True tension of the measured cable at the samples, N.
    output : numpy.ndarray
        The amplifier's output at the samples (the tension through its low-pass), N, noise-free.
    adc : numpy.ndarray
        Load-cell ADC counts at the samples (loop saturation, noise and quantisation included).
    steps : numpy.ndarray
        Motor position at the samples, steps (a step at a sample instant counts).
    angles : numpy.ndarray
        Tangent angles at the element ends at the samples, rad, shape ``(n_samples, n_elements)``.
    params : RigParameters
        The rig.
    newtons_per_count, offset_counts : float
        The load cell's true calibration.
    max_rotor_lag_steps : float
        Largest lag of the rotor behind its commanded angle during the run, microsteps (health figure).
    """

    t: np.ndarray
    tension: np.ndarray
    output: np.ndarray
    adc: np.ndarray
    steps: np.ndarray
    angles: np.ndarray
    params: RigParameters
    newtons_per_count: float
    offset_counts: float
    max_rotor_lag_steps: float = 0.0

    @property
    def u_mm(self) -> np.ndarray:
        """Cable displacement at the samples, mm."""
        return self.steps * self.params.cable_per_step * 1e3

    def shapes(self) -> tuple[np.ndarray, np.ndarray]:
        """Backbone node positions ``(x, y)`` at every sample, m, each of shape ``(n_samples, n_nodes)``."""
        return node_positions(self.params, self.angles)

    def shape_at(self, time_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Node positions ``(x, y)`` at the sample nearest ``time_s``."""
        i = int(np.argmin(np.abs(self.t - time_s)))
        return node_positions(self.params, self.angles[i])

    def tip(self) -> tuple[np.ndarray, np.ndarray]:
        """Tip position ``(x, y)`` over time, m."""
        x, y = self.shapes()
        return x[:, -1], y[:, -1]

    def frame(self, signal: str = "output") -> pd.DataFrame:
        """The run as a recording-like frame ``t_s``, ``steps``, ``adc``, ``tension_n`` (for the metrics).

        Parameters
        ----------
        signal : {"output", "tension", "adc"}
            ``tension_n`` is the amplifier's noise-free output, the true tension of the measured cable, or the
            ADC counts converted with the load cell's true calibration (what a calibrated user would compute
            from a recording). The ``adc`` column is always there, so the metrics' range check sees clipping.
        """
        if signal == "output":
            tension = self.output
        elif signal == "tension":
            tension = self.tension
        elif signal == "adc":
            tension = counts_to_newtons(self.adc, self.newtons_per_count, self.offset_counts)
        else:
            raise ValueError(f"signal must be 'output', 'tension' or 'adc', got {signal!r}")
        return pd.DataFrame({"t_s": self.t, "steps": self.steps, "adc": self.adc, "tension_n": tension})


def programme_steps(programme: Any) -> tuple[np.ndarray, np.ndarray, float]:
    """Step times (s from GO), signs and duration (s) of a programme.

    Accepts a :class:`helpers.board.programmes.Programme` (``step_times()``, ``duration_s``), the tuple that
    ``helpers.board.programmes.experiment_programme`` returns (programme, report), or ``(times_s, signs)``
    arrays.
    """
    if isinstance(programme, tuple) and len(programme) == 2 and hasattr(programme[0], "step_times"):
        programme = programme[0]
    if hasattr(programme, "step_times"):
        times, signs = programme.step_times()
        duration = float(programme.duration_s)
    else:
        try:
            times, signs = programme
        except (TypeError, ValueError) as exc:
            raise ValueError("programme must be a Programme or a (step_times_s, step_signs) pair") from exc
        times = np.asarray(times, dtype=float)
        duration = float(times[-1]) if times.size else 0.0
    return np.asarray(times, dtype=float), np.asarray(signs, dtype=float), duration


def simulate(
    programme: Any,
    rate_hz: float = 1000.0,
    params: RigParameters | None = None,
    t_go: float = 0.0,
    t_end: float | None = None,
    seed: int | None = 0,
    plant: ArmPlant | None = None,
    sensor: LoadCell | None = None,
) -> SimResult:
    """Run ``programme`` on the virtual rig and sample it at ``rate_hz``.

    Parameters
    ----------
    programme : Programme or (times_s, signs)
        What the stepper board executes; step times count from GO.
    rate_hz : float
        DAQ sample rate; samples at ``k / rate_hz`` for k = 0, 1, ... up to ``t_end``.
    params : RigParameters, optional
        Default: the tuned rig ``RigParameters()``.
    t_go : float
        Time of GO on the DAQ clock, s (``experiment_programme`` already contains the 1 s lead-in, so 0).
    t_end : float, optional
        End of the recording, s (default: the end of the programme).
    seed : int, optional
        Seed of the load-cell noise.
    plant : ArmPlant, optional
        Reuse a plant (it is reset first), e.g. to avoid rebuilding it in sweeps.
    sensor : LoadCell, optional
        The signal chain (default ``LoadCell(params, seed=seed)``).

    Returns
    -------
    SimResult
    """
    if params is None:
        params = RigParameters() if plant is None else plant.params
    t, times, signs = _grid(programme, rate_hz, t_go, t_end)
    if plant is None:
        plant = ArmPlant(params)
    else:
        plant.reset()
    output, raw, angles = plant.advance_all(t, times, signs)
    lag = plant.max_rotor_lag_steps
    return _result(plant.params, t, times, signs, output, raw, angles, lag, seed, sensor)


def simulate_lanes(
    programmes: Sequence[Any],
    params: Sequence[RigParameters],
    rate_hz: float = 1000.0,
    t_end: float | None = None,
    seeds: Sequence[int | None] | None = None,
) -> list[SimResult]:
    """:func:`simulate` of several runs in the lanes of one kernel call: the same results, bit for bit.

    Parameters
    ----------
    programmes : sequence
        One programme per run (as :func:`simulate` takes), 1 to ``max(LANE_WIDTHS)`` runs.
    params : sequence of RigParameters
        One rig per run; all share :func:`helpers.virtual.plant.lane_group` (see :class:`ArmLanes`).
    rate_hz, t_end
        As :func:`simulate`, shared by every run (one sample grid; ``t_end`` None: each programme's end,
        which must then be the same).
    seeds : sequence of int or None, optional
        Each run's load-cell noise seed (default 0 for all).

    Returns
    -------
    list of SimResult
        In the order of the runs.
    """
    if len(programmes) != len(params):
        raise ValueError(f"one rig per programme: {len(programmes)} programmes, {len(params)} rigs")
    seeds = [0] * len(params) if seeds is None else list(seeds)
    if len(seeds) != len(params):
        raise ValueError(f"one seed per run: {len(params)} runs, {len(seeds)} seeds")
    grids = [_grid(prog, rate_hz, 0.0, t_end) for prog in programmes]
    t = grids[0][0]
    if any(g[0].shape != t.shape or np.any(g[0] != t) for g in grids[1:]):
        raise ValueError("the runs of one simulate_lanes call must share their sample times (rate_hz, t_end)")
    lanes = ArmLanes(params)
    output, raw, angles = lanes.advance_all(t, [g[1] for g in grids], [g[2] for g in grids])
    lags = lanes.max_rotor_lag_steps
    return [
        _result(p, t, g[1], g[2], output[k], raw[k], angles[k], float(lags[k]), seeds[k], None)
        for k, (p, g) in enumerate(zip(params, grids, strict=True))
    ]


def _grid(programme: Any, rate_hz: float, t_go: float, t_end: float | None) -> tuple[np.ndarray, ...]:
    """The sample times of a run and its step times and signs up to its end (checked)."""
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz must be positive, got {rate_hz!r}")
    if not (math.isfinite(t_go) and t_go >= 0):
        raise ValueError(f"t_go must be >= 0, got {t_go!r}")
    times, signs, duration = programme_steps(programme)
    times = times + t_go
    t_end = t_go + duration if t_end is None else float(t_end)
    if not (math.isfinite(t_end) and t_end > 0):
        raise ValueError(f"t_end must be positive, got {t_end!r}")
    keep = times <= t_end
    times, signs = times[keep], signs[keep]
    n = int(math.floor(t_end * rate_hz + 1e-9)) + 1
    return np.arange(n) / rate_hz, times, signs


def _result(
    params: RigParameters, t: np.ndarray, times: np.ndarray, signs: np.ndarray, output: np.ndarray,
    raw: np.ndarray, angles: np.ndarray, lag: float, seed: int | None, sensor: LoadCell | None,
) -> SimResult:  # fmt: skip
    """A run's :class:`SimResult` from what the plant produced (the ADC sampled here)."""
    at = np.searchsorted(t, times, side="left")
    steps = np.cumsum(np.bincount(at, weights=signs, minlength=t.size)[: t.size])
    sensor = LoadCell(params, seed=seed) if sensor is None else sensor
    adc = sensor.counts(output)
    return SimResult(
        t=t,
        tension=raw,
        output=output,
        adc=adc,
        steps=np.rint(steps).astype(np.int64),
        angles=angles,
        params=params,
        newtons_per_count=sensor.newtons_per_count,
        offset_counts=sensor.offset_counts,
        max_rotor_lag_steps=lag,
    )


def run_steps(
    params: RigParameters, t: npt.ArrayLike, times: npt.ArrayLike, signs: npt.ArrayLike
) -> np.ndarray:
    """Tension at ``t`` for steps at ``times`` with ``signs`` (a fresh plant; for sweeps and tests)."""
    return ArmPlant(params).advance(t, times, signs)
