"""The linear-model playground of notebook 03: the paper's shapers designed for the wrong mode.

A shaper is designed from an identified mode (frequency and damping). Here the design is moved away from the
arm's: the design's damped frequency is ``design_ratio`` times the identified one and its damping ratio is the
identified one plus ``zeta_error``. For the paper's non-robust (ZV) and robust (ZVD) TDFs, one shaped Up move
(200 mm/s, 20 mm by default) is run on the **linear model** (:func:`helpers.paper.model.linear_response` of
the model fitted to the identified mode), and the residual vibration after the move
(:func:`helpers.paper.metrics.residual_vibration`: half the peak-to-peak tension from 0.1 s to 1.1 s after
the move, in % of the step) is shown for each. The step ``yf - y0`` is taken as the mean over that window
minus the tension before the move.

The model is linear and time-invariant, so a shaped move's response is the unshaped move's response, delayed
by each impulse's time and scaled by its amplitude (:meth:`LinearPlayground.shaped`: one response,
computed once, finely).
:meth:`LinearPlayground.update` recomputes and redraws one figure; notebook 03 ties it to two sliders in
JupyterLab and shows a static figure of the same function under nbval and ``reproduce``. The same study on
the virtual rig, with an EI shaper beside, is :mod:`helpers.research.playground` (notebook 06).
"""

from __future__ import annotations

from dataclasses import dataclass

import matplotlib.pyplot as plt
import numpy as np

from helpers.base.style import SYSTEM_COLOURS
from helpers.paper import metrics, model, shapers
from helpers.paper.modes import omega_n_from_damped
from helpers.paper.profiles import single_pulse

SHAPERS = ("zv", "zvd")
"""The paper's shapers, by name."""
LABELS = {"unshaped": "unshaped", "zv": "ZV (non-robust TDF)", "zvd": "ZVD (robust TDF)"}
T_UP_S = 0.2
"""Start of the move, s (after a short rest)."""
T_END_S = 1.8
"""Length of each run, s: the longest shaped move plus the 1.1 s residual window fits."""
DT_S = 1e-3
"""Sample interval, s (the DAQ's 1 kHz)."""
FINE_DT_S = 1e-4
"""Grid of the linear model's one unshaped response, s (shifted copies are interpolated from it)."""
RATIO_RANGE = (0.6, 1.6)
"""Slider range of the design frequency over the identified one."""
ZETA_ERROR_RANGE = (-0.04, 0.10)
"""Slider range of the design damping ratio minus the identified one."""


def residual_after(t: np.ndarray, y: np.ndarray, move_end: float) -> float:
    """Residual vibration (% of the step) after a move that ends at ``move_end`` and starts at ``T_UP_S``."""
    y0 = float(np.mean(y[t < T_UP_S]))
    lo = move_end + metrics.RESIDUAL_START_S
    window = (t >= lo) & (t <= lo + metrics.RESIDUAL_LENGTH_S)
    return metrics.residual_vibration(t, y, move_end, y0, float(np.mean(y[window])))


def check_design(design_ratio: float, zeta_design: float) -> None:
    """Refuse a design outside the sliders' ranges (ValueError naming the slider)."""
    if not (RATIO_RANGE[0] <= design_ratio <= RATIO_RANGE[1]):
        raise ValueError(f"design_ratio {design_ratio} is outside {RATIO_RANGE}")
    if not (0.0 <= zeta_design < 0.3):
        raise ValueError(f"design damping {zeta_design:.3f} is outside [0, 0.3) (EI's fit)")


@dataclass
class LinearStudy:
    """One setting of the sliders and what it leaves on the linear model.

    Attributes
    ----------
    design_ratio, zeta_error : float
        The sliders.
    omega_d_design, zeta_design : float
        The mode the shapers were designed for (damped rad/s, damping ratio).
    t : numpy.ndarray
        Sample times, s.
    linear : dict of str to numpy.ndarray
        Tension (N) per system (``unshaped`` and :data:`SHAPERS`).
    residual_linear : dict of str to float
        Residual vibration, % of the step, per system.
    """

    design_ratio: float
    zeta_error: float
    omega_d_design: float
    zeta_design: float
    t: np.ndarray
    linear: dict[str, np.ndarray]
    residual_linear: dict[str, float]


