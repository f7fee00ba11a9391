"""Shaper designs from a mode map, checked against closed forms computed here (not by the code under test)."""

from __future__ import annotations

import cmath
import json
import math

import numpy as np
import pytest
from scipy.integrate import quad

from helpers.base.jsonfile import DataFileError
from helpers.paper.shapers import Shaper
from helpers.research.design import (
    Design,
    MoveSchedule,
    Schedule,
    ShaperPair,
    SubMove,
    auto_choice,
    band_centred,
    load_design,
    map_following,
    minimax,
    multi_mode_design,
    save_design,
    scheduled_pair,
    time_varying_residual,
)
from helpers.research.families import FAMILIES
from helpers.research.modemap import ModeMap

SOURCE = {"kind": "virtual-rig", "method": "test map"}
POS = np.arange(0.0, 40.1, 5.0)
WD = np.array([25.1, 25.4, 26.3, 27.8, 30.0, 33.3, 37.7, 43.6, 51.5])


def v_closed(amps, times, omega_n, zeta):
    """Singer and Seering's residual, written out: exp(-s t_N) |sum A_i exp((s + i w_d) t_i)|."""
    s, wd = zeta * omega_n, omega_n * math.sqrt(1 - zeta**2)
    total = sum(a * cmath.exp(complex(s, wd) * t) for a, t in zip(amps, times, strict=True))
    return abs(total) * math.exp(-s * times[-1])


def zv_closed(omega_d, zeta):
    k = math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2))
    return [1 / (1 + k), k / (1 + k)], [0.0, math.pi / omega_d]


def zvd_closed(omega_d, zeta):
    k = math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2))
    t = math.pi / omega_d
    return [1 / (1 + k) ** 2, 2 * k / (1 + k) ** 2, k * k / (1 + k) ** 2], [0.0, t, 2 * t]


def varying_map(zeta=0.04, se=0.0):
    return ModeMap(POS, WD, np.full(POS.size, zeta), omega_d_se=se * WD, source=SOURCE)


# -- scheduled and map-following -------------------------------------------------------------------
@pytest.mark.parametrize(("name", "closed"), [("ZV", zv_closed), ("ZVD", zvd_closed)])
def test_on_a_constant_map_the_scheduled_pair_is_the_classical_shaper(name, closed):
    m = ModeMap.constant(27.0, 0.05)
    d = scheduled_pair(m, 20.0, name)
    amps, times = closed(27.0, 0.05)
    assert d.system == "scheduled" and isinstance(d.shaping, ShaperPair)
    for s in (d.shaping.up, d.shaping.down):
        np.testing.assert_allclose(s.amplitudes, amps, rtol=1e-12)
        np.testing.assert_allclose(s.times, times, rtol=1e-12)


def test_the_scheduled_pair_uses_the_destination_up_and_the_rest_down():
    d = scheduled_pair(varying_map(), 30.0, "ZV")
    np.testing.assert_allclose(d.shaping.up.times, [0, math.pi / 37.7], rtol=1e-12)  # 30 mm
    np.testing.assert_allclose(d.shaping.down.times, [0, math.pi / 25.1], rtol=1e-12)  # rest


