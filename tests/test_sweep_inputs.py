"""Sweeps refuse what cannot run in one line naming the field, lock their output, check every chunk against
their definition, and refuse an address that is not a Dask scheduler without hanging or allocating."""

from __future__ import annotations

import http.server
import json
import os
import socket
import threading

import numpy as np
import pytest
import xarray as xr

from helpers.__main__ import main
from helpers.base.locks import folder_lock
from helpers.research.sweep import execute
from helpers.research.sweep.definition import SweepDefinition
from helpers.research.sweep.execute import probe_scheduler, run_sweep

SHORT_RUN = {"t_end_s": 4.0, "t_up_s": 0.3, "t_down_s": 1.8}


def _status(argv) -> int:
    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code)


BAD = {
    "a list for the grid": ({"grid": [["freq_error", [0.1]]]}, "grid: Input should be a valid dictionary"),
    "rate_hz 1e9": ({"run": {"rate_hz": 1e9}}, "run.rate_hz: Input should be less than or equal to 2000"),
    "n 1e12": (
        {"sample": {"n": 10**12, "distributions": {"freq_error": {"uniform": [0, 0.1]}}}},
        "sample.n: Input should be less than or equal to 200000",
    ),
    "too many runs": ({"grid": {"freq_error": [i / 1e4 for i in range(10_000)],
                                "damping_scale": [0.5 + i / 100 for i in range(100)]}}, "over the limit"),
    "an absurd custom shaper": (
        {"shapers": ["x"], "custom_shapers": {"x": {"amplitudes": [-1000, 1001], "times": [0, 0.1]}}},
        "custom_shapers.x: an amplitude beyond +-2",
    ),
    "a custom shaper with negative times": (
        {"shapers": ["x"], "custom_shapers": {"x": {"amplitudes": [0.5, 0.5], "times": [-1, 0.1]}}},
        "times must start at >= 0",
    ),
    "zeta 2": (
        {"shapers": ["x"], "custom_shapers": {"x": {"family": "ZV", "omega_d": 25.0, "zeta": 2}}},
        "custom_shapers.x.zeta: Input should be less than 1",
    ),
    "an unknown family": (
        {"shapers": ["x"], "custom_shapers": {"x": {"family": "ZZZ", "omega_d": 25.0, "zeta": 0.04}}},
        "custom_shapers.x.family: Input should be",
    ),
    "a text for a number": (
        {"fixed": {"amplitude_mm": "twenty"}}, "fixed.amplitude_mm: Input should be a valid"
    ),
}


@pytest.mark.parametrize("case", list(BAD))
def test_a_malformed_definition_is_one_line_naming_the_field(tmp_path, capsys, case):
    change, message = BAD[case]
    definition = {"name": "bad", "shapers": ["zv"], "run": SHORT_RUN, **change}
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(definition))
    assert _status(["sweep", "run", str(path), "--serial", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.json"]  # nothing computed, nothing written


def test_deep_nesting_is_one_line(tmp_path, capsys):
    path = tmp_path / "deep.json"
    path.write_text('{"name": "deep", "shapers": ["zv"], "grid": ' + "[" * 100_000 + "]" * 100_000 + "}")
    assert _status(["sweep", "run", str(path), "--serial"]) == 5
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "nested too deeply" in err


def test_sweep_info_on_a_dataset_without_its_attributes_is_one_line(tmp_path, capsys):
    path = tmp_path / "x.nc"
    xr.Dataset({"residual_pct": ("run", np.zeros(3))}).to_netcdf(path, engine="scipy")
    assert _status(["sweep", "info", str(path)]) == 5
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not a sweep's dataset: attribute definition" in err


def test_an_output_in_use_is_refused(tmp_path, capsys):
    path = tmp_path / "d.json"
    path.write_text(json.dumps({"name": "d", "shapers": ["unshaped"], "run": SHORT_RUN}))
    with folder_lock(tmp_path, what="running a sweep into d.nc", name=".d.nc.lock"):  # another sweep holds it
        assert _status(["sweep", "run", str(path), "--serial", "--no-progress"]) == 5
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"process {os.getpid()} is running a sweep into d.nc" in err
    assert not (tmp_path / "d.nc.parts").exists()


@pytest.mark.slow  # resuming over undamaged chunks: tests/test_sweep.py (default suite)
def test_damaged_and_foreign_chunks_are_named_and_computed_again(tmp_path):
    d = SweepDefinition(name="c", shapers=("unshaped", "zv"), chunk_runs=1, run=SHORT_RUN)
    first, _ = run_sweep(d, tmp_path / "c.nc", serial=True, progress=False, keep_parts=True)
    parts = tmp_path / "c.nc.parts"
    (parts / "chunk-00001.npz").write_bytes((parts / "chunk-00000.npz").read_bytes())  # chunk 0 as chunk 1
    (parts / "chunk-00000.npz").write_bytes(b"PK\x03\x04 damaged")
    again, report = run_sweep(d, tmp_path / "c.nc", serial=True, progress=False, overwrite=True)
    assert report.resumed == 0 and report.computed == 2
    assert any("chunk-00000.npz: damaged chunk" in r for r in report.rejected)
    assert any("chunk-00001.npz: holds chunk 0, not 1" in r for r in report.rejected)
    assert np.array_equal(first["residual_pct"].values, again["residual_pct"].values, equal_nan=True)
    assert np.isfinite(first["residual_pct"].values).any()


@pytest.fixture
def http_server():
    server = http.server.HTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.server_address[1]}"
    server.shutdown()


@pytest.fixture
def random_bytes_server():
    """A service that sends 1 MB of random bytes to whoever connects (listening before the test starts)."""
    sock = socket.create_server(("127.0.0.1", 0))
    junk = np.random.default_rng(5).integers(0, 256, 1 << 20, dtype=np.uint8).tobytes()

    def serve():
        while True:
            try:
                conn, _ = sock.accept()
            except OSError:
                return
            try:
                conn.sendall(junk)
            except OSError:
                pass
            conn.close()

    threading.Thread(target=serve, daemon=True).start()
    yield f"tcp://127.0.0.1:{sock.getsockname()[1]}"
    sock.close()


def test_an_http_server_is_not_taken_for_a_scheduler(tmp_path, capsys, monkeypatch, http_server):
    monkeypatch.setattr(execute, "GREETING_TIMEOUT_S", 1.0)  # it waits for a request that never comes
    path = tmp_path / "d.json"
    path.write_text(json.dumps({"name": "d", "shapers": ["unshaped"], "run": SHORT_RUN}))
    assert _status(["sweep", "run", str(path), "--scheduler", http_server, "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "did not greet as a Dask scheduler within 1 s" in err


def test_a_service_sending_random_bytes_is_refused_without_allocating(random_bytes_server):
    with pytest.raises(ValueError, match="is not a Dask scheduler: its first message announces"):
        probe_scheduler(random_bytes_server, timeout=30.0)


def test_a_dask_scheduler_passes_the_probe():
    from distributed import LocalCluster

    with LocalCluster(n_workers=0, processes=False, protocol="tcp", dashboard_address=":0") as cluster:
        probe_scheduler(cluster.scheduler_address, timeout=30.0)  # no error
