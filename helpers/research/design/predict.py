"""The predicted residual of a shaper over the band a move sweeps and the map's uncertainty.

**Predicted residual.** For a shaper with impulses ``A_i`` at ``t_i`` and one mode ``(omega_n, zeta)`` the
residual vibration relative to the unshaped move is Singer and Seering's ``V`` (:meth:`Shaper.vibration`).
At a point of the mode map with a second mode of share ``s`` (the fraction of the unshaped residual
amplitude the second mode carries) the prediction is the share-weighted sum

    V_pred = (1 - s) V(omega_n1, zeta1) + s V(omega_n2, zeta2),

the residual amplitude bound of the two modes together relative to the unshaped move's (without a second
mode, ``V_pred = V(omega_n1, zeta1)``). Results are given in percent.

**Band and uncertainty.** A move from ``x_a`` to ``x_b`` sweeps the cable positions between them. Its
:class:`Band` is the set of map points a design must hold over:

- positions: the measured positions strictly inside ``[x_a, x_b]``, the two ends, and ``n_between``
  (default :data:`DEFAULT_N_BETWEEN`) evenly spaced positions between consecutive ones, where the map is
  interpolated (:meth:`helpers.research.modemap.ModeMap.at`);
- at each position, each mode's frequency and damping at the nominal value and ``coverage`` (default
  :data:`DEFAULT_COVERAGE`) standard errors either side: ``omega_d + k se * {-1, 0, 1}`` crossed with
  ``zeta + k se * {-1, 0, 1}`` (nine points per mode; damping clipped to ``[0, 0.99]``, frequency to > 0),
  and the share at ``s -/+ k se`` (clipped to ``[0, 0.99]``).

The **worst predicted residual** at a position is ``max over shares of (1 - s) max V1 + s max V2`` (the modes'
uncertainties are independent); over the band it is the largest of these. It is what the minimax design
minimises and what the automatic choice compares with the tolerance (default :data:`DEFAULT_TOLERANCE_PCT`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from helpers.paper.shapers import Shaper
from helpers.research.design.formats import Design, Schedule, Shaping, up_down
from helpers.research.modemap import ModeMap

DEFAULT_TOLERANCE_PCT = 5.0
"""Default tolerance of the automatic choice: 5 % predicted residual."""

DEFAULT_COVERAGE = 2.0
"""Default coverage factor ``k``: the map's values +- 2 standard errors (about 95 % for a normal estimate)."""

DEFAULT_N_BETWEEN = 2
"""Default number of interpolated positions between consecutive measured ones."""

ZETA_CLIP = 0.99
"""Upper clip of a damping ratio (or share) moved by its uncertainty."""

_CORNERS = np.array([(a, b) for a in (-1.0, 0.0, 1.0) for b in (-1.0, 0.0, 1.0)])


def _corners(omega_d: np.ndarray, omega_se: np.ndarray, zeta: np.ndarray, zeta_se: np.ndarray, k: float):
    """(omega_n, zeta) at the nine uncertainty corners of each position: arrays (P, 9)."""
    wd = omega_d[:, None] + k * omega_se[:, None] * _CORNERS[None, :, 0]
    wd = np.maximum(wd, 1e-6 * omega_d[:, None])
    z = np.clip(zeta[:, None] + k * zeta_se[:, None] * _CORNERS[None, :, 1], 0.0, ZETA_CLIP)
    return wd / np.sqrt(1.0 - z**2), z


