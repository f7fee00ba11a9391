"""The shapers a sweep can run, each designed for a run's point with the design's errors applied.

A design error is the design's mode minus the rig's: the design frequency is the identified (or the map's)
times ``1 + freq_error`` and the design damping ratio the identified one plus ``zeta_error``. Built-in
shapers (:data:`BUILTIN`):

- ``unshaped``; ``zv``, ``zvd``: the paper's two TDFs from the identified mode (``design_tdfs``);
- ``zvdd``, ``mzv``, ``ei``, ``2-hump-ei``, ``3-hump-ei``, ``um-zv``: those families at the identified mode
  (EI's tolerance 5 %);
- ``multi-mode``: ZVD on the dominant mode times ZV on the second, both at the centre of the band the move
  sweeps on the mode map (``helpers.research.design.multi_mode_design``);
- ``scheduled-zv``, ``scheduled-zvd``: the scheduled pair (Up at the destination's mode, Down at rest's);
- ``map-following-zv``, ``map-following-zvd``: the map-following schedules of the move;
- ``ei-band``, ``2-hump-ei-band``: EI and 2-hump EI centred on the band the move sweeps.

Map-based designs read the sweep's mode map with every frequency scaled by ``1 + freq_error`` and every
damping ratio shifted by ``zeta_error``. A **custom** shaper (``custom_shapers`` of the definition, or a
design-set file of :mod:`helpers.research.robustness`) is either a family at a stated mode, ``{"family": "EI",
"omega_d": 27.0, "zeta": 0.044, "vtol": 0.08}`` (the errors apply to that mode), or fixed impulses
``{"amplitudes": [...], "times": [...], "reference_omega_d": 25.09}``, whose times are divided by
``1 + freq_error`` (a design for a frequency that much higher); a damping error does not change fixed
impulses, which were not designed from one damping ratio.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from helpers.paper.modes import omega_n_from_damped
from helpers.paper.shapers import Shaper, design_tdfs
from helpers.research.design import (
    Design,
    ShaperPair,
    band_centred,
    map_following,
    multi_mode_design,
    scheduled_pair,
)
from helpers.research.families import FAMILIES, ei
from helpers.research.modemap import ModeMap

__all__ = ["BUILTIN", "ShapingContext", "shaping_for", "check_shapers"]

_FAMILY_OF = {"zvdd": "ZVDD", "mzv": "MZV", "ei": "EI", "2-hump-ei": "2-hump EI", "3-hump-ei": "3-hump EI",
              "um-zv": "UM-ZV"}  # fmt: skip

BUILTIN: dict[str, str] = {
    "unshaped": "no shaping",
    "zv": "the paper's non-robust TDF (ZV) at the identified mode",
    "zvd": "the paper's robust TDF (ZVD) at the identified mode",
    **{k: f"{v} at the identified mode" for k, v in _FAMILY_OF.items()},
    "multi-mode": "ZVD on the dominant mode * ZV on the second, at their band centres (mode map)",
    "scheduled-zv": "scheduled pair of ZV: Up at the destination's mode, Down at rest's (mode map)",
    "scheduled-zvd": "scheduled pair of ZVD (mode map)",
    "map-following-zv": "map-following schedule of ZV (mode map)",
    "map-following-zvd": "map-following schedule of ZVD (mode map)",
    "ei-band": "EI centred on the band the move sweeps (mode map)",
    "2-hump-ei-band": "2-hump EI centred on the band the move sweeps (mode map)",
}
"""Built-in shaper names and what they are."""


@dataclass
class ShapingContext:
    """What designs are made from: the identified mode, the mode map, the custom shapers.

    Attributes
    ----------
    omega_d, zeta : float
        The identified mode (damped rad/s, damping ratio).
    mode_map : ModeMap
        The sweep's mode map.
    custom : dict
        Custom shapers by name.
    """

    omega_d: float
    zeta: float
    mode_map: ModeMap
    custom: dict[str, dict[str, Any]] = field(default_factory=dict)
    _maps: dict[tuple[float, float], ModeMap] = field(default_factory=dict, repr=False)

    def design_mode(self, freq_error: float, zeta_error: float) -> tuple[float, float]:
        """The identified mode with the design errors: ``(omega_d (1 + e), zeta + dz)``."""
        zeta = self.zeta + zeta_error
        if not 0.0 <= zeta < 1.0:
            raise ValueError(f"zeta_error = {zeta_error:g} makes the design damping ratio {zeta:g}")
        return self.omega_d * (1.0 + freq_error), zeta

    def design_map(self, freq_error: float, zeta_error: float) -> ModeMap:
        """The mode map with the design errors (frequencies scaled, damping ratios shifted); cached."""
        key = (float(freq_error), float(zeta_error))
        if key not in self._maps:
            m = self.mode_map
            scale = 1.0 + freq_error
            kw: dict[str, Any] = {
                "omega_d": m.omega_d * scale, "zeta": _shifted(m.zeta, zeta_error),
                "omega_d_se": m.omega_d_se * scale, "zeta_se": m.zeta_se,
            }  # fmt: skip
            if m.has_second_mode:
                kw.update(
                    omega_d2=m.omega_d2 * scale,
                    zeta2=_shifted(m.zeta2, zeta_error),
                    share2=m.share2,
                    omega_d2_se=m.omega_d2_se * scale,
                    zeta2_se=m.zeta2_se,
                    share2_se=m.share2_se,
                )
            source = {**m.source, "design_errors": {"freq_error": key[0], "zeta_error": key[1]}}
            self._maps[key] = ModeMap(m.positions_mm, source=source, **kw)
        return self._maps[key]


def _shifted(zeta: np.ndarray, dz: float) -> np.ndarray:
    out = np.asarray(zeta) + dz
    if np.any(out < 0) or np.any(out >= 1):
        raise ValueError(f"zeta_error = {dz:g} takes a damping ratio of the map outside [0, 1)")
    return out


def _family(name: str, omega_d: float, zeta: float, vtol: float | None = None) -> Shaper:
    omega_n = omega_n_from_damped(omega_d, zeta)
    if name == "EI":
        return ei(omega_n, zeta, 0.05 if vtol is None else float(vtol))
    return FAMILIES[name](omega_n, zeta)


def _custom(entry: dict[str, Any], ctx: ShapingContext, e: float, dz: float, name: str) -> Shaper:
    if "family" in entry:
        fam = entry["family"]
        if fam not in FAMILIES:
            raise ValueError(f"custom shaper {name!r}: unknown family {fam!r}")
        zeta = float(entry["zeta"]) + dz
        if not 0 <= zeta < 1:
            raise ValueError(f"zeta_error = {dz:g} makes {name!r}'s design damping ratio {zeta:g}")
        s = _family(fam, float(entry["omega_d"]) * (1.0 + e), zeta, entry.get("vtol"))
        return Shaper(s.amplitudes, s.times, name)
    a = np.asarray(entry["amplitudes"], dtype=float)
    t = np.asarray(entry["times"], dtype=float) / (1.0 + e)
    return Shaper(a, t, name)


def _builtin(name: str, ctx: ShapingContext, point: dict[str, Any]) -> Shaper | ShaperPair | Design | None:
    e, dz = float(point["freq_error"]), float(point["zeta_error"])
    x, v = float(point["amplitude_mm"]), float(point["speed_mm_s"])
    if name == "unshaped":
        return None
    if name in ("zv", "zvd"):
        w, z = ctx.design_mode(e, dz)
        return design_tdfs(w, z)[0 if name == "zv" else 1]
    if name in _FAMILY_OF:
        w, z = ctx.design_mode(e, dz)
        return _family(_FAMILY_OF[name], w, z)
    m = ctx.design_map(e, dz)
    makers: dict[str, Callable[[], Design]] = {
        "multi-mode": lambda: multi_mode_design(m, x, "ZVD", "ZV", "centre"),
        "scheduled-zv": lambda: scheduled_pair(m, x, "ZV"),
        "scheduled-zvd": lambda: scheduled_pair(m, x, "ZVD"),
        "map-following-zv": lambda: map_following(m, x, v, "ZV"),
        "map-following-zvd": lambda: map_following(m, x, v, "ZVD"),
        "ei-band": lambda: band_centred(m, x, "EI"),
        "2-hump-ei-band": lambda: band_centred(m, x, "2-hump EI"),
    }
    return makers[name]()


def shaping_for(name: str, point: dict[str, Any], ctx: ShapingContext) -> Shaper | ShaperPair | Design | None:
    """The shaping of shaper ``name`` for a run at ``point`` (with its design errors).

    Parameters
    ----------
    name : str
        A built-in name (:data:`BUILTIN`) or a custom shaper's.
    point : dict
        The run's parameters (:meth:`helpers.research.sweep.definition.SweepDefinition.point`).
    ctx : ShapingContext
        What designs are made from.

    Returns
    -------
    Shaper, ShaperPair, Design or None
        What :func:`helpers.board.programmes.experiment_programme` takes.

    Raises
    ------
    ValueError
        If the design cannot be made at this point (the message says why).
    """
    if name in ctx.custom:
        return _custom(ctx.custom[name], ctx, float(point["freq_error"]), float(point["zeta_error"]), name)
    if name in BUILTIN:
        return _builtin(name, ctx, point)
    raise ValueError(f"unknown shaper {name!r}")


def check_shapers(names: tuple[str, ...], custom: dict[str, dict[str, Any]]) -> None:
    """Refuse names that are neither built in nor custom, and malformed custom entries (one line)."""
    for name in names:
        if name in custom:
            entry = custom[name]
            if "family" in entry:
                missing = [k for k in ("omega_d", "zeta") if not _number(entry.get(k))]
            else:
                missing = [k for k in ("amplitudes", "times") if not isinstance(entry.get(k), list)]
            if missing:
                raise ValueError(f"custom shaper {name!r}: {', '.join(missing)} missing or not valid")
            if "family" not in entry:
                Shaper(np.asarray(entry["amplitudes"], float), np.asarray(entry["times"], float), name)
        elif name not in BUILTIN:
            known = ", ".join([*BUILTIN, *custom])
            raise ValueError(f"unknown shaper {name!r}; known: {known}")


def _number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)
