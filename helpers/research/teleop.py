"""Arbitrary (teleoperation-like) motion: commands, a shaper scheduled on the configuration, analysis.

The stepper board shapes a velocity stream with one fixed shaper (``docs/streaming.md``). A shaper scheduled
on the arm's configuration cannot live on the board, so it runs on the host: :func:`schedule_setpoints` shapes
the set-points before they are sent (the board then holds the unit shaper). Each set-point ``v[k]`` (one per
10 ms period) is spread over the impulses of the family's shaper designed for the mode at the cable position
the command has reached at that period (:class:`helpers.research.modemap.ModeMap`): amplitude ``A_i`` at delay
``t_i``, a delay between two periods split between them in proportion (a linear fractional delay). The
amplitudes of every spread sum to one, so the shaped stream moves the cable exactly as far as the command.

The two commands of notebook 08 (:func:`teleop_command`: band-limited random moves with stops;
:func:`pick_and_place`: a scripted sequence) are velocity arrays at 100 Hz, and :func:`stops` /
:func:`stop_residuals` / :func:`tracking_delay` / :func:`tip_path` analyse a recorded stream.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from helpers.board.stream_reference import STEPS_PER_S_PER_UNIT
from helpers.paper import metrics
from helpers.paper.modes import omega_n_from_damped
from helpers.paper.shapers import Shaper, design_tdfs
from helpers.research.families import FAMILIES
from helpers.research.modemap import ModeMap
from helpers.rig.stream import stream
from helpers.rigfile import derived
from helpers.virtual import RigParameters, simulate

PERIOD_S = 0.01
"""The stream's control period, s (100 Hz)."""



def _shaper_at(mode_map: ModeMap, x_mm: float, family: str) -> Shaper:
    point = mode_map.at(min(max(x_mm, mode_map.range_mm[0]), mode_map.range_mm[1]))
    return FAMILIES[family](omega_n_from_damped(float(point.omega_d), float(point.zeta)), float(point.zeta))


def schedule_setpoints(
    setpoints_mm_s: np.ndarray,
    mode_map: ModeMap,
    family: str = "ZV",
    start_mm: float = 0.0,
    period_s: float = PERIOD_S,
    *,
    mm_per_step: float,
) -> np.ndarray:
    """Shape a velocity stream on the host with a shaper designed for the configuration of each set-point.

    Parameters
    ----------
    setpoints_mm_s : numpy.ndarray
        Cable speed per period, mm/s.
    mode_map : helpers.research.modemap.ModeMap
        The measured map (positions outside it use its end values).
    family : str
        A family of :data:`helpers.research.families.FAMILIES` with positive impulses (``"ZV"``, ``"ZVD"``,
        ...).
    start_mm : float
        Cable position at the first set-point, mm.
    period_s : float
        The stream's period, s.
    mm_per_step : float
        The rig's cable per step (the board's set-point unit follows from it).

    Returns
    -------
    numpy.ndarray
        The shaped set-points (longer by the longest shaper's duration), mm/s, in whole board units
        (:func:`on_board_units`); their sum equals the command's, so the cable ends where the command does.
    """
    v = np.asarray(setpoints_mm_s, dtype=float)
    if v.ndim != 1 or not np.all(np.isfinite(v)):
        raise ValueError("set-points must be a finite 1-D array of mm/s")
    if family not in FAMILIES:
        raise ValueError(f"unknown shaper family {family!r}; one of {', '.join(FAMILIES)}")
    position = start_mm + np.concatenate([[0.0], np.cumsum(v[:-1]) * period_s])
    cache: dict[float, Shaper] = {}
    spreads = []
    for k in np.flatnonzero(v):
        key = round(float(position[k]), 1)  # one design per 0.1 mm of cable
        shaper = cache.get(key) or cache.setdefault(key, _shaper_at(mode_map, key, family))
        if np.any(shaper.amplitudes < 0):
            raise ValueError(f"family {family!r} has negative impulses; use one with positive impulses")
        spreads.append((k, shaper))
    longest = max((s.duration for _, s in spreads), default=0.0)
    out = np.zeros(v.size + int(math.ceil(longest / period_s)) + 2)
    for k, shaper in spreads:
        for a, t in zip(shaper.amplitudes, shaper.times, strict=True):
            j, frac = divmod(t / period_s, 1.0)
            out[k + int(j)] += a * (1.0 - frac) * v[k]
            out[k + int(j) + 1] += a * frac * v[k]
    return on_board_units(np.trim_zeros(out, "b"), mm_per_step)


def on_board_units(setpoints_mm_s: np.ndarray, mm_per_step: float) -> np.ndarray:
    """The set-points as the board will hold them, with their sum kept exact.

    The board rounds every set-point to its unit (2^-16 step per 16 us, 0.2434 mm/s): rounded one by one,
    a stream meant to come back to where it started may end a fraction of a step off, and a stream that ends
    at the travel limit 0 would then be clamped there. This rounds the running sum instead (error diffusion):
    every set-point stays within one unit of its value and the displacement is exactly the command's, to the
    unit.

    ``mm_per_step`` is the rig's cable per step: the unit is ``STEPS_PER_S_PER_UNIT`` steps/s.

    Returns
    -------
    numpy.ndarray
        mm/s values that are whole board units.
    """
    unit = mm_per_step * STEPS_PER_S_PER_UNIT
    total = np.rint(np.cumsum(np.asarray(setpoints_mm_s, dtype=float) / unit))
    return np.diff(total, prepend=0.0) * unit


