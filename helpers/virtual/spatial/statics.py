"""The spatial twin's statics and small vibrations: rest state, equilibria, linearisation, modes.

- :func:`spatial_model` builds (and caches) the rest state: every tendon at its pretension with every stepper
  at position 0 and the arm in equilibrium under gravity (gravity and tensions raised together), the
  references of every cable, and the high-mode damping floor (the planar rig's rule, on the spatial modes).
- :func:`equilibrium` is the frictionless equilibrium with each tendon's spool held at a displacement ``u_i``
  from rest (cable pulled: ``u_i > 0``); a tendon may instead be held at a prescribed tension
  (``tension=``), the statics then saying how far its spool must turn.
- :func:`linearise` gives the small vibrations about an equilibrium with the spools held (``rotor="locked"``)
  or the rotors on their microstep springs (``"free"``, the rig as it runs): poles, damping, mode shapes,
  what each mode's tip does and each mode's weight in every tendon's tension.

Newton uses the exact Hessian (complex step on the analytic gradient of
:class:`~helpers.virtual.spatial.chain.SpatialChain`), with continuation from rest in steps of at most 1 mm
of every spool.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy import linalg

from helpers.virtual.spatial.chain import Control, SpatialChain
from helpers.virtual.spatial.rig import SpatialRig
from helpers.virtual.statics import DECAY_S, floor_modes, modal_state, rk4_stable_step

__all__ = [
    "SpatialModel",
    "spatial_model",
    "SpatialEquilibrium",
    "equilibrium",
    "rest_equilibrium",
    "SpatialLinearisation",
    "linearise",
    "modal_analysis",
    "stable_max_step",
    "equilibrium_state",
    "DECAY_S",
]


def _newton(chain: SpatialChain, q0: np.ndarray, ctrl: Control, g: np.ndarray | None = None,
            tol: float = 1e-12, max_iter: int = 60, forces: dict | None = None) -> np.ndarray:  # fmt: skip
    """Damped Newton on the potential's gradient with the exact Hessian (``forces``: constant point loads)."""
    q = np.array(q0, dtype=float)
    scale = float(chain.kb)
    g0, _, _ = chain.potential_grad(q, ctrl, g, forces)
    for _ in range(max_iter):
        norm = np.linalg.norm(g0) / scale
        if norm < tol:
            return q
        dq = -np.linalg.solve(chain.hessian(q, ctrl, g, forces), g0)
        step = 1.0
        while True:
            qn = q + step * dq
            gn, _, _ = chain.potential_grad(qn, ctrl, g, forces)
            if np.linalg.norm(gn) / scale < norm or step < 1e-3:
                break
            step *= 0.5
        q, g0 = qn, gn
    if np.linalg.norm(g0) / scale > 1e-8:
        raise RuntimeError(f"static equilibrium did not converge (residual {np.linalg.norm(g0) / scale:.2e})")
    return q


