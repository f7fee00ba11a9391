"""Helpers for reproducing *Input Shaping for Point-to-Point Motion with a Continuum Robot Arm*.

The notebooks in ``notebooks/`` hold the narrative; this package holds every computation that a
notebook needs, one concern per module (see ``docs/architecture.md``). Numbers flow one way::

    recordings -> identify -> shapers -> profiles -> rig (or virtual rig) -> recordings -> metrics
"""

from helpers.notebook import setup

__version__ = "0.1.0"

__all__ = ["__version__", "setup"]
