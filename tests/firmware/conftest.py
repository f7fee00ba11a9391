"""Firmware-in-simulator tests: build once per session, skip (saying what to install) without the toolchain.

A missing toolchain is a skip with the exact apt-get command; a toolchain that is present but fails to build
the firmware is a failure.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import fwsim
import pytest

_BUILD: dict[str, str | None] = {}
FOUR = fwsim.FIRMWARE / "common" / "rig_config_four_tendon.h"


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    missing = fwsim.missing_toolchain()
    if not missing:
        return
    reason = f"firmware toolchain missing ({', '.join(missing)}): {fwsim.INSTALL_HINT}"
    for item in items:
        if item.get_closest_marker("firmware"):
            item.add_marker(pytest.mark.skip(reason=reason))


@pytest.fixture(scope="session")
def firmware_build() -> None:
    """Run ``make -C firmware`` once; a failed build fails every firmware test that needs it."""
    if "error" not in _BUILD:
        proc = subprocess.run(
            ["make", "-C", str(fwsim.FIRMWARE)], capture_output=True, text=True, check=False, timeout=600
        )
        _BUILD["error"] = None if proc.returncode == 0 else (proc.stdout[-3000:] + proc.stderr[-3000:])
    if _BUILD["error"] is not None:
        pytest.fail(f"make -C firmware failed:\n{_BUILD['error']}", pytrace=False)


@pytest.fixture(scope="session")
def four_build(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """Both sketches built for the four-tendon config into a temporary directory, and the build's output."""
    build = tmp_path_factory.mktemp("four_tendon")
    targets = [f"RIG_CONFIG={FOUR}", f"BUILD={build}", "firmware", "size"]
    proc = subprocess.run(
        ["make", "-C", str(fwsim.FIRMWARE), "-j2", *targets],
        capture_output=True,
        text=True,
        check=False,
        timeout=600,
    )
    if proc.returncode != 0:
        pytest.fail(f"four-tendon build failed:\n{proc.stdout[-3000:]}{proc.stderr[-3000:]}", pytrace=False)
    return build, proc.stdout
