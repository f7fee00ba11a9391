"""The paper's linear modal model of the cable-driven arm (paper eqs. 1-13), with python-control.

The backbone is a uniform Euler-Bernoulli cantilever of length ``L``; its first ``N`` bending modes are
driven by one cable at offset ``r`` from the neutral axis, fixed to the last disc. With ``u`` the cable
displacement (m, positive when pulled), ``lambda`` the cable tension (N) and ``q_n`` the modal coordinates
(m of tip displacement, see *Sign convention*)::

    sum_n K_n q_n + lambda / k - u = 0                       (1) kinematic compatibility of the cable
    m_n q_n'' + c_n q_n' + k_n q_n = lambda K_n              (2) independent modes, forced by the tension
    K_n = r phi_n'(L)                                        (6) coupling coefficient
    c_n = eta m_n + delta k_n                                (8-10) Rayleigh damping, zeta on modes 1 and 2

which give the transfer functions from the cable *velocity* ``v = s U`` (m/s) to the tension (N) and to
the tip displacement ``y`` (m)::

    Lambda / (s U) = 1 / (s (1/k + sum_n K_n^2 / D_n))       (11)
    Y / (s U)      = (sum_n K_n / D_n) / (s (1/k + sum_n K_n^2 / D_n))
    D_n            = m_n s^2 + c_n s + m_n omega_n^2         (12)

Sign convention
---------------
The paper's mode function (eq. 3) has ``Phi_n(L) = 2 (-1)^(n+1)`` at the exact roots. We use the
*tip-normalised* shapes ``phi_n(x) = Phi_n(x) / Phi_n(L)``, so that ``phi_n(L) = +1`` for every mode. Then

- ``q_n`` is the tip displacement carried by mode ``n``, and the tip displacement is ``y = sum_n q_n``,
  which is what the paper's ``Y/(sU)`` (numerator ``sum K_n / D_n``) assumes;
- ``int_0^L phi_n^2 dx = L / 4``, so the modal masses are ``m_n = m / 4`` (paper, below eq. 4);
- ``K_n = r phi_n'(L) = r Phi_n'(L) / Phi_n(L)`` is positive for every mode (the paper's eq.-3 shapes would
  give alternating signs ``+, -, +, -``; only ``K_n^2`` enters the tension transfer function).

The masses of the 12 discs are smeared uniformly along the backbone (the paper's "uniform parameter
distribution" assumption): the mass per length is ``(rod mass + discs) / L``.

Which parameters are known, assumed and fitted is documented on :class:`ArmParameters` and :data:`FITTED`,
and in ``docs/model.md``. The fit itself, the project's procedure and not the paper's, is
:func:`helpers.research.model_fit.fit_to_mode`; this module keeps its result as data. (The model *fit* is not
the virtual rig's *tuning*, :mod:`helpers.virtual.tuning`, nor the *load-cell calibration*,
:mod:`helpers.paper.calibration`.)
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import control
import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy import linalg, optimize

from helpers.paper.backbone import Backbone

FIXED_DISC_MASS: float = 1.0e-3
"""Mass of each cable-support disc (kg), *fixed* (not fitted); :mod:`helpers.research.model_fit` says why."""


# ----------------------------------------------------------------------------------------------
# Cantilever roots and mode shapes (paper eqs. 3-4)
# ----------------------------------------------------------------------------------------------


def _check_n(n: int, name: str = "n") -> int:
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
        raise ValueError(f"{name} must be a positive integer, got {n!r}")
    return int(n)


def cantilever_roots(n: int) -> np.ndarray:
    """Return the first ``n`` roots beta_1 < ... < beta_n of ``cos(b) cosh(b) + 1 = 0``.

    Root ``j`` lies in ``((j - 1) pi, j pi)``; it is found with Brent's method on the equivalent,
    well-scaled equation ``cos(b) + 1/cosh(b) = 0`` (same roots, no overflow for large ``b``).

    Parameters
    ----------
    n : int
        Number of roots (>= 1).

    Returns
    -------
    numpy.ndarray
        ``beta_1..beta_n`` (1.8751, 4.6941, 7.8548, 10.9955, ...), to about 1e-14.
    """
    return np.array(_roots(_check_n(n)))


@functools.lru_cache(maxsize=64)
def _roots(n: int) -> tuple[float, ...]:
    def g(b: float) -> float:
        e = math.exp(-b)
        return math.cos(b) + 2.0 * e / (1.0 + e * e)  # cos(b) + 1/cosh(b), without overflow

    return tuple(
        optimize.brentq(g, (j - 1) * math.pi, j * math.pi, xtol=1e-15, rtol=4 * np.finfo(float).eps)
        for j in range(1, n + 1)
    )


def _shape_z(z: np.ndarray, beta: float, derivative: int) -> np.ndarray:
    """Paper eq. 3, Phi(z) with z = beta x / L, or its ``derivative``-th derivative in z.

    Written as ``((1 - sigma)/2) e^z + ((1 + sigma)/2) e^-z - cos z + sigma sin z`` with ``1 - sigma`` and
    ``e^z / (sinh beta + sin beta)`` evaluated without cancellation, so it stays accurate for high modes.
    """
    g = math.exp(-beta)
    # sigma = (cosh b + cos b) / (sinh b + sin b), divided through by e^b / 2
    sigma = (1.0 + g * g + 2.0 * g * math.cos(beta)) / (1.0 - g * g + 2.0 * g * math.sin(beta))
    # (1 - sigma)/2 * e^z  =  (sin b - cos b - e^-b) e^(z - b) / (1 - e^-2b + 2 e^-b sin b)
    grow = (math.sin(beta) - math.cos(beta) - g) * np.exp(z - beta) / (1.0 - g * g + 2.0 * g * math.sin(beta))
    decay = 0.5 * (1.0 + sigma) * np.exp(-z)
    phase = derivative * math.pi / 2.0
    return grow + (-1) ** derivative * decay - np.cos(z + phase) + sigma * np.sin(z + phase)


def _check_x(x: npt.ArrayLike, length: float, derivative: int) -> np.ndarray:
    if not (isinstance(derivative, int | np.integer) and 0 <= derivative <= 4):
        raise ValueError(f"derivative must be an integer 0..4, got {derivative!r}")
    if not (np.isfinite(length) and length > 0):
        raise ValueError(f"length must be positive and finite, got {length!r}")
    xa = np.asarray(x, dtype=float)
    if np.any(~np.isfinite(xa)) or np.any(xa < -1e-12 * length) or np.any(xa > length * (1 + 1e-12)):
        raise ValueError(f"x must lie in [0, length={length}]")
    return xa


def mode_function(
    x: npt.ArrayLike, n: int, length: float = 1.0, derivative: int = 0, beta: float | None = None
) -> np.ndarray:
    """The paper's mode function ``Phi_n(x)`` (eq. 3, *not* normalised) or one of its derivatives.

    At the exact roots ``Phi_n(L) = 2 (-1)^(n+1)`` and ``int_0^L Phi_n^2 dx = L``.

    Parameters
    ----------
    x : array_like
        Arc length (m), ``0 <= x <= length``.
    n : int
        Mode number (1-based).
    length : float
        Beam length L (m).
    derivative : int
        0 for the function, 1..4 for ``d^k Phi_n / dx^k`` (units 1/m^k).
    beta : float, optional
        Use this root instead of the computed ``beta_n`` (e.g. the paper's rounded value).

    Returns
    -------
    numpy.ndarray
        Values at ``x``.
    """
    n = _check_n(n)
    xa = _check_x(x, length, derivative)
    b = float(cantilever_roots(n)[-1]) if beta is None else float(beta)
    if not (math.isfinite(b) and b > 0):
        raise ValueError(f"beta must be positive and finite, got {beta!r}")
    return (b / length) ** derivative * _shape_z(b * xa / length, b, derivative)


def mode_shape(
    x: npt.ArrayLike, n: int, length: float = 1.0, derivative: int = 0, beta: float | None = None
) -> np.ndarray:
    """Tip-normalised cantilever mode shape ``phi_n(x)`` (``phi_n(L) = +1``) or one of its derivatives.

    ``phi_n(x) = Phi_n(x) / Phi_n(L)`` with ``Phi_n`` the paper's eq. 3 (:func:`mode_function`, whose
    parameters it takes); its values are dimensionless (tip displacement 1), its ``derivative``-th
    derivatives in 1/m^k.
    """
    values = mode_function(x, n, length, derivative, beta)
    return values / mode_function(length, n, length, 0, beta)


def coupling_coefficients(n: int, beta: npt.ArrayLike | None = None) -> np.ndarray:
    """Signed, dimensionless coupling coefficients ``K_n L / r = L phi_n'(L)`` of modes 1..n (paper eq. 6).

    With tip-normalised shapes (``phi_n(L) = +1``) all are positive: 1.376505, 4.780778, 7.848666,
    10.995910, ...; they tend to ``beta_n`` for high modes. The paper prints 1.3765, 4.7811, 7.8470, 10.9913,
    which is what this function returns for the paper's 3-decimal roots ``beta=(1.875, 4.694, 7.855,
    10.996)``: off an exact root the slope-to-tip ratio ``L Phi_n'(L)/Phi_n(L)`` is sensitive to beta
    (derivative about -0.3, -3.9, -6.8, -10.0 for modes 1-4), and the rounding errors of up to 4.6e-4 in
    beta_n move it in the 4th digit (see notebook 01).

    Parameters
    ----------
    n : int
        Number of modes.
    beta : array_like, optional
        Roots to use (length ``n``); default: the exact roots of :func:`cantilever_roots`.

    Returns
    -------
    numpy.ndarray
        ``K_n L / r`` for n = 1..n.
    """
    n = _check_n(n)
    betas = cantilever_roots(n) if beta is None else np.asarray(beta, dtype=float)
    if betas.shape != (n,) or np.any(~np.isfinite(betas)) or np.any(betas <= 0):
        raise ValueError(f"beta must hold {n} positive finite roots, got {beta!r}")
    return np.array([b * float(_shape_z(np.array(b), b, 1) / _shape_z(np.array(b), b, 0)) for b in betas])


# ----------------------------------------------------------------------------------------------
# Parameters
# ----------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ArmParameters(Backbone):
    """Physical parameters of the linear modal model (SI units), the one place they are defined.

    The backbone (``E``, ``rho``, ``d``, ``L``, ``n_discs``) is :class:`helpers.paper.backbone.Backbone`'s,
    shared
    with the virtual rig. The defaults of ``r``, ``k`` and ``zeta`` are the fitted values (:data:`FITTED`),
    rounded to 3 significant digits (they are also the fit's starting point); use :data:`FITTED` for the
    exact solution.

    Attributes
    ----------
    r : float
        Cable offset from the neutral axis, m. Not given by the paper: solved by
        :func:`helpers.research.model_fit.fit_to_mode` from the paper's statement that 30 mm of cable gives
        about 0.5 m of predicted tip displacement.
    disc_mass : float
        Mass of each cable-support disc, kg. Not given by the paper: *fixed* at 1.0 g (a 3D-printed disc of
        about 18 mm diameter and 3 mm thickness); see :func:`helpers.research.model_fit.fit_to_mode`.
    k : float
        Series stiffness of cable, pulleys and load cell, N/m. Not given by the paper: solved by
        :func:`helpers.research.model_fit.fit_to_mode`. ``numpy.inf`` gives the paper's inextensible-cable
        limit.
    zeta : float
        Rayleigh damping ratio of modes 1 and 2 (paper eqs. 8-10), dimensionless. Solved by
        :func:`helpers.research.model_fit.fit_to_mode` so that the *dominant* pole has the identified damping
        0.044.
    n_modes : int
        Number of modes N retained (paper: 4).
    """

    r: float = 5.86e-3
    disc_mass: float = FIXED_DISC_MASS
    k: float = 1740.0
    zeta: float = 0.0583
    n_modes: int = 4

    def __post_init__(self) -> None:
        super().__post_init__()
        value = self.r
        if not (isinstance(value, int | float | np.floating) and math.isfinite(value) and value > 0):
            raise ValueError(f"ArmParameters.r must be a positive finite number, got {value!r}")
        if not (math.isfinite(self.disc_mass) and self.disc_mass >= 0):
            raise ValueError(f"ArmParameters.disc_mass must be >= 0 and finite, got {self.disc_mass!r}")
        if not (math.isfinite(self.zeta) and 0 <= self.zeta < 1):
            raise ValueError(f"ArmParameters.zeta must be in [0, 1), got {self.zeta!r}")
        if math.isnan(self.k) or self.k <= 0:
            raise ValueError(f"ArmParameters.k must be positive (numpy.inf allowed), got {self.k!r}")
        _check_n(self.n_modes, "ArmParameters.n_modes")

    def replace(self, **changes: float) -> ArmParameters:
        """Return a copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)

    @property
    def total_mass(self) -> float:
        """Total mass m = rod + discs, kg (the discs are treated as uniformly distributed)."""
        return self.rod_mass + self.n_discs * self.disc_mass

    @property
    def mass_per_length(self) -> float:
        """Effective mass per length (rod + smeared discs), kg/m; the paper's ``rho A`` in eq. 5."""
        return self.total_mass / self.L


