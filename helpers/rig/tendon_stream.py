"""Streams for a rig with several tendons: per-tendon velocity set-points, shaped on the stepper board.

:meth:`TendonStreamRig.stream` sends one set-point per tendon and 10 ms control period (``MV <v_0> ...``, one
per period at 100 Hz of device time, paced as :class:`~helpers.rig.stream.Pacer` paces a one-tendon stream);
the board shapes every tendon with the one loaded shaper (``firmware/PROTOCOL.md``, streaming mode, *several
tendons*). Every channel is recorded, and the recording (``schema_version`` 3) says in ``scenario.kind`` that
it is a ``stream``, with the set-points and the periods the board gave them in ``scenario.stream``.

Before any byte is sent, :func:`check_tendon_stream` refuses, in one line naming the tendon and the figure
(:class:`~helpers.rig.safety.SafetyError`, exit status 3; ``docs/safety.md``):

- a set-point that is not a finite number or is beyond the stream's speed limit, a shape other than
  (periods, tendons), an empty stream or one longer than the host's ``max_programme_s``;
- a tendon whose integrated set-points (the commanded cable, from its present position) leave its travel
  (``-release..travel``: a tendon pays out at most the rig file's ``release_mm`` below position 0, its rest);
- a period whose commanded state has every tendon slack by the rig file's statics (``pretension_n_i +
  cable_stiffness_n_m_i * pull_i <= 0`` for every tendon: :func:`~helpers.rig.tendon_safety.static_tensions`,
  the rule programmes are checked by);
- unless ``allow_clamps``, a shaped motion (the board's own planner,
  :class:`~helpers.board.stream_reference.AxesRun`) that the board would clamp at a tendon's travel or at the
  speed limit.

During the stream a board reset or silence, the watchdog (:class:`~helpers.rig.stream.StreamStarved`), a
clamp the board reports unless ``allow_clamps`` (:class:`~helpers.rig.stream.StreamLimit`), any exception or
Ctrl-C stop it as a one-tendon stream is stopped: ``ABORT``, ``EN 0``, the DAQ's ``STOP``, and what was
recorded is saved under an aborted name (the exception carries ``recording``, ``saved_path`` and
``cleanup``).
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from helpers import recordings
from helpers.base.paths import DATA_DIR
from helpers.board import stream_reference as hs
from helpers.live.driver import utc_now
from helpers.recordings import Recording, RecordingError, reserve
from helpers.rig.boards import BoardError, BoardTimeout, CommandRefused, Waiter
from helpers.rig.safety import SafetyError
from helpers.rig.stepper import last_int
from helpers.rig.stream import STREAM_RATE_HZ, Pacer, StreamLimit, refuse_notice
from helpers.rig.tendon_safety import static_tensions, travel_text
from helpers.rig.tendons import TendonRig, tendon_frame, tendon_recording, with_twin_tip
from helpers.rigfile import RigFile
from helpers.rigfile.derived import derived

__all__ = ["TendonStreamPlan", "TendonStreamRig", "check_tendon_stream", "tendon_units"]

STEPS_PER_UNIT_PERIOD = hs.PERIOD / (1 << 16)
"""Steps one set-point unit moves in one control period (625 DELTA x 2^-16 step per DELTA)."""

_FEED_READ_S = 0.005
"""The DAQ's read timeout during a stream (s): device time advances in steps under a control period."""


