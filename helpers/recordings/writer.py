"""The one writer of recordings, for 1 to 4 tendons alike.

A run's samples, its rig and its metadata become a :class:`Recording` of ``schema_version`` 4
(``docs/recording_format.md``): :func:`from_samples` builds it (and checks its metadata as
:func:`helpers.recordings.load` will); :func:`helpers.recordings.save` writes it. :func:`nominal_calibration`
is the rig file's load-cell chain, the calibration of a tendon whose cell has not been calibrated.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from helpers import __version__, rigfile
from helpers.base.jsonfile import dumps
from helpers.recordings.checks import validate_meta
from helpers.recordings.format import VERSION, Recording, raw_columns
from helpers.rigfile.recorded import rig_section

TWIN_TIP = (
    "twin-provided: the spatial twin's tip node, clamp frame, at channel 0's instant of each sample "
    "(not measured)"
)
"""The ``tip.origin`` of rows carrying the tip's three columns (only the in-process virtual rig has them)."""


def nominal_calibration(rig: rigfile.RigFile) -> list[dict[str, Any]]:
    """Every tendon's calibration from the rig file's load-cell chain (the loop's offset, its range)."""
    d = rigfile.derived(rig)
    origin = f"nominal: rig file {rig.name} ({rig.hash}), [hardware] loop and load_cell_range_n"
    return [
        {"newtons_per_count": 1.0 / g, "offset_counts": d.offset_counts, "mm_per_step": mm, "origin": origin}
        for g, mm in zip(d.gain_counts_per_n, d.mm_per_step, strict=True)
    ]  # fmt: skip


def from_samples(
    rows: Any, rig: rigfile.RigFile, calibration: Sequence[Any] | None = None, *, source: Mapping[str, Any],
    scenario: Mapping[str, Any], rate_hz: int, started_utc: str, firmware: Mapping[str, str],
    status: str = "complete", reason: str | None = None, counts: Mapping[str, int] | None = None,
    t_go_us: int | None = None, **more: Any,
) -> Recording:  # fmt: skip
    """A run as a recording of :data:`~helpers.recordings.format.VERSION` 4, its frame derived.

    Parameters
    ----------
    rows : array_like of int
        The samples, one row each: ``(seq, t_us, adc_0 .. adc_{n-1}, steps_0 .. steps_{n-1})`` for the rig's
        n tendons (``steps_i``: the axis's position, the DAQ's count plus where the run started), and three
        more, ``tip_x_um, tip_y_um, tip_z_um``, when the twin provides the tip.
    rig : helpers.rigfile.RigFile
        The rig the run was made on (kept whole in the metadata's ``rig``).
    calibration : sequence, optional
        One calibration per tendon: a mapping or an object with ``to_dict()``
        (:class:`helpers.paper.tension.LoadCellCalibration`) holding ``newtons_per_count``,
        ``offset_counts``, ``mm_per_step`` and ``origin``. Default :func:`nominal_calibration`.
    source, scenario, rate_hz, started_utc, firmware, status, reason, counts, t_go_us
        The metadata of the same names (``reason`` is ``abort_reason``; ``counts`` the link's ``dropped``,
        ``corrupted``, ``overruns``, ``implausible``: ``samples`` is counted here).
    **more
        Further top-level keys (e.g. ``done_positions``, ``deviation``).

    Raises
    ------
    ValueError
        ``rows`` or ``calibration`` do not fit the rig's tendon count.
    helpers.recordings.RecordingError
        The metadata breaks the contract (a key of the wrong type or range: a bug of the caller).
    """
    n = rig.n_tendons
    width = 2 + 2 * n
    a = np.asarray(rows, dtype=np.int64)
    a = a.reshape(0, width) if a.size == 0 else a
    if a.ndim != 2 or a.shape[1] not in (width, width + 3):
        raise ValueError(f"rows: shape {a.shape}; a rig of {n} tendons records {width} columns (+3: the tip)")
    cals = [
        dict(c.to_dict() if hasattr(c, "to_dict") else c) for c in calibration or nominal_calibration(rig)
    ]
    if len(cals) != n:
        raise ValueError(f"calibration: {len(cals)} given for a rig of {n} tendons")
    meta = {
        "schema_version": VERSION, "tendons": n, "rig": rig_section(rig), "source": dict(source),
        "scenario": dict(scenario), "calibration": {k: [c.get(k) for c in cals] for k in cals[0]},
        "rate_hz": int(rate_hz), "firmware": dict(firmware), "host": {"helpers": __version__},
        "started_utc": started_utc, "status": status, "abort_reason": reason,
        "counts": {**(counts or {}), "samples": len(a)}, "t_go_us": t_go_us,
        "t_go_s": None if t_go_us is None or not len(a) else (t_go_us - int(a[0, 1])) / 1e6, **more,
    }  # fmt: skip
    if a.shape[1] > width:
        meta["tip"] = {"origin": TWIN_TIP, "unit": "um"}
    meta = json.loads(dumps(meta))  # as saved and loaded: plain JSON values
    validate_meta({**meta, "csv_sha256": "0" * 64}, Path("<unsaved recording>"))  # saved later, with its sha
    return Recording(pd.DataFrame(a, columns=list(raw_columns(meta))), meta).derive()