@pytest.mark.parametrize(("name", "closed"), [("ZV", zv_closed), ("ZVD", zvd_closed)])
def test_on_a_constant_map_the_map_following_schedule_is_the_convolution(name, closed):
    m = ModeMap.constant(27.0, 0.05)
    d = map_following(m, 20.0, 200.0, name)
    amps, times = closed(27.0, 0.05)
    assert d.system == "map-following" and isinstance(d.shaping, Schedule)
    for move in (d.shaping.up, d.shaping.down):
        subs = move.sub_moves
        np.testing.assert_allclose([s.amplitude for s in subs], amps, rtol=1e-12)
        np.testing.assert_allclose([s.start_s for s in subs], times, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose([s.duration_s for s in subs], 20.0 / 200.0, rtol=1e-11)


def _position(move: MoveSchedule, v, x0, direction, t):
    done = sum(s.amplitude * min(max(t - s.start_s, 0.0), s.duration_s) for s in move.sub_moves)
    return x0 + direction * v * done


@pytest.mark.parametrize(("v", "x_f"), [(200.0, 30.0), (50.0, 30.0)])
def test_map_following_spaces_starts_and_stops_by_the_phase_the_mode_turns(v, x_f):
    """The rule itself, checked by quadrature of omega_d along the commanded position."""
    m = varying_map()
    d = map_following(m, x_f, v, "ZVD")
    for move, x0, direction in ((d.shaping.up, 0.0, 1), (d.shaping.down, x_f, -1)):
        assert v * move.mean_duration_s == pytest.approx(x_f, rel=1e-12)

        def omega(t, move=move, x0=x0, direction=direction):
            return float(m.at(_position(move, v, x0, direction, t)).omega_d)

        for edges in ([s.start_s for s in move.sub_moves], [s.end_s for s in move.sub_moves]):
            for a, b in zip(edges, edges[1:], strict=False):
                phase = quad(omega, a, b, epsabs=1e-12, epsrel=1e-12, limit=200)[0]
                assert phase == pytest.approx(math.pi, abs=1e-7)


def test_map_following_beats_the_scheduled_pair_on_the_time_varying_model():
    m = varying_map()
    for v, x in ((200.0, 30.0), (300.0, 20.0)):
        following = time_varying_residual(map_following(m, x, v, "ZV"), m, x, v)
        scheduled = time_varying_residual(scheduled_pair(m, x, "ZV"), m, x, v)
        assert following["up"] < scheduled["up"] / 3 and following["down"] < scheduled["down"] / 2


def test_the_time_varying_residual_of_a_constant_map_is_the_shapers_v():
    amps, times = zv_closed(25.0, 0.044)
    shaper = Shaper(np.array(amps), np.array(times), "zv")
    omega_n = 30.0 / math.sqrt(1 - 0.044**2)
    r = time_varying_residual(shaper, ModeMap.constant(30.0, 0.044), 20.0, 200.0)
    assert r["up"] == pytest.approx(v_closed(amps, times, omega_n, 0.044), rel=1e-7)
    assert r["down"] == pytest.approx(r["up"], rel=1e-7)


def test_map_following_refuses_negative_impulses_and_another_move():
    m = varying_map()
    with pytest.raises(ValueError, match="positive impulses"):
        map_following(m, 20.0, 200.0, "UM-ZV")
    d = map_following(m, 20.0, 200.0, "ZV")
    with pytest.raises(ValueError, match="computed for 20 mm at 200 mm/s, not 20 mm at 300 mm/s"):
        d.shaping.check_move(300.0, 20.0)


# -- multi-mode, band-centred, minimax -------------------------------------------------------------
def test_multi_mode_v_is_the_product_of_the_single_mode_v():
    m = ModeMap.constant(25.0, 0.04, second=(90.0, 0.02, 0.2))
    d = multi_mode_design(m, 20.0, "ZVD", "ZV", coverage=0.0)
    a1, t1 = zvd_closed(25.0, 0.04)
    a2, t2 = zv_closed(90.0, 0.02)
    s = d.shaping
    for omega_n in (20.0, 25.0 / math.sqrt(1 - 0.04**2), 47.0, 90.0, 130.0):
        product = v_closed(a1, t1, omega_n, 0.03) * v_closed(a2, t2, omega_n, 0.03)
        assert v_closed(s.amplitudes, s.times, omega_n, 0.03) == pytest.approx(product, rel=1e-9, abs=1e-14)
    assert v_closed(s.amplitudes, s.times, 90.0 / math.sqrt(1 - 0.02**2), 0.02) < 1e-12
    assert d.provenance["predicted_worst_pct"] < 1e-9


def test_multi_mode_scheduled_designs_each_move_at_its_configuration():
    n = POS.size
    m = ModeMap(POS, WD, np.full(n, 0.04), omega_d2=3 * WD, zeta2=np.full(n, 0.02), share2=np.full(n, 0.2),
                source=SOURCE)  # fmt: skip
    d = multi_mode_design(m, 30.0, "ZV", "ZV", placement="scheduled")
    # ZV * ZV: impulses at 0, pi/w2, pi/w1, pi/w1 + pi/w2 with the modes at 30 mm (up) and at rest (down)
    for shaper, w in ((d.shaping.up, 37.7), (d.shaping.down, 25.1)):
        np.testing.assert_allclose(shaper.times, [0, math.pi / (3 * w), math.pi / w, math.pi / w * 4 / 3])
    with pytest.raises(ValueError, match="placement must be"):
        multi_mode_design(m, 30.0, placement="middle")
    with pytest.raises(ValueError, match="needs a mode map with a second mode"):
        multi_mode_design(varying_map(), 30.0)


def test_ei_is_centred_on_the_band():
    m = ModeMap(POS, WD, np.full(POS.size, 0.04), source=SOURCE)
    d = band_centred(m, 30.0, "EI", coverage=0.0)
    lo, hi = 25.1 / math.sqrt(1 - 0.04**2), 37.7 / math.sqrt(1 - 0.04**2)  # the map rises monotonically
    assert d.system == "ei"
    # EI lasts one undamped period of its design frequency
    assert d.shaping.duration == pytest.approx(2 * math.pi / (0.5 * (lo + hi)), rel=1e-12)


def _worst_over(shaper, m, x_f, n=301):
    p = m.at(np.linspace(0.0, x_f, n))
    modes = zip(p.omega_n, p.zeta, strict=True)
    return max(v_closed(shaper.amplitudes, shaper.times, wn, z) for wn, z in modes)


def test_minimax_on_a_single_point_cancels_it():
    m = ModeMap.constant(25.0, 0.044)
    d = minimax(m, 10.0, 0.2, coverage=0.0)
    s = d.shaping
    assert d.system == "minimax" and s.duration <= 0.2 + 1e-12
    assert np.all(s.amplitudes >= 0) and s.amplitudes.sum() == pytest.approx(1.0, abs=1e-12)
    assert v_closed(s.amplitudes, s.times, 25.0 / math.sqrt(1 - 0.044**2), 0.044) < 1e-6


@pytest.mark.slow  # 4 s of optimisation
def test_minimax_beats_zvd_over_a_wide_band_at_the_same_duration():
    m = varying_map(zeta=0.04)
    wn_lo, wn_hi = 25.1 / math.sqrt(1 - 0.04**2), 37.7 / math.sqrt(1 - 0.04**2)
    wd_c = 0.5 * (wn_lo + wn_hi) * math.sqrt(1 - 0.04**2)
    amps, times = zvd_closed(wd_c, 0.04)
    zvd = Shaper(np.array(amps), np.array(times), "ZVD")
    d = minimax(m, 30.0, zvd.duration, coverage=0.0)
    assert d.shaping.duration <= zvd.duration + 1e-12
    ours, theirs = _worst_over(d.shaping, m, 30.0), _worst_over(zvd, m, 30.0)
    assert theirs > 0.05  # ZVD does not cover 25-38 rad/s ...
    assert ours < 0.7 * theirs  # ... the minimax design, as long, does much better


# -- the automatic choice --------------------------------------------------------------------------
def test_auto_picks_zv_when_the_map_is_one_point():
    m = ModeMap.constant(25.0, 0.044)
    choice = auto_choice(m, 10.0, coverage=0.0, include_minimax=False)
    assert choice.design is not None and choice.design.system == "auto"
    assert choice.design.shaping.duration == pytest.approx(math.pi / 25.0, rel=1e-12)
    assert "ZV centred" in choice.message


def test_auto_picks_the_shortest_family_within_the_tolerance():
    m = varying_map(zeta=0.04)
    tol = 5.0
    positions = m.positions_in(0.0, 20.0, 2)  # the band's points (default n_between)
    p = m.at(positions)
    wn = p.omega_n
    centre = 0.5 * (wn.min() + wn.max())
    expected = []
    for name in ("ZV", "MZV", "ZVD", "EI", "ZVDD", "2-hump EI", "3-hump EI"):
        s = FAMILIES[name](centre, 0.04)
        worst = max(v_closed(s.amplitudes, s.times, w, 0.04) for w in wn)
        if 100 * worst <= tol:
            expected.append((s.duration, name))
    assert expected, "the test map must leave some family within the tolerance"
    choice = auto_choice(m, 20.0, tolerance_pct=tol, coverage=0.0, include_minimax=False)
    assert choice.design.shaping.duration == pytest.approx(min(expected)[0], rel=1e-12)
    assert choice.design.provenance["chosen"] == f"{min(expected)[1]} centred"


def test_auto_says_when_nothing_qualifies():
    m = varying_map(zeta=0.04, se=0.02)
    choice = auto_choice(m, 30.0, tolerance_pct=0.01, include_minimax=False)
    assert choice.design is None
    assert choice.message.startswith("no candidate keeps the predicted residual within 0.01 % over 0-30 mm")
    with pytest.raises(ValueError, match="no candidate"):
        choice.require()
    capped = auto_choice(ModeMap.constant(25.0, 0.044), 10.0, max_duration_s=0.05, include_minimax=False)
    assert capped.design is None and "within 0.05 s" in capped.message


# -- the design file -------------------------------------------------------------------------------
def _designs():
    m = varying_map()
    return [
        Design("zvd", Shaper(np.array([0.25, 0.5, 0.25]), np.array([0.0, 0.1, 0.2]), "zvd"), {"note": "x"}),
        scheduled_pair(m, 20.0, "ZVD"),
        map_following(m, 20.0, 200.0, "ZVD"),
    ]


@pytest.mark.parametrize("index", [0, 1, 2], ids=["shaper", "pair", "schedule"])
def test_designs_round_trip_exactly(tmp_path, index):
    design = _designs()[index]
    back = load_design(save_design(design, tmp_path / "d.json"))
    assert back.to_dict() == design.to_dict()
    assert back.system == design.system and back.kind == design.kind
    if design.kind == "schedule":
        for a, b in ((design.shaping.up, back.shaping.up), (design.shaping.down, back.shaping.down)):
            assert a == b  # every float bit for bit
    else:
        for a, b in ((design.up_shaper, back.up_shaper), (design.down_shaper, back.down_shaper)):
            assert np.array_equal(a.amplitudes, b.amplitudes) and np.array_equal(a.times, b.times)
            assert a.name == b.name


def test_a_bare_shaper_saves_as_custom_or_keeps_its_paper_name(tmp_path):
    s = FAMILIES["ZVDD"](25.0, 0.04)
    assert load_design(save_design(s, tmp_path / "a.json")).system == "custom"
    zv = Shaper(s.amplitudes, s.times, "zv")
    assert load_design(save_design(zv, tmp_path / "b.json")).system == "zv"


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d.update(version=7), "version: unknown 7"),
        (lambda d: d.update(format="something"), "format"),
        (lambda d: d.pop("kind"), "kind"),
        (lambda d: d.update(system="unshaped"), "system"),
        (lambda d: d.update(colour="red"), "colour: unknown key"),
        (lambda d: d.update(kind="pair"), "up: missing"),
        (lambda d: d["shaper"].update(amplitudes=[0.5, 0.6, 0.25]), "shaper: .*sum to 1"),
        (lambda d: d["shaper"].update(times=[0.0, "0.1", 0.2]), "shaper.times"),
        (lambda d: d["shaper"].pop("times"), "shaper.times: missing"),
    ],
)
def test_malformed_shaper_files_name_the_field(tmp_path, edit, field):
    _assert_refused(tmp_path, _designs()[0], edit, field)


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d["schedule"]["up"]["sub_moves"][1].update(duration_s=-1), r"sub_moves\[1\].*duration_s"),
        (lambda d: d["schedule"].update(x_f_mm=25.0), "its sub-moves move 20 mm"),
        (lambda d: d["schedule"].pop("v_in_mm_s"), "schedule.v_in_mm_s: missing"),
        (lambda d: d["schedule"]["down"].update(sub_moves=[]), "down.sub_moves: expected a non-empty list"),
    ],
)
def test_malformed_schedule_files_name_the_field(tmp_path, edit, field):
    _assert_refused(tmp_path, _designs()[2], edit, field)


def _assert_refused(tmp_path, design, edit, field):
    doc = design.to_dict()
    edit(doc)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(DataFileError, match=field) as info:
        load_design(path)
    assert str(info.value).startswith(str(path)) and "\n" not in str(info.value)


def test_schedule_types_check_their_parts():
    with pytest.raises(ValueError, match="amplitudes must sum to 1"):
        MoveSchedule((SubMove(0.5, 0.0, 0.1), SubMove(0.4, 0.1, 0.1)))
    with pytest.raises(ValueError, match="first sub-move must start at 0"):
        MoveSchedule((SubMove(1.0, 0.1, 0.1),))
    with pytest.raises(ValueError, match="design system must be one of"):
        Design("unshaped", Shaper.unit())
