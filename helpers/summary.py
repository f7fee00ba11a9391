"""The one-screen summary printed at the end of ``python -m helpers reproduce``.

It reads only files that the notebooks wrote (``data/`` and ``figures/``), so it summarises what was
actually regenerated. Sections whose inputs do not exist yet say so.
"""

from __future__ import annotations

from helpers.shapers import paper_tdfs


def print_summary() -> None:
    """Print the paper's headline numbers beside ours."""
    print("-- summary --------------------------------------------------------------")
    zv, zvd = paper_tdfs()
    print(
        "paper's TDFs from (zeta=0.044, omega_d=25.085 rad/s): "
        f"ZV A0={zv.amplitudes[0]:.4f} A1={zv.amplitudes[1]:.4f} T={zv.times[1]:.5f} s; "
        f"ZVD {', '.join(f'{a:.4f}' for a in zvd.amplitudes)}"
    )
