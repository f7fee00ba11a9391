"""Parameter sweeps on the virtual rig, chunked into Dask tasks, resumable, saved as labelled datasets.

``python -m helpers sweep`` (``docs/sweeps.md``). A sweep runs every shaper of its definition over a grid
or a random sample of parameters (the design's frequency and damping errors, the move's amplitude and speed,
the rig's disc mass, cable stiffness and damping, the noise seed) and keeps, per run and move, the residual
vibration and the Table II metrics.

- :mod:`~helpers.sweep.definition`: :class:`SweepDefinition` (JSON), the parameters, runs and chunks;
- :mod:`~helpers.sweep.shaping`: the shapers a sweep can run, designed with the run's design errors;
- :mod:`~helpers.sweep.runs`: one chunk (:func:`run_chunk`, the task), its measurements;
- :mod:`~helpers.sweep.store`: finished chunks on disk, the dataset, NetCDF;
- :mod:`~helpers.sweep.execute`: :func:`run_sweep` on a local cluster, a scheduler, or in a loop;
- :mod:`~helpers.sweep.presets`: the robustness atlas's definitions;
- :mod:`~helpers.sweep.command`: the command line.

Dask itself is imported only when chunks are sent to it.
"""

from helpers.sweep.definition import PARAMETERS, SweepDefinition, load_definition
from helpers.sweep.execute import SweepInterrupted, SweepReport, local_client, run_sweep
from helpers.sweep.runs import VARIABLES, run_chunk
from helpers.sweep.shaping import BUILTIN
from helpers.sweep.store import load_sweep

__all__ = [
    "BUILTIN",
    "PARAMETERS",
    "SweepDefinition",
    "SweepInterrupted",
    "SweepReport",
    "VARIABLES",
    "load_definition",
    "load_sweep",
    "local_client",
    "run_chunk",
    "run_sweep",
]
