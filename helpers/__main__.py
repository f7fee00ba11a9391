"""Command line: ``python -m helpers <command>`` (or ``continuum-helpers <command>``).

Each command lives in the module that owns the job; that module provides ``add_arguments(parser)`` and
``run(args) -> int``. The command modules are imported by name only when their command runs, so that
``--help`` stays quick (the virtual rig compiles with numba, the notebooks need Jupyter).

Every error ends in **one line** on stderr and an exit status from :data:`EXIT_CODES` (``--debug`` shows the
traceback instead). SIGTERM and SIGHUP are handled like Ctrl-C: a running experiment aborts the stepper,
disables the driver, stops the DAQ and saves what it recorded, and the line says where.
"""

from __future__ import annotations

# Only the standard library and the core's light modules (standard library only) load here: the rig file
# (numpy) and the command's module load by name once main() has installed the handlers (helpers/__init__.py
# installs them even earlier for ``python -m helpers``).
import argparse
import contextlib
import errno
import importlib
import sys
import threading
import traceback
from pathlib import Path
from typing import Any

from helpers.base.paths import shown
from helpers.base.signals import Interrupted, end_at_once_on_signals, interrupts_from_signals

COMMANDS: dict[str, tuple[str, str]] = {
    "reproduce": (
        "helpers.commands.reproduce",
        "execute every notebook in order; regenerate figures/ and tables",
    ),
    "record": ("helpers.commands.record", "record experiments into my_data/<rig>/ (hardware or virtual rig)"),
    "metrics": (
        "helpers.commands.metrics_report",
        "Table II metrics (peak, overshoot, settling) of any recordings",
    ),
    "tune": ("helpers.research.tune", "measure the modes across configurations, design shapers, verify them"),
    "home": ("helpers.commands.home", "bring the cable back to position 0 safely"),
    "serve-virtual-rig": (
        "helpers.virtual.emulator.server",
        "serve the virtual rig's boards on pseudo-terminals",
    ),
    "frame": ("helpers.commands.frame", "append the CRC-8 to commands typed by hand (PING -> PING*79)"),
    "bench": ("helpers.commands.benchmarks", "print the speed figures (virtual rig, serial I/O)"),
    "virtual-rig": (
        "helpers.virtual.studies",
        "check or re-tune the virtual rig; rewrite its evidence tables",
    ),
    "sweep": (
        "helpers.research.sweep.command",
        "parameter sweeps on the virtual rig (Dask); the robustness atlas",
    ),
    "rig": (
        "helpers.commands.rig_file",
        "check a rig file (limits, ADC range, predicted modes); write a template",
    ),
    "ringdowns": (
        "helpers.research.rest_ringdowns",
        "identify the ring-down after every rest of an external recording (DROPBEAR); CSV",
    ),
}
"""command name -> (module, one-line help)."""

EXIT_CODES: dict[int, str] = {
    0: "success",
    1: "the command failed (e.g. a notebook raised)",
    2: "usage: an invalid or out-of-range argument, refused before anything was sent",
    3: "refused by the safety limits (travel, speed, step rate, programme length, position unknown)",
    4: "board fault: a board did not answer, reset, disconnected, is busy, runs other firmware, sent garbage",
    5: "data error: a recording or result file is missing, malformed, exists already, or the disk is full",
    130: "interrupted by Ctrl-C (SIGINT)",
    129: "interrupted by SIGHUP",
    143: "interrupted by SIGTERM",
}
"""Exit status -> meaning (also in docs/faults.md)."""

EXTRAS: dict[str, str] = {
    "numba": "virtual",
    "llvmlite": "virtual",
    "tqdm": "virtual",
    "dask": "sweep",
    "distributed": "sweep",
    "xarray": "sweep",
    "pydantic": "sweep",
}
"""A package the light install lacks -> the extra of ``pyproject.toml`` that brings it."""


def _run_outcome(exc: BaseException) -> str:
    """For a run that ended early: where its data went, and whether the cleanup reached the boards."""
    if not hasattr(exc, "cleanup"):
        return ""
    n = len(exc.recording.frame) if getattr(exc, "recording", None) is not None else 0
    if getattr(exc, "complete", False) and getattr(exc, "saved_path", None) is not None:
        saved = f"the run had finished: saved whole to {shown(exc.saved_path)} ({n} samples)"
    elif getattr(exc, "saved_path", None) is not None:
        saved = f"partial recording saved to {shown(exc.saved_path)} ({n} samples)"
    else:
        saved = f"the recording could NOT be saved ({getattr(exc, 'save_error', '?')})"
    cleanup = exc.cleanup
    stepper_failed = [c for c in cleanup if "stepper board" in c]
    if stepper_failed:
        boards = "cleanup failed: " + "; ".join(cleanup) + ": the driver may be on, switch its power off"
    elif cleanup:  # only the DAQ's STOP failed: the stepper is stopped and its driver off
        boards = "the stepper was stopped and disabled; " + "; ".join(cleanup)
    else:
        boards = "the stepper was stopped and disabled and the DAQ stopped"
    return f"; {saved}; {boards}"


