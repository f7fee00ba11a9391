"""The spatial twin against SoroSim: a bare rod held deflected and released, as in a SoroSim tip-release test.

SoroSim (an independent Cosserat-rod solver) holds a spring-steel rod deflected under gravity with forces on
its middle and its tip and releases it (read by ``helpers.virtual.sorosim_file``). Here the same rod is built
as a bare rod's file (``docs/rig_file.md``, ``[rod]``: :func:`rod_file_text`, the test's length, radius,
material, gravity and held forces), the spatial twin made from that file
(:mod:`helpers.virtual.spatial.bare_rod`), held by the same forces, released and sampled at the test's
instants (:func:`compare`).

**Frames.** The file's ``x`` runs along the unloaded rod; the twin's clamp frame has ``z`` there. Vectors go
over as ``(x, y, z)_clamp = (y, z, x)_file`` (a rotation), and back for the comparison.

**What is compared** (:class:`Comparison`):

- the held state at ``t = 0`` (the tip's and the middle's distance from the file's: a static check);
- the tip frequency and decay: a damped-sine fit (:func:`helpers.paper.identify.identify`) of the tip's
  dominant component over :data:`FIT_WINDOW_S`, for the file and for the twin; the dominant component is the
  direction of the file's largest tip motion (the first principal axis of its tip displacement over the
  window, the same axis for both);
- the RMS distance between the twin's and the file's tip over 0-2 s and over the whole test, relative to the
  file's initial tip deflection (its tip at ``t = 0`` from its tip at the end);
- the phase lag at 2 s: the file's fitted phase minus the twin's, in degrees (positive: the twin behind);
- a convergence row: the twin's lowest mode at rest (linearised) for several segment counts, and the
  time-domain tip frequency for some.

**Damping: fitted, not a validation.** SoroSim's header holds its own damping parameter (0.0041 for test 1),
not a modal damping ratio. The twin's damping is **fitted**: mass-proportional (``alpha``, air-drag-like),
chosen so that the twin's lowest mode at rest has the damping ratio fitted on the file's tip,
``alpha = 2 zeta_file omega_n``. The twin's decay therefore agrees by construction; it is reported beside the
file's, never called a validation. (Read as a Kelvin-Voigt time constant, SoroSim's parameter would give
``zeta_1 = 0.0041 omega_1 / 2 = 0.040``, as fitted; the twin's explicit integrator cannot carry a
stiffness-proportional law at its step, so the parameter is not mapped.)
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from helpers.paper.identify import IdentificationResult, identify
from helpers.rigfile.model import RigFile
from helpers.virtual.sorosim_file import SoroSimTest, read_sorosim
from helpers.virtual.spatial import bare_rod
from helpers.virtual.spatial.rod_file import loads_rod

__all__ = [
    "FIT_WINDOW_S", "RMS_WINDOWS_S", "PHASE_AT_S", "CONVERGENCE_LINEAR", "CONVERGENCE_TIME", "MAX_SEGMENTS",
    "to_clamp", "to_file", "rod_file_text", "euler_bernoulli_hz", "Comparison", "compare", "run_command",
]  # fmt: skip

FIT_WINDOW_S = (0.0, 6.0)
"""The window of the damped-sine fits of the tip, s."""

RMS_WINDOWS_S = (2.0, 10.0)
"""The RMS tip differences are taken over ``0-T`` for each ``T``, s."""

PHASE_AT_S = 2.0
"""When the phase lag is read, s."""

CONVERGENCE_LINEAR = (10, 20, 40, 80)
"""Segment counts of the convergence row's linearised lowest mode."""

MAX_SEGMENTS = 80
"""Most elements a comparison integrates (the explicit step shrinks with the element: 80 take minutes)."""

CONVERGENCE_TIME = (10,)
"""Segment counts, besides the rod file's, whose release is integrated for the convergence row."""

BETA_1 = 1.8751040687119611
"""First root of ``1 + cos b cosh b = 0`` (a clamped-free beam)."""


def to_clamp(v: Iterable[float]) -> list[float]:
    """A vector in the file's frame -> the clamp frame: ``(y, z, x)``."""
    x, y, z = (float(c) for c in v)
    return [y, z, x]


