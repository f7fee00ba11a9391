"""A rig that also streams: :class:`StreamRig` is a :class:`~helpers.rig.Rig` with the board's streaming mode.

The paper's experiments are programmes (:meth:`Rig.run`, :meth:`Rig.run_pulse`); arbitrary motion beyond the
paper is a stream of set-points shaped by the board (``docs/streaming.md``). :meth:`StreamRig.stream` runs one
as an experiment, with the parts of :mod:`helpers.rig.stream` and the board's reference
(:mod:`helpers.board.stream_reference`); a :class:`StreamRig` connects as a :class:`Rig` does
(``StreamRig.connect(...)``) and runs programmes too.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from helpers.board.stream_reference import board_shaper
from helpers.paper.hardware import LIMITS
from helpers.recordings import Recording, reserve
from helpers.rig.boards import BoardError, BoardTimeout, CommandRefused
from helpers.rig.experiment import Rig, RunOptions, _DeviceTimeBar, _RunState
from helpers.rig.stepper import StepperBoard, last_int
from helpers.rig.stream import (
    STREAM_RATE_HZ,
    Pacer,
    SetpointSource,
    ShapedCheck,
    StreamRecord,
    refuse_notice,
)

__all__ = ["STREAM_FIRMWARE", "StreamRig"]

STREAM_FIRMWARE = (2, 1)
"""The oldest stepper firmware that streams: 2.0.x held the last set-point through a period without one."""


def _check_stream_firmware(version: str | None) -> None:
    """Refuse a stream on a stepper board whose firmware holds the last set-point when the host is late."""
    try:
        major, minor = (int(x) for x in str(version).split(".")[:2])
    except ValueError:
        major, minor = -1, -1
    if (major, minor) < STREAM_FIRMWARE:
        raise BoardError(
            f"the stepper board runs firmware {version}, whose streams hold the last set-point through a "
            "period the host was late for (the cable then goes further than commanded): flash firmware "
            f"{STREAM_FIRMWARE[0]}.{STREAM_FIRMWARE[1]} or later to stream (make -C firmware upload-stepper)"
        )


def _start_stream(stepper: StepperBoard) -> int:
    """``STREAM``: start streaming from the present position (returned); the notices list is emptied."""
    stepper.done_position = None
    stepper.notices.clear()
    return last_int(stepper.command("STREAM"), "STREAM")


def _set_point(stepper: StepperBoard, units: int) -> int | None:
    """``V <units>``: queue a set-point; return the period it drives, or None if the FIFO was full.

    A full FIFO (``ERR FULL``) drops the set-point: send it again later. Any other refusal raises
    :class:`helpers.rig.CommandRefused`.
    """
    try:
        return last_int(stepper.command(f"V {units}"), "V")
    except CommandRefused as exc:
        if exc.code == "FULL":
            return None
        raise


_FEED_READ_S = 0.005
"""During a stream the DAQ is read with this timeout (s): device time advances in steps under a control period
(on the in-process virtual rig a read that finds nothing moves the device clock by its timeout)."""


def _shaper_meta(shaper: Any) -> dict[str, Any]:
    """A shaper as the recording's ``scenario.shaper`` states it: ``name``, ``amplitudes``, ``times`` (s)."""
    if hasattr(shaper, "delays_us"):  # a board shaper given as it is
        return {
            "name": "board",
            "amplitudes": [a / 4096 for a in shaper.amplitudes],
            "times": [d * 1e-6 for d in shaper.delays_us],
        }
    return {
        "name": getattr(shaper, "name", None),
        "amplitudes": [float(a) for a in shaper.amplitudes],
        "times": [float(t) for t in shaper.times],
    }


@dataclass(frozen=True)
class _Stream:
    """What one stream is, checked before anything is sent (:meth:`StreamRig.stream`'s own arguments)."""

    board: Any
    source: SetpointSource
    units: np.ndarray | None
    lead_periods: int
    lead_in_s: float
    tail_s: float
    allow_clamps: bool


