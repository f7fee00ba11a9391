"""The one driver of a rig's two boards, for 1 to 4 tendons: :class:`Rig`, one board-timed run per call.

``Rig(ports, rig)`` opens the DAQ and the stepper board (``"virtual"``: the in-process virtual rig of the rig
file; ``"auto"``: the boards found by USB id; ``"DAQ,STEPPER"``: device paths or pyserial URLs), waits for
each, and checks that both were built for the rig file (its hash in ``HELLO``/``PONG``) and, by ``CONFIG``,
for its tendons: at least as many load-cell channels and step counters, every tendon's travel, its release
below position 0 exactly. A board built for another rig or tendon count: one line, :class:`WrongRig`, and
nothing else is sent.

:meth:`Rig.run` runs one :class:`~helpers.board.programmes.Programme` (``SEG``/``MSEG``/``WAIT``) as one
experiment: the programme is checked against every tendon's limits from where the stepper says the tendons
are (:func:`~helpers.rig.safety.check_programme`: nothing is sent if it fails), the tension of every channel
must come to rest, the programme is loaded, the DAQ started, the driver enabled and ``GO`` sent; then the
DAQ's samples are read until the programme's end (plus a tail) has passed on the DAQ's own clock and ``DONE``
has come. Nothing is timed with sleeps or from the programme's duration in wall time: ``DONE`` is awaited in
*device time*; when it is :data:`DONE_GRACE_S` late there, ``POS`` is asked (a ``DONE`` lost on the link, or a
stepper running late, is not a dead board), and a board is declared gone only when it has sent nothing for
the stated silence interval (:data:`SILENCE_S`: no sample from the DAQ, no reply from the stepper).
:meth:`Rig.run_pulse` runs the paper's pulse from position 0. Streams are :func:`helpers.rig.stream.stream`'s.

A run of several tendons is given its guard (``run(..., guard=...)``, a
:class:`helpers.rig.trim.TensionGuard`): what may trim every tendon by whole steps to its target tension
measured at rest before the programme, and what watches the floor on every parsed sample during it (a tendon
below ``[arm] tension_floor_n`` for longer than ``[arm] floor_watch_ms`` of device time stops it, saved
``aborted``). Neither is for one tendon, whose run is the paper's (``docs/safety.md``); the driver only calls
them, so the paper's path does not hold them.

Every run sits in one guard (:meth:`Rig._guarded`): on any exception (``KeyboardInterrupt``, and
SIGTERM/SIGHUP turned into one by :mod:`helpers.base.signals`, a board that hangs, resets or disconnects) the
stepper is sent ``ABORT`` and ``EN 0`` and the DAQ ``STOP``, and what was recorded is saved marked
``aborted`` under a name of its own (``<name>_aborted_<UTC>``) with the reason; the exception goes on carrying
``recording``, ``saved_path`` (None, with ``save_error``, if the save failed) and ``cleanup`` (the problems
the cleanup met: empty when it reached both boards). A signal that comes once every sample is in saves the
run whole. A run never overwrites a recording unless asked (``replace=True``).
"""

from __future__ import annotations

import os
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Self

import numpy as np

try:  # a progress bar where tqdm is installed (the [virtual] extra); the paper's part runs without it
    from tqdm.auto import tqdm
except ImportError:  # pragma: no cover - the light environment
    tqdm = None

from helpers import recordings
from helpers.base.noise import white_noise_std
from helpers.base.signals import Interrupted, run_guard
from helpers.board.programmes import Programme, experiment_programme
from helpers.board.protocol import StreamParser
from helpers.paper import numbers as paper
from helpers.paper.tension import LoadCellCalibration, load_calibration
from helpers.recordings import Recording, RecordingError
from helpers.recordings.shaping import pulse_metadata
from helpers.rig.link import (
    BOOT_TIMEOUT_S,
    BoardError,
    BoardTimeout,
    CommandRefused,
    Link,
    Waiter,
    WrongRig,
    ints,
    rebuild_hint,
)  # fmt: skip
from helpers.rig.ports import rig_urls, virtual_source_for
from helpers.rig.safety import SafetyError, check_programme, check_request
from helpers.rigfile import RigFile, derived

REST_WINDOW_S = 0.5
"""Span (s) over which the tension must be steady before a run."""

REST_FACTOR = 2.0
"""Steady: standard deviation over the window <= this factor x the white-noise level (and >= 0.5 count)."""

REST_TIMEOUT_S = 30.0
"""Longest wait (device s) for the tension to come to rest."""

