"""Safety limits checked on the host before any byte is sent (``docs/safety.md``), for 1 to 4 tendons.

The limits are the stepper board's compiled-in ones, which follow from the rig file
(:meth:`helpers.board.programmes.Limits.of`; the paper's rig: cable travel 0-40 mm from zero, 156 steps,
speed <= 400 mm/s and step rate <= 2000 steps/s, a step at most every 639 us, programmes of at most 64 items,
dwells <= 60 s) and one of the host's own: a programme lasts at most ``max_programme_s`` (a recording is held
in memory). On a rig of several tendons a state in which every tendon is slack is refused too: by the rig
file's statics tendon ``i`` pulled ``u_i`` from zero holds ``pretension_n_i + cable_stiffness_n_m_i u_i``,
and where that is ``<= 0`` for every tendon the arm hangs on none. Every refusal is one line naming the
tendon (numbered from 1, as in the rig file) and the limit.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from helpers.base.validate import check_positive
from helpers.board.programmes import Limits, Programme
from helpers.rigfile import RigFile, derived


class SafetyError(ValueError):
    """A request outside the rig's limits; nothing was sent to the boards."""


def check_request(v_in_mm_s: Any, x_f_mm: Any, rig: RigFile) -> tuple[float, float]:
    """Check a pulse request (tendon 1's speed and displacement) against ``rig``'s limits.

    Returns
    -------
    (float, float)
        The checked values.

    Raises
    ------
    SafetyError
        Not a finite positive number, faster than the speed limit or the step-rate cap, beyond the travel
        or less than half a step; the message names the limit.
    """
    try:
        v = check_positive(v_in_mm_s, "speed v_in_mm_s (mm/s)")
        x = check_positive(x_f_mm, "displacement x_f_mm (mm)")
    except ValueError as exc:
        raise SafetyError(str(exc)) from None
    lim = Limits.of(rig)
    mm, n = lim.mm_per_step[0], round(x / lim.mm_per_step[0])
    if v > lim.max_speed_mm_s:
        raise SafetyError(f"speed {v} mm/s exceeds the limit of {lim.max_speed_mm_s:.0f} mm/s")
    if v / mm > lim.max_step_rate_hz:
        raise SafetyError(f"speed {v} mm/s needs {v / mm:.0f} steps/s, above {lim.max_step_rate_hz:.0f}")
    if x > rig.hardware.travel_mm:
        raise SafetyError(f"displacement {x} mm exceeds the travel limit of {rig.hardware.travel_mm:g} mm")
    if n < 1:
        raise SafetyError(f"displacement {x} mm is less than half a step ({mm:.5f} mm)")
    if n > lim.travel_steps[0]:
        raise SafetyError(
            f"displacement {x} mm is {n} steps, beyond the travel of {lim.travel_steps[0]} steps "
            f"({lim.travel_steps[0] * mm:.1f} mm)"
        )
    return v, x


def static_tensions(rig: RigFile, positions: Sequence[float] | np.ndarray) -> np.ndarray:
    """Each tendon's tension by the rig file's statics, ``T_0 + k u`` (N), at ``positions`` (steps from zero).

    ``positions``: one per tendon, or an array of such rows (shape ``(..., n)``, fractions of a step allowed).
    """
    pre = np.array([t.pretension_n for t in rig.tendons], dtype=float)
    k = np.array([t.cable_stiffness_n_m for t in rig.tendons], dtype=float)
    return pre + k * np.asarray(positions, dtype=float) * np.asarray(derived(rig).mm_per_step) * 1e-3


def check_slack(rig: RigFile, positions: np.ndarray, where: Sequence[str]) -> None:
    """Refuse the first row of ``positions`` (steps, shape ``(k, n)``) at which every tendon is slack."""
    tensions = static_tensions(rig, positions)
    slack = np.flatnonzero(np.all(tensions <= 0.0, axis=1)) if rig.n_tendons > 1 else []
    if len(slack):
        k = int(slack[0])
        at = ", ".join(f"{p:g}" for p in positions[k])
        figures = ", ".join(f"{t:.2f}" for t in tensions[k])
        raise SafetyError(
            f"tendons 1-{rig.n_tendons}, {where[k]}: every tendon slack at positions ({at}) steps "
            f"(pretension + k pull = {figures} N <= 0): the arm would hang on no tendon"
        )


def check_programme(
    programme: Any, rig: RigFile, start: Sequence[int] | int = 0, rest_ok: bool = False
) -> None:
    """Check a stepper programme against ``rig``'s limits from every tendon's ``start`` position.

    ``rest_ok``: the rest state (every tendon at zero) is allowed even where every tendon is slack there
    (homing returns to the rest the rig file describes).

    Raises
    ------
    SafetyError
        Not a programme, or outside a limit (:meth:`~helpers.board.programmes.Programme.check_limits`), or a
        state with every tendon slack; one line naming the tendon and the limit.
    """
    if not isinstance(programme, Programme):
        raise SafetyError(f"expected a helpers.board.programmes.Programme, got {type(programme).__name__}")
    try:
        programme.check_limits(Limits.of(rig), start)
    except ValueError as exc:
        raise SafetyError(f"programme refused: {exc}") from None
    rows = programme.positions(start, rig.n_tendons)  # (its limits checked: a Move fits the rig's tendons)
    states = [(i, r) for i, r in enumerate(rows[1:], start=1) if not (rest_ok and not any(r))]
    if states:
        check_slack(rig, np.array([r for _, r in states], dtype=float), [f"item {i}" for i, _ in states])