class StreamRig(Rig):
    """:class:`~helpers.rig.Rig` with the stepper board's streaming mode (:meth:`stream`)."""

    def stream(
        self,
        setpoints: Any,
        shaper: Any = None,
        *,
        path: str | os.PathLike | None = None,
        scenario: dict[str, Any] | None = None,
        source_name: str | None = None,
        stream_rate_hz: float = STREAM_RATE_HZ,
        lead_periods: int = 4,
        lead_in_s: float = 1.0,
        tail_s: float = 1.0,
        allow_clamps: bool = False,
        **options: Any,
    ) -> Recording:
        """Stream cable speeds through the stepper board's shaper; return (and save) the recording.

        The board shapes the set-points with ``shaper`` and enforces its limits on the shaped motion
        (``firmware/PROTOCOL.md``, streaming mode). The run: check everything that can be checked before a
        byte is sent (the set-points, the shaper; for an array, the whole shaped motion from the cable's
        present position, with the board's own planner, :class:`~helpers.rig.stream.ShapedCheck`), wait
        until the tension is at rest, load the shaper, start the DAQ, record ``lead_in_s``, enable the
        driver and ``STREAM``, feed the set-points at 100 Hz of device time
        (:class:`~helpers.rig.stream.Pacer`), ``END``, wait for ``DONE``, record ``tail_s`` more, stop the
        DAQ and disable the driver. It runs in the same guard as :meth:`run`: any exception, Ctrl-C or
        SIGTERM, a board reset or silence, the stream's watchdog (:class:`~helpers.rig.stream.StreamStarved`)
        and, unless ``allow_clamps``, a clamp the board reports (:class:`~helpers.rig.stream.StreamLimit`)
        abort the stepper, disable the driver, stop the DAQ and save what was recorded under an aborted name.

        Parameters
        ----------
        setpoints : array_like or iterable of float
            Cable speeds (mm/s, + = pull), one per 10 ms period. An array is checked whole before the run; a
            generator or a live source (which must return its present value at once) one value at a time.
        shaper : helpers.paper.shapers.Shaper, helpers.board.stream_reference.StreamShaper or None
            Loaded on the board (a real shaper is rounded to the board's 16 us and 1/4096); None streams
            unshaped (the unit shaper).
        path : path-like, optional
            ``data/<group>/<name>``; default ``data/runs/run_<UTC time>``.
        scenario : dict, optional
            More scenario metadata; ``kind`` is ``"stream"``.
        source_name : str, optional
            Where the set-points come from, for the recording (default: ``array`` or the iterable's type).
        stream_rate_hz : float
            The set-points' rate: the board takes one per 10 ms control period, so only 100 is accepted.
        lead_periods : int
            Periods a set-point waits in the board's FIFO (1-7): latency against tolerance of host jitter.
        lead_in_s, tail_s : float
            Device time recorded before ``STREAM`` and after ``DONE`` (0-60 s).
        allow_clamps : bool
            Go on when the board clamps the shaped motion (the notices are counted in the recording).
        **options
            The run's options, shared with every run of a rig (:class:`RunOptions`: ``rate_hz``,
            ``progress``, ``replace``, ``noise_seed``, timeouts).

        Returns
        -------
        helpers.recordings.Recording
            Its ``scenario.stream`` describes the stream (``docs/recording_format.md``).

        Raises
        ------
        SafetyError
            Before anything moves: a set-point that is not finite or beyond the speed limit, an array whose
            shaped motion would clamp at the travel or speed limit, a stream over 600 s.
        ValueError
            A shaper that cannot be loaded (amplitudes not summing to 1, delays beyond 1 s, ...), a rate
            other than 100 Hz, an out-of-range ``lead_periods``, ``lead_in_s`` or ``tail_s``.
        """
        o = RunOptions(**options)
        if stream_rate_hz != STREAM_RATE_HZ:
            raise ValueError(
                f"the stepper board takes one set-point per 10 ms control period: stream_rate_hz must be "
                f"{STREAM_RATE_HZ}, got {stream_rate_hz!r} (resample the trajectory)"
            )
        for name, value in (("lead_in_s", lead_in_s), ("tail_s", tail_s)):
            if isinstance(value, bool) or not isinstance(value, int | float) or not 0 <= value <= 60:
                raise ValueError(f"{name} must be a number of seconds in 0-60, got {value!r}")
        board = board_shaper(shaper)
        Pacer(0, lead_periods)  # refuses a bad lead before anything is sent
        source = SetpointSource(setpoints, source_name)
        units = source.check_all() if source.sized else None
        target = self._target(path)
        _check_stream_firmware(self.stepper.version)
        stream = _Stream(board, source, units, lead_periods, lead_in_s, tail_s, allow_clamps)
        with reserve(target, o.replace):  # a second run to this name is refused now, not after this one
            return self._stream(stream, shaper, target, scenario, o)

    def _stream(
        self, stream: _Stream, shaper: Any, target: Path, scenario: dict[str, Any] | None, o: RunOptions
    ) -> Recording:
        board, source, units, lead_periods = stream.board, stream.source, stream.units, stream.lead_periods
        lead_in_s, tail_s, allow_clamps = stream.lead_in_s, stream.tail_s, stream.allow_clamps
        self.stepper.check_reset()
        self.daq.check_reset()
        position = self.stepper.position()
        if units is not None:
            whole = ShapedCheck(board, position, refuse=not allow_clamps)
            for u in units.tolist():
                whole.setpoint(u)
            whole.end()
            reach = whole.reach()
        else:
            reach = (0, LIMITS.max_position_steps)
        # the prediction that follows the board period by period as the set-points go out (module docstring)
        check = ShapedCheck(board, position, refuse=not allow_clamps)
        record = StreamRecord(board, source.name, lead_periods)
        record.data.update({"lead_in_s": float(lead_in_s), "tail_s": float(tail_s)})
        scenario = {**(scenario or {}), "kind": "stream"}
        scenario["shaper"] = None if shaper is None else _shaper_meta(shaper)
        scenario["start_position_steps"] = position
        scenario["stream"] = record.data
        self._seed_noise(o.noise_seed, scenario)
        feed = iter(units.tolist()) if units is not None else source
        expected_s = None if units is None else len(units) / STREAM_RATE_HZ + board.duration_s + tail_s + 0.05

        def body(state: _RunState) -> None:
            scenario["rest"] = self.wait_for_rest(o.rate_hz, o.rest_timeout_s)
            self.stepper.abort()  # whatever an earlier session left running stops; driver off
            self.daq.stop()
            self.stepper.send_all(board.commands())  # SHAPER first: loading again discards it
            self.daq.set_rate(o.rate_hz)
            self.daq.zero()
            self.daq.start()
            self.daq.expect_steps(reach[0] - position, reach[1] - position)
            timeout = self.daq.port.timeout
            self.daq.port.timeout = min(timeout or _FEED_READ_S, _FEED_READ_S)  # device time in small steps
            bar = _DeviceTimeBar(expected_s, o.progress)
            try:
                self._feed(state, feed, check, record, stream, o, bar, position)
            finally:
                self.daq.port.timeout = timeout
                bar.close()
            state.deviation = record.deviation()
            state.finished = True
            self.daq.stop()
            self.stepper.enable(False)

        return self._guarded(body, scenario, target, o.rate_hz, replace=o.replace)

    def _feed(
        self,
        state: _RunState,
        feed: Any,
        check: ShapedCheck,
        record: StreamRecord,
        stream: _Stream,
        o: RunOptions,
        bar: _DeviceTimeBar,
        position: int,
    ) -> None:
        """The lead-in, ``STREAM``, the set-points as they fall due, ``END``, ``DONE``, the tail.

        Every set-point is planned with the board's own planner before it is sent (``check``), and planned
        again where the board put it if the board ran short meanwhile: a clamp the board would make is
        refused before it happens, whatever the host's timing.
        """
        lead_periods, lead_in_s, tail_s, allow_clamps = (
            stream.lead_periods,
            stream.lead_in_s,
            stream.tail_s,
            stream.allow_clamps,
        )
        done_grace_s, max_corrupted_fraction = o.done_grace_s, o.max_corrupted_fraction
        silence = self.daq.waiter(o.silence_timeout)
        while not self.daq.rows or self.daq.rows[-1][1] - self.daq.rows[0][1] < lead_in_s * 1e6:
            _, silence = self._read_both(silence, max_corrupted_fraction)
        self.stepper.enable(True)
        state.go_sent = True
        _start_stream(self.stepper)
        self.daq.pump(block=False)
        state.t_go_us = now = self.daq.rows[-1][1]  # STREAM's device time, as GO's in run()
        pacer = Pacer(now, lead_periods)
        pending: int | None = None  # a set-point the board refused with ERR FULL, to send again
        exhausted = False
        end_period = finish_due = done_at = None
        noticed = 0

        def take_notices() -> None:
            nonlocal noticed
            for line in self.stepper.notices[noticed:]:
                noticed += 1
                record.notice(line)
                refuse_notice(line, allow_clamps)

        while True:
            take_notices()
            while end_period is None and not exhausted and pacer.due(now):
                if pending is None:
                    try:
                        pending = next(feed)
                    except StopIteration:
                        exhausted = True
                        break
                planned = check.checkpoint()
                check.setpoint(pending)  # StreamLimit before the byte is sent if the board would clamp
                try:
                    period = _set_point(self.stepper, pending)
                except CommandRefused:
                    take_notices()  # a stream the board has ended (the watchdog) refuses V: say why
                    raise
                self.daq.pump(block=False)  # device time went on while the source and the board were asked
                now = self.daq.rows[-1][1]
                if period is None:
                    check.rollback(planned)
                    pacer.refused_full(now)
                else:
                    record.sent(pending, period)
                    if check.confirm(planned, pending, period):  # the board ran short: planned where it went
                        self.daq.expect_steps(-position, LIMITS.max_position_steps - position)
                    pacer.accepted(period, now)
                    pending = None
                record.counts(pacer)
            if exhausted and end_period is None:
                end_period = last_int(self.stepper.command("END"), "END")
                record.data["end_period"] = end_period
                finish_due = pacer.finish_due_us(end_period, record.shaper_q_max, done_grace_s * 1e6)
            if self.stepper.done_position is not None:
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
            _, silence = self._read_both(silence, max_corrupted_fraction)
            now = self.daq.rows[-1][1]
            bar.show((now - state.t_go_us) / 1e6)
