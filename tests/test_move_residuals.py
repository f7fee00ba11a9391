"""The one residual analysis of a move (``helpers.research.residuals``) on hand-made recordings whose figures
are known, and the lead tendon (``helpers.rigfile.derived.lead_tendon``) worked out by hand.

**Two tendons, no pre-pull** (:func:`_two`): tendon 1 pulls 40 steps in 1.000-1.200 s and releases them in
3.000-3.200 s. Its tension is 2 N + 3 N x (steps / 40), plus after each motion's end a sine of 0.4 N at 5 Hz
(sampled at 1 kHz, the window 0.1-1.1 s after the end holds five whole periods and the sine's peaks): the
residual is 0.4 N, the step +3 N (Up) and -3 N (Down), 13.33 %. Tendon 2 holds 2 N, except ten samples at
1 N inside the Up's residual window (below a 1.5 N floor). The tip moves 10 mm along x with tendon 1's steps,
plus 0.2 mm of the same sine after Up.

**Three tendons at 0/120/240 deg, bent towards 45 deg, with a pre-pull** (:func:`_three`): every count is 0
until 0.2 s, then every tendon is pulled one step in (the pre-pull); at 2.005-2.100 s tendon 1 takes 20 steps
(one each 5 ms), tendon 2 ten (one each 10 ms) and tendon 3 pays 24 out (one each 4 ms); back at 6.005-6.100
s; the pre-pull is let out one tendon at a time at 9.0 (tendon 1), 9.25 (tendon 3) and 9.5 s (tendon 2); 11 s
recorded. Each
tension is 2 N + 5 N per pre-pull step + 0.15 N per step of the move, plus a sine of 0.3 N at 5 Hz for 1.6 s
after each motion's end: tendon 1's step is +3 N (Up) and -3 N (Down, whose window ends where the release
starts, at 9.0 s), its residual 0.3 N, 10 %. The largest step range is tendon 3's (24 steps, paying out);
the lead is tendon 1.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from helpers.research.residuals import move_phases, move_residuals, residual_table, rising_tendon
from helpers.rigfile.derived import lead_tendon


def _ring(t: np.ndarray, ends: tuple[float, ...], amplitude: float) -> np.ndarray:
    out = np.zeros_like(t)
    for end in ends:
        after = (t > end) & (t < end + 1.6)
        out[after] = np.sin(2 * np.pi * 5.0 * (t[after] - end) - np.pi / 2) * amplitude  # peaks on samples
    return out


def _two() -> pd.DataFrame:
    k = np.arange(0, 6000)
    t = k / 1000.0
    steps = np.clip((k - 1000) // 5, 0, 40) - np.clip((k - 3000) // 5, 0, 40)  # one step every 5 ms
    ring = _ring(t, (1.2, 3.2), 0.4)
    tension1 = np.full_like(t, 2.0)
    tension1[1500:1510] = 1.0
    tip_x = 10.0 * steps / 40 + np.where((t > 1.2) & (t < 2.8), ring / 2, 0.0)
    return pd.DataFrame({
        "t_s": t, "steps_0": steps.astype(int), "steps_1": np.zeros(t.size, int),
        "tension_n_0": 2.0 + 3.0 * steps / 40 + ring, "tension_n_1": tension1,
        "tip_x_mm": tip_x, "tip_y_mm": np.zeros_like(t), "tip_z_mm": np.full_like(t, 240.0),
    })  # fmt: skip


def _three() -> pd.DataFrame:
    k = np.arange(0, 11000)
    t = k / 1000.0
    pre = (k >= 200).astype(int)

    def move(n: int, every_ms: int) -> np.ndarray:
        sign = 1 if n > 0 else -1
        out = np.clip((k - 2000) // every_ms, 0, abs(n)) - np.clip((k - 6000) // every_ms, 0, abs(n))
        return sign * out

    moves = (move(20, 5), move(10, 10), move(-24, 4))
    releases = (9000, 9500, 9250)
    frame = {"t_s": t}
    ring = _ring(t, (2.1, 6.1), 0.3)
    for i, (m, r) in enumerate(zip(moves, releases, strict=True)):
        p = pre - (k >= r).astype(int)
        frame[f"steps_{i}"] = p + m
        frame[f"tension_n_{i}"] = 2.0 + 5.0 * p + 0.15 * m + (ring if i == 0 else 0.0)
    return pd.DataFrame(frame)


def test_the_lead_is_the_tendon_that_pulls_most_towards_the_bend() -> None:
    """(r_i / r_mean) cos(beta - a_i) by hand; equal pulls: the lowest index; offsets weigh the pull."""
    three = [SimpleNamespace(angle_deg=a, offset_mm=7.8) for a in (0.0, 120.0, 240.0)]
    four = [SimpleNamespace(angle_deg=a, offset_mm=7.8) for a in (0.0, 90.0, 180.0, 270.0)]
    assert lead_tendon(three, 45.0) == 0  # cos 45 = 0.71 against cos 75 = 0.26; tendon 3 pays out
    assert lead_tendon(three, 67.5) == 1  # cos 67.5 = 0.38 against cos 52.5 = 0.61
    assert lead_tendon(three, 180.0) == 1  # tendons 2 and 3 pull alike (cos 60): the lower index
    assert lead_tendon(four, 45.0) == 0 and lead_tendon(four, 135.0) == 1 and lead_tendon(four, 315.0) == 0
    uneven = [SimpleNamespace(angle_deg=0.0, offset_mm=5.0), SimpleNamespace(angle_deg=90.0, offset_mm=10.0)]
    assert lead_tendon(uneven, 40.0) == 1  # 5 cos 40 = 3.8 against 10 cos 50 = 6.4


def test_without_a_direction_the_lead_is_the_count_that_rises_most_not_the_largest_range() -> None:
    f = _three()
    counts = f[["steps_0", "steps_1", "steps_2"]].to_numpy()
    assert np.ptp(counts, axis=0).tolist() == [21, 11, 24]  # tendon 3, paying out, has the largest range
    assert rising_tendon(counts) == 0


def test_residuals_steps_and_slack_samples_are_the_hand_made_ones() -> None:
    f = _two()
    phases = move_phases(f["t_s"].to_numpy(), f[["steps_0", "steps_1"]].to_numpy(), 0)
    df = residual_table(f, 2, phases, floor_n=1.5).set_index(["motion", "signal"])
    up, down = df.loc[("Up", "tendon 1")], df.loc[("Down", "tendon 1")]
    assert up["move_end_s"] == pytest.approx(1.2) and down["move_end_s"] == pytest.approx(3.2)
    assert up["residual"] == pytest.approx(0.4, abs=1e-9) and down["residual"] == pytest.approx(0.4, abs=1e-9)
    assert up["step"] == pytest.approx(3.0, abs=1e-9) and down["step"] == pytest.approx(-3.0, abs=1e-9)
    assert up["residual_pct"] == pytest.approx(100 * 0.4 / 3.0)
    assert up["noise"] == 0.0 and up["below_floor"] == 0 and up["role"] == "lead"
    held = df.loc[("Up", "tendon 2")]
    assert held["below_floor"] == 10 and held["least"] == 1.0 and np.isnan(held["residual_pct"])
    assert held["role"] == "held" and held["tendon"] == 2
    assert df.loc[("Down", "tendon 2"), "below_floor"] == 0
    tip = df.loc[("Up", "tip")]
    assert tip["unit"] == "mm" and tip["residual"] == pytest.approx(0.2, abs=1e-9)
    assert tip["step"] == pytest.approx(10.0, abs=1e-9) and tip["below_floor"] == 0


def test_a_pre_pull_is_no_part_of_the_move() -> None:
    f = _three()
    phases = move_phases(f["t_s"].to_numpy(), f[["steps_0", "steps_1", "steps_2"]].to_numpy(), 0, prepull=1,
                         start=(0, 0, 0))  # fmt: skip
    assert phases.prepull_s == pytest.approx(0.2)
    assert (phases.up_start_s, phases.up_end_s) == (pytest.approx(2.005), pytest.approx(2.1))
    assert (phases.down_start_s, phases.down_end_s) == (pytest.approx(6.005), pytest.approx(6.1))
    assert phases.release_s == pytest.approx(9.0) and phases.end_s == pytest.approx(9.0)
    df = residual_table(f, 3, phases).set_index(["motion", "signal"])
    for motion, step in (("Up", 3.0), ("Down", -3.0)):  # the move's 20 steps, not the pre-pull's 5 N
        row = df.loc[(motion, "tendon 1")]
        assert row["step"] == pytest.approx(step, abs=1e-9)
        assert row["residual"] == pytest.approx(0.3, abs=1e-9) and row["residual_pct"] == pytest.approx(10.0)
        assert row["y0"] == pytest.approx(7.0 if motion == "Up" else 10.0, abs=1e-9)
    assert df.loc[("Down", "tendon 1"), "window_end_s"] == pytest.approx(9.0)
    assert df.loc[("Up", "tendon 1"), "noise"] == 0.0  # the second before the move, after the pre-pull
    roles = df.loc["Up"][["role", "held_steps"]]
    assert roles.to_dict("index") == {"tendon 1": {"role": "lead", "held_steps": 20},
                                      "tendon 2": {"role": "pulled", "held_steps": 10},
                                      "tendon 3": {"role": "paid out", "held_steps": -24}}  # fmt: skip


def test_the_pre_pulls_let_out_is_counted_with_the_moves_down_motion() -> None:
    """Dips below a 1 N floor as the pre-pull is let out (tendon 1: 2 samples at 9.000 s, tendon 3: 3 at
    9.250 s, the steps' transients) and one at 8.0 s, at rest between the Down's residual window (6.2-7.2 s)
    and the release: the Down motion counts the let-out's five, the Up none, the rest at 8.0 s neither."""
    f = _three()
    for i, at, n in ((0, 9000, 2), (2, 9250, 3), (1, 8000, 1)):
        f.loc[at : at + n - 1, f"tension_n_{i}"] = 0.4
    phases = move_phases(f["t_s"].to_numpy(), f[["steps_0", "steps_1", "steps_2"]].to_numpy(), 0, prepull=1,
                         start=(0, 0, 0))  # fmt: skip
    df = residual_table(f, 3, phases, floor_n=1.0).set_index(["motion", "signal"])
    down = df.loc["Down"]
    assert down["below_floor"].tolist() == [2, 0, 3] and down["below_floor_letout"].tolist() == [2, 0, 3]
    assert down.loc["tendon 1", "least"] == pytest.approx(0.4)
    up = df.loc["Up"]
    assert up["below_floor"].tolist() == [0, 0, 0] and up["below_floor_letout"].tolist() == [0, 0, 0]
    # without a pre-pull there is no let-out: the column is there, and nothing counts in it
    two = _two()
    phases = move_phases(two["t_s"].to_numpy(), two[["steps_0", "steps_1"]].to_numpy(), 0)
    plain = residual_table(two, 2, phases, floor_n=1.5)
    assert plain["below_floor_letout"].tolist() == [0] * len(plain) and plain["below_floor"].sum() == 10


def test_a_move_whose_count_turns_back_within_itself_is_one_motion() -> None:
    """A shaper with a negative impulse (UMZV) takes the count back within the move: out 40 steps, back 37,
    out 37 again (2.0-2.25 s), held to 6 s; the move back mirrored (its antagonist, paying out, falls below
    its level within it); the pre-pull let out at 9 s. One Up, one Down, the release where it is."""
    k = np.arange(0, 11000)
    t = k / 1000.0

    def piece(at: int, n: int) -> np.ndarray:  # n steps from ``at`` ms, one per ms
        return np.sign(n) * np.clip(k - at, 0, abs(n))

    out = piece(2000, 40) + piece(2100, -37) + piece(2200, 37)
    back = piece(6000, -40) + piece(6100, 37) + piece(6200, -37)
    lead = 1 + out + back - (k >= 9000)
    anta = 1 - out - back - (k >= 9250)
    phases = move_phases(t, np.column_stack([lead, anta]), 0, prepull=1, start=(0, 0))
    assert (phases.up_start_s, phases.up_end_s) == (pytest.approx(2.001), pytest.approx(2.237))
    assert (phases.down_start_s, phases.down_end_s) == (pytest.approx(6.001), pytest.approx(6.237))
    assert phases.release_s == pytest.approx(9.0)


def test_a_pre_pull_done_before_the_first_sample_is_found_from_the_start_positions() -> None:
    """A pre-pull of a millisecond is complete at the first sample: the counts start at 1, the start at 0."""
    f = _three().iloc[300:].reset_index(drop=True)
    counts = f[["steps_0", "steps_1", "steps_2"]].to_numpy()
    assert counts[0].tolist() == [1, 1, 1]
    phases = move_phases(f["t_s"].to_numpy(), counts, 0, prepull=1, start=(0, 0, 0))
    assert phases.up_start_s == pytest.approx(2.005) and phases.release_s == pytest.approx(9.0)
    assert phases.prepull_s == pytest.approx(0.3)  # pulled in at (or before) the first sample


def test_a_lead_that_makes_no_up_hold_down_move_is_named_in_one_line() -> None:
    f = _three()
    with pytest.raises(ValueError, match=r"^tendon 3 \(the lead\) makes no up-hold-down move from 1 step"):
        move_phases(f["t_s"].to_numpy(), f[["steps_0", "steps_1", "steps_2"]].to_numpy(), 2, prepull=1,
                    start=(0, 0, 0))  # fmt: skip


def test_the_one_tendon_table_is_the_same_analysis() -> None:
    """``move_residuals`` (one tendon, the shape the one-tendon tuning keeps) gives tendon 1's figures."""
    f = _two()
    one = f[["t_s"]].assign(steps=f["steps_0"], tension_n=f["tension_n_0"])
    table = move_residuals(one).set_index("motion")
    assert table.loc["Up", "residual_pct"] == pytest.approx(100 * 0.4 / 3.0)
    assert table.loc["Down", "move_end_s"] == pytest.approx(3.2) and not table.loc["Up", "slack"]
    assert list(table.columns) == ["move_start_s", "move_end_s", "move_duration_s", "residual_pct",
                                   "noise_floor_pct", "slack", "peak_n", "overshoot_pct", "settling_ms",
                                   "reason"]  # fmt: skip
