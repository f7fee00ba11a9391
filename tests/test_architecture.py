"""The package's rooms and their one-way flow, measured from the code's own imports (docs/architecture.md).

Every module of ``helpers`` is given a layer below; a module may import only modules of a lower layer, or of
its own layer inside the same room (package). No cycles, and no function-local import of the package's own
modules (a local import is how a cycle is usually hidden); the command line dispatcher is the one place that
imports command modules by name, so that ``python -m helpers --help`` does not load numba and scipy.
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

from helpers.paths import REPO_ROOT

PACKAGE = REPO_ROOT / "helpers"

LAYERS: dict[str, int] = {
    # 0: base facts and utilities
    "helpers.paper": 0,
    "helpers.paths": 0,
    "helpers.validate": 0,
    "helpers.modes": 0,
    "helpers.jsonfile": 0,
    "helpers.style": 0,
    "helpers.crc8": 0,
    "helpers.signals": 0,
    "helpers.noise": 0,
    "helpers.locks": 0,
    "helpers.rigfile": 0,
    "helpers.hardware": 1,
    "helpers.scenarios": 2,
    "helpers.modemap": 1,
    "helpers.backbone": 1,
    "helpers.notebook": 1,
    # 2: the linear model, the recording format, the serial protocol
    "helpers.model": 2,
    "helpers.recordings": 2,
    "helpers.protocol": 2,
    # 3: what is derived from recordings and models
    "helpers.loadcell": 3,
    "helpers.identify": 3,
    "helpers.shapers": 3,
    "helpers.ringdown": 4,
    "helpers.streaming": 3,
    "helpers.profiles": 4,
    "helpers.design": 4,
    "helpers.robustness": 4,
    "helpers.programmes": 5,
    # 6: the rig and the virtual rig side by side; the emulated boards above the physics
    "helpers.rig": 6,
    "helpers.virtual": 6,
    "helpers.emulator": 7,
    # 8: analysis
    "helpers.metrics": 8,
    "helpers.tables": 8,
    "helpers.plotting": 9,
    # 10: procedures that combine the rooms, and the command line
    "helpers.rig_tuning": 10,
    "helpers.rig_file_tuning": 11,
    "helpers.record": 10,
    "helpers.home": 10,
    "helpers.frame_command": 10,
    "helpers.summary": 10,
    "helpers.playground": 10,
    "helpers.survey": 10,
    "helpers.teleop": 9,
    "helpers.tune": 11,
    "helpers.table2": 10,
    "helpers.sweep": 10,
    "helpers.reproduce": 11,
    "helpers.benchmarks": 11,
    "helpers.rig_studies": 12,
    "helpers.rig_command": 11,
    "helpers.__main__": 12,
}
"""Layer of each module or room (a room's submodules share its layer)."""

DISPATCHERS = {"helpers.__main__"}
"""Modules allowed to import package modules by name at run time (the command line)."""


def _module_name(path: Path) -> str:
    rel = path.relative_to(REPO_ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _room(name: str) -> str:
    """The entry of LAYERS that ``name`` belongs to (itself or its package)."""
    parts = name.split(".")
    for n in range(len(parts), 0, -1):
        candidate = ".".join(parts[:n])
        if candidate in LAYERS:
            return candidate
    raise KeyError(name)


def _imports(path: Path, name: str) -> tuple[set[str], list[tuple[int, str]]]:
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
            inner = in_function or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef)
            for t in targets(child):
                if t.split(".")[0] == "helpers":
                    (local.append((child.lineno, t)) if in_function else top.add(t))
            visit(child, inner)

    visit(tree, False)
    return {t for t in top if t in modules and t != name}, local


def test_every_module_has_a_layer():
    missing = [m for m in _modules() if m != "helpers" and _safe_room(m) is None]
    assert not missing, f"add these modules to LAYERS and docs/architecture.md: {missing}"


def _safe_room(name: str) -> str | None:
    try:
        return _room(name)
    except KeyError:
        return None


def test_imports_flow_one_way():
    problems = []
    for name, path in _modules().items():
        if name == "helpers":
            continue
        own_room = _room(name)
        for target in _imports(path, name)[0]:
            if target == "helpers":
                continue
            other = _room(target)
            if other == own_room:
                continue  # inside one room
            if LAYERS[other] >= LAYERS[own_room]:
                problems.append(f"{name} (layer {LAYERS[own_room]}) imports {target} (layer {LAYERS[other]})")
    assert not problems, "\n".join(problems)


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
    ],
)
def test_rooms_import_without_what_they_do_not_need(module, blocked):
    proc = _import_without(module, blocked)
    assert proc.returncode == 0, proc.stderr[-1500:]


def test_virtual_scheme_is_registered_by_opening_a_port_not_by_importing():
    code = (
        "import serial, helpers.rig\n"
        "assert 'helpers.emulator' not in serial.protocol_handler_packages, 'registered on import'\n"
        "from helpers.rig.ports import open_port\n"
        "p = open_port('virtual://daq?rig=arch', baudrate=500000, timeout=0.01, write_timeout=1.0)\n"
        "assert 'helpers.emulator' in serial.protocol_handler_packages\n"
        "p.close()\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-1500:]


ONE_HOME = {
    "MM_PER_STEP": "helpers.hardware",
    "LIMITS": "helpers.hardware",
    "MAX_TRAVEL_MM": "helpers.hardware",
    "MAX_SPEED_MM_S": "helpers.hardware",
    "ADC_MAX": "helpers.hardware",
    "DAQ_RATE_MIN_HZ": "helpers.hardware",
    "FW_VERSION": "helpers.protocol",
    "SCHEMA_VERSION": "helpers.recordings.format",
    "IDENTIFICATION_RESULT": "helpers.paths",
    "LOADCELL_CALIBRATION": "helpers.paths",
    "VIRTUAL_RIG_REGISTRY": "helpers.paths",
    "E_A228": "helpers.backbone",
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
                if t in ONE_HOME and ONE_HOME[t] != name:
                    problems.append(f"{t} is defined in {name}, its home is {ONE_HOME[t]}")
    assert not problems, "\n".join(problems)


def test_the_spool_and_steps_give_the_cable_per_step():
    from helpers import hardware, paper

    # 65 mm spool and 800 steps per revolution (the paper): pi * 65 / 800 mm per step
    assert (paper.SPOOL_DIAMETER_M, paper.STEPS_PER_REV) == (0.065, 800)
    assert hardware.MM_PER_STEP == pytest.approx(0.2552544, abs=1e-7)
    assert hardware.LIMITS.max_position_steps * hardware.MM_PER_STEP <= hardware.MAX_TRAVEL_MM