def teleop_command(
    mm_per_step: float,
    seed: int = 0,
    n_moves: int = 6,
    low_mm: float = 3.0,
    high_mm: float = 32.0,
    max_speed_mm_s: float = 150.0,
    stop_s: float = 2.0,
    period_s: float = PERIOD_S,
) -> np.ndarray:
    """A teleoperation-like velocity command: band-limited moves between random positions, with stops.

    Each move goes to a random position in ``[low_mm, high_mm]`` with a smooth speed profile (a Hann window:
    band-limited, no overshoot below zero speed, as from a hand on a joystick) of random peak up to
    ``max_speed_mm_s``, then stops for ``stop_s``. The first move starts from 0 and the command ends at
    :data:`END_MM` (see :func:`pick_and_place`). ``mm_per_step`` is the rig's (:func:`on_board_units`).

    Returns
    -------
    numpy.ndarray
        Cable speed per period, mm/s.
    """
    rng = np.random.default_rng(seed)
    parts = [np.zeros(round(0.5 / period_s))]
    here = 0.0
    targets = [*rng.uniform(low_mm, high_mm, n_moves), 0.0]
    for target in targets:
        distance = target - here
        peak = rng.uniform(0.5, 1.0) * max_speed_mm_s
        duration = max(2.0 * abs(distance) / peak, 0.1)
        n = max(round(duration / period_s), 4)
        move = np.hanning(n + 2)[1:-1]
        move *= distance / (move.sum() * period_s)
        parts += [move, np.zeros(round(stop_s / period_s))]
        here = target
    return on_board_units(np.concatenate(parts), mm_per_step)


def pick_and_place(
    mm_per_step: float, speed_mm_s: float = 200.0, hold_s: float = 2.0, period_s: float = PERIOD_S
) -> np.ndarray:
    """A scripted pick-and-place: 0 -> 25 -> 10 -> 30 -> 0 mm at constant speed, holding at each.

    ``mm_per_step`` is the rig's (:func:`on_board_units`).

    Returns
    -------
    numpy.ndarray
        Cable speed per period, mm/s (each move rounded to whole periods, its speed adjusted to arrive).
    """
    parts = [np.zeros(round(0.5 / period_s))]
    here = 0.0
    for target in (25.0, 10.0, 30.0, 0.0):
        distance = target - here
        n = max(round(abs(distance) / speed_mm_s / period_s), 1)
        parts += [np.full(n, distance / (n * period_s)), np.zeros(round(hold_s / period_s))]
        here = target
    return on_board_units(np.concatenate(parts), mm_per_step)


def stops(frame: pd.DataFrame, min_stop_s: float = 1.2) -> list[tuple[float, float, float]]:
    """The moves of a recorded stream and the stops after them, from the step count.

    Returns
    -------
    list of (float, float, float)
        ``(move start, move end, stop end)`` in s of the recording's clock: a move is a stretch where the
        step count changes with gaps shorter than 0.1 s; its stop lasts until the next move (or the end) and
        at least ``min_stop_s``.
    """
    t = frame["t_s"].to_numpy()
    changes = np.flatnonzero(np.diff(frame["steps"].to_numpy()) != 0) + 1
    if changes.size == 0:
        return []
    out = []
    start = prev = t[changes[0]]
    for i in changes[1:]:
        if t[i] - prev > 0.1:
            out.append((start, prev, t[i]))
            start = t[i]
        prev = t[i]
    out.append((start, prev, t[-1]))
    return [m for m in out if m[2] - m[1] >= min_stop_s]


def stop_residuals(frame: pd.DataFrame, column: str = "tension_n") -> pd.DataFrame:
    """Residual vibration after each stop of a recorded stream (:func:`~metrics.residual_vibration`).

    The step of a move is the tension's change from the 0.2 s before it to the mean of its residual window.

    Returns
    -------
    pandas.DataFrame
        One row per stop: ``move_start_s``, ``move_end_s``, ``position_mm``, ``step_n``, ``residual_pct``.
    """
    t = frame["t_s"].to_numpy()
    y = frame[column].to_numpy(dtype=float)
    cable = frame["cable_mm"].to_numpy()
    rows = []
    for start, end, _stop_end in stops(frame):
        before = (t >= start - 0.2) & (t < start)
        lo = end + metrics.RESIDUAL_START_S
        window = (t >= lo) & (t <= lo + metrics.RESIDUAL_LENGTH_S)
        if not (before.any() and window.any()):
            continue
        y0, yf = float(y[before].mean()), float(y[window].mean())
        rows.append({
            "move_start_s": float(start), "move_end_s": float(end),
            "position_mm": float(cable[np.searchsorted(t, end)]), "step_n": yf - y0,
            "residual_pct": metrics.residual_vibration(t, y, end, y0, yf),
        })  # fmt: skip
    return pd.DataFrame(rows)


