"""Worlds of the emulated boards whose twin is integrated by a chosen integrator (for tests pinned with RK4).

The twin's default integrator is the implicit step at 0.5 ms (``helpers.virtual.parameters``); tests whose
expected bytes or tolerances were set with RK4 at its stable step build their worlds inside
:func:`integrated_by` ``("rk4")``.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Iterator
from unittest import mock

from helpers.virtual import RigParameters


@contextlib.contextmanager
def integrated_by(integrator: str) -> Iterator[None]:
    """Worlds built inside (``build_world``) integrate their twin by ``integrator`` at its step."""
    import helpers.virtual.emulator.world as w

    planar, spatial = w.rig_parameters, w.spatial_rig

    def spatial_by(rig, **kw):
        twin = spatial(rig, **kw)
        return dataclasses.replace(twin, arm=twin.arm.with_integrator(integrator))

    with mock.patch.multiple(
        w,
        RigParameters=lambda: RigParameters().with_integrator(integrator),
        rig_parameters=lambda rig, **kw: planar(rig, **kw).with_integrator(integrator),
        spatial_rig=spatial_by,
    ):
        yield
