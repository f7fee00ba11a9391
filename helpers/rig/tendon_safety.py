"""A coordinated programme for several tendons, and its safety limits, checked before any byte is sent.

:class:`TendonProgramme` is a list of items, each either every tendon's signed step count in one time window
(the stepper's ``MSEG``) or a dwell of every tendon (``WAIT``). :func:`check_tendon_programme` refuses, in
one line naming the tendon and the limit (``docs/safety.md``), a programme that

- has no item, more items than the board holds, or an item without one step count per tendon;
- moves a tendon past its travel (``-release_steps..travel_steps`` of the rig file, from its present
  position: position 0 is the rest, and a tendon pays out at most ``release_mm`` below it);
- steps a tendon faster than the step-interval floor (``window / |n|`` below the rig's shortest interval) or
  slower than the longest interval, or dwells longer than the rig's longest dwell;
- commands a state in which every tendon is slack: by the statics of the rig file's tendons, tendon ``i``
  pulled ``u_i`` (m) from zero holds ``pretension_n_i + cable_stiffness_n_m_i u_i``, and a state where that
  is ``<= 0`` for every tendon leaves the arm hanging on none (the state after each item is checked);
- lasts longer than the host's ``max_programme_s``.

Tendons are named 1.. as in the rig file (tendon ``i`` is the boards' axis and channel ``i - 1``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from helpers.rig.safety import SafetyError
from helpers.rigfile import RigFile
from helpers.rigfile.derived import derived

__all__ = [
    "TendonItem", "TendonProgramme", "check_tendon_programme", "slack_tendons", "static_tensions",
    "travel_text",
]  # fmt: skip


def travel_text(rig: RigFile, i: int) -> str:
    """Tendon ``i``'s (0-based) travel for a refusal.

    ``0-156 steps (39.8 mm)``; with a release below position 0, ``-78-156 steps (-19.9-39.8 mm)``.
    """
    d = derived(rig)
    travel, release, mm = d.travel_steps[i], d.release_steps[i], d.mm_per_step[i]
    if not release:
        return f"0-{travel} steps ({travel * mm:.1f} mm)"
    return f"-{release}-{travel} steps ({-release * mm:.1f}-{travel * mm:.1f} mm)"


@dataclass(frozen=True)
class TendonItem:
    """One item: ``steps`` (signed, + pulls) of every tendon in ``window_us``, or a dwell (``steps`` None)."""

    window_us: int
    steps: tuple[int, ...] | None = None

    @classmethod
    def dwell(cls, ms: int) -> TendonItem:
        """A dwell of ``ms`` milliseconds."""
        return cls(1000 * int(ms), None)

    def command(self, axes: int) -> str:
        """The stepper command (``MSEG`` with zeros for a board's further axes, or ``WAIT``)."""
        if self.steps is None:
            return f"WAIT {self.window_us // 1000}"
        counts = list(self.steps) + [0] * (axes - len(self.steps))
        return f"MSEG {self.window_us} " + " ".join(map(str, counts))


@dataclass(frozen=True)
class TendonProgramme:
    """A coordinated programme: items run back to back, every tendon in each item's window."""

    items: tuple[TendonItem, ...]

    @classmethod
    def moves(cls, moves: Sequence[tuple[int, Sequence[int]]]) -> TendonProgramme:
        """From ``(window_us, steps)`` pairs (``steps`` None: a dwell of ``window_us``)."""
        items = (TendonItem(int(w), None if s is None else tuple(int(n) for n in s)) for w, s in moves)
        return cls(tuple(items))

    @property
    def duration_s(self) -> float:
        """Sum of the items' windows, s."""
        return sum(it.window_us for it in self.items) / 1e6

    def commands(self, axes: int) -> list[str]:
        """``CLEAR`` and the items' commands for a board with ``axes`` axes."""
        return ["CLEAR"] + [it.command(axes) for it in self.items]

    def end_positions(self, start: Sequence[int]) -> tuple[int, ...]:
        """Every tendon's position after the programme."""
        pos = list(start)
        for it in self.items:
            if it.steps is not None:
                pos = [p + n for p, n in zip(pos, it.steps, strict=True)]
        return tuple(pos)


def static_tensions(rig: RigFile, positions: Sequence[float] | np.ndarray) -> np.ndarray:
    """Each tendon's tension by the rig file's statics, ``T_0 + k u`` (N), at ``positions`` (steps from zero).

    ``positions``: one per tendon, or an array of such rows (shape ``(..., n)``, fractions of a step allowed).
    """
    d = derived(rig)
    pre = np.array([t.pretension_n for t in rig.tendons], dtype=float)
    k = np.array([t.cable_stiffness_n_m for t in rig.tendons], dtype=float)
    pull_m = np.asarray(positions, dtype=float) * np.asarray(d.mm_per_step, dtype=float) * 1e-3
    return pre + k * pull_m


def slack_tendons(rig: RigFile, positions: Sequence[float]) -> list[bool]:
    """Whether each tendon is slack at ``positions`` (steps from zero): ``T_0 + k u <= 0`` (N, m)."""
    return [bool(x <= 0.0) for x in static_tensions(rig, positions)]


def check_tendon_programme(
    programme: TendonProgramme, rig: RigFile, start: Sequence[int] | None = None, rest_ok: bool = False
) -> tuple[int, ...]:
    """Check ``programme`` against every tendon's limits from ``start``; return the end positions.

    ``rest_ok``: the rest state (every tendon at zero) is allowed even when every tendon is slack there
    (homing returns to the rest the rig file describes).

    Raises
    ------
    SafetyError
        One line naming the tendon (1..) and the limit; see the module's docstring.
    """
    if not isinstance(programme, TendonProgramme):
        raise SafetyError(f"expected a TendonProgramme, got {type(programme).__name__}")
    n = rig.n_tendons
    d = derived(rig)
    hw = rig.hardware
    pos = list(start) if start is not None else [0] * n
    if len(pos) != n:
        raise SafetyError(f"{len(pos)} start positions for the rig's {n} tendons")
    if not programme.items:
        raise SafetyError("programme refused: it has no item")
    if len(programme.items) > hw.programme_max_items:
        raise SafetyError(
            f"programme length: {len(programme.items)} items exceed the board's {hw.programme_max_items}"
        )
    for k, it in enumerate(programme.items, start=1):
        where = f"item {k}"
        if it.steps is None:
            if not 0 <= it.window_us <= 1000 * hw.max_dwell_ms or it.window_us % 1000:
                raise SafetyError(f"{where}: dwell {it.window_us / 1000:g} ms outside 0-{hw.max_dwell_ms} ms")
            continue
        if len(it.steps) != n:
            raise SafetyError(f"{where}: {len(it.steps)} step counts for the rig's {n} tendons")
        if not any(it.steps):
            raise SafetyError(f"{where}: no tendon moves (a dwell is TendonItem.dwell)")
        if it.window_us < 1:
            raise SafetyError(f"{where}: window {it.window_us} us must be at least 1 us")
        for i, steps in enumerate(it.steps):
            m = abs(steps)
            if m and it.window_us < m * d.min_interval_us:
                raise SafetyError(
                    f"tendon {i + 1}, {where}: {m} steps in {it.window_us} us is a step every "
                    f"{it.window_us / m:.0f} us, below the step-interval floor of {d.min_interval_us} us"
                )
            if m and it.window_us > m * d.max_interval_us:
                raise SafetyError(
                    f"tendon {i + 1}, {where}: a step every {it.window_us / m:.0f} us, above the longest "
                    f"interval of {d.max_interval_us} us (slower is a dwell)"
                )
            pos[i] += steps
            travel, release = d.travel_steps[i], d.release_steps[i]
            if not -release <= pos[i] <= travel:
                raise SafetyError(
                    f"tendon {i + 1}, {where}: position {pos[i]} steps is past its travel of "
                    f"{travel_text(rig, i)}"
                )
        if all(slack_tendons(rig, pos)) and not (rest_ok and not any(pos)):
            tensions = ", ".join(
                f"{t.pretension_n + t.cable_stiffness_n_m * p * d.mm_per_step[i] * 1e-3:.2f}"
                for i, (t, p) in enumerate(zip(rig.tendons, pos, strict=True))
            )
            raise SafetyError(
                f"tendons 1-{n}, {where}: every tendon slack at positions {tuple(pos)} (pretension + "
                f"k pull = {tensions} N <= 0): the arm would hang on no tendon"
            )
    if programme.duration_s > hw.max_programme_s:
        raise SafetyError(
            f"programme length: {programme.duration_s:.1f} s exceeds the host's limit of "
            f"{hw.max_programme_s:.0f} s"
        )
    return tuple(pos)
