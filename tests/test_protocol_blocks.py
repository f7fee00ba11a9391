"""The DAQ's lines in blocks against line by line: the same bytes, rows and counts.

The emulated board frames a chunk of samples at once (``helpers.virtual.emulator.framing``) and the host
checks a read at once (``helpers.board.protocol.unframe``); both must give exactly what the line-by-line
protocol gives. The expected bytes come from the bitwise reference CRC (``crc_reference``), and the parser is
compared with the line-by-line parser of the same rules (:class:`LineByLine`: every line through
``line_reference``'s ``unframe`` and ``parse_body`` and every data line placed on its own, as the parser did
before blocks) on random streams with every kind of damage, every channel count and any chunking.
"""

from __future__ import annotations

import random

import numpy as np
import pytest
from crc_reference import link_hex, xor_hex
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from line_reference import check_line

from helpers.board.protocol import MAX_DIGITS, MAX_PENDING, WRAP_US, StreamParser, crc8_spans, unframe
from helpers.virtual.emulator.framing import frame_data_lines


def _reference_line(row: list[int]) -> bytes:
    body = "D," + ",".join(str(v) for v in row)
    return f"{body}*{link_hex(body)}\n".encode()


class LineByLine(StreamParser):
    """The parser as it was before blocks, the reference: every line checked on its own (``unframe``,
    ``parse_body``) and every data line placed on its own (its checks as the parser made them, row by row)."""

    def feed(self, data: bytes) -> tuple[list[tuple[int, ...]], list[str]]:
        samples: list[tuple[int, ...]] = []
        messages: list[str] = []
        self._buf += data
        parts = self._buf.split(b"\n")
        rest = parts.pop()
        lines = [bytes(p) for p in parts]
        if len(rest) > MAX_PENDING:
            lines.append(bytes(rest))
            rest = b""
        self._buf = bytearray(rest)
        for line in lines:
            check_line(self, line, samples, messages)
        return samples, messages

    def _place(self, values: np.ndarray, out: list) -> None:
        for sample in values.tolist():
            if self.last_seq is not None and sample[0] <= self.last_seq:
                self.stats.corrupted += 1
            else:
                self._accept(tuple(sample), out)

    def _accept(self, sample: tuple[int, ...], out: list) -> None:
        wrapped = self._last_raw_t is not None and sample[1] < self._last_raw_t
        offset = 0 if self._last is None else self._last[0] - self._last_raw_t
        seq, t_us = sample[0], sample[1] + offset + (WRAP_US if wrapped else 0)
        steps = sample[2 + self.channels :]
        if not self._plausible(t_us, steps):
            self.stats.implausible += 1
            return
        self._last_raw_t = sample[1]  # the clock moves on with a placed one
        self.stats.dropped += seq - (0 if self.last_seq is None else self.last_seq + 1)
        self.last_seq = seq
        self.stats.samples += 1
        self._last = (t_us, steps)
        out.append((seq, t_us, *sample[2:]))

    def _plausible(self, t_us: int, steps: tuple[int, ...]) -> bool:
        for a, n in enumerate(steps):
            if self.steps_range is not None and not self.steps_range[a][0] <= n <= self.steps_range[a][1]:
                return False
            if self._last is None or n == self._last[1][a]:
                continue
            t_last, rate = self._last[0], self.max_step_rate_hz
            if rate is not None and abs(n - self._last[1][a]) > rate * max(t_us - t_last, 0) * 1e-6 + 1:
                return False
            if self.step_windows is not None:
                starts, ends = self.step_windows[a]
                i = int(np.searchsorted(starts, t_us, side="right")) - 1
                if i < 0 or ends[i] < t_last:
                    return False
        return True


# --- the emulator's side: framing ---------------------------------------------------------------------------
@pytest.mark.parametrize("tendons", [1, 2, 3, 4])
def test_a_block_of_data_lines_is_the_lines_framed_one_by_one(tendons):
    r = np.random.default_rng(tendons)
    n = 400
    seq = np.sort(r.integers(0, 10**6, n))
    t_us = r.integers(0, WRAP_US, n)
    t_us[:3] = [0, 9, WRAP_US - 1]
    counts = r.integers(0, 1024, (n, tendons))
    counts[0] = 0
    steps = r.integers(-20_000, 20_000, (n, tendons)) // r.choice([1, 10, 1000], (n, tendons))
    steps[1], steps[2] = 0, -1  # zero, minus one
    fields = np.column_stack([seq, t_us, counts, steps])
    assert (fields < 0).any() and (fields == 0).any()
    assert frame_data_lines(fields) == b"".join(_reference_line(row) for row in fields.tolist())
    assert frame_data_lines(fields[:1]) == _reference_line(fields[0].tolist())
    assert frame_data_lines(fields[:0]) == b""


