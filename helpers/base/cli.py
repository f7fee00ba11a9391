"""The command line's shared parts: argparse types that name the accepted range, and help with defaults.

Used by every command's parser (:mod:`helpers.commands`, and the wings' commands); a refusal is argparse's
one-line usage error, exit status 2 (``docs/faults.md``).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from helpers.base.jsonfile import MissingDataError
from helpers.base.paths import REPO_ROOT, repo_path, shown, user_data_dir
from helpers.base.validate import RIG_NAME

RIG_HELP = "the rig file (a path, or a shipped rig's name: paper, four-tendon, ...; docs/rig_file.md)"


def rig_option() -> argparse.ArgumentParser:
    """A parent parser holding ``--rig FILE`` for a command's (or sub-command's) own options.

    Its default is suppressed, so that ``python -m helpers --rig FILE <command>`` (the default ``paper``) is
    kept unless the option is given again after the command.
    """
    parent = argparse.ArgumentParser(add_help=False)
    parent.add_argument("--rig", metavar="FILE", default=argparse.SUPPRESS, help=RIG_HELP)
    return parent


def step_command(args: argparse.Namespace, words: str) -> str:
    """The command line that makes a previous step's result for the same rig and data folder.

    E.g. ``python -m helpers --rig long-arm record calibration --data-dir D`` (``--rig`` left out for the
    paper's rig, ``--data-dir`` for the default folder, :func:`helpers.base.paths.user_data_dir`).
    """
    rig = args.rig
    source = Path(getattr(rig, "source", ""))
    shipped = source.parent == REPO_ROOT / "rigs" and source.stem == rig.name
    parts = ["python -m helpers"]
    if not (shipped and rig.name == "paper"):
        parts.append(f"--rig {rig.name if shipped else shown(source)}")
    parts.append(words)
    data_dir = getattr(args, "data_dir", None)
    if data_dir is not None and Path(data_dir).resolve() != user_data_dir(rig).resolve():
        parts.append(f"--data-dir {data_dir}")  # as given
    return " ".join(parts)


def needs(load: Callable[[Path], Any], path: Path, what: str, args: argparse.Namespace, words: str) -> Any:
    """``load(path)`` of a previous step's result; if missing, one line naming the command that makes it.

    Raises
    ------
    helpers.base.jsonfile.MissingDataError
        ``<path>: no <what> yet: make it with `<command>``` (exit status 5, ``docs/faults.md``).
    """
    try:
        return load(path)
    except MissingDataError:
        made = step_command(args, words)
        raise MissingDataError(f"{repo_path(path)}: no {what} yet: make it with `{made}` (add --ports for "
                               "hardware)") from None  # fmt: skip


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
    """An argparse ``type`` for a virtual rig's name (:data:`RIG_NAME`)."""
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
