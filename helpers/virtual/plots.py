"""Figures of the virtual rig (notebook 06): validation, frequency map, arm shapes, calibration run."""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from helpers.paper.metrics import clipped_samples

__all__ = [
    "statics_oracle",
    "linear_model_agreement",
    "convergence",
    "frequency_map",
    "arm_shapes",
    "identification_run",
    "pulse_comparison",
    "animate_shapes",
]


def statics_oracle(df: pd.DataFrame) -> plt.Figure:
    """Tension against total bend: the rig's statics beside ``EI theta / (L r)``.

    Parameters
    ----------
    df : pandas.DataFrame
        Columns ``theta_rad``, ``tension_n``, ``oracle_n``, ``config`` (one curve per config).
    """
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(7.0, 3.0))
    for i, (name, g) in enumerate(df.groupby("config", sort=False)):
        ax.plot(g["theta_rad"], g["tension_n"], "o", ms=3, color=f"C{i}", label=name)
        ax2.plot(g["theta_rad"], 100 * (g["tension_n"] / g["oracle_n"] - 1), "o-", ms=3, color=f"C{i}")
    th = np.linspace(0, df["theta_rad"].max(), 50)
    slope = (df["oracle_n"] / df["theta_rad"]).iloc[0]
    ax.plot(th, slope * th, "k-", lw=0.8, label="EI theta / (L r)")
    ax.set_xlabel("total bend theta (rad)")
    ax.set_ylabel("cable tension (N)")
    ax.legend()
    ax2.axhspan(-1, 1, color="0.9", label="+-1 %")
    ax2.set_xlabel("total bend theta (rad)")
    ax2.set_ylabel("deviation from oracle (%)")
    ax2.legend()
    fig.suptitle("Virtual rig: constant-curvature statics against the closed form (gravity off)", fontsize=10)
    fig.tight_layout()
    return fig


def linear_model_agreement(df: pd.DataFrame) -> plt.Figure:
    """Natural frequencies of the rig (uniform-mass configuration) against the linear modal model.

    Parameters
    ----------
    df : pandas.DataFrame
        Columns ``mode``, ``rig_rad_s``, ``model_rad_s``.
    """
    fig, ax = plt.subplots(figsize=(5.0, 3.0))
    ax.semilogy(df["mode"], df["model_rad_s"], "ks", mfc="none", label="helpers.paper.model (linear modal)")
    ax.semilogy(df["mode"], df["rig_rad_s"], "C0o", ms=4, label="virtual rig, linearised")
    for _, row in df.iterrows():
        ax.annotate(f"{100 * (row.rig_rad_s / row.model_rad_s - 1):+.2f} %", (row["mode"], row.rig_rad_s),
                    textcoords="offset points", xytext=(6, -3), fontsize=7)  # fmt: skip
    ax.set_xlabel("mode")
    ax.set_ylabel("natural frequency (rad/s)")
    ax.set_xticks(df["mode"])
    ax.legend()
    ax.set_title("Virtual rig (linearised) against the linear modal model", fontsize=10)
    fig.tight_layout()
    return fig