FITTED = ArmParameters(r=0.005864293416234312, k=1744.1442579272143, zeta=0.058275450909921825)
"""The fitted model: the paper's backbone, the fixed 1.0 g discs and the solved ``r``, ``k`` and ``zeta``.

Stored values, to the last digit, of :func:`helpers.research.model_fit.fit_to_mode` with its defaults (the
paper's identified mode, omega_d = 25.085 rad/s and zeta = 0.044, and its "30 mm of cable gives about 0.5 m
of tip displacement"); ``tests/test_model_fit.py`` re-runs that fit and checks that it reproduces them
(``pytest tests/test_model_fit.py``; its failure message prints the values to store here)."""


PARAMETER_SOURCES: dict[str, tuple[str, str]] = {
    "E": ("Pa", "handbook: ASTM A228 music wire, 30e6 psi"),
    "rho": ("kg/m^3", "handbook: carbon steel"),
    "d": ("m", "paper"),
    "L": ("m", "paper"),
    "r": ("m", "fitted (k, r, zeta jointly), see fit_to_mode()"),
    "disc_mass": ("kg", "assumed and fixed: ~1 g printed disc"),
    "n_discs": ("-", "paper"),
    "k": ("N/m", "fitted (k, r, zeta jointly), see fit_to_mode()"),
    "zeta": ("-", "fitted (k, r, zeta jointly), see fit_to_mode()"),
    "n_modes": ("-", "paper"),
}
"""Unit and origin of every :class:`ArmParameters` field."""


