"""The twins built from rig files: the shipped files give the built-in rigs (docs/rig_file.md)."""

from __future__ import annotations

import dataclasses

import pytest

from helpers import rigfile
from helpers.virtual.from_rig import base_angle_deg, rig_parameters
from helpers.virtual.parameters import RigParameters
from helpers.virtual.spatial.from_rig import spatial_rig
from helpers.virtual.spatial.rig import PRESETS


def _same(a: object, b: object, path: str = "") -> list[str]:
    """Fields of two dataclasses that differ (floats beyond 1e-13 relative)."""
    if dataclasses.is_dataclass(a):
        out = []
        for f in dataclasses.fields(a):
            out += _same(getattr(a, f.name), getattr(b, f.name), f"{path}.{f.name}")
        return out
    if isinstance(a, tuple):
        if len(a) != len(b):
            return [path]
        return [p for i, (x, y) in enumerate(zip(a, b, strict=True)) for p in _same(x, y, f"{path}[{i}]")]
    if isinstance(a, float) and isinstance(b, float):
        return [] if a == pytest.approx(b, rel=1e-13, abs=0.0) else [f"{path}: {a!r} != {b!r}"]
    return [] if a == b else [f"{path}: {a!r} != {b!r}"]


def test_paper_file_gives_the_tuned_virtual_rig():
    assert _same(rig_parameters(rigfile.default_rig()), RigParameters()) == []


@pytest.mark.parametrize("name", ["paper", "four-tendon", "hanging"])
def test_shipped_files_give_the_spatial_presets(name):
    built = spatial_rig(rigfile.load(rigfile.RIGS_DIR / f"{name}.toml"))
    assert _same(built, PRESETS[name]()) == []


def test_second_rig_twin():
    p = rig_parameters(rigfile.load(rigfile.RIGS_DIR / "long-arm.toml"))
    assert (p.L, p.n_discs, p.d, p.spool_diameter, p.steps_per_rev, p.span_n) == (
        0.45,
        10,
        1.2e-3,
        0.04,
        1600,
        10.0,
    )
    assert p.k_cable == pytest.approx(71706.9638870073, rel=1e-12)  # the file's cable stiffness, recovered


def test_gravity_direction_to_base_angle():
    assert base_angle_deg((-1.0, 0.0, 0.0)) == 0.0
    assert base_angle_deg((0.0, 0.0, 1.0)) == pytest.approx(-90.0)
    with pytest.raises(ValueError, match="spatial twin"):
        base_angle_deg((0.0, 1.0, 0.0))
