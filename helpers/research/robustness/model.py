"""The uncertainty a user of the arm faces, as a distribution of modes, and a shaper's residual under it.

What varies between the mode a shaper was designed for and the mode it meets:

- **where the residual rings.** A pulse's Up move leaves its residual at its destination ``x`` and the Down
  move at rest (``0``); the frequency there is the **mode map**'s. The amplitude ``x`` is uniform over the
  moves a user commands (default the paper's Table I range, 10-30 mm; the speed, 200-300 mm/s, does not
  enter the linear model). Both moves count equally: every draw gives an Up and a Down residual.
- **the identification's standard errors.** The rest frequency a shaper is designed from was identified
  with a standard error: the true frequency is the map's times ``1 + e``, ``e ~ N(0, se / omega_d)``; a
  measured map's own standard error adds ``N(0, se_map(x))`` (0 for a predicted map).
- **damping**: a stated prior, uniform in ``zeta_prior`` (default 0.02-0.08, a factor two either side of the
  identified 0.044), because one identification at rest says little about the damping of other positions,
  amplitudes and days. The identified damping ratio is only the designs' input.

The distribution is fixed before any design is judged by it and favours none. :func:`uncertainty_model` is
the one place that chooses the map: the map given, else :func:`default_map` (the measured map of
``data/tuning/mode_map.json`` when the repository has one, else the virtual rig's predicted map). With a
second mode in the map, its frequency carries the same identification error, its damping ratio moves with the
dominant mode's (the map's ratio times the drawn one over the map's dominant one: the rig's damping scales
as a whole) and its share is the map's, with its standard error.

On the **linear model** a shaper's residual for a draw is Singer and Seering's ``V``
(:meth:`helpers.paper.shapers.Shaper.vibration`) at the draw's mode, in percent of the unshaped move's (with a
second mode and its share, the predicted-residual rule ``(1 - s) V1 + s V2`` of ``docs/shaper_design.md``).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from scipy.stats import norm, qmc

from helpers.base.paths import DATA_DIR, stored_table
from helpers.paper.identify import IdentifiedMode, load_identification
from helpers.paper.shapers import Shaper
from helpers.research.modemap import ModeMap, load_map

__all__ = [
    "MEASURED_MAP",
    "PREDICTED_MAP_TABLE",
    "PREDICTED_RANGE_MM",
    "UncertaintyModel",
    "UncertaintySample",
    "default_map",
    "predicted_map",
    "uncertainty_model",
    "linear_residual_pct",
    "percentile_pct",
]

MEASURED_MAP = DATA_DIR / "tuning" / "mode_map.json"
"""The measured frequency map (``python -m helpers tune``: a kick and two ring-downs per position, two modes
identified from each, with standard errors and the second mode's share)."""

PREDICTED_MAP_TABLE = "virtual_frequency_map.csv"
"""The virtual rig's predicted frequency map in ``figures/`` (notebook 06, ``helpers.virtual.statics``)."""

PREDICTED_RANGE_MM = (0.0, 35.0)
"""Positions of the predicted map used: beyond about 37 mm the second mode dominates the tension."""

DEFAULT_ZETA_PRIOR = (0.02, 0.08)
"""The stated damping prior (uniform)."""

DEFAULT_AMPLITUDE_MM = (10.0, 30.0)
"""Move amplitudes a user commands (uniform): the paper's Table I range."""

DEFAULT_SPEED_MM_S = (200.0, 300.0)
"""Move speeds a user commands (uniform): the paper's Table I range."""


def predicted_map(share2: float | None = None) -> ModeMap:
    """The virtual rig's predicted frequency map as a :class:`~helpers.research.modemap.ModeMap`.

    The dominant mode of the rig as it runs (rotor free: ``dominant_omega_d_rad_s``, ``dominant_zeta`` of
    ``figures/virtual_frequency_map.csv``), 0-35 mm every millimetre, no standard errors. The second mode
    (``omega_d2_rad_s``, ``zeta2``, spool held) is kept only when its share of the residual is given.

    Parameters
    ----------
    share2 : float, optional
        The second mode's share of the unshaped residual amplitude (a prediction has none of its own).

    Returns
    -------
    ModeMap
    """
    table = pd.read_csv(stored_table(PREDICTED_MAP_TABLE))
    lo, hi = PREDICTED_RANGE_MM
    rows = table[(table["u_mm"] >= lo) & (table["u_mm"] <= hi)]
    df = pd.DataFrame(
        {
            "position_mm": rows["u_mm"].to_numpy(float),
            "omega_d_rad_s": rows["dominant_omega_d_rad_s"].to_numpy(float),
            "zeta": rows["dominant_zeta"].to_numpy(float),
            "omega_d2_rad_s": rows["omega_d2_rad_s"].to_numpy(float),
            "zeta2": rows["zeta2"].to_numpy(float),
        }
    )
    source = {
        "kind": "virtual-rig",
        "method": "predicted: linearisation of the virtual rig, the tension-dominant mode with the rotor "
        f"free (figures/{PREDICTED_MAP_TABLE}, {lo:g}-{hi:g} mm)",
    }
    return ModeMap.from_table(df, source, share2=share2)


def default_map(share2_if_predicted: float | None = None) -> ModeMap:
    """The map the designs and the uncertainty use by default: the measured one, else the predicted one.

    The measured map (:data:`MEASURED_MAP`) when the repository has one; otherwise the virtual rig's
    predicted map (:func:`predicted_map`, with ``share2_if_predicted`` as its second mode's share). The map's
    ``source`` says which.
    """
    if MEASURED_MAP.exists():
        return load_map(MEASURED_MAP)
    return predicted_map(share2_if_predicted)


@dataclass(frozen=True)
class UncertaintySample:
    """Draws from an :class:`UncertaintyModel`: one Up and one Down residual case per draw.

    Arrays of the cases (length ``2 n``, the Up case of draw ``i`` at ``2 i``, its Down case at ``2 i + 1``):
    ``move`` (``"up"``/``"down"``), ``position_mm`` (where the residual rings), ``omega_n`` (rad/s),
    ``zeta``, and, with a second mode, ``omega_n2``, ``zeta2``, ``share2`` (else None). Arrays of the draws
    (length ``n``): ``amplitude_mm``, ``speed_mm_s``, ``identification_error`` (the relative frequency error
    ``e`` of the identified rest frequency).
    """

    move: np.ndarray
    position_mm: np.ndarray
    omega_n: np.ndarray
    zeta: np.ndarray
    amplitude_mm: np.ndarray
    speed_mm_s: np.ndarray
    identification_error: np.ndarray
    omega_n2: np.ndarray | None = None
    zeta2: np.ndarray | None = None
    share2: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.omega_n.size)

    @property
    def is_up(self) -> np.ndarray:
        """True for the Up cases."""
        return self.move == "up"