def _v_max(rig: RigFile) -> int:
    """The build's set-point limit: ``floor(2^20 / RIG_MIN_INTERVAL_US)`` (1640 for 639 us)."""
    return min(hs.V_MAX, (1 << 20) // derived(rig).min_interval_us)


def tendon_units(setpoints: Any, rig: RigFile) -> np.ndarray:
    """Cable speeds (mm/s, + pulls; shape (periods, tendons)) as board set-points, checked.

    Raises
    ------
    SafetyError
        One line: the shape, an empty or too long stream, or the first set-point (tendon 1.., period 0..)
        that is not finite or beyond the speed limit.
    """
    n = rig.n_tendons
    try:
        a = np.asarray(setpoints, dtype=float)
    except (TypeError, ValueError):
        raise SafetyError(
            f"set-points must be numbers (cable speeds in mm/s), one row of {n} per period"
        ) from None
    if a.ndim != 2 or a.shape[1] != n:
        raise SafetyError(f"set-points of shape {a.shape}: expected (periods, {n}), one speed per tendon")
    if not len(a):
        raise SafetyError("no set-points: the stream is empty")
    limit_s = rig.hardware.max_programme_s
    if len(a) > limit_s * STREAM_RATE_HZ:
        raise SafetyError(
            f"{len(a)} set-points last {len(a) / STREAM_RATE_HZ:.0f} s, over the host's limit of "
            f"{limit_s:.0f} s"
        )
    mm_per_step = np.asarray(derived(rig).mm_per_step, dtype=float)
    bad = ~np.isfinite(a)
    if bad.any():
        k, i = np.argwhere(bad)[0]
        raise SafetyError(f"tendon {i + 1}, set-point {k}: {a[k, i]} mm/s is not finite")
    with np.errstate(invalid="ignore", over="ignore"):
        u = np.rint(a / mm_per_step / hs.STEPS_PER_S_PER_UNIT)
    v_max = _v_max(rig)
    over = np.abs(u) > v_max
    if over.any():
        k, i = np.argwhere(over)[0]
        limit = v_max * hs.STEPS_PER_S_PER_UNIT * mm_per_step[i]
        raise SafetyError(
            f"tendon {i + 1}, set-point {k}: {a[k, i]:g} mm/s exceeds the stream's speed limit of "
            f"{limit:.1f} mm/s ({v_max} board units)"
        )
    return u.astype(np.int64)


@dataclass(frozen=True)
class TendonStreamPlan:
    """A stream checked before it is sent: its set-points (board units) and what the board will do."""

    units: np.ndarray
    """Set-points, shape (periods, tendons)."""
    start: tuple[int, ...]
    end: tuple[int, ...]
    """Every tendon's position when the board's shaped motion is over (the planner's)."""
    reach: tuple[tuple[int, int], ...]
    """Each tendon's lowest and highest step count on the way."""
    q_max: int
    """Whole control periods in the shaper's longest delay."""


def check_tendon_stream(
    units: np.ndarray,
    rig: RigFile,
    start: tuple[int, ...],
    shaper: hs.StreamShaper,
    allow_clamps: bool = False,
) -> TendonStreamPlan:
    """Check a stream against every tendon's limits and their combination; plan it (module docstring).

    Raises
    ------
    SafetyError
        One line naming the tendon and the figure.
    """
    n = rig.n_tendons
    d = derived(rig)
    if len(start) != n:
        raise SafetyError(f"{len(start)} start positions for the rig's {n} tendons")
    if max(shaper.delays_us) > hs.MAX_DELAY_US_AXES and n > 1:
        raise SafetyError(
            f"the shaper's last impulse at {shaper.delays_us[-1] / 1e6:.3f} s is beyond the "
            f"{hs.MAX_DELAY_US_AXES / 1e6:.2f} s a stepper board with several axes holds"
        )
    # the commanded cable: the integrated set-points, at the end of every period
    commanded = np.asarray(start, dtype=float) + np.cumsum(units, axis=0) * STEPS_PER_UNIT_PERIOD
    for i in range(n):
        travel, release, mm = d.travel_steps[i], d.release_steps[i], d.mm_per_step[i]
        out = np.flatnonzero((commanded[:, i] < -release - 1e-9) | (commanded[:, i] > travel + 1e-9))
        if len(out):
            k = int(out[0])
            x = commanded[k, i]
            raise SafetyError(
                f"tendon {i + 1}, set-point {k}: the set-points integrate to {x:.2f} steps "
                f"({x * mm:.2f} mm), past its travel of {travel_text(rig, i)}"
            )
    tensions = static_tensions(rig, commanded)
    slack = np.flatnonzero(np.all(tensions <= 0.0, axis=1))
    if len(slack):
        k = int(slack[0])
        where = ", ".join(f"{x:.1f}" for x in commanded[k])
        figures = ", ".join(f"{t:.2f}" for t in tensions[k])
        raise SafetyError(
            f"tendons 1-{n}, set-point {k}: every tendon slack at positions ({where}) steps (pretension + "
            f"k pull = {figures} N <= 0): the arm would hang on no tendon"
        )
    run = hs.AxesRun(shaper, start, d.travel_steps, d.release_steps)
    hs.drive_axes(run, units.tolist())
    limits = [x for x in run.notices if x.kind.startswith("LIMIT")]
    if limits and not allow_clamps:
        x = limits[0]
        what = (
            f"reach its travel limit ({x.value} steps)"
            if x.kind == "LIMIT,TRAVEL"
            else "exceed the speed limit (the shaper overshoots)"
        )
        raise StreamLimit(f"tendon {x.axis + 1}: the shaped stream would {what} in period {x.period}")
    reach = []
    for p, s in zip(run.planners, start, strict=True):
        path = s + np.cumsum(np.asarray(p.dirs, dtype=np.int64))
        reach.append((int(path.min(initial=s)), int(path.max(initial=s))))
    end = tuple(p.c for p in run.planners)
    return TendonStreamPlan(units, tuple(start), end, tuple(reach), max(shaper.delays_delta) // hs.PERIOD)


def _shaper_meta(shaper: Any, board: hs.StreamShaper) -> dict[str, Any] | None:
    if shaper is None:
        return None
    if isinstance(shaper, hs.StreamShaper):
        return {"name": "board", "amplitudes": [a / hs.AMP_ONE for a in board.amplitudes],
                "times": [t * 1e-6 for t in board.delays_us]}  # fmt: skip
    return {"name": getattr(shaper, "name", None), "amplitudes": [float(a) for a in shaper.amplitudes],
            "times": [float(t) for t in shaper.times]}  # fmt: skip


@dataclass
class _Feed:
    """A stream as it goes: what was sent and what the board said (``scenario.stream``)."""

    plan: TendonStreamPlan
    board: hs.StreamShaper
    lead_periods: int
    data: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._digest = hashlib.sha256()
        self.data.update(
            {
                "rate_hz": STREAM_RATE_HZ,
                "impulses": {"amplitudes": list(self.board.amplitudes),
                             "delays_us": list(self.board.delays_us),
                             "allow_negative": self.board.allow_negative, "amplitude_unit": 1 / hs.AMP_ONE},
                "setpoints": [], "tendon_setpoints": [[] for _ in self.plan.start], "periods": [],
                "n_setpoints": 0, "setpoints_sha256": self._digest.hexdigest(), "end_period": None,
                "lead_periods": self.lead_periods, "fifo_full": 0, "underruns": 0, "late_start_periods": 0,
                "notices": [], "clamps": {"speed": 0, "travel": 0}, "watchdog": False,
            }
        )  # fmt: skip

    def sent(self, row: list[int], period: int) -> None:
        """One ``MV`` the board accepted for ``period``.

        ``setpoints`` lists tendon 1's (axis 0, as a one-tendon stream's), ``tendon_setpoints`` every
        tendon's; the digest covers every row (int16, little-endian, tendon by tendon, period by period).
        """
        self.data["setpoints"].append(int(row[0]))
        for column, u in zip(self.data["tendon_setpoints"], row, strict=True):
            column.append(int(u))
            self._digest.update(int(u).to_bytes(2, "little", signed=True))
        self.data["setpoints_sha256"] = self._digest.hexdigest()
        self.data["periods"].append(int(period))
        self.data["n_setpoints"] += 1

    def notice(self, line: str) -> None:
        self.data["notices"].append(line)
        kind = {"N,LIMIT,SPEED": "speed", "N,LIMIT,TRAVEL": "travel"}.get(",".join(line.split(",")[:3]), "")
        if kind:
            self.data["clamps"][kind] += 1
        self.data["watchdog"] |= line.startswith("N,WATCHDOG")

    def counts(self, pacer: Pacer) -> None:
        self.data.update(fifo_full=pacer.full, underruns=pacer.underruns, late_start_periods=pacer.late_start)


class TendonStreamRig(TendonRig):
    """:class:`~helpers.rig.tendons.TendonRig` with the stepper board's multi-axis streaming mode."""

    def stream(
        self,
        setpoints: Any,
        shaper: Any = None,
        *,
        path: str | os.PathLike | None = None,
        scenario: dict[str, Any] | None = None,
        rate_hz: int = 1000,
        lead_periods: int = 4,
        lead_in_s: float = 0.2,
        tail_s: float = 0.5,
        allow_clamps: bool = False,
        replace: bool = False,
        silence_timeout: float = 2.0,
        done_grace_s: float = 1.0,
    ) -> Recording:
        """Stream every tendon's cable speeds through the board's shaper; return (and save) the recording.

        Parameters
        ----------
        setpoints : array_like, shape (periods, tendons)
            Cable speeds (mm/s, + = pull), one row per 10 ms control period, checked whole before anything
            is sent (:func:`check_tendon_stream`).
        shaper : helpers.paper.shapers.Shaper, helpers.board.stream_reference.StreamShaper or None
            Loaded on the board (rounded to its 16 us and 1/4096); None streams unshaped. Its last impulse
            must be within 0.62 s (a board with several axes).
        path : path-like, optional
            ``data/<group>/<name>``; default ``data/runs/run_<UTC time>``.
        scenario : dict, optional
            More scenario metadata; ``kind`` is ``"stream"``.
        rate_hz : int
            The DAQ's sample rate.
        lead_periods : int
            Periods a set-point waits in the board's FIFO (1-7).
        lead_in_s, tail_s : float
            Device time recorded before ``STREAM`` and after ``DONE`` (0-60 s).
        allow_clamps : bool
            Go on when the board clamps (counted in the recording, which is then ``deviated``).
        replace : bool
            Replace a recording of the same name.
        silence_timeout, done_grace_s : float
            A DAQ silent this long fails the run; ``DONE`` must come within ``done_grace_s`` of its due time.

        Returns
        -------
        helpers.recordings.Recording
            Saved; ``complete``, or ``deviated`` (under its own name) when the board ran short of set-points
            or clamped.

        Raises
        ------
        SafetyError
            Before anything is sent (module docstring).
        ValueError
            A shaper that cannot be loaded, a bad ``rate_hz``, ``lead_periods``, ``lead_in_s`` or ``tail_s``.
        """
        hw = self.rig.hardware
        if not (isinstance(rate_hz, int) and hw.daq_rate_min_hz <= rate_hz <= hw.daq_rate_max_hz):
            raise ValueError(f"rate_hz must be an integer within the DAQ's rates, got {rate_hz!r}")
        for name, value in (("lead_in_s", lead_in_s), ("tail_s", tail_s)):
            if isinstance(value, bool) or not isinstance(value, int | float) or not 0 <= value <= 60:
                raise ValueError(f"{name} must be a number of seconds in 0-60, got {value!r}")
        Pacer(0, lead_periods)  # refuses a bad lead before anything is sent
        board = hs.board_shaper(shaper)
        units = tendon_units(setpoints, self.rig)
        plan = check_tendon_stream(units, self.rig, tuple(self.positions), board, allow_clamps)
        target = self._target(path)
        scene = {**(scenario or {}), "kind": "stream", "tendons": self.rig.n_tendons,
                 "shaper": _shaper_meta(shaper, board),
                 "start_positions_steps": list(plan.start)}  # fmt: skip
        feed = _Feed(plan, board, lead_periods)
        unit_mm_s = [hs.STEPS_PER_S_PER_UNIT * m for m in derived(self.rig).mm_per_step]
        feed.data.update(lead_in_s=float(lead_in_s), tail_s=float(tail_s), setpoint_unit_mm_s=unit_mm_s)
        scene["stream"] = feed.data
        timing = (lead_in_s, tail_s, silence_timeout, done_grace_s, allow_clamps)
        with reserve(target, replace):
            return self._stream(feed, scene, target, rate_hz, timing, replace)

    def _target(self, path: str | os.PathLike | None) -> Path:
        if path is None:
            return DATA_DIR / "runs" / ("run_" + utc_now().replace(":", "").replace("-", "") + ".csv")
        target = Path(path)
        target = target.with_suffix(".csv") if target.suffix in ("", ".json") else target
        recordings.check_name(target.stem)
        return target

    def _stream(self, feed: _Feed, scene: dict[str, Any], target: Path, rate_hz: int, timing: tuple,
                replace: bool) -> Recording:  # fmt: skip
        started = utc_now()
        self.daq.rows.clear()
        try:
            self.stepper.check_reset()
            self.daq.check_reset()
            self.stepper.abort()  # whatever an earlier session left running stops; driver off
            self.daq.stop()
            self.stepper.send_all(feed.board.commands())  # SHAPER first: loading again discards it
            self.daq.set_rate(rate_hz)
            self.daq.zero()
            self.daq.start()
            timeout = self.daq.port.timeout
            self.daq.port.timeout = min(timeout or _FEED_READ_S, _FEED_READ_S)
            try:
                self._feed(feed, scene, timing)
            finally:
                self.daq.port.timeout = timeout
            self.daq.stop()
            self.stepper.enable(False)
        except BaseException as exc:
            self.last_cleanup = self._cleanup()
            exc.cleanup = list(self.last_cleanup)  # type: ignore[attr-defined]
            try:  # where the tendons were stopped (a board that is gone leaves them unknown)
                self.positions = self.stepper.positions()[: self.rig.n_tendons]
            except Exception:  # noqa: BLE001 - the run's own error is the one to raise
                pass
            reason = f"{type(exc).__name__}: {exc}"
            if self.last_cleanup:
                reason += " | cleanup: " + "; ".join(self.last_cleanup)
            rec = self._stream_recording(feed, scene, rate_hz, "aborted", started)
            rec.meta["abort_reason"] = reason
            try:
                saved = recordings.save(rec, recordings.aborted_path(target, started))
            except (RecordingError, OSError) as save_exc:
                exc.recording, exc.saved_path = None, None  # type: ignore[attr-defined]
                exc.save_error = str(save_exc)  # type: ignore[attr-defined]
            else:
                exc.recording, exc.saved_path, exc.save_error = rec, saved, None  # type: ignore[attr-defined]
            raise
        done = self.stepper.done_positions or ()
        self.positions = tuple(done[: self.rig.n_tendons])
        deviation = []
        if feed.data["underruns"]:
            deviation.append(f"the host fell behind: {feed.data['underruns']} period(s) had no set-point and "
                             "moved nothing, so the motion is the command's stretched in time")  # fmt: skip
        if feed.data["clamps"]["speed"] or feed.data["clamps"]["travel"]:
            deviation.append(f"the board clamped the shaped motion ({feed.data['notices']})")
        if self.positions != feed.plan.end and not deviation:
            deviation.append(f"the stepper board ended the stream at {self.positions}, not at the plan's "
                             f"{feed.plan.end}")  # fmt: skip
        status = "deviated" if deviation else "complete"
        rec = self._stream_recording(feed, scene, rate_hz, status, started)
        if deviation:
            rec.meta["deviation"] = "; ".join(deviation)
        where = target if status == "complete" else recordings.aborted_path(target, started, status)
        recordings.save(rec, where, replace=replace and status == "complete")
        return rec

    def _stream_recording(self, feed: _Feed, scene: dict[str, Any], rate_hz: int, status: str,
                          started: str) -> Recording:  # fmt: skip
        channels = getattr(self.daq.parser, "channels", self.rig.n_tendons)
        frame = tendon_frame(list(self.daq.rows), self.rig, feed.plan.start, channels)
        frame = with_twin_tip(frame, getattr(self.daq.port, "twin_tip_um", None))  # the virtual rig's tip
        stats = self.daq.stats
        counts = {"samples": len(frame), "dropped": int(stats.dropped), "corrupted": int(stats.corrupted),
                  "overruns": int(stats.overruns)}  # fmt: skip
        boards = {"daq": self.daq.version, "stepper": self.stepper.version}
        rec = tendon_recording(frame, self.rig, rate_hz, counts, self.source, scene, status, firmware=boards)
        rec.meta["started_utc"] = started
        rec.meta["done_positions"] = (
            None
            if self.stepper.done_positions is None
            else list(self.stepper.done_positions[: self.rig.n_tendons])
        )
        return rec

    def _read_both(self, silence: Waiter) -> Waiter:
        before = len(self.daq.rows)
        self.daq.pump()
        self.daq.check_reset()
        self.stepper.poll()
        self.stepper.check_reset()
        if len(self.daq.rows) > before:
            return self.daq.waiter(silence.timeout)
        silence.idle(self.daq.port.timeout or 0.0)
        if silence.expired:
            raise BoardTimeout(
                f"the daq board sent no sample for {silence.timeout:.1f} s (it stopped answering)"
            )
        return silence

    def _feed(self, feed: _Feed, scene: dict[str, Any], timing: tuple) -> None:
        """The lead-in, ``STREAM``, one ``MV`` per period as it falls due, ``END``, ``DONE``, the tail."""
        lead_in_s, tail_s, silence_timeout, done_grace_s, allow_clamps = timing
        units, stepper, rows = feed.plan.units, self.stepper, self.daq.rows
        silence = self.daq.waiter(silence_timeout)
        while not rows or rows[-1][1] - rows[0][1] < lead_in_s * 1e6:
            silence = self._read_both(silence)
        stepper.enable(True)
        stepper.done_positions = None
        stepper.done_position = None
        stepper.notices.clear()
        last_int(stepper.command("STREAM"), "STREAM")
        self.daq.pump(block=False)
        now = rows[-1][1]
        scene["t_stream_us"] = now
        pacer = Pacer(now, feed.lead_periods)
        sent = 0
        end_period: int | None = None
        finish_due = done_at = None
        noticed = 0

        def take_notices() -> None:
            nonlocal noticed
            for line in stepper.notices[noticed:]:
                noticed += 1
                feed.notice(line)
                refuse_notice(line, allow_clamps)

        while True:
            take_notices()
            while end_period is None and sent < len(units) and pacer.due(now):
                row = units[sent].tolist()
                words = " ".join(map(str, row + [0] * (self.axes - len(row))))  # a board's further axes: 0
                try:
                    period: int | None = last_int(stepper.command("MV " + words), "MV")
                except CommandRefused as exc:
                    if exc.code != "FULL":
                        take_notices()  # a stream the board has ended (the watchdog) refuses MV: say why
                        raise
                    period = None
                self.daq.pump(block=False)
                now = rows[-1][1]
                if period is None:
                    pacer.refused_full(now)
                else:
                    feed.sent(row, period)
                    pacer.accepted(period, now)
                    sent += 1
                feed.counts(pacer)
            if sent == len(units) and end_period is None:
                end_period = last_int(stepper.command("END"), "END")
                feed.data["end_period"] = end_period
                finish_due = pacer.finish_due_us(end_period, feed.plan.q_max, done_grace_s * 1e6)
            if stepper.done_positions is not None:
                if end_period is None:
                    raise BoardError(f"the stepper board ended the stream before END (DONE at {now} us)")
                done_at = now if done_at is None else done_at
                if now - done_at >= tail_s * 1e6:
                    return
            elif finish_due is not None and now > finish_due:
                raise BoardTimeout(
                    f"the stepper board did not report DONE within {done_grace_s:.1f} s of device time after "
                    "the stream's end (it stopped answering)"
                )
            silence = self._read_both(silence)
            now = rows[-1][1]
