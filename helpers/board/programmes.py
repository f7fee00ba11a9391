"""Stepper programmes: the board's command format, its limits, and the quantiser that makes whole steps.

The stepper board runs a :class:`Programme` of items with the timing of ``firmware/PROTOCOL.md``:
:class:`Segment` (``SEG``: axis 0 makes n steps, one every ``interval_us``), :class:`Move` (``MSEG``: every
axis its signed steps in one window; step k of n on tick ``ceil(k W / n)`` of 0.5 us) and :class:`Dwell`
(``WAIT``, ms). One programme serves rigs of 1 to 4 tendons; the paper's pulses are segments and dwells.
:func:`experiment_programme` turns a whole Up-hold-Down experiment (a
:class:`helpers.paper.profiles.VelocityProfile` per move) into one such programme and reports every rounding
it made (:class:`QuantisationReport`). The board's compiled-in limits follow from the rig file:
:meth:`Limits.of`, and :meth:`Programme.check_limits` is the one check of a programme against them.

The quantiser takes the moves it quantises: the paper's pulse shaped by one shaper (or none), or the moves
of any shaping that makes its own (:class:`ShapesMoves`: the research wing's designs), never a design type.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np
import pandas as pd

from helpers import rigfile
from helpers.base.validate import check_int, check_time
from helpers.paper import numbers as paper
from helpers.paper.profiles import VelocityProfile, pulse_time, single_pulse
from helpers.paper.shapers import Shaper


@runtime_checkable
class ShapesMoves(Protocol):
    """A shaping that makes the Up and Down moves of a pulse experiment itself (e.g. an Up/Down pair)."""

    def moves(
        self, v_in_mm_s: float, x_f_mm: float, t_up: float, t_down: float
    ) -> tuple[VelocityProfile, VelocityProfile]:
        """The exact Up move (positive velocities, from ``t_up``) and Down move (negative, ``t_down``)."""


MIN_PIECE_S = 2e-3
"""Pieces of a shaped move shorter than this are merged into a neighbour before quantisation."""


@dataclass(frozen=True)
class Limits:
    """The stepper board's compiled-in limits (its build of the rig file), and the host's programme length.

    Per axis (one per tendon): ``travel_steps``, ``release_steps`` (positions ``-release..travel``) and
    ``mm_per_step``; for every axis: step intervals, programme length and dwell, speed and step-rate caps.
    """

    travel_steps: tuple[int, ...]
    release_steps: tuple[int, ...]
    mm_per_step: tuple[float, ...]
    min_interval_us: int
    max_interval_us: int
    max_items: int
    max_dwell_ms: int
    max_speed_mm_s: float
    max_step_rate_hz: float
    max_programme_s: float

    @classmethod
    def of(cls, rig: rigfile.RigFile) -> Limits:
        """The limits of ``rig`` (``helpers.rigfile.derived``; the firmware header holds the same)."""
        d, hw = rigfile.derived(rig), rig.hardware
        return cls(d.travel_steps, d.release_steps, d.mm_per_step, d.min_interval_us, d.max_interval_us,
                   hw.programme_max_items, hw.max_dwell_ms, hw.speed_limit_mm_s, hw.step_rate_cap_hz,
                   hw.max_programme_s)  # fmt: skip

    @property
    def axes(self) -> int:
        """The number of axes (tendons)."""
        return len(self.travel_steps)

    def travel_text(self, i: int) -> str:
        """Axis ``i``'s travel for a refusal: ``0-156 steps (39.8 mm)``, ``-78-156 steps (-19.9-39.8 mm)``."""
        travel, release, mm = self.travel_steps[i], self.release_steps[i], self.mm_per_step[i]
        if not release:
            return f"0-{travel} steps ({travel * mm:.1f} mm)"
        return f"-{release}-{travel} steps ({-release * mm:.1f}-{travel * mm:.1f} mm)"