def parameter_table(params: ArmParameters) -> pd.DataFrame:
    """The parameters with their units and where each value comes from, plus the derived masses.

    Returns
    -------
    pandas.DataFrame
        Index: parameter name; columns ``value``, ``unit``, ``source``.
    """
    rows = [(name, float(getattr(params, name)), *PARAMETER_SOURCES[name]) for name in PARAMETER_SOURCES]
    rows += [
        ("EI", params.EI, "N m^2", "derived"),
        ("rod mass", params.rod_mass, "kg", "derived"),
        ("total mass m", params.total_mass, "kg", "derived (discs smeared uniformly)"),
    ]
    return pd.DataFrame(rows, columns=["parameter", "value", "unit", "source"]).set_index("parameter")


@dataclass(frozen=True)
class DominantMode:
    """The lightly damped pole pair that dominates the tension response.

    Attributes
    ----------
    omega_n : float
        Undamped natural frequency |p|, rad/s.
    zeta : float
        Damping ratio -Re(p)/|p|.
    omega_d : float
        Damped natural frequency Im(p), rad/s.
    """

    omega_n: float
    zeta: float
    omega_d: float

    @property
    def pole(self) -> complex:
        """The pole with positive imaginary part."""
        return complex(-self.zeta * self.omega_n, self.omega_d)


