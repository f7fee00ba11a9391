"""Line framing and the DAQ stream parser: examples from PROTOCOL.md and hypothesis fuzzing.

The fuzz tests generate at least 10,000 streams in total (FUZZ_EXAMPLES x STREAMS_PER_EXAMPLE plus the
structured strategy) and check that the parser never raises, flags every corrupted line and counts every
dropped sequence number exactly, whatever the chunking.
"""

from __future__ import annotations

import random

import numpy as np
import pytest
from crc_reference import link_hex, xor_hex
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from line_reference import FramingError
from line_reference import unframe as unframe_line

from helpers.board.protocol import WRAP_US, StreamParser, checksum, frame, unframe

STRUCTURED_EXAMPLES = 1000
FUZZ_EXAMPLES = 750
STREAMS_PER_EXAMPLE = 12


def test_checksums_of_the_protocol_examples():
    # PROTOCOL.md: "PONG daq 2.0.0*FD"; "the host may send PING*79"; check value 0x20
    assert frame("PONG daq 2.0.0") == b"PONG daq 2.0.0*FD\n"
    assert frame("PING") == b"PING*79\n"
    assert checksum("PING") == "79" == link_hex("PING")
    assert checksum(b"123456789") == "20"


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=63))
def test_checksum_matches_the_bitwise_reference(body):
    assert checksum(body) == link_hex(body)


def _framed(line: bytes) -> list[bytes]:
    """The bodies of ``line``'s framed lines whose CRC-8 is right (:func:`unframe`)."""
    starts, stars, good, _ = unframe(line + b"\n")
    return [line[a:b] for a, b, ok in zip(starts.tolist(), stars.tolist(), good.tolist(), strict=True) if ok]


def test_unframe_accepts_good_and_rejects_bad():
    assert _framed(b"PONG daq 2.0.0*FD") == [b"PONG daq 2.0.0"]
    assert _framed(b"PONG daq 2.0.0*FD\r") == [b"PONG daq 2.0.0"]
    assert unframe(b"\r\n\n")[3] == 0  # blank lines: neither framed nor corrupted
    for bad in (
        b"PONG daq 2.0.0*FC",
        b"PONG daq 2.0.0*fd",  # a board sends upper case
        b"PONG daq 2.0.0*F",
        b"PONG daq 2.0.0",
        b"PONG daq 2.0.0*FG",
        b"\xffPONG*00",
        b"A*B*00",
        b"x" * 64,
        b"D,5002,344403000,620,58*" + link_hex("D,5002,344403000,600,78").encode(),  # 2-bit error XOR misses
    ):
        assert _framed(bad) == []
        p = StreamParser()
        assert p.feed(bad + b"\n") == ([], []) and p.stats.corrupted == 1


def test_a_protocol_1_line_is_named_as_such_and_kept_by_the_parser():
    old = f"PONG daq 1.0.0*{xor_hex('PONG daq 1.0.0')}".encode()
    assert xor_hex("PONG daq 1.0.0") == "53"  # protocol 1's own example
    assert _framed(old) == [] and len(unframe(old + b"\n")[0]) == 1  # framed, the CRC-8 wrong
    p = StreamParser()
    rows, msgs = p.feed(frame("D,0,10,1,0") + old + b"\n")
    assert len(rows) == 1 and msgs == [] and p.stats.corrupted == 1
    assert p.legacy == "PONG daq 1.0.0"
    p = StreamParser()  # a 1.x board's answer to a CRC-framed command
    p.feed(f"ERR CHECKSUM bad checksum*{xor_hex('ERR CHECKSUM bad checksum')}\n".encode())
    assert p.legacy == "ERR CHECKSUM bad checksum"
    p = StreamParser()  # an XOR-valid data line is merely corrupted (noise can do that), not a 1.x board
    p.feed(f"D,0,10,1,0*{xor_hex('D,0,10,1,0')}\n".encode())
    assert p.legacy is None and p.stats.corrupted == 1


def test_frame_refuses_what_cannot_be_sent():
    for bad in ("A*B", "caf\u00e9", "line\n", "x" * 61):
        with pytest.raises(ValueError):
            frame(bad)


def _parsed(body: str, channels: int = 1, axes: int = 1) -> tuple:
    """What the parser makes of ``body`` framed: its rows, messages, overruns and corrupted lines."""
    p = StreamParser(channels, axes)
    rows, msgs = p.feed(frame(body))
    return rows, msgs, p.stats.overruns, p.stats.corrupted


