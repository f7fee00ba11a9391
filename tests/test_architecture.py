"""The package's wings and their one-way flow, measured from the code's own imports (docs/architecture.md).

Every module of ``helpers`` belongs to one wing: the core (the paper's part), the twin (the virtual rig), the
research beyond the paper, or the commands. Imports point towards the core: the core imports nothing of the
other wings, the twin only the core, the research the core and the twin, the commands anything. Inside the
core, ``helpers.base`` needs nothing else, ``helpers.paper`` only ``base``, and the rig's serial I/O imports
no physics. No cycles, and no function-local import of the package's own modules (a local import is how a
cycle is usually hidden); the command line dispatcher is the one place that imports command modules by name,
so that ``python -m helpers --help`` does not load numba and scipy. The one map of the package is
``docs/architecture.md``: a module it does not name, or a name in it with no module, fails here.
"""

from __future__ import annotations

import ast
import functools
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from helpers.base.paths import REPO_ROOT

PACKAGE = REPO_ROOT / "helpers"
MAP = REPO_ROOT / "docs" / "architecture.md"

WINGS: dict[str, str] = {
    "helpers.base": "core",
    "helpers.paper": "core",
    "helpers.recordings": "core",
    "helpers.board": "core",
    "helpers.rig": "core",
    "helpers.rigfile": "core",
    "helpers.plotting": "core",
    "helpers.virtual": "twin",
    "helpers.research": "research",
    "helpers.commands": "commands",
    "helpers.__main__": "commands",
}
"""Package (or module) -> its wing."""

MAY_IMPORT: dict[str, set[str]] = {
    "core": {"core"},
    "twin": {"core", "twin"},
    "research": {"core", "twin", "research"},
    "commands": {"core", "twin", "research", "commands"},
}
"""Wing -> the wings its modules may import."""

CORE_INSIDE: dict[str, tuple[str, ...]] = {
    "helpers.base": ("helpers.base",),
    "helpers.rigfile": ("helpers.base", "helpers.rigfile"),
    "helpers.paper": ("helpers.base", "helpers.rigfile", "helpers.paper"),
}
"""Core packages that may import only these (the utilities; the paper's part on the utilities)."""

DISPATCHERS = {"helpers.__main__"}
"""Modules allowed to import package modules by name at run time (the command line)."""