@settings(max_examples=200, deadline=None)
@given(st.lists(st.binary(min_size=0, max_size=64), min_size=1, max_size=20), st.binary(max_size=30))
def test_the_crc_of_many_spans_at_once_is_the_crc_of_each(spans, gap):
    """Spans of 0-64 bytes with bytes between them: the CRC of each as the bitwise reference gives it."""
    data = gap + b"".join(x + gap for x in spans)
    lengths = np.array([len(x) + len(gap) for x in spans])
    starts = len(gap) + np.concatenate([[0], np.cumsum(lengths)[:-1]])
    got = crc8_spans(np.frombuffer(data, np.uint8), starts, starts + [len(x) for x in spans])
    assert [f"{x:02X}" for x in got.tolist()] == [link_hex(x) for x in spans]


# --- the host's side: scanning and the parser ---------------------------------------------------------------
def test_a_read_is_checked_at_once_as_each_of_its_lines_alone():
    good = [
        _reference_line([5, 1000, 512, -3]),
        _reference_line([6, 2000, 0, 0]),
        _reference_line([7, 3, 9, -0]),
        _reference_line([12, 5, 5, 1]).replace(b"\n", b"\r\n"),  # a \r before the \n is ignored
    ]
    other = [
        b"OK STOP 7*" + link_hex("OK STOP 7").encode() + b"\n",  # a reply
        _reference_line([8, 4000, 1024, 1]),  # a count beyond the ADC
        _reference_line([9, WRAP_US, 5, 1]),  # a time beyond the clock
        _reference_line([10 ** (MAX_DIGITS + 1), 5, 5, 1]),  # valid: read as a Python int
        _reference_line([10**MAX_DIGITS - 1] * 3 + [1 - 10**MAX_DIGITS]),  # a data line's shape, 70 bytes
        _reference_line([11, 5, 5, 1])[:-4] + b"00\n",  # "*hh" lost: no checksum
        _reference_line([12, 5, 5, 1]).replace(b"\n", b"\r\r\n"),  # two: the \r is the line's
        b"D,18,5,5,1\r*" + link_hex("D,18,5,5,1\r").encode() + b"\n",  # a \r inside the line: a control byte
        b"D,13,5,5,1*" + xor_hex("D,13,5,5,1").encode() + b"\n",  # protocol 1's checksum
        b"D,14,5,5*" + link_hex("D,14,5,5").encode() + b"\n",  # a field short
        b"D,15,5,-5,1*" + link_hex("D,15,5,-5,1").encode() + b"\n",  # a negative count
        b"D,16,5,5,1-*" + link_hex("D,16,5,5,1-").encode() + b"\n",  # a minus inside a field
        b"D,17,,5,1*" + link_hex("D,17,,5,1").encode() + b"\n",  # an empty field
        b"\n",
    ]
    data = b"".join(good + other + good[:1])
    starts, stars, ok, unframed = unframe(data)
    assert unframed == 4  # 70 bytes, no checksum, two \r, a \r inside (the blank line is not counted)
    bodies = [data[a:b] for a, b in zip(starts.tolist(), stars.tolist(), strict=True)]
    assert bodies == [
        line.rstrip(b"\r\n").rpartition(b"*")[0] for line in good + other[:4] + other[8:-1] + good[:1]
    ]
    assert ok.tolist() == [True] * 8 + [False] + [True] * 5  # protocol 1's checksum
    parser, reference = StreamParser(), LineByLine()
    assert parser.feed(data) == reference.feed(data) and parser.stats == reference.stats
    rows, messages = StreamParser().feed(data)
    w = WRAP_US  # the clock wrapped before seq 7
    assert rows == [
        (5, 1000, 512, -3),
        (6, 2000, 0, 0),
        (7, w + 3, 9, 0),
        (12, w + 5, 5, 1),
        (10**16, w + 5, 5, 1),
    ]
    assert messages == ["OK STOP 7"] and parser.stats.corrupted == len(other) - 3 + 1  # the last: seq 5 again


_HEX = "0123456789ABCDEF"


def _body_line(body: str, r: random.Random) -> bytes:
    """``body`` framed, mostly with the right CRC-8, sometimes with a wrong one or protocol 1's XOR."""
    x = r.random()
    check = link_hex(body) if x < 0.9 else xor_hex(body) if x < 0.95 else r.choice(_HEX) + r.choice(_HEX)
    return f"{body}*{check}\n".encode()


