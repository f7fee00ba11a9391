"""The exact shaped trajectory of a stream, in floating point, from ``firmware/PROTOCOL.md``'s numbers.

The independent check of :mod:`helpers.board.stream_reference`'s integer planner (tests/test_streaming.py):
it shares none of the reference's arithmetic, constants or step-time rule (as ``tests/crc_reference.py``, the
CRC's independent implementation, shares nothing with ``helpers.board.crc8``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

TICKS_PER_DELTA = 32  # the timer tick is 0.5 us; DELTA, the delays' and velocities' unit, is 16 us
PERIOD_TICKS = 625 * TICKS_PER_DELTA  # a control period: 10 ms
STEPS_PER_TICK_PER_UNIT = 2.0**-16 / TICKS_PER_DELTA  # a set-point unit: 2^-16 step per DELTA


def exact_position(
    shaper, v_by_period: Sequence[int], t_ticks: np.ndarray, position: int = 0, limits: bool = True,
    travel: int = 156, release: int = 0, v_max: int = 1640,
) -> np.ndarray:  # fmt: skip
    """The exact shaped position (steps, float) at times ``t_ticks`` (ticks from ``STREAM``).

    The velocity is the shaped set-point stream (set-point k on ``[(k + 1) T, (k + 2) T)``; amplitudes in
    1/4096, delays in us), clamped to the speed limit (``v_max`` units, the build's), integrated exactly piece
    by piece in floating point; with ``limits`` the position is saturated at ``-release`` and ``travel`` steps
    (the board's travel clamp: 0 and 156 by default).
    """
    d = np.asarray(shaper.delays_us, dtype=float) * 2  # ticks
    amp = np.asarray(shaper.amplitudes, dtype=float) / 4096
    v = np.asarray(v_by_period, dtype=float) * STEPS_PER_TICK_PER_UNIT  # steps per tick
    n = len(v)
    # breakpoints of the shaped velocity
    edges = sorted({float((k + 1) * PERIOD_TICKS + di) for k in range(n + 1) for di in d})
    t_query = np.asarray(t_ticks, dtype=float)
    t_end = max(float(t_query.max()) if t_query.size else 0.0, edges[-1])
    edges = [0.0] + [e for e in edges if e < t_end] + [t_end]

    def vcmd(t: float) -> float:
        k = int(np.floor(t / PERIOD_TICKS)) - 1
        return float(v[k]) if 0 <= k < n else 0.0

    s_max = v_max * STEPS_PER_TICK_PER_UNIT  # steps per tick
    x = float(position)
    xs = np.empty(len(edges))
    xs[0] = x
    rates = np.empty(len(edges) - 1)
    for i in range(len(edges) - 1):
        mid = 0.5 * (edges[i] + edges[i + 1])
        s = float(np.sum(amp * np.array([vcmd(mid - di) for di in d])))
        s = min(max(s, -s_max), s_max)
        rates[i] = s
        x = x + s * (edges[i + 1] - edges[i])
        if limits:
            x = min(max(x, -float(release)), float(travel))
        xs[i + 1] = x
    # positions at the query times: from the piece each falls in
    idx = np.clip(np.searchsorted(edges, t_query, side="right") - 1, 0, len(rates) - 1)
    e0 = np.asarray(edges)[idx]
    out = xs[idx] + rates[idx] * (t_query - e0)
    if limits:
        out = np.clip(out, -float(release), float(travel))
    return out
