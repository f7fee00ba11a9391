"""The twin's two integrators compared: what sets each one's step, what a second costs, convergence.

``docs/virtual_rig.md`` (section 2) states the results. Everything here drives the compiled kernels:

- **stability** (:func:`step_limit`, :func:`limiting_mode`): the Jacobian of one integrator step about the
  rest state, by central differences through the kernel (``planar_system``, ``spatial_system``), its spectral
  radius against the step, and the mode of the right-hand side's own Jacobian (the same differences) whose
  shape the step's growing eigenvector has where the step stops being stable;
- **cost** (:func:`segment_costs`): CPU seconds per simulated second of the plant benchmark's up move with
  12, 24, 36 and 48 arc elements, each integrator at the largest ``1 ms / n`` within 90 % of its limit;
- **convergence** (:func:`table_i_convergence`, :func:`four_tendon_convergence`): the implicit step at its
  step against RK4 at a quarter of it, on the Table II rows of the twelve Table I scenarios and the
  identification run, and on four-tendon bends (tensions, tip, steps taken).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd

from helpers.board.programmes import experiment_programme
from helpers.paper import numbers as paper
from helpers.paper.identify import identify
from helpers.paper.metrics import recording_metrics
from helpers.paper.shapers import design_tdfs
from helpers.virtual import _driver as drv
from helpers.virtual import _kernel as kern
from helpers.virtual.parameters import RigParameters
from helpers.virtual.plant import ArmPlant
from helpers.virtual.simulate import simulate
from helpers.virtual.spatial import _kernel as skern
from helpers.virtual.spatial.direction_map import bend_equilibrium
from helpers.virtual.spatial.plant import SpatialPlant, kernel_arrays
from helpers.virtual.spatial.rig import SpatialRig
from helpers.virtual.spatial.simulate import merge_programmes
from helpers.virtual.spatial.statics import spatial_model
from helpers.virtual.statics import ArcChain
from helpers.virtual.tuning import identification_run

__all__ = [
    "System", "planar_system", "spatial_system", "step_limit", "limiting_mode", "segment_costs",
    "bend_programmes", "table_i_convergence", "four_tendon_convergence",
]  # fmt: skip


@dataclass(frozen=True)
class System:
    """A twin at rest, as the kernels see it: its state, right-hand side and one step of either integrator.

    Attributes
    ----------
    y0 : numpy.ndarray
        The rest state.
    rhs : callable
        ``rhs(y) -> dy``.
    step : callable
        ``step(y, h, scheme) -> y1``: one step of ``h`` (no drive change), ``scheme`` a
        :data:`helpers.virtual._kernel.SCHEMES` name.
    labels : tuple of str
        What each position coordinate is (``"node 3"``, ``"rotor"``, ``"carriage"``...), for naming modes.
    positions : numpy.ndarray
        Where those coordinates sit in the state.
    mass : numpy.ndarray
        Their mass matrix at rest (to share a mode's kinetic energy among them).
    """

    y0: np.ndarray
    rhs: Callable[[np.ndarray], np.ndarray]
    step: Callable[[np.ndarray, float, str], np.ndarray]
    labels: tuple[str, ...]
    positions: np.ndarray
    mass: np.ndarray


def planar_system(params: RigParameters) -> System:
    """The planar rig at rest (:class:`helpers.virtual.plant.ArmPlant`'s kernel)."""
    plant = ArmPlant(params)
    a = plant._arr
    n = a.n
    work = kern.make_work(n, a.disc.shape[0])

    def rhs(y: np.ndarray) -> np.ndarray:
        return kern.rhs(y, 0.0, a.P, a.mb, a.Jb, a.disc, a.W, a.cw)[0]

    def step(y: np.ndarray, h: float, scheme: str) -> np.ndarray:
        # one step of h from t = 0 to a sample at h, no drive, no amplifier (split at a taut/slack transition)
        y = np.array(y, dtype=float)
        S = np.zeros(kern.N_STATE)
        S[kern.S_HMAX] = h
        none = np.zeros((1, 1))
        kern.advance(kern.SCHEMES.index(scheme), y, S, np.zeros((1, kern.N_LANE_INTS), np.int64),
                     np.array([[h]]), none, none, np.zeros(1, np.int64), a.P, a.P,
                     a.mb, a.Jb, a.disc, a.W, a.cw, *work, np.empty((1, 1)), np.empty((1, 1)),
                     np.empty((1, 1, n)))  # fmt: skip
        return y

    labels = tuple(f"node {i + 1}" for i in range(n)) + ("rotor", "carriage")
    mass = np.zeros((n + 2, n + 2))
    mass[:n, :n] = ArcChain(params).mass_matrix(a.y_rest[:n])
    mass[n, n] = params.drive_inertia
    mass[n + 1, n + 1] = params.carriage_mass
    positions = np.concatenate([np.arange(n), [2 * n, 2 * n + 2]])
    return System(np.array(a.y_rest), rhs, step, labels, positions, mass)


def spatial_system(rig: SpatialRig) -> System:
    """The spatial twin at rest (:class:`helpers.virtual.spatial.plant.SpatialPlant`'s kernel)."""
    a = kernel_arrays(rig)
    n, nt = a.n, a.nt
    m = 6 * n + 4 * nt
    drive = np.zeros(nt)

    def rhs(y: np.ndarray) -> np.ndarray:
        wb, wt, sp = skern.workspaces(n, nt, n)
        dy = np.empty(m)
        skern.rhs(y, dy, drive, a.geo, a.mb, a.Jd, a.Jp, a.tp, a.W, a.cw, wb, wt, sp, np.zeros((4, nt)))
        return dy

    def step(y: np.ndarray, h: float, scheme: str) -> np.ndarray:
        # one step of h from t = 0 to a sample at h, no drive, no amplifier (split at a taut/slack transition)
        y = np.array(y, dtype=float)
        S = np.zeros(skern.N_STATE)
        S[drv.D_HMAX] = h
        none = np.zeros((1, 1))
        z = np.zeros(nt)
        lints = np.zeros((1, skern.N_LANE_INTS), np.int64)
        # the plant's own (read-only) step angles: the same argument types as SpatialPlant's calls, so that
        # one compiled form of the kernel serves both (no step is given)
        skern.advance(kern.SCHEMES.index(scheme), y, S, lints, z.copy(), a.d_drive, z.copy(), z.copy(),
                      np.array([[h]]), none, np.zeros((1, 1), np.int64), none, np.zeros(1, np.int64), a.geo,
                      a.mb, a.Jd, a.Jp, a.tp, a.W, a.cw, *skern.make_work(n, nt), np.empty((1, 1, nt)),
                      np.empty((1, 1, nt)), np.empty((1, 1, 3 * n)),
                      np.empty((1, 1, 3)))  # fmt: skip
        return y

    labels = tuple(f"node {e + 1} {c}" for e in range(n) for c in ("bend a", "bend b", "twist"))
    labels += tuple(f"rotor {i + 1}" for i in range(nt)) + tuple(f"carriage {i + 1}" for i in range(nt))
    nq = 3 * n
    mass = np.zeros((nq + 2 * nt, nq + 2 * nt))
    mass[:nq, :nq] = spatial_model(rig).chain.mass_matrix(a.y_rest[:nq])
    for i in range(nt):
        mass[nq + i, nq + i] = rig.arm.drive_inertia
        mass[nq + nt + i, nq + nt + i] = rig.arm.carriage_mass
    positions = np.concatenate([np.arange(nq), 2 * nq + np.arange(nt), 2 * nq + 2 * nt + np.arange(nt)])
    return System(np.array(a.y_rest), rhs, step, labels, positions, mass)


def _jacobian(fun: Callable[[np.ndarray], np.ndarray], y: np.ndarray) -> np.ndarray:
    m = y.size
    J = np.empty((m, m))
    for j in range(m):
        d = 1e-7 * max(1.0, abs(y[j]))
        e = np.zeros(m)
        e[j] = d
        J[:, j] = (fun(y + e) - fun(y - e)) / (2.0 * d)
    return J


def _radius(system: System, h: float, scheme: str) -> float:
    S = _jacobian(lambda y: system.step(y, h, scheme), system.y0)
    return float(np.max(np.abs(np.linalg.eigvals(S))))


def step_limit(system: System, scheme: str, h_hi: float = 2e-3) -> float:
    """The largest step (s, up to ``h_hi``) whose step map at rest has spectral radius at most 1.

    A scan in 2 % increments from ``h_hi / 64``, refined by bisection (the radius is that of the linearised
    step, so it is the linear stability limit of the scheme on the twin itself).
    """
    ok = 1.0 + 1e-9
    hs = h_hi / 64 * 1.02 ** np.arange(int(math.log(64) / math.log(1.02)) + 2)
    lo = 0.0
    for h in hs[hs <= h_hi]:
        if _radius(system, float(h), scheme) > ok:
            hi = float(h)
            break
        lo = float(h)
    else:
        return h_hi
    for _ in range(8):
        mid = 0.5 * (lo + hi)
        if _radius(system, mid, scheme) > ok:
            hi = mid
        else:
            lo = mid
    return lo


def limiting_mode(system: System, scheme: str, h_limit: float) -> dict[str, object]:
    """The mode whose shape the step map's growing eigenvector has just beyond ``h_limit``.

    Returns ``omega`` (|pole|, rad/s), ``zeta``, ``where`` (the coordinate with the largest share of the
    mode's kinetic energy), ``share`` (that share) and ``match`` (the cosine between the two eigenvectors).
    """
    S = _jacobian(lambda y: system.step(y, 1.03 * h_limit, scheme), system.y0)
    mu, W = np.linalg.eig(S)
    w = W[:, int(np.argmax(np.abs(mu)))]
    ev, V = np.linalg.eig(_jacobian(system.rhs, system.y0))
    cos = np.abs(V.conj().T @ w) / (np.linalg.norm(V, axis=0) * np.linalg.norm(w))
    j = int(np.argmax(cos))
    shape = V[system.positions, j]
    energy = np.abs(np.real(np.conj(shape) * (system.mass @ shape)))
    k = int(np.argmax(energy))
    p = ev[j]
    return {"omega": float(abs(p)), "zeta": float(-p.real / abs(p)), "where": system.labels[k],
            "share": float(energy[k] / np.sum(energy)), "match": float(cos[j])}  # fmt: skip


def _stable_division(h_limit: float, margin: float = 0.9) -> float:
    n = max(1, math.ceil(1e-3 / (margin * h_limit) - 1e-9))
    return 1e-3 / n


def segment_costs(
    elements_per_disc: tuple[int, ...] = (1, 2, 3, 4), window_s: tuple[float, float] = (0.9, 1.4),
    rosw_step: float | None = None,
) -> pd.DataFrame:
    """Cost per simulated second of the up move with 12, 24, 36, 48 elements, and the modes that set the step.

    Each integrator runs at the largest ``1 ms / n`` within 90 % of its own stability limit at rest
    (:func:`step_limit`), the implicit one at most at ``rosw_step`` (default: the rig's choice,
    ``RigParameters(integrator="rosw")``'s step if set, else 0.5 ms); CPU time (``time.process_time``) of
    ``window_s`` of the 200 mm/s, 20 mm scenario, best of two.

    Returns
    -------
    pandas.DataFrame
        Per element count and integrator: ``elements``, ``integrator``, ``limit_ms``, ``step_ms``,
        ``cpu_s_per_s`` (CPU seconds per simulated second), ``steps``, ``mode_rad_s``, ``mode_zeta``,
        ``mode_where`` (the mode that sets the limit), ``unstable_rk4`` etc. as named.
    """
    cap = 5e-4 if rosw_step is None else float(rosw_step)
    prog, _ = experiment_programme(200.0, 20.0)
    st, sg = prog.step_times()
    t = np.arange(1, 12001) * 1e-3
    t = t[(t > window_s[0]) & (t <= window_s[1])]
    rows = []
    for m in elements_per_disc:
        base = RigParameters(elements_per_disc=m)
        system = planar_system(base)
        for scheme in kern.SCHEMES:
            limit = step_limit(system, scheme)
            mode = limiting_mode(system, scheme, limit) if limit < 2e-3 else None
            h = _stable_division(limit)
            if scheme == "rosw":
                h = min(h, cap)
            p = base.replace(integrator=scheme, max_step=h)
            plant = ArmPlant(p)
            best = math.inf
            for _ in range(2):
                plant.reset()
                pre = st <= t[0]
                plant.advance(t[:1], st[pre], sg[pre])
                sel = (st > t[0]) & (st <= t[-1])
                c0 = time.process_time()
                plant.advance(t[1:], st[sel], sg[sel])
                best = min(best, time.process_time() - c0)
            rows.append({
                "elements": 12 * m, "integrator": scheme, "limit_ms": 1e3 * limit, "step_ms": 1e3 * h,
                "cpu_s_per_s": best / (t[-1] - t[0]), "steps": plant.integrator_steps,
                "mode_rad_s": mode["omega"] if mode else math.nan,
                "mode_zeta": mode["zeta"] if mode else math.nan,
                "mode_where": mode["where"] if mode else "none below 2 ms",
            })  # fmt: skip
    return pd.DataFrame(rows)


def _table_ii(params: RigParameters) -> tuple[pd.DataFrame, tuple[float, float], float]:
    """The twelve Table I scenarios' rows (noise-free output), the identification, the CPU seconds taken."""
    zv, zvd = design_tdfs()
    shapers = {"unshaped": None, "zv": zv, "zvd": zvd}
    rows, cpu, plant = [], 0.0, ArmPlant(params)
    for v, x in paper.TABLE_I_CONDITIONS:
        for system in paper.SYSTEMS:
            prog, _ = experiment_programme(v, x, shaper=shapers[system])
            c0 = time.process_time()
            run = simulate(prog, params=params, seed=0, plant=plant)
            cpu += time.process_time() - c0
            m = recording_metrics(run.frame("output")).set_index("motion")
            for motion in ("Up", "Down"):
                rows.append({"v_in_mm_s": v, "x_f_mm": x, "system": system, "motion": motion,
                             "peak_n": float(m.loc[motion, "peak_n"]),
                             "overshoot_pct": float(m.loc[motion, "overshoot_pct"]),
                             "settling_ms": float(m.loc[motion, "settling_ms"]),
                             "steps": plant.integrator_steps})  # fmt: skip (that run's: reset per run)
    run = identification_run(params)
    res = identify(run.t, run.adc.astype(float), window=paper.IDENTIFICATION_RUN["window_s"])
    return pd.DataFrame(rows), (float(res.omega_d), float(res.zeta)), cpu


def table_i_convergence(params: RigParameters, reference_fraction: float = 0.25) -> dict[str, object]:
    """``params`` against RK4 at ``reference_fraction`` of its step: Table II rows and the identification.

    Returns
    -------
    dict
        ``rows`` (a DataFrame: each row's peak, overshoot and settling under ``params`` and the reference and
        their differences ``d_peak_n``, ``d_overshoot_pp``, ``d_settling_ms``, and each run's integrator steps
        ``steps``, ``ref_steps``), ``omega_d``, ``zeta`` (identified, ``params``), ``ref_omega_d``,
        ``ref_zeta``, ``cpu_s``, ``ref_cpu_s``.
    """
    ref = params.replace(integrator="rk4", max_step=params.max_step * reference_fraction)
    a, ida, ca = _table_ii(params)
    b, idb, cb = _table_ii(ref)
    rows = a.copy()
    for col in ("peak_n", "overshoot_pct", "settling_ms", "steps"):
        rows[f"ref_{col}"] = b[col].to_numpy()
    rows["d_peak_n"] = rows.peak_n - rows.ref_peak_n
    rows["d_overshoot_pp"] = rows.overshoot_pct - rows.ref_overshoot_pct
    rows["d_settling_ms"] = rows.settling_ms - rows.ref_settling_ms
    return {"rows": rows, "omega_d": ida[0], "zeta": ida[1], "ref_omega_d": idb[0], "ref_zeta": idb[1],
            "cpu_s": ca, "ref_cpu_s": cb}  # fmt: skip


def bend_programmes(rig: SpatialRig, direction_deg: float, bend_mm: float, v_mm_s: float) -> list:
    """Every tendon's up-hold-down programme for a bend: the paper's pulse timing, one time window.

    The bend's static spool displacements (:func:`~helpers.virtual.spatial.direction_map.bend_equilibrium`)
    each become a pulse (:func:`helpers.board.programmes.experiment_programme`) at the speed that makes it
    last ``bend_mm / v_mm_s``; a paying-out tendon runs the mirror image. A tendon that moves by less than a
    step gets no programme.
    """
    u = bend_equilibrium(rig, direction_deg, bend_mm).u * 1e3
    progs = []
    for i, ui in enumerate(u):
        n = round(abs(ui) / (rig.cable_per_step(i) * 1e3))
        if n == 0:
            progs.append(None)
            continue
        prog, _ = experiment_programme(v_mm_s * abs(ui) / bend_mm, abs(ui))
        t, s = prog.step_times()
        progs.append((t, s * np.sign(ui)))
    return progs


def four_tendon_convergence(
    rig: SpatialRig, bends: tuple[tuple[float, float], ...] = ((45.0, 20.0), (0.0, 20.0), (90.0, 10.0)),
    v_mm_s: float = 200.0, reference_fraction: float = 0.25, t_end: float = 12.0,
) -> pd.DataFrame:
    """The rig's own integrator against RK4 at ``reference_fraction`` of its step on bends of ``rig``.

    Each bend (direction in degrees, bend in mm of cable) runs up at 1 s and down at 8 s at ``v_mm_s``
    (:func:`bend_programmes`), 1 kHz samples to ``t_end``. Per bend and tendon: the largest difference of the
    amplifier output (N), the peak and the end tension of each move (N), the tip's largest difference (mm),
    and the integrator steps and transitions of both runs.
    """
    ref_rig = dataclasses.replace(rig, arm=rig.arm.replace(integrator="rk4"))
    h = SpatialPlant(rig).max_step
    t = np.arange(1, int(round(t_end * 1000)) + 1) * 1e-3
    rows = []
    for direction, bend in bends:
        progs = bend_programmes(rig, direction, bend, v_mm_s)
        times, tendons, signs, _ = merge_programmes(progs, rig.n_tendons)
        keep = times <= t[-1]
        steps = (times[keep], tendons[keep], signs[keep])
        a, b = SpatialPlant(rig), SpatialPlant(ref_rig, max_step=h * reference_fraction)
        c0 = time.process_time()
        oa = a.advance(t, *steps)
        c1 = time.process_time()
        ob = b.advance(t, *steps)
        c2 = time.process_time()
        up, down = (t >= 1.0) & (t < 8.0), t >= 8.0
        for i in range(rig.n_tendons):
            ya, yb = oa["output"][:, i], ob["output"][:, i]
            rows.append({
                "direction_deg": direction, "bend_mm": bend, "tendon": i + 1,
                "max_diff_n": float(np.max(np.abs(ya - yb))),
                "d_up_peak_n": float(ya[up].max() - yb[up].max()),
                "d_down_peak_n": float(ya[down].max() - yb[down].max()),
                "d_hold_n": float(np.mean(ya[(t > 7.0) & (t < 8.0)]) - np.mean(yb[(t > 7.0) & (t < 8.0)])),
                "tip_max_diff_mm": 1e3 * float(np.max(np.linalg.norm(oa["tip"] - ob["tip"], axis=1))),
                "steps": a.integrator_steps, "ref_steps": b.integrator_steps,
                "transitions": a.transitions, "ref_transitions": b.transitions,
                "cpu_s": c1 - c0, "ref_cpu_s": c2 - c1,
            })  # fmt: skip
    return pd.DataFrame(rows)
