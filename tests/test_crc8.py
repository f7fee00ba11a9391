"""The link's CRC-8 (``helpers.board.crc8``, firmware/PROTOCOL.md): variant, choice of polynomial,
guarantees, fuzz.

Expected values come from ``crc_reference`` (a table-free implementation anchored to published catalogue
check values), never from the code under test. The fuzz compares the XOR of protocol 1 with the CRC-8 on
realistic lines; run this file as a script for the figures quoted in PROTOCOL.md::

    python tests/test_crc8.py 200000
"""

from __future__ import annotations

import random
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from crc_reference import CATALOGUE, LINK, LINK_CHECK, crc_rocksoft, link_hex, xor_hex

from helpers.board import crc8 as hc
from helpers.board.protocol import unframe

HEX = "0123456789ABCDEF"
Checksum = Callable[[str], str]


# --- the variant ------------------------------------------------------------------------------------------
def test_reference_reproduces_the_published_catalogue_check_values():
    for name, (poly, init, refin, refout, xorout, check) in CATALOGUE.items():
        got = crc_rocksoft(b"123456789", poly=poly, init=init, refin=refin, refout=refout, xorout=xorout)
        assert got == check, name


def test_variant_and_check_value():
    assert (hc.POLY, hc.INIT, hc.REFLECTED, hc.XOROUT) == (
        LINK["poly"],
        LINK["init"],
        LINK["refin"] and LINK["refout"],
        LINK["xorout"],
    )
    assert hc.crc8(b"123456789") == hc.CHECK == LINK_CHECK == 0x20


def test_table_driven_crc_matches_the_bitwise_reference():
    r = random.Random(1)
    cases = [bytes([b]) for b in range(256)] + [r.randbytes(r.randint(0, 80)) for _ in range(500)]
    for data in cases:
        assert hc.crc8(data) == int(link_hex(data), 16)


def _polymod(a: int, g: int) -> int:
    while a.bit_length() >= g.bit_length():
        a ^= g << (a.bit_length() - g.bit_length())
    return a


def test_polynomial_is_primitive():
    """x has order 255 modulo g: g is primitive, so two flips closer than 255 bits are always detected."""
    g = 0x100 | LINK["poly"]
    orders = [k for k in range(1, 256) if _polymod(1 << k, g) == 1]
    assert orders[0] == 255


