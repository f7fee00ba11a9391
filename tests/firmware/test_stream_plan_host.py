"""The firmware's streaming planner (firmware/common/stream_plan.cpp), compiled for the host with g++, against
``helpers.board.stream_reference.Planner`` on random shapers and set-point sequences: the same step ticks,
directions,
notices and final state, integer for integer (fast; the simavr tests check the board itself)."""

from __future__ import annotations

import random
import shutil
import subprocess

import fwsim
import pytest

from helpers.board import stream_reference as hs

pytestmark = [pytest.mark.firmware, pytest.mark.streaming]

KINDS = {"LIMIT,SPEED": 1, "LIMIT,TRAVEL": 2}


@pytest.fixture(scope="module")
def planner_c(tmp_path_factory):
    gxx = shutil.which("g++")
    if gxx is None:
        pytest.skip("g++ is missing: apt-get install -y g++")
    exe = tmp_path_factory.mktemp("stream") / "stream_host_test"
    common = fwsim.FIRMWARE / "common"
    subprocess.run(
        [gxx, "-O1", "-Wall", "-Wextra", "-Werror", "-I", str(common), "-o", str(exe)]
        + [str(common / "stream_host_test.cpp"), str(common / "stream_plan.cpp")],
        check=True,
        capture_output=True,
        text=True,
    )
    proc = subprocess.Popen([str(exe)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)

    def plan(shaper: hs.StreamShaper, position: int, v: list[int]) -> str:
        assert proc.stdin is not None and proc.stdout is not None
        parts = [len(shaper.amplitudes)]
        for a, d in zip(shaper.amplitudes, shaper.delays_delta, strict=True):
            parts += [a, d]
        parts += [position, len(v), *v]
        proc.stdin.write(" ".join(map(str, parts)) + "\n")
        proc.stdin.flush()
        return proc.stdout.readline().strip()

    yield plan
    proc.stdin.close()
    proc.wait(timeout=5)


def reference(shaper: hs.StreamShaper, position: int, v: list[int]) -> str:
    p = hs.Planner(shaper, position)
    for k, vk in enumerate(v, start=1):
        p.plan_period(k, vk)
    steps = "".join(f" {t % 2**32}:{d}" for t, d in zip(p.ticks, p.dirs, strict=True))
    notices = "".join(f" {KINDS[n.kind]}:{n.value}" for n in p.notices)
    return f"S{steps} N{notices} E {p.c} {p.r}"


def random_case(r: random.Random) -> tuple[hs.StreamShaper, int, list[int]]:
    n = r.randint(1, 8)
    negative = r.random() < 0.3
    while True:  # amplitudes normalised to sum 1 (a negative one now and then), delays in DELTA
        span = r.choice([200, 5000, 62500])
        delays = [0, *sorted(r.sample(range(1, span + 1), n - 1))]
        weights = [
            r.uniform(0.05, 1.0) * (-0.5 if negative and i and r.random() < 0.4 else 1) for i in range(n)
        ]
        try:
            shaper = hs.StreamShaper.quantise(weights, [d * 16e-6 for d in delays], negative)
        except ValueError:
            continue
        if len(shaper.amplitudes) == n:
            break
    top = r.choice([7, 100, 800, hs.V_MAX])
    v = [r.randint(-top, top) if r.random() < 0.7 else 0 for _ in range(r.randint(1, 120))]
    if r.random() < 0.2:
        v = [r.choice([-hs.V_MAX, hs.V_MAX])] * len(v)
    return shaper, r.randint(0, hs.TRAVEL_MAX), v


def _compare(planner_c, n: int, seed: int) -> None:
    r = random.Random(seed)
    for i in range(n):
        shaper, position, v = random_case(r)
        assert planner_c(shaper, position, v) == reference(shaper, position, v), f"case {i}: {shaper}"


def test_host_build_of_the_planner_matches_the_reference(planner_c):
    _compare(planner_c, 500, seed=11)


@pytest.mark.slow
def test_host_build_of_the_planner_matches_the_reference_long(planner_c):
    _compare(planner_c, 20000, seed=12)
