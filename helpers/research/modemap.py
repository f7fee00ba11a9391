"""A measured frequency map: the arm's modes against cable position, with standard errors and provenance.

The arm's lowest mode stiffens as the cable bends it: its damped frequency rises with the cable position
``x`` (mm, 0 = rest, positive = pulled). A :class:`ModeMap` holds, at measured cable positions, the dominant
mode's damped frequency ``omega_d`` (rad/s) and damping ratio ``zeta`` with their standard errors, and
optionally a second mode (``omega_d2``, ``zeta2``) with its **share** ``share2`` of the residual vibration:
the fraction of the unshaped residual amplitude that the second mode carries (the dominant mode carries
``1 - share2``). How the map was obtained travels with it (:attr:`ModeMap.source`: ``kind`` is
``"virtual-rig"`` or ``"hardware"``, ``method`` says how it was measured or predicted, ``rig`` the rig file's
``name`` and ``hash``: a map without it was made before rig files, on the paper's rig).

Between measured positions every column is interpolated with a monotone cubic (``scipy``'s PCHIP: no
overshoot, so interpolated standard errors and shares stay within their neighbours). Outside the measured
range :meth:`ModeMap.at` refuses unless asked to hold the end values (``extrapolate=True``).

Files (format ``FORMAT``, version ``FORMAT_VERSION``; ``docs/shaper_design.md``):

- JSON: ``{"format", "version", "source": {...}, "columns": {name: [values]}}`` with the column names of
  :data:`COLUMNS`;
- CSV: one row per position with the columns of :data:`COLUMNS` (the second mode's only if present) and the
  provenance in two leading columns ``source`` and ``method`` (the same in every row), so the file carries
  it wherever it is copied. Floats are written with 17 significant digits and read back exactly.

The type imports no physics: :meth:`ModeMap.from_table` builds a map from any table (for example the
virtual rig's predicted map, ``helpers.virtual.statics.frequency_map``, whose column names it recognises).
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.interpolate import PchipInterpolator

from helpers import rigfile
from helpers.base.jsonfile import (
    DataFileError,
    MissingDataError,
    atomic_write,
    read_json,
    write_json,
)
from helpers.paper.modes import omega_n_from_damped
from helpers.research.versioned import check_versioned

FORMAT = "continuum-arm-mode-map"
"""The ``format`` tag of a mode-map JSON file."""

FORMAT_VERSION = 1
"""Version of the mode-map file layout; :func:`load_map` refuses any other."""

SOURCE_KINDS = ("virtual-rig", "hardware", "external")
"""The vocabulary of ``source["kind"]`` (as in the recordings; ``external``: data made elsewhere, whose
configuration may be in another unit than mm, named by ``source["position_unit"]``)."""

COLUMNS: dict[str, str] = {
    "position_mm": "cable position, mm (strictly increasing)",
    "omega_d_rad_s": "dominant mode: damped natural frequency, rad/s",
    "omega_d_se_rad_s": "its standard error, rad/s",
    "zeta": "dominant mode: damping ratio",
    "zeta_se": "its standard error",
    "omega_d2_rad_s": "second mode (optional): damped natural frequency, rad/s",
    "omega_d2_se_rad_s": "its standard error, rad/s",
    "zeta2": "second mode: damping ratio",
    "zeta2_se": "its standard error",
    "share2": "second mode's share of the unshaped residual amplitude, in [0, 1)",
    "share2_se": "its standard error",
}
"""The map's columns in file order, with their meaning (the ``*2*`` ones only when a second mode is given)."""

_FIRST = ("position_mm", "omega_d_rad_s", "omega_d_se_rad_s", "zeta", "zeta_se")
_SECOND = ("omega_d2_rad_s", "omega_d2_se_rad_s", "zeta2", "zeta2_se", "share2", "share2_se")
_ATTR = {
    "position_mm": "positions_mm",
    "omega_d_rad_s": "omega_d",
    "omega_d_se_rad_s": "omega_d_se",
    "zeta": "zeta",
    "zeta_se": "zeta_se",
    "omega_d2_rad_s": "omega_d2",
    "omega_d2_se_rad_s": "omega_d2_se",
    "zeta2": "zeta2",
    "zeta2_se": "zeta2_se",
    "share2": "share2",
    "share2_se": "share2_se",
}

