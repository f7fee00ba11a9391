"""Test doubles for the rig tests: a tiny deterministic plant and sensor, a spying port, a rig factory."""

from __future__ import annotations

import itertools
import math

import numpy as np

from helpers import rigfile
from helpers.rig import Rig
from helpers.virtual.emulator.boards import build_limits
from helpers.virtual.emulator.world import VirtualWorld, forget_world, register_world

MM_PER_STEP = math.pi * 65.0 / 800  # the paper's rig, by hand: the test double's cable per step
K_N_PER_MM = 0.5
PRETENSION_N = 1.0
GAIN = 40.0
OFFSET = 60.0

_names = itertools.count()


class SpringPlant:
    """Quasi-static cable: tension = pretension + k * cable displacement (no dynamics, exact and fast)."""

    def __init__(self) -> None:
        self.t = 0.0
        self.steps = 0
        self.calls = 0

    def advance(self, sample_times, step_times=(), step_signs=()):
        ts = np.asarray(sample_times, dtype=float)
        st = np.asarray(step_times, dtype=float)
        sg = np.asarray(step_signs, dtype=np.int64)
        assert ts.size and np.all(np.diff(ts) > 0) and ts[0] >= self.t - 1e-12
        assert st.size == 0 or (st[0] > self.t - 1e-12 and st[-1] <= ts[-1] + 1e-12)
        k = np.searchsorted(st, ts, side="right")
        pos = self.steps + np.concatenate([[0], np.cumsum(sg)])[k]
        self.steps += int(sg.sum())
        self.t = float(ts[-1])
        self.calls += 1
        return PRETENSION_N + K_N_PER_MM * MM_PER_STEP * pos


class LinearSensor:
    """counts = round(OFFSET + GAIN * tension), clipped to 0..1023, no noise."""

    def counts(self, tension):
        return np.clip(np.rint(OFFSET + GAIN * np.asarray(tension, dtype=float)), 0, 1023).astype(np.int64)

    def reseed(self, seed):
        self.seed = seed  # no noise to seed; remembered so that tests can see it was asked


CALIBRATION = {
    "newtons_per_count": 1.0 / GAIN,
    "offset_counts": OFFSET,
    "mm_per_step": MM_PER_STEP,
    "origin": "test double",
}


def make_world(rig: rigfile.RigFile | None = None, **kwargs) -> VirtualWorld:
    """Register a fresh world with the test doubles, its boards built for ``rig`` (default the paper's)."""
    name = f"test{next(_names)}"
    forget_world(name)
    limits = build_limits(rigfile.default_rig() if rig is None else rig)
    return register_world(VirtualWorld(SpringPlant(), LinearSensor(), name=name, limits=limits, **kwargs))


def make_rig(
    daq_options: str = "", stepper_options: str = "", rig: rigfile.RigFile | None = None,
    silence_s: float = 2.0, **world_kwargs,
) -> tuple[Rig, VirtualWorld]:
    """A connected rig on a fresh test-double world; options are URL query strings like '&hang_at=1'.

    ``rig``: the rig file (default the paper's), the boards built for it.
    """
    rig = rigfile.default_rig() if rig is None else rig
    world = make_world(rig, **world_kwargs)
    rig = Rig(
        "virtual",
        rig,
        calibration=dict(CALIBRATION, mm_per_step=rigfile.derived(rig).mm_per_step[0]),
        world=world.name,
        timeout=0.5,
        hello_timeout=1.0,
        silence_s=silence_s,
        daq_options=daq_options,
        stepper_options=stepper_options,
    )
    return rig, world


class SpyPort:
    """Wraps a serial port and records every byte written."""

    def __init__(self, inner) -> None:
        self.inner = inner
        self.written = bytearray()

    def write(self, data):
        self.written += data
        return self.inner.write(data)

    def __getattr__(self, name):
        return getattr(self.inner, name)
