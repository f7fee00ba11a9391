"""Every command and every error reply of PROTOCOL.md, for both boards, on the real ELF files in simavr."""

from __future__ import annotations

import functools
import re

import fw_cases as cases
import fwsim
import pytest

pytestmark = pytest.mark.firmware

HELLO = {"daq": r"HELLO daq 2\.3\.0\+481e87e3", "stepper": r"HELLO stepper 2\.3\.0\+481e87e3"}


def _script(board: str) -> list[tuple[bytes, str | None, float, str | None]]:
    # an extra 0.1 ms per byte: a 200-byte line takes 17 ms at 115200 baud
    if board == "daq":
        return [(c, r, 1e-4 * len(c), None) for c, r in cases.framing_cases("daq") + cases.daq_cases()]
    return [(c, r, 1e-4 * len(c), None) for c, r in cases.framing_cases("stepper")] + cases.stepper_cases()


@functools.cache
def _session(board: str):
    script = _script(board)
    run, groups = fwsim.command_session(board, [c for c, *_ in script], [p for _, _, p, _ in script])
    return board, script, run, groups


@pytest.fixture(scope="module", params=["daq", "stepper"])
def session(request, firmware_build):
    return _session(request.param)


@pytest.fixture(scope="module")
def daq_session(firmware_build):
    return _session("daq")


def test_every_line_has_a_valid_checksum(session):
    _, _, run, _ = session
    bad = [ln.raw for ln in run.lines if not ln.checksum_ok]
    assert not bad, f"lines with a wrong or missing checksum: {bad[:5]}"
    assert all(len(ln.raw) <= 63 for ln in run.lines)


def test_hello_once_at_reset(session):
    board, _, run, _ = session
    hellos = [ln for ln in run.lines if ln.body.startswith("HELLO")]
    assert len(hellos) == 1
    assert re.fullmatch(HELLO[board], hellos[0].body)
    assert run.lines[0] is hellos[0]


def test_each_command_gets_exactly_its_reply(session):
    _, script, _, groups = session
    failures = []
    for (cmd, expected, _, done), group in zip(script, groups, strict=True):
        replies = [ln.body for ln in group if not ln.body.startswith(("D,", "W,", "DONE"))]
        dones = [ln.body for ln in group if ln.body.startswith("DONE")]
        want = [] if expected is None else [expected]
        ok = len(replies) == len(want) and all(re.fullmatch(w, r) for w, r in zip(want, replies, strict=True))
        ok = ok and (len(dones) == 0 if done is None else len(dones) == 1 and re.fullmatch(done, dones[0]))
        if not ok:
            failures.append(f"{cmd[:40]!r}: expected {expected!r} (DONE {done!r}), got {replies + dones!r}")
    assert not failures, "\n".join(failures)


def test_daq_stop_counts_the_data_lines_sent(daq_session):
    _, script, _, groups = daq_session
    n_data, checked = None, 0
    for group in groups:
        for ln in group:
            if ln.body.startswith("OK START"):
                n_data = 0
            elif ln.body.startswith("D,"):
                assert n_data is not None, "data line outside START/STOP"
                seq = int(ln.body.split(",")[1])
                assert seq == n_data, "seq must start at 0 and increase by 1 per sample"
                n_data += 1
            elif ln.body.startswith("OK STOP"):
                assert int(ln.body.split()[2]) == (n_data or 0)
                if n_data:
                    checked += 1
                n_data = None
    assert checked == 2, "both streaming periods were checked"