@dataclass(frozen=True)
class SpatialModel:
    """The rest state and every reference the statics and the kernel share (``docs/spatial_twin.md``).

    Attributes
    ----------
    rig : SpatialRig
    chain : SpatialChain
    q_rest : numpy.ndarray
        Rest shape (3N).
    lam_rest : numpy.ndarray
        Tensions at rest (the pretensions), N.
    ell_rest : numpy.ndarray
        Tendon paths at rest, m.
    H_rest : numpy.ndarray
        Bowing compliance at rest (nt x nt), m/N.
    psi0 : numpy.ndarray
        Rotor angles at rest (the static lag behind command 0), rad.
    s1_ref, ell_ref_arm : numpy.ndarray
        References of the spool-side stretch ``R psi - x_c - s1_ref`` and of the arm-side stretch
        ``x_c + ell(q) - ell_ref_arm`` (carriage at ``x_c = 0`` at rest).
    ell_ref_series : numpy.ndarray
        Reference of the statics' series stretch ``u + ell(q) - ell_ref_series`` (spool held at ``u``).
    k1, k2, kc : numpy.ndarray
        Spool-side, arm-side and series cable stiffnesses, N/m.
    floor_W, floor_c : numpy.ndarray
        The high-mode damping floor ``C_f = W^T diag(c) W``.
    """

    rig: SpatialRig
    chain: SpatialChain = field(repr=False)
    q_rest: np.ndarray = field(repr=False)
    lam_rest: np.ndarray
    ell_rest: np.ndarray
    H_rest: np.ndarray = field(repr=False)
    psi0: np.ndarray
    s1_ref: np.ndarray
    ell_ref_arm: np.ndarray
    ell_ref_series: np.ndarray
    k1: np.ndarray
    k2: np.ndarray
    kc: np.ndarray
    floor_W: np.ndarray = field(repr=False)
    floor_c: np.ndarray = field(repr=False)

    def series_control(self, u: np.ndarray, lam: np.ndarray | None = None, rotor: str = "locked") -> Control:
        """The statics' control: spools held at ``u`` (m), or tendons with a finite ``lam`` held at it.

        ``rotor="free"``: ``u`` is each stepper's commanded cable displacement and its rotor lags it as its
        torque law says (the rig at rest after a move); ``"locked"``: the spool itself sits at ``u``.
        """
        nt = self.rig.n_tendons
        lam = np.full(nt, np.nan) if lam is None else np.asarray(lam, dtype=float)
        e0 = np.asarray(u, dtype=float) - self.ell_ref_series
        if rotor == "locked":
            return Control(lam=lam, e0=e0, kinv=1.0 / self.kc)
        if rotor != "free":
            raise ValueError(f"rotor must be 'locked' or 'free', got {rotor!r}")
        return Control(lam=lam, e0=e0 - self.R * self.psi0, kinv=1.0 / self.kc, motor=self.motor)

    @property
    def R(self) -> np.ndarray:
        """Spool radii, m."""
        return np.array([self.rig.spool_radius(i) for i in range(self.rig.n_tendons)])

    @property
    def motor(self) -> tuple:
        """``(R, T_h, N_r, sin_law)`` of the steppers (:class:`~helpers.virtual.spatial.chain.Control`)."""
        th = np.array([t.holding_torque_n_m for t in self.rig.tendons])
        return (self.R, th, float(self.rig.arm.rotor_teeth), self.rig.arm.torque_law == "sin")