@dataclass(frozen=True)
class Band:
    """The points a design must hold over for one move (see the module docstring).

    Attributes
    ----------
    low_mm, high_mm : float
        The cable positions the move sweeps.
    positions_mm : numpy.ndarray
        The positions evaluated, shape ``(P,)``.
    omega_d, zeta : numpy.ndarray
        The dominant mode's nominal values there.
    omega_n1, zeta1 : numpy.ndarray
        Shape ``(P, 9)``: the dominant mode at the uncertainty corners.
    omega_n2, zeta2 : numpy.ndarray or None
        Shape ``(P, 9)``: the second mode at its corners.
    shares : numpy.ndarray or None
        Shape ``(P, 2)``: the second mode's share at ``-k`` and ``+k`` standard errors.
    coverage : float
        The coverage factor ``k``.
    """

    low_mm: float
    high_mm: float
    positions_mm: np.ndarray
    omega_d: np.ndarray
    zeta: np.ndarray
    omega_n1: np.ndarray
    zeta1: np.ndarray
    omega_n2: np.ndarray | None
    zeta2: np.ndarray | None
    shares: np.ndarray | None
    coverage: float

    @property
    def omega_n_range(self) -> tuple[float, float]:
        """Lowest and highest dominant-mode undamped frequency over the points (rad/s)."""
        return float(self.omega_n1.min()), float(self.omega_n1.max())

    @property
    def omega_n2_range(self) -> tuple[float, float] | None:
        """Lowest and highest second-mode undamped frequency (rad/s), or None."""
        if self.omega_n2 is None:
            return None
        return float(self.omega_n2.min()), float(self.omega_n2.max())

    def centre(self) -> tuple[float, float]:
        """The dominant mode at the band's centre: ``(omega_n, zeta)``.

        ``omega_n`` is the midpoint of the lowest and highest undamped frequency over the points (uncertainty
        included); ``zeta`` the mean of the nominal damping ratios.
        """
        lo, hi = self.omega_n_range
        return 0.5 * (lo + hi), float(np.mean(self.zeta1[:, 4]))

    def centre2(self) -> tuple[float, float] | None:
        """The second mode at the band's centre (as :meth:`centre`), or None."""
        rng = self.omega_n2_range
        if rng is None:
            return None
        return 0.5 * (rng[0] + rng[1]), float(np.mean(self.zeta2[:, 4]))  # type: ignore[index]

    def as_dict(self) -> dict[str, float | int]:
        """A JSON-safe summary for provenance."""
        out: dict[str, float | int] = {
            "low_mm": self.low_mm,
            "high_mm": self.high_mm,
            "n_positions": int(self.positions_mm.size),
            "coverage": self.coverage,
            "omega_n_min": self.omega_n_range[0],
            "omega_n_max": self.omega_n_range[1],
        }
        if self.omega_n2_range is not None:
            out["omega_n2_min"], out["omega_n2_max"] = self.omega_n2_range
        return out


def band(
    mode_map: ModeMap,
    start_mm: float,
    end_mm: float,
    coverage: float = DEFAULT_COVERAGE,
    n_between: int = DEFAULT_N_BETWEEN,
) -> Band:
    """The :class:`Band` of a move from ``start_mm`` to ``end_mm`` (see the module docstring).

    Parameters
    ----------
    mode_map : ModeMap
        The measured map; the move must lie inside its range.
    start_mm, end_mm : float
        The move's ends (either order), mm.
    coverage : float
        Standard errors either side, >= 0.
    n_between : int
        Interpolated positions between consecutive ones.

    Returns
    -------
    Band
    """
    if not (isinstance(coverage, int | float) and np.isfinite(coverage) and coverage >= 0):
        raise ValueError(f"coverage must be a finite number >= 0 (standard errors), got {coverage!r}")
    low, high = mode_map.sweep(start_mm, end_mm)
    x = mode_map.positions_in(low, high, n_between)
    p = mode_map.at(x)
    k = float(coverage)
    wn1, z1 = _corners(p.omega_d, p.omega_d_se, p.zeta, p.zeta_se, k)
    wn2 = z2 = shares = None
    if mode_map.has_second_mode:
        wn2, z2 = _corners(p.omega_d2, p.omega_d2_se, p.zeta2, p.zeta2_se, k)
        shares = np.clip(p.share2[:, None] + k * p.share2_se[:, None] * np.array([-1.0, 1.0]), 0.0, ZETA_CLIP)
    return Band(low, high, x, p.omega_d, p.zeta, wn1, z1, wn2, z2, shares, k)


