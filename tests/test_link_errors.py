"""A bit error on the link is never "the board did not answer".

A command damaged on its way is sent again, so is a command whose second execution changes nothing when its
reply was damaged, a programme whose load lost a reply is loaded again, a lost DONE is checked with POS, and
anything else stops with the true reason."""

from __future__ import annotations

import pytest
from rig_fakes import make_rig

from helpers import recordings
from helpers.board.programmes import Dwell, Programme, Segment
from helpers.rig import LinkCorrupted
from helpers.rig.stream import stream

PROGRAMME = Programme((Dwell(50), Segment(1, 10, 2000), Dwell(50), Segment(-1, 10, 2000), Dwell(50)))


class Damaging:
    """A port that flips one bit in the first line read starting with ``reply`` or written starting with
    ``command`` (the first character: 'O' becomes 'N', 'D' becomes 'E', 'G' becomes 'F', ...)."""

    def __init__(self, inner, reply: bytes | None = None, command: bytes | None = None) -> None:
        self.inner, self.reply, self.command = inner, reply, command
        self.damaged = 0

    @staticmethod
    def _flip(data: bytes, at: int) -> bytes:
        b = bytearray(data)
        b[at] ^= 0x01
        return bytes(b)

    def read(self, n=1):
        data = self.inner.read(n)
        if self.reply is not None:
            at = data.find(b"\n" + self.reply)
            at = 0 if data.startswith(self.reply) else (at + 1 if at >= 0 else -1)
            if at >= 0:
                data, self.reply = self._flip(data, at), None
                self.damaged += 1
        return data

    def write(self, data):
        if self.command is not None and data.startswith(self.command):
            data, self.command = self._flip(data, 0), None
            self.damaged += 1
        return self.inner.write(data)

    def __getattr__(self, name):
        return getattr(self.inner, name)


def _damage(rig, **kw) -> Damaging:
    rig.stepper.port = Damaging(rig.stepper.port, **kw)
    return rig.stepper.port


def test_a_damaged_reply_to_a_harmless_command_is_asked_again():
    rig, world = make_rig()
    port = _damage(rig, reply=b"OK POS")
    before = world.stepper.received.count("POS")
    assert rig.positions() == (0,) and port.damaged == 1
    assert world.stepper.received.count("POS") == before + 2


@pytest.mark.parametrize(
    ("damage", "resent"),
    [
        ({"reply": b"OK SEG"}, "CLEAR"),  # a reply of the programme's load: the load starts again
        ({"command": b"GO"}, "GO"),  # the board refused GO as damaged and did nothing: sent again
        ({"reply": b"DONE"}, "POS"),  # the end of the programme lost: POS says it ended where it should
    ],
)
def test_a_run_survives_a_bit_error_on_the_link(tmp_path, damage, resent):
    rig, world = make_rig()
    rig.run(PROGRAMME, path=tmp_path / "ref", progress=False)
    port = _damage(rig, **damage)
    before = world.stepper.received.count(resent)
    rec = rig.run(PROGRAMME, path=tmp_path / "p", progress=False)
    once = {"CLEAR": 1, "GO": 0, "POS": 1}[resent]  # what a run sends anyway (the damaged GO never arrived)
    assert port.damaged == 1 and world.stepper.received.count(resent) > before + once
    back = recordings.load(rec.path)
    assert back.status == "complete" and back.frame["steps"].max() == 10 and back.meta["done_position"] == 0
    assert (rig.stepper.parser.stats.corrupted >= 1) == ("reply" in damage)  # a damaged reply is counted


def test_a_damaged_reply_to_a_set_point_stops_the_stream_with_the_true_reason(tmp_path):
    rig, world = make_rig()
    _damage(rig, reply=b"OK V 3")
    with pytest.raises(LinkCorrupted, match=r"reply to 'V \d+' was corrupted on the link") as info:
        stream(rig, [50.0] * 20, None, path=tmp_path / "s", progress=False)
    assert "did not answer" not in str(info.value)
    assert recordings.load(info.value.saved_path).status == "aborted" and not world.stepper.enabled
