"""Verification runs each in a fresh virtual world of its own, several at once with their plants in lanes.

``tune --lanes N`` (one tendon: :func:`helpers.research.tune.verify`; several:
:func:`helpers.research.tune_tendons.verify`): each run in a world built from the rig file (at rest, ``t =
0``, named ``<world>.<run>``), up to ``lanes`` of them in lockstep
(:class:`~helpers.virtual.emulator.lockstep.Lockstep`: their plants, :class:`~helpers.virtual.ArmPlant` or
:class:`~helpers.virtual.spatial.plant.SpatialPlant`, in the SIMD lanes of one kernel call). Each recording
is the one its run makes alone in such a world, whatever the lane width.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from helpers.rig import Rig
from helpers.virtual import ArmPlant
from helpers.virtual.emulator.lockstep import Lockstep
from helpers.virtual.emulator.world import build_world, forget_world, register_world
from helpers.virtual.spatial.plant import SpatialPlant

__all__ = ["in_lanes", "record_in_lanes"]


def in_lanes(rig: Rig) -> bool:
    """Whether ``rig`` is an in-process virtual rig whose runs can go in lanes (its plant a twin's)."""
    return rig.world is not None and isinstance(rig.world.plant, ArmPlant | SpatialPlant)


def _twin(plant: ArmPlant | SpatialPlant) -> Any:
    """What a :class:`Lockstep` lane is built from: the planar rig's parameters, or the spatial rig."""
    return plant.rig if isinstance(plant, SpatialPlant) else plant.params


def record_in_lanes(
    rig: Rig, jobs: Sequence[Any], names: Sequence[str], seeds: Sequence[int | None],
    record: Callable[[Rig, Any, str, int | None], Any], lanes: int,
    done: Callable[[int], Any] = lambda n: None,
) -> list[Any]:  # fmt: skip
    """Each job in a fresh world of its own (``<world>.<name>``), ``lanes`` at a time in lockstep.

    ``record(r, job, name, seed)`` makes one run's recording on the rig ``r`` (opened on the job's world);
    ``done(n)`` is told of every batch of ``n`` runs finished. Returns the recordings in the jobs' order.
    """
    out: list[Any] = []
    for start in range(0, len(jobs), lanes):
        batch = list(range(start, min(start + lanes, len(jobs))))
        worlds = [build_world(rig.rig, f"{rig.world.name}.{names[i]}") for i in batch]
        # one run alone keeps its own plant (the same bits, without idle lanes)
        lockstep = Lockstep([_twin(w.plant) for w in worlds]) if len(batch) > 1 else None
        for k, w in enumerate(worlds):
            if lockstep is not None:
                w.plant = lockstep.plant(k)
            register_world(w)

        def session(i: int, w: Any) -> Any:
            with Rig("virtual", rig.rig, calibration=list(rig.calibration), world=w.name) as r:
                return record(r, jobs[i], names[i], seeds[i])

        try:
            if lockstep is None:  # in this thread, as any run
                out.append(session(batch[0], worlds[0]))
            else:
                pairs = zip(batch, worlds, strict=True)
                out += lockstep.run([lambda i=i, w=w: session(i, w) for i, w in pairs])
        finally:
            for w in worlds:
                forget_world(w.name, rig.rig)
        done(len(batch))
    return out
