"""The twins built from rig files: the shipped files give the built-in rigs (docs/rig_file.md)."""

from __future__ import annotations

import dataclasses

import pytest

from helpers import rigfile
from helpers.virtual.emulator.world import build_world
from helpers.virtual.from_rig import base_angle_deg, planar_holds, rig_parameters, tendon_gravity
from helpers.virtual.parameters import RigParameters
from helpers.virtual.spatial.from_rig import spatial_rig
from helpers.virtual.spatial.plant import SpatialPlant
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


def _one_tendon_at(angle_deg: float) -> rigfile.RigFile:
    """The paper's rig with its one tendon at ``angle_deg`` (the horizontal arm, gravity along -x)."""
    paper = rigfile.default_rig()
    text = paper.text.replace('name = "paper"', f'name = "at-{angle_deg:g}"')
    return rigfile.loads(text + f"\n[[tendon]]\nangle_deg = {angle_deg!r}\n", f"at-{angle_deg:g}.toml")


def test_a_one_tendon_twin_sees_gravity_from_its_tendon():
    """docs/rig_file.md: gravity turned by minus the tendon's angle. At 180 deg the horizontal arm hangs
    towards its tendon (gravity along +x of the tendon's frame: clamp angle 180 deg); at 37 deg gravity has
    sin 37 = 0.60 of its magnitude across the tendon's plane: the planar twin does not hold it."""
    assert tendon_gravity(rigfile.default_rig()) == (-1.0, 0.0, 0.0) and planar_holds(rigfile.default_rig())
    under = _one_tendon_at(180.0)
    g = tendon_gravity(under)
    assert g == pytest.approx((1.0, 0.0, 0.0), abs=1e-15) and planar_holds(under)
    assert abs(rig_parameters(under).base_angle_deg) == pytest.approx(180.0)  # -180 and 180: one angle
    aside = _one_tendon_at(37.0)
    assert tendon_gravity(aside)[1] == pytest.approx(0.6018150231520483) and not planar_holds(aside)


def test_a_one_tendon_rig_out_of_gravitys_plane_is_the_spatial_twin_with_one_tendon():
    world = build_world(_one_tendon_at(37.0), "one-tendon-aside")
    assert isinstance(world.plant, SpatialPlant) and world.info["tendons"] == 1
    assert world.limits.axes == 1 and len(world.sensor) == 1  # one axis, one channel, as the file says
    planar = build_world(_one_tendon_at(180.0), "one-tendon-under")
    assert not isinstance(planar.plant, SpatialPlant) and abs(planar.plant.params.base_angle_deg) == 180.0
