"""Figures of the shaper design (notebook 03): impulse sequences, sensitivity curves, shaped commands.

Every function returns the figure and saves it under ``figures/`` (the file names below).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import matplotlib.pyplot as plt
import numpy as np

from helpers.board.programmes import Programme
from helpers.paper import numbers as paper
from helpers.paper.profiles import VelocityProfile
from helpers.paper.shapers import Shaper
from helpers.plotting import SYSTEM_COLOURS, finish

SENSITIVITY_NAME = "shaper_sensitivity.png"
IMPULSES_NAME = "shaper_impulses.png"
COMMANDS_NAME = "shaped_commands_table_i.png"
"""File names under ``figures/`` (the paper has no figure for these; they support its Section II-C)."""


_OTHER_COLOURS = ("C1", "C4", "C5", "C6", "C7", "C8", "C9")
"""Colours for shapers other than the paper's systems (which keep SYSTEM_COLOURS)."""


def _colour(name: str, i: int) -> str:
    key = name.lower()
    return SYSTEM_COLOURS.get(key, _OTHER_COLOURS[i % len(_OTHER_COLOURS)])


def impulse_sequences(shapers: Sequence[Shaper]) -> plt.Figure:
    """Stem plots of impulse sequences, one axes per shaper, times in ms.

    Parameters
    ----------
    shapers : sequence of Shaper
        E.g. the paper's two TDFs.

    Returns
    -------
    matplotlib.figure.Figure
    """
    n = len(shapers)
    fig, axes = plt.subplots(1, n, figsize=(3.4 * n, 2.8), sharey=True, squeeze=False)
    t_max = max(s.duration for s in shapers) * 1e3
    for i, (ax, s) in enumerate(zip(axes[0], shapers, strict=True)):
        markers, stems, base = ax.stem(s.times * 1e3, s.amplitudes, basefmt="k-")
        colour = _colour(s.name, i)
        markers.set_color(colour)
        stems.set_color(colour)
        for t, a in zip(s.times, s.amplitudes, strict=True):
            ax.annotate(f"{a:.4f}", (t * 1e3, a), textcoords="offset points", xytext=(4, 4), fontsize=7)
        ax.set_xlim(-0.08 * t_max, 1.15 * t_max)
        ax.set_xlabel("time (ms)")
        label = paper.SYSTEM_LABELS.get(s.name)
        ax.set_title(f"{label} TDF ({s.name.upper()})" if label else s.name)
    axes[0, 0].set_ylabel("impulse amplitude")
    axes[0, 0].set_ylim(min(0.0, min(s.amplitudes.min() for s in shapers)) - 0.05, 0.75)
    return finish(fig, IMPULSES_NAME)


def sensitivity_curves(
    shapers: Sequence[Shaper],
    omega_model: float,
    zeta: float,
    vtol: float = 0.05,
    name: str = SENSITIVITY_NAME,
) -> plt.Figure:
    """Residual vibration against ``omega / omega_model`` for several shapers, with the ``vtol`` line.

    Parameters
    ----------
    shapers : sequence of Shaper
        Designed for ``omega_model``.
    omega_model : float
        Design undamped frequency (rad/s).
    zeta : float
        Damping ratio of the mode the curves are evaluated at.
    vtol : float
        Tolerance line (5 %).
    name : str
        File name under ``figures/`` (notebook 03's paper TDFs keep the default; another notebook's set of
        shapers gets its own name, so that neither overwrites the other).

    Returns
    -------
    matplotlib.figure.Figure
    """
    r = np.linspace(0.2, 1.8, 1601)
    fig, ax = plt.subplots(figsize=(7.0, 3.8))
    others = 0
    for s in shapers:
        v = s.sensitivity(omega_model, zeta, r)
        paper_system = s.name.lower() in SYSTEM_COLOURS
        colour = _colour(s.name, others)
        others += 0 if paper_system else 1
        ax.plot(r, 100 * v, label=s.name, color=colour, lw=1.8 if paper_system else 1.0)
    ax.axhline(100 * vtol, color="k", ls="--", lw=0.8, label=f"{100 * vtol:.0f} %")
    ax.axvline(1.0, color="0.5", lw=0.6)
    ax.set_ylim(0, 100)
    ax.set_xlim(r[0], r[-1])
    ax.set_xlabel("omega / omega_model")
    ax.set_ylabel("residual vibration V (%)")
    ax.set_title(f"Sensitivity of the shapers (zeta = {zeta:.3f})")
    ax.legend(ncol=3, loc="upper center")
    return finish(fig, name)


def shaped_commands(
    commands: Mapping[tuple[float, float], Mapping[str, VelocityProfile]],
    programmes: Mapping[tuple[float, float], Mapping[str, Programme]],
    mm_per_step: float,
) -> plt.Figure:
    """The up move of each condition: shaped velocity (left) and cable displacement with steps (right).

    Parameters
    ----------
    commands : mapping
        ``(v_in_mm_s, x_f_mm) -> {system: VelocityProfile}``.
    programmes : mapping
        Same keys -> ``{system: Programme}``; their step positions are drawn as staircases.
    mm_per_step : float
        The rig's cable per step (``helpers.rigfile.derived(rig).mm_per_step[0]``).

    Returns
    -------
    matplotlib.figure.Figure
    """
    keys = list(commands)
    fig, axes = plt.subplots(len(keys), 2, figsize=(8.0, 1.9 * len(keys)), sharex=True, squeeze=False)
    t = np.linspace(0.95, 1.55, 3001)
    for row, key in enumerate(keys):
        ax_v, ax_x = axes[row]
        for i, (system, prof) in enumerate(commands[key].items()):
            colour = _colour(system, i)
            ax_v.plot(t, prof.sample(t), color=colour, label=system, drawstyle="steps-post")
            ax_x.plot(t, prof.displacement(t), color=colour, lw=0.9, label=f"{system} (exact)")
            if system in programmes.get(key, {}):
                pos = programmes[key][system].position_steps(t) * mm_per_step
                ax_x.plot(t, pos, color=colour, lw=0.6, ls=":", drawstyle="steps-post")
        ax_v.set_ylabel("v (mm/s)")
        ax_x.set_ylabel("u (mm)")
        ax_v.set_title(f"{key[1]:.0f} mm at {key[0]:.0f} mm/s", fontsize=8, loc="left")
    axes[0, 0].legend(loc="upper right")
    axes[0, 1].plot([], [], color="k", ls=":", lw=0.6, label="stepper programme")
    axes[0, 1].legend(loc="lower right")
    axes[-1, 0].set_xlabel("time (s)")
    axes[-1, 1].set_xlabel("time (s)")
    return finish(fig, COMMANDS_NAME)