def to_file(v: np.ndarray) -> np.ndarray:
    """Vectors (..., 3) in the clamp frame -> the file's frame."""
    v = np.asarray(v, dtype=float)
    return np.stack([v[..., 2], v[..., 0], v[..., 1]], axis=-1)


def euler_bernoulli_hz(test: SoroSimTest) -> float:
    """The straight clamped-free rod's first mode, no gravity: ``b_1^2 / (2 pi) sqrt(EI / (rho A L^4))``."""
    area = math.pi * test.radius_m**2
    ei = test.youngs_modulus_pa * math.pi * test.radius_m**4 / 4.0
    return BETA_1**2 / (2.0 * math.pi) * math.sqrt(ei / (test.density_kg_m3 * area * test.length_m**4))


def _vector(v: Iterable[float]) -> str:
    return "[" + ", ".join(f"{c:.10g}" for c in v) + "]"


def rod_file_text(test: SoroSimTest, segments: int = 20, alpha_per_s: float = 0.0) -> str:
    """A bare rod's file (``docs/rig_file.md``, ``[rod]``) holding ``test``'s rod, gravity and held forces.

    Parameters
    ----------
    test : SoroSimTest
        The tip-release test.
    segments : int
        The twin's elements (even: the middle is a node).
    alpha_per_s : float
        The twin's mass-proportional damping, 1/s (the fitted value: :func:`compare`).

    Returns
    -------
    str
        TOML text; :func:`helpers.virtual.spatial.rod_file.loads_rod` reads it.
    """
    if np.any(test.mid_moment != 0.0) or np.any(test.tip_moment != 0.0):
        raise ValueError(f"{test.path}: holding moments are not supported (the twin holds the rod by forces)")
    return bare_rod.rod_file_text(
        f"sorosim-{test.name}", length_m=test.length_m, radius_m=test.radius_m,
        youngs_modulus_pa=test.youngs_modulus_pa, density_kg_m3=test.density_kg_m3,
        shear_modulus_pa=test.shear_modulus_pa, gravity=to_clamp(test.gravity), segments=segments,
        mid_force_n=to_clamp(test.mid_force), tip_force_n=to_clamp(test.tip_force), alpha_per_s=alpha_per_s,
        description=f"SoroSim tip-release test {test.name}: {test.length_m:g} m rod, held and released",
        comments=(
            "A bare rod for the spatial twin (docs/rig_file.md, [rod]), made from SoroSim's tip-release test",
            f"{test.name} ({test.path.name}, sha256 {test.sha256[:16]}...) and its rod's description",
            f"{test.description.name}. Every value is the test's; the clamp frame's z is the file's x (along",
            "the rod), its x the file's y and its y the file's z. Simulated by both solvers, never measured.",
        ),
        notes={"shear_modulus_gpa": f"E / (2 (1 + {test.poisson_ratio:g}))",
               "damping_alpha_per_s": "fitted to the test's tip decay (helpers.virtual.sorosim)"},
    )  # fmt: skip


def _fit(t: np.ndarray, y: np.ndarray) -> IdentificationResult:
    return identify(t, y, window=FIT_WINDOW_S)


def _phase_at(res: IdentificationResult, t: float) -> float:
    """The fitted sine's phase at ``t``, rad."""
    assert res.fit is not None
    return res.fit.omega_d * (t - res.fit.t0) + res.fit.phase


