"""Streams for the stepper firmware in simavr, and their comparison with ``helpers.board.stream_reference``
(test support).

A session is a list of :class:`StreamSpec` run back to back in one harness run: each loads its shaper, sends
``STREAM``, its set-points at the given times, and ``END`` (or nothing, so that the watchdog ends it). The
replies tell which period each set-point drives (``OK V <period>``, ``OK END <period>``); from them
the reference run through them (``tests/stream_run.py``'s :func:`simulate`, the board's
:class:`helpers.board.stream_reference.AxesRun`) gives the steps the board must make, to be set beside the
STEP/DIR edges logged from the pins.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import fwsim
import numpy as np
from stream_run import PeriodCommands, StreamResult, simulate

from helpers.board import stream_reference as hs

F = fwsim.F_CPU
CYCLES_PER_TICK = 8
PINS = ("D5", "D6", "D7", "B0", "B1")  # STEP, DIR, ENA, test points (control tick, step interrupt)


@dataclass
class StreamSpec:
    """One stream: its shaper, set-points ``(s after STREAM, v)``, when ``END`` is sent (None: never)."""

    shaper: hs.StreamShaper
    setpoints: list[tuple[float, int]]
    end_at: float | None

    def duration(self) -> float:
        """Seconds from ``STREAM`` by which the board has surely stopped."""
        last = max([t for t, _ in self.setpoints] + [self.end_at or 0.0])
        # queued set-points (8), the watchdog (10 periods), the shaper, the finish (3 periods), margin
        return last + 0.09 + (0.11 if self.end_at is None else 0.0) + self.shaper.duration_s + 0.06 + 0.05


def _framed(body: str) -> bytes:
    return (fwsim.with_checksum(body) + "\n").encode("ascii")


@dataclass
class Session:
    """The script of a run and, per stream, its commands and when they were sent."""

    script: list[tuple[float, bytes]] = field(default_factory=list)
    streams: list[dict] = field(default_factory=list)
    end: float = 0.0


def build(specs: list[StreamSpec], t0: float = 0.05, gap: float = 0.004) -> Session:
    """Write the script for the streams, back to back."""
    session = Session()
    t = t0
    for spec in specs:
        commands = ["EN 1", *spec.shaper.commands()]
        entry = {"spec": spec, "commands": [], "t_first": t}
        for body in commands:
            session.script.append((t, _framed(body)))
            entry["commands"].append(body)
            t += gap
        t_stream = t
        session.script.append((t, _framed("STREAM")))
        entry["commands"].append("STREAM")
        entry["t_stream"] = t_stream
        timed = [(t_stream + dt, f"V {v}") for dt, v in spec.setpoints]
        if spec.end_at is not None:
            timed.append((t_stream + spec.end_at, "END"))
        for when, body in sorted(timed, key=lambda x: x[0]):
            session.script.append((when, _framed(body)))
            entry["commands"].append(body)
        t = t_stream + spec.duration()
        entry["t_last"] = t
        session.streams.append(entry)
    session.script.append((t, _framed("MEM")))  # the least free stack after everything
    session.end = t + 0.02
    return session


UNSOLICITED = ("N,", "DONE", "HELLO")


@dataclass
class StreamOutcome:
    """One stream as the firmware ran it and as the reference says it must run."""

    replies: list[str]
    notices: list[str]
    done: list[fwsim.Line]
    step_cycles: np.ndarray
    step_dirs: np.ndarray
    reference: StreamResult
    commands: PeriodCommands
    start_position: int
    tick_rises: np.ndarray  # control-tick test point (B0) rising edges
    dir_setup: np.ndarray  # cycles from the last DIR change to each STEP rising edge


def run(specs: list[StreamSpec], timeout: float = 900.0) -> tuple[fwsim.SimRun, list[StreamOutcome]]:
    """Run the streams in one harness session; return the run and every stream's outcome.

    The run's last line is the reply to ``MEM`` (the least free stack over the whole session).
    """
    session = build(specs)
    result = fwsim.run("stepper", session.script, session.end, watch=PINS, timeout=timeout)
    rises = np.array([c for c, p, lv in result.pins if p == "D5" and lv == 1], dtype=np.int64)
    dir_edges = [(c, lv) for c, p, lv in result.pins if p == "D6"]
    tick_rises_all = np.array([c for c, p, lv in result.pins if p == "B0" and lv == 1], dtype=np.int64)
    outcomes = []
    position = 0
    for entry in session.streams:
        lo, hi = entry["t_first"] * F, entry["t_last"] * F
        lines = [ln for ln in result.lines if lo <= ln.cycle < hi]
        replies = [ln.body for ln in lines if not ln.body.startswith(UNSOLICITED)]
        notices = [ln.body for ln in lines if ln.body.startswith("N,")]
        done = [ln for ln in lines if ln.body.startswith("DONE")]
        assert len(replies) == len(entry["commands"]), (entry["commands"], replies)
        assigned: dict[int, int] = {}
        end_period = None
        for body, reply in zip(entry["commands"], replies, strict=True):
            if body.startswith("V ") and (m := re.fullmatch(r"OK V (\d+)", reply)):
                assigned[int(m[1])] = int(body.split()[1])
            elif body == "END" and (m := re.fullmatch(r"OK END (\d+)", reply)):
                end_period = int(m[1])
        commands = PeriodCommands(assigned, end_period)
        reference = simulate(entry["spec"].shaper, commands, position=position)
        stream_lo = entry["t_stream"] * F
        in_window = (rises >= stream_lo) & (rises < hi)
        cycles = rises[in_window]
        dirs = np.array([1 if _level_at(dir_edges, c) else -1 for c in cycles], dtype=np.int64)
        ticks = tick_rises_all[(tick_rises_all >= stream_lo) & (tick_rises_all < hi)]
        dir_times = np.array([c for c, _ in dir_edges] or [-(10**12)], dtype=np.int64)
        last_change = dir_times[np.maximum(np.searchsorted(dir_times, cycles, side="right") - 1, 0)]
        outcomes.append(
            StreamOutcome(
                replies,
                notices,
                done,
                cycles,
                dirs,
                reference,
                commands,
                position,
                ticks,
                cycles - last_change,
            )
        )
        position = reference.position
    return result, outcomes


def _level_at(edges: list[tuple[int, int]], cycle: int) -> int:
    level = 0
    for c, lv in edges:
        if c > cycle:
            break
        level = lv
    return level


def residuals(outcome: StreamOutcome) -> np.ndarray:
    """Firmware step edge minus the reference's step tick, in CPU cycles (a constant plus the jitter)."""
    return outcome.step_cycles - CYCLES_PER_TICK * outcome.reference.ticks


