"""Sweeps on the virtual rig: definitions, a tiny sweep on a local Dask cluster, resumption, the CLI."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import xarray as xr

from helpers import __main__ as cli
from helpers.base.jsonfile import DataFileError
from helpers.base.paths import DATA_DIR, REPO_ROOT
from helpers.research.modemap import ModeMap
from helpers.research.sweep import execute as execute_module
from helpers.research.sweep.definition import SweepDefinition, load_definition
from helpers.research.sweep.execute import SweepInterrupted, local_client, run_sweep
from helpers.research.sweep.files import load_sweep
from helpers.research.sweep.store import same_physics

# short runs: a 5 mm pulse at 200 mm/s, up at 0.6 s, down at 2.0 s, 3.2 s long (the residual windows fit)
SHORT = {"t_end_s": 3.2, "t_up_s": 0.6, "t_down_s": 2.0}


def tiny(**kw) -> SweepDefinition:
    spec = {
        "name": "tiny",
        "shapers": ("unshaped", "zvd", "fixed"),
        "custom_shapers": {"fixed": {"amplitudes": [0.5, 0.5], "times": [0.0, 0.125]}},
        "grid": {"freq_error": [0.0, 0.2], "seed": [0, 1]},
        "fixed": {"amplitude_mm": 5.0},
        "chunk_runs": 2,
        "run": SHORT,
    }
    spec.update(kw)
    return SweepDefinition(**spec)


def test_definition_counts_runs_and_chunks():
    d = tiny(grid={"freq_error": [0.0, 0.1, 0.2], "seed": [3, 4]})
    # the seed shares one integration: 3 errors x 3 shapers runs, in chunks of 2
    assert d.run_dims == ("freq_error", "shaper")
    assert (d.n_runs, d.n_chunks) == (9, 5)
    assert list(d.chunk_range(4)) == [8]
    assert d.seeds == (3, 4)
    p = d.point(5)  # freq_error index 1, shaper index 2
    assert (p["freq_error"], p["shaper"], p["amplitude_mm"], p["speed_mm_s"]) == (0.1, "fixed", 5.0, 200.0)


def test_sample_is_reproducible_and_in_range():
    sample = {"n": 50, "seed": 7, "distributions": {"amplitude_mm": {"uniform": [10, 30]},
                                                    "freq_error": {"normal": [0.0, 0.01]}}}  # fmt: skip
    a, b = tiny(sample=sample, grid={}, fixed={}), tiny(sample=sample, grid={}, fixed={})
    va, vb = a.sample_values(), b.sample_values()
    assert np.array_equal(va["amplitude_mm"], vb["amplitude_mm"])
    assert va["amplitude_mm"].min() >= 10 and va["amplitude_mm"].max() <= 30
    assert a.run_dims == ("sample", "shaper") and a.n_runs == 150
    assert a.point(4)["amplitude_mm"] == va["amplitude_mm"][1]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"grid": {"frequency": [0.1]}}, "unknown parameter 'frequency'"),
        ({"grid": {"freq_error": []}}, "grid.freq_error must be a non-empty list"),
        ({"grid": {"speed_mm_s": [500.0]}}, "speed_mm_s must be a number in [1, 400]"),
        ({"fixed": {"freq_error": 0.1}}, "freq_error is fixed and also on the grid"),
        ({"chunk_runs": 0}, "chunk_runs must be a positive integer"),
        ({"shapers": ("zvd", "zvd")}, "listed twice"),
        ({"run": {"t_end_s": 1.0}}, "t_down_s < t_end_s"),
        (
            {"sample": {"n": 4, "distributions": {"seed": {"choice": [1, 2]}}}},
            "noise seed is set on the grid",
        ),
    ],
)
def test_bad_definitions_are_refused_in_one_line(change, message):
    with pytest.raises(ValueError, match="sweep definition 'tiny'") as err:
        tiny(**change)
    assert message in str(err.value) and "\n" not in str(err.value)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The tiny sweep (2 design errors x 2 seeds x 3 shapers) run serially, and its file."""
    out = tmp_path_factory.mktemp("reference") / "serial.nc"
    ds, report = run_sweep(tiny(), out, serial=True, progress=False)
    return ds, report, out