@dataclass(frozen=True)
class Comparison:
    """The twin beside one SoroSim test (every twin value simulated; the file's computed by SoroSim).

    Attributes
    ----------
    test : SoroSimTest
    rig : RigFile
        The bare rod's file the twin was built from.
    segments : int
    alpha_per_s : float
        The twin's fitted damping.
    file_fit, twin_fit : IdentificationResult
        The damped-sine fits of the tip's dominant component over :data:`FIT_WINDOW_S`.
    axis : numpy.ndarray
        The dominant component's direction (file frame).
    held_tip_m, held_mid_m : float
        Distance of the twin's held tip and middle from the file's at ``t = 0``, m.
    deflection_m : float
        The file's initial tip deflection (tip at 0 from tip at the end), m.
    rms : dict
        ``{T: RMS tip distance over 0-T s / deflection}``.
    phase_lag_deg : float
        File's phase minus the twin's at :data:`PHASE_AT_S`, degrees, in (-180, 180].
    t, twin_tip, file_tip : numpy.ndarray
        The samples (file frame, m), for plotting.
    convergence : list of dict
        ``segments``, ``f1_linear_hz`` (lowest mode at rest), ``f_time_hz`` (NaN where not integrated).
    euler_bernoulli_hz : float
    max_step_s : float
        The twin's RK4 step.
    """

    test: SoroSimTest
    rig: RigFile
    segments: int
    alpha_per_s: float
    file_fit: IdentificationResult
    twin_fit: IdentificationResult
    axis: np.ndarray
    held_tip_m: float
    held_mid_m: float
    deflection_m: float
    rms: dict
    phase_lag_deg: float
    t: np.ndarray = field(repr=False)
    twin_tip: np.ndarray = field(repr=False)
    file_tip: np.ndarray = field(repr=False)
    convergence: list = field(default_factory=list)
    euler_bernoulli_hz: float = math.nan
    max_step_s: float = math.nan

    @property
    def file_hz(self) -> float:
        """The file's tip frequency, Hz."""
        return self.file_fit.omega_d / (2.0 * math.pi)

    @property
    def twin_hz(self) -> float:
        """The twin's tip frequency, Hz."""
        return self.twin_fit.omega_d / (2.0 * math.pi)

    def report(self) -> str:
        """The comparison side by side, fixed precision."""
        test = self.test
        d = self.deflection_m
        step_us = self.max_step_s * 1e6
        lines = [
            f"SoroSim tip-release test {test.name} ({test.path.name}: computed by SoroSim, MIT) against the "
            f"spatial twin as a bare rod of {self.segments} segments (simulated; RK4 step {step_us:.2f} us)",
            f"held at t = 0 (forces on the middle and the tip): the twin's tip is "
            f"{self.held_tip_m * 1e3:.2f} mm from the file's, its middle {self.held_mid_m * 1e3:.2f} mm "
            f"(initial tip deflection {d * 1e3:.1f} mm)",
            f"tip's dominant component (file frame, unit vector): {_vector(np.round(self.axis, 4))}",
            "",
            f"{'':34s}{'file':>10s}{'twin':>10s}   twin/file - 1",
            f"{'tip frequency, fit 0-6 s (Hz)':34s}{self.file_hz:10.4f}{self.twin_hz:10.4f}   "
            f"{100 * (self.twin_hz / self.file_hz - 1):+.2f} %",
            f"{'tip decay, fit 0-6 s (zeta)':34s}{self.file_fit.zeta:10.4f}{self.twin_fit.zeta:10.4f}   "
            f"(the twin's damping is FITTED to the file's: alpha {self.alpha_per_s:.4f} 1/s; "
            "not a validation)",
            "",
            *(f"RMS tip distance 0-{T:g} s: {100 * v:.2f} % of the initial tip deflection "
              f"({v * d * 1e3:.2f} mm)" for T, v in self.rms.items()),  # fmt: skip
            f"phase lag at {PHASE_AT_S:g} s: {self.phase_lag_deg:+.1f} deg (the file's phase minus the "
            "twin's)",
            "",
            "convergence (the twin; segments against frequency):",
            f"{'segments':>10s}{'f1 at rest, linear (Hz)':>26s}{'tip f 0-6 s, time domain (Hz)':>32s}",
        ]
        for row in self.convergence:
            tf = row["f_time_hz"]
            shown = "-" if math.isnan(tf) else f"{tf:.4f}"
            lines.append(f"{row['segments']:10d}{row['f1_linear_hz']:26.4f}{shown:>32s}")
        lines.append(f"Euler-Bernoulli, straight and without gravity: {self.euler_bernoulli_hz:.4f} Hz")
        return "\n".join(lines)


def _release(rig: RigFile, segments: int, alpha: float, times: np.ndarray) -> bare_rod.Release:
    rod = bare_rod.rod_rig(rig, segments=segments, alpha=alpha)
    return bare_rod.release(rod, bare_rod.held_state(rod, bare_rod.held_forces(rig, rod)), times)


def _alpha(rig: RigFile, segments: int, zeta: float) -> float:
    """The mass-proportional damping that gives the twin's lowest mode at rest the damping ratio ``zeta``."""
    f1, _ = bare_rod.first_modes(bare_rod.rod_rig(rig, segments=segments, alpha=0.0, floor_zeta=0.0), 1)[0]
    return 2.0 * zeta * 2.0 * math.pi * f1 / math.sqrt(1.0 - zeta**2)


