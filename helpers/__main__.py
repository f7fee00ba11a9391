"""Command line: ``python -m helpers <command>``.

Each command lives in the module that owns the job; that module provides ``add_arguments(parser)`` and
``run(args) -> int``. Modules are imported only when their command runs.
"""

from __future__ import annotations

import argparse
import importlib
import sys

COMMANDS: dict[str, tuple[str, str]] = {
    "reproduce": ("helpers.reproduce", "execute every notebook in order; regenerate figures/ and tables"),
    "bench": ("helpers.benchmarks", "print the speed figures (virtual rig, serial I/O)"),
    "serve-virtual-rig": ("helpers.emulator.server", "serve the virtual rig's boards on pseudo-terminals"),
    "record": ("helpers.record", "record the paper's experiments into data/ (hardware or virtual rig)"),
    "virtual-rig": ("helpers.rig_studies", "check or re-tune the virtual rig; rewrite its evidence tables"),
}
"""command name -> (module, one-line help)."""


def main(argv: list[str] | None = None) -> int:
    """Run the command line and return its exit status."""
    argv = sys.argv[1:] if argv is None else argv
    parser = argparse.ArgumentParser(prog="python -m helpers", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, metavar="command")
    chosen = argv[0] if argv else None
    for name, (module, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.set_defaults(module=module)
        if name == chosen:
            importlib.import_module(module).add_arguments(p)
    args = parser.parse_args(argv)
    return int(importlib.import_module(args.module).run(args))


if __name__ == "__main__":
    sys.exit(main())
