"""The one schema of a sweep definition's file and of a sweep dataset's attributes (pydantic), with limits.

:class:`DefinitionFile` checks the JSON's structure, types and sizes before :class:`SweepDefinition` checks
what depends on the parameters (their ranges, the grid against the sample); :func:`check_custom` checks a
custom shaper wherever it comes from (the definition, a design-set file); :class:`DatasetAttrs` checks a
stored dataset's attributes. A violation is one line naming the field (:func:`problem`), e.g.
``grid.freq_error: Input should be a valid list``.

The limits (:data:`SWEEP_LIMITS`): a run lasts at most 120 s at 100-2000 Hz (the paper's pulse is 12 s at
1 kHz); a sweep has at most 200 000 runs (the full atlas has about 17 000), a grid at most 10 000 values per
parameter; a shaper at most 64 impulses over at most 5 s.
"""

from __future__ import annotations

import json
import math
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    StringConstraints,
    Tag,
    ValidationError,
    model_validator,
)

from helpers.research.families import FAMILIES

SWEEP_LIMITS = {
    "run_s": 120.0,
    "rate_hz": (100.0, 2000.0),  # the sweep format's sample rates: the paper's DAQ board's (rigs/paper.toml)
    "runs": 200_000,
    "grid_values": 10_000,
    "shapers": 256,
    "chunk_runs": 10_000,
    "impulses": 64,
    "shaper_s": 5.0,
}
"""How big a sweep may be (module docstring)."""

Finite = Annotated[float, Field(allow_inf_nan=False)]
Name = Annotated[
    str, StringConstraints(min_length=1, max_length=100, pattern=r"^[A-Za-z0-9][A-Za-z0-9_.+-]*$")
]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=False)


class RunSettings(_Strict):
    """``run``: the pulse's timing and the sampling (s, Hz)."""

    t_end_s: Finite = Field(12.0, gt=0, le=SWEEP_LIMITS["run_s"])
    rate_hz: Finite = Field(1000.0, ge=SWEEP_LIMITS["rate_hz"][0], le=SWEEP_LIMITS["rate_hz"][1])
    t_up_s: Finite = Field(1.0, ge=0)
    t_down_s: Finite = Field(8.0, ge=0)


class Sample(_Strict):
    """``sample``: ``n`` points drawn with ``seed``, one distribution per parameter."""

    n: int = Field(ge=1, le=SWEEP_LIMITS["runs"])
    seed: int = Field(0, ge=0, le=2**32 - 1)
    distributions: dict[Name, dict[Literal["uniform", "normal", "choice"], list[Finite]]] = Field(
        min_length=1
    )


class FamilyShaper(_Strict):
    """A custom shaper of a family at a stated mode."""

    family: Literal[tuple(FAMILIES)]  # type: ignore[valid-type]
    omega_d: Finite = Field(gt=0, le=10_000)
    zeta: Finite = Field(ge=0, lt=1)
    vtol: Finite | None = Field(None, gt=0, lt=1)
    duration_s: Finite | None = None  # a design set's notes on the entry
    objective_pct: Finite | None = None

    @model_validator(mode="after")
    def _zeta_in_range(self) -> FamilyShaper:
        lo, hi = FAMILIES[self.family].zeta_range
        if not lo <= self.zeta <= hi:
            raise ValueError(f"{self.family} holds for {lo} <= zeta <= {hi}, got {self.zeta}")
        return self


class ImpulseShaper(_Strict):
    """A custom shaper of fixed impulses (times in s; the amplitudes sum to 1)."""

    amplitudes: list[Finite] = Field(min_length=1, max_length=SWEEP_LIMITS["impulses"])
    times: list[Finite] = Field(min_length=1, max_length=SWEEP_LIMITS["impulses"])
    reference_omega_d: Finite | None = Field(None, gt=0, le=10_000)
    name: str | None = None
    duration_s: Finite | None = None  # a design set's notes on the entry
    objective_pct: Finite | None = None

    @model_validator(mode="after")
    def _impulses(self) -> ImpulseShaper:
        if len(self.amplitudes) != len(self.times):
            raise ValueError("amplitudes and times must pair up")
        if abs(sum(self.amplitudes) - 1.0) > 1e-6:
            raise ValueError(f"the amplitudes sum to {sum(self.amplitudes):.6g}, not 1")
        if any(abs(a) > 2 for a in self.amplitudes):  # negative impulses are allowed (UM-ZV's are +-1)
            raise ValueError("an amplitude beyond +-2")
        if self.times[0] < 0 or any(b < a for a, b in zip(self.times, self.times[1:], strict=False)):
            raise ValueError("times must start at >= 0 and not decrease")
        if self.times[-1] > SWEEP_LIMITS["shaper_s"]:
            raise ValueError(f"the shaper lasts {self.times[-1]:g} s, over {SWEEP_LIMITS['shaper_s']:g} s")
        return self