def _module_name(path: Path) -> str:
    rel = path.relative_to(REPO_ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


@functools.cache  # the tree does not change during a test run; read it once
def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _wing(name: str) -> str | None:
    """The wing of module ``name`` (None for the package itself or a module outside every wing)."""
    parts = name.split(".")
    for n in range(len(parts), 1, -1):
        wing = WINGS.get(".".join(parts[:n]))
        if wing is not None:
            return wing
    return None


@functools.cache
def _imports(path: Path, name: str) -> tuple[frozenset[str], tuple[tuple[int, str], ...]]:
    """Package modules imported at module level, and (line, module) of function-local ones."""
    tree = ast.parse(path.read_text(), filename=str(path))
    modules = _modules()
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    top: set[str] = set()
    local: list[tuple[int, str]] = []

    def targets(node: ast.AST) -> list[str]:
        if isinstance(node, ast.Import):
            return [a.name for a in node.names]
        if isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join([*parts[: len(parts) - node.level + 1], base]).strip(".")
            # "from pkg import mod" imports the module pkg.mod; "from mod import name" imports mod
            return [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
        return []

    def visit(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            test = child.test if isinstance(child, ast.If) else None
            if isinstance(test, ast.Name) and test.id == "TYPE_CHECKING":
                continue  # an import for type hints only is no dependency at run time
            inner = in_function or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef)
            for t in targets(child):
                if t.split(".")[0] == "helpers":
                    (local.append((child.lineno, t)) if in_function else top.add(t))
            visit(child, inner)

    visit(tree, False)
    return frozenset(t for t in top if t in modules and t != name), tuple(local)


def test_every_module_is_in_a_wing():
    missing = [m for m in _modules() if m != "helpers" and _wing(m) is None]
    assert not missing, f"add these modules to a wing (WINGS) and to docs/architecture.md: {missing}"


def test_imports_point_towards_the_core():
    problems = []
    for name, path in _modules().items():
        own = _wing(name)
        for target in _imports(path, name)[0]:
            if target != "helpers" and _wing(target) not in MAY_IMPORT.get(own, {"core"}):
                problems.append(f"{name} ({own}) imports {target} ({_wing(target)})")
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("package", sorted(CORE_INSIDE))
def test_the_core_utilities_and_the_paper_need_only_what_is_below_them(package):
    problems = []
    for name, path in _modules().items():
        if name == package or name.startswith(package + "."):
            for target in _imports(path, name)[0]:
                if target != "helpers" and not any(
                    target == ok or target.startswith(ok + ".") for ok in CORE_INSIDE[package]
                ):
                    problems.append(f"{name} imports {target}")
    assert not problems, "\n".join(problems)


def test_the_rig_imports_no_physics():
    problems = []
    for name, path in _modules().items():
        if name.split(".")[:2] in (["helpers", "rig"], ["helpers", "live"]):
            physics = [t for t in _imports(path, name)[0] if t.startswith("helpers.virtual")]
            problems += [f"{name} imports {t}" for t in physics]
            tree = ast.parse(path.read_text())
            for node in ast.walk(tree):
                if isinstance(node, ast.Import | ast.ImportFrom):
                    is_import = isinstance(node, ast.Import)
                    mods = [a.name for a in node.names] if is_import else [node.module or ""]
                    problems += [f"{name} imports {m}" for m in mods if m.split(".")[0] in ("numba", "scipy")]
    assert not problems, "\n".join(problems)


def _mapped_modules() -> list[str]:
    """The modules named in the first column of the tables under the map's ``## Every module``."""
    text = MAP.read_text()
    section = text[text.index("## Every module") :]
    names = []
    for line in section.splitlines():
        cells = line.split("|")
        if line.startswith("|") and len(cells) > 2:
            names += re.findall(r"`(helpers[\w.]*)`", cells[1])
    return names


def test_the_map_names_every_module_and_no_other():
    named = _mapped_modules()
    modules = set(_modules()) - {"helpers"}
    assert len(named) == len(set(named)), "a module is named twice in docs/architecture.md"
    missing = sorted(modules - set(named))
    stale = sorted(set(named) - modules)
    assert not missing, f"docs/architecture.md does not name: {missing}"
    assert not stale, f"docs/architecture.md names modules that do not exist: {stale}"


def test_the_package_docstring_points_to_the_map_instead_of_keeping_its_own():
    import helpers

    assert "docs/architecture.md" in helpers.__doc__
    table = re.search(r"^\s+\w+(, \w+)+\s{3,}\w", helpers.__doc__, re.M)
    assert not table, "a table of modules in the package's docstring"


def test_no_function_local_imports_of_the_package():
    problems = []
    for name, path in _modules().items():
        if name in DISPATCHERS:
            continue
        where = path.relative_to(REPO_ROOT)
        problems += [f"{where}:{line} imports {t}" for line, t in _imports(path, name)[1]]
        if "importlib" in path.read_text():
            problems.append(f"{path.relative_to(REPO_ROOT)} uses importlib")
    assert not problems, "\n".join(problems)


def test_no_import_cycle():
    # a package's __init__ importing its own submodules is the package's structure, not a cycle
    graph = {}
    for name, path in _modules().items():
        own = path.name == "__init__.py"
        deps = _imports(path, name)[0] - {"helpers"}
        graph[name] = {m for m in deps if not (own and m.startswith(name + "."))}
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n: str) -> None:
        state[n] = 1
        stack.append(n)
        for m in graph.get(n, ()):
            if state.get(m) == 1:
                raise AssertionError("import cycle: " + " -> ".join(stack[stack.index(m) :] + [m]))
            if m not in state:
                visit(m)
        stack.pop()
        state[n] = 2

    for n in graph:
        if n not in state:
            visit(n)


def _import_without(module: str, blocked: str) -> subprocess.CompletedProcess:
    code = f"import sys; sys.modules[{blocked!r}] = None; import {module}"
    env = dict(os.environ)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)


