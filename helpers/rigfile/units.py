"""Unit conversion of a rig file's decimal values (standard library only)."""

from __future__ import annotations


def si(value: float, exponent: int) -> float:
    """``value * 10**exponent`` rounded once from the decimal (``si(0.82, -3) == 0.82e-3`` exactly).

    Multiplying by ``1e-3`` can land one unit in the last place away from the literal the code writes; the
    decimal shift gives the same float as the literal, so the paper's rig file reproduces today's numbers.
    """
    return float(f"{float(value)!r}e{exponent}")
