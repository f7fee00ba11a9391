"""Shaper design from a measured frequency map (``docs/shaper_design.md``).

The paper designs its two time-delay filters from one mode identified at rest. The arm's frequency rises as
the cable bends it and a second mode carries part of the residual, so this room designs from a
:class:`helpers.research.modemap.ModeMap` instead; every design is a pure function of the map, the move
(``x_f``, ``v_in``) and options, and returns a :class:`Design` (a shaper, an Up/Down pair or a
map-following schedule, named by a system of :data:`SYSTEMS`) that :func:`save_design` writes as JSON and
``python -m helpers record pulse --design FILE`` runs.

- :mod:`~helpers.research.design.formats`: :class:`Design`, :class:`ShaperPair`, :class:`Schedule`, the JSON
file,
  the system vocabulary;
- :mod:`~helpers.research.design.predict`: the predicted residual over the band a move sweeps and the
uncertainty;
- :mod:`~helpers.research.design.scheduled`: :func:`scheduled_pair`, :func:`map_following`;
- :mod:`~helpers.research.design.robust`: :func:`band_centred` (EI, multi-hump EI), :func:`multi_mode_design`,
  :func:`minimax`;
- :mod:`~helpers.research.design.auto`: :func:`auto_choice`;
- :mod:`~helpers.research.design.timevarying`: the residual on a model whose frequency follows the map during
a move.
"""

from helpers.research.design.auto import AutoChoice, auto_choice
from helpers.research.design.formats import (
    DESIGN_FORMAT,
    DESIGN_VERSION,
    PAPER_SYSTEMS,
    SYSTEMS,
    Design,
    MoveSchedule,
    Schedule,
    ShaperPair,
    Shaping,
    SubMove,
    as_design,
    load_design,
    save_design,
    up_down,
)
from helpers.research.design.predict import (
    DEFAULT_COVERAGE,
    DEFAULT_TOLERANCE_PCT,
    Band,
    band,
    predicted_residual,
    worst_predicted_pct,
    worst_residual_pct,
)
from helpers.research.design.robust import band_centred, minimax, multi_mode_design
from helpers.research.design.scheduled import map_following, scheduled_pair
from helpers.research.design.timevarying import compare_time_varying, time_varying_residual

__all__ = [
    "AutoChoice",
    "Band",
    "DEFAULT_COVERAGE",
    "DEFAULT_TOLERANCE_PCT",
    "DESIGN_FORMAT",
    "DESIGN_VERSION",
    "Design",
    "MoveSchedule",
    "PAPER_SYSTEMS",
    "SYSTEMS",
    "Schedule",
    "ShaperPair",
    "Shaping",
    "SubMove",
    "as_design",
    "auto_choice",
    "band",
    "band_centred",
    "compare_time_varying",
    "load_design",
    "map_following",
    "minimax",
    "multi_mode_design",
    "predicted_residual",
    "save_design",
    "scheduled_pair",
    "time_varying_residual",
    "up_down",
    "worst_predicted_pct",
    "worst_residual_pct",
]