@pytest.mark.parametrize(
    ("module", "blocked"),
    [
        ("helpers.virtual", "serial"),  # the physics needs no serial port
        ("helpers.rig", "numba"),  # the drivers need no compiler
        ("helpers.rig", "helpers.virtual"),  # ... nor the physics
        ("helpers.paper.metrics", "helpers.research"),  # the paper's part needs no research
    ],
)
def test_wings_import_without_what_they_do_not_need(module, blocked):
    proc = _import_without(module, blocked)
    assert proc.returncode == 0, proc.stderr[-1500:]


def test_the_drivers_package_leaves_streams_to_those_who_import_them():
    """The notebooks' live cells import ``helpers.rig``: its streams (``helpers.rig.stream``) stay out."""
    code = "import sys, helpers.rig; assert 'helpers.rig.stream' not in sys.modules, sorted(sys.modules)"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-1500:]


def test_virtual_scheme_is_registered_by_opening_a_port_not_by_importing():
    code = (
        "import serial, helpers.rig\n"
        "assert 'helpers.virtual.emulator' not in serial.protocol_handler_packages, 'registered on import'\n"
        "from helpers.rig.link import open_port\n"
        "p = open_port('virtual://daq?world=arch', 'daq', 500000, 1.0)\n"
        "assert 'helpers.virtual.emulator' in serial.protocol_handler_packages\n"
        "p.close()\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-1500:]


RIG_NUMBERS = ("MM_PER_STEP", "LIMITS", "MAX_TRAVEL_MM", "MAX_SPEED_MM_S", "ADC_MAX", "DAQ_RATE_MIN_HZ",
               "DAQ_RATE_MAX_HZ", "MAX_PROGRAMME_S", "DAQ_BAUD", "STEPPER_BAUD", "RIG")  # fmt: skip
"""The rig's numbers that were module constants of ``helpers.paper.hardware`` (read from the selected rig at
import): the rig is a value now (``helpers.rigfile.derived(rig)``, ``Limits.of(rig)``), bound nowhere."""

ONE_HOME = {
    **dict.fromkeys(RIG_NUMBERS),
    "FW_VERSION": "helpers.board.protocol",
    "IDENTIFICATION_RESULT": "helpers.base.paths",
    "LOADCELL_CALIBRATION": "helpers.base.paths",
    "VIRTUAL_RIG_REGISTRY": "helpers.base.paths",
    "E_A228": "helpers.paper.backbone",
}
"""Names that may be bound (assigned, not imported) in one module only."""


def test_each_fact_has_one_home():
    problems = []
    for name, path in _modules().items():
        tree = ast.parse(path.read_text())
        for node in tree.body:
            targets = []
            if isinstance(node, ast.Assign):
                targets = [t.id for t in node.targets if isinstance(t, ast.Name)]
            elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
                targets = [node.target.id]
            for t in targets:
                if t in ONE_HOME and ONE_HOME[t] is None:
                    problems.append(f"{t} is bound in {name}: the rig's numbers come from the rig, a value")
                elif t in ONE_HOME and ONE_HOME[t] != name:
                    problems.append(f"{t} is defined in {name}, its home is {ONE_HOME[t]}")
    assert not problems, "\n".join(problems)


def test_the_spool_and_steps_give_the_cable_per_step():
    from helpers import rigfile
    from helpers.board.programmes import Limits
    from helpers.paper import numbers as paper

    # 65 mm spool and 800 steps per revolution (the paper): pi * 65 / 800 mm per step
    assert (paper.SPOOL_DIAMETER_M, paper.STEPS_PER_REV) == (0.065, 800)
    limits = Limits.of(rigfile.default_rig())
    assert limits.mm_per_step[0] == pytest.approx(0.2552544, abs=1e-7)
    assert limits.travel_steps[0] * limits.mm_per_step[0] <= 40.0 < (limits.travel_steps[0] + 1) * 0.2552544
