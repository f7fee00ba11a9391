"""The coordinated experiment: :class:`Rig` runs one board-timed programme or stream per call -> a recording.

A whole Up-hold-Down experiment is one stepper programme (lead-in dwell, up segments, hold, down segments,
trailing dwell), so its timing is the stepper board's, not the host's. :meth:`Rig.run` loads the programme,
zeroes and starts the DAQ, enables the driver and sends ``GO``; then it reads DAQ lines until the device time
has passed the programme's end (``GO``'s device time + duration + a margin) and ``DONE`` has arrived. It never
times anything with sleeps, which is also what lets the in-process virtual rig run faster than real time.

Every run starts at rest: before ``GO`` the host streams the tension until its standard deviation over
``REST_WINDOW_S`` is within ``REST_FACTOR`` times the sensor's white noise (or refuses after a timeout), on
hardware and on the virtual rig alike, and the start position is recorded. A pulse experiment must start
at cable position 0 (``python -m helpers home`` brings it there).

Every run sits in a guard: on any exception (``KeyboardInterrupt``, and SIGTERM/SIGHUP turned into one by
:mod:`helpers.base.signals`, included) the stepper is sent ``ABORT`` and ``EN 0`` and the DAQ ``STOP``, and
what
was recorded is saved marked ``aborted``, under a name of its own (``<name>_aborted_<UTC>``), with the
reason; signals are held while that cleanup and save run. The exception is then re-raised carrying
``exc.recording`` (the saved recording, or None if it could not be saved), ``exc.saved_path`` and
``exc.cleanup`` (the problems the cleanup met; empty when it reached both boards). A complete run never
overwrites a recording unless asked (``replace=True``). Requests outside the safety limits raise
:class:`helpers.rig.safety.SafetyError` before any byte is sent.

:meth:`StreamRig.stream` streams velocity set-points through the stepper board's shaper (its parts, which
touch no
port, are :mod:`helpers.rig.stream`) with the same guarantees: it starts at rest, checks what it can before
sending, runs in the same guard and reads the device time the same way (its pacing follows the DAQ's clock,
so the in-process virtual rig streams faster than real time, deterministically).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

try:  # a progress bar where tqdm is installed (the [virtual] extra); the paper's part runs without it
    from tqdm.auto import tqdm
except ImportError:  # pragma: no cover - the light environment
    tqdm = None
from helpers import recordings
from helpers.base.paths import DATA_DIR
from helpers.base.signals import Interrupted, run_guard
from helpers.base.validate import RIG_NAME
from helpers.board.programmes import Programme, Segment
from helpers.live.driver import (
    REST_FACTOR,
    REST_TIMEOUT_S,
    REST_WINDOW_S,
    BoardPair,
    NotAtRest,
    pulse_scenario,
    recording_of,
    rest_of,
    utc_now,
)
from helpers.live.ports import virtual_source_for
from helpers.paper.hardware import DAQ_RATE_MAX_HZ, DAQ_RATE_MIN_HZ, RIG
from helpers.paper.tension import LoadCellCalibration, load_calibration
from helpers.recordings import Recording, RecordingError, reserve
from helpers.rig.boards import BOOT_TIMEOUT_S, BoardError, BoardLink, BoardTimeout, Waiter
from helpers.rig.daq import DaqBoard
from helpers.rig.discovery import find_rig_ports
from helpers.rig.safety import SafetyError, check_programme
from helpers.rig.stepper import StepperBoard


class RunAborted(BoardError):
    """The run was stopped because its data were unusable (e.g. mostly corrupted lines)."""


class NotAtZero(SafetyError):
    """A pulse experiment was asked for while the cable is not at position 0."""


__all__ = [
    "GO_LATENCY_US",
    "REST_FACTOR",
    "REST_TIMEOUT_S",
    "REST_WINDOW_S",
    "NotAtRest",
    "NotAtZero",
    "Rig",
    "RunAborted",
    "RunOptions",
    "step_windows",
]


@dataclass
class _RunState:
    """What a run knows about itself besides its samples.

    The samples are the DAQ driver's ``rows`` since the run's ``START``, kept there and never moved, so that
    an interrupt cannot lose a chunk on its way from one list to another.
    """

    t_go_us: int | None = None
    step_offsets: tuple[np.ndarray, np.ndarray] | None = None
    """The programme's step windows relative to GO (:func:`step_windows` at ``t_go_us = 0``)."""
    go_sent: bool = False
    started_utc: str = ""
    finished: bool = False
    """Every sample of the run is in: an interrupt from now on cannot make it partial."""
    deviation: str | None = None
    """Why the motion differed from its command (a stream's underruns, clamps), or None."""


