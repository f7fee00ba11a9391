"""Figures of the linear modal model: mode shapes, pole-zero map and the paper's Fig. 12.

Every function returns the figure; :func:`fig12` also saves it as ``figures/fig12_model_shaping.png``.
"""

from __future__ import annotations

from dataclasses import dataclass

import matplotlib.pyplot as plt
import numpy as np

from helpers.paper import model
from helpers.paper import numbers as paper
from helpers.paper.profiles import pulse_profile
from helpers.paper.shapers import design_tdfs
from helpers.plotting import SYSTEM_COLOURS, finish, save

FIG12_NAME = "fig12_model_shaping.png"
"""File name of the paper's Fig. 12 under ``figures/``."""


def mode_shapes(n_modes: int = 4) -> plt.Figure:
    """Plot the tip-normalised mode shapes ``phi_n(x/L)`` of modes 1..n_modes.

    Parameters
    ----------
    n_modes : int
        Number of modes.

    Returns
    -------
    matplotlib.figure.Figure
        One axes, shape against x/L.
    """
    beta = model.cantilever_roots(n_modes)
    x = np.linspace(0.0, 1.0, 401)
    fig, ax = plt.subplots(figsize=(6.0, 3.2))
    for n in range(1, n_modes + 1):
        ax.plot(x, model.mode_shape(x, n), label=f"mode {n} (beta = {beta[n - 1]:.4f})")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("x / L")
    ax.set_ylabel("phi_n (tip-normalised)")
    ax.set_title("Cantilever mode shapes, phi_n(L) = +1")
    ax.legend(loc="lower left")
    return fig


def pole_zero_map(params: model.ArmParameters, zoom: float = 60.0) -> plt.Figure:
    """Pole-zero map of the tension transfer function ``Lambda/(sU)``, full and zoomed on the dominant pair.

    Poles are crosses, zeros circles (the zeros are the uncoupled modal poles ``D_n = 0``); the dashed
    lines mark the first two modal frequencies ``Im s = +-omega_1, +-omega_2`` (the modes are lightly
    damped, so ``|s|`` and ``Im s`` nearly agree), and the dominant pair is ringed.

    Parameters
    ----------
    params : helpers.paper.model.ArmParameters
        The model (finite ``k``).
    zoom : float
        The right panel shows ``-zoom <= Re s <= 0.15 zoom`` (1/s) and ``|Im s| <= 1.1 omega_2``.

    Returns
    -------
    matplotlib.figure.Figure
        Two panels.
    """
    tension, _ = model.transfer_functions(params)
    p = model.poles(params)
    z = np.asarray(tension.zeros(), dtype=complex)
    w = model.modal_frequencies(params)
    dom = model.dominant_mode(params)
    fig, axes = plt.subplots(1, 2, figsize=(7.2, 3.6))
    for ax in axes:
        ax.plot(p.real, p.imag, "x", color="C3", ms=7, mew=1.5, label="poles")
        ax.plot(z.real, z.imag, "o", mfc="none", color="C0", ms=7, label="zeros (uncoupled modes)")
        for i, (wi, style) in enumerate(zip(w[:2], ("--", ":"), strict=True)):
            ax.axhline(wi, ls=style, color="0.4", lw=0.8, label=rf"$\pm\omega_{i + 1}$ = {wi:.2f} rad/s")
            ax.axhline(-wi, ls=style, color="0.4", lw=0.8)
        ax.plot(dom.pole.real, dom.pole.imag, "o", ms=14, mfc="none", color="C2", mew=1.2, label="dominant")
        ax.plot(dom.pole.real, -dom.pole.imag, "o", ms=14, mfc="none", color="C2", mew=1.2)
        ax.axhline(0.0, color="k", lw=0.6)
        ax.axvline(0.0, color="k", lw=0.6)
        ax.set_xlabel("Re s (1/s)")
    axes[0].set_ylabel("Im s (rad/s)")
    axes[0].set_title(r"$\Lambda/(sU)$: all poles and zeros")
    axes[1].set_xlim(-zoom, 0.15 * zoom)
    axes[1].set_ylim(-1.1 * w[1], 1.1 * w[1])
    axes[1].set_title(rf"zoom: dominant pair, $\omega_d$ = {dom.omega_d:.3f} rad/s")
    axes[1].legend(loc="lower left", fontsize=7)
    return finish(fig, None)


@dataclass(frozen=True)
class ShapingResponse:
    """Model responses to one pulse, unshaped and shaped (the data behind Fig. 12).

    Attributes
    ----------
    t : numpy.ndarray
        Time, s.
    commands : dict of str to numpy.ndarray
        Cable velocity command per system (``"unshaped"``, ``"zv"``, ``"zvd"``), mm/s.
    tension : dict of str to numpy.ndarray
        Model tension per system, N.
    v_in_mm_s, x_f_mm : float
        The pulse.
    """

    v_in_mm_s: float
    x_f_mm: float
    t: np.ndarray
    commands: dict[str, np.ndarray]
    tension: dict[str, np.ndarray]