@dataclass(frozen=True)
class UncertaintyModel:
    """The distribution of the mode a shaper meets (module docstring).

    Attributes
    ----------
    mode_map : ModeMap
        The frequency map (measured, or the predicted one).
    identified : IdentifiedMode
        The identified rest mode (the designs' input) and its standard errors.
    zeta_prior : (float, float)
        Uniform prior of the damping ratio.
    amplitude_mm, speed_mm_s : (float, float)
        Uniform ranges of the commanded moves.
    """

    mode_map: ModeMap
    identified: IdentifiedMode
    zeta_prior: tuple[float, float] = DEFAULT_ZETA_PRIOR
    amplitude_mm: tuple[float, float] = DEFAULT_AMPLITUDE_MM
    speed_mm_s: tuple[float, float] = DEFAULT_SPEED_MM_S

    def __post_init__(self) -> None:
        for name in ("zeta_prior", "amplitude_mm", "speed_mm_s"):
            lo, hi = (float(v) for v in getattr(self, name))
            if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo <= hi):
                raise ValueError(f"uncertainty model: {name} must be a range 0 <= low <= high, got {lo, hi}")
            object.__setattr__(self, name, (lo, hi))
        if self.zeta_prior[1] >= 1:
            raise ValueError(f"uncertainty model: zeta_prior must lie below 1, got {self.zeta_prior}")
        self.mode_map.sweep(0.0, self.amplitude_mm[1])  # the moves must lie inside the map

    @property
    def identification_sigma(self) -> float:
        """Relative standard error of the identified rest frequency (0 if it has none)."""
        se = self.identified.omega_d_std
        return 0.0 if not math.isfinite(se) else float(se / self.identified.omega_d)

    def describe(self) -> dict[str, Any]:
        """The model as JSON-safe data (for a sweep's or a notebook's record)."""
        return {
            "map_source": dict(self.mode_map.source),
            "map_range_mm": list(self.mode_map.range_mm),
            "map_has_standard_errors": bool(np.any(self.mode_map.omega_d_se > 0)),
            "second_mode": self.mode_map.has_second_mode,
            "identified_omega_d": self.identified.omega_d,
            "identified_zeta": self.identified.zeta,
            "identification_sigma": self.identification_sigma,
            "zeta_prior": list(self.zeta_prior),
            "amplitude_mm": list(self.amplitude_mm),
            "speed_mm_s": list(self.speed_mm_s),
        }

    def sample(self, n: int, seed: int = 0) -> UncertaintySample:
        """``n`` draws (scrambled Halton points, so a modest ``n`` covers the space evenly), deterministic.

        Parameters
        ----------
        n : int
            Draws (each gives an Up and a Down case).
        seed : int
            Seed of the scrambling.

        Returns
        -------
        UncertaintySample
        """
        if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
            raise ValueError(f"n must be a positive integer, got {n!r}")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            u = qmc.Halton(d=8, scramble=True, seed=seed).random(int(n))
        u = np.clip(u, 1e-12, 1 - 1e-12)
        amp = self.amplitude_mm[0] + (self.amplitude_mm[1] - self.amplitude_mm[0]) * u[:, 0]
        speed = self.speed_mm_s[0] + (self.speed_mm_s[1] - self.speed_mm_s[0]) * u[:, 1]
        z_lo, z_hi = self.zeta_prior
        zeta_up = z_lo + (z_hi - z_lo) * u[:, 2]
        zeta_down = z_lo + (z_hi - z_lo) * u[:, 3]
        e_id = self.identification_sigma * norm.ppf(u[:, 4])
        e_map = norm.ppf(u[:, 5])
        pos = np.column_stack([amp, np.zeros(n)]).ravel()
        zeta = np.column_stack([zeta_up, zeta_down]).ravel()
        e_id2 = np.repeat(e_id, 2)
        m = self.mode_map.at(pos)
        omega_d = np.asarray(m.omega_d) * (1.0 + e_id2) + e_map.repeat(2) * np.asarray(m.omega_d_se)
        omega_n = omega_d / np.sqrt(1.0 - zeta**2)
        second: dict[str, Any] = {}
        if self.mode_map.has_second_mode:
            # the rig's damping scales as a whole: the second mode's ratio moves with the dominant one's
            z2 = np.clip(np.asarray(m.zeta2) * zeta / np.asarray(m.zeta), 0.0, 0.99)
            wd2 = np.asarray(m.omega_d2) * (1.0 + e_id2) + norm.ppf(u[:, 6]).repeat(2) * np.asarray(
                m.omega_d2_se
            )
            share = np.asarray(m.share2) + norm.ppf(u[:, 7]).repeat(2) * np.asarray(m.share2_se)
            second = {
                "omega_n2": wd2 / np.sqrt(1.0 - z2**2),
                "zeta2": z2,
                "share2": np.clip(share, 0.0, 0.99),
            }
        move = np.tile(np.array(["up", "down"]), n)
        return UncertaintySample(move, pos, omega_n, zeta, amp, speed, e_id, **second)