def _loaded(module: str, name: str) -> type | None:
    """An exception class of a module that is loaded already (error_line never imports anything)."""
    mod = sys.modules.get(module)
    return getattr(mod, name, None) if mod is not None else None


def _is(exc: BaseException, *classes: tuple[str, str]) -> bool:
    found = tuple(c for c in (_loaded(m, n) for m, n in classes) if c is not None)
    return bool(found) and isinstance(exc, found)


def error_line(exc: BaseException) -> tuple[str, int]:
    """The one line the user sees for ``exc``, and the exit status (:data:`EXIT_CODES`)."""
    if isinstance(exc, KeyboardInterrupt):
        signum = exc.signum if isinstance(exc, Interrupted) else 2
        what = str(exc) if isinstance(exc, Interrupted) else "interrupted by Ctrl-C"
        return f"{what}{_run_outcome(exc)}", 128 + signum  # the documented status: 130, 143, 129
    first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
    missing = exc.name.split(".")[0] if isinstance(exc, ModuleNotFoundError) and exc.name else None
    if missing in EXTRAS:  # the paper's part runs without them; this command needs one
        extra = EXTRAS[missing]
        why = f"this command needs the [{extra}] extra ({missing} is not installed)"
        return f'error: {why}: pip install -e ".[{extra}]"', 1
    if _is(exc, ("helpers.rig.safety", "SafetyError")):
        status = 3
    elif _is(exc, ("helpers.rig.link", "BoardError")):
        status = 4
    elif _is(
        exc, ("helpers.recordings.format", "RecordingError"), ("helpers.base.jsonfile", "DataFileError"),
        ("helpers.base.locks", "FolderBusy"),
    ):  # fmt: skip
        status = 5
    elif isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EROFS, errno.EACCES, errno.EDQUOT):
        why = {errno.ENOSPC: "no space left on device", errno.EROFS: "read-only file system",
               errno.EACCES: "permission denied", errno.EDQUOT: "disk quota exceeded"}[exc.errno]  # fmt: skip
        where = exc.filename if exc.filename is not None else "?"
        first, status = f"{shown(Path(where))}: could not write ({why})", 5
    elif isinstance(exc, ValueError):
        status = 2
    else:
        status = 1
    return f"error: {first}{_run_outcome(exc)}", status


class _Parser(argparse.ArgumentParser):
    """argparse with one-line usage errors (the full usage is one ``--help`` away)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def main(argv: list[str] | None = None) -> int:
    """Run the command line and return its exit status.

    Without ``argv`` (a process of its own: ``python -m helpers``, ``continuum-helpers``) a signal while the
    modules load and the arguments are parsed ends the process at once with one line and its status
    (:func:`helpers.base.signals.end_at_once_on_signals`); the command itself runs under
    :func:`helpers.base.signals.interrupts_from_signals`, which ends a run cleanly. With ``argv`` (called in
    a process that has its own handlers) both parts run under the latter.
    """
    own_process = argv is None and threading.current_thread() is threading.main_thread()
    if own_process:
        end_at_once_on_signals()
    argv = sys.argv[1:] if argv is None else argv
    debug = "--debug" in argv
    try:
        with contextlib.nullcontext() if own_process else interrupts_from_signals():
            args, command = _parse(argv)
        with interrupts_from_signals():
            return int(command.run(args))
    except SystemExit as exc:
        if isinstance(exc.code, str):  # a command's usage refusal: one line, status 2
            print(f"error: {exc.code}", file=sys.stderr)
            return 2
        raise
    except BaseException as exc:  # noqa: BLE001 - every error ends in one line and a documented status
        if debug:
            traceback.print_exc()
        line, status = error_line(exc)
        print(line, file=sys.stderr)
        return status


def _parse(argv: list[str]) -> tuple[argparse.Namespace, Any]:
    """The parsed arguments (the rig file loaded into ``args.rig``) and the command's module."""
    parser = _Parser(
        prog="python -m helpers",
        description=__doc__.splitlines()[0].replace("``", ""),
        epilog="exit status: " + "; ".join(f"{k} {v}" for k, v in EXIT_CODES.items()),
    )
    parser.add_argument("--debug", action="store_true", help="show the traceback of an error")
    cli = importlib.import_module("helpers.base.cli")  # after the handlers: it loads numpy
    parser.add_argument("--rig", metavar="FILE", default="paper", help=cli.RIG_HELP)
    after = cli.rig_option()  # the same option after the command's name
    sub = parser.add_subparsers(dest="command", required=True, metavar="command")
    chosen = next((a for a in argv if a in COMMANDS), None)
    for name, (module, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text, parents=[after])
        p.set_defaults(module=module)
        if name == chosen:
            importlib.import_module(module).add_arguments(p)
    args = parser.parse_args(argv)
    rigfile = importlib.import_module("helpers.rigfile")  # after the handlers: it loads numpy
    args.rig = rigfile.load(rigfile.resolve(args.rig))  # the rig, read once, passed to the command as a value
    return args, importlib.import_module(args.module)


if __name__ == "__main__":
    sys.exit(main())