def residual_by_position(shaper: Shaper, b: Band) -> pd.DataFrame:
    """The predicted residual of ``shaper`` at each position of band ``b``, in percent.

    Returns
    -------
    pandas.DataFrame
        ``position_mm``, ``omega_d_rad_s`` (nominal), ``v1_nominal_pct`` (dominant mode, nominal values),
        ``v1_worst_pct`` (over its uncertainty corners), ``v2_worst_pct`` (second mode; NaN without one) and
        ``worst_pct`` (the share-weighted worst, see the module docstring).
    """
    v1 = np.asarray(shaper.vibration(b.omega_n1, b.zeta1))
    v1_worst = v1.max(axis=1)
    if b.omega_n2 is None:
        v2_worst = np.full(v1_worst.shape, np.nan)
        worst = v1_worst
    else:
        v2_worst = np.asarray(shaper.vibration(b.omega_n2, b.zeta2)).max(axis=1)
        worst = np.max((1.0 - b.shares) * v1_worst[:, None] + b.shares * v2_worst[:, None], axis=1)
    return pd.DataFrame(
        {
            "position_mm": b.positions_mm,
            "omega_d_rad_s": b.omega_d,
            "v1_nominal_pct": 100.0 * v1[:, 4],
            "v1_worst_pct": 100.0 * v1_worst,
            "v2_worst_pct": 100.0 * v2_worst,
            "worst_pct": 100.0 * worst,
        }
    )


def worst_residual_pct(shaper: Shaper, b: Band) -> float:
    """The worst predicted residual (percent) of ``shaper`` over band ``b``."""
    return float(residual_by_position(shaper, b)["worst_pct"].max())


def move_bands(
    mode_map: ModeMap,
    x_f_mm: float,
    start_mm: float = 0.0,
    coverage: float = DEFAULT_COVERAGE,
    n_between: int = DEFAULT_N_BETWEEN,
) -> dict[str, Band]:
    """The bands of a pulse experiment's two moves: ``{"up": ..., "down": ...}``.

    The Up move goes from ``start_mm`` to ``start_mm + x_f_mm`` and the Down move back, so both sweep the same
    positions; they are returned separately so that a pair is judged move by move.
    """
    b = band(mode_map, start_mm, start_mm + float(x_f_mm), coverage, n_between)
    return {"up": b, "down": b}


def predicted_residual(
    shaping: Shaping | Design,
    mode_map: ModeMap,
    x_f_mm: float,
    start_mm: float = 0.0,
    coverage: float = DEFAULT_COVERAGE,
    n_between: int = DEFAULT_N_BETWEEN,
) -> pd.DataFrame:
    """The predicted residual of a shaper or pair, move by move and position by position (percent).

    Parameters
    ----------
    shaping : Shaper, ShaperPair or Design of either
        What to judge. A map-following schedule has no predicted residual in this sense (it is no
        convolution): judge it on the time-varying model, :mod:`helpers.research.design.timevarying`.
    mode_map : ModeMap
        The map.
    x_f_mm, start_mm : float
        The move (mm).
    coverage, n_between
        As :func:`band`.

    Returns
    -------
    pandas.DataFrame
        The columns of :func:`residual_by_position` and ``move`` (``up``/``down``) first.
    """
    up, down = _shapers_of(shaping)
    bands = move_bands(mode_map, x_f_mm, start_mm, coverage, n_between)
    frames = [residual_by_position(s, bands[m]).assign(move=m) for m, s in (("up", up), ("down", down))]
    out = pd.concat(frames, ignore_index=True)
    return out[["move", *[c for c in out.columns if c != "move"]]]


def worst_predicted_pct(
    shaping: Shaping | Design,
    mode_map: ModeMap,
    x_f_mm: float,
    start_mm: float = 0.0,
    coverage: float = DEFAULT_COVERAGE,
    n_between: int = DEFAULT_N_BETWEEN,
) -> float:
    """The worst predicted residual (percent) of a shaper or pair over both moves (module docstring)."""
    table = predicted_residual(shaping, mode_map, x_f_mm, start_mm, coverage, n_between)
    return float(table["worst_pct"].max())


def _shapers_of(shaping: Shaping | Design) -> tuple[Shaper, Shaper]:
    inner = shaping.shaping if isinstance(shaping, Design) else shaping
    if isinstance(inner, Schedule):
        raise ValueError(
            "a map-following schedule has no convolution residual: judge it with "
            "helpers.research.design.timevarying.time_varying_residual"
        )
    up, down = up_down(inner)
    if up is None or down is None:
        raise ValueError(f"not a shaper or pair: {shaping!r}")
    return up, down