def _floor(
    chain: SpatialChain, q: np.ndarray, lam: np.ndarray, ell: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The planar rig's high-mode floor on the spatial arm's undamped modes at rest.

    The tendons are springs of their series stiffness (microstep spring and cables) carrying the
    pretension; ``c = 2 zeta_f omega s(omega)``, ``s = 1 / (1 + (omega_f / omega)^8)``.
    """
    rig = chain.rig
    p = rig.arm
    if p.floor_zeta == 0.0:
        return np.zeros((0, chain.nq)), np.zeros(0)
    ks = np.array([rig.k_series(i) for i in range(rig.n_tendons)])
    H = chain.bow_matrix(q)
    e = (1.0 / ks) * lam + H @ lam
    ctrl = Control(lam=np.full(rig.n_tendons, np.nan), e0=e - ell, kinv=1.0 / ks)
    K = chain.hessian(q, ctrl)
    return floor_modes(K, chain.mass_matrix(q), p.floor_omega, p.floor_zeta)


@functools.lru_cache(maxsize=32)
def spatial_model(rig: SpatialRig) -> SpatialModel:
    """The rest state of ``rig`` and the references that make it carry the pretensions (cached)."""
    chain = SpatialChain(rig)
    lam0 = rig.pretensions
    nt = rig.n_tendons
    q = np.zeros(chain.nq)
    stages = 10
    for i in range(1, stages + 1):
        f = i / stages
        ctrl = Control(lam=lam0 * f, e0=np.zeros(nt), kinv=np.ones(nt))
        q = _newton(chain, q, ctrl, g=chain.gvec * f)
    ell = chain.tendon_lengths(q)
    H = chain.bow_matrix(q)
    k1 = np.array([rig.k_spool_side(i) for i in range(nt)])
    k2 = np.array([rig.k_arm_side(i) for i in range(nt)])
    kc = np.array([rig.k_cable(i) for i in range(nt)])
    psi0 = np.array([-rig.static_lag(i, lam0[i]) for i in range(nt)])
    R = np.array([rig.spool_radius(i) for i in range(nt)])
    W, cw = _floor(chain, q, lam0, ell)
    arrays = dict(q_rest=q, lam_rest=lam0.copy(), ell_rest=ell, H_rest=H, psi0=psi0,
                  s1_ref=R * psi0 - lam0 / k1, ell_ref_arm=ell - (lam0 / k2 + H @ lam0),
                  ell_ref_series=ell - (lam0 / kc + H @ lam0), k1=k1, k2=k2, kc=kc, floor_W=W,
                  floor_c=cw)  # fmt: skip
    for a in arrays.values():
        a.setflags(write=False)
    return SpatialModel(rig=rig, chain=chain, **arrays)


@dataclass(frozen=True)
class SpatialEquilibrium:
    """A static equilibrium of the spatial arm (spools held).

    Attributes
    ----------
    u : numpy.ndarray
        Each tendon's cable displacement at its spool from rest, m (for a tension-controlled tendon: what
        the statics needs).
    command : numpy.ndarray
        Each stepper's commanded cable displacement from rest, m: ``u`` plus the change of its rotor's lag
        (``u`` itself where the statics held the spools).
    q : numpy.ndarray
        Element rotation vectors (3N), rad.
    tension : numpy.ndarray
        Tendon tensions, N.
    positions : numpy.ndarray
        Node positions (N+1, 3), clamp first, m.
    """

    u: np.ndarray
    command: np.ndarray
    q: np.ndarray
    tension: np.ndarray
    positions: np.ndarray

    @property
    def tip(self) -> np.ndarray:
        """Tip position, m."""
        return self.positions[-1]


def _make(model: SpatialModel, q: np.ndarray, ctrl: Control) -> SpatialEquilibrium:
    chain = model.chain
    _, lam, ell = chain.potential_grad(q, ctrl)
    lam = np.real(lam)
    H = chain.bow_matrix(q)
    u = lam / model.kc + H @ lam - ell + model.ell_ref_series  # where the spools sit (taut or at the verge)
    rig = model.rig
    fixed = ctrl.tension_controlled
    lag = np.array([rig.static_lag(i, lam[i]) for i in range(rig.n_tendons)])
    shift = model.R * (lag + model.psi0)  # the rotor's lag now less at rest (psi0 = -lag at rest)
    if ctrl.motor is None:  # the spools were held
        u = np.where(fixed, u, ctrl.e0 + model.ell_ref_series)
        command = u + shift
    else:  # the steppers were commanded (a slack tendon's spool: its command less the rest lag's change)
        command = np.where(fixed, u + shift, ctrl.e0 + model.ell_ref_series + model.R * model.psi0)
        u = np.where(fixed | (lam > 0), np.where(fixed, u, command - shift), command - shift)
    return SpatialEquilibrium(u=u, command=command, q=q, tension=lam, positions=chain.positions(q))


def rest_equilibrium(rig: SpatialRig) -> SpatialEquilibrium:
    """The rest state as an equilibrium (every spool at 0, every tendon at its pretension)."""
    model = spatial_model(rig)
    return _make(model, model.q_rest.copy(), model.series_control(np.zeros(rig.n_tendons)))


def equilibrium(
    rig: SpatialRig,
    u: np.ndarray | float,
    tension: np.ndarray | None = None,
    du_max: float = 2e-3,
    start: SpatialEquilibrium | None = None,
    rotor: str = "locked",
) -> SpatialEquilibrium:
    """Frictionless static equilibrium with tendon ``i``'s spool held at displacement ``u[i]`` (m) from rest.

    With ``rotor="free"``, ``u[i]`` is instead tendon ``i``'s commanded displacement and its rotor rests at
    the lag its torque law needs (the rig at rest after a move; the stiffer a tendon's load, the more the
    microstep spring matters).

    Parameters
    ----------
    rig : SpatialRig
        The rig.
    u : array_like
        Displacement of each tendon (a scalar for a one-tendon rig), m; ignored where ``tension`` is finite.
    tension : array_like, optional
        A finite value holds that tendon at that tension (N) instead; its displacement is then computed.
    du_max : float
        Largest change of any displacement (or tension / 2 kN/m) per continuation step from ``start``.
    start : SpatialEquilibrium, optional
        Where the continuation starts (default: the rest state).
    rotor : {"locked", "free"}
        Spools held at ``u``, or steppers commanded to ``u``.
    """
    model = spatial_model(rig)
    nt = rig.n_tendons
    u = np.broadcast_to(np.asarray(u, dtype=float), (nt,)).copy()
    lam = np.full(nt, np.nan) if tension is None else np.broadcast_to(np.asarray(tension, dtype=float), (nt,))
    if not np.all(np.isfinite(u[~np.isfinite(lam)])):
        raise ValueError("cable displacements must be finite")
    if np.any(np.isfinite(lam) & ~(lam >= 0)):
        raise ValueError("prescribed tensions must be >= 0")
    if start is None:
        start = rest_equilibrium(rig)
    u0, lam0 = (start.command if rotor == "free" else start.u), start.tension
    fixed = np.isfinite(lam)
    span = max(float(np.max(np.abs(np.where(fixed, 0.0, u - u0)), initial=0.0)),
               float(np.max(np.abs(np.where(fixed, lam - lam0, 0.0)), initial=0.0)) / 2000.0)  # fmt: skip
    n_inc = max(1, int(math.ceil(span / du_max - 1e-9)))
    q = start.q.copy()
    for i in range(1, n_inc + 1):
        f = i / n_inc
        lam_f = np.where(fixed, lam0 + (lam - lam0) * f, np.nan)
        ctrl = model.series_control(u0 + (u - u0) * f, lam_f, rotor)
        q = _newton(model.chain, q, ctrl)
    eq = _make(model, q, ctrl)
    pull_out = np.array([t.holding_torque_n_m / rig.spool_radius(i) for i, t in enumerate(rig.tendons)])
    over = np.flatnonzero(eq.tension >= 0.99 * pull_out)
    if over.size:
        i = int(over[0])
        raise ValueError(f"tendon {i + 1} would carry {eq.tension[i]:.1f} N, at its stepper's pull-out "
                         f"tension ({pull_out[i]:.1f} N): the motor slips")  # fmt: skip
    return eq


def equilibrium_state(rig: SpatialRig, eq: SpatialEquilibrium) -> tuple[np.ndarray, np.ndarray]:
    """The kernel's state at rest in ``eq`` and the commanded rotor angles that hold it there.

    Returns
    -------
    (y, drive)
        ``[phi, 0, psi, 0, x_c, 0]`` with each spool where ``eq`` holds it and each carriage between its two
        cables' equal tensions (a slack tendon's at the verge of its spool side), and each rotor's command
        its static lag ahead of it.
    """
    model = spatial_model(rig)
    nt, nq = rig.n_tendons, model.chain.nq
    R = np.array([rig.spool_radius(i) for i in range(nt)])
    psi = model.psi0 + eq.u / R
    x = R * psi - model.s1_ref - eq.tension / model.k1
    drive = psi + np.array([rig.static_lag(i, eq.tension[i]) for i in range(nt)])
    y = np.concatenate([eq.q, np.zeros(nq), psi, np.zeros(nt), x, np.zeros(nt)])
    return y, drive


# --- small vibrations ------------------------------------------------------------------------------------
def modal_analysis(M: np.ndarray, C: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poles and mode shapes of ``M x'' + C x' + K x = 0`` in a well-conditioned form.

    The state form of :func:`helpers.virtual.statics.modal_state` (as the planar twin's poles).

    Returns
    -------
    poles : numpy.ndarray
        Eigenvalues (1/s), sorted by modulus.
    shapes : numpy.ndarray
        Their shapes in ``x`` (columns, complex).
    modal : tuple
        ``(T, Omega, left, right)``: the modal transformation ``x = T eta`` and the state matrix's
        eigenvectors, for input/output weights.
    """
    T, Om, A = modal_state(M, C, K)
    n = M.shape[0]
    ev, vl, vr = linalg.eig(A, left=True, right=True)
    order = np.argsort(np.abs(ev), kind="stable")
    ev, vl, vr = ev[order], vl[:, order], vr[:, order]
    shapes = T @ (vr[:n] / Om[:, None])
    return ev, shapes, (T, Om, vl, vr)


