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
import json
import os
import tempfile
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from helpers import __version__ as HELPERS_VERSION
from helpers import recordings
from helpers.paths import DATA_DIR
from helpers.profiles import MM_PER_STEP, Programme, experiment_programme
from helpers.recordings import Recording
from helpers.rig.boards import BoardError, BoardLink, BoardTimeout, Waiter
from helpers.rig.daq import DaqBoard
from helpers.rig.safety import SafetyError, check_programme, check_request
from helpers.rig.stepper import StepperBoard

VIRTUAL_REGISTRY = Path(tempfile.gettempdir()) / "helpers-virtual-rigs"
"""Where ``python -m helpers serve-virtual-rig`` announces its pseudo-terminals (so recordings made through
them are labelled ``virtual-rig``, never ``hardware``)."""

UNCALIBRATED = {
    "newtons_per_count": 1.0,
    "offset_counts": 0.0,
    "mm_per_step": MM_PER_STEP,
    "origin": "uncalibrated: tension_n equals adc counts",
}
"""Placeholder calibration when none is available (clearly labelled)."""


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


def announced_virtual_rigs() -> list[dict[str, Any]]:
    """Return the announcements of running ``serve-virtual-rig`` processes (dead ones are ignored)."""
    out = []
    if not VIRTUAL_REGISTRY.is_dir():
        return out
    for f in VIRTUAL_REGISTRY.glob("*.json"):
        try:
            info = json.loads(f.read_text())
            os.kill(int(info["pid"]), 0)
        except (OSError, ValueError, KeyError, json.JSONDecodeError):
            continue
        out.append(info)
    return out


def _virtual_source_for(paths: tuple[str, str]) -> dict[str, Any] | None:
    real = {os.path.realpath(p) for p in paths}
    for info in announced_virtual_rigs():
        if {os.path.realpath(info["daq"]), os.path.realpath(info["stepper"])} & real:
            return {"kind": "virtual-rig", "via": "pseudo-terminal server", **info.get("source", {})}
    return None


def load_calibration(path: str | os.PathLike | None = None) -> dict[str, Any]:
    """Read the load-cell calibration (``data/calibration/calibration.json`` by default).

    Returns
    -------
    dict
        ``newtons_per_count``, ``offset_counts``, ``mm_per_step`` and ``origin``; :data:`UNCALIBRATED` if the
        file does not exist.
    """
    p = Path(path) if path is not None else DATA_DIR / "calibration" / "calibration.json"
    if not p.exists():
        return dict(UNCALIBRATED)
    data = json.loads(p.read_text())
    rel = p.relative_to(DATA_DIR).as_posix() if p.is_relative_to(DATA_DIR) else p.name
    return {
        "newtons_per_count": float(data["newtons_per_count"]),
        "offset_counts": float(data["offset_counts"]),
        "mm_per_step": float(data.get("mm_per_step", MM_PER_STEP)),
        "origin": f"data/{rel}",
        "source": data.get("source", {}).get("kind", "unknown"),
    }