@pytest.mark.slow  # the serial loop and the batch API in the default suite; a cluster here and in -m slow
def test_tiny_sweep_on_a_local_cluster_of_two_workers_equals_the_serial_loop(tmp_path, reference):
    d = tiny()
    serial, rep_s, serial_path = reference
    with local_client(2, processes=False) as client:
        assert len(client.scheduler_info()["workers"]) == 2
        dist, rep_d = run_sweep(d, tmp_path / "dist.nc", client=client, progress=False)
    assert "Dask client" in rep_d.where and rep_s.computed == rep_d.computed == 3
    # the same numbers, bit for bit, and the same bytes on disk but for the code version's line
    xr.testing.assert_identical(serial.drop_attrs(), dist.drop_attrs())
    assert serial_path.read_bytes() == (tmp_path / "dist.nc").read_bytes()
    assert not serial_path.with_name("serial.nc.parts").exists()
    ds = load_sweep(tmp_path / "dist.nc")
    assert dict(ds.sizes) == {"freq_error": 2, "shaper": 3, "seed": 2, "move": 2}
    assert ds["residual_pct"].dims == ("freq_error", "shaper", "move")
    assert ds["peak_n"].dims == ("freq_error", "shaper", "seed", "move")
    assert int((ds["status"] > 0).sum()) == 0
    # what the numbers must say: a shaper leaves far less than the unshaped pulse; the noise seed changes the
    # ADC readings, not the true tension; the unshaped pulse does not depend on the design error
    res = ds["residual_pct"].sel(freq_error=0.0)
    assert float(res.sel(shaper="zvd").max()) < 0.5 * float(res.sel(shaper="unshaped").min())
    # (the ADC's residual is a handful of counts, so one move's can coincide across seeds: compare them all)
    adc = ds["residual_adc_pct"]
    assert not np.array_equal(adc.sel(seed=0), adc.sel(seed=1))
    assert not np.array_equal(ds["peak_n"].sel(seed=0), ds["peak_n"].sel(seed=1))
    unshaped = ds["residual_pct"].sel(shaper="unshaped")
    assert np.array_equal(unshaped.sel(freq_error=0.0), unshaped.sel(freq_error=0.2))
    # the fixed impulses' move lasts its shaper (125 ms, shortened by 1 + freq_error) plus t_p = 25 ms
    dur = ds["move_duration_s"].sel(shaper="fixed", move="up")
    assert float(dur.sel(freq_error=0.0)) == pytest.approx(0.150, abs=2e-3)
    assert float(dur.sel(freq_error=0.2)) == pytest.approx(0.125 / 1.2 + 0.025, abs=2e-3)
    definition = json.loads(ds.attrs["definition"])
    assert definition["name"] == "tiny" and definition["identified"]["omega_d"] > 0
    assert json.loads(ds.attrs["rig_parameters"])["n_discs"] == 12
    assert ds.attrs["code_version"].startswith("helpers ") and len(ds.attrs["physics_fingerprint"]) == 16


def test_an_interrupted_sweep_resumes_without_recomputing_finished_chunks(tmp_path, monkeypatch, reference):
    d = tiny()
    real = execute_module.run_chunk
    calls: list[int] = []

    def interrupted_after_two(text, chunk, threads):
        if len(calls) == 2:
            raise KeyboardInterrupt
        calls.append(chunk)
        return real(text, chunk, threads)

    monkeypatch.setattr(execute_module, "run_chunk", interrupted_after_two)
    out = tmp_path / "out.nc"
    with pytest.raises(SweepInterrupted) as err:
        run_sweep(d, out, serial=True, progress=False)
    assert "2 of 3 chunks are saved" in str(err.value) and "run the same command again" in str(err.value)
    assert err.value.signum == 2 and not out.exists()
    assert len(list((tmp_path / "out.nc.parts").glob("chunk-*.npz"))) == 2

    calls.clear()
    monkeypatch.setattr(execute_module, "run_chunk", lambda t, c, n: calls.append(c) or real(t, c, n))
    resumed, report = run_sweep(d, out, serial=True, progress=False)
    assert calls == [2] and (report.resumed, report.computed) == (2, 1)
    xr.testing.assert_identical(reference[0].drop_attrs(), resumed.drop_attrs())


def test_parts_of_another_sweep_are_refused(tmp_path, monkeypatch):
    def stop(text, chunk, threads):
        raise KeyboardInterrupt

    monkeypatch.setattr(execute_module, "run_chunk", stop)
    with pytest.raises(SweepInterrupted):
        run_sweep(tiny(), tmp_path / "x.nc", serial=True, progress=False)
    with pytest.raises(DataFileError, match="another definition"):
        run_sweep(tiny(fixed={"amplitude_mm": 6.0}), tmp_path / "x.nc", serial=True, progress=False)


def test_refused_designs_are_recorded_not_raised(tmp_path):
    # the scheduled pair needs the map at the destination; this map ends at 20 mm: a 30 mm move is refused
    short_map = ModeMap.constant(25.0, 0.044, positions_mm=(0.0, 20.0)).to_dict()
    d = tiny(shapers=("scheduled-zvd",), grid={"amplitude_mm": [5.0, 30.0]}, fixed={}, mode_map=short_map)
    ds, report = run_sweep(d, tmp_path / "r.nc", serial=True, progress=False)
    assert report.refused == 1
    assert ds["status"].sel(shaper="scheduled-zvd").values.tolist() == [0, 1]
    refused = ds["residual_pct"].sel(amplitude_mm=30.0, move="up", shaper="scheduled-zvd")
    assert math.isnan(float(refused))
    assert "leaves the measured range" in json.loads(ds.attrs["refused_runs"])["1"]