def convergence(df: pd.DataFrame, tension_tol_pct: float = 1.0, omega_tol_pct: float = 0.5) -> plt.Figure:
    """The rig (one arc per disc interval) against a finer rod: static tension and dominant frequency.

    Parameters
    ----------
    df : pandas.DataFrame
        Columns ``u_mm``, ``tension_pct`` and ``omega_d_pct`` (the rig's deviation from the finer rod, %);
        optionally ``plain_tension_pct`` and ``plain_omega_d_pct``, the same for the plain arc chain (no
        bowing between eyelets), drawn dashed.
    tension_tol_pct, omega_tol_pct : float
        The convergence criteria, drawn as bands.
    """
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(7.0, 2.8))
    ax.axhspan(-tension_tol_pct, tension_tol_pct, color="0.9", label=f"+-{tension_tol_pct:g} %")
    ax.plot(df["u_mm"], df["tension_pct"], "o-", ms=4, label="the rig")
    ax.set_ylabel("static tension vs 4x finer (%)")
    ax2.axhspan(-omega_tol_pct, omega_tol_pct, color="0.9", label=f"+-{omega_tol_pct:g} %")
    ax2.plot(df["u_mm"], df["omega_d_pct"], "o-", ms=4, label="the rig")
    ax2.set_ylabel("omega_d vs 4x finer (%)")
    for a, col in ((ax, "plain_tension_pct"), (ax2, "plain_omega_d_pct")):
        if col in df:
            a.plot(df["u_mm"], df[col], "s--", ms=3, color="0.4", label="no bowing")
    for a in (ax, ax2):
        a.set_xlabel("cable displacement u (mm)")
        a.set_xticks(df["u_mm"])
        a.legend(loc="upper left")
    fig.suptitle("Virtual rig: the rod against one 4x finer (static tension, dominant omega_d)", fontsize=10)
    fig.tight_layout()
    return fig


def frequency_map(fm: pd.DataFrame, omega_design: float, zeta_design: float) -> plt.Figure:
    """omega_d(u) and zeta(u) of the lowest bending mode about the static equilibria, beside the design."""
    fig, axs = plt.subplots(1, 3, figsize=(7.5, 2.8))
    axs[0].plot(fm["u_mm"], fm["omega_d_rad_s"], "o-", ms=2.5, label="spool held")
    if "dominant_omega_d_rad_s" in fm:
        axs[0].plot(fm["u_mm"], fm["dominant_omega_d_rad_s"], "-", lw=1.0, label="rotor free (as it runs)")
    axs[0].axhline(omega_design, color="k", lw=0.8, label="design (identified)")
    axs[0].fill_between(fm["u_mm"], 0.9 * omega_design, 1.1 * omega_design, color="0.9", label="+-10 %")
    axs[0].set_ylabel("omega_d (rad/s)")
    axs[0].legend(fontsize=6)
    axs[1].plot(fm["u_mm"], fm["zeta"], "o-", ms=2.5)
    axs[1].axhline(zeta_design, color="k", lw=0.8)
    axs[1].set_ylabel("zeta")
    axs[2].plot(fm["u_mm"], fm["static_tension_n"], "o-", ms=2.5)
    axs[2].set_ylabel("static tension (N)")
    for ax in axs:
        ax.set_xlabel("cable displacement u (mm)")
    fig.suptitle("Virtual rig: frequency map of the lowest bending mode about the static equilibrium",
                 fontsize=10)  # fmt: skip
    fig.tight_layout()
    return fig


