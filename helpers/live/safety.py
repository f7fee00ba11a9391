"""Safety limits checked on the host before any byte is sent (``docs/safety.md``).

The limits are the stepper board's compiled-in ones (:mod:`helpers.paper.hardware`, the same numbers as
``firmware/PROTOCOL.md``): cable travel 0-40 mm from zero (156 steps), speed <= 400 mm/s and step rate
<= 2000 steps/s (minimum step interval 639 us), programme length <= 64 items, dwells <= 60 s. The host adds
one of its own: a programme may last at most ``MAX_PROGRAMME_S`` (a recording is held in memory).
"""

from __future__ import annotations

from typing import Any

from helpers.base.validate import check_positive
from helpers.board.programmes import Programme
from helpers.paper.hardware import (
    LIMITS,
    MAX_PROGRAMME_S,
    MAX_PULSE_MM,
    MAX_SPEED_MM_S,
    MAX_STEP_RATE_HZ,
    MAX_TRAVEL_MM,
    MM_PER_STEP,
)


class SafetyError(ValueError):
    """A request outside the rig's limits; nothing was sent to the boards."""


def check_request(v_in_mm_s: Any, x_f_mm: Any) -> tuple[float, float]:
    """Check a pulse request (speed and displacement) against the limits.

    Parameters
    ----------
    v_in_mm_s : float
        Cable speed (mm/s): finite, > 0, <= 400 mm/s and <= 2000 steps/s.
    x_f_mm : float
        Cable displacement (mm): finite, > 0, at least half a step, at most the travel's 156 steps (39.8 mm).

    Returns
    -------
    (float, float)
        The checked values.

    Raises
    ------
    SafetyError
        Naming the limit.
    """
    try:
        v = check_positive(v_in_mm_s, "speed v_in_mm_s (mm/s)")
        x = check_positive(x_f_mm, "displacement x_f_mm (mm)")
    except ValueError as exc:
        raise SafetyError(str(exc)) from None
    if v > MAX_SPEED_MM_S:
        raise SafetyError(f"speed {v} mm/s exceeds the limit of {MAX_SPEED_MM_S:.0f} mm/s")
    if v / MM_PER_STEP > MAX_STEP_RATE_HZ:
        raise SafetyError(f"speed {v} mm/s needs {v / MM_PER_STEP:.0f} steps/s, above {MAX_STEP_RATE_HZ:.0f}")
    if x > MAX_TRAVEL_MM:
        raise SafetyError(f"displacement {x} mm exceeds the travel limit of {MAX_TRAVEL_MM:.0f} mm")
    if round(x / MM_PER_STEP) < 1:
        raise SafetyError(f"displacement {x} mm is less than half a step ({MM_PER_STEP:.5f} mm)")
    if round(x / MM_PER_STEP) > LIMITS.max_position_steps:
        raise SafetyError(
            f"displacement {x} mm is {round(x / MM_PER_STEP)} steps, beyond the travel of "
            f"{LIMITS.max_position_steps} steps ({MAX_PULSE_MM:.1f} mm)"
        )
    return v, x


def check_programme(programme: Any, start_position: int = 0) -> None:
    """Check a stepper programme against the board's limits and the host's duration limit.

    Parameters
    ----------
    programme : helpers.board.programmes.Programme
        The programme.
    start_position : int
        Motor position (steps) when ``GO`` is sent.

    Raises
    ------
    SafetyError
        Not a programme, empty, too many items, a step interval too short (speed, step rate) or too long, a
        dwell too long, travel outside 0-40 mm, or longer than :data:`MAX_PROGRAMME_S`.
    """
    if not isinstance(programme, Programme):
        raise SafetyError(f"expected a helpers.board.programmes.Programme, got {type(programme).__name__}")
    try:
        programme.check_limits(start_position=start_position)
    except ValueError as exc:
        raise SafetyError(f"programme refused: {exc}") from None
    if programme.duration_s > MAX_PROGRAMME_S:
        raise SafetyError(
            f"programme length: {programme.duration_s:.1f} s exceeds the host's limit of "
            f"{MAX_PROGRAMME_S:.0f} s"
        )