def uncertainty_model(
    mode_map: ModeMap | None = None,
    identified: IdentifiedMode | None = None,
    zeta_prior: tuple[float, float] = DEFAULT_ZETA_PRIOR,
    amplitude_mm: tuple[float, float] = DEFAULT_AMPLITUDE_MM,
    speed_mm_s: tuple[float, float] = DEFAULT_SPEED_MM_S,
) -> UncertaintyModel:
    """The uncertainty a user faces: the one function that chooses the map (module docstring).

    Parameters
    ----------
    mode_map : ModeMap, optional
        The measured frequency map (``helpers.research.modemap.load_map``). Default: the virtual rig's
        **predicted**
        map (:func:`predicted_map`), until a measured map exists; pass the measured one to switch.
    identified : IdentifiedMode, optional
        Default: ``data/identification/result.json``.
    zeta_prior, amplitude_mm, speed_mm_s : (float, float)
        The damping prior and the commanded moves' ranges.

    Returns
    -------
    UncertaintyModel
    """
    return UncertaintyModel(
        mode_map=default_map() if mode_map is None else mode_map,
        identified=load_identification() if identified is None else identified,
        zeta_prior=zeta_prior,
        amplitude_mm=amplitude_mm,
        speed_mm_s=speed_mm_s,
    )