class Rig:
    """Both boards of one rig (hardware or virtual) and the calibration that turns counts into newtons.

    Parameters
    ----------
    daq : DaqBoard
        The synchronised DAQ driver.
    stepper : StepperBoard
        The synchronised stepper driver.
    calibration : dict, optional
        ``newtons_per_count``, ``offset_counts``, ``mm_per_step``, ``origin``; default
        :func:`load_calibration`.
    source : dict, optional
        Provenance written into every recording; default ``{"kind": "hardware"}``.
    """

    def __init__(
        self,
        daq: DaqBoard,
        stepper: StepperBoard,
        calibration: dict[str, Any] | None = None,
        source: dict[str, Any] | None = None,
    ) -> None:
        self.daq = daq
        self.stepper = stepper
        self.calibration = dict(calibration) if calibration is not None else load_calibration()
        self.source = dict(source) if source is not None else {"kind": "hardware"}
        if self.source.get("kind") == "hardware" and self.calibration.get("source") == "virtual-rig":
            # the raw ADC counts are recorded either way, so tension can be recomputed after calibrating
            warnings.warn(
                "this is hardware, but the load-cell calibration "
                f"({self.calibration.get('origin', '?')}) was recorded on the virtual rig: tension_n will be "
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
        calibration: dict[str, Any] | None = None,
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
        calibration : dict, optional
            Default :func:`load_calibration`.
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
            from helpers.rig.discovery import find_rig_ports

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
            source = _virtual_source_for((daq_url, stepper_url)) or {"kind": "hardware"}
        source["ports"] = {"daq": daq_url.split("?")[0], "stepper": stepper_url.split("?")[0]}
        return cls(daq, stepper, calibration=calibration, source=source)

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
        """Check a pulse request, build its programme (:func:`helpers.profiles.experiment_programme`), run it.

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
        try:
            programme, report = experiment_programme(v, x, shaper, t_end=t_end_s)
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
            "t_up_s": 1.0,
            "t_down_s": 8.0,
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

        Parameters
        ----------
        programme : helpers.profiles.Programme
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
        if not isinstance(rate_hz, int) or isinstance(rate_hz, bool) or not 100 <= rate_hz <= 2000:
            raise SafetyError(f"DAQ rate must be an integer in 100-2000 Hz, got {rate_hz!r}")
        scenario = dict(scenario or {"kind": "programme"})
        scenario.setdefault("programme", programme.to_dict())
        duration_us = programme.duration_us
        total_s = programme.duration_s + margin_s

        from tqdm import tqdm

        # The travel limit depends on where the cable is now: ask (POS moves nothing), refuse before the run.
        self.stepper.check_reset()
        self.daq.check_reset()
        position = self.stepper.position()
        check_programme(programme, start_position=position)

        def body(state: _RunState) -> None:
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
            period_us = round(1e6 / rate_hz)
            bar = tqdm(
                total=round(total_s, 1),
                unit="s",
                desc="device time",
                disable=not progress,
                bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} s",
            )
            shown = 0.0
            silence = Waiter(silence_timeout)
            try:
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
                                f"the daq board sent no sample for {silence_timeout:.1f} s "
                                "(it stopped answering)"
                            )
                    stats = self.daq.stats
                    if stats.corrupted > 50 and stats.corrupted > max_corrupted_fraction * (
                        stats.samples + 1
                    ):
                        raise RunAborted(
                            f"{stats.corrupted} corrupted lines against {stats.samples} samples "
                            "(wrong baud rate or a bad cable?)"
                        )
                    if state.t_go_us is None or not state.rows:
                        continue
                    elapsed_s = (state.rows[-1][1] - state.t_go_us) / 1e6
                    if elapsed_s - shown >= 0.1:
                        bar.update(round(elapsed_s - shown, 1))
                        shown += round(elapsed_s - shown, 1)
                    past_end = state.rows[-1][1] >= state.t_go_us + duration_us + margin_s * 1e6
                    if past_end and self.stepper.done_position is not None:
                        break
                    if (
                        self.stepper.done_position is None
                        and state.rows[-1][1] >= state.t_go_us + duration_us + done_grace_s * 1e6
                    ):
                        raise BoardTimeout(
                            "the stepper board did not report DONE within "
                            f"{done_grace_s:.1f} s of device time "
                            "after the programme's end (it stopped answering)"
                        )
            finally:
                bar.close()
            self.daq.stop()
            state.rows.extend(self.daq.take_rows())
            self.stepper.enable(False)

        return self._guarded(body, scenario, path, rate_hz)

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
            Device seconds to record (0 < duration <= 600).
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
        import math

        if (
            not isinstance(duration_s, (int, float))
            or not math.isfinite(duration_s)
            or not 0 < duration_s <= 600
        ):
            raise SafetyError(f"duration must be within (0, 600] s, got {duration_s!r}")
        if not isinstance(rate_hz, int) or isinstance(rate_hz, bool) or not 100 <= rate_hz <= 2000:
            raise SafetyError(f"DAQ rate must be an integer in 100-2000 Hz, got {rate_hz!r}")

        from tqdm import tqdm

        def body(state: _RunState) -> None:
            self.daq.check_reset()
            self.daq.stop()  # a stream left running by an earlier session stops (OK STOP 0 when idle)
            self.daq.set_rate(rate_hz)
            self.daq.start()
            bar = tqdm(total=round(duration_s, 1), unit="s", disable=not progress)
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
            "calibration": self.calibration,
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
