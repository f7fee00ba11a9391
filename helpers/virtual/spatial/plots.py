"""Figures of the spatial twin (for a notebook): its modes over bend direction and magnitude, its shapes.

Every function takes what :func:`helpers.virtual.spatial.direction_map.frequency_map` returns (or node
positions) and returns a figure; nothing here simulates. Titles say "spatial twin": the numbers are simulated.
"""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

__all__ = ["mode_splitting", "direction_map_polar", "shapes_3d"]


def _mode_columns(df: pd.DataFrame) -> list[int]:
    cols = [c for c in df.columns if c.startswith("omega_d") and c.endswith("_rad_s")]
    mid = [c[len("omega_d") : -len("_rad_s")] for c in cols]
    ks = sorted(int(m) for m in mid if m.isdigit())
    if not ks:
        raise ValueError("the frame has no omega_d<k>_rad_s columns (helpers.virtual.spatial.frequency_map)")
    return ks


def mode_splitting(df: pd.DataFrame, direction_deg: float, title: str = "") -> plt.Figure:
    """The lowest modes against bend magnitude in one direction (the pairs split as the arm bends).

    Parameters
    ----------
    df : pandas.DataFrame
        A frequency map (columns ``direction_deg``, ``bend_mm``, ``omega_d<k>_rad_s``, ``torsion<k>``).
    direction_deg : float
        The direction to show (a value of ``df.direction_deg``).
    title : str
        Extra title text (the rig's name).
    """
    sel = df[np.isclose(df.direction_deg, direction_deg)].sort_values("bend_mm")
    if sel.empty:
        raise ValueError(f"the map has no direction {direction_deg:g} deg")
    fig, ax = plt.subplots(figsize=(5.5, 3.4))
    for k in _mode_columns(df):
        tors = sel[f"torsion{k}"].to_numpy() if f"torsion{k}" in sel else np.zeros(len(sel))
        ax.plot(sel.bend_mm, sel[f"omega_d{k}_rad_s"], "o-", ms=3, label=f"mode {k}")
        for x, y, s in zip(sel.bend_mm, sel[f"omega_d{k}_rad_s"], tors, strict=True):
            if s > 0.3:  # mostly twisting
                ax.plot(x, y, "s", mfc="none", mec="k", ms=6)
    if "dominant_omega_d_rad_s" in sel:
        ax.plot(sel.bend_mm, sel.dominant_omega_d_rad_s, "k--", lw=1, label="dominant in the leading tendon")
    ax.set_xlabel("bend (mm of cable)")
    ax.set_ylabel("omega_d (rad/s), spools held")
    ax.set_title(
        f"spatial twin (simulated) {title}: towards {direction_deg:g} deg; squares: twist > 30 %", fontsize=8
    )
    ax.legend(fontsize=7)
    fig.tight_layout()
    return fig


def direction_map_polar(df: pd.DataFrame, mode: int = 1, title: str = "") -> plt.Figure:
    """Mode ``mode``'s frequency around the backbone (angle: bend direction; one curve per magnitude)."""
    col = f"omega_d{mode}_rad_s"
    if col not in df:
        raise ValueError(f"the map has no column {col}")
    fig = plt.figure(figsize=(4.6, 4.6))
    ax = fig.add_subplot(projection="polar")
    for b, g in df.groupby("bend_mm"):
        g = g.sort_values("direction_deg")
        th = np.radians(np.append(g.direction_deg.to_numpy(), g.direction_deg.iloc[0] + 360.0))
        r = np.append(g[col].to_numpy(), g[col].iloc[0])
        ax.plot(th, r, "o-", ms=2, label=f"{b:g} mm")
    ax.set_title(f"spatial twin (simulated) {title}: mode {mode} (rad/s) against bend direction", fontsize=8)
    ax.legend(fontsize=7, loc="lower left", bbox_to_anchor=(1.0, 0.0))
    fig.tight_layout()
    return fig


def shapes_3d(
    positions: Sequence[np.ndarray], labels: Sequence[str] | None = None, title: str = ""
) -> plt.Figure:
    """Backbone node positions (each (N+1, 3), clamp frame, m) in 3D, mm."""
    fig = plt.figure(figsize=(5.0, 4.6))
    ax = fig.add_subplot(projection="3d")
    for i, p in enumerate(positions):
        p = np.asarray(p) * 1e3
        ax.plot(p[:, 0], p[:, 1], p[:, 2], "o-", ms=2, label=None if labels is None else labels[i])
    ax.set_xlabel("x: tendon 1 (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z: clamp axis (mm)")
    ax.set_title(f"spatial twin (simulated) {title}", fontsize=9)
    if labels is not None:
        ax.legend(fontsize=7)
    fig.tight_layout()
    return fig
