"""Ctrl-C, SIGTERM or SIGHUP while a command is still loading its modules: one line, the documented status.

The command runs with ``python -X importtime``, which writes a line to stderr as each module finishes
loading; the signal is sent once numpy's first module has loaded (the command line's handlers are in place
by then, and pandas, scipy and the command's own modules are still to come). The lines ``-X importtime``
writes are left out of the count.
"""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest

from helpers.base.paths import REPO_ROOT

COMMANDS = {
    "metrics": ["metrics", "data/experiments"],
    "record": ["record", "pulse", "--v-in", "100", "--x-f", "10", "--dry-run"],
    "sweep": ["sweep", "info", "data/sweeps/atlas_uncertainty.nc"],
}
STATUS = {signal.SIGINT: 130, signal.SIGTERM: 143, signal.SIGHUP: 129}


@pytest.mark.parametrize("signum", list(STATUS), ids=lambda s: signal.Signals(s).name)
@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_signal_while_the_command_loads_gives_one_line_and_its_status(command, signum):
    proc = subprocess.Popen(
        [sys.executable, "-X", "importtime", "-m", "helpers", *COMMANDS[command]],
        cwd=REPO_ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    seen = []
    for line in proc.stderr:  # readiness: numpy has begun to load, after the handlers were installed
        seen.append(line)
        if "| numpy" in line or "|   numpy" in line or " numpy." in line:
            break
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=120)
    every = "".join(seen[-1:]).splitlines() + err.splitlines()
    lines = [ln for ln in every if not ln.startswith("import time:")]
    assert proc.returncode == STATUS[signum], (lines, out[-300:])
    assert len(lines) == 1 and lines[0].startswith("interrupted by"), lines
    assert "Traceback" not in err
