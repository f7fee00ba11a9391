"""The lane driver's pieces shared by the planar and the spatial kernels (numba, no ``fastmath``).

Both kernels advance every lane through its events (stepper steps, samples) in equal steps, splitting a step
at a taut/slack transition found by the Illinois method on the step size
(:func:`helpers.virtual._kernel.advance`, :func:`helpers.virtual.spatial._kernel.advance`). Their float state
``S`` (one row per quantity, lanes along it) begins with the rows below, the same in both; each kernel's own
rows follow from :data:`N_DRIVER`. Their integer state ``L[lane]`` begins with the columns below, its own
from :data:`N_DRIVER_INTS`. Rows ``0 .. D_PERSIST - 1`` carry over from one call to the next.
"""

from __future__ import annotations

import math

from numba import njit

from helpers.virtual.lanes import all_lane, any_lane, lane, lane_count, select, set_lane

# what persists between calls (time, the largest step, the amplifier's time constant, steps and transitions
# counted), then the present piece and step
(D_T, D_HMAX, D_TAU, D_NSTEP, D_NTRANS, D_TARGET, D_H, D_REM, D_FLO, D_FHI, D_LO, D_HI, D_HC, D_HSTEP, D_FH,
 D_FA, D_ACTIVE, D_LEFT, D_SPLITS, D_SEARCH, D_GEOM, D_COMMIT, D_FULL, D_PEND) = range(24)  # fmt: skip
N_DRIVER = 24
"""Rows of the shared float state; a kernel's own rows follow."""
D_PERSIST = D_TARGET
"""Shared rows ``0 .. D_PERSIST - 1`` carry over from one call to the next; the other shared rows are work."""
(L_QI, L_JS, L_SIDE, L_IT, L_TOSTEP, L_AIMED) = range(6)
N_DRIVER_INTS = 6
"""Columns of the shared integer state; a kernel's own columns follow."""


@njit(cache=True, error_model="numpy", nogil=True)
def blend(mask, dst, src, count):
    """``dst[:count] <- src[:count]`` in the lanes of ``mask``."""
    if all_lane(mask):
        for i in range(count):
            dst[i] = src[i]
    elif any_lane(mask):
        for i in range(count):
            dst[i] = select(mask, src[i], dst[i])


@njit(cache=True, error_model="numpy", nogil=True)
def begin(S, L):
    """A call's start: the shared work rows cleared, every lane active and aiming at nothing yet."""
    for j in range(D_PERSIST, N_DRIVER):
        S[j] = 0.0
    S[D_ACTIVE] = 1.0
    for k in range(L.shape[0]):
        L[k, L_AIMED] = 0
        L[k, L_QI] = 0
        L[k, L_JS] = 0


@njit(cache=True, error_model="numpy", nogil=True)
def start_steps(S, mask, implicit):
    """The lanes of ``mask`` begin a step of their piece's size (the kernel sets its branch state)."""
    h = S[D_H]
    S[D_REM] = select(mask, h, S[D_REM])
    S[D_HSTEP] = select(mask, h, S[D_HSTEP])
    if implicit:
        S[D_GEOM] = select(mask, 1.0, S[D_GEOM])
    S[D_SPLITS] = select(mask, 0.0, S[D_SPLITS])
    S[D_SEARCH] = select(mask, 0.0, S[D_SEARCH])


@njit(cache=True, error_model="numpy", nogil=True)
def arrive(S, L, k):
    """Lane ``k``: True if it has reached the target it aimed at (its time is then the target's)."""
    if L[k, L_AIMED] != 0 and lane(S[D_LEFT], k) == 0.0:
        L[k, L_AIMED] = 0
        target = lane(S[D_TARGET], k)
        if target > lane(S[D_T], k):
            S[D_T] = set_lane(S[D_T], k, target)
        return True
    return False


@njit(cache=True, error_model="numpy", nogil=True)
def aim(S, L, k, sample_times, step_times, n_steps):
    """Lane ``k`` aims at its next event: its next step if not after its next sample, else that sample.

    Returns
    -------
    bool
        True if the lane is there already (within ``1e-9`` steps: a few ulps), as no step is taken; False
        if it has steps to take (``D_LEFT`` of size ``D_H``) or no sample is left (it goes idle).
    """
    qi = L[k, L_QI]
    if qi == sample_times.shape[1]:
        S[D_ACTIVE] = set_lane(S[D_ACTIVE], k, 0.0)
        return False
    ts = sample_times[k, qi]
    js = L[k, L_JS]
    to_step = js < n_steps[k] and step_times[k, js] <= ts
    target = step_times[k, js] if to_step else ts
    L[k, L_TOSTEP] = 1 if to_step else 0
    L[k, L_AIMED] = 1
    S[D_TARGET] = set_lane(S[D_TARGET], k, target)
    dt = target - lane(S[D_T], k)
    nst = math.ceil(dt / lane(S[D_HMAX], k) - 1e-9) if dt > 0.0 else 0
    if nst < 1:
        S[D_LEFT] = set_lane(S[D_LEFT], k, 0.0)
        return True
    S[D_LEFT] = set_lane(S[D_LEFT], k, float(nst))
    S[D_H] = set_lane(S[D_H], k, dt / nst)
    return False


