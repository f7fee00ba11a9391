"""Figures of the experiments: the paper's Figs. 9-11 (and the 10 mm case), tension of the three systems."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import matplotlib.pyplot as plt
import numpy as np

from helpers.paper import numbers as paper
from helpers.paper.metrics import clipped_samples
from helpers.plotting import SYSTEM_COLOURS, finish
from helpers.rigfile.recorded import calibration_of, recording_rig

PAPER_FIGURE_NUMBERS: dict[tuple[float, float], int | str] = {
    (200.0, 20.0): 9,
    (200.0, 30.0): 10,
    (300.0, 20.0): 11,
    (200.0, 10.0): "A",
}
"""The paper's figure number for each (v_in mm/s, x_f mm) condition; the 10 mm case has no figure there."""


def _matches(rec: Any, condition: tuple[float, float]) -> bool:
    sc = rec.meta["scenario"]
    return (
        abs(float(sc["v_in_mm_s"]) - condition[0]) < 1e-6 and abs(float(sc["x_f_mm"]) - condition[1]) < 1e-6
    )


def _common_grid(recs: Sequence[Any], column: str) -> tuple[np.ndarray, np.ndarray]:
    """The recordings' ``column`` on the first one's time grid (shortest length), one row per recording."""
    t = recs[0].frame["t_s"].to_numpy()
    n = min(len(r.frame) for r in recs)
    rows = [np.interp(t[:n], r.frame["t_s"].to_numpy(), r.frame[column].to_numpy()) for r in recs]
    return t[:n], np.vstack(rows)


def fig_scenario(
    recordings: Iterable[Any],
    condition: tuple[float, float],
    *,
    save: bool = False,
) -> plt.Figure:
    """Tension responses of the three systems for one condition, the motor position underneath (Figs. 9-11).

    One row per system, so that no trace hides another: the mean over the repetitions as a line and the range
    between their lowest and highest value as a band; the cable displacement of each system underneath.
    Recordings of other conditions are ignored. Samples the sensor clipped
    (:func:`helpers.paper.metrics.clipped_samples`, on the ``adc`` column) are marked with black crosses:
    their
    tension is only a bound.

    Parameters
    ----------
    recordings : iterable
        Recordings (objects with ``.frame`` holding ``t_s``, ``tension_n`` and ``cable_mm`` or ``steps``, and
        ``.meta`` with ``"scenario"``; a ``source.kind`` of ``"virtual-rig"`` is named in the title), grouped
        by ``meta["scenario"]["system"]``.
    condition : (float, float)
        ``(v_in in mm/s, x_f in mm)``.
    save : bool
        Save as ``figures/fig<number>_<x_f>mm_<v_in>mms.png``, with the paper's figure number
        (:data:`PAPER_FIGURE_NUMBERS`; ``X`` for a condition not listed there).

    Returns
    -------
    matplotlib.figure.Figure
        The figure.

    Raises
    ------
    ValueError
        If no recording matches ``condition``.
    """
    condition = (float(condition[0]), float(condition[1]))
    number = PAPER_FIGURE_NUMBERS.get(condition, "X")
    groups: dict[str, list[Any]] = {}
    for rec in recordings:
        if _matches(rec, condition):
            groups.setdefault(str(rec.meta["scenario"]["system"]), []).append(rec)
    if not groups:
        raise ValueError(
            f"no recording matches the condition v_in = {condition[0]:g} mm/s, x_f = {condition[1]:g} mm"
        )
    order = [s for s in paper.SYSTEMS if s in groups] + sorted(s for s in groups if s not in paper.SYSTEMS)

    # one row per system (the shaped traces never hide each other), the repetitions as their mean and the
    # band between their lowest and highest sample, the cable underneath
    fig, axes = plt.subplots(
        len(order) + 1, 1, sharex=True, figsize=(7.0, 1.9 * len(order) + 1.6),
        gridspec_kw={"height_ratios": [2.0] * len(order) + [1.2]},
    )  # fmt: skip
    ax_u = axes[-1]
    virtual = False
    clipped_label = "clipped (outside the sensor's range)"
    n_reps = max(len(v) for v in groups.values())
    for ax_t, system in zip(axes[:-1], order, strict=False):
        colour = SYSTEM_COLOURS.get(system, "C7")
        label = paper.SYSTEM_LABELS.get(system, system) + (" TDF" if system in ("zv", "zvd") else "")
        recs = sorted(groups[system], key=lambda r: int(r.meta["scenario"].get("repetition", 0)))
        virtual |= any(r.meta.get("source", {}).get("kind") == "virtual-rig" for r in recs)
        t, tension = _common_grid(recs, "tension_n")
        if len(recs) > 1:
            ax_t.fill_between(t, tension.min(axis=0), tension.max(axis=0), color=colour, alpha=0.3, lw=0,
                              label=f"range of {len(recs)} repetitions")  # fmt: skip
        ax_t.plot(t, tension.mean(axis=0), color=colour, lw=0.9,
                  label=f"mean of {len(recs)}" if len(recs) > 1 else "tension")  # fmt: skip
        for rec in recs:
            f = rec.frame
            if "adc" in f.columns:
                cal = calibration_of(rec.meta) if "calibration" in (rec.meta or {}) else None  # any version
                clip = clipped_samples(f["adc"].to_numpy(), cal, recording_rig(rec.meta or {}))
                if clip.any():
                    ax_t.plot(f["t_s"][clip], f["tension_n"][clip], "x", color="k", ms=4, label=clipped_label)
                    clipped_label = None
        ax_t.set_ylabel("tension (N)")
        ax_t.set_title(label, fontsize=9, loc="left", color=colour)
        ax_t.legend(loc="upper right", fontsize=7)
        column = "cable_mm" if "cable_mm" in recs[0].frame.columns else "steps"
        ax_u.plot(recs[0].frame["t_s"], recs[0].frame[column], color=colour, lw=1.0, label=label)
    low = min(ax.get_ylim()[0] for ax in axes[:-1])
    high = max(ax.get_ylim()[1] for ax in axes[:-1])
    for ax in axes[:-1]:
        ax.set_ylim(low, high)
    first = groups[order[0]][0].frame
    ax_u.set_ylabel("cable (mm)" if "cable_mm" in first.columns else "motor (steps)")
    ax_u.set_xlabel("time (s)")
    ax_u.legend(loc="upper right", fontsize=7, ncols=len(order))
    what = f"{condition[1]:g} mm at {condition[0]:g} mm/s"
    title = f"Fig. {number}: {what}" if isinstance(number, int) else f"{what} (no figure in the paper)"
    reps = f", {n_reps} repetitions per system" if n_reps > 1 else ""
    fig.suptitle(title + (" (virtual rig" + reps + ")" if virtual else reps), fontsize=10)
    return finish(fig, f"fig{number}_{condition[1]:g}mm_{condition[0]:g}mms.png" if save else None)
