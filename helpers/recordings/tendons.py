"""Deprecated: the names the several-tendon writer (``helpers.rig.tendons``) and its readers import from here.

Recordings of any tendon count are :mod:`helpers.recordings.format`'s (columns, frame) and
:func:`helpers.recordings.from_samples`'s (the writer, ``schema_version`` 4); this module goes once
``helpers.rig.tendons``, ``helpers.research.tendon_residuals`` and ``helpers.commands.metrics_tendons`` import
those names from :mod:`helpers.recordings`.
"""

from __future__ import annotations

from helpers.recordings.format import TIP_COLUMNS, TIP_MM_COLUMNS, tendon_columns, tendon_count
from helpers.recordings.format import raw_columns as recorded_columns

__all__ = ["TENDON_SCHEMA_VERSION", "TIP_COLUMNS", "TIP_MM_COLUMNS", "recorded_columns", "tendon_columns",
           "tendon_count"]  # fmt: skip

TENDON_SCHEMA_VERSION = 3
"""The version the several-tendon writer of ``helpers.rig.tendons`` stamps (version 3)."""