def _damage(line: bytes, r: random.Random) -> bytes:
    b = bytearray(line[:-1])
    how = r.choice(["flip", "truncate", "insert", "delete", "newline", "cr"])
    i = r.randrange(len(b) + 1)
    if how == "flip" and b:
        b[min(i, len(b) - 1)] ^= 1 << r.randrange(8)
    elif how == "truncate":
        del b[i:]
    elif how == "insert":
        b[i:i] = bytes([r.choice(b"0123456789,-*D\r\xff ")])
    elif how == "delete" and b:
        del b[min(i, len(b) - 1)]
    elif how == "newline":  # the line broken in two
        b[i:i] = b"\n"
    elif how == "cr":
        b += b"\r"
    return bytes(b) + b"\n"


def _stream(r: random.Random, channels: int, axes: int, n: int) -> bytes:
    """Data lines with gaps, repeats and jumps of ``seq``, clock wraps, steps that jump, and every fault."""
    out = []
    seq, t = r.randrange(1000), r.choice([0, WRAP_US - 3000, r.randrange(WRAP_US)])
    steps = [r.randint(-50, 50) for _ in range(axes)]
    for _ in range(n):
        seq += r.choice([1] * 20 + [0, 2, 3, -1, -5, 40])
        t = (t + r.choice([1000] * 20 + [0, 500, 7000, -1000])) % WRAP_US
        for a in range(axes):
            steps[a] += r.choice([0] * 10 + [1, -1, 2, -2, 60, -300])
        counts = [r.choice([r.randrange(1024), 0, 1023, 1024, 99999]) for _ in range(channels)]
        fields = [max(seq, 0), t, *counts, *steps]
        if r.random() < 0.02:
            fields[r.randrange(len(fields))] = r.choice([10**15, 10**16 + 7, -(10**15), 10**30, 10**15 - 1])
        if r.random() < 0.01:  # every field of a data line's shape at its longest: beyond the longest line
            fields = [10**MAX_DIGITS - 1] * (len(fields) - axes) + [1 - 10**MAX_DIGITS] * axes
        if r.random() < 0.03:  # a field too many or too few
            fields = fields[:-1] if r.random() < 0.5 else [*fields, 1]
        text = [str(v) for v in fields]
        if r.random() < 0.02:
            i = r.randrange(len(text))
            text[i] = r.choice(["0" + text[i], "-0", "", "-", "+1", " 1", "1e3", "x"])
        body = "D," + ",".join(text)
        line = _body_line(body, r) if len(body) <= 60 or r.random() < 0.5 else (body + "*00\n").encode()
        if r.random() < 0.08:
            line = _damage(line, r)
        if r.random() < 0.03:
            continue  # lost
        out.append(line)
        x = r.random()
        if x < 0.03:
            out.append(
                _body_line(
                    r.choice(
                        [
                            "OK STOP 5",
                            "HELLO daq 2.3.0 481e87e3",
                            "PONG daq 1.0.0",
                            "N,LIMIT,1",
                            "W,OVERRUN,3",
                            "W,OVERRUN,x",
                            "ERR CHECKSUM",
                        ]
                    ),
                    r,
                )
            )
        elif x < 0.04:
            out.append(
                r.choice([b"\n", b"\r\n", b"\r", bytes(r.randrange(256) for _ in range(r.randrange(80)))])
            )
        elif x < 0.045:
            out.append(b"x" * r.randrange(MAX_PENDING - 5, 3 * MAX_PENDING))
    return b"".join(out)


