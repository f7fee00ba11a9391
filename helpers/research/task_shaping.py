"""Shapers for task-space moves, and the dynamic tension floor, on the spatial twin (**simulated**).

The families, the direction-scheduled and multi-mode designs, the automatic choice; nothing here is measured.
A move (:func:`helpers.research.task_space.plan_move`) is every tendon's steps for a bend; its command is
every tendon's constant-speed ramp, convolved with **one** shaper
(:func:`helpers.research.task_space.move_programme`).
This module chooses that shaper and checks what its dynamics do to the tensions.

**The modes of a move** (:func:`move_modes`). About the bend's equilibrium (rotors free) the twin's
linearisation gives every mode's weight in every tendon's tension after a step of the command that moves the
bend on (every spool's ``du_i / d bend``, as :func:`helpers.virtual.spatial.direction_map.frequency_map`
defines its dominant mode); the modes are ranked by their weight in the **lead** tendon's tension (the pulled
tendon that moves most). A move's ramp of ``T_r`` seconds filters mode ``k`` by
``R_k = |sin(omega_k T_r / 2) / (omega_k T_r / 2)|`` (:func:`ramp_factor`), so its **effective** weight is
``w_k R_k``.

**Split modes** (:func:`split_ratio`). The map shows split modes at a bend when the second mode's effective
weight in the lead tendon's tension is at least :data:`SPLIT_WEIGHT` (0.25) of the dominant's and the two
frequencies are more than :data:`SPLIT_APART` (5 %) apart. Why: a design for the dominant mode alone leaves
the second mode's share times its residual ``V`` there; the shortest design (ZV) leaves ``V`` = 0.26-0.45 at
a mode 15-30 % away, so a second mode of a quarter of the dominant's weight leaves 6-11 % of the dominant's
unshaped residual, the order of the 10 % goal; below a quarter, or within 5 % (where ZVD leaves under 1 %),
one mode's design is enough.

**Designs** (:func:`design_move`, names :data:`SHAPERS`):

- ``zv``, ``zvd``, ``zvdd``, ``mzv``, ``ei``, ``ei2``, ``ei3``, ``umzv``: the family
  (:data:`helpers.research.families.FAMILIES`) at the dominant mode;
- ``fixed``: ZVD at the dominant mode at rest (towards tendon 1, 0 mm: :data:`FIXED_AT`), the same for every
  move, as the one-tendon rig designs from one identification;
- ``scheduled``: ZVD at the dominant mode **scheduled on direction and magnitude**: read off a
  :class:`ModeGrid` (a map over directions x bends, interpolated bilinearly, direction periodic) when one is
  given, else the modes at the move itself;
- ``multimode``: where the modes split, ZV on each of the two (``families.multi_mode``, about one damped
  period like ZVD); elsewhere the scheduled ZVD (and says so);
- ``auto``: the **shortest** candidate whose predicted residual (below) is at most the tolerance (default
  :data:`AUTO_TOLERANCE_PCT`); ties to the smaller residual. Candidates: every family of
  :data:`AUTO_FAMILIES` at the dominant mode and, if a second mode has at least :data:`SECOND_WEIGHT` of the
  dominant's effective weight, ZV * ZV and ZVD * ZV on the two. None qualifies: the smallest residual is
  taken, and the report says so.

**Predicted residual** (:func:`predicted_residual_pct`): for each tendon ``i``,
``sum_k |w_ik| R_k Vmax_k / sum_k |w_ik| R_k`` (percent of the unshaped move's), ``Vmax_k`` the shaper's
largest ``V`` within +-:data:`BAND` (2 %) of mode ``k``'s frequency (the grid's interpolation and the change
of mode over the move); the worst tendon counts. It bounds the linearised twin's residual amplitude (the modes
add with their phases; the bound adds magnitudes).

**The dynamic floor** (:func:`dynamic_floor`, :func:`floor_check`). The shaped programme is simulated in the
spatial twin (:func:`simulate_move`: the plan's programme as each tendon's step instants on the firmware's
ticks, straight into :class:`~helpers.virtual.spatial.plant.SpatialPlant`, no board and no travel check) and
each tendon's least true arm-side tension, and its samples (1 kHz) below the floor, found over the whole
programme (lead-in, move out, hold, move back, tail). Where a **shaped** move has a sample below the floor the
policy changes, in this order, and the report names which:

1. **the pretension**: every tendon pulled in ``k`` = 1, then 2 (:data:`MAX_PREPULL_STEPS`) steps before the
   move and let out one at a time after it (:func:`prepull_programme`; one step on all four is about +5 N
   each), the move planned and designed from that pre-pulled rest (:func:`pretensioned`);
2. **the design**: at the best pretension found, each longer family of :data:`ROBUST_CHAIN`.

Why the pretension first: on the four-tendon twin the dips of a shaped move come during the move, from the
antagonists: they pay out as commanded while the arm lags the command, so the cable goes slack for tens of
milliseconds whatever the shaper and even at 25 mm/s (one step of cable is about 2.7 N of statics, the rest
pretension 2.36 N); only a higher tension before the move absorbs that lag. Unshaped moves are simulated and
reported, never changed (below the floor is the measured problem). If nothing lifts the move to the floor the
attempt with the highest least tension is returned with ``ok`` False.

**The second bending pair** (:func:`higher_modes`, :func:`with_higher_modes`). Above the dominant pair (each
plane's first bending mode, 21-27 rad/s on the four-tendon twin) the arm's next two modes are each plane's
second bending mode (its bending coordinates along the discs change sign twice, against once), 2.5-4.9
times the dominant: 58-61 and 75-82 rad/s at a 20 mm bend, 77-90 and 94-110 rad/s at 10 mm (the bend
softens them). A ZVD has zeros at its design frequency and its odd multiples only, so there it leaves 13-64 %
of what the move's ramp puts into them; :func:`with_higher_modes` convolves the design with a ZV on each
(``pi / omega_d`` longer each: 28-54 ms). ``docs/task_space.md`` has the measurements.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from helpers.board.programmes import Dwell, Move, Programme
from helpers.paper.modes import omega_n_from_damped
from helpers.paper.shapers import Shaper
from helpers.research.families import FAMILIES, multi_mode, zv, zvd
from helpers.research.task_space import MovePlan, move_programme, plan_move, shaper_metadata
from helpers.rig.safety import SafetyError
from helpers.rigfile import RigFile
from helpers.rigfile.derived import derived, lead_tendon
from helpers.virtual.spatial.direction_map import bend_equilibrium
from helpers.virtual.spatial.from_rig import spatial_rig
from helpers.virtual.spatial.plant import SpatialPlant
from helpers.virtual.spatial.rig import SpatialRig
from helpers.virtual.spatial.simulate import simulate_spatial
from helpers.virtual.spatial.statics import equilibrium, linearise

__all__ = [
    "SHAPERS", "FAMILY_OF", "SPLIT_WEIGHT", "SPLIT_APART", "SECOND_WEIGHT", "BAND", "AUTO_FAMILIES",
    "AUTO_TOLERANCE_PCT", "MAX_PREPULL_STEPS", "ROBUST_CHAIN", "MoveModes", "move_modes", "ModeGrid",
    "mode_grid", "ramp_factor", "split_ratio", "MoveShaping", "predicted_residual_pct", "design_move",
    "programme_step_times", "pretensioned", "prepull_programme", "release_order", "MoveRun", "simulate_move",
    "residuals", "FloorCheck", "dynamic_floor", "floor_check",
    "AUTO_TARGET_PCT", "simulated_pct", "verify_auto",
    "ShapedMove", "shaped_move", "residual_table", "TABLE_POINTS", "TABLE_SHAPERS", "benchmark",
    "N_HIGHER", "higher_modes", "with_higher_modes",
]  # fmt: skip

FAMILY_OF = {
    "zv": "ZV", "zvd": "ZVD", "zvdd": "ZVDD", "mzv": "MZV", "ei": "EI", "ei2": "2-hump EI",
    "ei3": "3-hump EI", "umzv": "UM-ZV",
}  # fmt: skip
"""Command-line names of the single-mode families (:data:`helpers.research.families.FAMILIES`)."""

SHAPERS = ("none", *FAMILY_OF, "fixed", "scheduled", "multimode", "auto")
"""Every shaper a task-space move can run."""

FIXED_AT = (0.0, 0.0)
"""Where the ``fixed`` ZVD is designed (direction deg from tendon 1's, bend mm): the rest, as one tendon's rig
identifies."""

SPLIT_WEIGHT = 0.25
"""A second mode at least this share of the dominant's effective weight (lead tendon) splits the modes."""

SPLIT_APART = 0.05
"""... and more than this fraction away from the dominant's frequency (closer, ZVD covers both)."""

SECOND_WEIGHT = 0.05
"""The automatic choice tries multi-mode candidates when a second mode has at least this effective share."""

BAND = 0.02
"""Relative half-width of the frequency band over which the predicted residual takes its worst value."""

AUTO_FAMILIES = ("ZV", "MZV", "ZVD", "EI", "ZVDD", "2-hump EI", "3-hump EI")
"""Single-mode families the automatic choice tries at the dominant mode."""

AUTO_TOLERANCE_PCT = 5.0
"""The automatic choice's tolerance on the predicted residual, percent of the unshaped move's."""

DB_MM = 0.1
"""The bend increment over which the command's direction (every spool's rate) is taken (as the map's)."""

N_MODES = 4
"""Modes kept per bend (by weight in the lead tendon's tension)."""


# --- the modes of a move ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MoveModes:
    """The modes a move excites, ranked by weight in the lead tendon's tension (rotors free).

    Attributes
    ----------
    direction_deg, bend_mm : float
        The bend.
    lead : int
        The lead tendon (0-based): the one that pulls most towards the bend
        (:func:`helpers.rigfile.derived.lead_tendon`).
    omega_d, zeta : tuple of float
        Each mode's damped frequency (rad/s) and damping ratio, the largest weight first.
    weight : tuple of tuple of float
        ``weight[i][k]``: mode ``k``'s amplitude in tendon ``i``'s tension after a unit step of the command
        (N per m of bend command).
    """

    direction_deg: float
    bend_mm: float
    lead: int
    omega_d: tuple[float, ...]
    zeta: tuple[float, ...]
    weight: tuple[tuple[float, ...], ...]

    def omega_n(self, k: int) -> float:
        """Mode ``k``'s undamped frequency, rad/s."""
        return omega_n_from_damped(self.omega_d[k], self.zeta[k])

    def effective(self, window_s: float) -> np.ndarray:
        """Each mode's effective weight in the lead tendon's tension after a ramp of ``window_s``."""
        w = np.abs(np.array(self.weight[self.lead]))
        return w * np.array([ramp_factor(o, window_s) for o in self.omega_d])


def ramp_factor(omega: float, window_s: float) -> float:
    """``|sin(omega T / 2) / (omega T / 2)|``: a ramp of ``T`` seconds' residual over a step's."""
    x = 0.5 * float(omega) * float(window_s)
    return 1.0 if x == 0 else abs(math.sin(x) / x)


def move_modes(twin: SpatialRig, direction_deg: float, bend_mm: float, n_modes: int = N_MODES) -> MoveModes:
    """The modes at a bend (module docstring): the linearisation about the bend's equilibrium, rotors free."""
    eq = bend_equilibrium(twin, float(direction_deg), float(bend_mm))
    nxt = bend_equilibrium(twin, float(direction_deg), float(bend_mm) + DB_MM, start=eq)
    u_cmd = (nxt.u - eq.u) / (DB_MM * 1e-3)
    lead = lead_tendon(twin.tendons, direction_deg)
    free = linearise(twin, eq, rotor="free")
    w = np.abs(np.einsum("ijk,j->ik", free.weights, u_cmd))  # (tendon, pole)
    ks = np.flatnonzero(free.poles.imag > 1e-9)
    order = ks[np.argsort(-w[lead, ks], kind="stable")][:n_modes]
    p = free.poles[order]
    return MoveModes(
        direction_deg=float(direction_deg), bend_mm=float(bend_mm), lead=lead,
        omega_d=tuple(float(v) for v in p.imag), zeta=tuple(float(v) for v in -p.real / np.abs(p)),
        weight=tuple(tuple(float(v) for v in w[i, order]) for i in range(twin.n_tendons)),
    )  # fmt: skip


N_HIGHER = 2
"""Modes above the dominant pair that :func:`higher_modes` keeps: the second bending pair."""


def higher_modes(
    rig: RigFile, twin: SpatialRig, plan: MovePlan, n_higher: int = N_HIGHER
) -> tuple[tuple[float, float], ...]:
    """The modes above the dominant pair at the pose a move reaches: ``(omega_d, zeta)``, lowest first.

    The twin's linearisation (rotors free) about the equilibrium with every stepper at the plan's whole steps
    (``twin``: the rest the plan starts from, pre-pulled where it is), its oscillatory modes by frequency:
    the first two are the dominant pair (each plane's first bending mode), the next ``n_higher`` the second
    bending pair (module docstring). The twin's prediction: nothing here is measured.
    """
    mm = np.asarray(derived(rig).mm_per_step, float)
    eq = equilibrium(twin, np.asarray(plan.steps, float) * mm * 1e-3, rotor="free")
    poles = linearise(twin, eq, rotor="free").poles
    osc = sorted(poles[poles.imag > 1e-9], key=lambda p: p.imag)
    if len(osc) < 2 + n_higher:
        raise ValueError(f"the twin has {len(osc)} oscillatory modes at the move, fewer than {2 + n_higher}")
    return tuple((float(p.imag), float(-p.real / abs(p))) for p in osc[2 : 2 + n_higher])


def with_higher_modes(shaper: Shaper, modes: Sequence[tuple[float, float]], name: str) -> Shaper:
    """``shaper`` convolved with a ZV on each of ``modes`` (``(omega_d, zeta)``), named ``name``."""
    out = shaper
    for omega_d, zeta in modes:
        out = out.convolve(zv(omega_n_from_damped(omega_d, zeta), zeta))
    return _renamed(out, name)


def split_ratio(modes: MoveModes, window_s: float) -> tuple[float, int | None]:
    """The split: the largest effective share of a mode more than :data:`SPLIT_APART` from the dominant.

    Returns ``(ratio, k)``: that mode's effective weight over the dominant's and its index (``None``, 0.0 if
    there is none). The modes are split when ``ratio >= SPLIT_WEIGHT``.
    """
    eff = modes.effective(window_s)
    k0 = int(np.argmax(eff))
    best, which = 0.0, None
    for k in range(len(eff)):
        apart = abs(modes.omega_d[k] - modes.omega_d[k0]) / modes.omega_d[k0]
        if k != k0 and apart > SPLIT_APART and eff[k] / eff[k0] > best:
            best, which = float(eff[k] / eff[k0]), k
    return best, which


# --- the grid over direction and magnitude ----------------------------------------------------------------
@dataclass(frozen=True)
class ModeGrid:
    """Modes on a grid of directions x bends, interpolated to any move inside it (:meth:`at`).

    Directions are periodic (360 deg); bends must lie within the grid's range. Each grid point keeps its
    :data:`N_MODES` modes; at a move, each of the nearest point's modes is matched at the four corners to the
    mode of nearest frequency and its frequency, damping and weights interpolated bilinearly.
    """

    directions_deg: tuple[float, ...]
    bends_mm: tuple[float, ...]
    points: dict[tuple[int, int], MoveModes] = field(repr=False)

    def to_frame(self) -> pd.DataFrame:
        """One row per grid point and mode: ``direction_deg, bend_mm, lead, mode, omega_d, zeta, w1..wn``."""
        rows = []
        for (i, j), m in sorted(self.points.items()):
            for k in range(len(m.omega_d)):
                row = {"direction_deg": self.directions_deg[i], "bend_mm": self.bends_mm[j],
                       "lead": m.lead + 1, "mode": k + 1, "omega_d_rad_s": m.omega_d[k],
                       "zeta": m.zeta[k]}  # fmt: skip
                row.update({f"weight{t + 1}": m.weight[t][k] for t in range(len(m.weight))})
                rows.append(row)
        return pd.DataFrame(rows)

    @classmethod
    def from_frame(cls, df: pd.DataFrame) -> ModeGrid:
        """The grid :meth:`to_frame` wrote."""
        dirs = tuple(sorted(float(v) for v in set(df["direction_deg"])))
        bends = tuple(sorted(float(v) for v in set(df["bend_mm"])))
        nt = sum(1 for c in df.columns if c.startswith("weight"))
        points = {}
        for (d, b), g in df.groupby(["direction_deg", "bend_mm"], sort=True):
            g = g.sort_values("mode")
            points[(dirs.index(float(d)), bends.index(float(b)))] = MoveModes(
                float(d), float(b), int(g["lead"].iloc[0]) - 1, tuple(g["omega_d_rad_s"].astype(float)),
                tuple(g["zeta"].astype(float)),
                tuple(tuple(g[f"weight{t + 1}"].astype(float)) for t in range(nt)),
            )  # fmt: skip
        if len(points) != len(dirs) * len(bends):
            raise ValueError(
                f"a mode grid needs every direction x bend: {len(points)} of {len(dirs) * len(bends)}"
            )
        return cls(dirs, bends, points)

    def write_csv(self, path: str | Path) -> Path:
        """Save the grid as CSV (:meth:`to_frame`, 9 significant digits); returns the path."""
        path = Path(path)
        self.to_frame().to_csv(path, index=False, float_format="%.9g")
        return path

    @classmethod
    def read_csv(cls, path: str | Path) -> ModeGrid:
        """The grid :meth:`write_csv` saved.

        Raises
        ------
        ValueError
            One line naming the file: missing, not a grid, or a grid without every direction x bend.
        """
        try:
            return cls.from_frame(pd.read_csv(path))
        except (OSError, KeyError, ValueError, pd.errors.ParserError) as exc:
            raise ValueError(f"{path}: not a mode grid ({exc})") from None

    def _corners(self, direction_deg: float, bend_mm: float) -> list[tuple[tuple[int, int], float]]:
        dirs, bends = np.array(self.directions_deg), np.array(self.bends_mm)
        if not bends[0] - 1e-9 <= bend_mm <= bends[-1] + 1e-9:
            raise ValueError(f"bend {bend_mm:g} mm is outside the mode grid's {bends[0]:g}-{bends[-1]:g} mm")
        beta = float(direction_deg) % 360.0
        if len(dirs) == 1:
            if abs(((beta - dirs[0] + 180) % 360) - 180) > 1e-9:
                raise ValueError(f"direction {direction_deg:g} deg is not on the grid's one direction")
            i0 = i1 = 0
            fd = 0.0
        else:
            ext = np.append(dirs, dirs[0] + 360.0)
            i = int(np.searchsorted(ext, beta, side="right") - 1)
            if beta < dirs[0]:
                i, beta = len(dirs) - 1, beta + 360.0
            i0, i1 = i, (i + 1) % len(dirs)
            lo, hi = ext[i] if i < len(dirs) else ext[-1], ext[i + 1] if i + 1 < len(ext) else ext[0] + 360
            fd = (beta - lo) / (hi - lo)
        j = int(np.clip(np.searchsorted(bends, bend_mm, side="right") - 1, 0, max(len(bends) - 2, 0)))
        j1 = min(j + 1, len(bends) - 1)
        fb = 0.0 if j1 == j else (bend_mm - bends[j]) / (bends[j1] - bends[j])
        fb = float(np.clip(fb, 0.0, 1.0))
        out = [((i0, j), (1 - fd) * (1 - fb)), ((i1, j), fd * (1 - fb)), ((i0, j1), (1 - fd) * fb),
               ((i1, j1), fd * fb)]  # fmt: skip
        return [(k, w) for k, w in out if w > 0] or [((i0, j), 1.0)]

    def at(self, direction_deg: float, bend_mm: float) -> MoveModes:
        """The modes at a move, interpolated (class docstring); the grid is not recomputed."""
        corners = self._corners(direction_deg, bend_mm)
        near = self.points[max(corners, key=lambda c: c[1])[0]]
        n = len(near.omega_d)
        om, ze = np.zeros(n), np.zeros(n)
        wt = np.zeros((len(near.weight), n))
        for key, f in corners:
            m = self.points[key]
            for k in range(n):
                c = int(np.argmin(np.abs(np.array(m.omega_d) - near.omega_d[k])))
                om[k] += f * m.omega_d[c]
                ze[k] += f * m.zeta[c]
                wt[:, k] += f * np.array([m.weight[t][c] for t in range(len(m.weight))])
        weights = tuple(tuple(float(v) for v in r) for r in wt)
        return MoveModes(float(direction_deg), float(bend_mm), near.lead, tuple(float(v) for v in om),
                         tuple(float(v) for v in ze), weights)  # fmt: skip


def mode_grid(twin: SpatialRig, directions_deg: Sequence[float], bends_mm: Sequence[float]) -> ModeGrid:
    """:func:`move_modes` at every direction x bend (about half a second each on the four-tendon twin)."""
    dirs = tuple(sorted({float(d) % 360.0 for d in directions_deg}))
    bends = tuple(sorted({float(b) for b in bends_mm}))
    if not dirs or not bends or bends[0] <= 0:
        raise ValueError("a mode grid needs at least one direction and bends > 0 mm")
    points = {(i, j): move_modes(twin, d, b) for i, d in enumerate(dirs) for j, b in enumerate(bends)}
    return ModeGrid(dirs, bends, points)


# --- designs ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MoveShaping:
    """A move's shaper, what it was designed from, and what the twin predicts of it.

    Attributes
    ----------
    name : str
        The command-line name (:data:`SHAPERS`).
    shaper : Shaper or None
        ``None``: unshaped.
    modes : tuple of (omega_d, zeta)
        The modes the design cancels.
    source : str
        ``"grid"`` (interpolated on a :class:`ModeGrid`) or ``"move"`` (the modes at the move itself).
    lead : int
        The lead tendon (0-based).
    split : float
        :func:`split_ratio` at the move.
    predicted_pct : float
        :func:`predicted_residual_pct`.
    note : str
        What the design did (a multi-mode design falling back, the automatic choice's pick).
    candidates : pandas.DataFrame or None
        The automatic choice's candidates (``candidate``, ``duration_s``, ``predicted_pct``, ``chosen``).
    """

    name: str
    shaper: Shaper | None
    modes: tuple[tuple[float, float], ...] = ()
    source: str = "move"
    lead: int = 0
    split: float = 0.0
    predicted_pct: float = 100.0
    note: str = ""
    candidates: pd.DataFrame | None = field(default=None, compare=False, repr=False)

    @property
    def duration_s(self) -> float:
        """The shaper's duration (0 unshaped)."""
        return 0.0 if self.shaper is None else float(self.shaper.duration)

    def describe(self) -> str:
        """One line: the design, its duration, its modes and its predicted residual."""
        if self.shaper is None:
            return "unshaped (every tendon's move a constant-speed ramp)"
        modes = ", ".join(f"{o:.3f} rad/s (zeta {z:.4f})" for o, z in self.modes)
        where = {"grid": "interpolated on the mode grid", "rest": "at rest"}.get(self.source, "at the move")
        note = f"; {self.note}" if self.note else ""
        return (
            f"{self.name}: {self.shaper.name}, {len(self.shaper)} impulses over "
            f"{1e3 * self.duration_s:.1f} ms, "
            f"from tendon {self.lead + 1}'s tension {where}: {modes}; split {self.split:.2f} "
            f"(>= {SPLIT_WEIGHT} splits); predicted residual {self.predicted_pct:.1f} % of unshaped{note}"
        )

    def metadata(self) -> dict[str, object]:
        """The design for a recording's scenario."""
        if self.shaper is None:
            return {"shaper": "none"}
        return shaper_metadata(
            self.shaper, self.name, family=self.shaper.name, source=self.source,
            tendon=self.lead + 1, modes=[{"omega_d_rad_s": o, "zeta": z} for o, z in self.modes],
            split=self.split, predicted_residual_pct=self.predicted_pct, note=self.note,
        )  # fmt: skip


def _vmax(shaper: Shaper, omega_n: float, zeta: float, band: float) -> float:
    grid = omega_n * np.linspace(1 - band, 1 + band, 9)
    return float(np.max(np.atleast_1d(shaper.vibration(grid, zeta))))


def predicted_residual_pct(
    shaper: Shaper | None, modes: MoveModes, window_s: float, band: float = BAND
) -> float:
    """The worst tendon's predicted residual, percent of the unshaped move's (module docstring)."""
    if shaper is None:
        return 100.0
    ramp = np.array([ramp_factor(o, window_s) for o in modes.omega_d])
    v = np.array([_vmax(shaper, modes.omega_n(k), modes.zeta[k], band) for k in range(len(modes.omega_d))])
    worst = 0.0
    for w in modes.weight:
        e = np.abs(np.array(w)) * ramp
        if e.sum() > 0:
            worst = max(worst, float((e * v).sum() / e.sum()))
    return 100.0 * worst


def _window_s(plan: MovePlan, rig: RigFile, speed_mm_s: float) -> float:
    lead = plan.lead
    return abs(plan.steps[lead]) * derived(rig).mm_per_step[lead] / float(speed_mm_s)


def _renamed(shaper: Shaper, name: str) -> Shaper:
    return Shaper(shaper.amplitudes, shaper.times, name)


def _auto(modes: MoveModes, window_s: float, tolerance_pct: float) -> tuple[Shaper, str, pd.DataFrame, tuple]:
    eff = modes.effective(window_s)
    k0 = int(np.argmax(eff))
    wn, z = modes.omega_n(k0), modes.zeta[k0]
    cands: list[tuple[str, Shaper, tuple]] = []
    for name in AUTO_FAMILIES:
        fam = FAMILIES[name]
        if fam.zeta_range[0] <= z <= fam.zeta_range[1]:
            cands.append((name, fam(wn, z), ((modes.omega_d[k0], z),)))
    ratio, k2 = split_ratio(modes, window_s)
    if k2 is not None and ratio >= SECOND_WEIGHT:
        m2 = (modes.omega_n(k2), modes.zeta[k2])
        two = ((modes.omega_d[k0], z), (modes.omega_d[k2], modes.zeta[k2]))
        cands.append(("ZV * ZV (two modes)", multi_mode([(wn, z), m2], zv), two))
        cands.append(("ZVD * ZV (two modes)", zvd(wn, z).convolve(zv(*m2)), two))
    rows = [{"candidate": n, "duration_s": float(s.duration),
             "predicted_pct": predicted_residual_pct(s, modes, window_s), "order": i}
            for i, (n, s, _) in enumerate(cands)]  # fmt: skip
    table = pd.DataFrame(rows).sort_values(["duration_s", "predicted_pct", "order"], kind="stable")
    ok = table[table["predicted_pct"] <= tolerance_pct]
    pick = ok.iloc[0] if len(ok) else table.sort_values(["predicted_pct", "order"], kind="stable").iloc[0]
    note = (
        f"auto: the shortest of {len(cands)} candidates within {tolerance_pct:g} % predicted: "
        f"{pick['candidate']}"
        if len(ok)
        else f"auto: no candidate within {tolerance_pct:g} % predicted; the smallest: {pick['candidate']}"
    )
    table["chosen"] = table["order"] == pick["order"]
    table["shaper"] = [_renamed(cands[int(i)][1], cands[int(i)][0]) for i in table["order"]]
    table["modes"] = [cands[int(i)][2] for i in table["order"]]
    name, shaper, used = cands[int(pick["order"])]
    return _renamed(shaper, name), note, table.drop(columns="order").reset_index(drop=True), used


def design_move(
    rig: RigFile,
    plan: MovePlan,
    name: str,
    speed_mm_s: float = 200.0,
    grid: ModeGrid | None = None,
    twin: SpatialRig | None = None,
    tolerance_pct: float = AUTO_TOLERANCE_PCT,
) -> MoveShaping:
    """The shaper ``name`` (:data:`SHAPERS`) for a planned move (module docstring).

    Parameters
    ----------
    rig : RigFile
        The rig file (steps, the floor).
    plan : MovePlan
        The move (its direction, bend and steps; the lead tendon's steps and ``speed_mm_s`` give the ramp).
    name : str
        ``none``, a family (``zv`` ... ``umzv``), ``scheduled``, ``multimode`` or ``auto``.
    speed_mm_s : float
        The lead tendon's cable speed.
    grid : ModeGrid, optional
        Read the modes off this grid (interpolated) instead of linearising the twin at the move.
    twin : SpatialRig, optional
        The twin of ``rig`` (default built from it).
    tolerance_pct : float
        The automatic choice's tolerance.
    """
    if name not in SHAPERS:
        raise ValueError(f"shaper must be one of {', '.join(SHAPERS)}, got {name!r}")
    if name == "none":
        return MoveShaping("none", None)
    twin = spatial_rig(rig) if twin is None else twin
    if grid is not None:
        modes, source = grid.at(plan.direction_deg, plan.bend_mm), "grid"
    else:
        modes, source = move_modes(twin, plan.direction_deg, plan.bend_mm), "move"
    window = _window_s(plan, rig, speed_mm_s)
    eff = modes.effective(window)
    k0 = int(np.argmax(eff))
    dom = (modes.omega_d[k0], modes.zeta[k0])
    wn = modes.omega_n(k0)
    ratio, k2 = split_ratio(modes, window)
    note, table = "", None
    if name in FAMILY_OF:
        shaper, used = FAMILIES[FAMILY_OF[name]](wn, dom[1]), (dom,)
    elif name == "fixed":
        towards = rig.tendons[0].angle_deg + FIXED_AT[0]  # tendon 1's direction (one it faces, on any rig)
        rest = move_modes(twin, towards, FIXED_AT[1])
        shaper = _renamed(zvd(rest.omega_n(0), rest.zeta[0]), "ZVD (fixed at rest)")
        used, source = ((rest.omega_d[0], rest.zeta[0]),), "rest"
        note = f"designed once at {FIXED_AT[1]:g} mm towards {towards:g} deg (tendon 1), whatever the move"
    elif name == "scheduled" or (name == "multimode" and (k2 is None or ratio < SPLIT_WEIGHT)):
        shaper, used = _renamed(zvd(wn, dom[1]), "ZVD (scheduled)"), (dom,)
        if name == "multimode":
            note = (
                f"the modes do not split here (second mode's share {ratio:.2f} < {SPLIT_WEIGHT}): "
                "the scheduled ZVD"
            )
    elif name == "multimode":
        second = (modes.omega_d[k2], modes.zeta[k2])
        shaper = multi_mode([(wn, dom[1]), (modes.omega_n(k2), second[1])], zv)
        used = (dom, second)
    else:
        shaper, note, table, used = _auto(modes, window, tolerance_pct)
    pct = predicted_residual_pct(shaper, modes, window)
    return MoveShaping(name, shaper, used, source, modes.lead, ratio, pct, note, table)


# --- the twin's dynamics of a move -------------------------------------------------------------------------
def programme_step_times(programme: Programme, n_tendons: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each tendon's step instants (s from GO) and signs (+1.0/-1.0), as the boards step them.

    :meth:`helpers.board.programmes.Programme.step_times_us`: step ``k`` of ``n`` in an item of ``W`` us on
    the firmware's 0.5 us tick ``ceil(2 k W / n)`` from the item's start (``firmware/PROTOCOL.md``).
    """
    return [(t * 1e-6, s.astype(float)) for t, s in programme.step_times_us(n_tendons)]


def pretensioned(rig: RigFile, twin: SpatialRig, k: int) -> SpatialRig:
    """The twin whose rest is every tendon pulled ``k`` steps in (each pretension the statics' tension).

    Only for tendons that balance (their offsets' vectors sum to zero, as four at 90 degrees): elsewhere
    pulling every tendon in bends the arm, and this raises ``ValueError`` (the dynamic floor then changes the
    design instead).
    """
    if k == 0:
        return twin
    r = np.array([t.offset_mm for t in twin.tendons])
    pull = np.hypot(np.sum(r * np.cos(twin.angles)), np.sum(r * np.sin(twin.angles)))
    if pull > 1e-6 * r.sum():  # every tendon pulled in alike bends an arm whose tendons do not balance
        angles = ", ".join(f"{t.angle_deg:g}" for t in twin.tendons)
        raise ValueError(
            f"pulling every tendon in would bend this arm (tendons at {angles} deg do not balance)"
        )
    mm = np.array(derived(rig).mm_per_step)
    tension = equilibrium(twin, np.full(twin.n_tendons, k) * mm * 1e-3, rotor="free").tension
    tendons = tuple(
        dataclasses.replace(t, pretension_n=float(v)) for t, v in zip(twin.tendons, tension, strict=True)
    )
    return dataclasses.replace(twin, tendons=tendons)


def prepull_programme(
    programme: Programme, k: int, n_tendons: int
) -> tuple[Programme, float, float]:
    """``programme`` with every tendon pulled ``k`` steps in before it and let out after it.

    The pull: every tendon at once, ``k`` steps in ``k`` ms, then :data:`PREPULL_SETTLE_MS` of dwell (all four
    together excite little: measured, the least tension stays at the pretension); the release: one tendon at a
    time (1, 3, 2, 4 ...), :data:`RELEASE_GAP_MS` apart (one step let out of about 7.5 N rings down to about
    0.6 N for a millisecond). Returns the programme and the instants (s) the move and the release start.
    """
    if k == 0:
        return programme, 0.0, programme.duration_s
    pull = [Move(1000 * k, (k,) * n_tendons), Dwell(PREPULL_SETTLE_MS)]
    release = []
    for j in release_order(n_tendons):
        release += [
            Move(1000 * k, tuple(-k * (i == j) for i in range(n_tendons))),
            Dwell(RELEASE_GAP_MS),
        ]
    moved = Programme(tuple(pull) + programme.items + tuple(release))
    start = sum(it.duration_us for it in pull) / 1e6
    return moved, start, start + programme.duration_s


def release_order(n_tendons: int) -> list[int]:
    """The order (0-based) a pre-pull lets the tendons out: every other one first (1, 3, then 2, 4 ...)."""
    return list(range(0, n_tendons, 2)) + list(range(1, n_tendons, 2))


PREPULL_SETTLE_MS = 500
"""Dwell after the pre-pull, before the move's own programme starts."""

RELEASE_GAP_MS = 250
"""Between the tendons let out after a pre-pulled move."""


@dataclass(frozen=True)
class MoveRun:
    """A move simulated in the spatial twin (**simulated**).

    ``t`` (s), ``tension`` (true arm-side, N), ``output`` (the amplifiers' noise-free output, N), ``tip`` (m);
    ``move_s``: where the move's own programme starts (after a pre-pull), ``end_up_s``/``end_down_s``: when
    each shaped command ends; ``t_down_s``: when the move back starts; ``release_s``: where a pre-pull's
    release starts (the end of the move's programme otherwise); ``tip_bend_m``: the tip at the bend's statics
    (rotors free); ``wall_s``: the simulation's wall time.
    """

    t: np.ndarray
    tension: np.ndarray
    output: np.ndarray
    tip: np.ndarray
    move_s: float
    end_up_s: float
    t_down_s: float
    end_down_s: float
    release_s: float
    tip_bend_m: np.ndarray
    wall_s: float

    def least_n(self) -> np.ndarray:
        """Each tendon's least true tension over the move's programme (the pre-pull's own steps excluded)."""
        w = (self.t >= self.move_s) & (self.t < self.release_s)
        return self.tension[w].min(axis=0)

    def below(self, floor_n: float) -> np.ndarray:
        """Each tendon's samples below ``floor_n`` over the move's programme (slack events)."""
        w = (self.t >= self.move_s) & (self.t < self.release_s)
        return (self.tension[w] < floor_n).sum(axis=0)


def simulate_move(
    rig: RigFile,
    plan: MovePlan,
    shaper: Shaper | None,
    speed_mm_s: float = 200.0,
    t_up_s: float = 1.0,
    t_down_s: float = 8.0,
    t_end_s: float = 12.0,
    twin: SpatialRig | None = None,
    plant: SpatialPlant | None = None,
    rate_hz: float = 1000.0,
    prepull: int = 0,
) -> MoveRun:
    """The move's programme (:func:`~helpers.research.task_space.move_programme`) run in the spatial twin.

    Each tendon's step instants go straight into the plant (no board, no travel check: the twin's position
    0 is the rest, and a tendon may pay out from it). ``prepull``: every tendon pulled that many steps in
    before the programme and let out after it (:func:`prepull_programme`; ``plan`` is then the plan from that
    pre-pulled rest). The times are the move's programme's own, from its start.
    """
    twin = spatial_rig(rig) if twin is None else twin
    prog = move_programme(plan, rig, speed_mm_s, shaper, t_up_s, t_down_s, t_end_s)
    prog, t0, t_release = prepull_programme(prog, prepull, rig.n_tendons)
    plant = SpatialPlant(twin) if plant is None else plant
    mm = np.array(derived(rig).mm_per_step)
    bend = equilibrium(twin, (np.array(plan.steps) + prepull) * mm * 1e-3, rotor="free")
    started = time.perf_counter()
    res = simulate_spatial(programme_step_times(prog, rig.n_tendons), plant=plant, rate_hz=rate_hz,
                           t_end=prog.duration_s + 1e-6)  # fmt: skip
    wall = time.perf_counter() - started
    dur = _window_s(plan, rig, speed_mm_s) + (0.0 if shaper is None else float(shaper.duration))
    return MoveRun(res.t, res.tension, res.output, res.tip, t0, t0 + t_up_s + dur, t0 + t_down_s,
                   t0 + t_down_s + dur, t_release, np.asarray(bend.tip), wall)  # fmt: skip


def residuals(
    run: MoveRun, floor_n: float, settle_s: float = 0.2, window_s: float = 2.0
) -> dict[str, object]:
    """The residual vibration after the move out, and the least tensions.

    The **residual window** is ``[end + settle_s, end + settle_s + window_s]`` after the shaped command out
    ends (``end``: the lead-in, the ramp and the shaper): ``tension_p2p_n`` is each tendon's amplifier
    output's peak to peak there (the settle skips the stepping's fast transients), ``tip_mm`` the tip's
    largest distance from where the bend's statics put it. ``least_n``: each tendon's least true tension
    over the move's programme; ``below_floor``: its samples below ``floor_n`` there.
    """
    t = run.t
    lo = run.end_up_s + settle_s
    w = (t >= lo) & (t <= lo + window_s)
    if not w.any() or lo + window_s > run.t_down_s + 1e-9:
        raise ValueError(
            f"the residual window {lo:.3f}-{lo + window_s:.3f} s does not fit before the move back"
        )
    tip = np.linalg.norm(run.tip[w] - run.tip_bend_m[None, :], axis=1)
    return {
        "window_s": (float(lo), float(lo + window_s)),
        "tension_p2p_n": tuple(float(v) for v in np.ptp(run.output[w], axis=0)),
        "tip_mm": float(1e3 * tip.max()),
        "least_n": tuple(float(v) for v in run.least_n()),
        "below_floor": tuple(int(v) for v in run.below(floor_n)),
    }


AUTO_TARGET_PCT = 10.0
"""The automatic choice's target on the residual simulated in the twin, percent of the unshaped move's."""

VERIFY_TIMES = (1.0, 4.0, 4.8)
"""The programme (t_up, t_down, t_end) on which :func:`verify_auto` simulates each candidate: the
recording's lead-in (so the move starts as long after a pre-pull as it will), a shorter hold and no tail."""


def simulated_pct(run: MoveRun, unshaped: dict[str, object], floor_n: float) -> float:
    """The worst of the tip's and every tendon's residual (:func:`residuals`), % of the unshaped one's."""
    r = residuals(run, floor_n)
    tip = 100 * float(r["tip_mm"]) / max(float(unshaped["tip_mm"]), 1e-12)
    p2p = np.array(r["tension_p2p_n"]) / np.maximum(np.array(unshaped["tension_p2p_n"]), 1e-12)
    return float(max(tip, 100 * p2p.max()))


def verify_auto(
    rig: RigFile,
    plan: MovePlan,
    shaping: MoveShaping,
    speed_mm_s: float = 200.0,
    prepull: int = 0,
    twin: SpatialRig | None = None,
    target_pct: float = AUTO_TARGET_PCT,
    unshaped_plan: MovePlan | None = None,
) -> MoveShaping:
    """The automatic choice checked in the twin: the shortest candidate whose **simulated** residual meets it.

    The candidates of ``shaping`` (an ``auto`` design) are simulated in order of duration
    (:data:`VERIFY_TIMES`, with ``prepull`` steps pulled in first) against the unshaped move as planned
    (``unshaped_plan``, no pre-pull; default ``plan`` with the same pre-pull); the first whose
    :func:`simulated_pct` is at most ``target_pct`` and that keeps every tendon at the floor is taken.
    None: the candidate of the smallest simulated residual among those keeping the floor (or of all). The
    linear prediction ranks nothing here: it misses the high modes the stepping and the slack excite (four
    tendons, 10 mm towards 45 deg: MZV predicted 3.2 %, simulated 18.7 %).
    """
    if shaping.candidates is None:
        raise ValueError("verify_auto needs an automatic choice's candidates")
    twin = spatial_rig(rig) if twin is None else twin
    plant = SpatialPlant(twin)
    ref, ref_k = (plan, prepull) if unshaped_plan is None else (unshaped_plan, 0)
    base = residuals(simulate_move(rig, ref, None, speed_mm_s, *VERIFY_TIMES, twin=twin, plant=plant,
                                   prepull=ref_k), plan.floor_n)  # fmt: skip
    table = shaping.candidates.sort_values("duration_s", kind="stable").reset_index(drop=True)
    sims, lows = [], []
    pick = None
    for _, row in table.iterrows():
        run = simulate_move(rig, plan, row["shaper"], speed_mm_s, *VERIFY_TIMES, twin=twin, plant=plant,
                            prepull=prepull)  # fmt: skip
        sims.append(simulated_pct(run, base, plan.floor_n))
        lows.append(int(run.below(plan.floor_n).sum()))
        if sims[-1] <= target_pct and lows[-1] == 0:
            pick = len(sims) - 1
            break
    table = table.iloc[: len(sims)].copy()
    table["simulated_pct"], table["below_floor"] = sims, lows
    if pick is None:
        keep = [i for i in range(len(sims)) if lows[i] == 0] or list(range(len(sims)))
        pick = min(keep, key=lambda i: sims[i])
        note = (f"auto, simulated: no candidate within {target_pct:g} % of the unshaped residual; the "
                f"smallest: {table['candidate'].iloc[pick]} at {sims[pick]:.1f} %")  # fmt: skip
    else:
        note = (f"auto, simulated: the shortest within {target_pct:g} % of the unshaped residual: "
                f"{table['candidate'].iloc[pick]} at {sims[pick]:.1f} % ({len(sims)} simulated)")  # fmt: skip
    table["chosen"] = [i == pick for i in range(len(sims))]
    chosen = table.iloc[pick]
    return dataclasses.replace(
        shaping, shaper=chosen["shaper"], modes=chosen["modes"], predicted_pct=float(chosen["predicted_pct"]),
        note=note, candidates=table,
    )  # fmt: skip


# --- the dynamic floor --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class FloorCheck:
    """The dynamic floor's verdict (module docstring).

    Attributes
    ----------
    plan : MovePlan
        The plan to run (from the pre-pulled rest if the pretension changed).
    shaping : MoveShaping
        The design to run.
    prepull : int
        Steps every tendon is pulled in before the move (0: the pretension unchanged).
    least_n : tuple of float
        Each tendon's least true tension over the move's programme as run, N.
    below_floor : tuple of int
        Each tendon's samples (at the DAQ rate) below the floor there.
    floor_n : float
    changed : str
        ``"nothing"``, ``"pretension"``, ``"design"`` or ``"pretension and design"``.
    ok : bool
        No sample of any tendon below the floor.
    attempts : tuple of str
        One line per simulation: what was run and its least tension.
    """

    plan: MovePlan
    shaping: MoveShaping
    prepull: int
    least_n: tuple[float, ...]
    below_floor: tuple[int, ...]
    floor_n: float
    changed: str
    ok: bool
    attempts: tuple[str, ...]

    def lines(self) -> list[str]:
        """The report: the least tension per tendon against the floor, and what changed."""
        pairs = enumerate(zip(self.least_n, self.below_floor, strict=True))
        least = ", ".join(f"tendon {i + 1} {v:.2f} N ({n} samples below)" for i, (v, n) in pairs)
        out = [f"least tension by the twin's dynamics (simulated): {least}; floor {self.floor_n:.2f} N"]
        out += [f"  tried: {a}" for a in self.attempts]
        if self.shaping.shaper is None:
            out.append("unshaped: never changed (allowed below the floor, reported)")
        elif self.changed == "nothing":
            out.append(
                "dynamic floor kept: nothing changed"
                if self.ok
                else "dynamic floor missed: nothing changed it"
            )
        else:
            what = f"{self.prepull} step(s) pulled in on every tendon before the move" if self.prepull else ""
            if "design" in self.changed:
                what += ("; " if what else "") + f"the design {self.shaping.shaper.name}"
            verdict = "kept" if self.ok else "still missed (the best attempt)"
            out.append(f"dynamic floor {verdict}: changed the {self.changed}: {what}")
        return out

    def metadata(self) -> dict[str, object]:
        """The check for a recording's scenario."""
        return {"least_tension_n": list(self.least_n), "samples_below_floor": list(self.below_floor),
                "floor_n": self.floor_n, "changed": self.changed, "prepull_steps": self.prepull,
                "ok": self.ok, "attempts": list(self.attempts), "simulated": True}  # fmt: skip


Simulator = Callable[[MovePlan, Shaper | None, int], tuple[np.ndarray, np.ndarray]]
"""``simulate(plan, shaper, prepull) -> (least tension, samples below the floor)`` per tendon."""

Planner = Callable[[int], tuple[MovePlan, MoveShaping]]
"""``planner(prepull) -> (plan, shaping)``: the move planned and designed from the pre-pulled rest."""


def dynamic_floor(
    plan: MovePlan,
    shaping: MoveShaping,
    simulate: Simulator,
    planner: Planner,
    redesign: Callable[[MovePlan, str, int], MoveShaping],
) -> FloorCheck:
    """Simulate the shaped move; where a tendon dips below the floor, change the pretension, then the design.

    The policy (module docstring): as planned; then every tendon pulled in 1 .. :data:`MAX_PREPULL_STEPS`
    steps before the move (``planner(k)`` plans and designs from that rest; a plan the statics refuse stops
    the raising); then, at the best pretension, each family of :data:`ROBUST_CHAIN` longer than the design
    (``redesign(plan, family_name, k)``). The first attempt with no sample below the floor is taken; if none,
    the attempt with the highest least tension, ``ok`` False. An unshaped move is simulated and reported,
    never changed. :func:`floor_check` wires it to the spatial twin.
    """
    floor = float(plan.floor_n)
    attempts: list[str] = []

    def run(p: MovePlan, s: MoveShaping, k: int, what: str) -> tuple[np.ndarray, np.ndarray]:
        least, below = (np.asarray(v) for v in simulate(p, s.shaper, k))
        attempts.append(f"{what}: least {least.min():.2f} N (tendon {int(np.argmin(least)) + 1}), "
                        f"{int(below.sum())} samples below the floor")  # fmt: skip
        return least, below

    def done(p, s, k, least, below, changed):
        return FloorCheck(p, s, k, tuple(map(float, least)), tuple(map(int, below)), floor, changed,
                          bool(below.sum() == 0), tuple(attempts))  # fmt: skip

    least, below = run(plan, shaping, 0, f"as planned ({shaping.name})")
    if below.sum() == 0 or shaping.shaper is None:
        return done(plan, shaping, 0, least, below, "nothing")
    best = (plan, shaping, 0, least, below, "nothing")
    for k in range(1, MAX_PREPULL_STEPS + 1):  # 1. the pretension
        try:
            p, s = planner(k)
        except (SafetyError, ValueError) as exc:
            attempts.append(f"every tendon +{k} step(s) before the move: refused ({exc})")
            break
        least, below = run(p, s, k, f"every tendon +{k} step(s) before the move")
        if least.min() > best[3].min():
            best = (p, s, k, least, below, "pretension")
        if below.sum() == 0:
            return done(p, s, k, least, below, "pretension")
    p0, _, k0, *_ = best
    for fam in ROBUST_CHAIN:  # 2. the design: longer, more robust, at the best pretension found
        s = redesign(p0, fam, k0)
        if s.duration_s <= shaping.duration_s + 1e-9:
            continue
        least, below = run(p0, s, k0, f"the design {fam}" + (f" with +{k0} step(s)" if k0 else ""))
        changed = "pretension and design" if k0 else "design"
        if least.min() > best[3].min():
            best = (p0, s, k0, least, below, changed)
        if below.sum() == 0:
            return done(p0, s, k0, least, below, changed)
    p, s, k, least, below, changed = best
    return done(p, s, k, least, below, changed)


MAX_PREPULL_STEPS = 2
"""Most steps the dynamic floor pulls every tendon in before the move (one step: about +5 N on each)."""

ROBUST_CHAIN = ("ZVD", "ZVDD", "3-hump EI")
"""The longer, more robust families the dynamic floor tries, in order, after the pretension."""


def floor_check(
    rig: RigFile,
    plan: MovePlan,
    shaping: MoveShaping,
    speed_mm_s: float = 200.0,
    times: tuple[float, float, float] = (1.0, 8.0, 12.0),
    twin: SpatialRig | None = None,
    grid: ModeGrid | None = None,
) -> FloorCheck:
    """:func:`dynamic_floor` on the spatial twin: the programme ``times`` = ``(t_up, t_down, t_end)``.

    A pre-pulled move is planned (:func:`~helpers.research.task_space.plan_move`) and designed
    (:func:`design_move`, the same name; modes of the pre-pulled twin, the grid ignored) from the rest with
    every tendon ``k`` steps in (:func:`pretensioned`); the simulation runs the original twin from its rest.
    """
    twin = spatial_rig(rig) if twin is None else twin
    plant = SpatialPlant(twin)

    def simulate(p: MovePlan, s: Shaper | None, k: int) -> tuple[np.ndarray, np.ndarray]:
        run = simulate_move(rig, p, s, speed_mm_s, *times, twin=twin, plant=plant, prepull=k)
        return run.least_n(), run.below(p.floor_n)

    def planner(k: int) -> tuple[MovePlan, MoveShaping]:
        pre = pretensioned(rig, twin, k)
        p = plan_move(rig, plan.direction_deg, plan.bend_mm, spatial=pre)
        return p, design_move(rig, p, shaping.name, speed_mm_s, twin=pre)

    def redesign(p: MovePlan, family_name: str, k: int) -> MoveShaping:
        pre = pretensioned(rig, twin, k)
        name = next(n for n, f in FAMILY_OF.items() if f == family_name)
        return design_move(rig, p, name, speed_mm_s, twin=pre, grid=grid if k == 0 else None)

    return dynamic_floor(plan, shaping, simulate, planner, redesign)


@dataclass(frozen=True)
class ShapedMove:
    """A move ready to run: its plan, its design, the dynamic floor's check and the programme.

    ``start`` is where every tendon stands when the move's own programme starts (``prepull`` steps in; the
    plan's steps count from there); ``check`` is None when the floor check was not asked for.
    """

    plan: MovePlan
    shaping: MoveShaping
    check: FloorCheck | None
    programme: Programme
    prepull: int

    @property
    def start(self) -> tuple[int, ...]:
        """Every tendon's position when the bend starts (after a pre-pull)."""
        return (self.prepull,) * len(self.plan.steps)

    def lines(self) -> list[str]:
        """The design (and its duration) and the dynamic floor's report, one item a line."""
        out = [f"shaper: {self.shaping.describe()}"]
        if self.check is None:
            out.append("dynamic floor: not checked (--no-floor-check)")
        else:
            out += self.check.lines()
        return out

    def metadata(self) -> dict[str, object]:
        """The design and the floor check for a recording's scenario."""
        meta: dict[str, object] = {"design": self.shaping.metadata(), "prepull_steps": self.prepull}
        if self.check is not None:  # skipped (--no-floor-check): no key, as docs/recording_format.md has it
            meta["floor_check"] = self.check.metadata()
        return meta


def shaped_move(
    rig: RigFile,
    direction_deg: float,
    bend_mm: float,
    shaper: str = "none",
    speed_mm_s: float = 200.0,
    times: tuple[float, float, float] = (1.0, 8.0, 12.0),
    grid: ModeGrid | None = None,
    check_floor: bool = True,
    verify: bool = True,
) -> ShapedMove:
    """Plan, design, check the dynamic floor (changing pretension or design) and build the programme.

    The command line's ``record move`` (``docs/task_space.md``): :func:`plan_move`, :func:`design_move`, then
    :func:`floor_check` (unless ``check_floor`` is False), for ``auto`` :func:`verify_auto` (unless ``verify``
    is False) and the programme of what they settled on (:func:`~helpers.research.task_space.move_programme`
    inside :func:`prepull_programme`).
    """
    twin = spatial_rig(rig)
    plan = as_planned = plan_move(rig, direction_deg, bend_mm, spatial=twin)
    shaping = design_move(rig, plan, shaper, speed_mm_s, grid=grid, twin=twin)
    check = None
    prepull = 0
    if check_floor:
        check = floor_check(rig, plan, shaping, speed_mm_s, times, twin=twin, grid=grid)
        plan, shaping, prepull = check.plan, check.shaping, check.prepull
    if shaping.name == "auto" and verify:
        linear = shaping.shaper
        shaping = verify_auto(rig, plan, shaping, speed_mm_s, prepull, twin=twin, unshaped_plan=as_planned)
        if check is not None and shaping.shaper != linear:  # the floor's figures of what will run
            run = simulate_move(rig, plan, shaping.shaper, speed_mm_s, *times, twin=twin, prepull=prepull)
            least, below = run.least_n(), run.below(plan.floor_n)
            line = (f"the simulated choice {shaping.shaper.name}: least {least.min():.2f} N (tendon "
                    f"{int(np.argmin(least)) + 1}), {int(below.sum())} samples below the floor")  # fmt: skip
            check = dataclasses.replace(
                check, shaping=shaping, least_n=tuple(map(float, least)), below_floor=tuple(map(int, below)),
                ok=bool(below.sum() == 0), attempts=(*check.attempts, line),
            )  # fmt: skip
    prog = move_programme(plan, rig, speed_mm_s, shaping.shaper, *times)
    prog, _, _ = prepull_programme(prog, prepull, rig.n_tendons)
    return ShapedMove(plan, shaping, check, prog, prepull)


TABLE_POINTS = ((0.0, 10.0), (0.0, 20.0), (22.5, 10.0), (22.5, 20.0), (45.0, 10.0), (45.0, 20.0))
"""The bends of :func:`residual_table` (direction deg, bend mm)."""

TABLE_SHAPERS = ("none", "zv", "zvd", "fixed", "scheduled", "multimode", "auto")
"""The designs of :func:`residual_table`."""


def residual_table(
    rig: RigFile,
    points: Sequence[tuple[float, float]] = TABLE_POINTS,
    names: Sequence[str] = TABLE_SHAPERS,
    grid: ModeGrid | None = None,
    speed_mm_s: float = 200.0,
    times: tuple[float, float, float] = (1.0, 8.0, 12.0),
    floor: bool = True,
) -> pd.DataFrame:
    """Residual vibration and least tensions of designed moves in the spatial twin (**simulated**).

    For each bend and design: the move as designed (:func:`simulate_move`, :func:`residuals`; ``zv``/``zvd``
    and the families at the move, ``scheduled``/``multimode``/``auto`` on ``grid`` if given) and, with
    ``floor``, the move after the dynamic floor's change (:func:`shaped_move`), simulated again.

    Returns
    -------
    pandas.DataFrame
        ``direction_deg, bend_mm, shaper, design, duration_s, predicted_pct, tip_mm, tip_pct`` (of the
        unshaped move's at that bend), ``p2p{i}_n``, ``worst_p2p_pct`` (the tendon whose peak to peak is the
        largest share of its unshaped one), ``least_n`` (any tendon), ``below_floor`` (samples, every tendon);
        with ``floor``, the move as :func:`shaped_move` settles it (the dynamic floor's change, the simulated
        automatic choice): ``changed``, ``prepull``, ``run_design``, ``run_duration_s``, ``run_tip_pct``,
        ``run_worst_p2p_pct``, ``run_least_n``, ``run_below_floor``; ``wall_s`` (every simulation of the row).
    """
    twin = spatial_rig(rig)
    plant = SpatialPlant(twin)
    rows = []
    for beta, bend in points:
        plan = plan_move(rig, beta, bend, spatial=twin)
        base: dict[str, object] | None = None
        for name in names:
            started = time.perf_counter()
            use = grid if name in ("scheduled", "multimode", "auto") else None
            shaping = design_move(rig, plan, name, speed_mm_s, grid=use, twin=twin)
            run = simulate_move(rig, plan, shaping.shaper, speed_mm_s, *times, twin=twin, plant=plant)
            r = residuals(run, plan.floor_n)
            if base is None:
                if name != "none":
                    unshaped = simulate_move(rig, plan, None, speed_mm_s, *times, twin=twin, plant=plant)
                    base = residuals(unshaped, plan.floor_n)
                else:
                    base = r
            p2p = np.array(r["tension_p2p_n"])
            ref = np.array(base["tension_p2p_n"])
            row: dict[str, object] = {
                "direction_deg": beta, "bend_mm": bend, "shaper": name,
                "design": "unshaped" if shaping.shaper is None else shaping.shaper.name,
                "duration_s": shaping.duration_s, "predicted_pct": shaping.predicted_pct,
                "tip_mm": r["tip_mm"], "tip_pct": 100 * r["tip_mm"] / base["tip_mm"],
            }  # fmt: skip
            row.update({f"p2p{i + 1}_n": float(v) for i, v in enumerate(p2p)})
            row["worst_p2p_pct"] = float(100 * np.max(p2p / ref))
            row["least_n"] = float(min(r["least_n"]))
            row["below_floor"] = int(sum(r["below_floor"]))
            if floor:
                move = shaped_move(rig, beta, bend, name, speed_mm_s, times, grid=use)
                ran = "unshaped" if move.shaping.shaper is None else move.shaping.shaper.name
                changed = move.check.changed if move.check is not None else "nothing"
                row.update({"changed": changed, "prepull": move.prepull, "run_design": ran,
                            "run_duration_s": move.shaping.duration_s})  # fmt: skip
                again = simulate_move(rig, move.plan, move.shaping.shaper, speed_mm_s, *times, twin=twin,
                                      plant=plant, prepull=move.prepull)  # fmt: skip
                q = residuals(again, plan.floor_n)
                row.update({
                    "run_tip_pct": 100 * q["tip_mm"] / base["tip_mm"],
                    "run_worst_p2p_pct": float(100 * np.max(np.array(q["tension_p2p_n"]) / ref)),
                    "run_least_n": float(min(q["least_n"])),
                    "run_below_floor": int(sum(q["below_floor"])),
                })  # fmt: skip
            row["wall_s"] = time.perf_counter() - started
            rows.append(row)
    return pd.DataFrame(rows)


def benchmark(
    rig: RigFile, direction_deg: float = 45.0, bend_mm: float = 20.0, seconds: float = 4.0
) -> float:
    """Wall seconds per simulated second of a shaped move in the spatial twin (after one warm-up run).

    Prints and returns the figure (a machine's, not a test's: nothing asserts it).
    """
    plan = plan_move(rig, direction_deg, bend_mm)
    twin = spatial_rig(rig)
    plant = SpatialPlant(twin)
    shaping = design_move(rig, plan, "zvd", twin=twin)
    times = (0.2, seconds / 2, seconds)
    simulate_move(rig, plan, shaping.shaper, 200.0, *times, twin=twin, plant=plant)  # compile and warm up
    run = simulate_move(rig, plan, shaping.shaper, 200.0, *times, twin=twin, plant=plant)
    ratio = run.wall_s / seconds
    print(f"spatial twin (simulated): {run.wall_s:.2f} s of wall time for {seconds:g} s of a ZVD move "
          f"{bend_mm:g} mm towards {direction_deg:g} deg: {ratio:.3f} wall s per simulated s")  # fmt: skip
    return ratio
