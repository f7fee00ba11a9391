"""Argument checks shared by the package: one clear ``ValueError`` that names the argument.

The command line's own checks (argparse types, the help's defaults) are :mod:`helpers.base.cli`'s.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
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


def is_int(value: Any) -> bool:
    """True for an integer that is not a bool (a JSON or TOML integer)."""
    return isinstance(value, int) and not isinstance(value, bool)


def _real(value: Any, name: str, what: str, within: Callable[[float], bool], need: str) -> float:
    """``value`` as a finite ``float`` that is ``within`` range, else ``ValueError`` naming ``name``.

    ``what`` names the kind of number and ``need`` its range, for the messages; a bool is not a number.
    """
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ValueError(f"{name} must be {what}, got {value!r}")
    value = float(value)
    if not (math.isfinite(value) and within(value)):
        raise ValueError(f"{name} must be finite and {need}, got {value!r}")
    return value


def check_positive(value: Any, name: str) -> float:
    """Return ``value`` as a finite ``float`` > 0 or raise ``ValueError`` naming ``name``."""
    return _real(value, name, "a number", lambda v: v > 0, "> 0")


def check_time(value: Any, name: str) -> float:
    """Return ``value`` as a finite number of seconds >= 0 or raise ``ValueError`` naming ``name``."""
    return _real(value, name, "a number of seconds", lambda v: v >= 0, ">= 0 s")


RIG_NAME = re.compile(r"[A-Za-z0-9_.-]{1,64}\Z")
"""An in-process virtual rig's name: letters, digits, ``_``, ``-``, ``.`` (no URL option can be injected)."""
