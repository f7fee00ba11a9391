"""Bends in any direction, and the map of the spatial twin's modes over bend direction and magnitude.

A *bend* is a direction ``beta`` (degrees around the backbone, counter-clockwise, 0 = towards tendon 1) and a
magnitude ``b`` in mm of cable (``bend_mm``, ``docs/spatial_twin.md``): every tendon whose angle ``a_i``
faces the direction (``cos(beta - a_i) > 0``) is pulled by ``u_i = b (r_i / r_mean) cos(beta - a_i)`` at its
spool, the cable a constant-curvature bend by the angle ``theta = b / r_mean`` towards ``beta`` would need
(its path shortens by ``r_i theta cos(beta - a_i)``); every other tendon is held at its pretension, the
statics turning its spool as far as that needs (an antagonist pays out). For tendons 90 degrees apart, the
two tendons neighbouring ``beta`` share the pull as ``cos`` and ``sin`` of the angle from the first; the
paper's one-tendon rig at ``beta = 0`` has ``u = b``, its cable displacement.

:func:`frequency_map` tabulates, for every direction and magnitude, the static equilibrium (tensions, spool
displacements, where the tip is), the lowest modes with the spools held (frequency, damping, the direction
of the tip's motion, the twist's share) and the mode that dominates the leading tendon's tension as the rig
runs (rotors free).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from helpers.rigfile.derived import lead_tendon
from helpers.virtual.spatial.rig import SpatialRig
from helpers.virtual.spatial.statics import DECAY_S, SpatialEquilibrium, equilibrium, linearise

__all__ = [
    "bend_command",
    "bend_equilibrium",
    "frequency_map",
    "frequency_map_csv",
    "parse_values",
    "DEFAULT_DIRECTIONS_DEG",
    "DEFAULT_BENDS_MM",
]

DEFAULT_DIRECTIONS_DEG = tuple(float(d) for d in range(0, 360, 15))
"""Directions of the default map, degrees."""

DEFAULT_BENDS_MM = (0.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0)
"""Bend magnitudes of the default map, mm of cable."""

_DB_MM = 0.1  # the bend increment over which the command's direction (every spool's rate) is taken


def bend_command(rig: SpatialRig, direction_deg: float, bend_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """The pulled tendons' spool displacements (m) for a bend, and which tendons pull.

    Returns
    -------
    (u, pulled)
        ``u[i] = b (r_i / r_mean) cos(beta - a_i)`` for the pulled tendons (0 for the others) and the mask of
        pulled tendons (``cos(beta - a_i) > 1e-9``).

    Raises
    ------
    ValueError
        On a non-finite or negative magnitude, or a direction no tendon faces.
    """
    if not (math.isfinite(direction_deg) and math.isfinite(bend_mm)):
        raise ValueError(f"direction and bend must be finite, got {direction_deg!r}, {bend_mm!r}")
    if bend_mm < 0:
        raise ValueError(f"bend_mm must be >= 0, got {bend_mm!r}")
    r = np.array([t.offset_mm for t in rig.tendons])
    c = np.cos(math.radians(direction_deg) - rig.angles)
    pulled = c > 1e-9
    if not pulled.any():
        angles = ", ".join(f"{t.angle_deg:g}" for t in rig.tendons)
        raise ValueError(f"no tendon faces {direction_deg:g} deg (tendons at {angles} deg)")
    u = np.where(pulled, bend_mm * 1e-3 * (r / r.mean()) * c, 0.0)
    return u, pulled


def bend_equilibrium(
    rig: SpatialRig, direction_deg: float, bend_mm: float, start: SpatialEquilibrium | None = None
) -> SpatialEquilibrium:
    """The static equilibrium of a bend (pulled tendons displaced, the others at their pretension)."""
    u, pulled = bend_command(rig, direction_deg, bend_mm)
    tension = np.where(pulled, np.nan, rig.pretensions)
    return equilibrium(rig, u, tension=tension, start=start)


def _tip_angles(eq: SpatialEquilibrium, chain: object) -> tuple[float, float]:
    """Where the tip is around the clamp axis (deg, 0-360) and its tangent's angle from that axis (deg)."""
    tip = np.round(eq.tip, 12)
    az = math.degrees(math.atan2(tip[1], tip[0])) if math.hypot(tip[0], tip[1]) > 1e-12 else 0.0
    R = chain.kinematics(eq.q)["R"][-1]
    bend = math.degrees(math.acos(max(-1.0, min(1.0, float(R[2, 2])))))
    return round(az, 6) % 360.0 + 0.0, bend