_VIRTUAL_COLUMNS = {
    # helpers.virtual.statics.frequency_map, present and announced layouts -> our names
    "u_mm": "position_mm",
    "omega_d": "omega_d_rad_s",
    "omega_d_rad_s": "omega_d_rad_s",
    "zeta": "zeta",
    "omega_d2_rad_s": "omega_d2_rad_s",
    "zeta2": "zeta2",
}


def _column(values: Any, name: str, n: int | None) -> np.ndarray:
    arr = np.array(values, dtype=float, ndmin=1)
    if arr.ndim != 1:
        raise ValueError(f"mode map: {name} must be one-dimensional, got shape {arr.shape}")
    if n is not None and arr.size != n:
        raise ValueError(f"mode map: {name} has {arr.size} values, positions_mm has {n}")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise ValueError(f"mode map: {name}[{bad[0]}] = {float(arr[bad[0]])!r} is not a finite number")
    arr.flags.writeable = False
    return arr


def _check_range(
    arr: np.ndarray, name: str, lo: float, hi: float | None, lo_open: bool, hi_open: bool
) -> None:
    below = arr <= lo if lo_open else arr < lo
    above = np.zeros(arr.shape, bool) if hi is None else (arr >= hi if hi_open else arr > hi)
    bad = np.flatnonzero(below | above)
    if bad.size:
        left = "(" if lo_open else "["
        right = "inf)" if hi is None else (f"{hi:g})" if hi_open else f"{hi:g}]")
        value = float(arr[bad[0]])
        raise ValueError(f"mode map: {name}[{bad[0]}] = {value!r} is outside {left}{lo:g}, {right}")


@dataclass(frozen=True)
class MapPoint:
    """The map's values at one or more cable positions (floats for a scalar position, else arrays).

    Attributes
    ----------
    position_mm : float or numpy.ndarray
        Where the map was evaluated.
    omega_d, omega_d_se, zeta, zeta_se : float or numpy.ndarray
        The dominant mode and its standard errors.
    omega_d2, omega_d2_se, zeta2, zeta2_se, share2, share2_se : float, numpy.ndarray or None
        The second mode, its share and standard errors (None without a second mode).
    """

    position_mm: Any
    omega_d: Any
    omega_d_se: Any
    zeta: Any
    zeta_se: Any
    omega_d2: Any = None
    omega_d2_se: Any = None
    zeta2: Any = None
    zeta2_se: Any = None
    share2: Any = None
    share2_se: Any = None

    @property
    def omega_n(self) -> Any:
        """Undamped natural frequency of the dominant mode, rad/s."""
        return self.omega_d / np.sqrt(1.0 - np.asarray(self.zeta) ** 2)

    @property
    def omega_n2(self) -> Any:
        """Undamped natural frequency of the second mode, rad/s (None without one)."""
        if self.omega_d2 is None:
            return None
        return self.omega_d2 / np.sqrt(1.0 - np.asarray(self.zeta2) ** 2)


