"""The project's plot style: one set of rcParams and one colour per system of the paper."""

from __future__ import annotations

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
    import matplotlib as mpl  # noqa: PLC0415 - here, so that importing helpers (the command line) stays light

    mpl.rcParams.update(STYLE)