def _weights(ev: np.ndarray, modal: tuple, f_in: np.ndarray, c_out: np.ndarray, decay_s: float) -> np.ndarray:
    """Weights ``2 |r / p| exp(Re p decay_s)`` of every pole in every step response.

    Outputs ``c_out @ x`` (rows) to inputs ``f_in`` (rows): shape (n_out, n_in, n_poles).
    """
    T, Om, vl, vr = modal
    n = T.shape[0]
    B = np.concatenate([np.zeros((n, f_in.shape[0])), T.T @ f_in.T])
    Cc = np.concatenate([(c_out @ T) / Om, np.zeros((c_out.shape[0], n))], axis=1)
    den = np.einsum("ij,ij->j", vl.conj(), vr)
    res = (Cc @ vr)[:, None, :] * ((vl.conj().T @ B) / den[:, None]).T[None, :, :]
    return 2.0 * np.abs(res / ev) * np.exp(ev.real * decay_s)


@dataclass(frozen=True)
class SpatialLinearisation:
    """Small vibrations of the spatial rig about an equilibrium.

    Attributes
    ----------
    equilibrium : SpatialEquilibrium
    rotor : str
        ``"locked"`` (spools held) or ``"free"`` (rotors on their microstep springs).
    M, C, K : numpy.ndarray
        Mass, damping and tangent stiffness: arm coordinates (3N), then the rotors (if free), then the
        carriages (of the taut tendons: a slack tendon's carriage is free and decoupled).
    poles : numpy.ndarray
        Eigenvalues, sorted by modulus (1/s).
    shapes : numpy.ndarray
        Mode shapes (columns) in the coordinates above.
    weights : numpy.ndarray
        ``weights[i, j, k]``: amplitude of pole ``k`` in tendon ``i``'s measured tension after a unit step of
        tendon ``j``'s input (commanded rotor angle if free, spool angle if locked), ``decay_s`` after it.
    n_arm : int
        Number of arm coordinates.
    """

    equilibrium: SpatialEquilibrium
    rotor: str
    M: np.ndarray = field(repr=False)
    C: np.ndarray = field(repr=False)
    K: np.ndarray = field(repr=False)
    poles: np.ndarray = field(repr=False)
    shapes: np.ndarray = field(repr=False)
    weights: np.ndarray = field(repr=False)
    n_arm: int = 0
    chain: SpatialChain | None = field(default=None, repr=False)

    def modes(self, command: np.ndarray | None = None) -> pd.DataFrame:
        """The oscillatory poles (upper half-plane), lowest first, with what each one does.

        Parameters
        ----------
        command : array_like, optional
            Tendon inputs' mix for the ``weight`` column (default: every tendon's input alone, summed).

        Returns
        -------
        pandas.DataFrame
            ``omega_n``, ``zeta``, ``omega_d``; ``azimuth_deg`` (direction of the tip's motion around the
            backbone, 0-180, the clamp frame's angle from tendon 1), ``tip_axial`` (share of the tip's motion
            along the clamp axis), ``torsion`` (the twist's share of the mode's strain energy), ``in_plane``
            (share of the strain energy in bending about the clamp frame's ``y``: the paper's plane for tendon
            1) (these four NaN for a mode degenerate with a neighbour to 1e-7: its shape is any mix),
            ``weight`` (largest over the tendons of the pole's weight in a tendon's tension for ``command``).
        """
        nt = self.weights.shape[0]
        mix = np.ones(nt) if command is None else np.asarray(command, dtype=float)
        w = np.abs(np.einsum("ijk,j->ik", self.weights, mix)).max(0)
        up = self.poles.imag > 1e-9
        rows = []
        chain = self.chain
        Jv_tip = chain.node_jacobians(self.equilibrium.q)[0][-1] if chain is not None else None
        kdiag = np.tile([chain.kb, chain.kb, chain.kt], chain.N) if chain is not None else None
        for k in np.flatnonzero(up):
            p = self.poles[k]
            v = self.shapes[: self.n_arm, k]
            v = np.real(v * np.exp(-0.5j * np.angle(np.sum(v * v))))
            row = {"omega_n": abs(p), "zeta": -p.real / abs(p), "omega_d": p.imag}
            if chain is not None:
                d = Jv_tip @ v
                # rounded so that round-off (a sideways motion of 1e-15 of the shape) prints as 0
                row["azimuth_deg"] = round(math.degrees(math.atan2(d[1], d[0])), 6) % 180.0 + 0.0
                row["tip_axial"] = round(float(abs(d[2]) / max(np.linalg.norm(d), 1e-300)), 9) + 0.0
                energy = kdiag * v * v
                tot = max(energy.sum(), 1e-300)
                row["torsion"] = round(float(energy[2::3].sum() / tot), 9) + 0.0
                row["in_plane"] = round(float(energy[1::3].sum() / tot), 9) + 0.0
            row["weight"] = float(w[k])
            rows.append(row)
        df = pd.DataFrame(rows)
        if not len(df):
            return df
        df = df.sort_values("omega_n", kind="stable").reset_index(drop=True)
        if "azimuth_deg" in df:  # a degenerate pair's shapes are any mix of the two: no direction of its own
            w = df.omega_n.to_numpy()
            gap = np.minimum(np.abs(np.diff(w, prepend=-np.inf)), np.abs(np.diff(w, append=np.inf)))
            degenerate = gap < 1e-7 * w
            for col in ("azimuth_deg", "tip_axial", "torsion", "in_plane"):
                df.loc[degenerate, col] = np.nan
        return df

    def dominant(self, tendon: int = 0, command: np.ndarray | None = None) -> tuple[float, float]:
        """``(omega_d, zeta)`` of the pole with the largest weight in tendon ``tendon``'s tension."""
        nt = self.weights.shape[0]
        mix = np.eye(nt)[tendon] if command is None else np.asarray(command, dtype=float)
        w = np.abs(np.einsum("jk,j->k", self.weights[tendon], mix))
        up = self.poles.imag > 1e-9
        k = int(np.argmax(np.where(up, w, -1.0)))
        p = self.poles[k]
        return float(p.imag), float(-p.real / abs(p))

    def undamped(self) -> np.ndarray:
        """Undamped natural frequencies (rad/s), ascending."""
        return np.sqrt(np.abs(linalg.eigh(self.K, self.M, eigvals_only=True)))


