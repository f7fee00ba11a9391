"""``tune`` on a rig with several tendons: the schedule over the measured map, the designs, the summary, and a
short run end to end on the virtual rig (slow).

Expected values by hand: the map's interpolation is linear in the direction (periodic over 360 deg) and in
the bend; ZV's second impulse follows a half damped period, pi / omega_d, and ZVD's last one a whole period,
2 pi / omega_d (Singer and Seering; the paper's equations).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from helpers import rigfile
from helpers.__main__ import main
from helpers.research.tune_tendons import (
    REFERENCE,
    SUMMARY_COLUMNS,
    MapPoint,
    design_for,
    scheduled_mode,
    summarise,
    write_report,
)


def _points() -> list[MapPoint]:
    """A map on 0/90/180/270 deg x 10/20 mm: omega_d = 20 + d / 10 + b / 10 rad/s, zeta = 0.04 + b / 1000."""
    return [MapPoint(d, b, 20 + d / 10 + b / 10, 0.04 + b / 1000, 0.0, 0.0, "r")
            for d in (0.0, 90.0, 180.0, 270.0) for b in (10.0, 20.0)]  # fmt: skip


def test_the_schedule_is_the_map_at_its_points_and_linear_between() -> None:
    pts = _points()
    assert scheduled_mode(pts, 90.0, 10.0) == pytest.approx((30.0, 0.05))
    assert scheduled_mode(pts, 45.0, 15.0) == pytest.approx((20 + 4.5 + 1.5, 0.055))
    # between 270 and 360 = 0: from 48 (270 deg, 10 mm... + 1) back to 21
    w270, w0 = 20 + 27 + 1, 20 + 0 + 1
    assert scheduled_mode(pts, 315.0, 10.0)[0] == pytest.approx((w270 + w0) / 2)
    assert scheduled_mode(pts, -45.0, 10.0)[0] == pytest.approx((w270 + w0) / 2)
    # outside the bends: the nearest bend
    assert scheduled_mode(pts, 0.0, 30.0) == pytest.approx(scheduled_mode(pts, 0.0, 20.0))


def test_a_map_of_one_direction_is_that_direction_everywhere() -> None:
    """A reduced tune's map (one direction, one bend) schedules its one mode at every direction, whatever the
    direction's floating-point turn (143.4 deg + 360 deg is not 503.4 deg - 360 deg to the last digit)."""
    point = MapPoint(143.4, 10.0, 23.5, 0.07, 23.1, 0.048, "map_d143p4_b10")
    for d in (143.4, 0.0, 100.0, 200.0, 359.9, -216.6):
        assert scheduled_mode([point], d, 10.0) == (23.5, 0.07)
    assert scheduled_mode([point], 143.4, 20.0) == (23.5, 0.07)  # the nearest bend


def test_fixed_designs_use_the_reference_and_scheduled_ones_the_move() -> None:
    pts = _points()
    w_ref = 20 + REFERENCE[0] / 10 + REFERENCE[1] / 10
    zv = design_for("zv", pts, 180.0, 20.0)
    assert zv.omega_d == pytest.approx(w_ref) and zv.shaper.times[-1] == pytest.approx(math.pi / w_ref)
    zvd = design_for("scheduled-zvd", pts, 180.0, 20.0)
    assert zvd.omega_d == pytest.approx(40.0) and zvd.shaper.times[-1] == pytest.approx(2 * math.pi / 40.0)
    assert design_for("unshaped", pts, 0.0, 10.0).shaper is None
    with pytest.raises(ValueError, match="system must be one of"):
        design_for("ei", pts, 0.0, 10.0)


def test_the_summary_takes_the_worst_of_the_lead_and_the_tip_and_counts_slack_samples() -> None:
    rows = []
    for rep, (res, tip, below) in enumerate(((0.5, 2.0, 0), (0.7, 1.0, 3)), start=1):
        for signal, unit, r, b in (
            ("tendon 1", "N", res, 0),
            ("tendon 2", "N", 9.9, below),
            ("tip", "mm", tip, 0),
        ):
            rows.append({"direction_deg": 0.0, "system": "zv", "repetition": rep, "motion": "Up",
                         "signal": signal, "unit": unit, "lead": 1, "residual": r, "residual_pct": 10 * r,
                         "below_floor": b,
                         "least": 1.0 - rep if unit == "N" else 0.0, "shaper_s": 0.12})  # fmt: skip
    s = summarise(pd.DataFrame(rows)).iloc[0]
    assert s["lead_residual_n"] == 0.7 and s["tip_residual_mm"] == 2.0  # tendon 2 is not the lead
    assert s["below_floor"] == 3 and s["least_tension_n"] == -1.0 and s["shaper_s"] == 0.12
    assert tuple(summarise(pd.DataFrame(rows)).columns) == SUMMARY_COLUMNS  # the report's column order


