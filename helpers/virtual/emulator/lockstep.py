"""Several in-process virtual rigs in lockstep: their plants integrated together, one lane each.

For ``tune``'s verification runs on the in-process virtual rig (``tune --lanes N``). Each session (a function
that opens a :class:`~helpers.rig.Rig` on its own world and records) runs in its own thread; its world's plant
is a :class:`LanePlant` that hands every ``advance`` call to the :class:`Lockstep`, which waits until every
session still running is waiting on its plant, integrates all their calls in one
:class:`~helpers.virtual.ArmLanes` (one lane per session; rigs of several tendons: one
:class:`~helpers.virtual.spatial.plant.SpatialLanes`, each call with its steps' tendons) and gives each
session its outputs. Nothing is
learnt in advance: whatever the host decides from the measured tension (the wait for rest, the checks), it
decides from the very outputs its plant would have given alone, so each recording is the one its session
makes alone (its lane takes exactly the steps its :class:`~helpers.virtual.ArmPlant` takes, and chunked
calls give the bits of one call).

Calls of different sessions hold different numbers of samples: a kernel call advances every lane by the
smallest number left (a lane's call in pieces: the same bits); a lane with nothing left in that call (its
session finished, or its call done) is parked: integrated a few microseconds on junk and put back as it was.
A lane that becomes unstable fails its own session only, as its plant alone would (``FloatingPointError`` at
that call and at every later one); the other lanes go on.
Python's threads run one at a time, and the sessions pass a baton (one runnable thread at a time, no
contention for the interpreter): the sessions' Python (boards, lines, host) stays serial, only the kernel's
arithmetic is shared.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from helpers.base.signals import Interrupted, run_guard
from helpers.virtual.parameters import RigParameters
from helpers.virtual.plant import LANE_WIDTHS, ArmLanes, _checked_times, unstable_error
from helpers.virtual.spatial import plant as spatial
from helpers.virtual.spatial.rig import SpatialRig

__all__ = ["Lockstep", "LanePlant"]

_PARK_DT = 1e-6
"""Spacing (s) of the junk samples a parked lane is integrated over (and then restored)."""


class LanePlant:
    """Lane ``k`` of a :class:`Lockstep` as a world's plant.

    ``advance(sample_times, step_times, step_signs)`` as :class:`~helpers.virtual.ArmPlant`'s, or (several
    tendons) ``advance(sample_times, step_times, step_tendons, step_signs)`` as
    :class:`~helpers.virtual.spatial.plant.SpatialPlant`'s.
    """

    def __init__(self, lockstep: Lockstep, k: int) -> None:
        self.lockstep, self.k = lockstep, k
        self.params = lockstep.params[k]

    @property
    def t(self) -> float:
        """The lane's simulated time, s."""
        return self.lockstep.time(self.k)

    def advance(self, sample_times: Any, *steps: Any) -> Any:
        """The outputs at ``sample_times`` (as the lane's plant alone gives them), integrated in lanes."""
        return self.lockstep.request(self.k, sample_times, *steps)