def shaping_response(
    params: model.ArmParameters,
    v_in_mm_s: float,
    x_f_mm: float,
    t_end: float = 12.0,
    rate_hz: int = 2000,
) -> ShapingResponse:
    """Simulate the model's response to the paper's velocity pulse, unshaped and with both TDFs.

    The pulse is :func:`helpers.paper.profiles.pulse_profile` (up at 1 s, down at 8 s); the shaped commands
    are
    the pulse convolved with the impulses of :func:`helpers.paper.shapers.design_tdfs` (designed from the
    paper's
    identified zeta = 0.044, omega_d = 25.085 rad/s), via ``Shaper.apply``.

    Parameters
    ----------
    params : helpers.paper.model.ArmParameters
        The model.
    v_in_mm_s, x_f_mm : float
        Pulse velocity (mm/s) and cable displacement (mm). The paper does not state Fig. 12's; notebook 01
        uses 200 mm/s and 20 mm, the middle row of Table I and the case of the paper's Fig. 9, so the model
        figure sits beside a measured one.
    t_end : float
        Simulated span, s.
    rate_hz : int
        Samples per second of the uniform grid ``t = i / rate_hz`` (written so that the pulse's
        breakpoints at whole milliseconds fall exactly on grid points).

    Returns
    -------
    ShapingResponse
        Commands and tensions on one grid.
    """
    if not (int(rate_hz) == rate_hz and rate_hz > 0 and t_end > 8.0 + x_f_mm / v_in_mm_s):
        raise ValueError(
            f"need an integer rate_hz > 0 and t_end after the down move, got {rate_hz!r}, t_end={t_end}"
        )
    t = np.arange(round(t_end * rate_hz) + 1) / rate_hz
    pulse = pulse_profile(v_in_mm_s, x_f_mm).sample(t)
    zv, zvd = design_tdfs()
    commands = {"unshaped": pulse, "zv": zv.apply(t, pulse), "zvd": zvd.apply(t, pulse)}
    tension = {name: model.linear_response(params, t, v * 1e-3)[0] for name, v in commands.items()}
    return ShapingResponse(
        v_in_mm_s=float(v_in_mm_s), x_f_mm=float(x_f_mm), t=t, commands=commands, tension=tension
    )


def fig12(response: ShapingResponse) -> plt.Figure:
    """The paper's Fig. 12: model tension response to the velocity pulse, without and with input shaping.

    Top: the three cable-velocity commands; middle: the model tension over the whole run; bottom: the
    up and down transients enlarged. Saved as ``figures/fig12_model_shaping.png``.

    Parameters
    ----------
    response : ShapingResponse
        The model's responses (:func:`shaping_response`).

    Returns
    -------
    matplotlib.figure.Figure
        The figure (also written to ``figures/``).
    """
    labels = {"unshaped": "Pulse (unshaped)", "zv": "Non-robust TDF (ZV)", "zvd": "Robust TDF (ZVD)"}
    t = response.t
    fig = plt.figure(figsize=(7.2, 6.4))
    grid = fig.add_gridspec(3, 2, height_ratios=[0.8, 1.2, 1.2])
    ax_cmd = fig.add_subplot(grid[0, :])
    ax_all = fig.add_subplot(grid[1, :], sharex=ax_cmd)
    ax_up = fig.add_subplot(grid[2, 0])
    ax_down = fig.add_subplot(grid[2, 1], sharey=ax_up)
    for name in paper.SYSTEMS:
        colour = SYSTEM_COLOURS[name]
        ax_cmd.plot(t, response.commands[name], color=colour, label=labels[name])
        for ax in (ax_all, ax_up, ax_down):
            ax.plot(t, response.tension[name], color=colour, label=labels[name])
    ax_cmd.set_ylabel("cable v (mm/s)")
    ax_cmd.legend(loc="upper right", ncols=3)
    ax_cmd.tick_params(labelbottom=False)
    ax_all.set_ylabel("tension (N)")
    ax_all.set_xlabel("time (s)")
    ax_all.set_xlim(t[0], t[-1])
    for ax, t_move, title in ((ax_up, paper.PULSE_T_UP_S, "Up"), (ax_down, paper.PULSE_T_DOWN_S, "Down")):
        ax.set_xlim(t_move - 0.1, t_move + 2.4)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("time (s)")
    ax_up.set_ylabel("tension (N)")
    ax_down.tick_params(labelleft=False)
    lowest = min(float(np.min(response.tension[name])) for name in paper.SYSTEMS)
    if lowest < 0.0:  # the linear model has no slack: say where it stops being physical
        for ax in (ax_all, ax_up, ax_down):
            ax.axhspan(lowest * 1.1, 0.0, color="0.85", zorder=0)
        ax_all.text(
            0.99, 0.04, f"below 0 N (to {lowest:.1f} N): the linear model pushes; a real cable goes slack",
            transform=ax_all.transAxes, ha="right", va="bottom", fontsize=7.5, color="0.25",
        )  # fmt: skip
    fig.suptitle(
        f"Fig. 12 (model, eqs. 11-12): velocity pulse {response.v_in_mm_s:.0f} mm/s, "
        f"{response.x_f_mm:.0f} mm, without and with input shaping",
        fontsize=10,
    )
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 0.98))
    save(fig, FIG12_NAME)
    return fig
