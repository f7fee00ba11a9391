"""The rig-parametrised tests: every test that depends on the rig's numbers runs for both shipped rig files.

Two fixtures yield each shipped single-tendon rig file, the paper's (``rigs/paper.toml``) and the second
rig (``rigs/long-arm.toml``), as a :class:`rigs.ShippedRig` (its keys, and what follows from them by the
arithmetic of ``docs/rig_file.md``, done in the test: never by the code under test):

- ``rig_file``: for code that takes the rig as an argument (a recording's rig, ``rigfile.derived``); the
  test runs in this process for both rigs;
- ``shipped_rig``: for code that follows the rig **the host runs** (``helpers.paper.hardware`` reads it once,
  when it is imported: the host limits and the quantiser, the safety refusals, the emulated boards' replies
  and greeting, the recordings' rig, the metrics' sensor range, the scaled scenarios, the calibration loads).
  The variant of the rig this process runs (the paper's, unless ``HELPERS_RIG`` says otherwise) runs here;
  the other rig's variants all run together in **one** pytest session of their own, started once per run
  with ``HELPERS_RIG`` naming that rig (as a user selects it), and each reports that session's outcome as
  its own (a failure shows the session's report).

The rig-parametrised tests (``[paper]`` and ``[long-arm]`` in their ids):

- ``test_profiles.py``: ``test_host_limits_follow_the_rig_file``, ``test_limits_refused_with_named_limit``,
  ``test_limits_accept_the_extremes``, ``test_travel_checked_from_start_position``,
  ``test_the_quantiser_lands_on_whole_steps_of_the_rig``, ``test_a_request_faster_than_the_rig_is_refused``;
- ``test_rig_safety.py``: ``test_bad_pulse_requests_are_refused_before_sending``,
  ``test_bad_programmes_are_refused_before_sending``, ``test_bad_sample_rates_are_refused_before_sending``,
  ``test_check_request_accepts_the_rigs_scenarios``;
- ``test_virtual_boards.py``: ``test_hello_on_reset_and_pong_with_the_documented_checksum``,
  ``test_stepper_limits``, ``test_config_replies_are_the_rigs_limits``;
- ``test_rig_virtual.py``: ``test_boards_built_for_another_rig_are_refused_with_the_rebuild_command``;
- ``test_rig_selection.py``: ``test_a_recording_from_the_virtual_rig_keeps_its_rig``,
  ``test_a_recordings_rig_section_round_trips``;
- ``test_rig_metrics.py``: ``test_the_sensor_range_is_the_rigs``;
- ``test_scenarios.py``: ``test_scenarios_follow_the_selected_rig``;
- ``test_second_rig.py``: ``test_calibration_masses_follow_the_load_cell``.

Tests whose expected numbers are the paper's published values (Table I's programmes, the paper's 0.25525 mm
per step, its hardware constants) stay paper-only; each says so.
"""

from __future__ import annotations

import fcntl
import json
import os
import subprocess
import sys

import pytest

from helpers import rigfile
from rigs import REPO, SHIPPED, ShippedRig

REPORT_VAR = "HELPERS_TEST_RIG_REPORT"
"""In a rig's own session: the file its outcomes are written to (read by the session that started it)."""

_OUTCOMES = pytest.StashKey[dict]()
_foreign: dict[str, list[str]] = {}  # rig name -> node ids of this run's items of that (another) rig
_sessions: dict[str, dict] = {}  # rig name -> {node id: outcome} once that rig's session has run


def _process_rig() -> str | None:
    """The shipped rig this process runs (by hash), or None."""
    selected = rigfile.selected().hash
    return next((name for name, rig in SHIPPED.items() if rig.hash == selected), None)


@pytest.fixture(params=list(SHIPPED), ids=list(SHIPPED))
def rig_file(request) -> ShippedRig:
    """Each shipped rig file, for code that takes the rig as an argument (runs in this process)."""
    return SHIPPED[request.param]