SILENCE_S = 2.0
"""A board that has sent nothing for this long (s; device time on the in-process virtual rig) is gone."""

DONE_GRACE_S = 1.0
"""Device time (s, the DAQ's clock) after the programme's end before ``POS`` asks where a quiet stepper is."""

GO_LATENCY_US = 50_000
"""How much earlier than the host's estimate ``GO`` may have happened on the DAQ's clock (the estimate is the
newest sample at hand once ``GO`` is acknowledged: never early, a few ms late over USB)."""

MAX_CORRUPTED_FRACTION = 0.05
"""A run stops when more than this fraction of the lines (and more than 50) came corrupted."""

class NotAtRest(BoardError):
    """The tension did not settle before a run (the arm still moves, or the sensor drifts)."""


class RunAborted(BoardError):
    """The run was stopped because its data were unusable (e.g. mostly corrupted lines)."""


class NotAtZero(SafetyError):
    """A pulse experiment was asked for while the cable is not at position 0."""


def rest_of(adc: Any, rate_hz: int) -> tuple[bool, float, float]:
    """(steady?, std, noise) of the last :data:`REST_WINDOW_S` of ``adc`` (rows of every channel's counts).

    Steady when every channel is; the std and noise are those of the channel farthest from it. Not steady
    while the window is shorter.
    """
    n = max(3, round(REST_WINDOW_S * rate_hz))
    a = np.asarray(adc, dtype=float).reshape(len(adc), -1)
    if len(a) < n:
        return False, float("nan"), float("nan")
    window = a[-n:]
    stds = window.std(axis=0)
    noises = np.array([white_noise_std(window[:, c]) for c in range(window.shape[1])])
    limit = np.maximum(REST_FACTOR * noises, 0.5)
    worst = int(np.argmax(stds / limit))
    return bool(stds[worst] <= limit[worst]), float(stds[worst]), float(noises[worst])


def step_windows(programme: Programme, axes: int, slack_us: int = 2_000) -> list[tuple[Any, Any]]:
    """Every axis's device-time windows (us from ``GO``) in which ``programme`` steps it.

    An item's steps of an axis fall in ``[t0 + W / n, t0 + W]``; the window opens :data:`GO_LATENCY_US`
    earlier (``GO`` may precede its estimate) and closes ``slack_us`` later. A step count that changes
    outside every window is impossible, and the DAQ's parser rejects it.
    """
    out = []
    for a in range(axes):
        starts: list[float] = []
        ends: list[float] = []
        for t0, item in zip(programme.item_starts_us(), programme.items, strict=True):
            n = abs(item.counts(axes)[a])
            if n:
                lo, hi = t0 + item.duration_us / n - GO_LATENCY_US, t0 + item.duration_us + slack_us
                if ends and lo <= ends[-1]:
                    ends[-1] = max(ends[-1], hi)
                else:
                    starts.append(lo)
                    ends.append(hi)
        out.append((np.array(starts, dtype=np.int64), np.array(ends, dtype=np.int64)))
    return out


def _bar(total_s: float | None, show: bool) -> Any:
    """A tqdm bar of device seconds (its ``n``: the seconds shown), or None where tqdm is not installed."""
    fmt = "{l_bar}{bar}| {n:.1f}/{total:.1f} s" if total_s is not None else "{desc}: {n:.1f} s"
    total = None if total_s is None else round(total_s, 1)
    return tqdm(total=total, unit="s", desc="device time", bar_format=fmt) if tqdm and show else None


@dataclass
class RunState:
    """What a run knows about itself besides its samples (the DAQ link's ``rows`` since its ``START``)."""

    start: tuple[int, ...] = ()
    """Every tendon's position when the run started (the DAQ counts steps from there)."""
    started_utc: str = field(default_factory=lambda: time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()))
    """When the run started, UTC to the second (e.g. ``2026-01-02T03:04:05Z``)."""
    t_go_us: int | None = None
    windows: list[tuple[np.ndarray, np.ndarray]] | None = None
    """The programme's step windows relative to ``GO`` (:func:`step_windows`)."""
    finished: bool = False
    """Every sample of the run is in: an interrupt from now on cannot make it partial."""
    deviation: str | None = None
    """Why the motion differed from its command (a stream's underruns, clamps), or None."""
    watch: Any = None
    """What checks every parsed sample (``catch_up(rows)``, ``t0_us`` set at ``GO``; the guard's), or None."""


