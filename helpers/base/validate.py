"""Argument checks shared by the package: one clear ``ValueError`` that names the argument."""

from __future__ import annotations

import argparse
import math
import re
from typing import Any

import numpy as np


def check_int(value: Any, name: str, minimum: int | None = None) -> int:
    """Return ``value`` as an ``int`` or raise ``ValueError`` naming ``name`` (no floats, bools or NaN)."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise ValueError(f"{name} must be an integer, got {value!r} ({type(value).__name__})")
    value = int(value)
    if minimum is not None and value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value}")
    return value


def check_positive(value: Any, name: str) -> float:
    """Return ``value`` as a finite ``float`` > 0 or raise ``ValueError`` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ValueError(f"{name} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be finite and > 0, got {value!r}")
    return value


def check_time(value: Any, name: str) -> float:
    """Return ``value`` as a finite number of seconds >= 0 or raise ``ValueError`` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ValueError(f"{name} must be a number of seconds, got {value!r}")
    value = float(value)
    if not math.isfinite(value) or value < 0:
        raise ValueError(f"{name} must be finite and >= 0 s, got {value!r}")
    return value


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


RIG_NAME = re.compile(r"[A-Za-z0-9_.-]{1,64}\Z")
"""An in-process virtual rig's name: letters, digits, ``_``, ``-``, ``.`` (no URL option can be injected)."""


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