def test_cli_errors_are_one_line_with_their_exit_codes(tmp_path, capsys):
    assert cli.main(["sweep", "run", str(tmp_path / "none.json")]) == 5
    assert "none.json" in capsys.readouterr().err
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"name": "bad", "shapers": ["zvd"], "grid": {"speed": [1]}}))
    assert cli.main(["sweep", "run", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown parameter 'speed'" in err
    unknown = tmp_path / "unknown.json"
    unknown.write_text(json.dumps({"name": "u", "shapers": ["nonsense"], "run": SHORT}))
    assert cli.main(["sweep", "run", str(unknown), "--serial"]) == 2
    assert "unknown shaper 'nonsense'" in capsys.readouterr().err


def test_cli_runs_a_definition_and_refuses_to_overwrite(tmp_path, capsys):
    path = tmp_path / "tiny.json"
    path.write_text(json.dumps(tiny(shapers=("zvd",), grid={}).to_dict()))
    assert load_definition(path).n_runs == 1
    assert cli.main(["sweep", "run", str(path), "--serial", "--no-progress"]) == 0
    assert "tiny: 1 runs in 1 chunks" in capsys.readouterr().out
    assert (tmp_path / "tiny.nc").exists()
    assert cli.main(["sweep", "run", str(path), "--serial"]) == 5
    assert "exists already" in capsys.readouterr().err
    assert cli.main(["sweep", "info", str(tmp_path / "tiny.nc")]) == 0
    assert "shaper 1" in capsys.readouterr().out


def test_cli_runs_against_a_given_scheduler_address(tmp_path, capsys, monkeypatch, reference):
    """``sweep run --scheduler ADDRESS``: a running scheduler (here a 2-worker cluster listening on TCP in
    this process), the same numbers as the serial loop."""
    from distributed import LocalCluster  # noqa: PLC0415 - the test's own cluster

    serial, _, _ = reference
    path = tmp_path / "tiny.json"
    path.write_text(json.dumps(tiny().to_dict()))
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp",
                      dashboard_address=":0") as cluster:  # fmt: skip
        assert cluster.scheduler_address.startswith("tcp://")
        address = cluster.scheduler_address
        code = cli.main(["sweep", "run", str(path), "--scheduler", address, "--no-progress"])
    assert code == 0
    assert f"the Dask scheduler at {cluster.scheduler_address}" in capsys.readouterr().out
    xr.testing.assert_identical(serial.drop_attrs(), load_sweep(tmp_path / "tiny.nc").drop_attrs())
    monkeypatch.setattr(execute_module, "CONNECT_TIMEOUT_S", 2)  # nothing listens on port 9
    assert cli.main(["sweep", "run", str(path), "--overwrite", "--scheduler", "tcp://127.0.0.1:9"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot reach the Dask scheduler at tcp://127.0.0.1:9" in err


@pytest.mark.slow
def test_sigterm_keeps_finished_chunks_and_the_same_command_resumes(tmp_path):
    # a real process on a real local cluster of 2 worker processes, stopped by SIGTERM after its first chunk
    path = tmp_path / "stop.json"
    d = tiny(grid={"freq_error": [0.0, 0.05, 0.1, 0.15, 0.2, 0.25]}, chunk_runs=1, run={"t_end_s": 12.0})
    path.write_text(json.dumps(d.to_dict()))
    env = {**os.environ, "PYTHONPATH": str(REPO_ROOT)}
    cmd = [sys.executable, "-m", "helpers", "sweep", "run", str(path), "--workers", "2", "--no-progress"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    parts = tmp_path / "stop.nc.parts"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not list(parts.glob("chunk-*.npz")):
        time.sleep(0.2)
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    lines = [line for line in err.splitlines() if line.strip()]
    assert (
        len(lines) == 1 and "interrupted by SIGTERM" in lines[0] and "run the same command again" in lines[0]
    )
    saved = len(list(parts.glob("chunk-*.npz")))
    assert 1 <= saved < d.n_chunks and f"{saved} of {d.n_chunks} chunks" in lines[0]
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
    assert done.returncode == 0, done.stderr
    assert f"({saved} found on disk, {d.n_chunks - saved} computed" in done.stdout
    assert load_sweep(tmp_path / "stop.nc")["residual_pct"].notnull().all()


@pytest.mark.slow
def test_the_stored_atlas_was_made_by_the_present_virtual_rig():
    # if this fails, the rig changed since the atlas was stored: python -m helpers sweep atlas --overwrite
    for name in ("atlas_freq_damping", "atlas_amplitude_speed", "atlas_uncertainty"):
        ds = load_sweep(DATA_DIR / "sweeps" / f"{name}.nc")
        assert same_physics(ds.attrs["physics_fingerprint"]), name
        assert json.loads(ds.attrs["definition"]) == json.loads(
            load_definition(DATA_DIR / "sweeps" / f"{name}.json").resolved().to_json()
        ), name
