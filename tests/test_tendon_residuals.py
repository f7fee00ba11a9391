"""Residuals of every tendon and of the tip after a move, on a hand-made recording whose figures are known.

The lead tendon (0) pulls 40 steps in 1.000-1.200 s and releases them in 3.000-3.200 s. Its tension is
2 N + 3 N x (steps / 40), plus after each motion's end a sine of 0.4 N at 5 Hz (sampled at 1 kHz, the window
0.1-1.1 s after the end holds five whole periods and the sine's peaks): the residual is 0.4 N, the step
+3 N (Up) and -3 N (Down), 13.33 %. Tendon 2 holds 2 N, except ten samples at 1 N inside the Up's residual
window (below a 1.5 N floor). The tip moves 10 mm along x with the lead's steps, plus 0.2 mm of the same
sine after Up.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from helpers.research.tendon_residuals import lead_tendon, move_residuals_tendons


def _frame() -> pd.DataFrame:
    k = np.arange(0, 6000)
    t = k / 1000.0
    steps = np.clip((k - 1000) // 5, 0, 40) - np.clip((k - 3000) // 5, 0, 40)  # one step every 5 ms
    ring = np.zeros_like(t)
    for end in (1.2, 3.2):
        after = (t > end) & (t < end + 1.6)
        ring[after] = np.sin(2 * np.pi * 5.0 * (t[after] - end) - np.pi / 2) * 0.4  # peaks on the samples
    tension0 = 2.0 + 3.0 * steps / 40 + ring
    tension1 = np.full_like(t, 2.0)
    tension1[1500:1510] = 1.0
    tip_x = 10.0 * steps / 40 + np.where((t > 1.2) & (t < 2.8), ring / 2, 0.0)
    return pd.DataFrame({
        "t_s": t, "steps_0": steps.astype(int), "steps_1": np.zeros(t.size, int),
        "tension_n_0": tension0, "tension_n_1": tension1,
        "tip_x_mm": tip_x, "tip_y_mm": np.zeros_like(t), "tip_z_mm": np.full_like(t, 240.0),
    })  # fmt: skip


def test_the_lead_is_the_tendon_that_moves_most() -> None:
    assert lead_tendon(_frame(), 2) == 0


def test_residuals_steps_and_slack_samples_are_the_hand_made_ones() -> None:
    df = move_residuals_tendons(_frame(), 2, floor_n=1.5).set_index(["motion", "signal"])
    up, down = df.loc[("Up", "tendon 1")], df.loc[("Down", "tendon 1")]
    assert up["move_end_s"] == pytest.approx(1.2) and down["move_end_s"] == pytest.approx(3.2)
    assert up["residual"] == pytest.approx(0.4, abs=1e-9) and down["residual"] == pytest.approx(0.4, abs=1e-9)
    assert up["step"] == pytest.approx(3.0, abs=1e-9) and down["step"] == pytest.approx(-3.0, abs=1e-9)
    assert up["residual_pct"] == pytest.approx(100 * 0.4 / 3.0)
    assert up["noise"] == 0.0 and up["below_floor"] == 0
    held = df.loc[("Up", "tendon 2")]
    assert held["below_floor"] == 10 and held["least"] == 1.0 and np.isnan(held["residual_pct"])
    assert df.loc[("Down", "tendon 2"), "below_floor"] == 0
    tip = df.loc[("Up", "tip")]
    assert tip["unit"] == "mm" and tip["residual"] == pytest.approx(0.2, abs=1e-9)
    assert tip["step"] == pytest.approx(10.0, abs=1e-9) and tip["below_floor"] == 0