class LinearPlayground:
    """Residual vibration of the paper's shapers, mis-designed, on the linear model.

    Parameters
    ----------
    omega_d, zeta : float
        The identified mode (damped rad/s, damping ratio): the shapers' design at ``design_ratio = 1`` and
        ``zeta_error = 0``.
    v_in_mm_s, x_f_mm : float
        The move.
    model_params : helpers.paper.model.ArmParameters, optional
        The linear model (default: :data:`helpers.paper.model.FITTED`).
    """

    def __init__(
        self,
        omega_d: float,
        zeta: float,
        v_in_mm_s: float = 200.0,
        x_f_mm: float = 20.0,
        model_params: model.ArmParameters | None = None,
    ) -> None:
        self.omega_d, self.zeta = float(omega_d), float(zeta)
        self.v_in_mm_s, self.x_f_mm = float(v_in_mm_s), float(x_f_mm)
        params = model.FITTED if model_params is None else model_params
        # the model is linear and time-invariant: one fine unshaped response, shifted and scaled per impulse
        self.t = np.arange(0.0, T_END_S, DT_S)
        self._fine_t = np.arange(0.0, T_END_S + 0.5, FINE_DT_S)
        move = single_pulse(self.v_in_mm_s, self.x_f_mm, T_UP_S)
        self._fine, _ = model.linear_response(params, self._fine_t, move.sample(self._fine_t) * 1e-3)
        self.fig: plt.Figure | None = None

    def shaped(self, shaper: shapers.Shaper | None) -> tuple[np.ndarray, float]:
        """(tension on :attr:`t`, end of the move in s) of the move shaped by ``shaper`` (None: unshaped)."""
        profile = single_pulse(self.v_in_mm_s, self.x_f_mm, T_UP_S).shaped(shaper)
        impulses = [(1.0, 0.0)] if shaper is None else zip(shaper.amplitudes, shaper.times, strict=True)
        y = sum(a * np.interp(self.t - d, self._fine_t, self._fine, left=0.0) for a, d in impulses)
        return y, float(profile.end)

    def design(self, design_ratio: float, zeta_error: float) -> dict[str, shapers.Shaper]:
        """ZV and ZVD designed for the displaced mode."""
        zeta_design = self.zeta + zeta_error
        check_design(design_ratio, zeta_design)
        omega_n = omega_n_from_damped(design_ratio * self.omega_d, zeta_design)
        return {"zv": shapers.zv(omega_n, zeta_design), "zvd": shapers.zvd(omega_n, zeta_design)}

    def study(self, design_ratio: float = 1.0, zeta_error: float = 0.0) -> LinearStudy:
        """Run the unshaped move and every shaper designed for the displaced mode on the model."""
        runs = {"unshaped": self.shaped(None)}
        runs |= {name: self.shaped(s) for name, s in self.design(design_ratio, zeta_error).items()}
        t = self.t
        return LinearStudy(
            design_ratio=float(design_ratio),
            zeta_error=float(zeta_error),
            omega_d_design=design_ratio * self.omega_d,
            zeta_design=self.zeta + zeta_error,
            t=t,
            linear={k: r[0] for k, r in runs.items()},
            residual_linear={k: residual_after(t, r[0], r[1]) for k, r in runs.items()},
        )

    def figure(self, study: LinearStudy) -> plt.Figure:
        """Draw ``study`` into a new figure (kept as ``self.fig`` for :meth:`update`)."""
        fig, (ax_lin, ax_bar) = plt.subplots(1, 2, figsize=(9.0, 3.6), width_ratios=[1.4, 1.0])
        self._lines: dict[str, plt.Line2D] = {}
        for name in ("unshaped", *SHAPERS):
            grey = name == "unshaped"
            style = {"color": "0.6" if grey else SYSTEM_COLOURS[name], "lw": 0.8 if grey else 1.2}
            (self._lines[name],) = ax_lin.plot(study.t, study.linear[name], label=LABELS[name], **style)
        ax_lin.set_xlabel("time (s)")
        ax_lin.set_xlim(0.0, T_END_S)
        ax_lin.set_ylabel("tension (N)")
        ax_lin.set_title("linear model (zero at rest)", fontsize=9)
        ax_lin.legend(loc="lower right", fontsize=7)
        x = np.arange(len(SHAPERS))
        colours = [SYSTEM_COLOURS[s] for s in SHAPERS]
        self._bars = ax_bar.bar(x, [study.residual_linear[s] for s in SHAPERS], 0.5, color=colours)
        ax_bar.set_xticks(x, [s.upper() for s in SHAPERS])
        ax_bar.set_ylabel("residual vibration (% of the step)")
        self.fig = fig
        self._redraw_text(study)
        fig.tight_layout()
        return fig

    def title(self, study: LinearStudy) -> str:
        """The figure's title: the mode the shapers were designed for, and the move."""
        return (
            f"Shapers designed for omega_d = {study.omega_d_design:.1f} rad/s ({study.design_ratio:.2f} x "
            f"identified), zeta = {study.zeta_design:.3f} ({study.zeta_error:+.3f}); "
            f"{self.x_f_mm:g} mm at {self.v_in_mm_s:g} mm/s"
        )

    def _redraw_text(self, study: LinearStudy) -> None:
        assert self.fig is not None
        self.fig.suptitle(self.title(study), fontsize=9)
        ax_bar = self.fig.axes[1]
        ax_bar.set_title(f"unshaped: {study.residual_linear['unshaped']:.0f} %", fontsize=9)
        ax_bar.set_ylim(0.0, 1.25 * max(*(study.residual_linear[s] for s in SHAPERS), 5.0))

    def update(self, design_ratio: float = 1.0, zeta_error: float = 0.0) -> LinearStudy:
        """Recompute for new slider values and redraw the figure (made on the first call)."""
        study = self.study(design_ratio, zeta_error)
        if self.fig is None:
            self.figure(study)
            return study
        for name, line in self._lines.items():
            line.set_ydata(study.linear[name])
        for bar, name in zip(self._bars, SHAPERS, strict=True):
            bar.set_height(study.residual_linear[name])
        self.fig.axes[0].relim()
        self.fig.axes[0].autoscale_view(scalex=False)
        self._redraw_text(study)
        self.fig.canvas.draw()
        return study