def arm_shapes(
    x: np.ndarray, y: np.ndarray, times: Sequence[float], title: str = "", tension: np.ndarray | None = None
) -> plt.Figure:
    """Backbone shapes at several instants (rows of ``x``, ``y`` in m), one distinct colour each.

    Instants separated by more than 2 s (an up move and a later down move) go into separate panels, and
    every shape is labelled at its tip with its time (and tension), so that no colour has to be matched to a
    legend.
    """
    times = list(times)
    groups: list[list[int]] = [[0]]
    for i in range(1, len(times)):
        if times[i] - times[i - 1] > 2.0:
            groups.append([])
        groups[-1].append(i)
    fig, axes = plt.subplots(1, len(groups), figsize=(4.2 * len(groups), 4.2), sharex=True, sharey=True,
                             squeeze=False)  # fmt: skip
    colours = plt.get_cmap("tab10").colors
    for ax, members in zip(axes[0], groups, strict=True):
        for k, i in enumerate(members):
            colour = colours[k % len(colours)]
            label = f"{times[i]:.2f} s" + ("" if tension is None else f", {tension[i]:.1f} N")
            ax.plot(1e3 * x[i], 1e3 * y[i], "-o", ms=2.5, lw=1.4, color=colour, label=label)
            ax.annotate(f"{times[i]:.2f} s", (1e3 * x[i][-1], 1e3 * y[i][-1]), textcoords="offset points",
                        xytext=(4, 2), fontsize=7, color=colour)  # fmt: skip
        ax.plot([0], [0], "ks", ms=6)
        ax.set_aspect("equal")
        ax.set_xlabel("x (mm)")
        ax.legend(fontsize=7, loc="best")
        span = f"{times[members[0]]:.2f}-{times[members[-1]]:.2f} s"
        ax.set_title(span, fontsize=9)
    axes[0][0].set_ylabel("y (mm), gravity down")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def identification_run(t: np.ndarray, adc: np.ndarray, window: tuple[float, float]) -> plt.Figure:
    """The simulated identification run in ADC counts, with the analysis window shaded (cf. paper Fig. 5).

    Samples outside the sensor's range (:func:`helpers.paper.metrics.clipped_samples`) are marked with
    crosses.
    """
    fig, ax = plt.subplots(figsize=(7.0, 2.8))
    ax.plot(t, adc, lw=0.7)
    clip = clipped_samples(adc)
    if clip.any():
        ax.plot(np.asarray(t)[clip], np.asarray(adc)[clip], "kx", ms=4, label="clipped (outside the range)")
    label = f"identification window {window[0]:.0f}-{window[1]:.0f} s"
    ax.axvspan(*window, color="C1", alpha=0.2, label=label)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("ADC counts")
    ax.legend()
    ax.set_title("Virtual rig (simulated, not measured): 100 mm/s, 10 mm pulse")
    fig.tight_layout()
    return fig


def pulse_comparison(table: pd.DataFrame) -> plt.Figure:
    """Peaks and overshoots of the simulated unshaped pulses beside the paper's Table II."""
    fig, axs = plt.subplots(1, 2, figsize=(7.0, 2.8))
    labels = [f"{r.x_f_mm:.0f}/{r.v_in_mm_s:.0f}\n{r.motion}" for r in table.itertuples()]
    pos = np.arange(len(table))
    for ax, col, unit in ((axs[0], "peak_n", "peak (N)"), (axs[1], "overshoot_pct", "overshoot (%)")):
        ax.bar(pos - 0.2, table[f"paper_{col}"], 0.4, label="paper (hardware)", color="0.6")
        ax.bar(pos + 0.2, table[col], 0.4, label="virtual rig", color="C0")
        ax.set_xticks(pos)
        ax.set_xticklabels(labels, fontsize=6)
        ax.set_ylabel(unit)
    axs[0].legend()
    fig.suptitle("Unshaped pulses: virtual rig (simulated) against the paper's Table II (hardware)",
                 fontsize=10)  # fmt: skip
    fig.tight_layout()
    return fig


def animate_shapes(x: np.ndarray, y: np.ndarray, t: np.ndarray, every: int = 20):  # pragma: no cover
    """A matplotlib animation of the backbone (interactive use only; returns the FuncAnimation)."""
    from matplotlib.animation import FuncAnimation

    fig, ax = plt.subplots(figsize=(4.5, 4.0))
    pad = 0.01
    ax.set_xlim(1e3 * (x.min() - pad), 1e3 * (x.max() + pad))
    ax.set_ylim(1e3 * (y.min() - pad), 1e3 * (y.max() + pad))
    ax.set_aspect("equal")
    (line,) = ax.plot([], [], "-o", ms=3)
    label = ax.text(0.02, 0.95, "", transform=ax.transAxes)

    def update(k: int):
        i = k * every
        line.set_data(1e3 * x[i], 1e3 * y[i])
        label.set_text(f"t = {t[i]:.2f} s")
        return line, label

    return FuncAnimation(fig, update, frames=len(t) // every, interval=20, blit=True)