def test_polynomial_choice_hex_digits():
    """Of the 16 primitive polynomials of degree 8, 0x65 keeps every 2-bit error in body + ``*hh`` detectable
    longest (bodies up to 20 bytes): a flip in the body can cancel one that turns a hex digit into another."""

    def order(p: int) -> int:
        return min(k for k in range(1, 256) if _polymod(1 << k, 0x100 | p) == 1)

    primitive = [p for p in range(1, 256, 2) if order(p) == 255]
    assert len(primitive) == 16
    deltas = set()  # value changes of a hex digit hit by one bit flip that leaves an upper-case hex digit
    for d, c in enumerate(HEX):
        for b in range(8):
            flipped = chr(ord(c) ^ (1 << b))
            if flipped in HEX:
                deltas |= {d ^ HEX.index(flipped), (d ^ HEX.index(flipped)) << 4}

    def first_bad_length(poly: int) -> int:
        for n in range(1, 61):
            base = crc_rocksoft(bytes(n), poly=poly, init=0xFF, refin=True, refout=True, xorout=0)
            for i in range(8 * n):
                e = bytearray(n)
                e[i // 8] ^= 1 << (i % 8)
                d = crc_rocksoft(bytes(e), poly=poly, init=0xFF, refin=True, refout=True, xorout=0) ^ base
                if d in deltas:
                    return n
        return 61

    lengths = {p: first_bad_length(p) for p in primitive}
    assert lengths[LINK["poly"]] == 21 == max(lengths.values())


# --- the host's check of one line, mirrored with either checksum ------------------------------------------
def accepts(fragment: bytes, checksum: Checksum) -> str | None:
    """The body the host accepts from one line under PROTOCOL.md's rules with ``checksum``, or None."""
    if fragment.endswith(b"\r"):
        fragment = fragment[:-1]
    if len(fragment) > 63:
        return None
    try:
        text = fragment.decode("ascii")
    except UnicodeDecodeError:
        return None
    if not text.isprintable():
        return None
    body, star, given = text.rpartition("*")
    if not star or "*" in body or len(given) != 2 or any(c not in HEX for c in given):
        return None
    return body if checksum(body) == given else None


def received(damaged: bytes, checksum: Checksum) -> list[str]:
    """Bodies accepted from a damaged line, which a byte turned into ``\\n`` may have split in two."""
    out = []
    for fragment in damaged.split(b"\n"):
        if fragment.strip(b"\r") and (body := accepts(fragment, checksum)) is not None:
            out.append(body)
    return out


def received_by_the_host(damaged: bytes) -> list[str]:
    """The same with the code under test (``helpers.board.protocol.unframe``, every fragment at once)."""
    starts, stars, good, _ = unframe(damaged + b"\n")
    spans = zip(starts.tolist(), stars.tolist(), good.tolist(), strict=True)
    return [damaged[a:b].decode("ascii") for a, b, ok in spans if ok]


def damage(line: bytes, positions: list[int]) -> bytes:
    """Flip the given bits; bit p is bit p % 8 of byte p // 8 (least significant first, as the UART sends)."""
    b = bytearray(line)
    for p in positions:
        b[p // 8] ^= 1 << (p % 8)
    return bytes(b)


# --- realistic lines --------------------------------------------------------------------------------------
REPLIES = [
    "HELLO daq 2.0.0",
    "PONG stepper 2.0.0",
    "OK RATE 1000",
    "OK START 1000",
    "OK STOP 123456",
    "OK ZERO",
    "W,OVERRUN,3",
    "OK CLEAR",
    "OK SEG 12",
    "OK WAIT 64",
    "OK GO 5",
    "DONE 156",
    "ABORTED 78",
    "OK EN 1",
    "OK POS 156",
    "ERR CHECKSUM bad checksum",
    "ERR TOOLONG line over 63 characters",
    "ERR UNKNOWN command",
    "ERR ARG SEG needs 3 integers",
    "ERR RANGE interval 639-1000000 us",
    "ERR STATE programme empty",
    "ERR RANGE travel 0-156 steps",
    "ERR FULL 64 items",
]


def data_bodies(r: random.Random, n: int) -> list[str]:
    """DAQ data lines ``D,<seq>,<t_us>,<adc>,<steps>`` of 16-28 bytes on the wire (``*hh\\n`` included)."""
    out: list[str] = []
    while len(out) < n:
        seq = r.randrange(10 ** r.randint(1, 6))
        t_us = r.randrange(10 ** r.randint(4, 9))
        body = f"D,{seq},{t_us},{r.randrange(1024)},{r.randrange(-40, 160)}"
        if 16 <= len(body) + 4 <= 28:
            out.append(body)
    return out


def framed(body: str, checksum: Checksum) -> bytes:
    return f"{body}*{checksum(body)}".encode()


# --- exhaustive guarantees --------------------------------------------------------------------------------
def test_the_mirrored_check_agrees_with_the_host():
    r = random.Random(2)
    for body in data_bodies(r, 30) + REPLIES:
        line = framed(body, link_hex)
        for _ in range(200):
            bits = r.sample(range(8 * len(line)), r.randint(1, 3))
            d = damage(line, bits)
            assert received(d, link_hex) == received_by_the_host(d)


def test_no_line_holds_the_byte_one_flip_away_from_a_newline():
    """``J`` and ``*`` are one bit flip from ``\\n``: no body may contain them (PROTOCOL.md)."""
    for body in REPLIES + data_bodies(random.Random(3), 200):
        assert "J" not in body and "*" not in body


def test_every_single_bit_error_is_detected():
    for body in data_bodies(random.Random(4), 40) + REPLIES:
        line = framed(body, link_hex)
        for i in range(8 * len(line)):
            assert all(b == body for b in received_by_the_host(damage(line, [i]))), (body, i)


def _burst_patterns(length: int) -> list[list[int]]:
    """Every burst of exactly ``length`` bits: first and last flipped, anything in between."""
    inner = length - 2
    return [[0, length - 1] + [1 + k for k in range(inner) if m >> k & 1] for m in range(1 << inner)]


BURST_LINES = [
    "D,0,1000,5,0",
    "D,99999,4294967295,1023,-40",
    "ERR RANGE interval 639-1000000 us",
    ("SEG -1 156 1000000 " * 4)[:60],
]


@pytest.mark.parametrize("body", BURST_LINES)
def test_every_burst_of_up_to_8_bits_that_leaves_the_line_whole_is_detected(body):
    line = framed(body, link_hex)
    for length in range(1, 9):
        for pattern in _burst_patterns(length) if length > 1 else [[0]]:
            for start in range(8 * len(line) - length + 1):
                d = damage(line, [start + p for p in pattern])
                wrong = [b for b in received_by_the_host(d) if b != body]
                if b"\n" not in d:
                    assert not wrong, (body, length, start, pattern)
                else:  # the line was cut in two: only an intact tail of the body can pass its own check
                    assert all(body.endswith(w) for w in wrong), (body, length, start, pattern)


@pytest.mark.slow  # single-bit errors and bursts up to 8 bits: the default suite
def test_two_bit_errors():
    """Data lines (bodies <= 20 bytes, whose bytes are all >= 3 flips from '\\n'): every 2-bit error anywhere;
    bodies <= 30 bytes: every 2-bit error inside the body; 60 bytes: only flips exactly 255 bits apart."""
    r = random.Random(6)
    short = [b for b in data_bodies(r, 400) if len(b) <= 20][:12] + ["D,99999,429496729,1023"[:20]]
    for body in short:
        line = framed(body, link_hex)
        n = 8 * len(line)
        for i in range(n):
            for j in range(i + 1, n):
                assert all(b == body for b in received_by_the_host(damage(line, [i, j]))), (body, i, j)
    alphabet = "0123456789,-D"
    for n_bytes in (30, 60):
        body = "D" + "".join(r.choice(alphabet) for _ in range(n_bytes - 1))
        line = framed(body, link_hex)
        missed = set()
        for i in range(8 * n_bytes):
            for j in range(i + 1, 8 * n_bytes):
                if any(b != body for b in received_by_the_host(damage(line, [i, j]))):
                    missed.add((i, j))
        assert all(j - i == 255 for i, j in missed)
        assert (len(missed) == 0) == (n_bytes <= 30)


# --- fuzz: XOR against CRC-8 ------------------------------------------------------------------------------
MODELS = ("1-bit", "2-bit", "burst 2-16")


def _errors(nbits: int, model: str, r: random.Random) -> list[int]:
    if model == "1-bit":
        return [r.randrange(nbits)]
    if model == "2-bit":
        return r.sample(range(nbits), 2)
    length = min(r.randint(2, 16), nbits)
    start = r.randrange(nbits - length + 1)
    return [start, start + length - 1] + [start + k for k in range(1, length - 1) if r.random() < 0.5]


def fuzz(trials: int, seed: int = 0) -> dict[tuple[str, str], dict[str, int]]:
    """Damage random realistic lines; count for each checksum the damaged lines the host would accept wrongly.

    For every (kind of line, error model) cell, ``trials`` lines get random errors; the same body and the same
    flipped bits are applied to its XOR-framed and its CRC-framed version (both end in two hex digits).
    An error is undetected when any piece of the damaged line (a byte may have become ``\\n``) passes the
    host's check with a body other than the one sent. Bursts: 2-16 bits long, first and last bit flipped.
    """
    r = random.Random(seed)
    out: dict[tuple[str, str], dict[str, int]] = {}
    for kind in ("data", "reply"):
        for model in MODELS:
            cell = {"trials": trials, "xor": 0, "crc": 0, "burst<=8 crc": 0}
            for _ in range(trials):
                body = data_bodies(r, 1)[0] if kind == "data" else r.choice(REPLIES)
                bits = _errors(8 * (len(body) + 3), model, r)
                for name, cs in (("xor", xor_hex), ("crc", link_hex)):
                    if any(b != body for b in received(damage(framed(body, cs), bits), cs)):
                        cell[name] += 1
                        if name == "crc" and model.startswith("burst") and max(bits) - min(bits) < 8:
                            cell["burst<=8 crc"] += 1
            out[(kind, model)] = cell
    return out


def format_fuzz(result: dict[tuple[str, str], dict[str, int]]) -> str:
    rows = ["| lines | errors | trials | XOR undetected | CRC-8 undetected |", "|---|---|---|---|---|"]
    for (kind, model), c in result.items():
        n = c["trials"]
        rows.append(
            f"| {kind} | {model} | {n} | {c['xor']} ({100 * c['xor'] / n:.2f} %) | "
            f"{c['crc']} ({100 * c['crc'] / n:.3f} %) |"
        )
    return "\n".join(rows)


def test_fuzz_crc_against_xor():
    result = fuzz(3000, seed=1)
    print("\n" + format_fuzz(result))
    for (_, model), c in result.items():
        if model == "1-bit":
            assert c["crc"] == 0
        if model == "burst 2-16":
            assert c["burst<=8 crc"] <= 2  # only bursts that turned a byte into '\n' can slip
        if model == "2-bit":
            assert c["xor"] > 10 * max(c["crc"], 1)  # XOR misses same-bit pairs; the CRC almost nothing
    assert result[("data", "2-bit")]["crc"] == 0


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 100_000
    print(f"python tests/test_crc8.py {n}  (seed 0)\n")
    print(format_fuzz(fuzz(n, seed=0)))
