"""The live cells' driver: both boards, one pulse of the paper per call -> one recording in ``data/``.

:class:`LiveRig` opens the DAQ and the stepper board (``"virtual"``: the in-process virtual rig; or
``"DAQ,STEPPER"``: device paths or pyserial URLs), waits for each and checks that its firmware speaks this
host's protocol and was built for the selected rig. :meth:`LiveRig.run_pulse` checks the request against the
limits before any byte is sent, waits until the tension is at rest, loads the pulse's programme, starts the
DAQ stream, sends ``GO`` and reads samples until the programme and a margin have passed and ``DONE`` has come.
On any exception (``KeyboardInterrupt`` and SIGTERM included) it sends the stepper ``ABORT`` and ``EN 0`` and
the DAQ ``STOP``, saves what was recorded as ``aborted`` beside the name asked for, and re-raises. A run never
overwrites a recording. Its metadata are those :class:`helpers.rig.Rig` writes for the same run (the full rig,
which the commands use, adds streams, resending over a noisy line, USB discovery and progress bars).
"""

from __future__ import annotations

import datetime as _dt
import math
import os
import warnings
from pathlib import Path
from typing import Any, Self

import numpy as np

from helpers import __version__ as HELPERS_VERSION
from helpers import recordings
from helpers.base.noise import white_noise_std
from helpers.base.signals import run_guard
from helpers.board.programmes import Programme, experiment_programme
from helpers.live.link import BoardError, BoardTimeout, Link
from helpers.live.ports import virtual_source_for
from helpers.live.safety import SafetyError, check_programme, check_request
from helpers.paper import numbers as paper
from helpers.paper.hardware import DAQ_BAUD, MAX_PROGRAMME_S, RIG, STEPPER_BAUD
from helpers.paper.tension import LoadCellCalibration, load_calibration
from helpers.recordings.shaping import pulse_metadata
from helpers.rigfile.recorded import rig_section

REST_WINDOW_S = 0.5
"""Span (s) over which the tension must be steady before a run."""

REST_FACTOR = 2.0
"""Steady: standard deviation over the window <= this factor x the white-noise level (and >= 0.5 count)."""

REST_TIMEOUT_S = 30.0
"""Longest wait (device s) for the tension to become steady."""

SILENCE_S = 2.0
"""Seconds without a sample after which the DAQ board counts as not answering."""

DONE_GRACE_S = 1.0
"""Device seconds after the programme's end by which the stepper board's ``DONE`` must have come."""

RATE_HZ = 1000
"""The DAQ's sample rate in a live run (the paper's 1 kHz)."""

T_END_S = 12.0
"""A live run's programme (and recording) length, s after ``GO``: the paper's 12 s."""


class NotAtRest(BoardError):
    """The tension did not settle before a run (the arm still moves, or the sensor drifts)."""


def utc_now() -> str:
    """The present UTC time to the second, e.g. ``2026-01-02T03:04:05Z``."""
    return _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat().replace("+00:00", "Z")


def rest_of(adc: list[int], rate_hz: int) -> tuple[bool, float, float]:
    """(steady?, std, noise) of the last :data:`REST_WINDOW_S` of ``adc`` (not steady while shorter)."""
    n = max(3, round(REST_WINDOW_S * rate_hz))
    if len(adc) < n:
        return False, float("nan"), float("nan")
    window = np.asarray(adc[-n:], dtype=float)
    std, noise = float(np.std(window)), white_noise_std(window)
    return std <= max(REST_FACTOR * noise, 0.5), std, noise


def pulse_scenario(
    v_in_mm_s: float, x_f_mm: float, shaper: Any, system: str | None, repetition: int, t_end_s: float
) -> tuple[Programme, dict[str, Any]]:
    """Check a pulse request, build its programme, and state it as a recording's scenario.

    The up move starts at ``paper.PULSE_T_UP_S`` (1 s) and the down move at ``paper.PULSE_T_DOWN_S`` (8 s)
    after ``GO``, as in the paper; ``shaper`` is anything
    :func:`~helpers.board.programmes.experiment_programme` takes (None: the unshaped pulse).

    Raises
    ------
    SafetyError
        The request or its programme is outside the limits (nothing has been sent).
    """
    v, x = check_request(v_in_mm_s, x_f_mm)
    if not (isinstance(t_end_s, int | float) and math.isfinite(t_end_s) and 0 < t_end_s <= MAX_PROGRAMME_S):
        raise SafetyError(f"programme length: t_end {t_end_s!r} s is outside (0, {MAX_PROGRAMME_S:.0f}] s")
    try:  # the up and down moves at experiment_programme's default times, the paper's
        programme, report = experiment_programme(v, x, shaper, t_end=t_end_s)
    except ValueError as exc:
        raise SafetyError(f"pulse {v} mm/s, {x} mm refused: {exc}") from None
    check_programme(programme)
    scenario = {
        "kind": "pulse",
        "v_in_mm_s": v,
        "x_f_mm": x,
        **pulse_metadata(shaper, system),
        "repetition": int(repetition),
        "t_up_s": paper.PULSE_T_UP_S,
        "t_down_s": paper.PULSE_T_DOWN_S,
        "quantisation": report.to_dict(),
    }
    return programme, scenario