@pytest.fixture(params=list(SHIPPED), ids=list(SHIPPED))
def shipped_rig(request) -> ShippedRig:
    """Each shipped rig file as the rig the host runs: this process's here, the other in its own session."""
    name = request.param
    if name != _process_rig():
        if os.environ.get(REPORT_VAR):
            pytest.fail(f"a session for rig {_process_rig()} was asked to run a {name} variant")
        request.node.stash[_OUTCOMES] = _rig_session(name, request)
    return SHIPPED[name]


def pytest_collection_finish(session):
    """Note the items of the rig-parametrised tests whose rig is not this process's (after deselection)."""
    here = _process_rig()
    _foreign.clear()
    for item in session.items:
        spec = getattr(item, "callspec", None)
        name = spec.params.get("shipped_rig") if spec is not None else None
        if name is not None and name != here:
            _foreign.setdefault(name, []).append(item.nodeid)


def _rig_session(name: str, request) -> dict:
    """The outcomes of this run's ``name`` variants: one pytest session with ``HELPERS_RIG`` set, run once.

    pytest-xdist's workers share the folder above their temporary folders: the first worker to get here
    runs the session under a lock, the others read its outcomes.
    """
    if name in _sessions:
        return _sessions[name]
    factory = request.getfixturevalue("tmp_path_factory")
    base = factory.getbasetemp()
    shared = base.parent if hasattr(request.config, "workerinput") else base
    report = shared / f"rig-session-{name}.json"
    with open(shared / f"rig-session-{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not report.exists():
            _run_rig_session(name, _foreign.get(name, []), report)
    _sessions[name] = json.loads(report.read_text())
    return _sessions[name]


def _run_rig_session(name: str, node_ids: list[str], report) -> None:
    env = dict(os.environ, **{rigfile.ENV_VAR: str(SHIPPED[name].path), REPORT_VAR: str(report) + ".part"})
    env.pop("PYTEST_XDIST_WORKER", None)
    env.pop("PYTEST_XDIST_WORKER_COUNT", None)
    argv = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist",
            "-p", "no:nbval", "-o", "addopts=", *node_ids]  # fmt: skip
    proc = subprocess.run(argv, cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    part = report.with_name(report.name + ".part")
    outcomes = json.loads(part.read_text()) if part.exists() else {}
    outcomes["<session>"] = {"status": proc.returncode, "tail": (proc.stdout + proc.stderr)[-3000:]}
    report.write_text(json.dumps(outcomes))


@pytest.hookimpl(tryfirst=True)
def pytest_pyfunc_call(pyfuncitem):
    """A variant of another rig than this process's: its outcome is that of its run in the rig's session."""
    outcomes = pyfuncitem.stash.get(_OUTCOMES, None)
    if outcomes is None:
        return None
    name = pyfuncitem.callspec.params["shipped_rig"]
    got = outcomes.get(pyfuncitem.nodeid)
    if got is None:
        session = outcomes["<session>"]
        pytest.fail(f"not run in the {name} session (exit status {session['status']}):\n{session['tail']}",
                    pytrace=False)  # fmt: skip
    if got["outcome"] == "skipped":
        pytest.skip(f"in the {name} session: {got['text']}")
    if got["outcome"] != "passed":
        pytest.fail(f"in the session run with HELPERS_RIG={SHIPPED[name].path.name}:\n{got['text']}",
                    pytrace=False)  # fmt: skip
    return True


# --- in a rig's own session: write each test's outcome for the session that started this one ------------
_reported: dict[str, dict] = {}


def pytest_runtest_logreport(report):
    """Keep each test's outcome (the first phase that did not pass decides it)."""
    if not os.environ.get(REPORT_VAR):
        return
    entry = _reported.setdefault(report.nodeid, {"outcome": "passed", "text": ""})
    if entry["outcome"] == "passed" and not report.passed:
        entry["outcome"] = "skipped" if report.skipped else "failed"
        entry["text"] = report.longreprtext[-4000:]

def pytest_sessionfinish(session):
    """Write the outcomes (in a rig's own session only)."""
    path = os.environ.get(REPORT_VAR)
    if path:
        with open(path, "w") as f:
            json.dump(_reported, f)