@dataclass(frozen=True, eq=False)
class ModeMap:
    """Modes of the arm against cable position, measured (or predicted) at a few positions.

    Parameters
    ----------
    positions_mm : array_like
        Cable positions (mm), strictly increasing, at least two.
    omega_d : array_like
        Dominant mode's damped natural frequency (rad/s) at each position, > 0.
    zeta : array_like
        Its damping ratio, in [0, 1).
    omega_d_se, zeta_se : array_like, optional
        Their standard errors (>= 0); default 0 (a prediction, or unknown).
    omega_d2, zeta2, share2 : array_like, optional
        The second mode and its share of the unshaped residual amplitude, in [0, 1): all three or none.
    omega_d2_se, zeta2_se, share2_se : array_like, optional
        Their standard errors (default 0; only with a second mode).
    source : dict
        Provenance: ``kind`` (``"virtual-rig"`` or ``"hardware"``) and ``method`` (how it was obtained), and
        any further JSON-safe keys.

    Raises
    ------
    ValueError
        One line naming the field and the first bad value.
    """

    positions_mm: np.ndarray
    omega_d: np.ndarray
    zeta: np.ndarray
    omega_d_se: np.ndarray | None = None
    zeta_se: np.ndarray | None = None
    omega_d2: np.ndarray | None = None
    zeta2: np.ndarray | None = None
    share2: np.ndarray | None = None
    omega_d2_se: np.ndarray | None = None
    zeta2_se: np.ndarray | None = None
    share2_se: np.ndarray | None = None
    source: dict[str, Any] = field(default_factory=lambda: {"kind": "hardware", "method": "unspecified"})

    def __post_init__(self) -> None:
        x = _column(self.positions_mm, "positions_mm", None)
        n = x.size
        if n < 2:
            raise ValueError(f"mode map: needs at least two positions, got {n}")
        steps = np.diff(x)
        if np.any(steps <= 0):
            i = int(np.flatnonzero(steps <= 0)[0])
            a, b = float(x[i]), float(x[i + 1])
            raise ValueError(f"mode map: positions_mm must increase strictly, got {a!r} then {b!r}")
        set_ = object.__setattr__
        set_(self, "positions_mm", x)
        set_(self, "omega_d", _column(self.omega_d, "omega_d", n))
        _check_range(self.omega_d, "omega_d", 0.0, None, True, False)
        set_(self, "zeta", _column(self.zeta, "zeta", n))
        _check_range(self.zeta, "zeta", 0.0, 1.0, False, True)
        for name in ("omega_d_se", "zeta_se"):
            value = np.zeros(n) if getattr(self, name) is None else getattr(self, name)
            set_(self, name, _column(value, name, n))
            _check_range(getattr(self, name), name, 0.0, None, False, False)
        given = [getattr(self, k) is not None for k in ("omega_d2", "zeta2", "share2")]
        if any(given) and not all(given):
            raise ValueError("mode map: a second mode needs omega_d2, zeta2 and share2 together")
        if not any(given):
            extra = [k for k in ("omega_d2_se", "zeta2_se", "share2_se") if getattr(self, k) is not None]
            if extra:
                raise ValueError(f"mode map: {extra[0]} given without a second mode")
        else:
            set_(self, "omega_d2", _column(self.omega_d2, "omega_d2", n))
            _check_range(self.omega_d2, "omega_d2", 0.0, None, True, False)
            set_(self, "zeta2", _column(self.zeta2, "zeta2", n))
            _check_range(self.zeta2, "zeta2", 0.0, 1.0, False, True)
            set_(self, "share2", _column(self.share2, "share2", n))
            _check_range(self.share2, "share2", 0.0, 1.0, False, True)
            for name in ("omega_d2_se", "zeta2_se", "share2_se"):
                value = np.zeros(n) if getattr(self, name) is None else getattr(self, name)
                set_(self, name, _column(value, name, n))
                _check_range(getattr(self, name), name, 0.0, None, False, False)
        set_(self, "source", _check_source(self.source))
        interp = {k: PchipInterpolator(x, getattr(self, k), extrapolate=False) for k in self._names()[1:]}
        set_(self, "_interp", interp)

    # -- construction ---------------------------------------------------------------------------------------
    @classmethod
    def constant(
        cls,
        omega_d: float,
        zeta: float,
        positions_mm: Iterable[float] = (0.0, 40.0),
        second: tuple[float, float, float] | None = None,
        source: Mapping[str, Any] | None = None,
    ) -> ModeMap:
        """A map whose modes do not depend on position (a linear, time-invariant arm): for tests.

        Parameters
        ----------
        omega_d, zeta : float
            The dominant mode (rad/s, damping ratio).
        positions_mm : iterable of float
            Where it is "measured".
        second : (omega_d2, zeta2, share2), optional
            A second mode.
        source : dict, optional
            Provenance; default ``{"kind": "virtual-rig", "method": "constant (test map)"}``.

        Returns
        -------
        ModeMap
        """
        x = np.array(list(positions_mm), dtype=float)
        ones = np.ones(x.size)
        kw: dict[str, Any] = {}
        if second is not None:
            kw = {"omega_d2": second[0] * ones, "zeta2": second[1] * ones, "share2": second[2] * ones}
        src = dict(source) if source is not None else {"kind": "virtual-rig", "method": "constant (test map)"}
        return cls(x, float(omega_d) * ones, float(zeta) * ones, source=src, **kw)

    @classmethod
    def from_table(
        cls,
        table: pd.DataFrame,
        source: Mapping[str, Any],
        positions_mm: Iterable[float] | None = None,
        share2: float | Iterable[float] | None = None,
    ) -> ModeMap:
        """Build a map from a table: the columns of :data:`COLUMNS`, or the virtual rig's predicted map.

        The virtual rig's :func:`helpers.virtual.statics.frequency_map` is recognised by its column names
        (``u_mm``, ``omega_d`` or ``omega_d_rad_s``, ``zeta``, and ``omega_d2_rad_s``, ``zeta2`` when it
        reports a second mode); it has no standard errors (they are 0) and no shares.

        Parameters
        ----------
        table : pandas.DataFrame
            One row per position.
        source : dict
            Provenance (``kind``, ``method``, ...).
        positions_mm : iterable of float, optional
            Keep only these rows (positions must be present in the table, to 1e-9 mm).
        share2 : float or array_like, optional
            The second mode's share, when the table has a second mode but no ``share2`` column. Without a
            share the second mode is left out (a share cannot be guessed).

        Returns
        -------
        ModeMap
        """
        if not isinstance(table, pd.DataFrame):
            raise ValueError(f"mode map: from_table needs a pandas DataFrame, got {type(table).__name__}")
        known = [c for c in table.columns if c in COLUMNS or c in _VIRTUAL_COLUMNS]
        renamed = {c: _VIRTUAL_COLUMNS.get(c, c) for c in known}
        if "omega_d_rad_s" in table.columns and "omega_d" in table.columns:
            renamed.pop("omega_d")
        df = table[list(renamed)].rename(columns=renamed)
        missing = [c for c in ("position_mm", "omega_d_rad_s", "zeta") if c not in df.columns]
        if missing:
            have = list(table.columns)
            raise ValueError(f"mode map: the table lacks {', '.join(missing)} (its columns: {have})")
        df = df.sort_values("position_mm")
        if positions_mm is not None:
            wanted = np.array(list(positions_mm), dtype=float)
            have = df["position_mm"].to_numpy(float)
            rows = []
            for x in wanted:
                hit = np.flatnonzero(np.abs(have - x) <= 1e-9)
                if hit.size == 0:
                    raise ValueError(f"mode map: position {x:g} mm is not in the table")
                rows.append(int(hit[0]))
            df = df.iloc[rows]
        kw = {_ATTR[c]: df[c].to_numpy(float) for c in df.columns if c in _ATTR}
        if share2 is not None and "share2" not in kw:
            if "omega_d2" not in kw:
                raise ValueError("mode map: share2 given but the table has no second mode (omega_d2_rad_s)")
            kw["share2"] = np.broadcast_to(np.asarray(share2, dtype=float), (len(df),)).copy()
        if "share2" not in kw:
            for k in ("omega_d2", "zeta2", "omega_d2_se", "zeta2_se"):
                kw.pop(k, None)
        return cls(source=dict(source), **kw)

    # -- properties -----------------------------------------------------------------------------------------
    @property
    def has_second_mode(self) -> bool:
        """True when the map holds a second mode."""
        return self.omega_d2 is not None

    @property
    def range_mm(self) -> tuple[float, float]:
        """The measured range of cable positions (mm)."""
        return float(self.positions_mm[0]), float(self.positions_mm[-1])

    def __len__(self) -> int:
        return int(self.positions_mm.size)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ModeMap):
            return NotImplemented
        mine, theirs = self.to_dict(), other.to_dict()
        return mine == theirs

    __hash__ = None  # type: ignore[assignment]

    def _names(self) -> list[str]:
        names = [_ATTR[c] for c in _FIRST]
        if self.has_second_mode:
            names += [_ATTR[c] for c in _SECOND]
        return names

    # -- evaluation -----------------------------------------------------------------------------------------
    def at(self, x_mm: float | Iterable[float], extrapolate: bool = False) -> MapPoint:
        """The map at cable position(s) ``x_mm`` (monotone cubic interpolation between measured positions).

        Parameters
        ----------
        x_mm : float or array_like
            Cable position(s), mm.
        extrapolate : bool
            Outside the measured range: False (default) refuses; True holds the nearest end's values (the
            caller says so explicitly; nothing is extrapolated silently).

        Returns
        -------
        MapPoint
            Floats for a scalar ``x_mm``, arrays otherwise.

        Raises
        ------
        ValueError
            If a position is not finite, or outside the measured range without ``extrapolate``.
        """
        x = np.asarray(x_mm, dtype=float)
        if np.any(~np.isfinite(x)):
            raise ValueError(f"mode map: cable position must be finite, got {x_mm!r}")
        lo, hi = self.range_mm
        outside = (x < lo - 1e-9) | (x > hi + 1e-9)
        if np.any(outside) and not extrapolate:
            bad = float(np.atleast_1d(x)[np.atleast_1d(outside)][0])
            raise ValueError(
                f"mode map: x = {bad:g} mm is outside the measured range {lo:g}-{hi:g} mm "
                "(pass extrapolate=True to hold the end values)"
            )
        xc = np.clip(x, lo, hi)
        # at a measured position, the measurement itself (the interpolant agrees only to round-off)
        k = np.clip(np.searchsorted(self.positions_mm, xc), 0, len(self) - 1)
        on_knot = self.positions_mm[k] == xc
        values: dict[str, Any] = {}
        for name, f in self._interp.items():  # type: ignore[attr-defined]
            v = np.where(on_knot, getattr(self, name)[k], f(xc))
            values[name] = float(v) if v.ndim == 0 else v
        pos = float(x) if x.ndim == 0 else x
        return MapPoint(position_mm=pos, **values)

    def sweep(self, start_mm: float, end_mm: float) -> tuple[float, float]:
        """The cable positions a move from ``start_mm`` to ``end_mm`` sweeps, checked against the map.

        Parameters
        ----------
        start_mm, end_mm : float
            Where the move starts and ends (either order), mm.

        Returns
        -------
        (float, float)
            ``(low, high)`` in mm.

        Raises
        ------
        ValueError
            If the move leaves the measured range.
        """
        lo, hi = sorted((float(start_mm), float(end_mm)))
        if not (math.isfinite(lo) and math.isfinite(hi)):
            raise ValueError(f"mode map: a move needs finite positions, got {start_mm!r} to {end_mm!r}")
        a, b = self.range_mm
        if lo < a - 1e-9 or hi > b + 1e-9:
            raise ValueError(
                f"mode map: the move {lo:g}-{hi:g} mm leaves the measured range {a:g}-{b:g} mm "
                "(measure the map over the whole move)"
            )
        return max(lo, a), min(hi, b)

    def positions_in(self, low_mm: float, high_mm: float, n_between: int = 0) -> np.ndarray:
        """Measured positions inside ``[low_mm, high_mm]``, the two ends, and ``n_between`` points per gap.

        Parameters
        ----------
        low_mm, high_mm : float
            A band of cable positions inside the measured range (e.g. from :meth:`sweep`).
        n_between : int
            Evenly spaced extra points between consecutive positions (0: measured positions and ends only).

        Returns
        -------
        numpy.ndarray
            Increasing positions (mm), duplicates removed.
        """
        if int(n_between) != n_between or n_between < 0:
            raise ValueError(f"n_between must be a whole number >= 0, got {n_between!r}")
        low, high = self.sweep(low_mm, high_mm)
        inside = self.positions_mm[(self.positions_mm > low) & (self.positions_mm < high)]
        knots = np.unique(np.concatenate([[low], inside, [high]]))
        if n_between and knots.size > 1:
            fractions = np.arange(1, int(n_between) + 1) / (int(n_between) + 1)
            extra = (knots[:-1, None] + np.diff(knots)[:, None] * fractions[None, :]).ravel()
            knots = np.unique(np.concatenate([knots, extra]))
        return knots

    # -- files ----------------------------------------------------------------------------------------------
    def to_frame(self) -> pd.DataFrame:
        """The map as a table with the columns of :data:`COLUMNS` (the second mode's only if present)."""
        names = _FIRST + (_SECOND if self.has_second_mode else ())
        return pd.DataFrame({c: np.array(getattr(self, _ATTR[c])) for c in names})

    def to_dict(self) -> dict[str, Any]:
        """The JSON document of the map (see the module docstring)."""
        frame = self.to_frame()
        return {
            "format": FORMAT,
            "version": FORMAT_VERSION,
            "source": dict(self.source),
            "columns": {c: [float(v) for v in frame[c]] for c in frame.columns},
        }

    @classmethod
    def from_dict(cls, data: Any, where: str = "mode map") -> ModeMap:
        """Rebuild a map from :meth:`to_dict`'s document; one ``ValueError`` naming the field otherwise."""
        data = check_versioned(data, where, FORMAT, FORMAT_VERSION)
        columns = data.get("columns")
        if not isinstance(columns, dict):
            raise ValueError(f"{where}: columns: expected an object of lists")
        unknown = [c for c in columns if c not in COLUMNS]
        if unknown:
            raise ValueError(f"{where}: columns: unknown column {unknown[0]!r}")
        for c in ("position_mm", "omega_d_rad_s", "zeta"):
            if c not in columns:
                raise ValueError(f"{where}: columns.{c}: missing")
        kw = {}
        for c, values in columns.items():
            if not isinstance(values, list) or not all(_is_number(v) for v in values):
                raise ValueError(f"{where}: columns.{c}: expected a list of finite numbers")
            kw[_ATTR[c]] = values
        if "source" not in data:
            raise ValueError(f"{where}: source: missing")
        try:
            return cls(source=data["source"], **kw)
        except ValueError as exc:
            raise ValueError(f"{where}: {str(exc).removeprefix('mode map: ')}") from None

    def save(self, path: str | os.PathLike) -> Path:
        """Write the map as JSON (``.json``) or CSV (``.csv``), atomically; return the path."""
        path = Path(path)
        if path.suffix == ".json":
            return write_json(path, self.to_dict())
        if path.suffix == ".csv":
            return atomic_write(path, self.to_csv().encode("utf-8"))
        raise ValueError(f"mode map: cannot save {path}: the name must end in .json or .csv")

    def to_csv(self) -> str:
        """The CSV text of the map (provenance in the ``source`` and ``method`` columns)."""
        frame = self.to_frame()
        out = io.StringIO()
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(["source", "method", *frame.columns])
        kind, method = str(self.source["kind"]), str(self.source["method"])
        for row in frame.itertuples(index=False, name=None):
            writer.writerow([kind, method, *(repr(float(v)) for v in row)])
        return out.getvalue()


