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
import time

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


DELAYS_S = (0.0, 0.05, 0.2, 0.5)
"""Delays after the package's first module loaded (the handlers are in place) at which a signal is sent."""


@pytest.mark.parametrize("delay", DELAYS_S)
@pytest.mark.parametrize("signum", list(STATUS), ids=lambda s: signal.Signals(s).name)
def test_a_signal_at_any_instant_of_start_up_gives_one_line_and_its_status(signum, delay):
    """From the package's first lines (helpers/__init__.py installs the handlers for ``python -m helpers``)
    through the imports, the parsing and the run: one line and the documented status, or the command had
    finished (0). Readiness, not a clock: the signal goes out ``delay`` after the first module the package
    loads after its handlers (``helpers.base.style``) has loaded; each delay lands wherever the host is by
    then. Before that (Python's own start-up) the signal is Python's: see docs/faults.md."""
    proc = subprocess.Popen(
        [sys.executable, "-X", "importtime", "-m", "helpers", "metrics", "data/experiments"],
        cwd=REPO_ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    seen = []
    for line in proc.stderr:
        seen.append(line)
        if line.rstrip().endswith("helpers.base.style"):
            break
    if delay:
        time.sleep(delay)
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=120)
    lines = [ln for ln in (*seen, *err.splitlines(True)) if not ln.startswith("import time:")]
    assert "Traceback" not in "".join(lines), lines
    assert proc.returncode in (STATUS[signum], 0), (proc.returncode, lines)
    if proc.returncode:
        assert len(lines) == 1 and lines[0].startswith("interrupted by"), lines
    else:  # finished before the signal: the table was printed whole
        assert "Per scenario" in out and not lines


HANDLER = "import signal, helpers; print(signal.getsignal(signal.SIGTERM) is signal.SIG_DFL)"
"""Imports the package, prints whether SIGTERM still has its default handler."""


@pytest.mark.parametrize(
    ("argv", "default"),
    [
        (["-c", HANDLER], True),  # a script, a notebook's kernel, pytest: the package leaves signals alone
        (["-X", "importtime", "-u", "-c", HANDLER], True),
        (["-c", f"import sys; sys.argv[:] = ['-m']; {HANDLER}"], False),  # as while -m finds the command
    ],
)
def test_only_python_m_installs_the_early_handlers(argv, default):
    proc = subprocess.run([sys.executable, *argv], cwd=REPO_ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and proc.stdout.split() == [str(default)], proc.stderr