def recording_of(
    rig: Any,
    scenario: dict[str, Any],
    rate_hz: int,
    started_utc: str,
    t_go_us: int | None,
    status: str,
    reason: str | None,
    rows: list[tuple[int, int, int, int]],
) -> recordings.Recording:
    """A run's recording: its samples since ``START`` and the metadata (``docs/recording_format.md``).

    ``rig`` is a :class:`LiveRig` or a :class:`helpers.rig.Rig`: its ``source``, ``calibration``, the DAQ's
    ``parser.stats`` and both boards' ``version``, the stepper's ``done_position``.
    """
    frame = recordings.frame_from_rows(rows) if rows else recordings.empty_frame()
    stats = rig.daq.parser.stats
    counts = {"samples": len(frame)}
    counts |= {k: int(getattr(stats, k)) for k in ("dropped", "corrupted", "overruns", "implausible")}
    meta = {
        "schema_version": recordings.SCHEMA_VERSION,
        "rig": rig_section(RIG),
        "source": rig.source,
        "scenario": scenario,
        "calibration": rig.calibration.to_dict(),
        "rate_hz": rate_hz,
        "firmware": {"daq": rig.daq.version, "stepper": rig.stepper.version},
        "host": {"helpers": HELPERS_VERSION},
        "started_utc": started_utc,
        "status": status,
        "abort_reason": reason,
        "counts": counts,
        "t_go_us": t_go_us,
        "t_go_s": None if t_go_us is None or not rows else (t_go_us - rows[0][1]) / 1e6,
        "done_position": rig.stepper.done_position,
    }
    return recordings.Recording(frame=frame, meta=meta)


def _urls(ports: str) -> tuple[str, str]:
    if ports == "virtual":
        return "virtual://daq?rig=default", "virtual://stepper?rig=default"
    pair = [p.strip() for p in str(ports).split(",")]
    if len(pair) != 2 or not all(pair):
        hint = " (USB discovery: python -m helpers record ... --ports auto)" if ports == "auto" else ""
        raise ValueError(f"ports must be 'virtual' or two ports 'DAQ,STEPPER', got {ports!r}{hint}")
    return pair[0], pair[1]