def compare(
    test: SoroSimTest,
    segments: int = 20,
    convergence_linear: Iterable[int] = CONVERGENCE_LINEAR,
    convergence_time: Iterable[int] = CONVERGENCE_TIME,
) -> Comparison:
    """The twin released as in ``test``, side by side with it (module docstring).

    Parameters
    ----------
    test : SoroSimTest
        The tip-release test (:func:`helpers.virtual.sorosim_file.read_sorosim`).
    segments : int
        The twin's elements for the comparison (even).
    convergence_linear, convergence_time : iterable of int
        Segment counts of the convergence row: linearised lowest mode; integrated release (0-6 s).

    Returns
    -------
    Comparison
    """
    if not 2 <= segments <= MAX_SEGMENTS or segments % 2:
        raise ValueError(f"segments must be even, 2-{MAX_SEGMENTS} (the middle is a node), got {segments!r}")
    file_tip = test.tip
    end = file_tip[-1]
    window = (test.t >= FIT_WINDOW_S[0]) & (test.t <= FIT_WINDOW_S[1])
    motion = file_tip[window] - end
    axis = np.linalg.svd(motion - motion.mean(axis=0), full_matrices=False)[2][0]
    axis = axis if axis[np.argmax(np.abs(axis))] > 0 else -axis
    file_fit = _fit(test.t, (file_tip - end) @ axis)
    rig = loads_rod(rod_file_text(test, segments, 0.0), source=f"<rod of {test.name}>")
    alpha = _alpha(rig, segments, file_fit.zeta)
    rig = loads_rod(rod_file_text(test, segments, alpha), source=f"<rod of {test.name}>")
    rel = _release(rig, segments, alpha, test.t)
    twin_tip = to_file(rel.tip)
    twin_fit = _fit(test.t, (twin_tip - to_file(rel.tip_rest)) @ axis)
    deflection = float(np.linalg.norm(file_tip[0] - end))
    dist = np.linalg.norm(twin_tip - file_tip, axis=1)
    rms = {T: float(np.sqrt(np.mean(dist[test.t <= T] ** 2))) / deflection for T in RMS_WINDOWS_S}
    lag = math.degrees(_phase_at(file_fit, PHASE_AT_S) - _phase_at(twin_fit, PHASE_AT_S))
    lag = -((-lag + 180.0) % 360.0 - 180.0)
    rows = []
    for n in sorted(set(convergence_linear) | set(convergence_time) | {segments}):
        f1 = bare_rod.first_modes(bare_rod.rod_rig(rig, segments=n, alpha=0.0), 1)[0][0]
        f_time = math.nan
        if n == segments:
            f_time = twin_fit.omega_d / (2.0 * math.pi)
        elif n in set(convergence_time):
            a_n = _alpha(rig, n, file_fit.zeta)
            short = test.t[test.t <= FIT_WINDOW_S[1]]
            r = _release(rig, n, a_n, short)
            y = (to_file(r.tip) - to_file(r.tip_rest)) @ axis
            f_time = _fit(short, y).omega_d / (2.0 * math.pi)
        rows.append({"segments": n, "f1_linear_hz": f1, "f_time_hz": f_time})
    return Comparison(
        test=test, rig=rig, segments=segments, alpha_per_s=alpha, file_fit=file_fit, twin_fit=twin_fit,
        axis=axis, held_tip_m=float(np.linalg.norm(twin_tip[0] - file_tip[0])),
        held_mid_m=float(np.linalg.norm(to_file(rel.mid[0]) - test.mid[0])), deflection_m=deflection, rms=rms,
        phase_lag_deg=lag, t=test.t, twin_tip=twin_tip, file_tip=file_tip, convergence=rows,
        euler_bernoulli_hz=euler_bernoulli_hz(test), max_step_s=rel.max_step,
    )  # fmt: skip


def run_command(path: str, segments: int = 20, print_rod_file: bool = False) -> int:
    """``python -m helpers virtual-rig sorosim FILE``: print the comparison (and the rod's file if asked)."""
    test = read_sorosim(path)
    result = compare(test, segments=segments)
    if print_rod_file:
        print(result.rig.text)
    print(result.report())
    return 0
