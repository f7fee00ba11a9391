"""The rig-parametrised tests: every test that depends on the rig's numbers runs for the shipped rig files.

The rig is a value (``docs/architecture.md``): the code under test takes it as an argument, so every rig runs
in this one pytest process. The fixture ``rig_file`` yields each shipped single-tendon rig file, the paper's
(``rigs/paper.toml``) and the second rig (``rigs/long-arm.toml``), as a :class:`rigs.ShippedRig`: its keys,
and what follows from them by the arithmetic of ``docs/rig_file.md``, done in the test, never by the code
under test; ``rig_file.load()`` is the value the test passes to the code. ``shipped_rig`` is the same fixture
under the name the tests of the host's limits use.

Tests whose expected numbers are the paper's published values (Table I's programmes, the paper's 0.25525 mm
per step, its hardware constants) stay paper-only; each says so. The rigs of several tendons have their own
fixtures and end-to-end runs (``tests/test_tendons.py``, ``tests/test_every_rig.py``).
"""

from __future__ import annotations

import pytest

from rigs import SHIPPED, ShippedRig


@pytest.fixture(params=list(SHIPPED), ids=list(SHIPPED))
def rig_file(request) -> ShippedRig:
    """Each shipped single-tendon rig file (pass ``rig_file.load()`` to the code under test)."""
    return SHIPPED[request.param]


@pytest.fixture(params=list(SHIPPED), ids=list(SHIPPED))
def shipped_rig(request) -> ShippedRig:
    """Each shipped single-tendon rig file, as the rig a driver or a command is given."""
    return SHIPPED[request.param]
