"""Figures of the experiments: the paper's Figs. 9-11 (and the 10 mm case), tension of the three systems."""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import matplotlib.pyplot as plt

from helpers import paper
from helpers.metrics import clipped_samples
from helpers.plotting import SYSTEM_COLOURS
from helpers.plotting import save as save_figure

PAPER_FIGURE_NUMBERS: dict[tuple[float, float], int | str] = {
    (200.0, 20.0): 9,
    (200.0, 30.0): 10,
    (300.0, 20.0): 11,
    (200.0, 10.0): "A",
}
"""The paper's figure number for each (v_in mm/s, x_f mm) condition; the 10 mm case has no figure there."""


def scenario_figure_name(condition: tuple[float, float], number: int | str) -> str:
    """File name of a scenario figure, e.g. ``fig9_20mm_200mms.png`` for ``(200, 20)`` and number 9."""
    v_in, x_f = condition
    return f"fig{number}_{x_f:g}mm_{v_in:g}mms.png"


def source_kind(meta: Mapping[str, Any]) -> str | None:
    """The recording's source (``"hardware"`` or ``"virtual-rig"``) from its metadata.

    Accepts ``meta["source"]`` as a string or as a dict with a ``kind``, ``type`` or ``name`` entry.
    """
    src = meta.get("source")
    if isinstance(src, str):
        return src
    if isinstance(src, Mapping):
        for key in ("kind", "type", "name"):
            if isinstance(src.get(key), str):
                return src[key]
    return None


def _group(recordings: Mapping[str, Sequence[Any]] | Iterable[Any]) -> dict[str, list[Any]]:
    if isinstance(recordings, Mapping):
        return {str(k): list(v) for k, v in recordings.items()}
    groups: dict[str, list[Any]] = {}
    for rec in recordings:
        groups.setdefault(str(rec.meta["scenario"]["system"]), []).append(rec)
    return groups


def _matches(rec: Any, condition: tuple[float, float]) -> bool:
    sc = rec.meta["scenario"]
    return (
        abs(float(sc["v_in_mm_s"]) - condition[0]) < 1e-6 and abs(float(sc["x_f_mm"]) - condition[1]) < 1e-6
    )


def fig_scenario(
    recordings_by_system: Mapping[str, Sequence[Any]] | Iterable[Any],
    condition: tuple[float, float],
    number: int | str | None = None,
    *,
    save: bool = False,
) -> plt.Figure:
    """Tension responses of the three systems for one condition, the motor position underneath (Figs. 9-11).

    Every repetition is drawn (the first with a label, the others fainter); recordings of other conditions
    are ignored. Samples the sensor clipped (:func:`helpers.metrics.clipped_samples`, on the ``adc`` column)
    are marked with black crosses: their tension is only a bound.

    Parameters
    ----------
    recordings_by_system : mapping or iterable
        ``{"unshaped": [...], "zv": [...], "zvd": [...]}`` of recordings (objects with ``.frame`` holding
        ``t_s``, ``tension_n`` and ``cable_mm`` or ``steps``, and ``.meta`` with ``"scenario"``), or a flat
        iterable of recordings grouped by ``meta["scenario"]["system"]``.
    condition : (float, float)
        ``(v_in in mm/s, x_f in mm)``.
    number : int or str, optional
        The paper's figure number (default from :data:`PAPER_FIGURE_NUMBERS`); names the saved file.
    save : bool
        Save as ``figures/fig<number>_<x_f>mm_<v_in>mms.png``.

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
    if number is None:
        number = PAPER_FIGURE_NUMBERS.get(condition, "X")
    groups = {
        s: [r for r in recs if _matches(r, condition)] for s, recs in _group(recordings_by_system).items()
    }
    groups = {s: recs for s, recs in groups.items() if recs}
    if not groups:
        raise ValueError(
            f"no recording matches the condition v_in = {condition[0]:g} mm/s, x_f = {condition[1]:g} mm"
        )
    order = [s for s in paper.SYSTEMS if s in groups] + sorted(s for s in groups if s not in paper.SYSTEMS)

    fig, (ax_t, ax_u) = plt.subplots(
        2, 1, sharex=True, figsize=(7.0, 4.8), gridspec_kw={"height_ratios": [3, 1.3]}
    )
    virtual = False
    clipped_label = "clipped (outside the sensor's range)"
    for system in order:
        colour = SYSTEM_COLOURS.get(system, "C7")
        label = paper.SYSTEM_LABELS.get(system, system) + (" TDF" if system in ("zv", "zvd") else "")
        recs = sorted(groups[system], key=lambda r: int(r.meta["scenario"].get("repetition", 0)))
        for i, rec in enumerate(recs):
            virtual |= source_kind(rec.meta) == "virtual-rig"
            f = rec.frame
            kw = {"color": colour, "lw": 1.0 if i == 0 else 0.7, "alpha": 1.0 if i == 0 else 0.4}
            ax_t.plot(f["t_s"], f["tension_n"], label=label if i == 0 else None, **kw)
            if "adc" in f.columns:
                clip = clipped_samples(f["adc"].to_numpy(), (rec.meta or {}).get("calibration"))
                if clip.any():
                    ax_t.plot(f["t_s"][clip], f["tension_n"][clip], "x", color="k", ms=4, label=clipped_label)
                    clipped_label = None
            if "cable_mm" in f.columns:
                ax_u.plot(f["t_s"], f["cable_mm"], **kw)
            else:
                ax_u.plot(f["t_s"], f["steps"], **kw)
    n_reps = max(len(v) for v in groups.values())
    ax_t.set_ylabel("tension (N)")
    ax_t.legend(loc="upper right", title=f"{n_reps} repetitions each" if n_reps > 1 else None)
    first = groups[order[0]][0].frame
    ax_u.set_ylabel("cable (mm)" if "cable_mm" in first.columns else "motor (steps)")
    ax_u.set_xlabel("time (s)")
    what = f"{condition[1]:g} mm at {condition[0]:g} mm/s"
    title = f"Fig. {number}: {what}" if isinstance(number, int) else f"{what} (no figure in the paper)"
    ax_t.set_title(title + (" (virtual rig)" if virtual else ""))
    fig.tight_layout()
    if save:
        save_figure(fig, scenario_figure_name(condition, number))
    return fig