def _shapers_of(shaping: Any) -> tuple[Shaper, Shaper]:
    """(Up, Down) shapers of a Shaper or of anything with ``up`` and ``down`` shapers (a pair)."""
    if isinstance(shaping, Shaper):
        return shaping, shaping
    up, down = getattr(shaping, "up", None), getattr(shaping, "down", None)
    if isinstance(up, Shaper) and isinstance(down, Shaper):
        return up, down
    if shaping is None:
        unit = Shaper.unit()
        return unit, unit
    raise ValueError(f"expected a Shaper or an Up/Down pair of shapers, got {type(shaping).__name__}")


def linear_residual_pct(shaping: Any, sample: UncertaintySample) -> np.ndarray:
    """Residual of ``shaping`` on the linear model for every case of ``sample``, % of the unshaped move's.

    Parameters
    ----------
    shaping : Shaper, a pair with ``up`` and ``down`` shapers, or None (unshaped: 100 %)
        The Up cases use the Up shaper, the Down cases the Down shaper.
    sample : UncertaintySample
        The cases.

    Returns
    -------
    numpy.ndarray
        ``100 V`` per case (``100 ((1 - s) V1 + s V2)`` with a second mode).
    """
    up, down = _shapers_of(shaping)
    out = np.empty(len(sample))
    for shaper, sel in ((up, sample.is_up), (down, ~sample.is_up)):
        v = np.asarray(shaper.vibration(sample.omega_n[sel], sample.zeta[sel]))
        if sample.omega_n2 is not None:
            s = sample.share2[sel]
            v = (1.0 - s) * v + s * np.asarray(shaper.vibration(sample.omega_n2[sel], sample.zeta2[sel]))
        out[sel] = 100.0 * v
    return out


def percentile_pct(values: np.ndarray, q: float = 95.0) -> float:
    """The ``q``-th percentile of residuals (linear interpolation between order statistics), NaN-free input.

    Parameters
    ----------
    values : numpy.ndarray
        Residuals, %.
    q : float
        Percentile in (0, 100).

    Returns
    -------
    float
    """
    v = np.asarray(values, dtype=float).ravel()
    if v.size == 0 or not np.all(np.isfinite(v)):
        raise ValueError("percentile_pct needs a non-empty array of finite residuals")
    if not 0.0 < q < 100.0:
        raise ValueError(f"q must lie in (0, 100), got {q!r}")
    return float(np.percentile(v, q))
