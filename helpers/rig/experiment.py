"""The coordinated experiment: :class:`Rig` runs one board-timed programme per call and returns a recording.

A whole Up-hold-Down experiment is one stepper programme (lead-in dwell, up segments, hold, down segments,
trailing dwell), so its timing is the stepper board's, not the host's. :meth:`Rig.run` loads the programme,
zeroes and starts the DAQ, enables the driver and sends ``GO``; then it reads DAQ lines until the device time
has passed the programme's end (``GO``'s device time + duration + a margin) and ``DONE`` has arrived. It never
times anything with sleeps, which is also what lets the in-process virtual rig run faster than real time.

Every run sits in a guard: on any exception (``KeyboardInterrupt`` included) the stepper is sent ``ABORT`` and
``EN 0`` and the DAQ ``STOP``, and what was recorded is saved marked ``aborted`` with the reason; the
exception is then re-raised with the saved :class:`helpers.recordings.Recording` attached as
``exc.recording``. Requests outside the safety limits raise :class:`helpers.rig.safety.SafetyError` before
any byte is sent.
"""

from __future__ import annotations

import datetime as _dt
import math
import os
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tqdm import tqdm

from helpers import __version__ as HELPERS_VERSION
from helpers import paper, recordings
from helpers.hardware import DAQ_RATE_MAX_HZ, DAQ_RATE_MIN_HZ, MAX_PROGRAMME_S
from helpers.loadcell import LoadCellCalibration, load_calibration
from helpers.paths import DATA_DIR
from helpers.programmes import Programme, experiment_programme
from helpers.recordings import Recording
from helpers.rig.boards import BoardError, BoardLink, BoardTimeout, Waiter
from helpers.rig.daq import DaqBoard
from helpers.rig.discovery import find_rig_ports, virtual_source_for
from helpers.rig.safety import SafetyError, check_programme, check_request
from helpers.rig.stepper import StepperBoard


class RunAborted(BoardError):
    """The run was stopped because its data were unusable (e.g. mostly corrupted lines)."""


@dataclass
class _RunState:
    rows: list[tuple[int, int, int, int]] = field(default_factory=list)
    t_go_us: int | None = None
    go_sent: bool = False
    started_utc: str = ""


def _utc_now() -> str:
    return _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat().replace("+00:00", "Z")


def _is_virtual_url(url: str) -> bool:
    return str(url).startswith("virtual://")


def _check_rate(rate_hz: Any) -> None:
    ok = isinstance(rate_hz, int) and not isinstance(rate_hz, bool)
    if not (ok and DAQ_RATE_MIN_HZ <= rate_hz <= DAQ_RATE_MAX_HZ):
        raise SafetyError(
            f"DAQ rate must be an integer in {DAQ_RATE_MIN_HZ}-{DAQ_RATE_MAX_HZ} Hz, got {rate_hz!r}"
        )


class _DeviceTimeBar:
    """A tqdm bar of device seconds, updated in 0.1 s increments."""

    def __init__(self, total_s: float, show: bool, desc: str | None = "device time") -> None:
        self.bar = tqdm(
            total=round(total_s, 1),
            unit="s",
            desc=desc,
            disable=not show,
            bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} s",
        )
        self.shown = 0.0

    def show(self, elapsed_s: float) -> None:
        if elapsed_s - self.shown >= 0.1:
            self.bar.update(round(elapsed_s - self.shown, 1))
            self.shown += round(elapsed_s - self.shown, 1)

    def close(self) -> None:
        self.bar.close()