def linearise(
    rig: SpatialRig,
    eq: SpatialEquilibrium | None = None,
    rotor: str = "locked",
    decay_s: float = DECAY_S,
) -> SpatialLinearisation:
    """Linearise the spatial rig about ``eq`` (default: the rest state).

    Coordinates: the arm's (3N), then each tendon's rotor angle if ``rotor="free"``, then each carriage.
    With ``rotor="locked"`` the spools are held where ``eq`` has them; with ``"free"`` each rotor sits on its
    motor's tangent microstep stiffness at its static lag and the input is its commanded angle. The stiffness
    is the exact Hessian (complex step) of the potential of arm, cables (the arm-side cables through the
    tendon-coupled bowing), carriages and motors; the outputs are the arm-side tensions the load cells read.
    """
    if rotor not in ("free", "locked"):
        raise ValueError(f"rotor must be 'free' or 'locked', got {rotor!r}")
    model = spatial_model(rig)
    eq = rest_equilibrium(rig) if eq is None else eq
    chain = model.chain
    nt, nq = rig.n_tendons, chain.nq
    free = rotor == "free"
    R = np.array([rig.spool_radius(i) for i in range(nt)])
    y_eq, cmd = equilibrium_state(rig, eq)
    psi, x = y_eq[2 * nq : 2 * nq + nt], y_eq[2 * nq + 2 * nt : 2 * nq + 3 * nt]
    lags = cmd - psi
    Th = np.array([t.holding_torque_n_m for t in rig.tendons])
    Nr = rig.arm.rotor_teeth
    sin_law = rig.arm.torque_law == "sin"
    arm_ctrl_kinv = 1.0 / model.k2

    def split(z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        q = z[..., :nq]
        ps = z[..., nq : nq + nt] if free else np.broadcast_to(psi, z.shape[:-1] + (nt,))
        xs = z[..., z.shape[-1] - nt :]  # the carriages (none for a bare rod)
        return q, ps, xs

    def grad(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        q, ps, xs = split(z)
        ctrl = Control(lam=np.full(nt, np.nan), e0=xs - model.ell_ref_arm, kinv=arm_ctrl_kinv)
        gq, lam2, _ = chain.potential_grad(q, ctrl)
        e1 = R * ps - xs - model.s1_ref
        lam1 = np.where(np.real(e1) > 0, model.k1 * e1, 0.0)
        parts = [gq]
        if free:
            d = cmd - ps
            tm = Th * np.sin(Nr * d) if sin_law else Th * Nr * d
            parts.append(R * lam1 - tm)
        parts.append(lam2 - lam1)
        return np.concatenate(parts, axis=-1), lam2

    z0 = np.concatenate([eq.q, psi, x] if free else [eq.q, x])
    nz = z0.size
    h = 1e-30
    Z = z0[None, :] + 1j * h * np.eye(nz)
    gz, lam2 = grad(Z)
    K = gz.imag / h
    K = 0.5 * (K + K.T)
    dlam = (lam2.imag / h).T  # (nt, nz): d lam2_i / dz
    M_arm = chain.mass_matrix(eq.q)
    C_arm = chain.damping_matrix(M_arm, (model.floor_W, model.floor_c))
    M = np.zeros((nz, nz))
    C = np.zeros((nz, nz))
    M[:nq, :nq] = M_arm
    C[:nq, :nq] = C_arm
    ix = np.arange(nz - nt, nz)
    M[ix, ix] = rig.arm.carriage_mass
    C[ix, ix] = [rig.carriage_damping(i) for i in range(nt)]
    inputs = np.zeros((nt, nz))
    if free:
        ir = np.arange(nq, nq + nt)
        M[ir, ir] = rig.arm.drive_inertia
        C[ir, ir] = [rig.rotor_damping(i) for i in range(nt)]
        km = np.array([rig.tangent_motor_stiffness(i, lags[i]) for i in range(nt)])
        inputs[np.arange(nt), ir] = km
    else:
        taut = R * psi - x - model.s1_ref > 0
        inputs[np.arange(nt), ix] = np.where(taut, model.k1 * R, 0.0)
    # a slack tendon's carriage sits between two slack cables: free and decoupled, so it leaves the model
    keep = np.ones(nz, dtype=bool)
    keep[ix[eq.tension <= 0.0]] = False
    if not keep.all():
        M, C, K = M[np.ix_(keep, keep)], C[np.ix_(keep, keep)], K[np.ix_(keep, keep)]
        inputs, dlam = inputs[:, keep], dlam[:, keep]
    poles, shapes, modal = modal_analysis(M, C, K)
    weights = _weights(poles, modal, inputs, dlam, decay_s)
    return SpatialLinearisation(equilibrium=eq, rotor=rotor, M=M, C=C, K=K, poles=poles, shapes=shapes,
                                weights=weights, n_arm=nq, chain=chain)  # fmt: skip


def stable_max_step(
    rig: SpatialRig, eqs: list[SpatialEquilibrium] | None = None, margin: float = 0.9
) -> float:
    """The largest step ``1 ms / n`` (n = 2, 3, ...) within ``margin`` of RK4's stability limit.

    The limit is taken over the rig's linearisations (rotors free) at ``eqs`` (default: the rest state).
    """
    eqs = [rest_equilibrium(rig)] if eqs is None else eqs
    h = min(rk4_stable_step(linearise(rig, eq, rotor="free").poles) for eq in eqs)
    n = max(2, math.ceil(1e-3 / (margin * h) - 1e-9))
    return 1e-3 / n
