"""Command line: ``python -m helpers {reproduce,bench,serve-virtual-rig,record}``."""

from __future__ import annotations

import argparse
import sys


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from helpers.reproduce import NotebookFailed, reproduce

    from pathlib import Path

    notebooks = [Path(n).resolve() for n in args.notebooks] or None
    try:
        reproduce(notebooks, timeout=args.timeout)
    except NotebookFailed as exc:
        print(f"\nERROR: {exc}", file=sys.stderr)
        return 1
    return 0


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of the command line (one sub-command per job)."""
    parser = argparse.ArgumentParser(prog="python -m helpers", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("reproduce", help="execute every notebook in order; regenerate figures/ and tables")
    p.add_argument("--timeout", type=int, default=600, help="seconds any one cell may take")
    p.add_argument("notebooks", nargs="*", help="only these notebooks (default: every numbered one)")
    p.set_defaults(func=_cmd_reproduce)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line and return its exit status."""
    args = build_parser().parse_args(argv)
    return int(args.func(args))


if __name__ == "__main__":
    sys.exit(main())
