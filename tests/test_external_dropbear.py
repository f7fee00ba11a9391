"""DROPBEAR Dataset-8 as recordings (helpers.research.dropbear) and its ring-downs (``ringdowns``).

The reference figures were measured independently of this code over all 11 repeats of the 10-step series
(a damped-sine fit to the low-g channel, band-passed 10-80 Hz, the 0.6 s after each stop): 26.20 Hz at PinLoc
1.23 V, 30.79 at 2.08, 33.88 at 2.51, 37.51 at 2.93, 41.85 at 3.35 V; up and down sweeps within 0.1 Hz;
median damping ratios 0.0013-0.0039 per position, a range of 0.0001-0.018. Nothing here compares the code with
numbers it computed itself.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from helpers.__main__ import main
from helpers.base.paths import DATA_DIR
from helpers.recordings import RecordingError
from helpers.research.dropbear import read_dropbear
from helpers.research.rest_ringdowns import COLUMNS, find_rests, identify_ringdowns

DROPBEAR = DATA_DIR / "external" / "dropbear"
STEPS = [DROPBEAR / "10steps_test0.txt", DROPBEAR / "10steps_test1.txt"]
RANDOM = DROPBEAR / "random_dwell_set0_test0.txt"
QUOTED_HZ = {1.23: 26.20, 2.08: 30.79, 2.51: 33.88, 2.93: 37.51, 3.35: 41.85}
"""The independent figures: PinLoc (V) -> first mode (Hz), means over the dataset's 11 repeats."""


def _nearest(position: float) -> float:
    return min(QUOTED_HZ, key=lambda p: abs(p - position))


@pytest.fixture(scope="module")
def ringdowns():
    return {p.name: identify_ringdowns(read_dropbear(p)) for p in [*STEPS, RANDOM]}


def test_a_trial_reads_as_a_recording_with_its_units_rate_and_provenance():
    rec = read_dropbear(STEPS[0])
    assert list(rec.frame.columns) == ["t_s", "low_g_accel_v", "accel_v", "pinloc_v"]
    assert len(rec.frame) == 70000 and rec.meta["rate_hz"] == 5000
    assert rec.frame["t_s"].iloc[-1] == pytest.approx(69999 / 5000)
    assert rec.frame["pinloc_v"].iloc[0] == pytest.approx(1.22559)  # the file's first row
    src = rec.meta["source"]
    assert src["kind"] == "external" and src["licence"] == "CC BY-SA 4.0" and src["file"] == STEPS[0].name
    assert src["sha256"] == hashlib.sha256(STEPS[0].read_bytes()).hexdigest()
    assert rec.meta["scenario"]["configuration"] == "pinloc_v"
    assert rec.meta["units"]["pinloc_v"] == "V" and rec.meta["units"]["t_s"] == "s"
    six = read_dropbear(RANDOM)
    six_columns = ["t_s", "low_g_accel_v", "sg_300_a_v", "sg_306_b_v", "accel_v", "pinloc_v"]
    assert list(six.frame.columns) == six_columns


def test_the_shipped_copies_are_the_datasets_files_with_their_licence():
    assert (DROPBEAR / "LICENSE.txt").read_bytes().startswith(b"Attribution-ShareAlike 4.0 International")
    readme = (DROPBEAR / "README.md").read_text()
    assert "CC BY-SA 4.0" in readme and "Vereen" in readme


@pytest.mark.parametrize("path", STEPS, ids=lambda p: p.stem)
def test_frequencies_agree_with_the_independent_figures_within_0_2_hz(ringdowns, path):
    table = ringdowns[path.name].table
    checked = set()
    for row in table.itertuples():
        nominal = _nearest(row.position)
        if abs(row.position - nominal) < 0.05:
            assert row.f_hz == pytest.approx(QUOTED_HZ[nominal], abs=0.2), (row.t_stop_s, row.position)
            checked.add(nominal)
    assert checked >= {2.08, 2.51, 2.93, 3.35, 1.23}


@pytest.mark.parametrize("path", STEPS, ids=lambda p: p.stem)
def test_every_stop_of_the_10_step_series_is_found_and_up_and_down_agree(ringdowns, path):
    table = ringdowns[path.name].table
    # ten moves, up to 3.35 V and back to 1.23 V (the roller creeps once at the top: an eleventh rest)
    assert 10 <= len(table) <= 11
    assert table["direction"].tolist()[:5] == ["up"] * 5 and table["direction"].iloc[-1] == "down"
    for nominal in (2.08, 2.51, 2.93):
        at = table[np.abs(table["position"] - nominal) < 0.05]
        assert set(at["direction"]) == {"up", "down"}
        assert np.ptp(at["f_hz"]) < 0.1


def test_damping_is_reported_as_poorly_determined(ringdowns):
    for result in ringdowns.values():
        tab = result.table
        # every interval is wider than the fit's own 95 % interval: the estimates disagree beyond it
        assert np.all(tab["zeta_hi"] - tab["zeta_lo"] > 2 * 1.96 * tab["zeta_se"])
        assert np.all((tab["zeta_lo"] <= tab["zeta"]) & (tab["zeta"] <= tab["zeta_hi"]))
        # and the reported damping lies in the range measured independently (0.0001-0.018)
        assert np.all((tab["zeta"] > 0.0001) & (tab["zeta"] < 0.018))
        assert any("poorly determined" in line for line in result.notes())


