"""The automatic choice: the shortest candidate whose predicted residual stays within a tolerance.

For a move, :func:`auto_choice` builds the candidates below, computes each one's worst predicted residual over
the band the move sweeps and the map's uncertainty (:mod:`helpers.research.design.predict`), and picks the
**shortest**
(smallest duration) whose worst predicted residual is at most the tolerance (default 5 %) and, if a cap is
given, whose duration is within it; ties go to the smaller residual, then to the earlier candidate. If none
qualifies it says so (:attr:`AutoChoice.design` is None and :attr:`AutoChoice.message` names the best
candidate and its residual; :meth:`AutoChoice.require` raises that message).

Candidates, in this order (one shaper for both moves, which sweep the same band):

1. each family of :data:`AUTO_FAMILIES` at the band centre
(:meth:`helpers.research.design.predict.Band.centre`);
2. with a second mode in the map: each of those convolved with each family of :data:`SECOND_FAMILIES` at the
   second mode's band centre (multi-mode);
3. unless ``include_minimax=False``: minimax designs (:func:`helpers.research.design.robust.minimax`) with
duration
   caps of :data:`MINIMAX_CAPS` band-centre damped periods (and the cap itself, if given).

Map-following schedules are not candidates: their residual is not a convolution's, so the predicted residual
does not apply to them (judge them with :mod:`helpers.research.design.timevarying`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import pandas as pd

from helpers.base.validate import check_positive
from helpers.paper.shapers import Shaper
from helpers.research.design.formats import Design
from helpers.research.design.predict import (
    DEFAULT_COVERAGE,
    DEFAULT_N_BETWEEN,
    DEFAULT_TOLERANCE_PCT,
    band,
    worst_residual_pct,
)
from helpers.research.design.robust import minimax
from helpers.research.design.scheduled import _map_info, _move_info, family
from helpers.research.modemap import ModeMap

AUTO_FAMILIES = ("ZV", "MZV", "ZVD", "EI", "ZVDD", "2-hump EI", "3-hump EI")
"""Single-mode families tried at the band centre."""

SECOND_FAMILIES = ("ZV", "ZVD", "EI")
"""Families tried on the second mode (convolved with each of :data:`AUTO_FAMILIES`)."""

MINIMAX_CAPS = (0.5, 0.75, 1.0, 1.25, 1.5, 2.0)
"""Duration caps of the minimax candidates, in damped periods of the band centre."""


@dataclass(frozen=True)
class AutoChoice:
    """The result of :func:`auto_choice`.

    Attributes
    ----------
    design : Design or None
        System ``"auto"``: the chosen shaper (None if no candidate qualifies).
    table : pandas.DataFrame
        Every candidate: ``candidate``, ``kind`` (``family``, ``multi-mode``, ``minimax``), ``duration_s``,
        ``worst_pct``, ``qualifies``, ``chosen``; sorted by duration.
    tolerance_pct : float
        The tolerance used.
    message : str
        What was chosen, or why nothing was.
    """

    design: Design | None
    table: pd.DataFrame
    tolerance_pct: float
    message: str

    def require(self) -> Design:
        """The chosen design, or ``ValueError`` with :attr:`message` when none qualifies."""
        if self.design is None:
            raise ValueError(self.message)
        return self.design


def _candidates(
    mode_map: ModeMap,
    x_f_mm: float,
    start_mm: float,
    coverage: float,
    n_between: int,
    include_minimax: bool,
    max_duration_s: float | None,
) -> list[tuple[str, str, Shaper]]:
    b = band(mode_map, start_mm, start_mm + x_f_mm, coverage, n_between)
    omega_n, zeta = b.centre()
    singles = []
    for name in AUTO_FAMILIES:
        fam = family(name)
        if fam.zeta_range[0] <= zeta <= fam.zeta_range[1]:
            singles.append((name, fam(omega_n, zeta)))
    out = [(f"{name} centred", "family", s) for name, s in singles]
    if mode_map.has_second_mode:
        omega_n2, zeta2 = b.centre2()  # type: ignore[misc]
        for name2 in SECOND_FAMILIES:
            fam2 = family(name2)
            if not fam2.zeta_range[0] <= zeta2 <= fam2.zeta_range[1]:
                continue
            second = fam2(omega_n2, zeta2)
            for name, s in singles:
                out.append((f"{name} * {name2} (second mode) centred", "multi-mode", s.convolve(second)))
    if include_minimax:
        period = 2 * math.pi / (omega_n * math.sqrt(1 - zeta**2))
        caps = [c * period for c in MINIMAX_CAPS]
        if max_duration_s is not None:
            caps = [c for c in caps if c < max_duration_s] + [max_duration_s]
        for cap in caps:
            d = minimax(mode_map, x_f_mm, cap, start_mm=start_mm, coverage=coverage, n_between=n_between)
            out.append((f"minimax, cap {cap:.4f} s", "minimax", d.shaping))  # type: ignore[arg-type]
    return out


def auto_choice(
    mode_map: ModeMap,
    x_f_mm: float,
    tolerance_pct: float = DEFAULT_TOLERANCE_PCT,
    max_duration_s: float | None = None,
    start_mm: float = 0.0,
    coverage: float = DEFAULT_COVERAGE,
    n_between: int = DEFAULT_N_BETWEEN,
    include_minimax: bool = True,
) -> AutoChoice:
    """The shortest candidate whose worst predicted residual is at most ``tolerance_pct`` (module docstring).

    Parameters
    ----------
    mode_map : ModeMap
        The measured map.
    x_f_mm, start_mm : float
        The move (mm).
    tolerance_pct : float
        The tolerance on the worst predicted residual, percent (default 5).
    max_duration_s : float, optional
        Refuse candidates longer than this (s).
    coverage, n_between
        The band (:func:`helpers.research.design.predict.band`).
    include_minimax : bool
        Also try minimax designs (slower: one optimisation per cap).

    Returns
    -------
    AutoChoice
    """
    tol = check_positive(tolerance_pct, "tolerance_pct")
    x_f = check_positive(x_f_mm, "x_f_mm")
    cap = None if max_duration_s is None else check_positive(max_duration_s, "max_duration_s")
    b = band(mode_map, start_mm, start_mm + x_f, coverage, n_between)
    rows: list[dict[str, Any]] = []
    shapers = []
    for order, (name, kind, shaper) in enumerate(
        _candidates(mode_map, x_f, float(start_mm), coverage, n_between, include_minimax, cap)
    ):
        worst = worst_residual_pct(shaper, b)
        within = cap is None or shaper.duration <= cap + 1e-12
        row = {"candidate": name, "kind": kind, "duration_s": shaper.duration, "worst_pct": worst}
        rows.append({**row, "qualifies": bool(worst <= tol and within), "chosen": False, "order": order})
        shapers.append(shaper)
    table = pd.DataFrame(rows).sort_values(["duration_s", "worst_pct", "order"], kind="stable")
    where = f"{b.low_mm:g}-{b.high_mm:g} mm (+-{b.coverage:g} standard errors)"
    capped = "" if cap is None else f" within {cap:.4g} s"
    ok = table[table["qualifies"]]
    if ok.empty:
        best = table.sort_values(["worst_pct", "duration_s", "order"], kind="stable").iloc[0]
        message = (
            f"no candidate keeps the predicted residual within {tol:g} % over {where}{capped}; the best is "
            f"{best['candidate']} at {best['worst_pct']:.2f} % ({best['duration_s']:.4f} s)"
        )
        return AutoChoice(None, table.drop(columns="order").reset_index(drop=True), tol, message)
    pick = ok.iloc[0]
    table.loc[pick.name, "chosen"] = True
    chosen = shapers[int(pick["order"])]
    shaper = Shaper(chosen.amplitudes, chosen.times, f"auto: {pick['candidate']}")
    message = (
        f"chosen {pick['candidate']}: {pick['duration_s']:.4f} s, worst predicted residual "
        f"{pick['worst_pct']:.2f} % <= {tol:g} % over {where}{capped}"
    )
    provenance = {
        "design": "automatic choice",
        "chosen": str(pick["candidate"]),
        "chosen_kind": str(pick["kind"]),
        "predicted_worst_pct": float(pick["worst_pct"]),
        "tolerance_pct": tol,
        "max_duration_s": cap,
        "candidates": table.drop(columns="order").to_dict(orient="records"),
        "move": _move_info(x_f, start_mm),
        "band": b.as_dict(),
        "mode_map": _map_info(mode_map),
    }
    design = Design("auto", shaper, provenance)
    return AutoChoice(design, table.drop(columns="order").reset_index(drop=True), tol, message)