# ----------------------------------------------------------------------------------------------
# Modal quantities (paper eqs. 2, 5-10)
# ----------------------------------------------------------------------------------------------


def modal_frequencies(params: ArmParameters) -> np.ndarray:
    """Undamped modal frequencies ``omega_n = beta_n^2 sqrt(EI / (rho_eff A L^4))`` (paper eq. 5), rad/s."""
    beta = cantilever_roots(params.n_modes)
    return beta**2 * math.sqrt(params.EI / (params.mass_per_length * params.L**4))


def modal_masses(params: ArmParameters) -> np.ndarray:
    """Modal masses ``m_n = m / 4`` of the tip-normalised modes, kg."""
    return np.full(params.n_modes, params.total_mass / 4.0)


def modal_stiffnesses(params: ArmParameters) -> np.ndarray:
    """Modal stiffnesses ``k_n = m_n omega_n^2``, N/m."""
    return modal_masses(params) * modal_frequencies(params) ** 2


def coupling(params: ArmParameters) -> np.ndarray:
    """Coupling coefficients ``K_n = r phi_n'(L)`` (paper eq. 6), dimensionless (m of cable per m of q_n)."""
    return params.r / params.L * coupling_coefficients(params.n_modes)


def rayleigh_coefficients(omega_1: float, omega_2: float, zeta: float) -> tuple[float, float]:
    """Rayleigh coefficients (eta, delta) giving damping ratio ``zeta`` at ``omega_1`` and ``omega_2``.

    ``delta = 2 zeta / (omega_1 + omega_2)`` (s), ``eta = 2 zeta omega_1 omega_2 / (omega_1 + omega_2)``
    (1/s), paper eqs. 9-10; ``c_n = eta m_n + delta k_n`` (eq. 8).
    """
    if not (omega_1 > 0 and omega_2 > 0 and math.isfinite(omega_1) and math.isfinite(omega_2)):
        raise ValueError(f"omega_1, omega_2 must be positive and finite, got {omega_1!r}, {omega_2!r}")
    if not (0 <= zeta < 1):
        raise ValueError(f"zeta must be in [0, 1), got {zeta!r}")
    total = omega_1 + omega_2
    return 2.0 * zeta * omega_1 * omega_2 / total, 2.0 * zeta / total


