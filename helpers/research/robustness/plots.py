"""Figures of the robustness atlas (notebook 09): residual maps per shaper, percentile against duration."""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import xarray as xr
from matplotlib.colors import LogNorm

__all__ = ["residual_maps", "percentile_against_duration"]


def residual_maps(
    worst: xr.DataArray,
    x: str,
    y: str,
    shapers: Sequence[str],
    title: str,
    labels: dict[str, str] | None = None,
    x_values: np.ndarray | None = None,
    y_values: np.ndarray | None = None,
    x_label: str | None = None,
    y_label: str | None = None,
) -> plt.Figure:
    """One small map per shaper of a residual over two sweep dimensions, on one logarithmic colour scale.

    Parameters
    ----------
    worst : xarray.DataArray
        The residual (%), with dimensions ``x``, ``y`` and ``shaper``.
    x, y : str
        The dimensions on the axes.
    shapers : sequence of str
        Which shapers, in order.
    title : str
        The figure's title.
    labels : dict, optional
        Shaper -> panel title.
    x_values, y_values : numpy.ndarray, optional
        Tick values to show instead of the coordinates (e.g. a damping ratio for a damping scale).
    x_label, y_label : str, optional
        Axis labels (default the dimension names).

    Returns
    -------
    matplotlib.figure.Figure
    """
    n = len(shapers)
    cols = min(n, 4)
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(2.1 * cols + 0.8, 1.9 * rows + 0.6), squeeze=False,
                             sharex=True, sharey=True)  # fmt: skip
    values = worst.sel(shaper=list(shapers))
    finite = values.values[np.isfinite(values.values)]
    norm = LogNorm(vmin=max(float(finite.min()), 0.5), vmax=float(finite.max()))
    xs = worst[x].values if x_values is None else np.asarray(x_values)
    ys = worst[y].values if y_values is None else np.asarray(y_values)
    mesh = None
    for k, ax in enumerate(axes.ravel()):
        if k >= n:
            ax.set_visible(False)
            continue
        z = values.sel(shaper=shapers[k]).transpose(y, x).values
        mesh = ax.imshow(z, norm=norm, cmap="viridis", origin="lower", aspect="auto", interpolation="nearest")
        ax.set_title((labels or {}).get(shapers[k], shapers[k]), fontsize=8)
        step = max(1, -(-xs.size // 4))
        ax.set_xticks(np.arange(xs.size)[::step])
        ax.set_xticklabels([f"{v:g}" for v in xs[::step]], fontsize=7)
        ax.set_yticks(np.arange(ys.size))
        ax.set_yticklabels([f"{v:g}" for v in ys], fontsize=7)
        ax.grid(False)
    for ax in axes[-1]:
        ax.set_xlabel(x_label or x)
    for ax in axes[:, 0]:
        ax.set_ylabel(y_label or y)
    fig.colorbar(mesh, ax=axes, label="residual, % of the step (worse move)", shrink=0.9)
    fig.suptitle(title)
    return fig


def percentile_against_duration(table: pd.DataFrame, q: float, title: str) -> plt.Figure:
    """Each shaper's percentile residual (with its bootstrap interval) against its mean move duration.

    Parameters
    ----------
    table : pandas.DataFrame
        :func:`helpers.research.sweep.atlas.percentile_table` (without the unshaped row, whose scale is
        another).
    q : float
        The percentile of the table.
    title : str
        The figure's title.

    Returns
    -------
    matplotlib.figure.Figure
    """
    col = f"p{q:g}_pct"
    fig, ax = plt.subplots(figsize=(7.0, 4.0))
    for name, row in table.iterrows():
        robust = str(name).startswith("robust")
        tuned = str(name).endswith("-tuned")
        marker, colour = ("*", "C3") if robust else (("s", "C1") if tuned else ("o", "C0"))
        err = [[row[col] - row["low_pct"]], [row["high_pct"] - row[col]]]
        ax.errorbar(row["move_ms"], row[col], yerr=err, fmt=marker, color=colour, ms=9 if robust else 6,
                    capsize=2, lw=0.8)  # fmt: skip
        ax.annotate(
            str(name), (row["move_ms"], row[col]), textcoords="offset points", xytext=(5, 3), fontsize=7
        )
    ax.set_xlabel("move duration, ms (shaper + t_p, mean over the sample)")
    ax.set_ylabel(f"{q:g}th percentile residual, % of the step")
    ax.set_title(title)
    return fig