class Rig:
    """Both boards of one rig (hardware or virtual) and the calibration that turns counts into newtons.

    Parameters
    ----------
    daq : DaqBoard
        The synchronised DAQ driver.
    stepper : StepperBoard
        The synchronised stepper driver.
    calibration : LoadCellCalibration or dict, optional
        The load-cell calibration; default :func:`helpers.loadcell.load_calibration` (which raises a clear
        error if there is none yet: pass :data:`helpers.loadcell.UNCALIBRATED` to record without one).
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
        self.cleanup_timeout = 0.5
        self.last_cleanup: list[str] = []

    # --- connecting ------------------------------------------------------------------------------
    @classmethod
    def connect(
        cls,
        ports: str | tuple[str, str] | list[str] = "virtual",
        rig_name: str = "default",
        calibration: LoadCellCalibration | dict[str, Any] | None = None,
        timeout: float = 2.0,
        hello_timeout: float = 3.0,
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
            Default :func:`helpers.loadcell.load_calibration`.
        timeout, hello_timeout : float
            Command timeout and boot timeout (s).
        daq_options, stepper_options : str
            Extra ``&key=value`` URL options for the virtual boards (faults, seed).

        Returns
        -------
        Rig
        """
        if ports == "virtual":
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

    def close(self) -> None:
        """Close both ports."""
        self.daq.close()
        self.stepper.close()

    def __enter__(self) -> Rig:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

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
        **kwargs: Any,
    ) -> Recording:
        """Check a pulse request, build its programme (:func:`~helpers.programmes.experiment_programme`), run.

        The up move starts at ``paper.PULSE_T_UP_S`` (1 s) and the down move at ``paper.PULSE_T_DOWN_S``
        (8 s) after ``GO``, as in the paper.

        Parameters
        ----------
        v_in_mm_s, x_f_mm : float
            Speed (mm/s) and displacement (mm); refused with :class:`SafetyError` outside the limits.
        shaper : helpers.shapers.Shaper, optional
            None for the unshaped pulse.
        system : str, optional
            ``"unshaped"``, ``"zv"`` or ``"zvd"`` (default from the shaper's name).
        path : path-like, optional
            Where to save.
        repetition : int
            Repetition number written into the scenario.
        t_end_s : float
            Programme end (s from ``GO``); the recording lasts that long.
        scenario_extra : dict, optional
            More scenario metadata (e.g. the identified mode the shaper was designed from).
        **kwargs
            Passed to :meth:`run`.
        """
        v, x = check_request(v_in_mm_s, x_f_mm)
        t_up, t_down = paper.PULSE_T_UP_S, paper.PULSE_T_DOWN_S
        try:
            programme, report = experiment_programme(v, x, shaper, t_up=t_up, t_down=t_down, t_end=t_end_s)
        except ValueError as exc:
            raise SafetyError(f"pulse {v} mm/s, {x} mm refused: {exc}") from None
        name = getattr(shaper, "name", None)
        scenario = {
            "kind": "pulse",
            "v_in_mm_s": v,
            "x_f_mm": x,
            "system": system or ("unshaped" if shaper is None else str(name or "shaped")),
            "shaper": None
            if shaper is None
            else {
                "name": name,
                "amplitudes": [float(a) for a in shaper.amplitudes],
                "times": [float(t) for t in shaper.times],
            },
            "repetition": int(repetition),
            "t_up_s": t_up,
            "t_down_s": t_down,
            "quantisation": report.to_dict(),
            **(scenario_extra or {}),
        }
        return self.run(programme, scenario=scenario, path=path, **kwargs)

    def run(
        self,
        programme: Programme,
        scenario: dict[str, Any] | None = None,
        path: str | os.PathLike | None = None,
        rate_hz: int = 1000,
        margin_s: float = 0.1,
        done_grace_s: float = 1.0,
        silence_timeout: float = 2.0,
        progress: bool = True,
        max_corrupted_fraction: float = 0.05,
    ) -> Recording:
        """Run one programme as one board-timed experiment and return (and save) its recording.

        The steps: check the programme against the limits from the cable's present position
        (:meth:`_checked_start_position`), load it and start the DAQ (:meth:`_load_and_go`), stream samples
        until the programme's end has passed and ``DONE`` has arrived (:meth:`_stream_until_done`), then stop
        the DAQ and disable the driver. All of it inside the guard (:meth:`_guarded`).

        Parameters
        ----------
        programme : helpers.programmes.Programme
            Checked against the limits before anything is sent.
        scenario : dict, optional
            Scenario metadata (kind, v_in_mm_s, x_f_mm, system, shaper, repetition, ...); the programme is
            added.
        path : path-like, optional
            ``data/<group>/<name>``; default ``data/runs/run_<UTC time>``.
        rate_hz : int
            DAQ sample rate.
        margin_s : float
            Device time recorded after the programme's end.
        done_grace_s : float
            Device time after the end by which ``DONE`` must have arrived.
        silence_timeout : float
            Seconds without a sample after which the DAQ counts as not answering.
        progress : bool
            Show a tqdm bar of device time.
        max_corrupted_fraction : float
            Abort when more than this fraction of lines (and more than 50) are corrupted.

        Returns
        -------
        helpers.recordings.Recording
        """
        check_programme(programme)
        _check_rate(rate_hz)
        scenario = dict(scenario or {"kind": "programme"})
        scenario.setdefault("programme", programme.to_dict())
        position = self._checked_start_position(programme)

        def body(state: _RunState) -> None:
            self._load_and_go(programme, position, rate_hz, state)
            bar = _DeviceTimeBar(programme.duration_s + margin_s, progress)
            try:
                self._stream_until_done(
                    state, programme.duration_us, rate_hz, margin_s, done_grace_s, silence_timeout,
                    max_corrupted_fraction, bar,
                )  # fmt: skip
            finally:
                bar.close()
            self.daq.stop()
            state.rows.extend(self.daq.take_rows())
            self.stepper.enable(False)

        return self._guarded(body, scenario, path, rate_hz)

    def _checked_start_position(self, programme: Programme) -> int:
        """Ask the stepper where the cable is (``POS`` moves nothing) and check the programme from there."""
        self.stepper.check_reset()
        self.daq.check_reset()
        position = self.stepper.position()
        check_programme(programme, start_position=position)
        return position

    def _load_and_go(self, programme: Programme, position: int, rate_hz: int, state: _RunState) -> None:
        """Stop what an earlier session left running, load the programme, start the DAQ, enable, ``GO``."""
        self.stepper.abort()  # a programme left running by an earlier session stops; driver off
        self.daq.stop()  # a stream left running by an earlier session stops (OK STOP 0 when idle)
        self.stepper.load(programme, start_position=position)
        self.daq.set_rate(rate_hz)
        self.daq.zero()
        self.daq.start()
        self.stepper.enable(True)
        state.go_sent = True
        self.stepper.go()
        # GO's device time, estimated as the newest DAQ sample at hand once GO is acknowledged (exact
        # on the in-process virtual rig; a few ms late on hardware). Metrics use `steps` instead.
        self.daq.pump(block=False)
        state.rows.extend(self.daq.take_rows())
        if state.rows:
            state.t_go_us = state.rows[-1][1]

    def _check_corruption(self, max_corrupted_fraction: float) -> None:
        stats = self.daq.stats
        if stats.corrupted > 50 and stats.corrupted > max_corrupted_fraction * (stats.samples + 1):
            raise RunAborted(
                f"{stats.corrupted} corrupted lines against {stats.samples} samples "
                "(wrong baud rate or a bad cable?)"
            )

    def _stream_until_done(
        self,
        state: _RunState,
        duration_us: int,
        rate_hz: int,
        margin_s: float,
        done_grace_s: float,
        silence_timeout: float,
        max_corrupted_fraction: float,
        bar: _DeviceTimeBar,
    ) -> None:
        """Read samples until the programme's end + ``margin_s`` has passed and ``DONE`` has arrived."""
        period_us = round(1e6 / rate_hz)
        silence = Waiter(silence_timeout)
        while True:
            self.daq.pump()
            rows = self.daq.take_rows()
            state.rows.extend(rows)  # on disk whatever happens next
            self.daq.check_reset()
            self.stepper.poll()
            self.stepper.check_reset()
            if rows:
                silence = Waiter(silence_timeout)
                if state.t_go_us is None:
                    state.t_go_us = rows[0][1] - period_us
            else:
                silence.idle(self.daq.port.timeout or 0.0)
                if silence.expired:
                    raise BoardTimeout(
                        f"the daq board sent no sample for {silence_timeout:.1f} s (it stopped answering)"
                    )
            self._check_corruption(max_corrupted_fraction)
            if state.t_go_us is None or not state.rows:
                continue
            last_us = state.rows[-1][1]
            bar.show((last_us - state.t_go_us) / 1e6)
            past_end = last_us >= state.t_go_us + duration_us + margin_s * 1e6
            if past_end and self.stepper.done_position is not None:
                return
            overdue = last_us >= state.t_go_us + duration_us + done_grace_s * 1e6
            if self.stepper.done_position is None and overdue:
                raise BoardTimeout(
                    f"the stepper board did not report DONE within {done_grace_s:.1f} s of device time "
                    "after the programme's end (it stopped answering)"
                )

    def record_static(
        self,
        duration_s: float,
        scenario: dict[str, Any],
        path: str | os.PathLike | None = None,
        rate_hz: int = 1000,
        silence_timeout: float = 2.0,
        progress: bool = False,
    ) -> Recording:
        """Record ``duration_s`` of device time with the motor idle (load-cell calibration, noise floor).

        Parameters
        ----------
        duration_s : float
            Device seconds to record (0 < duration <= ``MAX_PROGRAMME_S``).
        scenario : dict
            Scenario metadata (e.g. ``{"kind": "calibration", "load_n": 4.9}``).
        path : path-like, optional
            Where to save.
        rate_hz : int
            DAQ sample rate.
        silence_timeout : float
            Seconds without a sample after which the DAQ counts as not answering.
        progress : bool
            Show a tqdm bar.
        """
        if (
            not isinstance(duration_s, int | float)
            or not math.isfinite(duration_s)
            or not 0 < duration_s <= MAX_PROGRAMME_S
        ):
            raise SafetyError(f"duration must be within (0, {MAX_PROGRAMME_S:.0f}] s, got {duration_s!r}")
        _check_rate(rate_hz)

        def body(state: _RunState) -> None:
            self.daq.check_reset()
            self.daq.stop()  # a stream left running by an earlier session stops (OK STOP 0 when idle)
            self.daq.set_rate(rate_hz)
            self.daq.start()
            bar = _DeviceTimeBar(duration_s, progress, desc=None)
            try:
                for rows in self.daq.samples(silence_timeout):
                    state.rows.extend(rows)
                    if state.t_go_us is None:
                        state.t_go_us = rows[0][1] - round(1e6 / rate_hz)
                    if state.rows[-1][1] - state.t_go_us >= duration_s * 1e6:
                        break
            finally:
                bar.close()
            self.daq.stop()
            state.rows.extend(self.daq.take_rows())

        return self._guarded(body, dict(scenario), path, rate_hz, stepper_used=False)

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
            board.hello_seen = 0  # a rebooted board still takes the command
            try:
                fn()
            except (Exception, KeyboardInterrupt) as exc:  # noqa: BLE001 - cleanup must go on
                problems.append(f"{what} to the {board.kind} board failed: {type(exc).__name__}: {exc}")
        return problems

    def _guarded(
        self,
        body: Callable[[_RunState], None],
        scenario: dict[str, Any],
        path: str | os.PathLike | None,
        rate_hz: int,
        stepper_used: bool = True,
    ) -> Recording:
        state = _RunState(started_utc=_utc_now())
        target = (
            Path(path)
            if path is not None
            else DATA_DIR / "runs" / ("run_" + state.started_utc.replace(":", "").replace("-", ""))
        )
        try:
            body(state)
        except BaseException as exc:
            self.last_cleanup = self._cleanup(stepper_used)
            state.rows.extend(self.daq.take_rows())
            reason = f"{type(exc).__name__}: {exc}"
            if self.last_cleanup:
                reason += " | cleanup: " + "; ".join(self.last_cleanup)
            rec = self._recording(state, scenario, rate_hz, "aborted", reason)
            try:
                recordings.save(rec, target)
            except Exception as save_exc:  # noqa: BLE001 - keep the original error
                reason += f" | could not save: {save_exc}"
            exc.recording = rec.derive()  # type: ignore[attr-defined]
            raise
        self.last_cleanup = []
        rec = self._recording(state, scenario, rate_hz, "complete", None)
        recordings.save(rec, target)
        return rec.derive()

    def _recording(
        self, state: _RunState, scenario: dict[str, Any], rate_hz: int, status: str, reason: str | None
    ) -> Recording:
        # Keep only rows that can be placed (a reset board restarts seq); the parser already refused those.
        frame = recordings.frame_from_rows(state.rows) if state.rows else recordings.empty_frame()
        stats = self.daq.stats
        first_t = int(frame["t_us"].iloc[0]) if len(frame) else None
        meta = {
            "schema_version": recordings.SCHEMA_VERSION,
            "source": self.source,
            "scenario": scenario,
            "calibration": self.calibration.to_dict(),
            "rate_hz": rate_hz,
            "firmware": {"daq": self.daq.version, "stepper": self.stepper.version},
            "host": {"helpers": HELPERS_VERSION},
            "started_utc": state.started_utc,
            "status": status,
            "abort_reason": reason,
            "counts": {
                "samples": len(frame),
                "dropped": int(stats.dropped),
                "corrupted": int(stats.corrupted),
                "overruns": int(stats.overruns),
            },
            "t_go_us": state.t_go_us,
            "t_go_s": None if (state.t_go_us is None or first_t is None) else (state.t_go_us - first_t) / 1e6,
            "done_position": self.stepper.done_position,
        }
        return Recording(frame=frame, meta=meta)
