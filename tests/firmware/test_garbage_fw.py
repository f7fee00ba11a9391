"""After a burst of garbage ends, a board answers PING within 1 s of device time (firmware in simavr, over
the harness's pseudo-terminal as a host sees it, and the emulated boards).

In simavr the harness feeds the UART at the baud rate (10 bits a byte), so the burst's last byte cannot reach
the board before ``start + bytes x 10 / baud``; one of the ``PING`` sent every 100 ms from then on (as the
host's synchronisation does; one sent while the board still drops bytes of its overflowing input may arrive
damaged) must be answered within 1 s of that, whatever the garbage: random bytes, a newline every two bytes
(an error reply of about 40 bytes each), lines too long. Over the pseudo-terminal, the harness holds only a
USB-serial chip's worth of the host's bytes, so a host's write of a burst lasts until the board has nearly
taken it in, as on the bench (the harness used to take any amount at once, and a PING written after 1 MB of
garbage was then answered only when the board had read all of it, over a minute of device time later).
"""

from __future__ import annotations

import threading

import fwsim
import numpy as np
import pytest
from rig_fakes import make_world

from helpers.board.protocol import frame
from helpers.rig.link import Link
from helpers.rigfile import default_rig

BAUD = {"daq": 500_000, "stepper": 115_200}
PING = b"PING*79\n"


FLOODS = ["random bytes", pytest.param("newlines", marks=pytest.mark.slow),
          pytest.param("long lines", marks=pytest.mark.slow)]  # fmt: skip
"""The floods: random bytes in the default suite, the two structured ones in the slow suite."""

def _floods(n: int) -> dict[str, bytes]:
    rng = np.random.default_rng(7)
    return {
        "random bytes": rng.integers(0, 256, n, dtype=np.uint8).tobytes() + b"\n",
        "newlines": b"x\n" * (n // 2),  # the worst: a damaged line every 2 bytes
        "long lines": (b"y" * 200 + b"\n") * (n // 201),  # every line too long
    }


@pytest.mark.firmware
@pytest.mark.parametrize("flood", FLOODS)
@pytest.mark.parametrize("board", ["daq", "stepper"])
def test_the_firmware_answers_ping_within_a_second_after_a_flood(firmware_build, board, flood):
    junk = _floods(20_000)[flood]
    t0 = 0.05
    ended = t0 + len(junk) * 10 / BAUD[board]  # the burst's last byte, at the earliest
    pings = [(ended + 0.1 * k, PING) for k in range(10)]  # then a PING every 100 ms, as the host's sync does
    run = fwsim.run(board, [(t0, junk), *pings], ended + 1.2)
    pongs = [ln for ln in run.lines if ln.body.startswith(f"PONG {board}")]
    assert pongs, f"no PONG within {ended + 1.2:.2f} s (last line {run.lines[-1].body!r})"
    assert pongs[0].t <= ended + 1.0
    errors = [ln for ln in run.lines if ln.body.startswith("ERR")]
    assert len(errors) <= junk.count(b"\n")  # at most one reply per damaged line, and no more


@pytest.mark.firmware
def test_over_the_pseudo_terminal_the_daq_answers_within_a_second_after_a_burst(firmware_build):
    """The DAQ streams while 100 kB of random bytes are written to it; the device time comes from its data
    lines: the newest when the host's write has returned, and the newest when PONG arrives."""
    proc, path = fwsim.pty_process("daq", pace=0.0)
    try:
        daq = Link.open(path, "daq", default_rig(), BAUD["daq"], timeout=60.0, hello_timeout=60.0)
        daq.command("START")
        junk = np.random.default_rng(3).integers(0, 256, 100_000, dtype=np.uint8).tobytes() + b"\n"
        writer = threading.Thread(target=daq.port.write, args=(junk,))
        writer.start()
        while writer.is_alive() or not daq.rows:
            daq.read()
        writer.join()
        ended_us = daq.rows[-1][1]  # device time when the burst had been written
        daq.replies.clear()
        while not any(r.startswith("PONG") for r in daq.replies):
            daq.write_line("PING")
            for _ in range(20):  # a PING every 20 reads (reads wait at most 50 ms each)
                daq.read()
                if any(r.startswith("PONG") for r in daq.replies):
                    break
        assert daq.rows[-1][1] - ended_us <= 1_000_000
        daq.close()
    finally:
        proc.kill()
        proc.wait(timeout=30)


@pytest.mark.parametrize("flood", FLOODS)
@pytest.mark.parametrize("board", ["daq", "stepper"])
def test_the_emulated_board_answers_ping_within_a_second_after_a_flood(board, flood):
    world = make_world()
    b = getattr(world, board)
    b.take_output()
    b.receive(_floods(1_000_000)[flood])  # 1 MB at once
    t_end = world.t
    world.advance_to(t_end + 0.01)
    b.receive(PING)
    world.advance_to(t_end + 1.0)
    out = b.take_output().split(b"\n")
    assert frame(f"PONG {board} 2.3.0+481e87e3").rstrip(b"\n") in out
