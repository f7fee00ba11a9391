"""A board still running firmware 1.x (XOR checksums) is recognised in one clear error and never used."""

from __future__ import annotations

import pytest
from crc_reference import link_hex, xor_hex

from helpers import rigfile
from helpers.rig import OldFirmware
from helpers.rig.link import Link

PAPER = rigfile.default_rig()


class FakeBoard:
    """A serial port with a board behind it that frames its lines with ``checksum`` (protocol 1 or 2).

    It checks a command's ``*hh`` the same way (as firmware 1.x checks XOR) and answers ``PING`` with
    ``PONG <kind> <version>``; with ``hello`` it sends ``HELLO`` first, as a board that reset when opened.
    """

    def __init__(self, kind: str, version: str, checksum, hello: bool = False) -> None:
        self.kind, self.version, self.checksum = kind, version, checksum
        self.port = "/dev/pts/fake"
        self.timeout = 0.01
        self.out = bytearray(self._line(f"HELLO {kind} {version}") if hello else b"")

    def _line(self, body: str) -> bytes:
        return f"{body}*{self.checksum(body)}\n".encode()

    def write(self, data: bytes) -> int:
        for raw in data.split(b"\n")[:-1]:
            body, star, given = raw.decode().partition("*")
            if star and given.upper() != self.checksum(body):
                self.out += self._line("ERR CHECKSUM bad checksum")
            elif body == "PING":
                self.out += self._line(f"PONG {self.kind} {self.version}")
            else:
                self.out += self._line("ERR UNKNOWN command")
        return len(data)

    @property
    def in_waiting(self) -> int:
        return len(self.out)

    def read(self, n: int = 1) -> bytes:
        data = bytes(self.out[:n])
        del self.out[:n]
        return data

    def close(self) -> None:
        pass


@pytest.mark.parametrize("hello", [False, True])
@pytest.mark.parametrize("kind", ["daq", "stepper"])
def test_a_1x_board_is_refused_with_one_clear_error(kind, hello):
    port = FakeBoard(kind, "1.0.0", xor_hex, hello=hello)
    link = Link(port, kind, PAPER, timeout=0.5)
    with pytest.raises(OldFirmware, match=r"firmware 1\.x .*XOR.*flash firmware 2\.x") as info:
        link.sync(hello_timeout=0.5)
    # without HELLO the old board answered the host's CRC-framed PING with an XOR-framed ERR CHECKSUM
    expected = f"HELLO {kind} 1.0.0" if hello else "ERR CHECKSUM bad checksum"
    assert repr(expected) in str(info.value)


def test_the_current_firmware_is_accepted():
    link = Link(FakeBoard("daq", "2.0.0", link_hex), "daq", PAPER, timeout=0.5)
    assert link.sync(hello_timeout=0.5) == "2.0.0"


@pytest.mark.parametrize("version", ["3.0.0", "1.9.9"])
def test_a_crc_framed_board_of_another_major_version_is_refused(version):
    link = Link(FakeBoard("board", version, link_hex), "board", PAPER, timeout=0.5)
    with pytest.raises(OldFirmware, match=rf"firmware {version}; this host speaks protocol 2"):
        link.sync(hello_timeout=0.5)