def test_the_report_orders_its_columns_the_same_for_a_summary_read_back_from_json(tmp_path) -> None:
    """verification.json stores the summary with sorted keys: read back, its rows give the same report."""
    row = {"direction_deg": 0.0, "system": "zv", "lead_residual_n": 0.5, "lead_residual_pct": 5.0,
           "shaper_s": 0.12, "least_tension_n": 3.0, "below_floor": 0, "tip_residual_mm": 1.0,
           "tip_residual_pct": 2.0}  # fmt: skip
    doc = {"rig": "r", "source": {"kind": "virtual-rig"}, "repetitions": 1, "directions_deg": [0.0],
           "bends_mm": [10.0], "summary": [row]}  # fmt: skip
    (fresh,) = write_report(doc, tmp_path / "fresh")
    (read,) = write_report({**doc, "summary": [dict(sorted(row.items()))]}, tmp_path / "read")
    assert read.read_text() == fresh.read_text()
    header = "| direction_deg | system | lead_residual_n | lead_residual_pct | shaper_s | least_tension_n | "
    assert header + "below_floor | tip_residual_mm | tip_residual_pct |" in read.read_text()


def test_tune_on_several_tendons_refuses_the_one_tendon_options(monkeypatch, tmp_path, capsys) -> None:
    rig_args = ["--rig", "four-tendon"]
    assert main(rig_args + ["tune", "--grid", "wide", "--data-dir", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--grid apply to a rig with one tendon" in err
    assert not any(tmp_path.iterdir())


def test_a_reduced_tune_names_its_directions_and_bends_and_refuses_bad_ones_in_one_line(tmp_path, capsys):
    """``--directions`` and ``--bends`` (several tendons): a list or a range; the default grid leaves out the
    directions no tendon faces; a direction no tendon faces, a bend <= 0 or these options on one tendon are
    refused in one line (exit 2) before any port opens."""
    from helpers.research.tune_tendons import grid

    four = rigfile.load(rigfile.resolve("four-tendon"))
    assert grid(four, "45", "10") == ((45.0,), (10.0,))
    assert grid(four, "0:360:90", None) == ((0.0, 90.0, 180.0, 270.0), (10.0, 20.0))
    two = rigfile.load(_two_tendon_rig(tmp_path))  # tendons at 0 and 90 deg: 180-270 face neither
    assert grid(two, None, None)[0] == (0.0, 45.0, 90.0, 135.0, 315.0)
    for argv, message in (
        (["--rig", "four-tendon", "tune", "--directions", "45,x"], "--directions: expected numbers like"),
        (["--rig", str(_two_tendon_rig(tmp_path)), "tune", "--directions", "200"],
         "--directions: no tendon faces 200 deg (tendons at 0, 90 deg)"),
        (["--rig", "four-tendon", "tune", "--bends", "0"], "--bends: every bend must be > 0 mm"),
        (["tune", "--directions", "45"], "--directions and --bends apply to a rig with several tendons"),
    ):  # fmt: skip
        assert main([*argv, "--data-dir", str(tmp_path / "data")]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and message in err, err
    assert not (tmp_path / "data").exists()


def _two_tendon_rig(folder: Path) -> Path:
    four = rigfile.load(rigfile.resolve("four-tendon"))
    text = four.text.replace("[[tendon]]\nangle_deg = 180.0\n\n[[tendon]]\nangle_deg = 270.0\n\n", "")
    path = folder / "two.toml"
    path.write_text(text.replace('name = "four-tendon"', 'name = "two-tendon"'))
    return path


@pytest.mark.slow
def test_a_short_tune_measures_the_map_and_zvd_leaves_less_than_unshaped(tmp_path) -> None:
    """Two directions between the two tendons, one bend, one repetition, on the virtual rig."""
    import itertools

    from helpers.research import tune_tendons as tt
    from helpers.rig import Rig
    from helpers.virtual.emulator.world import build_world, forget_world, register_world

    rig = rigfile.load(_two_tendon_rig(tmp_path))
    world = register_world(build_world(rig, "tune-tendons-test"))
    seeds = itertools.count(7)
    try:
        with Rig("virtual", rig, world="tune-tendons-test") as trig:
            doc = tt.tune_tendons(trig, tmp_path / "out", 1, directions=(0.0, 45.0), bends=(10.0,),
                                  seeds=lambda: next(seeds), reseed=world.reseed)  # fmt: skip
    finally:
        forget_world("tune-tendons-test")
    assert (tmp_path / "out" / "verification.json").exists()
    assert len(list((tmp_path / "out" / "verify").glob("*.csv"))) == 2 * len(tt.SYSTEMS)
    for p in doc["map"]:  # the measured mode beside the twin's prediction: within 2 %
        assert p["omega_d"] == pytest.approx(p["predicted_omega_d"], rel=0.02)
    s = pd.DataFrame(doc["summary"]).set_index(["direction_deg", "system"])
    for d in (0.0, 45.0):
        assert s.loc[(d, "zvd"), "lead_residual_n"] < 0.5 * s.loc[(d, "unshaped"), "lead_residual_n"]
        assert np.isfinite(s.loc[(d, "unshaped"), "tip_residual_mm"])


def test_the_hold_gives_the_frequency_and_damping_of_a_known_decay() -> None:
    """A tension that rings as exp(-zeta omega_n t) sin(omega_d t) in the hold: both come back (FFT peak
    within 0.5 %, the envelope's damping within 3 %), beside a harmonic at twice the frequency."""
    from types import SimpleNamespace

    from helpers.research.tune_tendons import identify_hold

    k = np.arange(0, 8000)
    t = k / 1000.0
    steps = np.clip((k - 1500) // 4, 0, 25) - np.clip((k - 4500) // 4, 0, 25)
    zeta, omega_n = 0.05, 25.0
    omega_d = omega_n * math.sqrt(1 - zeta**2)
    tau = np.clip(t - 1.6, 0, None)
    hold = (t > 1.6) & (t < 4.5)
    ring = np.where(hold, 1.5 * np.exp(-zeta * omega_n * tau) * np.sin(omega_d * tau), 0.0)
    harmonic = np.where(hold, 0.01 * np.sin(2 * omega_d * tau), 0.0)
    frame = pd.DataFrame({"t_s": t, "steps_0": steps, "tension_n_0": 3.0 + ring + harmonic})
    w, z = identify_hold(SimpleNamespace(frame=frame, path="synthetic"), 0, omega0=24.0)
    assert w == pytest.approx(omega_d, rel=0.005) and z == pytest.approx(zeta, rel=0.03)


def test_the_report_lists_every_direction_and_design_with_the_pre_pull(tmp_path) -> None:
    doc = {"rig": "r", "source": {"kind": "virtual-rig"}, "repetitions": 3, "directions_deg": [0.0, 90.0],
           "bends_mm": [10.0], "prepull_steps": 1, "prepull_check": ["pre-pull 1 step(s): fine"],
           "summary": [{"system": s, "direction_deg": d, "lead_residual_n": 0.5 + d / 1000, "below_floor": 0}
                       for d in (0.0, 90.0) for s in ("zv", "zvd")]}  # fmt: skip
    (md,) = write_report(doc, tmp_path / "out")
    text = md.read_text()
    assert "Every move pre-pulled 1 step(s)" in text and "- pre-pull 1 step(s): fine" in text
    assert "| direction_deg | system | lead_residual_n | below_floor |" in text
    assert "| 90.000 | zvd | 0.590 | 0 |" in text
    assert sorted((tmp_path / "out").iterdir()) == [md]


def test_the_higher_mode_design_is_the_fixed_zvd_and_a_zv_on_each_mode_of_the_map_at_the_move() -> None:
    """ZVD (last impulse 2 pi / omega_d at the reference) convolved with ZV at 60 + d / 10 and 80 + b rad/s,
    each pi / omega_d longer: the map's higher modes interpolated at the move as its dominant mode is."""
    pts = [dataclasses.replace(
        p, predicted_higher=((60 + p.direction_deg / 10, 0.03), (80 + p.bend_mm, 0.04))
    ) for p in _points()]  # fmt: skip
    w_ref = 20 + REFERENCE[0] / 10 + REFERENCE[1] / 10
    d = design_for("zvd-zv34", pts, 135.0, 15.0)
    w3, w4 = 60 + 13.5, 80 + 15.0
    assert d.omega_d == pytest.approx(w_ref)
    assert np.ravel(d.higher) == pytest.approx([w3, 0.03, w4, 0.04])
    assert d.shaper.times[-1] == pytest.approx(2 * math.pi / w_ref + math.pi / w3 + math.pi / w4)
    assert len(d.shaper) == 12 and sum(d.shaper.amplitudes) == pytest.approx(1.0)
    meta = d.metadata()
    assert [m["omega_d_rad_s"] for m in meta["higher_modes"]] == pytest.approx([w3, w4])
    assert "higher_modes" not in design_for("zvd", pts, 135.0, 15.0).metadata()
    with pytest.raises(ValueError, match="predicted_higher"):
        design_for("zvd-zv34", _points(), 135.0, 15.0)
