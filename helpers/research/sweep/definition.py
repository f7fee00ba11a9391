"""A sweep's definition: which shapers, which parameters on a grid or drawn at random, how runs are chunked.

A definition is a JSON object (``docs/sweeps.md``)::

    {"format": "continuum-arm-sweep", "version": 1, "name": "atlas_freq_damping",
     "shapers": ["unshaped", "zvd", "ei", "robust"],
     "designs_file": "robust_shapers.json",          # optional: custom shapers by name (relative paths
                                                     # are relative to the definition file)
     "custom_shapers": {"my-ei": {"family": "EI", "omega_d": 27.0, "zeta": 0.044, "vtol": 0.1}},
     "grid": {"freq_error": [-0.1, 0.0, 0.1], "damping_scale": [0.5, 1.0, 2.0]},
     "sample": {"n": 48, "seed": 1, "distributions": {"amplitude_mm": {"uniform": [10, 30]}}},
     "fixed": {"amplitude_mm": 20, "speed_mm_s": 200},
     "chunk_runs": 4,
     "run": {"t_end_s": 12.0, "rate_hz": 1000.0, "t_up_s": 1.0, "t_down_s": 8.0}}

The parameters (:data:`PARAMETERS`) are the design's frequency and damping errors, the move, the rig's disc
mass, cable stiffness and damping (as scales of the tuned rig's) and the noise seed. Each is on the grid,
drawn in the sample (``n`` points, one coordinate ``sample``), or fixed (its default unless ``fixed`` says
otherwise). A **run** is one combination of the grid, one sample point and one shaper; the seeds of a grid
over ``seed`` share one integration (the seed changes only the ADC noise). Runs are ordered grid first (in
the order given), then sample, then shaper, and cut into chunks of ``chunk_runs``: a chunk is one task, one
file on disk while the sweep runs, and the unit of resumption.

:meth:`SweepDefinition.resolved` fills in what the definition leaves to the repository (the identified mode,
the mode map, the designs file's shapers), so that the definition stored with the results says everything
the numbers depend on.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from helpers.base.jsonfile import read_json
from helpers.paper.identify import load_identification
from helpers.research.modemap import ModeMap, load_map
from helpers.research.robustness import default_map, load_designs
from helpers.research.sweep.schema import SWEEP_LIMITS, RunSettings, check_custom, check_definition

__all__ = [
    "DESIGN_SHARE2",
    "FORMAT",
    "VERSION",
    "PARAMETERS",
    "Parameter",
    "SweepDefinition",
    "load_definition",
]

FORMAT = "continuum-arm-sweep"
"""The ``format`` tag of a sweep definition."""

VERSION = 1
"""Version of the definition layout; any other is refused."""


@dataclass(frozen=True)
class Parameter:
    """A sweep parameter: its default, unit, meaning and admissible range.

    Attributes
    ----------
    default : float
        Its value when neither the grid, the sample nor ``fixed`` sets it.
    unit : str
        Unit (``"1"`` for a ratio).
    meaning : str
        What it changes.
    low, high : float
        Admissible closed range.
    integer : bool
        Whole numbers only.
    """

    default: float
    unit: str
    meaning: str
    low: float
    high: float
    integer: bool = False

    def check(self, name: str, value: Any, where: str = "sweep definition") -> float | int:
        """``value`` as a number in range, or ``ValueError`` naming the definition and the parameter."""
        ok = isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)
        ok = ok and math.isfinite(float(value)) and self.low <= float(value) <= self.high
        if ok and self.integer and float(value) != int(value):
            ok = False
        if not ok:
            kind = "a whole number" if self.integer else "a number"
            raise ValueError(
                f"{where}: {name} must be {kind} in [{self.low:g}, {self.high:g}], got {value!r}"
            )
        return int(value) if self.integer else float(value)


PARAMETERS: dict[str, Parameter] = {
    "freq_error": Parameter(0.0, "1", "design frequency / identified frequency - 1 (the design's error)",
                            -0.5, 1.0),
    "zeta_error": Parameter(0.0, "1", "design damping ratio - identified damping ratio (the design's error)",
                            -0.04, 0.2),
    "amplitude_mm": Parameter(20.0, "mm", "the pulse's cable displacement x_f", 0.5, 40.0),
    "speed_mm_s": Parameter(200.0, "mm/s", "the pulse's cable speed v_in", 1.0, 400.0),
    "disc_mass_scale": Parameter(1.0, "1", "the rig's disc mass / the tuned rig's", 0.2, 5.0),
    "stiffness_scale": Parameter(1.0, "1", "the rig's series cable stiffness k / the tuned rig's "
                                 "(below 1.42: the microstep spring bounds it)", 0.1, 1.42),
    "damping_scale": Parameter(1.0, "1", "the rig's damping (alpha and beta_chord) / the tuned rig's: "
                               "zeta at rest scales with it", 0.0, 5.0),
    "seed": Parameter(0, "1", "seed of the load-cell noise (ADC readings only)", 0, 2**31 - 1, True),
}  # fmt: skip
"""Every sweep parameter by name."""

DISTRIBUTIONS = ("uniform", "normal", "choice")
"""Sample distributions: ``{"uniform": [low, high]}``, ``{"normal": [mean, sd]}``,
``{"choice": [v, ...]}``."""

DESIGN_SHARE2 = 0.05
"""Without a measured map: the second mode's share given to the predicted map (which has none of its own)
so that it keeps its second mode for the ``multi-mode`` design. The design (both factors at their band
centres) does not depend on it; only the predicted residual in the design's provenance does."""