def test_bodies_are_classified():
    assert _parsed("D,5,1000,512,-3") == ([(5, 1000, 512, -3)], [], 0, 0)
    assert _parsed("D,5,1000,512,7,0,-3,156", 2, 3) == ([(5, 1000, 512, 7, 0, -3, 156)], [], 0, 0)
    assert _parsed("W,OVERRUN,2") == ([], [], 2, 0)
    assert _parsed("OK STOP 7") == ([], ["OK STOP 7"], 0, 0)
    for bad in (
        "D,1,2,3",
        "D,1,2,3,4,5",
        "D,1,2,1024,0",
        "D,-1,2,3,4",
        "D,1,4294967296,3,4",
        "D,a,2,3,4",
        "W,OVERRUN",
        "W,LATE,1",
        "W,OVERRUN,-1",
    ):
        assert _parsed(bad) == ([], [], 0, 1), bad
    for bad in ("D,5,1000,512,7,0,-3", "D,5,1000,512,-7,0,-3,1", "D,5,1000,1024,7,0,-3,1", "D,5,9,5,7,0,x,1"):
        assert _parsed(bad, 2, 3) == ([], [], 0, 1), bad  # 2 channels, 3 axes: few, negative, big, junk


def test_time_unwraps_across_the_32_bit_boundary():
    p = StreamParser()
    t0 = WRAP_US - 2500
    data = b"".join(frame(f"D,{k},{(t0 + 1000 * k) % WRAP_US},1,0") for k in range(6))
    rows, _ = p.feed(data)
    assert [r[1] for r in rows] == [t0 + 1000 * k for k in range(6)]


def test_long_garbage_without_newline_is_bounded_and_flagged():
    p = StreamParser()
    p.feed(b"x" * 10_000)
    assert len(p._buf) <= 256  # the unfinished line held back
    rows, _ = p.feed(b"\n" + frame("D,0,10,1,0"))
    assert len(rows) == 1 and p.stats.corrupted >= 1


# --- the fuzzed streams ----------------------------------------------------------------------------------
_INSERTABLE = [x for x in range(256) if x not in (0x0A, 0x0D)]


def _corrupt_line(line: bytes, how: str, r: random.Random) -> bytes:
    """Damage a framed line (without its newline) so that the damage is detectable.

    A changed byte is a burst of at most 8 bits, which the CRC-8 always detects, and a truncation loses the
    ``*hh``; an inserted byte is not a burst, and the CRC-8 misses about 1 in 256 of those: such an insertion
    (judged by the reference CRC, not by the code under test) is drawn again.
    """
    if how == "insert":
        while True:
            damaged = _corrupt_line_once(line, how, r)
            body, star, given = damaged.rpartition(b"*")
            if not (star and given == link_hex(body).encode()):
                return damaged
    return _corrupt_line_once(line, how, r)


def _corrupt_line_once(line: bytes, how: str, r: random.Random) -> bytes:
    b = bytearray(line)
    if how == "flip":
        i = r.randrange(len(b))
        new = b[i]
        while new in (b[i], 0x0A, 0x0D):
            new = r.randrange(256)
        b[i] = new
    elif how == "truncate":
        del b[len(b) - r.randint(1, len(b) - 1) :]
    elif how == "insert":
        i = r.randrange(len(b) + 1)
        c = r.choice(_INSERTABLE)
        b[i:i] = bytes([c])
    return bytes(b)