class Lockstep:
    """Up to ``max(LANE_WIDTHS)`` sessions whose plants share one kernel call per round.

    Parameters
    ----------
    params : sequence of RigParameters or of SpatialRig
        One rig per session (sharing :func:`~helpers.virtual.plant.lane_group`, or
        :func:`~helpers.virtual.spatial.plant.lane_group` for spatial rigs).
    """

    def __init__(self, params: Sequence[RigParameters | SpatialRig]) -> None:
        self.params = list(params)
        if not 1 <= len(self.params) <= max(LANE_WIDTHS):
            raise ValueError(f"Lockstep takes 1 to {max(LANE_WIDTHS)} sessions, got {len(self.params)}")
        self.spatial = all(isinstance(p, SpatialRig) for p in self.params)
        """Whether the lanes are spatial twins (calls with their steps' tendons, outputs as dicts)."""
        self.lanes: ArmLanes | spatial.SpatialLanes = (
            spatial.SpatialLanes(self.params) if self.spatial else ArmLanes(self.params))  # fmt: skip
        # one lock for the bookkeeping; one event wakes the broker (every running session waits on its
        # plant), one per lane wakes that session (its outputs are ready): no thread is woken for nothing
        self._lock = threading.Lock()
        self._ready = threading.Event()
        self._done = [threading.Event() for _ in self.params]
        self._pending: dict[int, tuple[np.ndarray, ...]] = {}
        self._results: dict[int, Any] = {}
        self._running: set[int] = set()
        self._queue: list[int] = []
        self._interrupt: BaseException | None = None
        """The signal the broker took (as an exception), handed to each session once."""
        self._told: set[int] = set()
        self._unstable: dict[int, float] = {}
        """Lanes that became unstable -> their time (s): parked for good, every later call refused."""
        self.kernel_calls = 0
        """Kernel calls made (rounds split into pieces)."""
        self.rounds = 0
        """Rounds served (one call of every waiting session)."""

    def plant(self, k: int) -> LanePlant:
        """Lane ``k``'s plant, to put in session ``k``'s world before its first ``advance``."""
        return LanePlant(self, k)

    def time(self, k: int) -> float:
        """Lane ``k``'s simulated time, s."""
        return self._unstable.get(k, float(self.lanes.t[k]))

    # --- the sessions' side --------------------------------------------------------------------------
    def request(self, k: int, sample_times: Any, *steps: Any) -> Any:
        """Session ``k``'s call: wait for its round, return its outputs (or the interrupt, once).

        ``steps``: the step times and signs (one tendon), or the times, tendons and signs (several).
        """
        if self._interrupt is not None and k not in self._told:
            self._told.add(k)
            raise Interrupted(getattr(self._interrupt, "signum", signal.SIGINT))
        kinds = (float, np.int64, float) if self.spatial else (float, float)
        steps = steps + ((),) * (len(kinds) - len(steps))
        if len(steps) != len(kinds):
            raise TypeError(f"advance takes sample_times and {len(kinds)} step arrays, got {len(steps)}")
        ts = np.ascontiguousarray(sample_times, dtype=float).reshape(-1)
        pairs = zip(steps, kinds, strict=True)
        arrays = tuple(np.ascontiguousarray(a, dtype=d).reshape(-1) for a, d in pairs)
        with self._lock:
            self._pending[k] = (ts, *arrays)
            self._pass_on()
        self._done[k].wait()
        self._done[k].clear()
        with self._lock:
            out = self._results.pop(k)
        if isinstance(out, BaseException):
            raise out
        return out

    def _pass_on(self) -> None:
        """Wake the next session of the round, or the broker once none is left (lock held).

        One thread runs at a time (a baton): the sessions' Python does not contend for the interpreter.
        """
        if self._queue:
            self._done[self._queue.pop(0)].set()
        elif self._running <= set(self._pending):
            self._ready.set()

    # --- the broker's side ---------------------------------------------------------------------------
    def run(self, sessions: Sequence[Callable[[], Any]]) -> list[Any]:
        """Run session ``k`` (a function of no arguments using :meth:`plant` ``(k)``) on lane ``k``, together.

        Returns each session's result; the first session's exception (by lane) is raised once all ended.
        """
        if len(sessions) != len(self.params):
            raise ValueError(f"{len(self.params)} lanes, {len(sessions)} sessions")
        results: list[Any] = [None] * len(sessions)
        errors: list[BaseException | None] = [None] * len(sessions)

        def body(k: int, fn: Callable[[], Any]) -> None:
            self._done[k].wait()  # its turn
            self._done[k].clear()
            try:
                results[k] = fn()
            except BaseException as exc:  # noqa: BLE001 - handed to the caller
                errors[k] = exc
            finally:
                with self._lock:
                    self._running.discard(k)
                    self._pass_on()

        self._running = set(range(len(sessions)))
        self._queue = list(range(1, len(sessions)))
        threads = [threading.Thread(target=body, args=(k, fn), daemon=True) for k, fn in enumerate(sessions)]
        for t in threads:
            t.start()
        self._done[0].set()
        # signals come to the main thread (the broker's): the first one is handed to every session at its
        # next plant call, as it would interrupt that session alone (its guard saves its run aborted, its
        # cleanup's calls are served as usual); none interrupts a kernel call
        with run_guard() as guard:
            while True:
                # a round: every running session waits on its plant (none is between calls)
                try:
                    with guard.interruptible():
                        self._ready.wait()
                except KeyboardInterrupt as exc:
                    self._interrupt = self._interrupt or exc
                    continue
                with self._lock:
                    self._ready.clear()
                    if not self._running:
                        break
                    if not self._running <= set(self._pending):
                        continue
                    calls = {k: self._pending.pop(k) for k in list(self._running)}
                try:
                    outs = self._serve(dict(calls))
                except BaseException as exc:  # noqa: BLE001 - a fault of the broker: every waiting session gets it
                    outs = dict.fromkeys(calls, exc)
                self.rounds += 1
                signum = guard.take_pending()
                if signum is not None and self._interrupt is None:
                    self._interrupt = Interrupted(signum)
                with self._lock:
                    self._results.update(outs)
                    self._queue = sorted(outs)
                    self._done[self._queue.pop(0)].set()
        for t in threads:
            t.join()
        for e in errors:
            if e is not None:
                raise e
        if self._interrupt is not None:  # it came after every session's last plant call: their runs are whole
            raise self._interrupt
        return results

    def _check(self, k: int, call: tuple[np.ndarray, ...]) -> None:
        """What lane ``k``'s plant alone refuses of ``call`` (``ValueError``)."""
        if self.spatial:
            ts, st, sk, sg = call
            spatial._checked(ts, st, sk, sg, self.time(k), self.params[k].n_tendons)
        else:
            _checked_times(*call, self.time(k))

    def _unstable_error(self, k: int, t_end: float) -> FloatingPointError:
        """What lane ``k``'s plant alone raises when its call to ``t_end`` (s) became unstable."""
        if self.spatial:
            return spatial.unstable_error(t_end, float(self.lanes.max_steps[k]))
        return unstable_error(t_end, self.params[k].max_step)

    def _serve(self, calls: dict[int, tuple[np.ndarray, ...]]) -> dict[int, Any]:
        """Integrate every lane's call; lanes without one are parked (restored after each kernel call).

        A call the lane's plant alone would refuse gets its ``ValueError``; a lane that becomes unstable gets
        its ``FloatingPointError`` (now and at every later call, as its plant alone); the others go on.
        """
        lanes = self.lanes
        nl = lanes.lanes
        failed: dict[int, Any] = {}
        for k, call in list(calls.items()):
            try:
                self._check(k, call)
            except ValueError as exc:
                failed[k] = exc
                del calls[k]
                continue
            ts = call[0]
            if k in self._unstable and ts.size:  # alone: its state is not finite, every call raises
                failed[k] = self._unstable_error(k, ts[-1])
                self._unstable[k] = float(ts[-1])
                del calls[k]
        nsteps = 3 if self.spatial else 2
        at = {k: 0 for k in calls}  # samples of its call each lane has had
        st_at = {k: 0 for k in calls}
        outs: dict[int, list[Any]] = {k: [] for k in calls}
        while True:
            left = {k: calls[k][0].size - at[k] for k in calls if calls[k][0].size - at[k] > 0}
            if not left:
                break
            m = min(left.values())
            rows = []
            steps: list[list[np.ndarray]] = [[] for _ in range(nsteps)]
            for k in range(nl):
                if k in left:
                    ts, st = calls[k][0], calls[k][1]
                    piece = ts[at[k] : at[k] + m]
                    j = int(np.searchsorted(st, piece[-1], side="right"))
                    rows.append(piece)
                    for i in range(nsteps):
                        steps[i].append(calls[k][1 + i][st_at[k] : j])
                    st_at[k] = j
                else:  # parked: a few microseconds of junk, then put back
                    rows.append(float(lanes.t[k]) + _PARK_DT * np.arange(1, m + 1))
                    for i in range(nsteps):
                        steps[i].append(np.empty(0, dtype=np.int64 if (self.spatial and i == 1) else float))
            saved = lanes.save()
            got = lanes.advance_all(np.stack(rows), *steps, check=False)
            self.kernel_calls += 1
            bad = set(lanes.unstable()) & set(left)
            for k in bad:  # its session gets what its plant alone raises; its lane is parked from now on
                failed[k] = self._unstable_error(k, calls[k][0][-1])
                self._unstable[k] = float(calls[k][0][-1])
                del calls[k], outs[k]
            lanes.restore(saved, [k for k in range(nl) if k not in left or k in bad])
            for k in set(left) - bad:
                piece = {key: v[k].copy() for key, v in got.items()} if self.spatial else got[0][k].copy()
                outs[k].append(piece)
                at[k] += m
        for k, call in calls.items():
            if st_at[k] != call[1].size:
                raise ValueError(f"lane {k}: steps after its last sample time")
        return failed | {k: self._joined(v, k) for k, v in outs.items()}

    def _joined(self, pieces: list[Any], k: int) -> Any:
        """Lane ``k``'s outputs of one call from the pieces it was served in."""
        if not self.spatial:
            return np.concatenate(pieces) if pieces else np.empty(0)
        if not pieces:
            n, nt = 3 * spatial.kernel_arrays(self.params[k]).n, self.params[k].n_tendons
            return {"output": np.empty((0, nt)), "tension": np.empty((0, nt)), "q": np.empty((0, n)),
                    "tip": np.empty((0, 3))}  # fmt: skip
        return {key: np.concatenate([p[key] for p in pieces]) for key in pieces[0]}
