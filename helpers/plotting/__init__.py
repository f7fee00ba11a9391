"""The paper's figures, one function each, saved under ``figures/`` with the paper's number.

Submodules group the figures by the stage of the pipeline they show; this module holds the save function
(the style is :mod:`helpers.base.style`).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt

from helpers.base.paths import figure_path
from helpers.base.style import STYLE, SYSTEM_COLOURS, apply_style

__all__ = ["STYLE", "SYSTEM_COLOURS", "apply_style", "save", "finish"]


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


def finish(fig: plt.Figure, name: str | None) -> plt.Figure:
    """The figure laid out (``tight_layout``) and, unless ``name`` is None, saved as ``figures/<name>``."""
    fig.tight_layout()
    if name:
        save(fig, name)
    return fig