def tracking_delay(
    frame: pd.DataFrame, setpoints_mm_s: np.ndarray, t_stream_s: float, period_s: float = PERIOD_S
) -> float:
    """The delay of the cable behind the command, s: the lag that best aligns the two positions.

    Parameters
    ----------
    frame : pandas.DataFrame
        The recording (``t_s``, ``cable_mm``).
    setpoints_mm_s : numpy.ndarray
        The command (before any shaping).
    t_stream_s : float
        When the board took the first set-point, on the recording's clock.
    period_s : float
        The stream's period.

    Returns
    -------
    float
        The lag (s, resolution 1 ms) minimising the mean square difference between the cable position and the
        commanded position delayed by it.
    """
    t = frame["t_s"].to_numpy()
    cable = frame["cable_mm"].to_numpy(dtype=float)
    command_t = t_stream_s + np.arange(setpoints_mm_s.size + 1) * period_s
    command_x = np.concatenate([[0.0], np.cumsum(setpoints_mm_s) * period_s])
    lags = np.arange(0.0, 0.6, 0.001)
    errors = [np.mean((cable - np.interp(t - lag, command_t, command_x)) ** 2) for lag in lags]
    return float(lags[int(np.argmin(errors))])


def tip_path(frame: pd.DataFrame, params: RigParameters | None = None, rate_hz: float = 100.0) -> Any:
    """The arm's tip over a recorded run, from the virtual rig driven by the recorded step times.

    The step times are those the DAQ saw (to its sample), so this is the virtual rig's answer to the
    recorded motion: for hardware recordings, a model of what the tip did, not a measurement.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        Time (s), tip x and tip y (mm).
    """
    t = frame["t_s"].to_numpy()
    steps = frame["steps"].to_numpy()
    idx = np.flatnonzero(np.diff(steps) != 0) + 1
    times, signs = [], []
    for i in idx:
        n = int(steps[i] - steps[i - 1])
        times += [t[i] - t[0]] * abs(n)
        signs += [int(np.sign(n))] * abs(n)
    run = simulate((np.array(times), np.array(signs)), rate_hz=rate_hz, params=params, t_end=t[-1] - t[0],
                   seed=0)  # fmt: skip
    x, y = run.tip()
    return run.t + t[0], 1e3 * x, 1e3 * y


COMMANDS = {
    "teleop": lambda mm_per_step: teleop_command(mm_per_step, seed=3),
    "pick_and_place": pick_and_place,
}
"""The two commands of notebook 08, by name: each takes the rig's cable per step."""
SYSTEMS = ("unshaped", "zv", "zvd", "scheduled")
"""How each command is run: unshaped, the paper's non-robust (zv) and robust (zvd) TDFs loaded into the board,
and the ZV scheduled on the configuration by the host (the board holding the unit shaper)."""


def record_streams(
    rig: Any,
    folder: Any,
    mode_map: ModeMap,
    rest_mode: tuple[float, float],
    *,
    replace: bool = False,
    seeds: Any = lambda: None,
    rate_hz: int = 1000,
) -> list[Any]:
    """Record every command of :data:`COMMANDS` with every system of :data:`SYSTEMS` as a stream of ``rig``.

    Parameters
    ----------
    rig : helpers.rig.Rig
        A connected rig (cable at 0).
    folder : path-like
        Where the recordings go (``<command>_<system>``).
    mode_map : helpers.research.modemap.ModeMap
        The measured map, for the scheduled shaper.
    rest_mode : (float, float)
        ``(omega_d, zeta)`` identified at rest, for the paper's two TDFs.
    replace : bool
        Replace recordings of the same names.
    seeds : callable
        The noise seed of the next run (in-process virtual rig), or None.
    rate_hz : int
        DAQ rate.

    Returns
    -------
    list of helpers.recordings.Recording
    """
    from_rest = dict(zip(("zv", "zvd"), design_tdfs(*rest_mode), strict=True))
    mm = derived(rig.rig).mm_per_step[0]
    out = []
    for command, make in COMMANDS.items():
        v = make(mm)
        runs = {
            "unshaped": (v, None, "the command"),
            "zv": (v, from_rest["zv"], "the command; the board's shaper: the paper's non-robust TDF"),
            "zvd": (v, from_rest["zvd"], "the command; the board's shaper: the paper's robust TDF"),
            "scheduled": (schedule_setpoints(v, mode_map, "ZV", mm_per_step=mm), None,
                          "the command shaped on the host by ZV scheduled on the measured map"),
        }  # fmt: skip
        for system in SYSTEMS:
            setpoints, shaper, what = runs[system]
            scenario = {"kind": "stream", "system": system, "command": command, "setpoints_are": what,
                        "command_setpoints_mm_s": [float(x) for x in v]}  # fmt: skip
            path = Path(folder) / f"{command}_{system}"
            rec = stream(rig, setpoints, shaper, path=path, scenario=scenario, tail_s=2.0, rate_hz=rate_hz,
                         replace=replace, noise_seed=seeds(), progress=False)  # fmt: skip
            out.append(rec)
    return out