def modal_damping(params: ArmParameters) -> np.ndarray:
    """Modal damping coefficients ``c_n = eta m_n + delta k_n`` (paper eq. 8), N s/m.

    With one mode only, ``c_1 = 2 zeta m_1 omega_1`` (Rayleigh needs two frequencies).
    """
    w = modal_frequencies(params)
    m = modal_masses(params)
    if params.n_modes == 1:
        return 2.0 * params.zeta * m * w
    eta, delta = rayleigh_coefficients(float(w[0]), float(w[1]), params.zeta)
    return eta * m + delta * m * w**2


def modal_damping_ratios(params: ArmParameters) -> np.ndarray:
    """Damping ratio of each uncoupled mode, ``c_n / (2 m_n omega_n)``."""
    return modal_damping(params) / (2.0 * modal_masses(params) * modal_frequencies(params))


# ----------------------------------------------------------------------------------------------
# State space and transfer functions (paper eqs. 11-13)
# ----------------------------------------------------------------------------------------------


def state_space(params: ArmParameters) -> control.StateSpace:
    """State-space form of the N-mode model, order 2N+1, for a finite cable stiffness.

    States ``[u, q_1..q_N, q_1'..q_N']`` (m, m, m/s); input the cable velocity ``v`` (m/s); outputs the
    tension ``lambda = k (u - sum K_n q_n)`` (N) and the tip displacement ``y = sum q_n`` (m).

    Raises
    ------
    ValueError
        For ``k = inf``: the tension is then an improper function of the velocity (no state space);
        use :func:`transfer_functions`.
    """
    if not math.isfinite(params.k):
        raise ValueError("state_space needs a finite cable stiffness k; for k = inf use transfer_functions")
    n = params.n_modes
    m, c, kn, big_k = modal_masses(params), modal_damping(params), modal_stiffnesses(params), coupling(params)
    k = params.k
    a = np.zeros((2 * n + 1, 2 * n + 1))
    a[1 : n + 1, n + 1 :] = np.eye(n)
    a[n + 1 :, 0] = k * big_k / m
    a[n + 1 :, 1 : n + 1] = -(np.diag(kn) + k * np.outer(big_k, big_k)) / m[:, None]
    a[n + 1 :, n + 1 :] = -np.diag(c / m)
    b = np.zeros((2 * n + 1, 1))
    b[0, 0] = 1.0
    cmat = np.zeros((2, 2 * n + 1))
    cmat[0, 0] = k
    cmat[0, 1 : n + 1] = -k * big_k
    cmat[1, 1 : n + 1] = 1.0
    return control.ss(
        a,
        b,
        cmat,
        np.zeros((2, 1)),
        inputs=["v"],
        outputs=["tension", "tip"],
        states=["u"] + [f"q{i}" for i in range(1, n + 1)] + [f"qdot{i}" for i in range(1, n + 1)],
    )


