"""The command line's shared parts: argparse types that name the accepted range, and help with defaults.

Used by every command's parser (:mod:`helpers.commands`, and the wings' commands); a refusal is argparse's
one-line usage error, exit status 2 (``docs/faults.md``).
"""

from __future__ import annotations

import argparse
import math
from typing import Any

RIG_HELP = "the rig file (a path, or a shipped rig's name: paper, four-tendon, ...; docs/rig_file.md)"


def rig_option() -> argparse.ArgumentParser:
    """A parent parser holding ``--rig FILE`` for a command's (or sub-command's) own options.

    Its default is suppressed, so that ``python -m helpers --rig FILE <command>`` (the default ``paper``) is
    kept unless the option is given again after the command.
    """
    parent = argparse.ArgumentParser(add_help=False)
    parent.add_argument("--rig", metavar="FILE", default=argparse.SUPPRESS, help=RIG_HELP)
    return parent


def arg_number(lo: float, hi: float, kind: type = float, lo_open: bool = False) -> Any:
    """An argparse ``type`` accepting a finite ``kind`` in ``[lo, hi]`` (``(lo, hi]`` if ``lo_open``).

    The refusal names the accepted range (argparse prints it as a one-line usage error, exit status 2).
    """
    def parse(text: str) -> float | int:
        try:
            value = kind(text)
        except ValueError:
            what = "an integer" if kind is int else "a number"
            raise argparse.ArgumentTypeError(f"{text!r} is not {what}") from None
        inside = (lo < value if lo_open else lo <= value) and value <= hi
        if not (math.isfinite(value) and inside):
            bracket = "(" if lo_open else "["
            raise argparse.ArgumentTypeError(f"{text} is outside {bracket}{lo:g}, {hi:g}]")
        return value

    parse.__name__ = kind.__name__  # argparse shows it in "invalid <name> value"
    return parse


def arg_rig_name(text: str) -> str:
    """An argparse ``type`` for a virtual rig's name (:data:`helpers.base.validate.RIG_NAME`)."""
    from helpers.base.validate import RIG_NAME  # numpy: not before the command line's signal handlers
    if not RIG_NAME.match(text):
        raise argparse.ArgumentTypeError(
            f"invalid virtual rig name {text!r}: letters, digits, '_', '-', '.' (at most 64)"
        )
    return text


class DefaultsHelp(argparse.HelpFormatter):
    """Help that shows every option's default once: appended unless the help text already states it."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        shown = "default" in text.lower()
        unset = any(action.default is x for x in (None, False, argparse.SUPPRESS))
        trivial = unset or not action.option_strings
        return text if shown or trivial else f"{text} (default: %(default)s)"
