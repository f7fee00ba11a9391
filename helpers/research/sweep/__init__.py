"""Parameter sweeps on the virtual rig, chunked into Dask tasks, resumable, saved as labelled datasets.

``python -m helpers sweep`` (``docs/sweeps.md``). A sweep runs every shaper of its definition over a grid
or a random sample of parameters (the design's frequency and damping errors, the move's amplitude and speed,
the rig's disc mass, cable stiffness and damping, the noise seed) and keeps, per run and move, the residual
vibration and the Table II metrics.

- :mod:`~helpers.research.sweep.definition`: ``SweepDefinition`` (JSON), the parameters, runs and chunks;
- :mod:`~helpers.research.sweep.shaping`: the shapers a sweep can run, designed with the run's design errors;
- :mod:`~helpers.research.sweep.runs`: one chunk (:func:`run_chunk`, the task), its measurements;
- :mod:`~helpers.research.sweep.variables`: the measured variables (names, units, meaning);
- :mod:`~helpers.research.sweep.store`: finished chunks on disk, the dataset, NetCDF;
- :mod:`~helpers.research.sweep.files`: :func:`~helpers.research.sweep.files.load_sweep` (xarray only);
- :mod:`~helpers.research.sweep.atlas`: the atlas's tables from stored sweeps;
- :mod:`~helpers.research.sweep.execute`: :func:`run_sweep` on a local cluster, a scheduler, or in a loop;
- :mod:`~helpers.research.sweep.presets`: the robustness atlas's definitions;
- :mod:`~helpers.research.sweep.command`: the command line.

The package's ``__init__`` imports nothing, so that reading stored results
(:mod:`~helpers.research.sweep.files`,
:mod:`~helpers.research.sweep.atlas`) does not load the virtual rig or Dask: import the names from their
modules
(``from helpers.research.sweep.execute import run_sweep``). Dask itself is imported only when chunks are sent
to it.
"""