RUN_DEFAULTS = {"t_end_s": 12.0, "rate_hz": 1000.0, "t_up_s": 1.0, "t_down_s": 8.0}
"""The run's timing (the paper's pulse: up at 1 s, down at 8 s, 12 s at 1 kHz)."""

_KEYS = {"format", "version", "name", "description", "shapers", "designs_file", "custom_shapers", "grid",
         "sample", "fixed", "chunk_runs", "run", "identified", "mode_map"}  # fmt: skip


def _where(name: str) -> str:
    return f"sweep definition {name!r}" if name else "sweep definition"


@dataclass(frozen=True)
class SweepDefinition:
    """A sweep, checked (module docstring). Build it from a dict or JSON file, or with keywords.

    Attributes
    ----------
    name : str
        Short name (file names use it).
    shapers : tuple of str
        Shaper names: built-in (:data:`helpers.research.sweep.shaping.BUILTIN`) or custom.
    grid : dict of str to tuple
        Parameter -> values, in order.
    sample : dict or None
        ``{"n", "seed", "distributions": {parameter: {kind: args}}}``.
    fixed : dict of str to float
        Parameters held at a value other than their default.
    chunk_runs : int
        Runs per chunk.
    run : dict
        ``t_end_s``, ``rate_hz``, ``t_up_s``, ``t_down_s``.
    custom_shapers : dict
        Name -> entry (``{"family", "omega_d", "zeta", ["vtol"]}`` or ``{"amplitudes", "times",
        "reference_omega_d"}``).
    designs_file : str or None
        A design-set file whose shapers join ``custom_shapers`` when resolved.
    identified : dict or None
        ``{"omega_d", "zeta", "omega_d_std", "zeta_std"}``; None until resolved (then from the repository).
    mode_map : dict or str or None
        A map file's path, or the map as data (:meth:`helpers.research.modemap.ModeMap.to_dict`); None:
        :func:`helpers.research.robustness.default_map` (the measured map when the repository has one).
    description : str
        Free text.
    """

    name: str
    shapers: tuple[str, ...]
    grid: dict[str, tuple] = field(default_factory=dict)
    sample: dict[str, Any] | None = None
    fixed: dict[str, float] = field(default_factory=dict)
    chunk_runs: int = 4
    run: dict[str, float] = field(default_factory=lambda: dict(RUN_DEFAULTS))
    custom_shapers: dict[str, dict[str, Any]] = field(default_factory=dict)
    designs_file: str | None = None
    identified: dict[str, float] | None = None
    mode_map: Any = None
    description: str = ""

    def __post_init__(self) -> None:
        where = _where(self.name)
        if not isinstance(self.name, str) or not self.name or any(c in self.name for c in "/\\ "):
            raise ValueError(f"{where}: name must be a non-empty word without spaces or slashes")
        shapers = tuple(self.shapers)
        if not shapers or not all(isinstance(s, str) and s for s in shapers):
            raise ValueError(f"{where}: shapers must be a non-empty list of names")
        if len(set(shapers)) != len(shapers):
            raise ValueError(
                f"{where}: shapers are listed twice: {sorted({s for s in shapers if shapers.count(s) > 1})}"
            )
        object.__setattr__(self, "shapers", shapers)
        grid: dict[str, tuple] = {}
        for name, values in dict(self.grid).items():
            param = _parameter(name, where)
            if not isinstance(values, list | tuple) or not values:
                raise ValueError(f"{where}: grid.{name} must be a non-empty list of values")
            checked = tuple(param.check(name, v, where) for v in values)
            if len(set(checked)) != len(checked):
                raise ValueError(f"{where}: grid.{name} repeats a value")
            grid[name] = checked
        object.__setattr__(self, "grid", grid)
        object.__setattr__(self, "sample", _check_sample(self.sample, set(grid), where))
        fixed = {}
        for name, value in dict(self.fixed).items():
            param = _parameter(name, where)
            if name in grid or (self.sample and name in self.sample["distributions"]):
                raise ValueError(f"{where}: {name} is fixed and also on the grid or in the sample")
            fixed[name] = param.check(name, value, where)
        object.__setattr__(self, "fixed", fixed)
        if isinstance(self.chunk_runs, bool) or not isinstance(self.chunk_runs, int) or self.chunk_runs < 1:
            raise ValueError(f"{where}: chunk_runs must be a positive integer, got {self.chunk_runs!r}")
        run = dict(RUN_DEFAULTS)
        for key, value in dict(self.run).items():
            if key not in RUN_DEFAULTS:
                raise ValueError(f"{where}: unknown run setting {key!r}; known: {', '.join(RUN_DEFAULTS)}")
            if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
                raise ValueError(f"{where}: run.{key} must be a number, got {value!r}")
            run[key] = float(value)
        if not (0 < run["t_up_s"] < run["t_down_s"] < run["t_end_s"] and run["rate_hz"] > 0):
            raise ValueError(f"{where}: run needs 0 < t_up_s < t_down_s < t_end_s and rate_hz > 0, got {run}")
        object.__setattr__(self, "run", run)
        try:
            RunSettings.model_validate(run)
        except ValueError as exc:
            problem = str(exc).splitlines()
            raise ValueError(f"{where}: run: {problem[1].strip()}: {problem[2].strip()}") from None
        if self.n_runs > SWEEP_LIMITS["runs"]:
            limit = SWEEP_LIMITS["runs"]
            raise ValueError(f"{where}: {self.n_runs} runs, over the limit of {limit} in one sweep")
        if not isinstance(self.custom_shapers, Mapping):
            raise ValueError(f"{where}: custom_shapers must be an object of name -> shaper")
        for name, entry in self.custom_shapers.items():
            check_custom(str(name), entry)  # a family at a stated mode, or fixed impulses, within limits
        object.__setattr__(self, "custom_shapers", {str(k): dict(v) for k, v in self.custom_shapers.items()})

    # -- the runs -------------------------------------------------------------------------------------------
    @property
    def seeds(self) -> tuple[int, ...]:
        """The noise seeds every run is read with."""
        if "seed" in self.grid:
            return tuple(int(s) for s in self.grid["seed"])
        return (int(self.fixed.get("seed", PARAMETERS["seed"].default)),)

    @property
    def run_dims(self) -> tuple[str, ...]:
        """The dimensions of the runs, in order: the grid's (but ``seed``), ``sample``, ``shaper``."""
        dims = [d for d in self.grid if d != "seed"]
        if self.sample is not None:
            dims.append("sample")
        return (*dims, "shaper")

    @property
    def run_shape(self) -> tuple[int, ...]:
        """Sizes of :attr:`run_dims`."""
        sizes = {d: len(v) for d, v in self.grid.items()}
        if self.sample is not None:
            sizes["sample"] = int(self.sample["n"])
        sizes["shaper"] = len(self.shapers)
        return tuple(sizes[d] for d in self.run_dims)

    @property
    def n_runs(self) -> int:
        """Runs (integrations) in the sweep."""
        return int(np.prod(self.run_shape))

    @property
    def n_chunks(self) -> int:
        """Chunks (tasks)."""
        return -(-self.n_runs // self.chunk_runs)

    def chunk_range(self, chunk: int) -> range:
        """The flat run indices of ``chunk``."""
        if not 0 <= chunk < self.n_chunks:
            raise ValueError(f"chunk {chunk} is outside 0..{self.n_chunks - 1}")
        return range(chunk * self.chunk_runs, min((chunk + 1) * self.chunk_runs, self.n_runs))

    def sample_values(self) -> dict[str, np.ndarray]:
        """The sample's drawn coordinates, parameter -> array of ``n`` (empty without a sample).

        Drawn with ``numpy.random.default_rng(seed)``, one parameter after the other in the order of the
        definition, so the same definition always gives the same points.
        """
        if self.sample is None:
            return {}
        rng = np.random.default_rng(int(self.sample["seed"]))
        n = int(self.sample["n"])
        out: dict[str, np.ndarray] = {}
        for name, spec in self.sample["distributions"].items():
            ((kind, args),) = spec.items()
            if kind == "uniform":
                values = rng.uniform(args[0], args[1], n)
            elif kind == "normal":
                values = rng.normal(args[0], args[1], n)
            else:
                values = np.asarray(args)[rng.integers(0, len(args), n)]
            param = PARAMETERS[name]
            values = np.clip(values, param.low, param.high)
            out[name] = values.astype(np.int64) if param.integer else values.astype(float)
        return out

    def point(self, index: int, sample: dict[str, np.ndarray] | None = None) -> dict[str, Any]:
        """The parameters of run ``index`` (flat): every parameter but ``seed``, and ``shaper``."""
        idx = np.unravel_index(int(index), self.run_shape)
        values: dict[str, Any] = {k: p.default for k, p in PARAMETERS.items() if k != "seed"}
        values.update({k: v for k, v in self.fixed.items() if k != "seed"})
        sample = self.sample_values() if sample is None else sample
        for dim, i in zip(self.run_dims, idx, strict=True):
            if dim == "shaper":
                values["shaper"] = self.shapers[int(i)]
            elif dim == "sample":
                values.update({k: v[int(i)].item() for k, v in sample.items() if k != "seed"})
                values["sample"] = int(i)
            else:
                values[dim] = self.grid[dim][int(i)]
        return values

    # -- files ----------------------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The definition as JSON-safe data (:meth:`from_dict` reads it back)."""
        out: dict[str, Any] = {
            "format": FORMAT,
            "version": VERSION,
            "name": self.name,
            "description": self.description,
            "shapers": list(self.shapers),
            "grid": {k: list(v) for k, v in self.grid.items()},
            "sample": self.sample,
            "fixed": dict(self.fixed),
            "chunk_runs": self.chunk_runs,
            "run": dict(self.run),
            "custom_shapers": self.custom_shapers,
            "designs_file": self.designs_file,
            "identified": self.identified,
            "mode_map": self.mode_map,
        }
        return json.loads(json.dumps(out))

    def to_json(self) -> str:
        """Canonical JSON (sorted keys), the form stored with the results and compared on resumption."""
        return json.dumps(self.to_dict(), sort_keys=True, allow_nan=False)

    @classmethod
    def from_dict(cls, data: Any, base: Path | None = None) -> SweepDefinition:
        """Check and build a definition from JSON data (``base``: the folder relative paths start from)."""
        if not isinstance(data, dict):
            raise ValueError("a sweep definition must be a JSON object")
        name = data.get("name", "")
        where = _where(name if isinstance(name, str) else "")
        try:
            check_definition(data)  # the file's structure, types and sizes (helpers.research.sweep.schema)
        except ValueError as exc:
            raise ValueError(f"{where}: {exc}") from None
        if data.get("format", FORMAT) != FORMAT:
            raise ValueError(f"{where}: format must be {FORMAT!r}, got {data.get('format')!r}")
        if data.get("version", VERSION) != VERSION:
            raise ValueError(
                f"{where}: version {data.get('version')!r} is not supported (this code reads {VERSION})"
            )
        unknown = sorted(set(data) - _KEYS)
        if unknown:
            raise ValueError(f"{where}: unknown key(s) {', '.join(unknown)}")
        designs_file = data.get("designs_file")
        if designs_file is not None and base is not None and not Path(designs_file).is_absolute():
            designs_file = str(Path(base) / designs_file)
        mode_map = data.get("mode_map")
        if isinstance(mode_map, str) and base is not None and not Path(mode_map).is_absolute():
            mode_map = str(Path(base) / mode_map)
        return cls(
            name=name,
            shapers=tuple(data.get("shapers") or ()),
            grid=data.get("grid") or {},
            sample=data.get("sample"),
            fixed=data.get("fixed") or {},
            chunk_runs=data.get("chunk_runs", 4),
            run=data.get("run") or {},
            custom_shapers=data.get("custom_shapers") or {},
            designs_file=designs_file,
            identified=data.get("identified"),
            mode_map=mode_map,
            description=data.get("description", ""),
        )

    def resolved(self) -> SweepDefinition:
        """The definition with the identified mode, the mode map and the designs file's shapers filled in."""
        identified = self.identified
        if identified is None:
            m = load_identification()
            identified = {"omega_d": m.omega_d, "zeta": m.zeta, "omega_d_std": _finite(m.omega_d_std),
                          "zeta_std": _finite(m.zeta_std)}  # fmt: skip
        mode_map = self.mode_map
        if mode_map is None:
            mode_map = default_map(share2_if_predicted=DESIGN_SHARE2).to_dict()
        elif isinstance(mode_map, str):
            mode_map = load_map(mode_map).to_dict()
        else:
            ModeMap.from_dict(mode_map)  # checks it
        custom = dict(self.custom_shapers)
        if self.designs_file is not None:
            custom = {**load_designs(self.designs_file), **custom}
        return SweepDefinition(
            name=self.name, shapers=self.shapers, grid=dict(self.grid), sample=self.sample,
            fixed=dict(self.fixed), chunk_runs=self.chunk_runs, run=dict(self.run), custom_shapers=custom,
            designs_file=None, identified=json.loads(json.dumps(identified)), mode_map=mode_map,
            description=self.description,
        )  # fmt: skip


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _parameter(name: str, where: str) -> Parameter:
    if name not in PARAMETERS:
        raise ValueError(f"{where}: unknown parameter {name!r}; known: {', '.join(PARAMETERS)}")
    return PARAMETERS[name]


def _check_sample(sample: Any, on_grid: set[str], where: str) -> dict[str, Any] | None:
    if sample is None:
        return None
    if not isinstance(sample, Mapping):
        raise ValueError(f"{where}: sample must be an object with n, seed and distributions")
    n, seed = sample.get("n"), sample.get("seed", 0)
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"{where}: sample.n must be a positive integer, got {n!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"{where}: sample.seed must be an integer >= 0, got {seed!r}")
    dists = sample.get("distributions")
    if not isinstance(dists, Mapping) or not dists:
        raise ValueError(f"{where}: sample.distributions must name at least one parameter")
    out: dict[str, Any] = {}
    for name, spec in dists.items():
        param = _parameter(name, where)
        if name == "seed":
            raise ValueError(f"{where}: the noise seed is set on the grid or fixed, not sampled")
        if name in on_grid:
            raise ValueError(f"{where}: {name} is both on the grid and in the sample")
        if not isinstance(spec, Mapping) or len(spec) != 1 or next(iter(spec)) not in DISTRIBUTIONS:
            raise ValueError(f"{where}: sample.distributions.{name} must be one of {DISTRIBUTIONS}: [...]")
        ((kind, args),) = spec.items()
        if not isinstance(args, list | tuple) or not args:
            raise ValueError(f"{where}: sample.distributions.{name}.{kind} needs a list of numbers")
        if kind == "uniform":
            if len(args) != 2 or param.check(name, args[0], where) > param.check(name, args[1], where):
                raise ValueError(f"{where}: sample.distributions.{name}.uniform must be [low, high]")
        elif kind == "normal":
            ok = len(args) == 2 and all(isinstance(a, int | float) and math.isfinite(a) for a in args)
            if not ok or args[1] < 0:
                raise ValueError(f"{where}: sample.distributions.{name}.normal must be [mean, sd >= 0]")
        else:
            [param.check(name, a, where) for a in args]
        out[name] = {kind: [float(a) for a in args]}
    return {"n": int(n), "seed": int(seed), "distributions": out}


def load_definition(path: str | os.PathLike) -> SweepDefinition:
    """Read and check a sweep definition file (relative paths inside it start from its folder).

    Raises
    ------
    helpers.base.jsonfile.MissingDataError, helpers.base.jsonfile.DataFileError
        If the file is missing or is not JSON.
    ValueError
        One line naming the problem in the definition.
    """
    path = Path(path)
    data = read_json(path, "sweep definition", "write one as docs/sweeps.md shows")
    try:
        return SweepDefinition.from_dict(data, base=path.parent)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
