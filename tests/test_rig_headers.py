"""The firmware's committed rig headers are the generator's output for the shipped rig files, and the hash the
paper's build reports is the paper rig file's."""

from __future__ import annotations

import hashlib
import re
import subprocess
import sys
from pathlib import Path

import pytest

from helpers.board.protocol import PAPER_RIG_HASH

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    ("rig", "header"),
    [("paper.toml", "rig_config_paper.h"), ("four-tendon.toml", "rig_config_four_tendon.h")],
)
def test_committed_headers_are_generated_from_the_shipped_rig_files(tmp_path, rig, header):
    out = tmp_path / "h.h"
    subprocess.run(
        [sys.executable, "-m", "helpers.rigfile.firmware_header", str(ROOT / "rigs" / rig), "-o", str(out)],
        check=True, cwd=tmp_path,
    )  # fmt: skip
    committed = (ROOT / "firmware" / "common" / header).read_text()
    assert out.read_text() == committed, f"regenerate firmware/common/{header} from rigs/{rig}"
    digest = hashlib.sha256((ROOT / "rigs" / rig).read_bytes()).hexdigest()[:8]
    assert re.search(r'#define RIG_HASH "([0-9a-f]{8})"', committed).group(1) == digest


def test_the_paper_builds_hash_is_the_paper_rig_files():
    assert PAPER_RIG_HASH == hashlib.sha256((ROOT / "rigs" / "paper.toml").read_bytes()).hexdigest()[:8]
