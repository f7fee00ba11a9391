"""The firmware's shared framing code (firmware/common/proto.cpp, crc8.cpp), compiled for the host with g++
and checked against a reference written here from PROTOCOL.md, on generated inputs (hypothesis)."""

from __future__ import annotations

import re
import shutil
import subprocess

import fwsim
import pytest
from crc_reference import LINK_CHECK
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

pytestmark = pytest.mark.firmware

INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1


@pytest.fixture(scope="module")
def proto(tmp_path_factory):
    gxx = shutil.which("g++")
    if gxx is None:
        pytest.skip("g++ is missing: apt-get install -y g++")
    exe = tmp_path_factory.mktemp("proto") / "proto_host_test"
    common = fwsim.FIRMWARE / "common"
    subprocess.run(
        [
            gxx,
            "-O1",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-I",
            str(common),
            "-o",
            str(exe),
            str(common / "proto_host_test.cpp"),
            str(common / "proto.cpp"),
            str(common / "crc8.cpp"),
        ],
        check=True,
        capture_output=True,
        text=True,
    )
    proc = subprocess.Popen([str(exe)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)

    def ask(line: str) -> str:
        assert proc.stdin is not None and proc.stdout is not None
        proc.stdin.write(line + "\n")
        proc.stdin.flush()
        return proc.stdout.readline().rstrip("\n")

    yield ask
    proc.stdin.close()
    proc.wait(timeout=5)


def ref_reader(data: bytes) -> str:
    """PROTOCOL.md framing: lines end in '\\n', a '\\r' just before it is dropped (any other '\\r' is part of
    the line), more than 63 characters = one TOOLONG."""
    out = []
    for raw in data.split(b"\n")[:-1]:
        line = raw[:-1] if raw.endswith(b"\r") else raw
        out.append(" T" if len(line) > 63 else " R:" + line.hex())
    return "".join(out)


def ref_parse(line: bytes) -> str:
    """CRC-8 check, then words split on single spaces; arguments are -?[0-9]+ saturated to int32."""
    if not line:
        return "EMPTY"
    star = line.find(b"*")
    if star >= 0:
        given_hex = line[star + 1 :]
        if not re.fullmatch(rb"[0-9A-Fa-f]{2}", given_hex):
            return "CHECKSUM"
        if given_hex.decode().upper() != fwsim.checksum(line[:star]):
            return "CHECKSUM"
        line = line[:star]
        if not line:
            return "EMPTY"
    toks = line.split(b" ")
    bad = any(t == b"" for t in toks)
    args = []
    for t in toks[1:4]:
        if bad:
            break
        if not re.fullmatch(rb"-?[0-9]+", t):
            bad = True
            break
        args.append(max(INT32_MIN, min(INT32_MAX, int(t))))
    nargs = len(toks) - 1
    shown = [args[i] if (not bad and i < nargs) else 0 for i in range(3)]
    return f"OK {toks[0].hex()} {nargs} {int(bad)} " + " ".join(str(a) for a in shown)


def _c_answer(ans: str) -> str:
    return ans.split(" ")[0] if ans.startswith(("EMPTY", "CHECKSUM")) else ans


ALPHABET = " -+0123456789*ABCDEFGINOPRSTZabcfx"
lines = st.text(alphabet=ALPHABET, max_size=63).map(lambda s: s.encode("ascii"))


@st.composite
def commands(draw) -> bytes:
    """Mostly well-formed commands, some with a correct checksum."""
    word = draw(st.sampled_from(["PING", "RATE", "SEG", "WAIT", "EN", "GO", "X"]))
    args = draw(st.lists(st.integers(-(2**40), 2**40).map(str), max_size=4))
    body = " ".join([word, *args])[:60]
    if draw(st.booleans()):
        return fwsim.with_checksum(body).encode()[:63]
    return body.encode()


SETTINGS = settings(
    max_examples=400, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


@SETTINGS
@given(line=st.one_of(lines, commands()))
def test_parse_matches_the_protocol(proto, line):
    assert _c_answer(proto("P " + line.hex())) == ref_parse(line)


@SETTINGS
@given(data=st.binary(max_size=300).map(lambda b: b.replace(b"\x00", b"\x01")))
def test_line_reader_matches_the_protocol(proto, data):
    data = data + b"\n"
    assert proto("F " + data.hex()) == ref_reader(data)


def test_line_reader_edges(proto):
    assert proto("F " + (b"A" * 63 + b"\n").hex()) == " R:" + (b"A" * 63).hex()
    assert proto("F " + (b"A" * 64 + b"\nB\n").hex()) == " T R:42"
    assert proto("F " + (b"A" * 62 + b"\r\r\n").hex()) == " R:" + (b"A" * 62 + b"\r").hex()
    assert proto("F " + (b"A" * 63 + b"\r\n").hex()) == " R:" + (b"A" * 63).hex()
    assert proto("F " + (b"A" * 63 + b"\r\r\n").hex()) == " T"  # the first '\r' is the 64th character
    assert proto("F " + b"P\rI\rNG\r\n".hex()) == " R:" + b"P\rI\rNG".hex()


def test_crc8_check_value_and_reference(proto):
    assert proto("C " + b"123456789".hex()) == f"{LINK_CHECK:02X}" == "20"
    assert proto("C ") == "FF"  # the initial value, nothing shifted in


@SETTINGS
@given(data=st.binary(min_size=1, max_size=255))
def test_crc8_matches_the_reference(proto, data):
    assert proto("C " + data.hex()) == fwsim.checksum(data)


@SETTINGS
@given(v=st.one_of(st.integers(0, 2**32 - 1), st.sampled_from([0, 9, 10, 99, 10**9, 4_294_967_295])))
def test_u32_formatting(proto, v):
    assert proto(f"U {v}") == fwsim.with_checksum(str(v))


@SETTINGS
@given(v=st.one_of(st.integers(INT32_MIN, INT32_MAX), st.sampled_from([INT32_MIN, -1, 0, INT32_MAX])))
def test_i32_formatting(proto, v):
    assert proto(f"I {v}") == fwsim.with_checksum(str(v))