def _is_number(x: Any) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def _check_source(source: Any) -> dict[str, Any]:
    if not isinstance(source, Mapping):
        raise ValueError(f"mode map: source must be an object with kind and method, got {source!r}")
    kind = source.get("kind")
    if kind not in SOURCE_KINDS:
        raise ValueError(f"mode map: source.kind must be one of {', '.join(SOURCE_KINDS)}, got {kind!r}")
    method = source.get("method")
    if not isinstance(method, str) or not method.strip():
        raise ValueError("mode map: source.method must say how the map was obtained (a non-empty text)")
    if "rig" in source:
        rig = source["rig"]
        if not (isinstance(rig, Mapping) and all(isinstance(rig.get(k), str) for k in ("name", "hash"))):
            raise ValueError(f"mode map: source.rig must hold the rig's name and hash, got {rig!r}")
    return dict(source)


def map_rig(mode_map: ModeMap) -> tuple[str, str]:
    """The rig a map was measured on, ``(name, hash)``: ``source["rig"]``, else the paper's rig.

    A map without ``source["rig"]`` was made before rig files, on the paper's rig (as recordings of schema
    version 1 are).
    """
    rig = mode_map.source.get("rig")
    if rig is None:
        paper = rigfile.default_rig()
        return paper.name, paper.hash
    return str(rig["name"]), str(rig["hash"])