def _is_virtual_url(url: str) -> bool:
    return str(url).startswith("virtual://")


def _check_rate(rate_hz: Any) -> None:
    ok = isinstance(rate_hz, int) and not isinstance(rate_hz, bool)
    if not (ok and DAQ_RATE_MIN_HZ <= rate_hz <= DAQ_RATE_MAX_HZ):
        raise SafetyError(
            f"DAQ rate must be an integer in {DAQ_RATE_MIN_HZ}-{DAQ_RATE_MAX_HZ} Hz, got {rate_hz!r}"
        )


GO_LATENCY_US = 50_000
"""How much earlier than the host's estimate ``GO`` may have happened on the DAQ's clock (the estimate is the
newest sample at hand once ``GO`` is acknowledged: never early, a few ms late over USB)."""


def step_windows(programme: Programme, t_go_us: int, slack_us: int = 2_000) -> tuple[np.ndarray, np.ndarray]:
    """Device-time windows in which ``programme`` makes steps, given the estimated time of ``GO``.

    Each segment's steps fall in ``[t_go + first, t_go + last]``; the window opens :data:`GO_LATENCY_US`
    earlier (GO may precede its estimate) and closes ``slack_us`` later (a sample's own timing). A step count
    that changes outside every window is impossible, and the DAQ driver rejects it.
    """
    starts, ends = [], []
    for item, t0 in zip(programme.items, programme.item_starts_us(), strict=True):
        if isinstance(item, Segment):
            first = int(t0) + item.interval_us
            last = int(t0) + item.n_steps * item.interval_us
            starts.append(t_go_us + first - GO_LATENCY_US)
            ends.append(t_go_us + last + slack_us)
    merged_s: list[int] = []
    merged_e: list[int] = []
    for a, b in zip(starts, ends, strict=True):
        if merged_e and a <= merged_e[-1]:
            merged_e[-1] = max(merged_e[-1], b)
        else:
            merged_s.append(a)
            merged_e.append(b)
    return np.array(merged_s, dtype=np.int64), np.array(merged_e, dtype=np.int64)


class _DeviceTimeBar:
    """A tqdm bar of device seconds, updated in 0.1 s increments (none where tqdm is not installed)."""

    def __init__(self, total_s: float | None, show: bool, desc: str | None = "device time") -> None:
        self.bar = (
            None
            if tqdm is None
            else tqdm(
                total=None if total_s is None else round(total_s, 1),
                unit="s",
                desc=desc,
                disable=not show,
                bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} s"
                if total_s is not None
                else "{desc}: {n:.1f} s",
            )
        )
        self.shown = 0.0

    def show(self, elapsed_s: float) -> None:
        if self.bar is not None and elapsed_s - self.shown >= 0.1:
            self.bar.update(round(elapsed_s - self.shown, 1))
            self.shown += round(elapsed_s - self.shown, 1)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