def _modal_polynomials(params: ArmParameters) -> tuple[list[np.ndarray], np.ndarray, np.ndarray]:
    """Monic ``d_n = D_n / m_n`` and the weights ``a_n = K_n^2/m_n``, ``b_n = K_n/m_n``."""
    w, m, c, big_k = modal_frequencies(params), modal_masses(params), modal_damping(params), coupling(params)
    d = [np.array([1.0, c[i] / m[i], w[i] ** 2]) for i in range(params.n_modes)]
    return d, big_k**2 / m, big_k / m


def _product(polys: list[np.ndarray]) -> np.ndarray:
    return functools.reduce(np.polymul, polys, np.array([1.0]))


def transfer_functions(params: ArmParameters) -> tuple[control.TransferFunction, control.TransferFunction]:
    """Transfer functions ``Lambda(s)/(s U(s))`` (N per m/s) and ``Y(s)/(s U(s))`` (m per m/s).

    Built as exact rational functions of the modal polynomials: with ``d_n = D_n / m_n``, ``P = prod d_n``,
    ``P_n = prod_{j != n} d_j``, ``a_n = K_n^2 / m_n`` and ``b_n = K_n / m_n``::

        Lambda/(sU) = k P / (s (P + k sum a_n P_n)),   Y/(sU) = k sum b_n P_n / (s (P + k sum a_n P_n))

    so the denominator (order 2N+1) has no factor in common with the numerators and no cancellation is
    needed. For ``k = inf`` (inextensible cable) the limits ``P / (s sum a_n P_n)`` (numerator order 2N,
    denominator 2N-1: *improper*, as the paper says) and ``sum b_n P_n / (s sum a_n P_n)`` are returned.

    Parameters
    ----------
    params : ArmParameters
        The model.

    Returns
    -------
    tuple of control.TransferFunction
        ``(tension_tf, tip_tf)``; input cable velocity in m/s, outputs tension in N and tip displacement
        in m.
    """
    d, a, b = _modal_polynomials(params)
    n = params.n_modes
    p_all = _product(d)
    p_except = [_product([d[j] for j in range(n) if j != i]) for i in range(n)]
    sum_a = functools.reduce(np.polyadd, [a[i] * p_except[i] for i in range(n)])
    sum_b = functools.reduce(np.polyadd, [b[i] * p_except[i] for i in range(n)])
    s = np.array([1.0, 0.0])
    if math.isfinite(params.k):
        gain, den = params.k, np.polymul(s, np.polyadd(p_all, params.k * sum_a))
    else:
        gain, den = 1.0, np.polymul(s, sum_a)
    tension = control.tf(gain * p_all, den, inputs="v", outputs="tension")
    tip = control.tf(gain * sum_b, den, inputs="v", outputs="tip")
    return tension, tip


