"""One set-up call for every notebook: print precision, plot style, warnings and a seeded RNG."""

from __future__ import annotations

import os
import warnings
from typing import TYPE_CHECKING

from helpers.base.style import apply_style

if TYPE_CHECKING:
    import numpy as np

PRINT_PRECISION = 4
"""Digits after the decimal point in printed arrays and DataFrames."""

BATCH_ENV = "HELPERS_BATCH"
"""Set to ``1`` by ``python -m helpers reproduce`` and by the tests (nbval): notebooks run unattended."""


def interactive() -> bool:
    """Whether a person is at the notebook (JupyterLab), rather than ``reproduce`` or nbval running it.

    Interactive cells (sliders) show widgets only then; unattended runs show a static figure of the same
    function instead, so that no widget state is stored and reruns store the same bytes.
    """
    return os.environ.get(BATCH_ENV) != "1"


def _use_inline_backend() -> None:
    """Show figures inline even if the caller inherited ``MPLBACKEND`` (it would hide them from nbval)."""
    os.environ.pop("MPLBACKEND", None)
    try:
        from IPython import get_ipython
    except ImportError:  # pragma: no cover - IPython always ships with ipykernel
        return
    ip = get_ipython()
    if ip is not None and getattr(ip, "kernel", None) is not None:
        ip.run_line_magic("matplotlib", "inline")


def setup(precision: int = PRINT_PRECISION, seed: int = 0) -> np.random.Generator:
    """Configure a notebook so that its stored outputs are reproducible.

    - numpy prints plain floats (``0.5345``, not ``np.float64(0.5345)``) with fixed precision;
    - pandas shows ``precision`` digits;
    - matplotlib draws inline with the project's style;
    - warnings are shown once per location (never with temporary file paths in the outputs).

    Parameters
    ----------
    precision : int
        Digits after the decimal point.
    seed : int
        Seed of the returned random generator.

    Returns
    -------
    numpy.random.Generator
        A generator seeded with ``seed``, for any randomness a notebook needs.
    """
    # numpy and pandas load here, not when the package is imported: `python -m helpers` imports the package
    # first, and a Ctrl-C must find the command line's handlers in place while the heavy modules load
    import numpy as np  # noqa: PLC0415
    import pandas as pd  # noqa: PLC0415

    np.set_printoptions(precision=precision, suppress=True, legacy="1.25")
    pd.set_option("display.precision", precision)
    pd.set_option("display.width", 120)
    pd.set_option("display.max_columns", 20)
    _use_inline_backend()
    apply_style()
    warnings.simplefilter("once")
    return np.random.default_rng(seed)
