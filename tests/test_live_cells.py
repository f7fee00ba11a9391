"""The notebooks' live cells on the one driver (``helpers.rig.Rig``): a pulse over the virtual rig records its
programme and the rig's metadata, the notebooks' live cells run end to end, and a failing board, a refused
request or a busy port is one clear error with the motor stopped and the ports closed. Paper-only: the
expected limits and rig hash are the paper's rig file's (the rig this session runs)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from crc_reference import link_hex, xor_hex
from rig_fakes import CALIBRATION, MM_PER_STEP, make_rig, make_world
from test_old_firmware import FakeBoard

from helpers import recordings, rigfile
from helpers.base.paths import REPO_ROOT, repo_path
from helpers.board.programmes import experiment_programme
from helpers.board.protocol import FW_VERSION
from helpers.paper import numbers as paper
from helpers.paper import scenarios
from helpers.paper.shapers import design_tdfs
from helpers.rig import BoardReset, BoardTimeout, OldFirmware, PortBusy, Rig, SafetyError, WrongRig
from helpers.rig.link import Link

PAPER = rigfile.load(REPO_ROOT / "rigs" / "paper.toml")


def _ports(world, daq: str = "", stepper: str = "") -> str:
    return f"virtual://daq?world={world.name}{daq},virtual://stepper?world={world.name}{stepper}"


def _live(world, daq: str = "", stepper: str = "") -> Rig:
    return Rig(_ports(world, daq, stepper), PAPER, calibration=CALIBRATION, timeout=0.5)


@pytest.mark.parametrize("shaped", [False, True], ids=["unshaped", "zvd"])
def test_a_pulse_records_its_programme_and_the_rigs_metadata(tmp_path, shaped):
    zvd = design_tdfs(paper.OMEGA_D, paper.ZETA)[1] if shaped else None
    system = "zvd" if shaped else None
    with _live(make_world()) as rig:
        rec = rig.run_pulse(200, 20, zvd, system, path=tmp_path / "live" / "p", repetition=2, progress=False)
    again, _ = make_rig()
    with again:  # the same request through the rig of the commands' tests: the same samples
        ref = again.run_pulse(200, 20, zvd, system=system, path=tmp_path / "full" / "p", repetition=2,
                              progress=False)  # fmt: skip
    live = recordings.load(rec.path)
    meta = live.meta
    # the values that follow from the request and the rig file, computed here without the driver
    programme, _ = experiment_programme(200.0, 20.0, zvd, t_up=1.0, t_down=8.0, t_end=12.0)
    assert meta["scenario"]["programme"] == programme.to_dict()
    assert (meta["scenario"]["v_in_mm_s"], meta["scenario"]["x_f_mm"], meta["scenario"]["repetition"]) == (
        200.0, 20.0, 2,
    )  # fmt: skip
    assert meta["scenario"]["system"] == ("zvd" if shaped else "unshaped")
    assert meta["rig"]["hash"] == rigfile.load(REPO_ROOT / "rigs" / "paper.toml").hash
    assert meta["firmware"]["daq"].startswith(FW_VERSION + "+") and meta["status"] == "complete"
    assert meta["source"]["kind"] == "virtual-rig" and meta["calibration"]["origin"] == ["test double"]
    # a deterministic world: the same samples as the full rig's, and the whole programme in them
    assert live.frame[["t_us", "adc", "steps"]].equals(
        recordings.load(ref.path).frame[["t_us", "adc", "steps"]]
    )
    assert live.frame["steps"].max() == round(20.0 / MM_PER_STEP) and live.frame["steps"].iloc[-1] == 0
    assert meta["counts"] == {"samples": len(live.frame), "dropped": 0, "corrupted": 0, "overruns": 0,
                              "implausible": 0}  # fmt: skip


def test_a_second_run_to_the_same_name_is_refused_before_anything_moves(tmp_path):
    world = make_world()
    with _live(world) as rig:
        rig.run_pulse(100, 10, path=tmp_path / "g" / "p", progress=False)
        sent = len(world.stepper.received)
        with pytest.raises(recordings.RecordingExists):
            rig.run_pulse(100, 10, path=tmp_path / "g" / "p", progress=False)
        assert len(world.stepper.received) == sent


@pytest.mark.parametrize(
    "v, x, message",
    [(500, 10, "exceeds the limit of 400 mm/s"), (100, 45, "travel limit"), (float("nan"), 10, "finite")],
)
def test_an_out_of_range_motion_is_refused_before_any_byte_is_sent(tmp_path, v, x, message):
    world = make_world()
    with _live(world) as rig:
        daq, stepper = len(world.daq.received), len(world.stepper.received)
        with pytest.raises(SafetyError, match=message) as info:
            rig.run_pulse(v, x, path=tmp_path / "p", progress=False)
    assert "\n" not in str(info.value)
    assert (len(world.daq.received), len(world.stepper.received)) == (daq, stepper)
    assert not list(tmp_path.iterdir())


CASES = [
    ("daq", "reset_at", BoardReset, "daq board reset"),
    ("daq", "hang_at", BoardTimeout, "daq board sent no sample"),
    ("stepper", "reset_at", BoardReset, "stepper board reset"),
    ("stepper", "hang_at", BoardTimeout, "stepper board did not answer 'POS'"),  # asked when DONE is late
]


@pytest.mark.parametrize("board, fault, error, message", CASES)
def test_a_board_that_resets_or_stops_answering_mid_run_stops_the_motor(
    tmp_path, board, fault, error, message
):
    world = make_world()
    option = f"&{fault}=3.0"  # device s after the ports open: during the hold (after the 0.5 s rest)
    rig = _live(world, **({"daq": option} if board == "daq" else {"stepper": option}))
    with rig, pytest.raises(error, match=message) as info:
        rig.run_pulse(100, 10, path=tmp_path / "p", progress=False)
    assert "\n" not in str(info.value)
    assert not rig.daq.port.is_open and not rig.stepper.port.is_open  # closed by the with block
    assert not world.stepper.running
    if not (board == "stepper" and fault == "hang_at"):
        assert world.stepper.received[-2:] == ["ABORT", "EN 0"] and not world.stepper.enabled
    saved = recordings.load(info.value.saved_path)  # what was recorded, as aborted, beside the name asked for
    assert saved.status == "aborted" and error.__name__ in saved.meta["abort_reason"]
    assert not (tmp_path / "p.csv").exists() and info.value.saved_path.name.startswith("p_aborted_")
    assert len(saved.frame) == saved.meta["counts"]["samples"] > 1000  # 0.5 s of lead-in and more
    if board == "daq":  # nothing after the fault (3 s after opening, as the world's clock counts)
        assert saved.frame["t_us"].iloc[-1] <= 3.0e6 + world.t0_us


def test_an_interrupt_mid_run_saves_what_was_recorded_and_disables_the_motor(tmp_path):
    world = make_world()

    def interrupt(w):
        if w.t > 3.0:
            w.listeners.clear()
            raise KeyboardInterrupt

    with _live(world) as rig:
        world.listeners.append(interrupt)
        with pytest.raises(KeyboardInterrupt) as info:
            rig.run_pulse(100, 10, path=tmp_path / "p", progress=False)
    assert world.stepper.received[-2:] == ["ABORT", "EN 0"] and not world.stepper.enabled
    assert recordings.load(info.value.saved_path).status == "aborted"


def test_a_second_open_of_the_same_port_is_refused(tmp_path):
    world = make_world()
    with _live(world) as first:
        with pytest.raises(PortBusy, match="port busy: the daq board"):
            _live(world)
        first.run_pulse(100, 10, path=tmp_path / "p", progress=False)  # the first is undisturbed
    with _live(world):  # and once it is closed, the port opens again
        pass


@pytest.mark.parametrize("hello", [False, True])
def test_a_board_of_another_protocol_or_rig_is_refused_when_it_is_synchronised(hello):
    with pytest.raises(OldFirmware, match=r"firmware 1\.x .*XOR.*flash firmware 2\.x"):
        Link(FakeBoard("daq", "1.0.0", xor_hex, hello=hello), "daq", PAPER, timeout=0.5).sync()
    with pytest.raises(WrongRig, match=r"built for rig deadbeef, but this host runs rig 'paper'"):
        Link(FakeBoard("stepper", "2.3.0+deadbeef", link_hex, hello), "stepper", PAPER, timeout=0.5).sync()
    paper_rig = f"2.3.0+{PAPER.hash}"
    assert Link(FakeBoard("daq", paper_rig, link_hex, hello), "daq", PAPER, timeout=0.5).sync() == paper_rig
    no_hash = Link(FakeBoard("daq", "2.0.0", link_hex), "daq", PAPER, timeout=0.5)  # 2.0: the paper's rig
    assert no_hash.sync() == "2.0.0"


def test_ports_other_than_virtual_auto_or_a_pair_are_one_clear_error():
    with pytest.raises(ValueError, match=r"'virtual', 'auto' or two ports 'DAQ,STEPPER', got 'nowhere'"):
        Rig("nowhere", PAPER, calibration=CALIBRATION)
    with pytest.raises(ValueError, match="rig must be a rig file"):
        Rig("virtual", "paper", calibration=CALIBRATION)


def _cell(notebook: str, start: str) -> str:
    cells = json.loads((REPO_ROOT / "notebooks" / notebook).read_text())["cells"]
    (source,) = [
        "".join(c["source"]) for c in cells if c["cell_type"] == "code" and start in "".join(c["source"])
    ]
    assert source.startswith("# NBVAL_SKIP\nif LIVE:")
    return source


def test_notebook_02s_live_cell_records_the_identification_run(tmp_path):
    world = make_world()
    identified, calibrations, saved = [], [], []
    namespace = {
        "LIVE": True, "PORTS": _ports(world), "RIG_FILE": PAPER, "V_IN_MM_S": 100, "X_F_MM": 10,
        "WINDOW_S": (9.0, 10.0), "DATA": tmp_path,
        "RECORDING": tmp_path / "identification" / "pulse_v100_x10", "repo_path": repo_path,
        "load_calibration": lambda path: calibrations.append(path) or CALIBRATION,
        "identify_recording": lambda rec, window, column: identified.append(rec) or rec.path,
        "save_identification": lambda result, path: saved.append((result, path)) or path,
    }  # fmt: skip
    exec(_cell("02_pulse_identification.ipynb", "run_pulse"), namespace)  # noqa: S102
    (rec,) = identified
    assert recordings.load(tmp_path / "identification" / "pulse_v100_x10.csv").status == "complete"
    assert rec.meta["scenario"]["v_in_mm_s"] == 100 and rec.frame["steps"].max() == round(10 / MM_PER_STEP)
    # the calibration and the result in the notebook's data folder (my_data/<rig>/ when LIVE), not in data/
    assert calibrations == [tmp_path / "calibration" / "calibration.json"]
    assert saved == [(rec.path, tmp_path / "identification" / "result.json")]
    assert rec.meta["calibration"]["origin"] == ["test double"]


def test_notebook_04s_live_cell_records_every_system_of_a_condition(tmp_path, monkeypatch, capsys):
    world = make_world()
    monkeypatch.setattr(scenarios, "table_i_conditions", lambda rig: ((200.0, 10.0),))  # one of four
    zv, zvd = design_tdfs(paper.OMEGA_D, paper.ZETA)
    calibrations = []
    namespace = {
        "LIVE": True, "PORTS": _ports(world), "RIG_FILE": PAPER, "REPETITIONS": 1,
        "DATA": tmp_path, "GROUP": tmp_path / "experiments", "repo_path": repo_path,
        "load_calibration": lambda path: calibrations.append(path) or CALIBRATION,
        "paper": paper, "shapers": {"unshaped": None, "zv": zv, "zvd": zvd},
        "zeta": paper.ZETA, "omega_d": paper.OMEGA_D,
    }  # fmt: skip
    exec(_cell("04_experiments.ipynb", "run_pulse"), namespace)  # noqa: S102
    names = sorted(p.name for p in (tmp_path / "experiments").glob("*.csv"))
    assert names == ["unshaped_v200_x10_r1.csv", "zv_v200_x10_r1.csv", "zvd_v200_x10_r1.csv"]
    rec = recordings.load(tmp_path / "experiments" / "zvd_v200_x10_r1.csv")
    assert rec.meta["scenario"]["design"] == {"zeta": paper.ZETA, "omega_d": paper.OMEGA_D}
    assert rec.meta["scenario"]["system"] == "zvd" and rec.meta["scenario"]["repetition"] == 1
    assert np.allclose(rec.meta["scenario"]["shaper"]["amplitudes"], zvd.amplitudes)
    assert calibrations == [tmp_path / "calibration" / "calibration.json"]  # the data folder's, not data/'s
    assert f"3 recordings written under {tmp_path / 'experiments'}" in capsys.readouterr().out