def relative_degree(tf: control.TransferFunction) -> int:
    """Denominator degree minus numerator degree of a SISO transfer function (< 0: improper)."""
    num = np.trim_zeros(np.atleast_1d(np.squeeze(tf.num[0][0])), "f")
    den = np.trim_zeros(np.atleast_1d(np.squeeze(tf.den[0][0])), "f")
    return len(den) - len(num)


def model_order(tf: control.TransferFunction, tol: float = 1e-6) -> int:
    """Number of poles left after cancelling coincident pole-zero pairs (McMillan degree, SISO).

    Parameters
    ----------
    tf : control.TransferFunction
        SISO transfer function.
    tol : float
        Relative distance ``|p - z| <= tol * max(1, |p|)`` under which a pole and a zero cancel.

    Returns
    -------
    int
        Order of a minimal realisation.
    """
    pls = list(np.atleast_1d(tf.poles()))
    zrs = list(np.atleast_1d(tf.zeros()))
    order = 0
    for p in pls:
        match = [i for i, z in enumerate(zrs) if abs(p - z) <= tol * max(1.0, abs(p))]
        if match:
            zrs.pop(match[0])
        else:
            order += 1
    return order


def poles(params: ArmParameters) -> np.ndarray:
    """Poles of the tension transfer function, sorted by increasing |p| (the integrator's 0 first).

    For finite ``k``: the eigenvalues of :func:`state_space` (2N+1 of them). For ``k = inf``: the roots of
    the denominator of the (improper) limit (2N-1 of them).
    """
    if math.isfinite(params.k):
        p = linalg.eigvals(state_space(params).A)
    else:
        p = transfer_functions(params)[0].poles()
    p = np.asarray(p, dtype=complex)
    return p[np.argsort(np.abs(p), kind="stable")]


def tension_residues(params: ArmParameters) -> tuple[np.ndarray, np.ndarray]:
    """Poles and residues of ``Lambda(s)/(s U(s))`` (finite ``k``), from the eigen-decomposition.

    The tension response to a unit cable *displacement* step (a unit impulse of velocity) is
    ``sum_i r_i exp(p_i t)``; a complex pair contributes an oscillation of amplitude ``2 |r_i|`` N/m.

    Returns
    -------
    tuple of numpy.ndarray
        ``(poles, residues)``, sorted as :func:`poles`.
    """
    sys_ = state_space(params)
    evals, left, right = linalg.eig(sys_.A, left=True, right=True)
    c = sys_.C[0:1, :]
    res = np.array(
        [
            (c @ right[:, i]).item() * (left[:, i].conj() @ sys_.B).item() / (left[:, i].conj() @ right[:, i])
            for i in range(len(evals))
        ]
    )
    order = np.argsort(np.abs(evals), kind="stable")
    return evals[order], res[order]


DOMINANCE_THRESHOLD: float = 1e-3
"""A pole pair whose velocity-step amplitude ``|r_i/p_i|`` is below this fraction of the largest one is
ignored by :func:`dominant_mode` (it is nearly cancelled by a zero and cannot dominate anything)."""