def stream_origin(outcome: StreamOutcome) -> float:
    """The cycle at which ``STREAM`` restarted Timer1, from the control-tick test point (rise k near k T)."""
    k = np.arange(1, len(outcome.tick_rises) + 1)
    return float(np.min(outcome.tick_rises - k * hs.PERIOD_TICKS * CYCLES_PER_TICK))


def isr_cycles_per_period(result: fwsim.SimRun) -> np.ndarray:
    """CPU cycles with a test point HIGH (control tick D8 or step interrupt D9) in each 10 ms control period.

    The two may nest (the step interrupt preempts the control tick): their union is counted once. Periods
    are cut at the control tick's rising edges. The UART's interrupts have no test point and are not counted
    (except where they preempt the control tick, which then includes them).
    """
    events = sorted((c, p, lv) for c, p, lv in result.pins if p in ("B0", "B1"))
    level = {"B0": 0, "B1": 0}
    busy_since = None
    intervals = []
    for c, p, lv in events:
        was = level["B0"] or level["B1"]
        level[p] = lv
        now = level["B0"] or level["B1"]
        if now and not was:
            busy_since = c
        elif was and not now and busy_since is not None:
            intervals.append((busy_since, c))
    ticks = np.array([c for c, p, lv in events if p == "B0" and lv == 1], dtype=np.int64)
    if len(ticks) < 2:
        return np.zeros(0, dtype=np.int64)
    totals = np.zeros(len(ticks) - 1, dtype=np.int64)
    for a, b in intervals:
        i = np.searchsorted(ticks, a, side="right") - 1
        if 0 <= i < len(totals):
            totals[i] += b - a
    # only whole periods of a running stream (a gap over 2 periods is the pause between two streams)
    whole = np.diff(ticks) <= 2 * hs.PERIOD_TICKS * CYCLES_PER_TICK
    return totals[whole]