class Rig:
    """Both boards of one rig (hardware or virtual, 1 to 4 tendons) and the calibration it records with.

    Parameters
    ----------
    ports : str or (str, str)
        ``"virtual"``, ``"auto"``, ``"DAQ,STEPPER"`` or a pair (:func:`helpers.rig.ports.rig_urls`).
    rig : RigFile
        The rig file (:func:`helpers.rigfile.load`): its tendons, limits and boards' builds.
    calibration : LoadCellCalibration, dict or sequence of them, optional
        One per tendon. Default: one tendon, :func:`helpers.paper.tension.load_calibration` (a clear error if
        there is none yet); several, the rig file's nominal load-cell chain.
    world : str, optional
        The in-process virtual rig's name (default the rig file's name).
    timeout, hello_timeout, silence_s : float
        Seconds a command may take, a board may take to boot, a board may stay silent during a run.
    daq_options, stepper_options : str
        Extra ``&key=value`` URL options for the virtual boards (faults, seed).
    """

    def __init__(
        self, ports: Any, rig: RigFile, calibration: Any = None, *, world: str | None = None,
        timeout: float = 2.0, hello_timeout: float = BOOT_TIMEOUT_S, silence_s: float = SILENCE_S,
        daq_options: str = "", stepper_options: str = "",
    ) -> None:  # fmt: skip
        if not isinstance(rig, RigFile):
            raise ValueError(f"rig must be a rig file loaded by helpers.rigfile.load, got {rig!r}")
        self.rig, self.n, self.silence_s = rig, rig.n_tendons, silence_s
        self.rest_window: list[Any] = []
        """The counts of the last :meth:`wait_for_rest`'s window, one row per sample."""
        self.calibration = self._calibrations(calibration)
        urls = rig_urls(ports, rig, world or rig.name, (daq_options, stepper_options))
        self.daq = Link.open(urls[0], "daq", rig, rig.hardware.daq_baud, timeout, hello_timeout)
        try:
            self.stepper = Link.open(urls[1], "stepper", rig, rig.hardware.stepper_baud, timeout,
                                     hello_timeout)  # fmt: skip
            self._check_builds()
        except BaseException:
            self.close()
            raise
        world_ = self.world
        if world_ is not None:
            self.source = {"kind": "virtual-rig", "via": "in-process", "rig": world_.name, **world_.info}
        else:
            self.source = virtual_source_for(urls) or {"kind": "hardware"}
        if any(isinstance(v, dict | list) for v in self.source.get("parameters", {}).values()):
            del self.source["parameters"]  # the spatial twin's: nested; they follow from `rig`
        self.source["ports"] = {"daq": urls[0].split("?")[0], "stepper": urls[1].split("?")[0]}
        if self.source["kind"] == "hardware" and any(c.source == "virtual-rig" for c in self.calibration):
            warnings.warn(  # the raw ADC counts are recorded either way, so tension can be recomputed
                "this is hardware, but the load-cell calibration was recorded on the virtual rig: tension_n "
                "will be wrong; calibrate this load cell first (python -m helpers record calibration)",
                UserWarning, stacklevel=2,
            )  # fmt: skip

    def _calibrations(self, calibration: Any) -> tuple[LoadCellCalibration, ...]:
        if calibration is None and self.n == 1:
            calibration = load_calibration()
        if calibration is None:
            calibration = recordings.nominal_calibration(self.rig)
        cals = list(calibration) if isinstance(calibration, list | tuple) else [calibration]
        cals = [LoadCellCalibration.from_dict(c) if isinstance(c, dict) else c for c in cals]
        if len(cals) != self.n:
            raise ValueError(f"{len(cals)} load-cell calibration(s) for the rig's {self.n} tendon(s)")
        return tuple(cals)

    def _check_builds(self) -> None:
        """``CONFIG`` of both boards against the rig file's tendons (firmware 2.1 has none: one of each)."""
        n, d, name = self.n, derived(self.rig), self.rig.name
        channels, axes = self._config(self.daq, (1, 1))[:2]
        if (channels, axes) != (n, n):
            raise WrongRig(
                f"the daq board was built for {channels} load cell(s) and {axes} step counter(s), but rig "
                f"'{name}' has {n} tendon(s): " + rebuild_hint(self.rig, "daq")
            )
        self.daq.parser = StreamParser(n, n, self.rig.hardware.step_rate_cap_hz, d.adc_max)
        values = self._config(self.stepper, (1, 0, 0, 0, d.travel_steps[0]))
        built = values[4 : 4 + n], values[4 + n :] or (0,) * n  # every axis's travel and release
        if values[0] != n or len(values) not in (4 + n, 4 + 2 * n):
            got = f"{values[0]} axis/axes" if values[0] != n else f"CONFIG {values}"
            raise WrongRig(f"the stepper board was built for {got}, but rig '{name}' has {n} tendon(s): "
                           + rebuild_hint(self.rig, "stepper"))  # fmt: skip
        for i in range(n):
            if built[0][i] < d.travel_steps[i] or built[1][i] != d.release_steps[i]:
                raise WrongRig(
                    f"the stepper board's axis {i} travels -{built[1][i]}..{built[0][i]} steps, but rig "
                    f"'{name}' gives tendon {i + 1} -{d.release_steps[i]}..{d.travel_steps[i]} (release_mm, "
                    "travel_mm): " + rebuild_hint(self.rig, "stepper")
                )

    @staticmethod
    def _config(board: Link, before: tuple[int, ...]) -> tuple[int, ...]:
        """A board's ``CONFIG`` numbers; ``before`` for firmware before 2.2, which has no ``CONFIG``."""
        try:
            return ints(board.command("CONFIG"))
        except CommandRefused:
            return before

    def close(self) -> None:
        """Close both ports."""
        self.daq.close()
        if hasattr(self, "stepper"):
            self.stepper.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def world(self) -> Any:
        """The in-process virtual rig's world (its calibration fixture, its noise seed), or None."""
        return getattr(self.daq.port, "world", None)

    def positions(self) -> tuple[int, ...]:
        """``POS``: every tendon's position (steps from zero), as the stepper board says."""
        self.stepper.check_reset()
        self.daq.check_reset()
        return ints(self.stepper.command("POS", timeout=self.silence_s))[: self.n]

    # --- running -------------------------------------------------------------------------------------
    def run_pulse(
        self, v_in_mm_s: float, x_f_mm: float, shaper: Any = None, system: str | None = None, *,
        path: str | os.PathLike, repetition: int = 1, t_end_s: float = 12.0,
        scenario_extra: dict[str, Any] | None = None, **options: Any,
    ) -> Recording:  # fmt: skip
        """Run the paper's pulse on tendon 1 (up at 1 s, down at 8 s after ``GO``) from position 0.

        Parameters
        ----------
        v_in_mm_s, x_f_mm : float
            Speed (mm/s) and displacement (mm): refused with :class:`SafetyError` outside the limits.
        shaper : Shaper or ShapesMoves, optional
            None for the unshaped pulse; anything :func:`~helpers.board.programmes.experiment_programme`
            takes.
        system : str, optional
            Its name in :data:`helpers.recordings.shaping.SYSTEMS` (default: the shaper's).
        path : path-like
            ``data/<group>/<name>``; an existing recording is refused before anything moves.
        repetition : int
            Repetition number written into the scenario.
        t_end_s : float
            Programme (and recording) length, s after ``GO``.
        scenario_extra : dict, optional
            More scenario metadata (e.g. the mode the shaper was designed from).
        **options
            :meth:`run`'s (``rate_hz``, ``progress``, ``replace``, ``noise_seed``).
        """
        v, x = check_request(v_in_mm_s, x_f_mm, self.rig)
        try:  # the up and down moves at experiment_programme's default times, the paper's
            programme, report = experiment_programme(v, x, shaper, t_end=t_end_s, rig=self.rig)
        except ValueError as exc:
            raise SafetyError(f"pulse {v} mm/s, {x} mm refused: {exc}") from None
        scenario = {
            "kind": "pulse", "v_in_mm_s": v, "x_f_mm": x, **pulse_metadata(shaper, system),
            "repetition": int(repetition), "t_up_s": paper.PULSE_T_UP_S, "t_down_s": paper.PULSE_T_DOWN_S,
            "quantisation": report.to_dict(), **(scenario_extra or {}),
        }  # fmt: skip
        return self.run(programme, path=path, scenario=scenario, from_zero=True, **options)

    def run(
        self, programme: Programme, *, path: str | os.PathLike, scenario: dict[str, Any] | None = None,
        rate_hz: int = 1000, tail_s: float = 0.1, progress: bool = True, replace: bool = False,
        noise_seed: int | None = None, from_zero: bool = False, guard: Any = None,
    ) -> Recording:  # fmt: skip
        """Run one programme as one board-timed experiment of every tendon; return (and save) its recording.

        Parameters
        ----------
        programme : helpers.board.programmes.Programme
            Checked against every tendon's limits from where they are before anything is sent.
        path : path-like
            ``data/<group>/<name>``; an existing recording is refused before anything moves.
        scenario : dict, optional
            Scenario metadata; the programme is added.
        rate_hz : int
            DAQ sample rate.
        tail_s : float
            Device time recorded after the programme's end.
        progress : bool
            Show a bar of device time (where tqdm is installed).
        replace : bool
            Replace a recording of the same name (kept until the new one is complete).
        noise_seed : int, optional
            In-process virtual rig: re-seed the sensor noise for this run (recorded in the scenario).
        from_zero : bool
            Refuse (:class:`NotAtZero`) unless every tendon is at position 0 (the paper's experiments).
        guard : helpers.rig.trim.TensionGuard, optional
            Several tendons (and needed for them): ``guard.before(rig, scenario, rate_hz)`` after the rest
            (the trim: True if it moved the tendons, the programme then checked again from there) and
            ``guard.watcher(rig, rate_hz)`` (the floor watch, or None). ``TensionGuard(watch=False)`` runs
            without either. None for one tendon: the paper's run.
        """
        self._check_run(rate_hz, noise_seed, tail_s)
        if guard is None and self.n > 1:
            raise ValueError(f"a run of {self.n} tendons needs its guard: guard=helpers.rig.trim"
                             ".TensionGuard() watches the floor (TensionGuard(watch=False): none)")
        check_programme(programme, self.rig, (0,) * self.n)  # before a byte: as far as it can be
        scenario = {"kind": "programme", **(scenario or {})}
        scenario.setdefault("programme", programme.to_dict())
        with recordings.reserve(path, replace) as target:  # a second run to this name is refused now
            start = self.positions()
            check_programme(programme, self.rig, start)
            if from_zero and any(start):
                ports = self.source["ports"]
                home = ("helpers.commands.home.home(rig.stepper, rig.rig) (the in-process rig lives here)"
                        if ports["daq"].startswith("virtual://") else
                        f"`python -m helpers home --ports {ports['daq']},{ports['stepper']}`")  # fmt: skip
                raise NotAtZero(
                    f"the cable is at {start} steps, not at 0 (the paper's experiments start from the down "
                    f"position): run {home} first"
                )
            self._note_start(scenario, start, noise_seed)
            cum = programme.positions(0, self.n)  # steps from where the run starts (the DAQ's ZERO)

            def body(state: RunState) -> None:
                if guard is not None and guard.before(self, scenario, rate_hz):  # the trim moved them
                    state.start = self.positions()
                    check_programme(programme, self.rig, state.start)  # from where the trim left it
                    self._note_start(scenario, state.start, None)
                end = tuple(int(p) for p in programme.positions(state.start, self.n)[-1])  # every tendon's
                scenario["rest"] = self.wait_for_rest(rate_hz)
                self.stepper.command("ABORT")  # a programme or stream an earlier session left running stops
                self.daq.command("STOP")  # a stream left running by an earlier session stops
                replies = self.stepper.send_all(programme.commands(self.n))  # CLEAR first
                if ints(replies[-1])[-1] != len(programme):
                    raise BoardError(f"the stepper board holds {replies[-1]}, not {len(programme)} items")
                state.windows = step_windows(programme, self.n)
                state.watch = None if guard is None else guard.watcher(self, rate_hz)
                self._start(rate_hz, list(zip(cum.min(axis=0), cum.max(axis=0), strict=True)))
                self.stepper.command("EN 1")
                self._go(state, "GO")
                done, total = (programme.duration_us, end), programme.duration_s + tail_s
                self._until_done(state, lambda now: done, rate_hz, tail_s, total, progress)
                self._finish(state)

            return self._guarded(body, scenario, target, rate_hz, replace, start)

    def _check_run(self, rate_hz: Any, noise_seed: Any, tail_s: Any) -> None:
        """Refuse a rate, a seed or a tail the run cannot take (``SafetyError``) before anything is sent."""
        hw = self.rig.hardware
        if type(rate_hz) is not int or not hw.daq_rate_min_hz <= rate_hz <= hw.daq_rate_max_hz:
            raise SafetyError(
            f"DAQ rate must be an integer in {hw.daq_rate_min_hz}-{hw.daq_rate_max_hz} Hz, got {rate_hz!r}"
            )
        if noise_seed is not None and not (type(noise_seed) is int and 0 <= noise_seed < 2**32):
            raise SafetyError(f"noise seed must be an integer in 0..2**32-1, got {noise_seed!r}")
        if type(tail_s) not in (int, float) or not 0 <= tail_s <= 60:
            raise ValueError(f"tail_s must be a number of seconds in 0-60, got {tail_s!r}")

    def _note_start(self, scenario: dict[str, Any], start: tuple[int, ...], noise_seed: int | None) -> None:
        """The start positions, and (in-process virtual rig) the noise re-seeded for this run, noted."""
        scenario["start_position_steps"] = start[0]
        if self.n > 1:
            scenario["start_positions_steps"] = list(start)
        if noise_seed is not None and self.world is not None:
            self.world.reseed(noise_seed)
            scenario["noise_seed"] = noise_seed

    def wait_for_rest(self, rate_hz: int = 1000) -> dict[str, Any]:
        """Stream until every channel's tension is steady (:func:`rest_of`); :class:`NotAtRest` if it is not.

        :class:`NotAtRest` comes after :data:`REST_TIMEOUT_S` of device time.

        The noise is the white-noise level of the same window (:func:`helpers.base.noise.white_noise_std`), so
        a ringing arm or a drifting amplifier keeps the wait going while sensor noise alone does not.

        Returns
        -------
        dict
            ``waited_s`` (device s), ``std_counts``, ``noise_counts`` of the last window, whose counts (every
            channel's) stay in :attr:`rest_window` (what :func:`helpers.rig.trim.rest_tensions` measures).
        """
        self.daq.check_reset()
        self.daq.command("STOP")
        self._start(rate_hz, None, zero=False)
        c, n, period = self.daq.parser.channels, max(3, round(REST_WINDOW_S * rate_hz)), round(1e6 / rate_hz)
        rest: dict[str, Any] = {}

        def steady(now: int) -> tuple[int, tuple[int, ...]] | None:  # read on: None; at rest: the end, now
            last = [r[2 : 2 + c] for r in self.daq.rows[-n:]]
            ok, std, noise = rest_of(last, rate_hz)
            waited = (now - period) / 1e6  # from the first sample (the reader starts a period before it)
            if ok:
                rest.update(waited_s=round(waited, 3), std_counts=std, noise_counts=noise)
                self.rest_window = last
                return now, ()
            if waited > REST_TIMEOUT_S:
                raise NotAtRest(
                    f"the tension did not come to rest within {REST_TIMEOUT_S:.0f} s (std {std:.2f} "
                    f"counts over {REST_WINDOW_S} s against a noise of {noise:.2f} counts): is the arm "
                    "moving?"
                )
            return None

        try:  # the one reader of a run's samples, the stepper neither read nor awaited
            self._until_done(RunState(), steady, rate_hz, 0.0, None, False, stepper=False)
        finally:
            self.daq.command("STOP")
            self.daq.rows.clear()
        return rest

    def _start(self, rate_hz: int, reach: list[tuple[int, int]] | None, zero: bool = True) -> None:
        """``RATE``, ``ZERO`` (if ``zero``), ``START`` the DAQ; a sample outside ``reach`` is refused.

        ``reach``: every axis's lowest and highest step count from ``ZERO`` the run can make (None: no check).
        """
        self.daq.command(f"RATE {rate_hz}")
        if zero:
            self.daq.command("ZERO")
        self.daq.rows.clear()
        self.daq.parser.restart()
        self.daq.command("START")
        self.daq.parser.steps_range = reach

    def _go(self, state: RunState, command: str) -> None:
        """Send ``GO`` or ``STREAM``; its device time: the newest sample at hand once it is acknowledged."""
        self.stepper.done, self.stepper.notices = None, []
        self.stepper.command(command)
        self.daq.read(block=False)
        if self.daq.rows:
            self._went(state, self.daq.rows[-1][1])

    def _went(self, state: RunState, t_go_us: int) -> None:
        """Note GO's device time; from then on a count changing between the programme's steps is refused."""
        state.t_go_us = t_go_us
        if state.watch is not None:
            state.watch.t0_us = t_go_us
        if state.windows is not None:
            self.daq.parser.step_windows = [(s + t_go_us, e + t_go_us) for s, e in state.windows]

    def _read(self, silence: Waiter, stepper: bool = True) -> tuple[int, Waiter]:
        """Read both boards once; the new samples and the silence timer.

        Raises :class:`~helpers.rig.BoardReset` if a board rebooted, :class:`~helpers.rig.BoardTimeout` after
        the silence interval without a sample, :class:`RunAborted` if corrupted lines dominate.
        """
        before = len(self.daq.rows)
        self.daq.read(silence)
        self.daq.check_reset()
        if stepper:
            self.stepper.read(block=False)
            self.stepper.check_reset()
        stats = self.daq.parser.stats
        if stats.corrupted > 50 and stats.corrupted > MAX_CORRUPTED_FRACTION * (stats.samples + 1):
            raise RunAborted(
                f"{stats.corrupted} corrupted lines against {stats.samples} samples (wrong baud rate or a "
                "bad cable?)"
            )
        if len(self.daq.rows) > before:
            return len(self.daq.rows) - before, self.daq.waiter(silence.timeout)
        if silence.expired:
            raise BoardTimeout(f"the daq board sent no sample for {silence.timeout:.1f} s (it is silent)")
        return 0, silence

    def _until_done(
        self, state: RunState, step: Callable[[int], Any], rate_hz: int, tail_s: float, total_s: float | None,
        progress: bool, stepper: bool = True,
    ) -> None:  # fmt: skip
        """Read until ``DONE`` and ``tail_s`` past the end (``step(now)``: ``(end us, positions)`` or None).

        ``step`` runs at each read with the device time from ``GO`` (a stream feeds its set-points there) and
        gives when the stepper's motion ends (us from ``GO``) and every tendon's position then, or None
        while that is not known (``DONE`` then is an error). ``DONE`` is awaited on the DAQ's clock:
        :data:`DONE_GRACE_S` after the end, and after each further grace, ``POS`` is asked: at the end, the
        ``DONE`` was lost on the link; still moving, the stepper is late and is waited for; not moving, it
        stopped short. A board that sends no sample, or does not answer ``POS``, within the silence interval
        is gone. Not ``stepper``: the stepper is not used (nor read), and the end is the end (the wait for
        rest, a static recording).
        """
        silence, asked, last, bar = self.daq.waiter(self.silence_s), 0, None, _bar(total_s, progress)
        try:
            while True:
                new, silence = self._read(silence, stepper)
                rows = self.daq.rows
                if new and state.t_go_us is None:
                    self._went(state, rows[-new][1] - round(1e6 / rate_hz))
                if state.watch is not None:  # every parsed sample against the floor (device time)
                    state.watch.catch_up(rows)
                if state.t_go_us is None:
                    continue
                now = rows[-1][1] - state.t_go_us
                if bar is not None and now / 1e6 - bar.n >= 0.1:  # in 0.1 s increments
                    bar.update(round(now / 1e6 - bar.n, 1))
                due = step(now)
                if due is None:
                    if stepper and self.stepper.done is not None:
                        raise BoardError(f"the stepper board ended before it was asked to (DONE at {now} us)")
                    continue
                end_us, end = due
                done = self.stepper.done if stepper else end
                if done is not None and now >= end_us + tail_s * 1e6:
                    break
                if done is None and now >= end_us + DONE_GRACE_S * 1e6 * (asked + 1):
                    asked, where = asked + 1, self.positions()
                    if where == end:
                        self.stepper.done = where  # its DONE was lost on the link (a corrupted line)
                    elif where == last:
                        raise BoardError(
                            f"the stepper board stopped at {where} steps without DONE, not at the end {end} "
                            f"({asked * DONE_GRACE_S:.0f} s of device time after it was due)"
                        )
                    last = where
        finally:
            if bar is not None:
                bar.close()
        if stepper and self.stepper.done[: self.n] != end:
            raise BoardError(f"the stepper board ended at {self.stepper.done}, not at the end {end}")

    def _finish(self, state: RunState) -> None:
        """Every sample is in: stop the DAQ, count the samples it sent that never arrived, disable."""
        state.finished = True
        sent, last = ints(self.daq.command("STOP"))[-1], self.daq.parser.last_seq
        self.daq.parser.stats.dropped += max(0, sent - (0 if last is None else last + 1))
        self.stepper.command("EN 0")

    # --- the guard -------------------------------------------------------------------------------------
    def _cleanup(self, stepper_used: bool) -> list[str]:
        """Abort and disable the stepper, stop the DAQ; return the problems met (never raises)."""
        problems = []
        steps = [("ABORT", self.stepper), ("EN 0", self.stepper)] * stepper_used + [("STOP", self.daq)]
        for body, board in steps:
            board.hello = 0  # a rebooted board still takes the command
            try:
                board.command(body, timeout=2.0)  # a board answers in ms, a busy pty server in < 2 s
            except (Exception, KeyboardInterrupt) as exc:  # noqa: BLE001 - cleanup must go on
                problems.append(f"{body} to the {board.kind} board failed: {type(exc).__name__}: {exc}")
        return problems

    def _guarded(
        self, body: Callable[[RunState], None], scenario: dict[str, Any], target: Path, rate_hz: int,
        replace: bool, start: tuple[int, ...], stepper_used: bool = True,
    ) -> Recording:  # fmt: skip
        """Run ``body`` so that every way it ends leaves the boards safe and its recording on disk.

        Signals interrupt only the body (:func:`helpers.base.signals.run_guard`): the first one raises, every
        later one waits until the cleanup and the save are done. A run that had recorded everything when the
        signal came (``state.finished``) is saved whole and the interrupt raised after the save; so is a run
        that ended normally and was interrupted just after.
        """
        state = RunState(start=start)
        self.daq.rows.clear()  # nothing of an earlier run is this run's
        with run_guard() as guard:
            try:
                with guard.interruptible():
                    body(state)
            except BaseException as exc:
                cleanup = exc.cleanup = self._cleanup(stepper_used)  # type: ignore[attr-defined]
                reason = None  # an interrupt once every sample is in: the run is saved whole
                if not (state.finished and isinstance(exc, KeyboardInterrupt)):
                    reason = f"{type(exc).__name__}: {exc}"
                    reason += " | cleanup: " + "; ".join(cleanup) if cleanup else ""
                self._save(state, scenario, target, rate_hz, replace, exc, reason)
                raise
            rec = self._save(state, scenario, target, rate_hz, replace)
            signum = guard.take_pending()
            if signum is not None:  # a signal came after the run had ended: it is saved; now act on it
                late = Interrupted(signum)
                late.cleanup, late.complete = [], True  # type: ignore[attr-defined]
                late.recording, late.saved_path, late.save_error = rec, rec.path, None  # type: ignore[attr-defined]
                raise late
        return rec

    def _save(
        self, state: RunState, scenario: dict[str, Any], target: Path, rate_hz: int, replace: bool,
        exc: BaseException | None = None, reason: str | None = None,
    ) -> Recording:  # fmt: skip
        """Save a run: ``aborted`` with ``reason``, or (every sample in) ``complete``, or ``deviated``.

        A complete run goes under its name, the others beside it (``recordings.aborted_path``). With ``exc``
        (the run ended by it) the outcome is noted on ``exc`` (``recording``, ``saved_path``, ``save_error``,
        ``complete``), and a failed save is noted there, not raised.
        """
        status = "aborted" if reason else "deviated" if state.deviation else "complete"
        rec = self.recording(state, scenario, rate_hz, status, reason)
        where = target if status == "complete" else recordings.aborted_path(target, state.started_utc, status)
        try:
            recordings.save(rec, where, replace=replace and status == "complete")
        except (RecordingError, OSError) as save_exc:
            if exc is None:
                raise
            exc.recording, exc.saved_path, exc.save_error = None, None, str(save_exc)  # type: ignore[attr-defined]
            return rec
        rec.derive()
        if exc is not None:
            exc.recording, exc.saved_path, exc.save_error = rec, rec.path, None  # type: ignore[attr-defined]
            exc.complete = status != "aborted"  # type: ignore[attr-defined]
        return rec

    def recording(
        self, state: RunState, scenario: dict[str, Any], rate_hz: int, status: str, reason: str | None
    ) -> Recording:
        """A run's recording: its samples since ``START`` and the metadata (``docs/recording_format.md``).

        The one place a run becomes a recording, for every tendon count: the rows (every tendon's steps from
        where the run started; the twin's tip where the in-process virtual rig gives it) go to the one writer,
        :func:`helpers.recordings.from_samples`.
        """
        rows = np.asarray(self.daq.rows, dtype=np.int64).reshape(-1, 2 + 2 * self.n)  # the build checked
        rows[:, 2 + self.n :] += np.asarray(state.start, dtype=np.int64)  # steps from where the run started
        tips = getattr(self.daq.port, "twin_tip_um", lambda t: None)(rows[:, 1]) if len(rows) else None
        if tips is not None:
            rows = np.column_stack([rows, np.asarray(tips, dtype=np.int64)])
        stats, done = self.daq.parser.stats, self.stepper.done
        return recordings.from_samples(
            rows, self.rig, self.calibration, source=self.source, scenario=scenario, rate_hz=rate_hz,
            started_utc=state.started_utc, status=status, reason=reason, t_go_us=state.t_go_us,
            firmware={"daq": self.daq.version, "stepper": self.stepper.version},
            counts={k: int(getattr(stats, k)) for k in ("dropped", "corrupted", "overruns", "implausible")},
            done_position=None if done is None else done[0],
            done_positions=None if done is None else list(done[: self.n]),
            **({"deviation": state.deviation} if state.deviation else {}),
        )  # fmt: skip