def _parsers(r: random.Random, channels: int, axes: int) -> tuple[StreamParser, StreamParser]:
    rate = r.choice([None, 2000.0, 2000, 150.5, 1e6])
    adc_max = r.choice([1023, 4095, 600])
    ranges = r.choice([None, [(r.randint(-400, 0), r.randint(0, 400)) for _ in range(axes)]])
    windows = None
    if r.random() < 0.5:
        windows = []
        for _ in range(axes):
            edges = np.cumsum([r.randrange(WRAP_US // 50) for _ in range(2 * r.randrange(6))])
            windows.append((edges[0::2], edges[1::2]))
    parsers = (StreamParser(channels, axes, rate, adc_max), LineByLine(channels, axes, rate, adc_max))
    for p in parsers:
        p.steps_range, p.step_windows = ranges, windows
    return parsers


def _same(data: bytes, blocks: StreamParser, lines: StreamParser, r: random.Random) -> None:
    cuts = sorted(r.randrange(len(data) + 1) for _ in range(r.randrange(6)))
    for a, b in zip([0, *cuts], [*cuts, len(data)], strict=True):
        assert blocks.feed(data[a:b]) == lines.feed(data[a:b])
        assert blocks.stats == lines.stats and blocks._buf == lines._buf  # the unfinished line held back
        assert blocks.legacy == lines.legacy and blocks.last_seq == lines.last_seq


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), channels=st.integers(1, 4), n=st.integers(0, 300))
def test_blocks_give_the_rows_and_counts_of_line_by_line(seed, channels, n):
    r = random.Random(seed)
    axes = channels if r.random() < 0.8 else r.randint(1, 4)
    data = _stream(r, channels, axes, n)
    blocks, lines = _parsers(r, channels, axes)
    _same(data, blocks, lines, r)
    # restarted (a new START) with the buffer kept: still the same
    blocks.restart(), lines.restart()
    _same(_stream(r, channels, axes, n // 3), blocks, lines, r)


def test_the_fuzzed_streams_exercise_every_outcome():
    """The comparison above sees every count move and rows both placed and refused."""
    seen = {
        "samples": 0,
        "dropped": 0,
        "corrupted": 0,
        "implausible": 0,
        "overruns": 0,
        "legacy": 0,
        "msgs": 0,
    }
    r = random.Random(7)
    for _ in range(60):
        c = r.randint(1, 4)
        blocks, lines = _parsers(r, c, c)
        data = _stream(r, c, c, 200)
        rows, msgs = blocks.feed(data)
        assert (rows, msgs) == lines.feed(data) and blocks.stats == lines.stats
        for k in ("samples", "dropped", "corrupted", "implausible", "overruns"):
            seen[k] += getattr(blocks.stats, k) > 0
        seen["legacy"] += blocks.legacy is not None
        seen["msgs"] += len(msgs) > 0
    assert all(v > 0 for v in seen.values()), seen


def test_an_emulated_stream_is_read_whole_by_the_scan():
    """Undamaged, the DAQ's own lines never leave the fast path, across the clock's wrap, for 1-4 channels."""
    for c in range(1, 5):
        n = 300
        t_us = (WRAP_US - 150_000 + 1000 * np.arange(n)) % WRAP_US
        steps = np.arange(n * c).reshape(n, c) // 7 - 20
        fields = np.column_stack([np.arange(n), t_us, np.full((n, c), 511), steps])
        data = frame_data_lines(fields)
        starts, stars, ok, unframed = unframe(data)
        assert ok.all() and unframed == 0 and np.array_equal(stars, unframe(data, shaped=True)[1])
        p = StreamParser(c, c, 2000.0)
        rows, msgs = p.feed(data)
        assert msgs == [] and len(rows) == n and p.stats.samples == n and p.stats.corrupted == 0
        assert [r[1] for r in rows] == (WRAP_US - 150_000 + 1000 * np.arange(n)).tolist()
        assert rows[-1] == (n - 1, WRAP_US - 150_000 + 1000 * (n - 1), *[511] * c, *(fields[-1, 2 + c :]))


@pytest.mark.parametrize("big", [10**15, 2**53 + 1, 2**63 - 1, -(2**63), 10**30, -(10**40)])
def test_a_count_of_any_size_is_placed_and_judged_exactly(big):
    """A step count the scan cannot read (over 15 digits) is placed as a block of one, exactly; scanned rows
    after it are judged against it exactly (int64's extremes included, where a difference overflows)."""
    lines = [
        _reference_line([0, 1000, 5, big]),  # the first sample ever: judged by its range only
        _reference_line([1, 2000, 5, big + 1]),  # one step in 1 ms: plausible at 2 kHz
        _reference_line([2, 3000, 5, 1]),  # scanned: a jump from big (2**63 from int64's least), implausible
        _reference_line([3, 4000, 5, big + 3]),  # two steps in 2 ms: plausible
        _reference_line([4, 5000, 5, big + 7]),  # four steps in 1 ms: implausible
        _reference_line([5, 6000, 5, big + 4]),
        _reference_line([6, 7000, 5, 3]),
    ]
    data = b"".join(lines)
    for rate in (2000.0, None):
        blocks, lines_ = StreamParser(1, 1, rate), LineByLine(1, 1, rate)
        got = blocks.feed(data)
        assert got == lines_.feed(data) and blocks.stats == lines_.stats
        assert [r[3] for r in got[0]] == (
            [big, big + 1, big + 3, big + 4] if rate else [big, big + 1, 1, big + 3, big + 7, big + 4, 3]
        )