def dominant_mode(params: ArmParameters) -> DominantMode:
    """The complex pole pair that dominates the tension response.

    Definition: the oscillatory pole pair of ``Lambda/(sU)`` with the **slowest decay** (smallest
    ``-Re p``), among the pairs whose term in the tension response to a unit step of cable velocity,
    ``2 |r_i / p_i| exp(Re(p_i) t)`` (``r_i`` the residue, :func:`tension_residues`), has an amplitude of
    at least :data:`DOMINANCE_THRESHOLD` times the largest. This is the mode that remains in a free
    decay once the faster-decaying terms have died away, which is what the paper identifies (window
    9-10 s, one second after the release starts at 8 s). For the fitted arm it is also the pair with
    the largest amplitude; for very stiff cables (k >~ 1e5 N/m) an ideal velocity step rings the fast
    cable mode harder, but that mode decays about 100 times faster. It lies between the first two modal
    frequencies: the cable stiffens mode 1 towards the clamped-guided frequency. For ``k = inf`` (no
    residues: the transfer function is improper) the slowest-decaying complex pair is returned.

    Returns
    -------
    DominantMode
        ``omega_n = |p|``, ``zeta = -Re p / |p|``, ``omega_d = Im p``.
    """
    if math.isfinite(params.k):
        p, r = tension_residues(params)
        upper = p.imag > 0
        p, amplitude = p[upper], np.abs(r[upper] / p[upper])
        candidates = p[amplitude >= DOMINANCE_THRESHOLD * np.max(amplitude, initial=0.0)]
    else:
        p = poles(params)
        candidates = p[p.imag > 0]
    if candidates.size == 0:
        raise ValueError("the model has no oscillatory pole pair")
    best = candidates[np.argmax(candidates.real)]
    omega_n = abs(best)
    return DominantMode(omega_n=float(omega_n), zeta=float(-best.real / omega_n), omega_d=float(best.imag))


def linear_response(
    params: ArmParameters, t: npt.ArrayLike, v: npt.ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """Tension and tip displacement of the model driven by a cable-velocity command, from rest.

    ``control.forced_response`` of :func:`state_space` (exact discretisation of the linear system with
    the command interpolated linearly between samples), so use a fine uniform grid for piecewise-constant
    commands.

    Parameters
    ----------
    params : ArmParameters
        The model (finite ``k``).
    t : array_like
        Increasing sample times, s.
    v : array_like
        Cable velocity at those times, **m/s** (positive pulls the cable).

    Returns
    -------
    tuple of numpy.ndarray
        ``(tension, tip)``: tension in N (zero at rest: the linear model has no pretension) and tip
        displacement in m.
    """
    ta = np.asarray(t, dtype=float)
    va = np.asarray(v, dtype=float)
    if ta.ndim != 1 or ta.shape != va.shape:
        raise ValueError(f"t and v must be 1-D arrays of equal length, got {ta.shape} and {va.shape}")
    if ta.size < 2 or np.any(np.diff(ta) <= 0) or not (np.all(np.isfinite(ta)) and np.all(np.isfinite(va))):
        raise ValueError("t must be finite and strictly increasing (at least 2 samples) and v finite")
    resp = control.forced_response(state_space(params), T=ta, U=va)
    y = np.asarray(resp.outputs)
    return y[0], y[1]


# ----------------------------------------------------------------------------------------------
# Statics
# ----------------------------------------------------------------------------------------------


def static_tension_gain(params: ArmParameters) -> float:
    """Static tension per cable displacement ``lambda/u = 1 / (1/k + sum K_n^2 / k_n)``, N/m."""
    big_k, kn = coupling(params), modal_stiffnesses(params)
    return 1.0 / (1.0 / params.k + float(np.sum(big_k**2 / kn)))


def static_tip_gain(params: ArmParameters) -> float:
    """Static tip displacement per cable displacement ``y/u = sum(K_n/k_n) / (1/k + sum K_n^2/k_n)``.

    As ``k -> inf`` and ``N -> inf`` this tends to ``L / (2 r)`` (a pure tip moment ``lambda r`` bends the
    cantilever to tip slope ``lambda r L / EI`` and tip deflection ``lambda r L^2 / (2 EI)``).
    """
    big_k, kn = coupling(params), modal_stiffnesses(params)
    return float(np.sum(big_k / kn)) * static_tension_gain(params)
