"""The board's streaming mode run through a whole stream: what the tests set the firmware, the emulated board
and the host's recordings beside.

:class:`helpers.board.stream_reference.AxesRun` is the reference of what the stepper board does, control tick
by control tick (the host plans with it, the emulated stepper runs with it). Here it is driven through a whole
stream whose set-points the board took (:class:`PeriodCommands`, from its ``OK V``/``OK MV`` and ``OK END``
replies, under the board's :class:`~helpers.board.stream_reference.SetpointRules`) until it stops, and what it
did is collected per axis (:class:`StreamResult`).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np

from helpers.board import stream_reference as hs


@dataclass
class PeriodCommands:
    """The set-points the board uses, from what it told the host.

    Parameters
    ----------
    assigned : dict
        ``{period: v}`` from the ``OK V <period>`` replies to ``V <v>`` (several axes:
        ``{period: (v_0, ...)}`` from ``OK MV <period>``, see :func:`simulate_axes`).
    end_period : int or None
        From ``OK END <period>``: the first period fed with zero.

    The board's rules are :class:`~helpers.board.stream_reference.SetpointRules`'.
    """

    assigned: dict[int, int] | dict[int, tuple[int, ...]]
    end_period: int | None = None

    def __iter__(self) -> Iterator[tuple[int, int, str]]:
        """Yield ``(period, v, state)`` for periods 1, 2, ...; ``state``: active, end or watchdog."""
        rules = hs.SetpointRules(self.end_period)
        k = 0
        while True:
            k += 1
            v = rules.take(k, self.assigned.get(k))
            yield k, v, rules.state


@dataclass
class StreamResult:
    """What the board does for a stream: step ticks (from ``STREAM``), directions, notices, the end."""

    ticks: np.ndarray
    directions: np.ndarray
    notices: list[hs.Notice] = field(default_factory=list)
    finish_tick: int | None = None
    """Control tick at which the board stops (``DONE``)."""
    position: int = 0
    residual: int = 0
    v_by_period: list[int] = field(default_factory=list)
    """The set-point of periods 0, 1, 2, ... as planned (period 0 is always 0)."""


def simulate_axes(
    shaper: hs.StreamShaper,
    commands: PeriodCommands,
    positions: Sequence[int],
    travels: Sequence[int] | None = None,
    releases: Sequence[int] | None = None,
    v_max: int = hs.V_MAX,
) -> list[StreamResult]:
    """Run a stream of a board of one or several axes (``V``, ``MV``) until it stops: one result per axis.

    Parameters
    ----------
    shaper, positions, travels, releases, v_max
        The loaded shaper (every axis's) and the axes, as :class:`~helpers.board.stream_reference.AxesRun`
        takes them.
    commands : PeriodCommands
        ``assigned`` maps each period to its set-points, a tuple with one per axis (``OK MV <period>``), or
        to an int (``OK V <period>``: axis 0's, the others zero).

    Every axis is planned by its own planner from the one shaper; the stream stops (``finish_tick``, the same
    for every axis) as ``AxesRun`` says, with a period counting as non-zero when any axis's set-point is: it
    stops after ``END`` or, the set-points being finite, after the watchdog, once the shaper is through. The
    ``WATCHDOG`` notice is in axis 0's result.
    """
    run = hs.AxesRun(shaper, positions, travels, releases, v_max)
    n = len(run.planners)
    v_by_axis: list[list[int]] = [[0] for _ in range(n)]
    for k, v, state in commands:
        if run.tick(k, v, state):  # planned (the board has not stopped): every axis's set-point of period k
            vs = tuple(v) if isinstance(v, tuple) else (v,) + (0,) * (n - 1)
            for vlist, va in zip(v_by_axis, vs, strict=True):
                vlist.append(va)
        if run.finish_tick is not None:  # (the periods left before the finish are zero)
            break
    return [
        StreamResult(np.array(p.ticks, dtype=np.int64), np.array(p.dirs, dtype=np.int64), p.notices,
                     run.finish_tick, p.c, p.r, vlist)
        for p, vlist in zip(run.planners, v_by_axis, strict=True)
    ]  # fmt: skip


def simulate(
    shaper: hs.StreamShaper, commands: PeriodCommands, position: int = 0, v_max: int = hs.V_MAX
) -> StreamResult:
    """Run the board's streaming mode on a one-axis stream until it stops (``END`` or the watchdog).

    :func:`simulate_axes` of one axis of travel ``TRAVEL_MAX``: step ticks counted from ``STREAM`` (the
    instant Timer1 restarts), directions, notices, the set-point of every period planned, and the control
    tick at which the board stops.
    """
    return simulate_axes(shaper, commands, [position], v_max=v_max)[0]


def velocity_units(mm_per_s: float, mm_per_step: float) -> int:
    """The set-point (units of 2^-16 step per 16 us) nearest to a cable speed."""
    return int(round(mm_per_s / mm_per_step / hs.STEPS_PER_S_PER_UNIT))