def refuse_map_of_other_rig(mode_map: ModeMap, rig: rigfile.RigFile, path: str | os.PathLike) -> None:
    """Refuse (``DataFileError``, one line naming both rigs' hashes) a map measured on another rig."""
    name, rig_hash = map_rig(mode_map)
    if rig_hash != rig.hash:
        raise DataFileError(
            f"{path}: mode map measured on rig {name!r} (hash {rig_hash}), not on the selected rig "
            f"{rig.name!r} (hash {rig.hash}); survey this rig (tune without --reuse-map, with --replace) or "
            f"select the map's rig file with --rig"
        )


def load_map(path: str | os.PathLike) -> ModeMap:
    """Read a map saved by :meth:`ModeMap.save` (JSON or CSV).

    Parameters
    ----------
    path : path-like
        A ``.json`` or ``.csv`` file.

    Returns
    -------
    ModeMap

    Raises
    ------
    MissingDataError
        If the file does not exist.
    DataFileError
        If it is malformed: one line naming the file and the field.
    """
    path = Path(path)
    if path.suffix == ".json":
        data = read_json(path, "mode map", "measure one first (docs/shaper_design.md)")
        try:
            return ModeMap.from_dict(data, where=str(path))
        except ValueError as exc:
            raise DataFileError(str(exc)) from None
    if path.suffix != ".csv":
        raise DataFileError(f"{path}: a mode map file must end in .json or .csv")
    if not path.exists():
        raise MissingDataError(f"{path}: no mode map yet: measure one first (docs/shaper_design.md)")
    return _read_csv(path)