def _build_stream(r: random.Random, n: int, p_fault: float) -> tuple[bytes, dict]:
    """A DAQ stream with drops, corruptions, merged lines, garbage, overruns and messages, and the truth."""
    out: list[bytes] = []
    received: list[int] = []
    corrupted = 0
    overruns = 0
    messages = 0
    t0 = r.choice([0, WRAP_US - 5000, r.randrange(WRAP_US)])
    seq = 0
    merge_next = False
    while seq < n:
        if not merge_next and r.random() < p_fault / 4:
            junk = r.randbytes(r.randint(1, 60)).replace(b"\n", b"")
            if junk.strip(b"\r"):
                try:
                    unframe_line(junk)
                    valid = True
                except FramingError:
                    valid = False
                if not valid:
                    out.append(junk + b"\n")
                    corrupted += 1
        if not merge_next and r.random() < p_fault / 4:
            k = r.randint(1, 3)
            out.append(frame(f"W,OVERRUN,{k}"))
            overruns += k
        if not merge_next and r.random() < p_fault / 8:
            out.append(frame("OK STOP 0"))
            messages += 1
        line = frame(f"D,{seq},{(t0 + 1000 * seq) % WRAP_US},{r.getrandbits(10)},{r.getrandbits(9) - 256}")
        if merge_next:  # the previous line lost its newline: this one is swallowed into it
            out.append(line)
            merge_next = False
            seq += 1
            continue
        fate = r.random()
        if fate < p_fault:
            pass  # dropped in transport
        elif fate < 2 * p_fault:
            out.append(_corrupt_line(line[:-1], r.choice(["flip", "truncate", "insert"]), r) + b"\n")
            corrupted += 1
        elif fate < 2.5 * p_fault and seq + 1 < n:
            out.append(line[:-1])  # newline lost: merges with the next line
            corrupted += 1
            merge_next = True
        else:
            out.append(line)
            received.append(seq)
        seq += 1
    truth = {
        "received": received,
        "dropped": (received[-1] + 1 - len(received)) if received else 0,
        "corrupted": corrupted,
        "overruns": overruns,
        "messages": messages,
        "t0": t0,
    }
    return b"".join(out), truth


def _check(data: bytes, truth: dict, cuts: list[int]) -> None:
    p = StreamParser()
    rows, msgs = [], []
    prev = 0
    for c in sorted({min(max(c, 0), len(data)) for c in cuts}) + [len(data)]:
        rr, mm = p.feed(data[prev:c])
        rows += rr
        msgs += mm
        prev = c
    assert [r[0] for r in rows] == truth["received"]
    if rows:  # unwrapped from the first sample received: strictly increasing, exact differences
        first = (truth["t0"] + 1000 * truth["received"][0]) % WRAP_US
        assert [r[1] for r in rows] == [first + 1000 * (s - truth["received"][0]) for s in truth["received"]]
    assert p.stats.dropped == truth["dropped"]
    assert p.stats.corrupted == truth["corrupted"]
    assert p.stats.overruns == truth["overruns"]
    assert len(msgs) == truth["messages"]
    assert p.stats.samples == len(truth["received"])


@settings(max_examples=STRUCTURED_EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(0, 40),
    p_fault=st.sampled_from([0.0, 0.05, 0.2, 0.4]),
    cuts=st.lists(st.integers(0, 3000), max_size=8),
)
def test_fuzz_stream_counts_exactly(seed, n, p_fault, cuts):
    data, truth = _build_stream(random.Random(seed), n, p_fault)
    _check(data, truth, cuts)


@pytest.mark.slow  # 750 fuzzed streams; the default suite keeps the structured and byte-level fuzzing
@settings(max_examples=FUZZ_EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), p_fault=st.floats(0.0, 0.3))
def test_fuzz_many_streams_per_example(seed, p_fault):
    r = random.Random(seed)
    for _ in range(STREAMS_PER_EXAMPLE):
        data, truth = _build_stream(r, r.randint(0, 40), p_fault)
        cuts = [r.randrange(len(data) + 1) for _ in range(r.randint(0, 10))]
        _check(data, truth, cuts)


@settings(max_examples=500, deadline=None)
@given(st.binary(max_size=300), st.lists(st.integers(0, 300), max_size=5))
def test_arbitrary_bytes_never_crash(data, cuts):
    p = StreamParser()
    prev = 0
    for c in sorted(set(cuts)) + [len(data)]:
        c = min(c, len(data))
        p.feed(data[prev:c])
        prev = max(prev, c)
    assert p.stats.dropped >= 0 and p.stats.corrupted >= 0
    assume(True)


def test_total_fuzzed_streams_is_at_least_ten_thousand():
    assert STRUCTURED_EXAMPLES + FUZZ_EXAMPLES * STREAMS_PER_EXAMPLE >= 10_000


