"""The shaper study of notebook 06: shapers designed for the wrong mode, on the linear model and the twin.

The design is moved away from the identified mode as in :mod:`helpers.plotting.playground` (the linear-model
playground of notebook 03, whose pieces this module uses): the design's damped frequency is ``design_ratio``
times the identified one and its damping ratio is the identified one plus ``zeta_error``. For the paper's ZV
and ZVD and the extra-insensitive (EI, :mod:`helpers.research.families`) shaper, one shaped Up move (200 mm/s,
20 mm by default) is run on the **linear model** and on the **virtual rig** (:func:`helpers.virtual.simulate`:
the nonlinear arm, a short run from rest; VIRTUAL data), and the residual vibration after the move is shown
for each.

:meth:`ShaperPlayground.update` recomputes everything and redraws one figure; notebook 06 ties it to two
sliders in JupyterLab and shows a static figure of the same function under nbval and ``reproduce``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Patch

from helpers.base.style import SYSTEM_COLOURS
from helpers.board.programmes import experiment_programme
from helpers.paper import model, shapers
from helpers.paper.modes import omega_n_from_damped
from helpers.plotting.playground import (
    DT_S,
    T_END_S,
    T_UP_S,
    LinearPlayground,
    LinearStudy,
    residual_after,
)
from helpers.research import families
from helpers.virtual import ArmPlant, RigParameters, simulate

SHAPERS = ("zv", "zvd", "ei")
"""The shapers compared, by name."""
LABELS = {"unshaped": "unshaped", "zv": "ZV (non-robust TDF)", "zvd": "ZVD (robust TDF)", "ei": "EI (5 %)"}
COLOURS = {**SYSTEM_COLOURS, "ei": "C4"}


@dataclass
class Study(LinearStudy):
    """One setting of the sliders and what it leaves on the linear model (:class:`LinearStudy`) and the rig.

    Attributes
    ----------
    rig : dict of str to numpy.ndarray
        Tension (N) per system (``unshaped`` and :data:`SHAPERS`) on the virtual rig.
    residual_rig : dict of str to float
        Residual vibration, % of the step, per system, on the virtual rig.
    """

    rig: dict[str, np.ndarray] = field(default_factory=dict)
    residual_rig: dict[str, float] = field(default_factory=dict)


class ShaperPlayground(LinearPlayground):
    """Residual vibration of mis-designed shapers on the linear model and the virtual rig.

    Parameters
    ----------
    omega_d, zeta, v_in_mm_s, x_f_mm, model_params
        As :class:`~helpers.plotting.playground.LinearPlayground`.
    rig_params : helpers.virtual.RigParameters, optional
        The virtual rig (default: the tuned rig).
    """

    def __init__(
        self,
        omega_d: float,
        zeta: float,
        v_in_mm_s: float = 200.0,
        x_f_mm: float = 20.0,
        model_params: model.ArmParameters | None = None,
        rig_params: RigParameters | None = None,
    ) -> None:
        super().__init__(omega_d, zeta, v_in_mm_s, x_f_mm, model_params)
        self.plant = ArmPlant(RigParameters() if rig_params is None else rig_params)
        self._unshaped = self._run(None)

    def design(self, design_ratio: float, zeta_error: float) -> dict[str, shapers.Shaper]:
        """ZV, ZVD (:meth:`LinearPlayground.design`) and EI designed for the displaced mode."""
        designed = super().design(design_ratio, zeta_error)
        zeta_design = self.zeta + zeta_error
        omega_n = omega_n_from_damped(design_ratio * self.omega_d, zeta_design)
        return designed | {"ei": families.ei(omega_n, zeta_design)}

    def _run(self, shaper: shapers.Shaper | None) -> tuple[np.ndarray, np.ndarray, float]:
        """(linear tension, rig tension, move end) of one move shaped by ``shaper``."""
        linear, move_end = self.shaped(shaper)
        programme, _ = experiment_programme(
            self.v_in_mm_s, self.x_f_mm, shaper, t_up=T_UP_S, t_down=T_END_S + 0.1, t_end=T_END_S + 1.0
        )
        run = simulate(programme, rate_hz=1.0 / DT_S, t_end=T_END_S - DT_S / 2, seed=0, plant=self.plant)
        rig = np.interp(self.t, run.t, run.tension)
        return linear, rig, move_end

    def study(self, design_ratio: float = 1.0, zeta_error: float = 0.0) -> Study:
        """Run every shaper designed for the displaced mode on the model and the rig."""
        designed = self.design(design_ratio, zeta_error)
        runs = {"unshaped": self._unshaped} | {name: self._run(s) for name, s in designed.items()}
        return Study(
            design_ratio=float(design_ratio),
            zeta_error=float(zeta_error),
            omega_d_design=design_ratio * self.omega_d,
            zeta_design=self.zeta + zeta_error,
            t=self.t,
            linear={k: r[0] for k, r in runs.items()},
            rig={k: r[1] for k, r in runs.items()},
            residual_linear={k: residual_after(self.t, r[0], r[2]) for k, r in runs.items()},
            residual_rig={k: residual_after(self.t, r[1], r[2]) for k, r in runs.items()},
        )

    def figure(self, study: Study) -> plt.Figure:
        """Draw ``study`` into a new figure (kept as ``self.fig`` for :meth:`update`)."""
        fig, (ax_lin, ax_rig, ax_bar) = plt.subplots(1, 3, figsize=(11.0, 3.6), width_ratios=[1.2, 1.2, 1.0])
        self._lines: dict[tuple[str, str], plt.Line2D] = {}
        for ax, which in ((ax_lin, "linear"), (ax_rig, "rig")):
            for name in ("unshaped", *SHAPERS):
                grey = name == "unshaped"
                style = {"color": "0.6" if grey else COLOURS[name], "lw": 0.8 if grey else 1.2}
                (line,) = ax.plot(study.t, getattr(study, which)[name], label=LABELS[name], **style)
                self._lines[(which, name)] = line
            ax.set_xlabel("time (s)")
            ax.set_xlim(0.0, T_END_S)
        ax_lin.set_ylabel("tension (N)")
        ax_lin.set_title("linear model (zero at rest)", fontsize=9)
        ax_rig.set_title("virtual rig (pretensioned)", fontsize=9)
        ax_lin.legend(loc="lower right", fontsize=7)
        x = np.arange(len(SHAPERS))
        colours = [COLOURS[s] for s in SHAPERS]
        self._bars = {
            "linear": ax_bar.bar(x - 0.2, [study.residual_linear[s] for s in SHAPERS], 0.4, color=colours,
                                 alpha=0.5, label="linear model"),
            "rig": ax_bar.bar(x + 0.2, [study.residual_rig[s] for s in SHAPERS], 0.4, color=colours,
                              label="virtual rig"),
        }  # fmt: skip
        ax_bar.set_xticks(x, [s.upper() for s in SHAPERS])
        ax_bar.set_ylabel("residual vibration (% of the step)")
        key = [Patch(color="0.3", alpha=0.5, label="linear model"), Patch(color="0.3", label="virtual rig")]
        ax_bar.legend(handles=key, loc="upper right", fontsize=7)
        self.fig = fig
        self._redraw_text(study)
        fig.tight_layout()
        return fig

    def _redraw_text(self, study: Study) -> None:
        assert self.fig is not None
        self.fig.suptitle(self.title(study), fontsize=9)
        ax_bar = self.fig.axes[2]
        ax_bar.set_title(
            f"unshaped: {study.residual_linear['unshaped']:.0f} % (model), "
            f"{study.residual_rig['unshaped']:.0f} % (rig)",
            fontsize=9,
        )
        top = max(*(study.residual_linear[s] for s in SHAPERS), *(study.residual_rig[s] for s in SHAPERS))
        ax_bar.set_ylim(0.0, 1.25 * max(top, 5.0))

    def update(self, design_ratio: float = 1.0, zeta_error: float = 0.0) -> Study:
        """Recompute for new slider values and redraw the figure (made on the first call).

        Parameters
        ----------
        design_ratio : float
            Design frequency over the identified one, in :data:`RATIO_RANGE`.
        zeta_error : float
            Design damping ratio minus the identified one, in :data:`ZETA_ERROR_RANGE`.

        Returns
        -------
        Study
        """
        study = self.study(design_ratio, zeta_error)
        if self.fig is None:
            self.figure(study)
            return study
        for (which, name), line in self._lines.items():
            line.set_ydata(getattr(study, which)[name])
        for which, bars in self._bars.items():
            values = study.residual_linear if which == "linear" else study.residual_rig
            for bar, name in zip(bars, SHAPERS, strict=True):
                bar.set_height(values[name])
        for ax in self.fig.axes[:2]:
            ax.relim()
            ax.autoscale_view(scalex=False)
        self._redraw_text(study)
        self.fig.canvas.draw()
        return study