def frequency_map(
    rig: SpatialRig,
    directions_deg: tuple[float, ...] | np.ndarray = DEFAULT_DIRECTIONS_DEG,
    bends_mm: tuple[float, ...] | np.ndarray = DEFAULT_BENDS_MM,
    n_modes: int = 4,
    decay_s: float = DECAY_S,
) -> pd.DataFrame:
    """The spatial twin's modes against bend direction and magnitude.

    For every direction (continuation over the sorted magnitudes from rest): the bend's equilibrium, the
    ``n_modes`` lowest oscillatory modes with every spool held, and the dominant mode of the leading tendon's
    tension with the rotors free (the mode an identification on that tendon would see) after a step of the
    command that moves the bend on (every spool's rate ``du_i/db``, the antagonists' paying out included).

    Returns
    -------
    pandas.DataFrame
        ``direction_deg``, ``bend_mm``; per tendon ``i`` (1-based) ``u{i}_mm`` (spool displacement) and
        ``tension{i}_n``; ``tip_x_mm``, ``tip_y_mm``, ``tip_z_mm`` (clamp frame), ``tip_azimuth_deg`` (where
        the tip is around the clamp axis), ``tip_bend_deg`` (tip tangent against the clamp axis); per mode
        ``k`` ``omega_d{k}_rad_s``, ``zeta{k}``, ``azimuth{k}_deg`` (direction of the tip's motion, 0-180),
        ``torsion{k}`` (the twist's share of the strain energy); ``dominant_omega_d_rad_s``,
        ``dominant_zeta``.
    """
    if isinstance(n_modes, bool) or not isinstance(n_modes, int) or n_modes < 1:
        raise ValueError(f"n_modes must be a positive integer, got {n_modes!r}")
    dirs = np.asarray(directions_deg, dtype=float).reshape(-1)
    bends = np.sort(np.asarray(bends_mm, dtype=float).reshape(-1))
    if dirs.size == 0 or bends.size == 0:
        raise ValueError("give at least one direction and one bend")
    rows = []
    for beta in dirs:
        eq = None
        for b in bends:
            eq = bend_equilibrium(rig, float(beta), float(b), start=eq)
            locked = linearise(rig, eq, rotor="locked", decay_s=decay_s)
            free = linearise(rig, eq, rotor="free", decay_s=decay_s)
            # the command that moves the bend on: every spool's rate, antagonists included
            nxt = bend_equilibrium(rig, float(beta), float(b) + _DB_MM, start=eq)
            u_cmd = (nxt.u - eq.u) / (_DB_MM * 1e-3)
            lead = lead_tendon(rig.tendons, float(beta))
            modes = locked.modes(command=u_cmd)
            row: dict[str, float] = {"direction_deg": float(beta), "bend_mm": float(b)}
            for i in range(rig.n_tendons):
                row[f"u{i + 1}_mm"] = float(eq.u[i] * 1e3)
                row[f"tension{i + 1}_n"] = float(eq.tension[i])
            tip = [round(float(v) * 1e3, 9) + 0.0 for v in eq.tip]
            row["tip_x_mm"], row["tip_y_mm"], row["tip_z_mm"] = tip
            row["tip_azimuth_deg"], row["tip_bend_deg"] = _tip_angles(eq, locked.chain)
            for k in range(n_modes):
                m = modes.iloc[k] if k < len(modes) else None
                row[f"omega_d{k + 1}_rad_s"] = float(m.omega_d) if m is not None else math.nan
                row[f"zeta{k + 1}"] = float(m.zeta) if m is not None else math.nan
                row[f"azimuth{k + 1}_deg"] = float(m.azimuth_deg) if m is not None else math.nan
                row[f"torsion{k + 1}"] = float(m.torsion) if m is not None else math.nan
            row["dominant_omega_d_rad_s"], row["dominant_zeta"] = free.dominant(lead, command=u_cmd)
            rows.append(row)
    return pd.DataFrame(rows)


def parse_values(text: str, name: str) -> tuple[float, ...]:
    """Numbers from ``"0,45,90"`` or ``"start:stop:step"`` (stop excluded), for the command line.

    Raises
    ------
    ValueError
        One line naming ``name`` and what is wrong.
    """
    text = str(text).strip()
    try:
        if ":" in text:
            parts = [float(p) for p in text.split(":")]
            if len(parts) != 3 or parts[2] <= 0 or not all(math.isfinite(p) for p in parts):
                raise ValueError
            values = tuple(float(v) for v in np.arange(parts[0], parts[1] - 1e-9 * parts[2], parts[2]))
        else:
            values = tuple(float(p) for p in text.split(",") if p.strip())
    except ValueError:
        raise ValueError(f"{name}: expected numbers like 0,45,90 or start:stop:step, got {text!r}") from None
    if not values or not all(math.isfinite(v) for v in values):
        raise ValueError(f"{name}: expected at least one finite number, got {text!r}")
    return values


def frequency_map_csv(rig: SpatialRig, directions: str, bends: str, n_modes: int = 4) -> str:
    """:func:`frequency_map` of ``rig`` as CSV text (6 significant digits), directions and bends as text."""
    dirs = parse_values(directions, "--directions")
    b = parse_values(bends, "--bends")
    if any(v < 0 for v in b):
        raise ValueError(f"--bends: bend magnitudes must be >= 0 mm, got {bends!r}")
    if rig.n_tendons == 1:
        for d in dirs:
            bend_command(rig, d, 1.0)  # refuse a direction no tendon faces, in one line
    return frequency_map(rig, dirs, b, n_modes=n_modes).to_csv(index=False, float_format="%.6g")
