"""The paper's published numbers, as data, so that notebooks and tests can set ours beside them.

Nothing here is computed by the project: these are the values printed in the paper (Ibarra, Baker, Molaei,
Stein, Gilbert, *Input Shaping for Point-to-Point Motion with a Continuum Robot Arm*, Louisiana State
University). Our own computations live in the modules that own them and are compared to these.
"""

from __future__ import annotations

import pandas as pd

BETA = (1.875, 4.694, 7.855, 10.996)
"""Cantilever characteristic roots beta_n as printed (3 decimals)."""

K_L_OVER_R = (1.3765, 4.7811, 7.8470, 10.9913)
"""Coupling coefficients K_n L / r as printed (magnitudes)."""

ZETA = 0.044
"""Damping ratio identified from the pulse-release transient (window 9-10 s)."""

OMEGA_D = 25.085
"""Damped natural frequency identified from the same transient, rad/s."""

ZV_A0, ZV_A1, ZV_T = 0.5345, 0.4655, 0.12524
"""Non-robust TDF amplitudes and delay (s) as printed (its eq. 15 evaluated at ZETA and OMEGA_D)."""

ZVD_AMPLITUDES = (0.2857, 0.4976, 0.2167)
"""Robust TDF (the square of the non-robust one) amplitudes at 0, T, 2T."""

BACKBONE = {"material": "A228 music wire", "d_m": 0.82e-3, "L_m": 0.24, "n_discs": 12}
"""Backbone geometry as stated in the paper."""

STEPS_PER_REV = 800
SPOOL_DIAMETER_M = 0.065
"""The stepper set to 800 steps per revolution (TB6600 driver) and the cable spool's diameter."""

FULL_STEP_DEG = 1.8
HOLDING_TORQUE_KG_CM = 4.3
"""The stepper (MOTOU 17HS4401S, NEMA 17): full step angle and holding torque as printed."""

SHUNT_OHM = 150.0
"""The resistor that turns the load-cell amplifier's current-loop output into the ADC's input voltage."""

LOADCELL_RANGE_N = 5.0
"""The load cell's stated range (LSP-5, 0-5 N); Table II reports peaks up to 17.7 N."""

PULSE_T_UP_S = 1.0
PULSE_T_DOWN_S = 8.0
"""The velocity pulse starts the up move at 1 s and the down move at 8 s."""

IDENTIFICATION_RUN = {"v_in_mm_s": 100.0, "x_f_mm": 10.0, "window_s": (9.0, 10.0)}
"""The identification experiment: 100 mm/s, 10 mm, analysed on 9-10 s."""

TABLE_I_CONDITIONS = ((200.0, 10.0), (200.0, 20.0), (200.0, 30.0), (300.0, 20.0))
"""(v_in in mm/s, x_f in mm) of Table I; each is run unshaped, with the non-robust and the robust TDF."""

SYSTEMS = ("unshaped", "zv", "zvd")
"""Our names of the paper's three systems: pulse (unshaped), non-robust TDF (ZV), robust TDF (ZVD)."""

SYSTEM_LABELS = {"unshaped": "Pulse", "zv": "Non-robust", "zvd": "Robust"}
"""The paper's names of the three systems."""

_TABLE_II = [
    # v_in, x_f, system, motion, peak N, overshoot %, settling ms
    (200, 10, "unshaped", "Up", 9.0, 153.1, 1223),
    (200, 10, "unshaped", "Down", 0.0, 75.9, 1608),
    (200, 10, "zv", "Up", 7.5, 94.2, 1118),
    (200, 10, "zv", "Down", 0.4, 60.1, 1378),
    (200, 10, "zvd", "Up", 6.3, 51.1, 1002),
    (200, 10, "zvd", "Down", 0.8, 44.3, 1348),
    (200, 20, "unshaped", "Up", 13.6, 131.7, 1253),
    (200, 20, "unshaped", "Down", 0.0, 63.2, 1899),
    (200, 20, "zv", "Up", 9.6, 27.0, 1014),
    (200, 20, "zv", "Down", 1.9, 20.0, 1149),
    (200, 20, "zvd", "Up", 9.5, 12.5, 898),
    (200, 20, "zvd", "Down", 2.6, 6.1, 878),
    (200, 30, "unshaped", "Up", 13.8, 92.9, 1138),
    (200, 30, "unshaped", "Down", 0.0, 25.9, 2140),
    (200, 30, "zv", "Up", 10.6, 15.3, 1044),
    (200, 30, "zv", "Down", 0.1, 7.7, 1211),
    (200, 30, "zvd", "Up", 10.9, 16.5, 1044),
    (200, 30, "zvd", "Down", 1.1, 5.9, 970),
    (300, 20, "unshaped", "Up", 17.7, 151.6, 1328),
    (300, 20, "unshaped", "Down", 0.0, 96.4, 2475),
    (300, 20, "zv", "Up", 13.1, 65.6, 1182),
    (300, 20, "zv", "Down", 2.0, 51.3, 2068),
    (300, 20, "zvd", "Up", 12.1, 43.8, 1139),
    (300, 20, "zvd", "Down", 2.9, 31.5, 1567),
]


def table_ii() -> pd.DataFrame:
    """Return the paper's Table II (hardware measurements) as a DataFrame.

    Returns
    -------
    pandas.DataFrame
        Columns ``v_in_mm_s``, ``x_f_mm``, ``system`` (``unshaped``/``zv``/``zvd``), ``motion``
        (``Up``/``Down``), ``peak_n``, ``overshoot_pct``, ``settling_ms``.
    """
    return pd.DataFrame(
        _TABLE_II,
        columns=["v_in_mm_s", "x_f_mm", "system", "motion", "peak_n", "overshoot_pct", "settling_ms"],
    ).astype({"v_in_mm_s": float, "x_f_mm": float, "settling_ms": float})