def test_impossible_step_counts_are_rejected_and_counted():
    """A bit error that survives the checksum can still describe the impossible: reject and count it."""
    p = StreamParser(max_step_rate_hz=2000.0)
    p.steps_range = [(0, 78)]
    lines = [
        frame("D,0,1000,600,10"),
        frame("D,1,2000,600,11"),  # 1 step in 1 ms: fine
        frame("D,2,3000,600,58"),  # 47 steps in 1 ms: faster than 2000 steps/s allows
        frame("D,3,4000,600,12"),
        frame("D,4,5000,600,99"),  # outside what the programme can reach
        frame("D,5,6000,600,12"),
    ]
    rows, _ = p.feed(b"".join(lines))
    assert [r[0] for r in rows] == [0, 1, 3, 5]
    assert p.stats.implausible == 2 and p.stats.dropped == 2 and p.stats.corrupted == 0
    plain = StreamParser()  # no limits given: nothing is judged
    rows, _ = plain.feed(b"".join(lines))
    assert len(rows) == 6 and plain.stats.implausible == 0


def test_a_step_while_the_programme_makes_none_is_rejected_and_counted():
    """Steps happen only inside the programme's segments; a count that changes in a dwell is impossible."""
    p = StreamParser(max_step_rate_hz=2000.0)
    p.step_windows = [(np.array([2_000, 9_000]), np.array([4_000, 10_000]))]  # two segments, a dwell between
    lines = [
        frame("D,0,1000,600,0"),
        frame("D,1,3000,600,2"),  # inside the first segment
        frame("D,2,5000,600,3"),  # changed in (3000, 5000]: overlaps the segment ending at 4000: fine
        frame("D,3,7000,600,4"),  # changed in (5000, 7000]: the dwell
        frame("D,4,8000,600,3"),  # unchanged since the last accepted sample: fine
        frame("D,5,9500,600,5"),  # inside the second segment
    ]
    rows, _ = p.feed(b"".join(lines))
    assert [r[0] for r in rows] == [0, 1, 2, 4, 5]
    assert p.stats.implausible == 1 and p.stats.dropped == 1


def test_step_windows_cover_every_step_of_a_programme_and_no_dwell():
    from helpers.board.programmes import Dwell, Programme, Segment
    from helpers.rig.driver import GO_LATENCY_US, step_windows

    prog = Programme((Dwell(1000), Segment(1, 10, 1000), Dwell(500), Segment(-1, 10, 2000)))
    [(starts, ends)] = step_windows(prog, 1)
    starts, ends = starts + 100_000, ends + 100_000  # GO at 100 ms of device time
    times, _ = prog.step_times_us()[0]
    for t in times + 100_000:  # every step of the programme lies in a window
        i = np.searchsorted(starts, t, side="right") - 1
        assert i >= 0 and t <= ends[i]
    assert starts[0] == 100_000 + 1_001_000 - GO_LATENCY_US and len(starts) == 2
    assert ends[0] < 100_000 + 1_000_000 + 10_000 + 500_000  # the dwell between the segments stays closed


def test_several_axes_are_judged_each_on_its_own():
    """Two axes: axis 1 steps only in its window; a count of axis 0 that moves there is impossible."""
    p = StreamParser(channels=2, axes=2, max_step_rate_hz=2000.0)
    p.steps_range = [(0, 0), (-78, 156)]  # axis 0 holds still; axis 1 may pay out and pull
    p.step_windows = [(np.array([], dtype=np.int64),) * 2, (np.array([2_000]), np.array([6_000]))]
    lines = [
        frame("D,0,1000,600,601,0,0"),
        frame("D,1,3000,600,601,0,-2"),  # axis 1 in its window
        frame("D,2,4000,600,601,1,-2"),  # axis 0 moved: outside its range
        frame("D,3,5000,600,601,0,-60"),  # axis 1: 58 steps in 2 ms, faster than 2000 steps/s
        frame("D,4,7000,600,601,0,-3"),  # axis 1 moved in (5000, 7000]: its window ends at 6000: fine
        frame("D,5,9000,600,601,0,-4"),  # axis 1 moved outside its window
    ]
    rows, _ = p.feed(b"".join(lines))
    assert [r[0] for r in rows] == [0, 1, 4]
    assert p.stats.implausible == 3 and rows[-1] == (4, 7000, 600, 601, 0, -3)
    assert p.stats.dropped == 2  # seq 2 and 3 before the last one accepted (seq 5's gap is known at STOP)


def test_frame_command_prints_what_to_type(capsys):
    from helpers.__main__ import main

    assert main(["frame", "PING", "RATE 500"]) == 0
    assert capsys.readouterr().out == "PING*79\nRATE 500*7A\n"  # PROTOCOL.md's examples
    assert main(["frame", "A*B"]) == 2
    assert "cannot frame" in capsys.readouterr().err