@dataclass(frozen=True)
class RunOptions:
    """The options every run of a rig takes (:meth:`Rig.run`, :meth:`StreamRig.stream` and what calls them).

    Attributes
    ----------
    rate_hz : int
        DAQ sample rate.
    done_grace_s : float
        Device time after the end by which ``DONE`` must have arrived.
    silence_timeout : float
        Seconds without a sample after which the DAQ counts as not answering.
    progress : bool
        Show a tqdm bar of device time (where tqdm is installed).
    max_corrupted_fraction : float
        Abort when more than this fraction of lines (and more than 50) are corrupted.
    replace : bool
        Replace a recording of the same name (kept until the new one is complete); otherwise an existing name
        is refused before anything moves.
    noise_seed : int, optional
        In-process virtual rig: re-seed the sensor noise for this run (recorded in the scenario).
    rest_timeout_s : float
        Longest wait for the tension to come to rest before the run (device s).
    """

    rate_hz: int = 1000
    done_grace_s: float = 1.0
    silence_timeout: float = 2.0
    progress: bool = True
    max_corrupted_fraction: float = 0.05
    replace: bool = False
    noise_seed: int | None = None
    rest_timeout_s: float = REST_TIMEOUT_S

    def __post_init__(self) -> None:
        """Refuse a rate or a seed the run cannot take (``SafetyError``) before anything is sent."""
        _check_rate(self.rate_hz)
        seed = self.noise_seed
        if seed is not None and not (type(seed) is int and 0 <= seed < 2**32):
            raise SafetyError(f"noise seed must be an integer in 0..2**32-1, got {seed!r}")