def _read_csv(path: Path) -> ModeMap:
    with path.open(newline="", encoding="utf-8") as fh:
        rows = list(csv.reader(fh))
    if not rows:
        raise DataFileError(f"{path}: the mode map CSV is empty")
    header, body = rows[0], rows[1:]
    if header[:2] != ["source", "method"]:
        raise DataFileError(f"{path}: the first two columns must be source and method, got {header[:2]}")
    unknown = [c for c in header[2:] if c not in COLUMNS]
    if unknown:
        raise DataFileError(f"{path}: unknown column {unknown[0]!r}")
    if not body:
        raise DataFileError(f"{path}: the mode map CSV has no rows")
    columns: dict[str, list[float]] = {c: [] for c in header[2:]}
    for i, row in enumerate(body, start=2):
        if len(row) != len(header):
            raise DataFileError(f"{path}: line {i} has {len(row)} fields, the header {len(header)}")
        if row[:2] != body[0][:2]:
            raise DataFileError(f"{path}: line {i}: source/method differ from the first row's")
        for name, text in zip(header[2:], row[2:], strict=True):
            try:
                columns[name].append(float(text))
            except ValueError:
                raise DataFileError(f"{path}: line {i}, column {name}: {text!r} is not a number") from None
    source = {"kind": body[0][0], "method": body[0][1]}
    data = {"format": FORMAT, "version": FORMAT_VERSION, "source": source, "columns": columns}
    try:
        return ModeMap.from_dict(data, where=str(path))
    except ValueError as exc:
        raise DataFileError(str(exc)) from None


def mode_at(mode_map: ModeMap, x_mm: float, extrapolate: bool = False) -> tuple[float, float]:
    """The dominant mode ``(omega_n, zeta)`` at cable position ``x_mm``: the package's argument order.

    Parameters
    ----------
    mode_map : ModeMap
        The map.
    x_mm : float
        Cable position, mm.
    extrapolate : bool
        As :meth:`ModeMap.at`.

    Returns
    -------
    (float, float)
        Undamped natural frequency (rad/s) and damping ratio.
    """
    p = mode_map.at(float(x_mm), extrapolate=extrapolate)
    return omega_n_from_damped(p.omega_d, p.zeta), float(p.zeta)