@njit(cache=True, error_model="numpy", nogil=True)
def _bracket(S, L, k, f_lo, f_hi, lo, hi, side):
    """Lane ``k``'s search bracket stored, and its next trial's size: the regula falsi point, else the middle.

    The trial's size is both ``D_HC`` and ``D_HSTEP``.
    """
    den = f_hi - f_lo
    hc = (lo * f_hi - hi * f_lo) / den if den != 0.0 else 0.5 * (lo + hi)
    if not (hc > lo and hc < hi):
        hc = 0.5 * (lo + hi)
    S[D_FLO] = set_lane(S[D_FLO], k, f_lo)
    S[D_FHI] = set_lane(S[D_FHI], k, f_hi)
    S[D_LO] = set_lane(S[D_LO], k, lo)
    S[D_HI] = set_lane(S[D_HI], k, hi)
    S[D_HC] = set_lane(S[D_HC], k, hc)
    S[D_HSTEP] = set_lane(S[D_HSTEP], k, hc)
    L[k, L_SIDE] = side


@njit(cache=True, error_model="numpy", nogil=True)
def begin_search(S, L, k, f_lo, f_hi):
    """Lane ``k`` starts the search for a transition within its step: ``f_lo``, ``f_hi`` its function there.

    Counts the transition; the next trial's size is ``D_HSTEP``.
    """
    S[D_NTRANS] = set_lane(S[D_NTRANS], k, lane(S[D_NTRANS], k) + 1.0)
    L[k, L_IT] = 0
    S[D_SEARCH] = set_lane(S[D_SEARCH], k, 1.0)
    _bracket(S, L, k, f_lo, f_hi, 0.0, lane(S[D_REM], k), 0)


@njit(cache=True, error_model="numpy", nogil=True)
def search_step(S, L, k, fc):
    """Lane ``k``'s search after a trial of size ``D_HC`` where the transition function is ``fc``.

    Illinois method: the bracket narrowed to the trial's side, the function at the end kept twice in a row
    halved; the next trial's size is ``D_HSTEP``.

    Returns
    -------
    tuple
        ``(found, hc, f_hi)``: True if the search ends (``|fc| < 1e-13``, a bracket below ``1e-11`` or 40
        trials), the trial's size, the function at the bracket's upper end.
    """
    f_lo = lane(S[D_FLO], k)
    f_hi = lane(S[D_FHI], k)
    lo = lane(S[D_LO], k)
    hi = lane(S[D_HI], k)
    side = L[k, L_SIDE]
    hc = lane(S[D_HC], k)
    it = L[k, L_IT] + 1
    L[k, L_IT] = it
    if abs(fc) < 1e-13 or hi - lo < 1e-11 or it == 40:
        return True, hc, f_hi
    if (fc > 0.0) == (f_lo > 0.0):
        lo = hc
        f_lo = fc
        if side == -1:
            f_hi *= 0.5
        side = -1
    else:
        hi = hc
        f_hi = fc
        if side == 1:
            f_lo *= 0.5
        side = 1
    _bracket(S, L, k, f_lo, f_hi, lo, hi, side)
    return False, hc, f_hi


@njit(cache=True, error_model="numpy", nogil=True)
def split(S, k, hc, implicit):
    """Lane ``k`` keeps its trial of size ``hc`` (to the transition); the rest of its step follows."""
    S[D_COMMIT] = set_lane(S[D_COMMIT], k, 1.0)
    rem = lane(S[D_REM], k) - hc
    S[D_REM] = set_lane(S[D_REM], k, rem)
    S[D_HSTEP] = set_lane(S[D_HSTEP], k, rem)
    S[D_SPLITS] = set_lane(S[D_SPLITS], k, lane(S[D_SPLITS], k) + 1.0)
    if implicit:
        S[D_GEOM] = set_lane(S[D_GEOM], k, 1.0)
    S[D_SEARCH] = set_lane(S[D_SEARCH], k, 0.0)


@njit(cache=True, error_model="numpy", nogil=True)
def filter_gain(S, accept):
    """The amplifier's ``exp(-h / tau)`` over the accepted steps (``D_REM`` each), lanes at once.

    Kept from the last step of the same size (the same bits as computing it again).

    Returns
    -------
    tuple
        ``(a, h, tau)``.
    """
    h = S[D_REM]
    tau = S[D_TAU]
    fresh = accept & (h != S[D_FH]) & (tau > 0.0)
    if any_lane(fresh):
        for k in range(lane_count(h)):
            if lane(fresh, k):
                hk = lane(h, k)
                S[D_FA] = set_lane(S[D_FA], k, math.exp(-hk / lane(tau, k)))
                S[D_FH] = set_lane(S[D_FH], k, hk)
    return S[D_FA], h, tau