@dataclass(frozen=True)
class Segment:
    """``SEG <direction> <n_steps> <interval_us>``: axis 0's ``n_steps``, step k at ``t0 + k interval_us``.

    Parameters
    ----------
    direction : int
        +1 pull (position increases), -1 release.
    n_steps : int
        Number of steps, >= 1.
    interval_us : int
        Time between steps (us), >= 1 (the board's range is checked by :meth:`Programme.check_limits`).
    """

    direction: int
    n_steps: int
    interval_us: int

    def __post_init__(self) -> None:
        direction = check_int(self.direction, "direction")
        if direction not in (1, -1):
            raise ValueError(f"direction must be 1 (pull) or -1 (release), got {direction}")
        object.__setattr__(self, "direction", direction)
        object.__setattr__(self, "n_steps", check_int(self.n_steps, "n_steps", 1))
        object.__setattr__(self, "interval_us", check_int(self.interval_us, "interval_us", 1))

    @property
    def duration_us(self) -> int:
        """``n_steps * interval_us``."""
        return self.n_steps * self.interval_us

    def counts(self, axes: int) -> tuple[int, ...]:
        """Every axis's signed steps: axis 0's, the others hold still."""
        return (self.direction * self.n_steps,) + (0,) * (axes - 1)

    def command(self, axes: int = 1) -> str:
        """The protocol line, e.g. ``SEG 1 78 1282``."""
        return f"SEG {self.direction} {self.n_steps} {self.interval_us}"


@dataclass(frozen=True)
class Move:
    """``MSEG <window_us> <n_0> ... <n_{A-1}>``: every axis its signed ``steps`` (+ pulls) in one window.

    Parameters
    ----------
    window_us : int
        The window (us), >= 1.
    steps : tuple of int
        One signed step count per tendon, at least one of them non-zero (a pause is a :class:`Dwell`).
    """

    window_us: int
    steps: tuple[int, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "window_us", check_int(self.window_us, "window_us", 1))
        steps = tuple(check_int(n, "steps") for n in self.steps)
        if not any(steps):
            raise ValueError("no tendon moves in this item (a pause is a Dwell)")
        object.__setattr__(self, "steps", steps)

    @property
    def duration_us(self) -> int:
        """The window."""
        return self.window_us

    def counts(self, axes: int) -> tuple[int, ...]:
        """Every axis's signed steps (a board's further axes hold still)."""
        return self.steps + (0,) * (axes - len(self.steps))

    def command(self, axes: int = 1) -> str:
        """The protocol line for a board of ``axes`` axes, e.g. ``MSEG 200000 10 -7 0 0``."""
        return f"MSEG {self.window_us} " + " ".join(map(str, self.counts(max(axes, len(self.steps)))))


@dataclass(frozen=True)
class Dwell:
    """``WAIT <ms>``: no steps for ``ms`` milliseconds.

    Parameters
    ----------
    ms : int
        Duration in ms, >= 0 (the board's maximum is checked by :meth:`Programme.check_limits`).
    """

    ms: int

    def __post_init__(self) -> None:
        object.__setattr__(self, "ms", check_int(self.ms, "dwell ms", 0))

    @property
    def duration_us(self) -> int:
        """``ms * 1000``."""
        return self.ms * 1000

    def counts(self, axes: int) -> tuple[int, ...]:
        """No axis moves."""
        return (0,) * axes

    def command(self, axes: int = 1) -> str:
        """The protocol line, e.g. ``WAIT 1000``."""
        return f"WAIT {self.ms}"


Item = Segment | Move | Dwell