class BoardPair:
    """Both boards of a rig (``daq``, ``stepper``), their ports closed on leaving a ``with`` block."""

    daq: Any
    stepper: Any

    def close(self) -> None:
        """Close both ports."""
        self.daq.close()
        self.stepper.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class LiveRig(BoardPair):
    """Both boards of one rig (hardware or virtual) and the load-cell calibration it records with.

    Parameters
    ----------
    ports : str
        ``"virtual"`` (the in-process virtual rig) or ``"DAQ,STEPPER"`` (device paths or pyserial URLs).
    calibration : LoadCellCalibration or dict, optional
        Default :func:`helpers.paper.tension.load_calibration` (a clear error if there is none yet).
    timeout : float
        Seconds a board may take to answer a command.
    """

    def __init__(
        self,
        ports: str = "virtual",
        calibration: LoadCellCalibration | dict | None = None,
        timeout: float = 2.0,
    ) -> None:
        if RIG.n_tendons > 1:
            raise ValueError(
                f"rig '{RIG.name}' has {RIG.n_tendons} tendons: use helpers.rig.tendons.TendonRig"
            )
        daq_url, stepper_url = _urls(ports)
        if isinstance(calibration, dict):
            calibration = LoadCellCalibration.from_dict(calibration)
        self.calibration = load_calibration() if calibration is None else calibration
        self.daq = Link.open(daq_url, "daq", DAQ_BAUD, timeout)
        try:
            self.stepper = Link.open(stepper_url, "stepper", STEPPER_BAUD, timeout)
        except BaseException:
            self.daq.close()
            raise
        world = getattr(self.daq.port, "world", None)
        if world is not None:
            self.source = {"kind": "virtual-rig", "via": "in-process", "rig": world.name, **world.info}
        else:
            self.source = virtual_source_for((daq_url, stepper_url)) or {"kind": "hardware"}
        self.source["ports"] = {"daq": daq_url.split("?")[0], "stepper": stepper_url.split("?")[0]}
        if self.source["kind"] == "hardware" and self.calibration.source == "virtual-rig":
            warnings.warn("hardware, but the load-cell calibration is the virtual rig's", stacklevel=2)

    def run_pulse(
        self,
        v_in_mm_s: float,
        x_f_mm: float,
        *,
        path: str | os.PathLike,
        shaper: Any = None,
        system: str | None = None,
        repetition: int = 1,
        scenario_extra: dict[str, Any] | None = None,
    ) -> recordings.Recording:
        """Run the paper's pulse (up at 1 s, down at 8 s after ``GO``), shaped by ``shaper``, from position 0.

        The run lasts :data:`T_END_S` after ``GO``, sampled at :data:`RATE_HZ`.

        Parameters
        ----------
        v_in_mm_s, x_f_mm : float
            Speed (mm/s) and displacement (mm): refused with :class:`SafetyError` outside the limits.
        path : path-like
            ``data/<group>/<name>``; an existing recording is refused before anything moves.
        shaper : Shaper, optional
            None for the unshaped pulse, else the shaper of both moves.
        system : str, optional
            Its name in :data:`helpers.recordings.shaping.SYSTEMS` (default: the shaper's).
        repetition : int
            Repetition number written into the scenario.
        scenario_extra : dict, optional
            More scenario metadata (e.g. the mode the shaper was designed from).

        Returns
        -------
        helpers.recordings.Recording
            The saved recording (``complete``).
        """
        programme, scenario = pulse_scenario(v_in_mm_s, x_f_mm, shaper, system, repetition, T_END_S)
        scenario.update(scenario_extra or {})
        scenario["programme"] = programme.to_dict()
        target = Path(path).with_suffix(".csv")
        recordings.check_name(target.stem)
        with recordings.reserve(target):  # a second run to this name is refused now, not after this one
            position = int(self.stepper.command("POS").split()[-1])
            if position != 0:
                raise SafetyError(
                    f"the cable is at {position} steps, not at 0: run `python -m helpers home` first"
                )
            scenario["start_position_steps"] = position
            return self._guarded(programme, scenario, target)

    def _start(self) -> None:
        """``STOP`` whatever streams, set the rate and ``START`` a new stream (its ``seq`` from 0)."""
        self.daq.command("STOP")
        self.daq.command(f"RATE {RATE_HZ}")
        self.daq.rows.clear()
        self.daq.parser.restart()
        self.daq.command("START")

    def _stop(self) -> None:
        """``STOP`` the stream; count as dropped the samples it sent that never arrived."""
        sent = int(self.daq.command("STOP").split()[-1])
        last = self.daq.parser.last_seq
        self.daq.parser.stats.dropped += max(0, sent - (0 if last is None else last + 1))

    def _read(self, silence: Any) -> Any:
        """Read both boards once; a reset, or no sample for :data:`SILENCE_S`, raises."""
        before = len(self.daq.rows)
        self.daq.read(silence)
        self.stepper.read(block=False)
        self.daq.check_reset()
        self.stepper.check_reset()
        if len(self.daq.rows) > before:
            return self.daq.waiter(SILENCE_S)
        if silence.expired:
            raise BoardTimeout(f"the daq board sent no sample for {SILENCE_S:.1f} s (it stopped answering)")
        return silence

    def _wait_for_rest(self) -> dict[str, Any]:
        """Stream until the tension is steady (:func:`rest_of`); :class:`NotAtRest` after the timeout."""
        self._start()
        silence = self.daq.waiter(SILENCE_S)
        while True:
            silence = self._read(silence)
            rows = self.daq.rows
            steady, std, noise = rest_of([r[2] for r in rows[-RATE_HZ:]], RATE_HZ)
            waited = (rows[-1][1] - rows[0][1]) / 1e6 if rows else 0.0
            if steady:
                self._stop()
                return {"waited_s": round(waited, 3), "std_counts": std, "noise_counts": noise}
            if waited > REST_TIMEOUT_S:
                raise NotAtRest(
                    f"the tension did not come to rest within {REST_TIMEOUT_S:.0f} s (std {std:.2f} "
                    f"counts against a noise of {noise:.2f}): is the arm still moving?"
                )

    def _pulse(self, programme: Any, scenario: dict[str, Any], run: dict[str, Any]) -> None:
        """Wait for rest, load the programme, start the DAQ, ``GO``, read until the end and ``DONE``."""
        scenario["rest"] = self._wait_for_rest()
        self.stepper.command("ABORT")  # a programme left running by an earlier session stops
        for line in programme.commands():  # CLEAR first: loading starts from nothing
            self.stepper.command(line)
        self.daq.command("ZERO")
        self._start()
        run["go"] = True  # from here on the DAQ's rows are this run's
        self.stepper.command("EN 1")
        self.stepper.done_position = None
        self.stepper.command("GO")
        self.daq.read(block=False)  # GO's device time: the newest sample at hand once GO is acknowledged
        run["t_go_us"] = self.daq.rows[-1][1] if self.daq.rows else None
        silence, end_us = self.daq.waiter(SILENCE_S), programme.duration_us
        while True:
            before = len(self.daq.rows)
            silence = self._read(silence)
            rows = self.daq.rows
            if run["t_go_us"] is None and len(rows) > before:
                run["t_go_us"] = rows[before][1] - round(1e6 / RATE_HZ)
            late_us = rows[-1][1] - run["t_go_us"] - end_us if rows and run["t_go_us"] is not None else -1
            if late_us >= 0.1e6 and self.stepper.done_position is not None:
                break
            if late_us >= DONE_GRACE_S * 1e6:
                raise BoardTimeout(
                    f"the stepper board did not report DONE within {DONE_GRACE_S:.1f} s of "
                    "device time after the programme's end (it stopped answering)"
                )
        self._stop()
        self.stepper.command("EN 0")

    def _cleanup(self) -> list[str]:
        """``ABORT`` and ``EN 0`` to the stepper, ``STOP`` to the DAQ; the problems met (it never raises)."""
        problems = []
        for board, body in ((self.stepper, "ABORT"), (self.stepper, "EN 0"), (self.daq, "STOP")):
            board.hello = 0  # a rebooted board still takes the command
            try:
                board.command(body, timeout=2.0)
            except (Exception, KeyboardInterrupt) as exc:  # noqa: BLE001 - cleanup must go on
                problems.append(f"{body} to the {board.kind} board failed: {type(exc).__name__}: {exc}")
        return problems

    def _guarded(self, programme: Any, scenario: dict[str, Any], target: Path) -> recordings.Recording:
        """Run :meth:`_pulse` so that every way it ends leaves the boards safe and its recording on disk.

        On an exception, the stepper is stopped and disabled and what was recorded is saved as ``aborted``
        beside ``target``; the exception goes on carrying ``saved_path`` (None, with ``save_error``, if the
        save failed) and ``cleanup`` (the problems the cleanup met). A signal that comes once the run has
        ended is held until the recording is saved.
        """
        run: dict[str, Any] = {"started_utc": utc_now(), "t_go_us": None, "go": False}
        with run_guard() as guard:
            try:
                with guard.interruptible():
                    self._pulse(programme, scenario, run)
            except BaseException as exc:
                problems = self._cleanup()
                reason = f"{type(exc).__name__}: {exc}"
                reason += " | cleanup: " + "; ".join(problems) if problems else ""
                rec = self._recording(scenario, run, "aborted", reason)
                exc.cleanup, exc.saved_path, exc.save_error = problems, None, None  # type: ignore[attr-defined]
                aborted = recordings.aborted_path(target, run["started_utc"])
                try:
                    exc.saved_path = recordings.save(rec, aborted)  # type: ignore[attr-defined]
                except (recordings.RecordingError, OSError) as save_exc:
                    exc.save_error = str(save_exc)  # type: ignore[attr-defined]
                raise
            rec = self._recording(scenario, run, "complete", None)
            recordings.save(rec, target)
        return rec.derive()

    def _recording(
        self, scenario: dict[str, Any], run: dict[str, Any], status: str, reason: str | None
    ) -> recordings.Recording:
        rows = list(self.daq.rows) if run["go"] else []  # the run's samples since its START
        return recording_of(self, scenario, RATE_HZ, run["started_utc"], run["t_go_us"], status, reason, rows)