def _custom_kind(entry: Any) -> str:
    return "by-family" if isinstance(entry, dict) and "family" in entry else "by-impulses"


CustomShaper = Annotated[
    Annotated[FamilyShaper, Tag("by-family")] | Annotated[ImpulseShaper, Tag("by-impulses")],
    Discriminator(_custom_kind),
]
"""A custom shaper: a family at a stated mode (it has ``family``), else fixed impulses."""

_TAGS = {"by-family", "by-impulses"}


class DefinitionFile(_Strict):
    """A sweep definition's JSON (``docs/sweeps.md``)."""

    format: Literal["continuum-arm-sweep"] = "continuum-arm-sweep"
    version: Literal[1] = 1
    name: Name
    description: str = Field("", max_length=10_000)
    shapers: list[Name] = Field(min_length=1, max_length=SWEEP_LIMITS["shapers"])
    designs_file: str | None = None
    custom_shapers: dict[Name, CustomShaper] = Field(default_factory=dict)
    grid: dict[Name, list[Finite]] = Field(default_factory=dict)
    sample: Sample | None = None
    fixed: dict[Name, Finite] = Field(default_factory=dict)
    chunk_runs: int = Field(4, ge=1, le=SWEEP_LIMITS["chunk_runs"])
    run: RunSettings = Field(default_factory=RunSettings)
    identified: dict[str, Finite | None] | None = None
    mode_map: str | dict[str, Any] | None = None

    @model_validator(mode="after")
    def _size(self) -> DefinitionFile:
        runs = len(self.shapers) * (self.sample.n if self.sample is not None else 1)
        for name, values in self.grid.items():
            if not 1 <= len(values) <= SWEEP_LIMITS["grid_values"]:
                raise ValueError(f"grid.{name}: 1 to {SWEEP_LIMITS['grid_values']} values, got {len(values)}")
            runs *= len(values) if name != "seed" else 1
        if runs > SWEEP_LIMITS["runs"]:
            raise ValueError(f"{runs} runs, over the limit of {SWEEP_LIMITS['runs']} runs in one sweep")
        return self


class DatasetAttrs(BaseModel):
    """The attributes every sweep dataset carries (more are allowed)."""

    model_config = ConfigDict(extra="allow")

    definition: str
    rig_parameters: str
    code_version: str
    physics_fingerprint: str
    source: Literal["virtual-rig"]
    refused_runs: str = "{}"

    @model_validator(mode="after")
    def _json(self) -> DatasetAttrs:
        for key in ("definition", "rig_parameters", "refused_runs"):
            try:
                value = json.loads(getattr(self, key))
            except (json.JSONDecodeError, RecursionError):
                raise ValueError(f"{key}: not JSON") from None
            if not isinstance(value, dict):
                raise ValueError(f"{key}: not a JSON object")
        if not isinstance(json.loads(self.definition).get("name"), str):
            raise ValueError("definition.name: missing")
        return self


def problem(exc: ValidationError) -> str:
    """The first error of a validation as one line: ``<field.path>: <message>``."""
    err = exc.errors(include_url=False)[0]
    where = ".".join(str(p) for p in err["loc"] if p not in _TAGS)
    msg = str(err["msg"]).removeprefix("Value error, ")
    return f"{where}: {msg}" if where else msg


def check_definition(data: Any) -> None:
    """Validate a definition's JSON against :class:`DefinitionFile`; ``ValueError`` with one line."""
    try:
        DefinitionFile.model_validate(data)
    except ValidationError as exc:
        raise ValueError(problem(exc)) from None
    except RecursionError:
        raise ValueError("nested too deeply") from None


def check_custom(name: str, entry: Any) -> None:
    """Validate one custom shaper (a family at a mode, or fixed impulses); ``ValueError`` with one line."""
    model = FamilyShaper if _custom_kind(entry) == "by-family" else ImpulseShaper
    try:
        model.model_validate(entry)
    except ValidationError as exc:
        raise ValueError(f"custom shaper {name!r}: {problem(exc)}") from None


def check_attrs(attrs: dict[str, Any]) -> None:
    """Validate a dataset's attributes against :class:`DatasetAttrs`; ``ValueError`` with one line."""
    try:
        DatasetAttrs.model_validate(attrs)
    except ValidationError as exc:
        raise ValueError(problem(exc)) from None


def finite(x: Any) -> bool:
    """True for a finite real number (not a bool)."""
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)
