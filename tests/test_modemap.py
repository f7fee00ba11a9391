"""The measured frequency map: validation, interpolation, the band of a move, files and provenance."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from helpers.base.jsonfile import DataFileError, MissingDataError
from helpers.research.modemap import ModeMap, load_map, mode_at

POS = np.arange(0.0, 40.1, 5.0)
WD = np.array([25.1, 25.4, 26.3, 27.8, 30.0, 33.3, 37.7, 43.6, 51.5])
ZETA = np.array([0.044, 0.0437, 0.0428, 0.0413, 0.0393, 0.0369, 0.0342, 0.0316, 0.029])
SOURCE = {"kind": "hardware", "method": "free decays after 2 mm steps, 3 per position"}


def _map(**kw):
    args = dict(omega_d_se=0.01 * WD, zeta_se=np.full(POS.size, 0.002), source=SOURCE)
    args.update(kw)
    return ModeMap(POS, WD, ZETA, **args)


def _with_second(**kw):
    return _map(
        omega_d2=np.linspace(128.0, 72.0, POS.size),
        zeta2=np.full(POS.size, 0.03),
        share2=np.linspace(0.1, 0.3, POS.size),
        omega_d2_se=np.full(POS.size, 1.5),
        **kw,
    )


def test_the_map_returns_its_measurements_at_the_measured_positions():
    m = _with_second()
    p = m.at(POS)
    np.testing.assert_array_equal(p.omega_d, WD)
    np.testing.assert_array_equal(p.zeta, ZETA)
    np.testing.assert_allclose(p.omega_n, WD / np.sqrt(1 - ZETA**2), rtol=1e-15)
    assert mode_at(m, 20.0) == pytest.approx((30.0 / np.sqrt(1 - 0.0393**2), 0.0393), rel=1e-15)
    assert isinstance(m.at(12.5).omega_d, float)


def test_interpolation_is_monotone_between_measurements():
    # PCHIP never leaves the interval of its neighbours (a cubic spline overshoots near 35-40 mm)
    m = _map()
    x = np.linspace(0.0, 40.0, 801)
    w = m.at(x).omega_d
    assert np.all(np.diff(w) >= 0)
    k = np.clip(np.searchsorted(POS, x, side="right") - 1, 0, POS.size - 2)
    assert np.all(w >= WD[k] - 1e-12) and np.all(w <= WD[k + 1] + 1e-12)


def test_no_silent_extrapolation():
    m = _map()
    with pytest.raises(ValueError, match=r"x = 45 mm is outside the measured range 0-40 mm"):
        m.at(45.0)
    held = m.at(45.0, extrapolate=True)
    assert held.omega_d == WD[-1] and held.zeta == ZETA[-1]
    with pytest.raises(ValueError, match="leaves the measured range"):
        m.sweep(0.0, 41.0)
    assert m.sweep(30.0, 10.0) == (10.0, 30.0)


def test_positions_of_a_band():
    m = _map()
    np.testing.assert_array_equal(m.positions_in(0.0, 12.0), [0.0, 5.0, 10.0, 12.0])
    np.testing.assert_allclose(m.positions_in(0.0, 10.0, 1), [0.0, 2.5, 5.0, 7.5, 10.0])


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"positions_mm": [0.0, 5.0, 5.0, *POS[3:]]}, "positions_mm must increase strictly"),
        ({"omega_d": [*WD[:3], -1.0, *WD[4:]]}, r"omega_d\[3\] = -1.0 is outside"),
        ({"zeta": [*ZETA[:2], 1.0, *ZETA[3:]]}, r"zeta\[2\] = 1.0 is outside \[0, 1\)"),
        ({"zeta_se": [-0.1] * POS.size}, r"zeta_se\[0\] = -0.1"),
        ({"omega_d": WD[:4]}, "omega_d has 4 values, positions_mm has 9"),
        ({"omega_d": [np.nan, *WD[1:]]}, r"omega_d\[0\] = nan is not a finite number"),
        ({"omega_d2": WD * 4}, "needs omega_d2, zeta2 and share2 together"),
        ({"source": {"kind": "simulation", "method": "x"}}, "source.kind must be one of virtual-rig"),
        ({"source": {"kind": "hardware"}}, "source.method must say how"),
    ],
)
def test_bad_maps_are_refused_in_one_line(change, message):
    args = {"positions_mm": POS, "omega_d": WD, "zeta": ZETA, "source": SOURCE}
    args.update(change)
    with pytest.raises(ValueError, match=message) as info:
        ModeMap(**args)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("suffix", [".json", ".csv"])
@pytest.mark.parametrize("second", [False, True])
def test_files_round_trip_exactly_with_their_provenance(tmp_path, suffix, second):
    m = _with_second() if second else _map()
    path = m.save(tmp_path / f"map{suffix}")
    back = load_map(path)
    assert back == m
    assert back.source["kind"] == "hardware" and back.source["method"] == SOURCE["method"]
    for name in ("positions_mm", "omega_d", "zeta", "omega_d_se", "zeta_se", "omega_d2", "share2"):
        a, b = getattr(m, name), getattr(back, name)
        assert (a is None and b is None) or np.array_equal(a, b)  # bit for bit


def test_csv_carries_the_provenance_in_every_row(tmp_path):
    path = _map().save(tmp_path / "map.csv")
    table = pd.read_csv(path)
    assert list(table.columns[:3]) == ["source", "method", "position_mm"]
    assert set(table["source"]) == {"hardware"} and set(table["method"]) == {SOURCE["method"]}


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d.update(version=2), "version"),
        (lambda d: d["columns"].pop("zeta"), "columns.zeta: missing"),
        (lambda d: d["columns"].update(omega_d_rad_s=["fast"] * 9), "columns.omega_d_rad_s"),
        (lambda d: d["columns"].update(speed=[1.0] * 9), "unknown column 'speed'"),
        (lambda d: d["source"].update(kind="guess"), "source.kind"),
    ],
)
def test_malformed_map_files_name_the_field(tmp_path, edit, field):
    path = tmp_path / "map.json"
    doc = _map().to_dict()
    edit(doc)
    path.write_text(json.dumps(doc))
    with pytest.raises(DataFileError, match=field) as info:
        load_map(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_a_missing_map_says_so(tmp_path):
    with pytest.raises(MissingDataError, match="no mode map yet"):
        load_map(tmp_path / "nothing.csv")


def test_csv_with_mixed_provenance_is_refused(tmp_path):
    path = _map().save(tmp_path / "map.csv")
    lines = path.read_text().splitlines()
    lines[3] = lines[3].replace("hardware", "virtual-rig", 1)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataFileError, match="line 4: source/method differ"):
        load_map(path)


@pytest.mark.parametrize(
    "columns",
    [
        # helpers.virtual.statics.frequency_map as it is ...
        {"u_mm": POS, "tension_n": POS, "omega_n": WD, "zeta": ZETA, "omega_d": WD, "period_s": 1 / WD},
        # ... and as announced by the physics rewrite (a lowest and a second bending mode)
        {"u_mm": POS, "static_tension_n": POS, "omega_n_rad_s": WD, "omega_d_rad_s": WD, "zeta": ZETA,
         "omega_d2_rad_s": 3 * WD, "zeta2": ZETA / 2, "dominant_omega_d_rad_s": WD},
    ],
)  # fmt: skip
def test_a_map_from_the_virtual_rigs_predicted_table(columns):
    table = pd.DataFrame(columns)
    source = {"kind": "virtual-rig", "method": "predicted: linearised about the equilibria"}
    m = ModeMap.from_table(table, source, positions_mm=[0.0, 10.0, 20.0, 30.0])
    np.testing.assert_array_equal(m.positions_mm, [0, 10, 20, 30])
    np.testing.assert_array_equal(m.omega_d, WD[[0, 2, 4, 6]])
    np.testing.assert_array_equal(m.omega_d_se, 0.0)
    assert not m.has_second_mode  # no share given: the second mode is left out
    if "omega_d2_rad_s" in columns:
        m2 = ModeMap.from_table(table, source, share2=0.2)
        np.testing.assert_array_equal(m2.omega_d2, 3 * WD)
        np.testing.assert_array_equal(m2.share2, 0.2)
    else:
        with pytest.raises(ValueError, match="no second mode"):
            ModeMap.from_table(table, source, share2=0.2)
    with pytest.raises(ValueError, match="position 7 mm is not in the table"):
        ModeMap.from_table(table, source, positions_mm=[7.0])


@pytest.mark.slow
def test_the_virtual_rigs_predicted_map_makes_a_map_and_designs():
    """On the real predicted table (several seconds: the virtual rig compiles and linearises)."""
    from helpers.board.programmes import experiment_programme
    from helpers.research.design import map_following, scheduled_pair
    from helpers.virtual.parameters import RigParameters
    from helpers.virtual.statics import frequency_map

    table = frequency_map(RigParameters(), np.arange(0.0, 40.1, 5.0))
    m = ModeMap.from_table(table, {"kind": "virtual-rig", "method": "predicted by frequency_map"})
    np.testing.assert_array_equal(m.positions_mm, np.arange(0.0, 40.1, 5.0))
    column = "omega_d_rad_s" if "omega_d_rad_s" in table.columns else "omega_d"
    np.testing.assert_array_equal(m.at(m.positions_mm).omega_d, table[column].to_numpy())
    assert m.omega_d[0] < m.omega_d[4] < m.omega_d[6]  # the arm stiffens as it bends
    for design in (scheduled_pair(m, 30.0, "ZVD"), map_following(m, 30.0, 200.0, "ZVD")):
        programme, _ = experiment_programme(200.0, 30.0, design)
        assert programme.net_steps == 0
