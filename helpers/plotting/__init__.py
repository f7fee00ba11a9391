"""The paper's figures, one function each, saved under ``figures/`` with the paper's number.

Submodules group the figures by the stage of the pipeline they show; this module holds the shared
style and the save function.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib as mpl
import matplotlib.pyplot as plt

from helpers.paths import figure_path

STYLE: dict[str, object] = {
    "figure.figsize": (7.0, 3.6),
    "figure.dpi": 100,
    "savefig.dpi": 150,
    "savefig.bbox": "tight",
    "axes.grid": True,
    "grid.alpha": 0.3,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "font.size": 9,
    "legend.fontsize": 8,
    "legend.frameon": False,
    "lines.linewidth": 1.2,
}
"""rcParams shared by every figure of the project."""

SYSTEM_COLOURS: dict[str, str] = {"unshaped": "C3", "zv": "C0", "zvd": "C2"}
"""One colour per system of the paper: the pulse (unshaped), the non-robust TDF and the robust TDF."""


def apply_style() -> None:
    """Apply the project's matplotlib style."""
    mpl.rcParams.update(STYLE)


def save(fig: plt.Figure, name: str) -> Path:
    """Save ``fig`` as ``figures/<name>`` (PNG unless ``name`` says otherwise) and return the path.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        The figure.
    name : str
        File name with extension, e.g. ``"fig12_model_shaping.png"``.

    Returns
    -------
    pathlib.Path
        Where it was written.
    """
    path = figure_path(name)
    fig.savefig(path, metadata={"Software": None} if path.suffix == ".png" else None)
    return path