@dataclass(frozen=True)
class Programme:
    """A stepper programme: items run back to back from ``GO`` (timing as in ``firmware/PROTOCOL.md``).

    Parameters
    ----------
    items : tuple of Segment, Move and Dwell
        The programme, in order.
    """

    items: tuple[Item, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        items = tuple(self.items)
        for i, item in enumerate(items):
            if not isinstance(item, Segment | Move | Dwell):
                raise ValueError(f"programme item {i} must be a Segment, a Move or a Dwell, got {item!r}")
        object.__setattr__(self, "items", items)

    def __len__(self) -> int:
        return len(self.items)

    @property
    def duration_us(self) -> int:
        """Total duration (us): the sum of the items' durations."""
        return sum(item.duration_us for item in self.items)

    @property
    def duration_s(self) -> float:
        """Total duration (s)."""
        return self.duration_us / 1e6

    @property
    def axes(self) -> int:
        """The axes the programme moves: 1, or its moves' tendon count."""
        return max([1] + [len(item.steps) for item in self.items if isinstance(item, Move)])

    @property
    def net_steps(self) -> int:
        """Signed sum of axis 0's steps (its position change)."""
        return sum(item.counts(1)[0] for item in self.items)

    @property
    def n_steps(self) -> int:
        """Total number of steps, every axis, either direction."""
        return sum(abs(n) for item in self.items for n in item.counts(self.axes))

    def positions(self, start: int | Sequence[int], axes: int) -> np.ndarray:
        """Every axis's position at ``GO`` and after each item, from ``start``: shape (items + 1, axes).

        ``start``: every axis's position at ``GO`` (an int: axis 0's, the others at 0).
        """
        first = [start] + [0] * (axes - 1) if isinstance(start, int) else list(start)
        return np.cumsum([first] + [item.counts(axes) for item in self.items], axis=0)

    def item_starts_us(self) -> np.ndarray:
        """Start time (us from ``GO``) of every item."""
        durations = np.array([item.duration_us for item in self.items], dtype=np.int64)
        return np.concatenate([[0], np.cumsum(durations)[:-1]]).astype(np.int64)

    def step_times_us(self, axes: int = 1) -> list[tuple[np.ndarray, np.ndarray]]:
        """Every axis's step instants (us from ``GO``, on the board's 0.5 us ticks) and signs (+1/-1).

        Step k of n in an item of window W falls on tick ``ceil(k 2W / n)`` from the item's start (a
        segment's exactly on ``k interval_us``).
        """
        out = []
        for a in range(axes):
            times, signs = [np.zeros(0)], [np.zeros(0, dtype=np.int8)]
            for start, item in zip(self.item_starts_us(), self.items, strict=True):
                n = item.counts(axes)[a]
                if n:
                    k = np.arange(1, abs(n) + 1, dtype=np.int64)
                    times.append(int(start) + -(-k * 2 * item.duration_us // abs(n)) / 2.0)
                    signs.append(np.full(abs(n), 1 if n > 0 else -1, dtype=np.int8))
            out.append((np.concatenate(times), np.concatenate(signs)))
        return out

    def step_times(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis 0's step instants (s from ``GO``, non-decreasing) and signs (+1 pull, -1 release, int8)."""
        t_us, signs = self.step_times_us()[0]
        return t_us / 1e6, signs

    def position_steps(self, t: np.ndarray | float, start_position: int = 0) -> np.ndarray:
        """Axis 0's position (steps) at times ``t`` (s from ``GO``); a step counts from its instant on."""
        t_s, signs = self.step_times()
        cum = np.concatenate([[0], np.cumsum(signs.astype(np.int64))])
        return start_position + cum[np.searchsorted(t_s, np.asarray(t, dtype=float), side="right")]

    def commands(self, axes: int = 1) -> list[str]:
        """The lines that load the programme on a board of ``axes`` axes: ``CLEAR``, its items (no ``GO``)."""
        return ["CLEAR", *(item.command(axes) for item in self.items)]

    def check_limits(self, limits: Limits, start_position: int | Sequence[int] = 0) -> None:
        """Raise ``ValueError`` naming the first limit the programme violates (the one check of a programme).

        Parameters
        ----------
        limits : Limits
            The rig's (:meth:`Limits.of`).
        start_position : int or sequence of int
            Every axis's position (steps from zero) when ``GO`` is sent (an int: axis 0's, the others at 0).

        Raises
        ------
        ValueError
            Empty programme, programme length (items or seconds), interval (speed), dwell length, travel, or
            a move for more tendons than the rig has; a refusal about one tendon of several names it.
        """
        lim, n = limits, limits.axes
        start = [start_position] + [0] * (n - 1) if isinstance(start_position, int) else list(start_position)
        pos = [check_int(p, "start_position") for p in start]
        if len(pos) != n:
            raise ValueError(f"{len(pos)} start positions for the rig's {n} tendon(s)")
        if not self.items:
            raise ValueError("programme length: the programme is empty (the board refuses GO)")
        if len(self.items) > lim.max_items:
            raise ValueError(f"programme length: {len(self.items)} items exceed the maximum {lim.max_items}")
        if self.duration_s > lim.max_programme_s:
            limit, s = lim.max_programme_s, self.duration_s
            raise ValueError(f"programme length: {s:.1f} s exceeds the host's limit of {limit:.0f} s")
        for a in range(n):
            if not -lim.release_steps[a] <= pos[a] <= lim.travel_steps[a]:
                who = f"tendon {a + 1}: " if n > 1 else ""
                raise ValueError(f"{who}travel limit: start position {pos[a]} outside {lim.travel_text(a)}")
        for i, item in enumerate(self.items):
            where = f"item {i + 1} ({item.command(n)})"
            if isinstance(item, Dwell):
                if item.ms > lim.max_dwell_ms:
                    raise ValueError(f"dwell limit: {where} exceeds the longest dwell, {lim.max_dwell_ms} ms")
                continue
            if isinstance(item, Move) and len(item.steps) > n:
                raise ValueError(f"{where}: {len(item.steps)} step counts, but the rig has {n} tendon(s)")
            for a, steps in enumerate(item.counts(n)):
                if not steps:
                    continue
                who = f"tendon {a + 1}, " if n > 1 else ""
                interval = item.duration_us / abs(steps)
                if interval < lim.min_interval_us:
                    speed = lim.mm_per_step[a] / interval * 1e6
                    raise ValueError(
                        f"{who}{where}: interval limit: a step every {interval:.0f} us ({speed:.0f} mm/s) is "
                        f"below the minimum interval {lim.min_interval_us} us ({lim.max_speed_mm_s:.0f} mm/s)"
                    )
                if interval > lim.max_interval_us:
                    raise ValueError(
                        f"{who}{where}: interval limit: a step every {interval:.0f} us is above the maximum "
                        f"interval of {lim.max_interval_us} us (slower is a dwell)"
                    )
                pos[a] += steps
                if not -lim.release_steps[a] <= pos[a] <= lim.travel_steps[a]:
                    raise ValueError(
                        f"{who}{where}: travel limit: position {pos[a]} steps "
                        f"({pos[a] * lim.mm_per_step[a]:.2f} mm) is past {lim.travel_text(a)}"
                    )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description for a recording's metadata (``kind``: ``SEG``, ``MSEG`` or ``WAIT``)."""
        items = [{"kind": item.command().split()[0], **asdict(item)} for item in self.items]
        return {"items": items, "duration_s": self.duration_s, "net_steps": self.net_steps}


# -- quantisation of an experiment ------------------------------------------------------------------------
@dataclass(frozen=True)
class QuantisationReport:
    """What :func:`experiment_programme` rounded, and by how much.

    Attributes
    ----------
    n_steps : int
        Steps per move, ``N = round(x_f / mm_per_step)`` (axis 0's).
    requested_mm, realised_mm : float
        ``x_f`` and ``N * mm_per_step``.
    pieces : pandas.DataFrame
        One row per piece of each move: ``move``, ``piece``, ``item`` (SEG/WAIT), nominal ``t_start_s``,
        ``t_end_s``, ``v_mm_s``, ``requested_mm``; realised ``steps`` (signed), ``interval_us``,
        ``realised_v_mm_s``, ``realised_end_s``, ``timing_error_us`` (realised minus nominal end).
    dwells : pandas.DataFrame
        The dwells between moves: ``dwell``, ``requested_s``, ``ms``, ``error_us``.
    down_start_error_s : float
        When the down move starts minus ``t_down``.
    merged_pieces : int
        Pieces shorter than :data:`MIN_PIECE_S` merged into a neighbour.
    carried_steps : int
        Steps moved to a neighbouring piece because rounding asked a short piece for more than the
        maximum step rate.
    """

    n_steps: int
    requested_mm: float
    realised_mm: float
    pieces: pd.DataFrame
    dwells: pd.DataFrame
    down_start_error_s: float
    merged_pieces: int = 0
    carried_steps: int = 0

    @property
    def max_timing_error_us(self) -> float:
        """Largest absolute piece-end timing error (us)."""
        return float(np.max(np.abs(self.pieces["timing_error_us"]))) if len(self.pieces) else 0.0

    def summary(self) -> pd.DataFrame:
        """One-row table of the headline numbers."""
        return pd.DataFrame(
            [
                {
                    "N_steps": self.n_steps,
                    "requested_mm": self.requested_mm,
                    "realised_mm": self.realised_mm,
                    "error_mm": self.realised_mm - self.requested_mm,
                    "max_piece_timing_error_us": self.max_timing_error_us,
                    "down_start_error_ms": 1e3 * self.down_start_error_s,
                }
            ]
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary for a recording's metadata."""
        return {
            "n_steps": self.n_steps,
            "requested_mm": self.requested_mm,
            "realised_mm": self.realised_mm,
            "max_timing_error_us": self.max_timing_error_us,
            "down_start_error_s": self.down_start_error_s,
            "merged_pieces": self.merged_pieces,
            "carried_steps": self.carried_steps,
        }


def _merge_short_pieces(
    b: np.ndarray, disp: np.ndarray, min_piece_s: float
) -> tuple[np.ndarray, np.ndarray, int]:
    """Merge pieces shorter than ``min_piece_s`` into their successor (the last one into its predecessor)."""
    b, disp = list(b), list(disp)
    merged = 0
    k = 0
    while len(disp) > 1 and k < len(disp):
        if b[k + 1] - b[k] >= min_piece_s:
            k += 1
            continue
        if k < len(disp) - 1:  # into the successor: drop breakpoint k+1
            disp[k + 1] += disp[k]
            del disp[k], b[k + 1]
        else:  # last piece: into the predecessor
            disp[k - 1] += disp[k]
            del disp[k], b[k]
        merged += 1
    return np.array(b), np.array(disp), merged


class _Builder:
    """Accumulates programme items while keeping the realised clock in whole microseconds."""

    def __init__(self, limits: Limits) -> None:
        self.limits, self.mm_per_step = limits, limits.mm_per_step[0]
        self.items: list[Item] = []
        self.clock_us = 0
        self.piece_rows: list[dict[str, Any]] = []
        self.dwell_rows: list[dict[str, Any]] = []

    def dwell_until(self, name: str, target_s: float) -> None:
        """Append dwells (split at the maximum) ending as close as 1 ms allows to ``target_s``."""
        ms = int(round((target_s * 1e6 - self.clock_us) / 1000.0))
        if ms < 0:
            raise ValueError(
                f"cannot dwell until {target_s:.6f} s: the programme already runs to "
                f"{self.clock_us / 1e6:.6f} s"
            )
        longest = self.limits.max_dwell_ms
        whole, rest = divmod(ms, longest)
        self.items += [Dwell(longest)] * whole + ([Dwell(rest)] if rest or not whole else [])
        self.clock_us += ms * 1000
        error_us = self.clock_us - target_s * 1e6
        self.dwell_rows.append({"dwell": name, "requested_s": target_s, "ms": ms, "error_us": error_us})

    def move(self, name: str, profile: VelocityProfile, direction: int, n_total: int) -> tuple[int, int]:
        """Quantise one move (all its pieces) so that it ends exactly ``n_total`` steps further on.

        Returns the number of merged short pieces and of steps carried to a neighbouring piece because
        rounding would have asked a short piece for a step rate above the limit.
        """
        b, disp, merged = _merge_short_pieces(profile.breakpoints, profile.piece_displacements, MIN_PIECE_S)
        cum_mm = np.concatenate([[0.0], np.cumsum(disp)]) * direction
        cum_steps = np.rint(cum_mm / self.mm_per_step).astype(np.int64)
        cum_steps[-1] = n_total  # cum_steps[0] is 0: the move starts from its first breakpoint
        min_iv = self.limits.min_interval_us
        carried = 0
        # the last piece cannot pass steps on: hand its excess back to its predecessor (1 us of margin)
        if disp.size > 1:
            n_last = int(cum_steps[-1] - cum_steps[-2])
            cap = int((b[-1] - b[-2]) * 1e6 // (min_iv + 1))
            if abs(n_last) > cap:
                cum_steps[-2] = cum_steps[-1] - np.sign(n_last) * cap
                carried += abs(n_last) - cap
        for k in range(disp.size):
            n_k = int(cum_steps[k + 1] - cum_steps[k])
            end_us = b[k + 1] * 1e6
            cap = max(0, int((end_us - self.clock_us) // min_iv))
            if abs(n_k) > cap and k < disp.size - 1:  # too fast for the board: pass the excess on
                cum_steps[k + 1] = cum_steps[k] + np.sign(n_k) * cap
                carried += abs(n_k) - cap
                n_k = int(cum_steps[k + 1] - cum_steps[k])
            row = {
                "move": name,
                "piece": k,
                "item": "WAIT" if n_k == 0 else "SEG",
                "t_start_s": b[k],
                "t_end_s": b[k + 1],
                "v_mm_s": disp[k] / (b[k + 1] - b[k]),
                "requested_mm": disp[k],
            }
            if n_k == 0:  # a dwell in whole ms (none if already late: the next piece catches up)
                ms = max(0, int(round((end_us - self.clock_us) / 1000.0)))
                if ms > 0:
                    self.items.append(Dwell(ms))
                self.clock_us += ms * 1000
                row.update(steps=0, interval_us=0, realised_v_mm_s=0.0)
            else:
                # never faster than the board allows: a piece that cannot fit ends late (reported)
                interval = max(min_iv, int(round((end_us - self.clock_us) / abs(n_k))))
                sign = direction * (1 if n_k > 0 else -1)
                self.items.append(Segment(sign, abs(n_k), interval))
                self.clock_us += abs(n_k) * interval
                row.update(
                    steps=n_k * direction,
                    interval_us=interval,
                    realised_v_mm_s=sign * self.mm_per_step / interval * 1e6,
                )
            row.update(realised_end_s=self.clock_us / 1e6, timing_error_us=self.clock_us - end_us)
            self.piece_rows.append(row)
        return merged, carried


def experiment_programme(
    v_in_mm_s: float,
    x_f_mm: float,
    shaper: Shaper | ShapesMoves | None = None,
    t_up: float = paper.PULSE_T_UP_S,
    t_down: float = paper.PULSE_T_DOWN_S,
    t_end: float = 12.0,
    *,
    rig: rigfile.RigFile | None = None,
) -> tuple[Programme, QuantisationReport]:
    """The whole Up-hold-Down experiment as one board-timed programme, quantised to whole steps.

    Lead-in dwell to ``t_up``; the up move (each constant piece of the shaped velocity becomes a segment,
    a piece with no step a dwell); a hold dwell to ``t_down``; the down move (direction -1: the mirror image
    for one shaper, the Down shaper of a pair, the Down sub-moves of a schedule); a trailing dwell to
    ``t_end``. Each move lands exactly on ``N = round(x_f / mm_per_step)`` steps:
    the steps of each piece are the differences of the cumulative displacement at the piece boundaries,
    rounded to whole steps. Each piece's integer interval is chosen so that it ends as close as possible to
    its nominal end on the realised clock, so rounding never accumulates (dwells are whole ms; the next
    segment absorbs their rounding). Pieces shorter than 2 ms (an edge of the pulse falling within 2 ms of an
    impulse time) are merged into a neighbour, and a step that rounding would ask of a short piece faster
    than the board's maximum step rate is carried to the neighbouring piece (both are counted in the
    report); a piece that still cannot fit runs at the maximum step rate and ends late (reported as its
    timing error). Commands faster than the speed limit are refused.

    Note the protocol puts step k of a segment at ``t0 + k*interval``: the staircase trails the continuous
    ramp by half an interval on average (0.6-0.7 ms at 200 mm/s).

    Parameters
    ----------
    v_in_mm_s, x_f_mm : float
        Cable speed (mm/s) and displacement (mm) of the pulse.
    shaper : Shaper, ShapesMoves or None, optional
        None for the unshaped pulse; a :class:`~helpers.paper.shapers.Shaper` shapes both moves; a shaping
        that makes its own moves (:class:`ShapesMoves`: the research wing's Up/Down pair, map-following
        schedule computed for this ``v_in_mm_s`` and ``x_f_mm``, or a design) gives them.
    t_up, t_down, t_end : float
        Start of the up move, start of the down move, end of the programme (s from ``GO``).
    rig : RigFile, optional
        The rig whose steps and limits the programme is made for (axis 0's); default the paper's rig.

    Returns
    -------
    (Programme, QuantisationReport)

    Raises
    ------
    ValueError
        Bad arguments, or a programme outside the board's limits (the message names the limit).
    """
    t_up, t_down, t_end = check_time(t_up, "t_up"), check_time(t_down, "t_down"), check_time(t_end, "t_end")
    limits = Limits.of(rigfile.default_rig() if rig is None else rig)
    up, down, n_total = _shaped_moves(v_in_mm_s, x_f_mm, shaper, (t_up, t_down, t_end), limits)
    build = _Builder(limits)
    build.dwell_until("lead-in", t_up)
    merged_up, carried_up = build.move("up", up, +1, n_total)
    build.dwell_until("hold", t_down)
    down_start_error = build.clock_us / 1e6 - t_down
    merged_down, carried_down = build.move("down", down, -1, n_total)
    build.dwell_until("trailing", t_end)

    programme = Programme(tuple(build.items))
    programme.check_limits(limits)
    report = QuantisationReport(
        n_steps=n_total,
        requested_mm=float(x_f_mm),
        realised_mm=n_total * limits.mm_per_step[0],
        pieces=pd.DataFrame(build.piece_rows),
        dwells=pd.DataFrame(build.dwell_rows),
        down_start_error_s=down_start_error,
        merged_pieces=merged_up + merged_down,
        carried_steps=carried_up + carried_down,
    )  # fmt: skip
    return programme, report


def _shaped_moves(
    v_in_mm_s: float, x_f_mm: float, shaper: Shaper | ShapesMoves | None, times: tuple[float, float, float],
    limits: Limits,
) -> tuple[VelocityProfile, VelocityProfile, int]:  # fmt: skip
    """The shaped up and down moves and their whole number of steps, checked against the limits and times."""
    t_up, t_down, t_end = times
    pulse_time(v_in_mm_s, x_f_mm)
    mm = limits.mm_per_step[0]
    n_total = int(round(x_f_mm / mm))
    if n_total < 1:
        raise ValueError(f"x_f_mm = {x_f_mm} mm is less than half a step ({mm:.5f} mm)")
    if shaper is None or isinstance(shaper, Shaper):
        up = single_pulse(v_in_mm_s, x_f_mm, t_up, +1).shaped(shaper)
        down = single_pulse(v_in_mm_s, x_f_mm, t_down, -1).shaped(shaper)
    elif isinstance(shaper, ShapesMoves):
        up, down = shaper.moves(v_in_mm_s, x_f_mm, t_up, t_down)
    else:
        raise ValueError(
            f"shaper must be a Shaper, a shaping that makes its own moves (ShapesMoves) or None, "
            f"got {shaper!r}"
        )
    peak = max(float(np.max(np.abs(up.velocities))), float(np.max(np.abs(down.velocities))))
    if peak > limits.max_speed_mm_s:
        raise ValueError(
            f"interval limit: the command's peak speed {peak:.1f} mm/s needs steps faster than the minimum "
            f"interval of {limits.min_interval_us} us ({limits.max_speed_mm_s:.0f} mm/s)"
        )
    if up.end > t_down:
        raise ValueError(f"the shaped up move ends at {up.end:.4f} s, after t_down = {t_down} s")
    if down.end > t_end:
        raise ValueError(f"the shaped down move ends at {down.end:.4f} s, after t_end = {t_end} s")
    return up, down, n_total


def table_i_programmes(
    shapers: dict[str, Shaper | None], t_end: float = 12.0, rig: rigfile.RigFile | None = None
) -> dict[tuple[str, float, float], tuple[Programme, QuantisationReport]]:
    """Programmes of every Table I scenario.

    Parameters
    ----------
    shapers : dict
        System name -> shaper (None for ``unshaped``), e.g. ``{"unshaped": None, "zv": zv, "zvd": zvd}``.
    t_end : float
        End of each programme (s).
    rig : RigFile, optional
        The rig (default the paper's).

    Returns
    -------
    dict
        ``(system, v_in_mm_s, x_f_mm) -> (Programme, QuantisationReport)``.
    """
    out = {}
    for system, shaper in shapers.items():
        for v, x in paper.TABLE_I_CONDITIONS:
            out[(system, v, x)] = experiment_programme(v, x, shaper, t_end=t_end, rig=rig)
    return out


def programmes_table(
    programmes: Iterable[tuple[Sequence[Any], tuple[Programme, QuantisationReport]]],
) -> pd.DataFrame:
    """Summarise programmes: key columns, items, steps, duration and the quantisation headline numbers.

    Parameters
    ----------
    programmes : iterable of (key, (Programme, QuantisationReport))
        E.g. ``table_i_programmes(...).items()`` with keys ``(system, v_in, x_f)``.

    Returns
    -------
    pandas.DataFrame
    """
    rows = []
    for (system, v, x), (prog, rep) in programmes:
        rows.append(
            {
                "system": system,
                "v_in_mm_s": v,
                "x_f_mm": x,
                "items": len(prog),
                "N_steps": rep.n_steps,
                "realised_mm": rep.realised_mm,
                "max_timing_error_us": rep.max_timing_error_us,
                "down_start_error_ms": 1e3 * rep.down_start_error_s,
                "duration_s": prog.duration_s,
            }
        )
    return pd.DataFrame(rows)