class Rig(BoardPair):
    """Both boards of one rig (hardware or virtual) and the calibration that turns counts into newtons.

    Parameters
    ----------
    daq : DaqBoard
        The synchronised DAQ driver.
    stepper : StepperBoard
        The synchronised stepper driver.
    calibration : LoadCellCalibration or dict, optional
        The load-cell calibration; default :func:`helpers.paper.tension.load_calibration` (which raises a
        clear
        error if there is none yet: pass :data:`helpers.paper.tension.UNCALIBRATED` to record without
        one).
    source : dict, optional
        Provenance written into every recording; default ``{"kind": "hardware"}``.
    """

    def __init__(
        self,
        daq: DaqBoard,
        stepper: StepperBoard,
        calibration: LoadCellCalibration | dict[str, Any] | None = None,
        source: dict[str, Any] | None = None,
    ) -> None:
        self.daq = daq
        self.stepper = stepper
        if calibration is None:
            calibration = load_calibration()
        elif isinstance(calibration, dict):
            calibration = LoadCellCalibration.from_dict(calibration)
        self.calibration: LoadCellCalibration = calibration
        self.source = dict(source) if source is not None else {"kind": "hardware"}
        if self.source.get("kind") == "hardware" and self.calibration.source == "virtual-rig":
            # the raw ADC counts are recorded either way, so tension can be recomputed after calibrating
            warnings.warn(
                "this is hardware, but the load-cell calibration "
                f"({self.calibration.origin or '?'}) was recorded on the virtual rig: tension_n will be "
                "wrong; calibrate this load cell first (python -m helpers record calibration --ports auto)",
                UserWarning,
                stacklevel=2,
            )
        self.rig = RIG  # transitional: the rig file (the one driver of issue 36 takes it as a value)
        self.cleanup_timeout = 2.0  # s per cleanup command: a board answers in ms, a busy pty server in < 2 s
        self.last_cleanup: list[str] = []

    # --- connecting ------------------------------------------------------------------------------
    @classmethod
    def connect(
        cls,
        ports: str | tuple[str, str] | list[str] = "virtual",
        rig_name: str = "default",
        calibration: LoadCellCalibration | dict[str, Any] | None = None,
        timeout: float = 2.0,
        hello_timeout: float = BOOT_TIMEOUT_S,
        daq_options: str = "",
        stepper_options: str = "",
    ) -> Rig:
        """Open and synchronise both boards.

        Parameters
        ----------
        ports : str or (str, str)
            ``"virtual"`` (the in-process virtual rig ``rig_name``), ``"auto"`` (find the boards by USB
            VID:PID, see :mod:`helpers.rig.discovery`), ``"DAQ,STEPPER"`` or a pair: device paths or pyserial
            URLs.
        rig_name : str
            Name of the in-process virtual rig.
        calibration : LoadCellCalibration or dict, optional
            Default :func:`helpers.paper.tension.load_calibration`.
        timeout, hello_timeout : float
            Command timeout and boot timeout (s).
        daq_options, stepper_options : str
            Extra ``&key=value`` URL options for the virtual boards (faults, seed).

        Returns
        -------
        Rig
        """
        if RIG.n_tendons > 1:  # before any port opens
            raise ValueError(
                f"rig '{RIG.name}' has {RIG.n_tendons} tendons, but Rig drives one: run its coordinated "
                "programmes with helpers.rig.tendons.TendonRig"
            )
        if ports == "virtual":
            if not (isinstance(rig_name, str) and RIG_NAME.match(rig_name)):
                raise ValueError(
                    f"invalid virtual rig name {rig_name!r}: letters, digits, '_', '-', '.' (at most 64)"
                )
            daq_url = f"virtual://daq?rig={rig_name}{daq_options}"
            stepper_url = f"virtual://stepper?rig={rig_name}{stepper_options}"
        elif ports == "auto":
            daq_url, stepper_url = find_rig_ports()
        else:
            pair = ports.split(",") if isinstance(ports, str) else list(ports)
            if len(pair) != 2:
                raise ValueError(f"ports must be 'virtual', 'auto' or two ports 'DAQ,STEPPER', got {ports!r}")
            daq_url, stepper_url = (p.strip() for p in pair)
        daq = DaqBoard.open(daq_url, timeout=timeout, hello_timeout=hello_timeout)
        try:
            stepper = StepperBoard.open(stepper_url, timeout=timeout, hello_timeout=hello_timeout)
        except BaseException:
            daq.close()
            raise
        if _is_virtual_url(daq_url):
            world = daq.port.world
            source = {"kind": "virtual-rig", "via": "in-process", "rig": world.name, **world.info}
        else:
            source = virtual_source_for((daq_url, stepper_url)) or {"kind": "hardware"}
        source["ports"] = {"daq": daq_url.split("?")[0], "stepper": stepper_url.split("?")[0]}
        try:
            return cls(daq, stepper, calibration=calibration, source=source)
        except BaseException:
            daq.close()
            stepper.close()
            raise

    @property
    def is_virtual(self) -> bool:
        """True for the virtual rig (in-process or through the pseudo-terminal server)."""
        return self.source.get("kind") == "virtual-rig"

    @property
    def virtual_world(self) -> Any:
        """The in-process virtual rig's world (for the VIRTUAL calibration fixture), or None."""
        return getattr(self.daq.port, "world", None)

    # --- running -------------------------------------------------------------------------------------
    def run_pulse(
        self,
        v_in_mm_s: float,
        x_f_mm: float,
        shaper: Any = None,
        system: str | None = None,
        path: str | os.PathLike | None = None,
        repetition: int = 1,
        t_end_s: float = 12.0,
        scenario_extra: dict[str, Any] | None = None,
        allow_offset: bool = False,
        **kwargs: Any,
    ) -> Recording:
        """Check a pulse request, build its programme (:func:`~programmes.experiment_programme`), run.

        The up move starts at ``paper.PULSE_T_UP_S`` (1 s) and the down move at ``paper.PULSE_T_DOWN_S``
        (8 s) after ``GO``, as in the paper.

        Parameters
        ----------
        v_in_mm_s, x_f_mm : float
            Speed (mm/s) and displacement (mm); refused with :class:`SafetyError` outside the limits.
        shaper : Shaper, ShaperPair, Schedule or Design, optional
            None for the unshaped pulse; otherwise anything
            :func:`~helpers.board.programmes.experiment_programme` accepts (a design of
            :mod:`helpers.research.design`: a
            shaper for both moves, an Up/Down pair, or a map-following schedule computed for this move).
        system : str, optional
            A name of :data:`helpers.research.design.SYSTEMS` (``"unshaped"``, ``"zv"``, ``"zvd"``, ``"ei"``,
            ``"scheduled"``, ...). Default: a design's own system; for a bare shaper its name.
        path : path-like, optional
            Where to save.
        repetition : int
            Repetition number written into the scenario.
        t_end_s : float
            Programme end (s from ``GO``); the recording lasts that long.
        scenario_extra : dict, optional
            More scenario metadata (e.g. the identified mode the shaper was designed from).
        allow_offset : bool
            Run even if the cable is not at position 0 (the paper's experiments start from the down position).
        **kwargs
            Passed to :meth:`run` (``path``, ``replace``, ``noise_seed``, ``rate_hz``, ...).
        """
        programme, scenario = pulse_scenario(v_in_mm_s, x_f_mm, shaper, system, repetition, t_end_s)
        scenario.update(scenario_extra or {})
        return self.run(programme, scenario=scenario, path=path, require_zero=not allow_offset, **kwargs)

    def run(
        self,
        programme: Programme,
        scenario: dict[str, Any] | None = None,
        path: str | os.PathLike | None = None,
        margin_s: float = 0.1,
        require_zero: bool = False,
        **options: Any,
    ) -> Recording:
        """Run one programme as one board-timed experiment and return (and save) its recording.

        The steps: check the programme against the limits from the cable's present position
        (:meth:`_checked_start_position`), wait until the tension is at rest (:meth:`wait_for_rest`), load
        the programme and start the DAQ (:meth:`_load_and_go`), stream samples until the programme's end has
        passed and ``DONE`` has arrived (:meth:`_stream_until_done`), then stop the DAQ and disable the
        driver. All of it inside the guard (:meth:`_guarded`).

        Parameters
        ----------
        programme : helpers.board.programmes.Programme
            Checked against the limits before anything is sent.
        scenario : dict, optional
            Scenario metadata (kind, v_in_mm_s, x_f_mm, system, shaper, repetition, ...); the programme is
            added.
        path : path-like, optional
            ``data/<group>/<name>``; default ``data/runs/run_<UTC time>``.
        margin_s : float
            Device time recorded after the programme's end.
        require_zero : bool
            Refuse unless the cable is at position 0.
        **options
            The run's options, shared with every run of a rig (:class:`RunOptions`: ``rate_hz``,
            ``progress``, ``replace``, ``noise_seed``, timeouts).

        Returns
        -------
        helpers.recordings.Recording
        """
        o = RunOptions(**options)
        check_programme(programme)
        scenario = dict(scenario or {"kind": "programme"})
        scenario.setdefault("programme", programme.to_dict())
        target = self._target(path)
        with reserve(target, o.replace):  # a second run to this name is refused now, not after this one
            return self._run(programme, scenario, target, margin_s, require_zero, o)

    def _run(
        self, programme: Programme, scenario: dict[str, Any], target: Path, margin_s: float,
        require_zero: bool, o: RunOptions,
    ) -> Recording:  # fmt: skip
        position = self._checked_start_position(programme)
        if require_zero and position != 0:
            raise NotAtZero(
                f"the cable is at {position} steps, not at 0 (the paper's experiments start from the down "
                f"position): {self._home_hint()} first"
            )
        scenario["start_position_steps"] = position
        self._seed_noise(o.noise_seed, scenario)
        positions = np.concatenate([[0], np.cumsum(programme.step_times()[1].astype(np.int64))])

        def body(state: _RunState) -> None:
            scenario["rest"] = self.wait_for_rest(o.rate_hz, o.rest_timeout_s)
            reach = (int(positions.min()), int(positions.max()))
            self._load_and_go(programme, position, o.rate_hz, state, reach)
            bar = _DeviceTimeBar(programme.duration_s + margin_s, o.progress)
            try:
                end = position + int(positions[-1])
                self._stream_until_done(state, programme.duration_us, margin_s, o, bar, end)
            finally:
                bar.close()
            state.finished = True
            self.daq.stop()
            self.stepper.enable(False)

        return self._guarded(body, scenario, target, o.rate_hz, replace=o.replace)

    def _home_hint(self) -> str:
        """How to bring this rig's cable home: the command with this rig's ports, or the call in-process."""
        ports = self.source.get("ports", {})
        if str(ports.get("daq", "")).startswith("virtual://"):
            return (
                "return it with helpers.commands.home.home(rig.stepper) "
                "(the in-process rig lives in this process)"
            )
        daq, stepper = ports.get("daq", "DAQ"), ports.get("stepper", "STEPPER")
        return f"run `python -m helpers home --ports {daq},{stepper}`"

    def _target(self, path: str | os.PathLike | None) -> Path:
        """Where a run is saved: ``path`` (its name checked) or ``data/runs/run_<UTC time>``."""
        if path is None:
            return DATA_DIR / "runs" / ("run_" + utc_now().replace(":", "").replace("-", "") + ".csv")
        target = Path(path)
        target = target.with_suffix(".csv") if target.suffix in ("", ".json") else target
        recordings.check_name(target.stem)
        return target

    def _seed_noise(self, noise_seed: int | None, scenario: dict[str, Any]) -> None:
        """In-process virtual rig: re-seed the sensor noise for this run and record the seed."""
        if noise_seed is None:
            return
        world = self.virtual_world
        if world is not None:
            world.reseed(noise_seed)
            scenario["noise_seed"] = noise_seed

    def wait_for_rest(self, rate_hz: int = 1000, timeout_s: float = REST_TIMEOUT_S) -> dict[str, Any]:
        """Stream the tension until it is steady: std over ``REST_WINDOW_S`` <= ``REST_FACTOR`` x noise.

        The noise is the white-noise level of the same window (:func:`helpers.base.noise.white_noise_std`),
        so a
        ringing arm or a drifting amplifier keeps the wait going while sensor noise alone does not.

        Returns
        -------
        dict
            ``waited_s`` (device s), ``std_counts``, ``noise_counts`` of the last window.

        Raises
        ------
        NotAtRest
            If it does not settle within ``timeout_s``.
        """
        self.daq.check_reset()
        self.daq.stop()
        self.daq.set_rate(rate_hz)
        self.daq.start()
        n = max(3, round(REST_WINDOW_S * rate_hz))
        adc: list[int] = []
        t0: int | None = None
        try:
            for rows in self.daq.samples():
                adc.extend(r[2] for r in rows)
                t0 = rows[0][1] if t0 is None else t0
                waited = (rows[-1][1] - t0) / 1e6
                steady, std, noise = rest_of(adc, rate_hz)
                if steady:
                    return {"waited_s": round(waited, 3), "std_counts": std, "noise_counts": noise}
                if waited > timeout_s:
                    raise NotAtRest(
                        f"the tension did not come to rest within {timeout_s:.0f} s (std {std:.2f} counts "
                        f"over {REST_WINDOW_S} s against a noise of {noise:.2f} counts): is the arm still "
                        "moving?"
                    )
                adc = adc[-n:]
        finally:
            self.daq.stop()
            self.daq.take_rows()
        raise NotAtRest("the DAQ stream ended while waiting for rest")  # pragma: no cover

    def _checked_start_position(self, programme: Programme) -> int:
        """Ask the stepper where the cable is (``POS`` moves nothing) and check the programme from there."""
        self.stepper.check_reset()
        self.daq.check_reset()
        position = self.stepper.position()
        check_programme(programme, start_position=position)
        return position

    def _load_and_go(
        self, programme: Programme, position: int, rate_hz: int, state: _RunState, reach: tuple[int, int]
    ) -> None:
        """Stop what an earlier session left running, load the programme, start the DAQ, enable, ``GO``.

        ``reach`` is the range of step counts (from ``ZERO``) the programme can produce: the DAQ driver
        rejects and counts any sample outside it, or one whose count changes faster than the step rate allows.
        """
        self.stepper.abort()  # a programme left running by an earlier session stops; driver off
        self.daq.stop()  # a stream left running by an earlier session stops (OK STOP 0 when idle)
        self.stepper.load(programme, start_position=position)
        self.daq.set_rate(rate_hz)
        self.daq.zero()
        self.daq.start()
        self.daq.expect_steps(*reach)
        self.stepper.enable(True)
        state.go_sent = True
        self.stepper.go()
        # GO's device time, estimated as the newest DAQ sample at hand once GO is acknowledged (exact
        # on the in-process virtual rig; a few ms late on hardware). Metrics use `steps` instead.
        state.step_offsets = step_windows(programme, 0)
        self.daq.pump(block=False)
        if self.daq.rows:
            self._went(state, self.daq.rows[-1][1])

    def _went(self, state: _RunState, t_go_us: int) -> None:
        """Note GO's device time; from then on a count changing between the programme's steps is refused."""
        state.t_go_us = t_go_us
        if state.step_offsets is not None:
            starts, ends = state.step_offsets
            self.daq.expect_steps_within(starts + t_go_us, ends + t_go_us)

    def _check_corruption(self, max_corrupted_fraction: float) -> None:
        stats = self.daq.stats
        if stats.corrupted > 50 and stats.corrupted > max_corrupted_fraction * (stats.samples + 1):
            raise RunAborted(
                f"{stats.corrupted} corrupted lines against {stats.samples} samples "
                "(wrong baud rate or a bad cable?)"
            )

    def _read_both(self, silence: Waiter, max_corrupted_fraction: float) -> tuple[int, Waiter]:
        """Read once from both boards during a run; return the number of new samples and the silence timer.

        Raises :class:`~helpers.rig.BoardReset` if a board rebooted, :class:`~helpers.rig.BoardTimeout` after
        ``silence.timeout`` s without a sample, :class:`RunAborted` if corrupted lines dominate.
        """
        before = len(self.daq.rows)
        self.daq.pump()
        self.daq.check_reset()
        self.stepper.poll()
        self.stepper.check_reset()
        new = len(self.daq.rows) - before
        if new:
            silence = self.daq.waiter(silence.timeout)
        else:
            silence.idle(self.daq.port.timeout or 0.0)
            if silence.expired:
                raise BoardTimeout(
                    f"the daq board sent no sample for {silence.timeout:.1f} s (it stopped answering)"
                )
        self._check_corruption(max_corrupted_fraction)
        return new, silence

    def _stream_until_done(
        self,
        state: _RunState,
        duration_us: int,
        margin_s: float,
        o: RunOptions,
        bar: _DeviceTimeBar,
        end_position: int,
    ) -> None:
        """Read samples until the programme's end + ``margin_s`` has passed and ``DONE`` has arrived.

        A ``DONE`` lost to a bit error on the link (a corrupted line came from the stepper instead) is not a
        silent board: ``POS`` then tells whether the programme ended where it should.
        """
        period_us = round(1e6 / o.rate_hz)
        done_grace_s = o.done_grace_s
        silence = self.daq.waiter(o.silence_timeout)
        corrupted = self.stepper.parser.stats.corrupted
        while True:
            new, silence = self._read_both(silence, o.max_corrupted_fraction)
            rows = self.daq.rows
            if new and state.t_go_us is None:
                self._went(state, rows[len(rows) - new][1] - period_us)
            if state.t_go_us is None or not rows:
                continue
            last_us = rows[-1][1]
            bar.show((last_us - state.t_go_us) / 1e6)
            past_end = last_us >= state.t_go_us + duration_us + margin_s * 1e6
            if past_end and self.stepper.done_position is not None:
                return
            overdue = last_us >= state.t_go_us + duration_us + done_grace_s * 1e6
            lost = self.stepper.parser.stats.corrupted > corrupted
            if self.stepper.done_position is None and overdue and lost:
                where = self.stepper.position()  # DONE came corrupted: ask where the programme ended
                if where == end_position:
                    self.stepper.done_position = where
                    continue
                raise BoardError(
                    f"the stepper board's DONE was lost on the link, and it is at {where} steps, not at the "
                    f"programme's end ({end_position})"
                )
            if self.stepper.done_position is None and overdue:
                raise BoardTimeout(
                    f"the stepper board did not report DONE within {done_grace_s:.1f} s of device time "
                    "after the programme's end (it stopped answering)"
                )

    # --- the guard -------------------------------------------------------------------------------------
    def _cleanup(self, stepper_used: bool) -> list[str]:
        """Abort and disable the stepper, stop the DAQ; return the problems met (never raises)."""
        problems = []
        steps: list[tuple[str, BoardLink, Callable[[], Any]]] = []
        if stepper_used:
            steps += [
                ("ABORT", self.stepper, lambda: self.stepper.abort(timeout=self.cleanup_timeout)),
                ("EN 0", self.stepper, lambda: self.stepper.enable(False, timeout=self.cleanup_timeout)),
            ]
        steps.append(("STOP", self.daq, lambda: self.daq.stop(timeout=self.cleanup_timeout)))
        for what, board, fn in steps:
            board.hello = 0  # a rebooted board still takes the command
            try:
                fn()
            except (Exception, KeyboardInterrupt) as exc:  # noqa: BLE001 - cleanup must go on
                problems.append(f"{what} to the {board.kind} board failed: {type(exc).__name__}: {exc}")
        return problems

    def _guarded(
        self,
        body: Callable[[_RunState], None],
        scenario: dict[str, Any],
        target: Path,
        rate_hz: int,
        stepper_used: bool = True,
        replace: bool = False,
    ) -> Recording:
        """Run ``body`` so that every way it ends leaves the boards safe and its recording on disk.

        Signals interrupt only the body (:func:`helpers.base.signals.run_guard`): the first one raises, every
        later
        one waits until the cleanup and the save are done. A run that had recorded everything when the signal
        came (``state.finished``) is saved whole, as if nothing had happened, and the interrupt is raised
        after the save; so is a run that ended normally and was interrupted just after.
        """
        state = _RunState(started_utc=utc_now())
        self.daq.take_rows()  # nothing of an earlier run is this run's
        with run_guard() as guard:
            try:
                with guard.interruptible():
                    body(state)
            except BaseException as exc:
                self.last_cleanup = self._cleanup(stepper_used)
                exc.cleanup = list(self.last_cleanup)  # type: ignore[attr-defined]
                if state.finished and isinstance(exc, KeyboardInterrupt):  # every sample is in: save it whole
                    self._save_finished(state, scenario, target, rate_hz, replace, exc)
                    raise
                reason = f"{type(exc).__name__}: {exc}"
                if self.last_cleanup:
                    reason += " | cleanup: " + "; ".join(self.last_cleanup)
                rec = self._recording(state, scenario, rate_hz, "aborted", reason)
                try:
                    recordings.save(rec, recordings.aborted_path(target, state.started_utc))
                except (RecordingError, OSError) as save_exc:
                    exc.recording = None  # type: ignore[attr-defined]
                    exc.saved_path = None  # type: ignore[attr-defined]
                    exc.save_error = str(save_exc)  # type: ignore[attr-defined]
                else:
                    exc.recording = rec.derive()  # type: ignore[attr-defined]
                    exc.saved_path = rec.path  # type: ignore[attr-defined]
                    exc.save_error = None  # type: ignore[attr-defined]
                raise
            self.last_cleanup = []
            rec = self._save_finished(state, scenario, target, rate_hz, replace, None)
            signum = guard.take_pending()
            if signum is not None:  # a signal came after the run had ended: it is saved; now act on it
                late = Interrupted(signum)
                late.cleanup, late.complete = [], True  # type: ignore[attr-defined]
                late.recording, late.saved_path, late.save_error = rec, rec.path, None  # type: ignore[attr-defined]
                raise late
        return rec

    def _save_finished(
        self, state: _RunState, scenario: dict[str, Any], target: Path, rate_hz: int, replace: bool,
        exc: BaseException | None,
    ) -> Recording:  # fmt: skip
        """Save a run that recorded everything: ``complete`` under its name, or ``deviated`` beside it.

        With ``exc`` (an interrupt that came after the last sample), a failed save is noted on ``exc`` rather
        than raised, so that the interrupt is what the caller sees.
        """
        status = "deviated" if state.deviation else "complete"
        rec = self._recording(state, scenario, rate_hz, status, None)
        if state.deviation:
            rec.meta["deviation"] = state.deviation
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
            exc.complete = True  # type: ignore[attr-defined]
        return rec

    def _recording(
        self, state: _RunState, scenario: dict[str, Any], rate_hz: int, status: str, reason: str | None
    ) -> Recording:
        # The run's samples since its START (a reset board restarts seq: the parser refused those already).
        return recording_of(
            self, scenario, rate_hz, state.started_utc, state.t_go_us, status, reason, list(self.daq.rows)
        )