def test_the_random_dwell_trial_works_and_names_the_short_rests(ringdowns):
    result = ringdowns[RANDOM.name]
    assert len(result.table) >= 5
    assert np.all(result.table["rest_s"] >= 0.3) and np.all(result.table["window_s"] <= 0.6)
    short = result.skipped[result.skipped["reason"].str.startswith("shorter")]
    assert len(short) >= 5 and np.all(short["rest_s"] < 0.3)
    # its positions lie between the 10-step series' nominal ones: the quoted map, interpolated linearly
    xs, fs = np.array(list(QUOTED_HZ)), np.array(list(QUOTED_HZ.values()))
    inside = result.table[(result.table["position"] > 2.08) & (result.table["position"] < 3.35)]
    assert len(inside) >= 3
    assert np.all(np.abs(inside["f_hz"] - np.interp(inside["position"], xs, fs)) < 0.3)


def test_find_rests_on_a_synthetic_staircase():
    t = np.arange(0, 5.0, 1e-3)
    step = np.floor(t)
    x = np.clip(step + 4 * (t - step), step, step + 1.0)  # a 0.25 s ramp each second
    rests = find_rests(t, x, speed_threshold=0.5)
    assert [round(r.t_start_s, 1) for r in rests] == [0.3, 1.3, 2.3, 3.3, 4.3]  # the quiet start is no stop
    assert [round(r.position) for r in rests] == [1, 2, 3, 4, 5]
    assert all(r.direction == "up" for r in rests)


def test_the_command_prints_csv_and_notes(capsys):
    assert main(["ringdowns", str(STEPS[0]), "--format", "dropbear"]) == 0
    out, err = capsys.readouterr()
    lines = out.strip().splitlines()
    assert lines[0].split(",") == list(COLUMNS)
    assert lines[0].startswith("t_stop_s,position,") and "f_hz" in lines[0] and "zeta_lo" in lines[0]
    assert len(lines) - 1 >= 10
    assert "skipped" in err and "CC BY-SA 4.0" in err


def _trial(path, rows: np.ndarray, header_lines: int = 5) -> None:
    head = ["C:\\somewhere\\test0.txt", "Programmer - None", "Striker Velocity - 0.0",
            "Sampling Frequency - 5000", "Tue, Jul 19, 2022 10:55 PM"][:header_lines]  # fmt: skip
    text = "\n".join([*head, "Low G Accel\tAccel\tPinLoc\tTime", "Voltage (unscaled)\tVoltage (unscaled)\t"
                      "Voltage (unscaled)\tSec", "0.0 0.0 0\t\t0.0 0.0 0\t", ""])  # fmt: skip
    body = "\n".join("\t".join(f"{v:.5E}" for v in r) for r in rows)
    path.write_text(text + "\n" + body + "\n")


def _one_line_status_5(capsys, *argv: str) -> str:
    assert main(["ringdowns", *argv]) == 5
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_bad_input_is_one_line_naming_the_file_and_line_status_5(tmp_path, capsys):
    good = STEPS[0].read_text().splitlines()
    truncated = tmp_path / "truncated.txt"
    truncated.write_text("\n".join(good[:3000]) + "\n" + good[3000][:9])  # cut inside a row
    line = _one_line_status_5(capsys, str(truncated))
    assert "truncated.txt" in line and "line 3001" in line and "truncated" in line
    malformed = tmp_path / "malformed.txt"
    malformed.write_text("\n".join(good[:2000] + ["1.0\tabc\t1.2\t0.5"] + good[2001:4000]) + "\n")
    line = _one_line_status_5(capsys, str(malformed))
    assert "malformed.txt" in line and "line 2001" in line
    other = tmp_path / "not_a_trial.csv"
    other.write_text("seq,t_us,adc,steps\n0,0,512,0\n")
    assert "not a DROPBEAR trial" in _one_line_status_5(capsys, str(other))
    missing = tmp_path / "absent.txt"
    assert "absent.txt" in _one_line_status_5(capsys, str(missing))
    # a trial whose roller never rests 0.3 s: moves every 0.2 s
    t = np.arange(0, 3.0, 1 / 5000)
    pin = 1.2 + 0.4 * np.floor(t / 0.2) + 0.4 * np.clip((t % 0.2) / 0.08, 0, 1)
    y = 0.1 * np.sin(2 * np.pi * 30 * t)
    restless = tmp_path / "restless.txt"
    _trial(restless, np.column_stack([y, y, pin, t]))
    line = _one_line_status_5(capsys, str(restless))
    assert "restless.txt" in line and "no rest" in line and "0.3 s" in line


def test_missing_sampling_frequency_is_refused(tmp_path):
    t = np.arange(0, 0.1, 1 / 5000)
    path = tmp_path / "no_rate.txt"
    _trial(path, np.column_stack([t, t, t, t]), header_lines=3)
    with pytest.raises(RecordingError, match="Sampling Frequency"):
        read_dropbear(path)
