"""The import rules of docs/architecture.md, read from every ``import`` in cvkit/."""
from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "cvkit"
COMMANDS = {"cvkit.cli", "cvkit.scaffold", "cvkit.catalog"}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _imports(name: str, path: Path) -> list[tuple[str, str, int]]:
    """(imported module, imported name or "", line) for every import of a cvkit module."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [(alias.name, "", node.lineno) for alias in node.names if alias.name.split(".")[0] == "cvkit"]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "cvkit":
                continue
            for alias in node.names:
                submodule = f"{target}.{alias.name}"
                found.append((submodule, "", node.lineno) if submodule in MODULES else (target, alias.name, node.lineno))
    return found


def layer(name: str) -> int:
    """The layer of a module, as in docs/architecture.md's table."""
    parts = name.split(".")
    if name in ("cvkit._validation", "cvkit._text"):
        return 0
    if name in ("cvkit", "cvkit.registry"):
        return 1
    if name.startswith("cvkit.grading.runtime"):
        return 3
    if name.startswith("cvkit.grading"):
        return 4
    if name.startswith("cvkit.sandbox"):
        return 6
    if name.startswith("cvkit.course"):
        return 7
    if name in COMMANDS:
        return 8
    if len(parts) >= 3 and parts[2] == "checks":
        return 5
    return 2


def _room(name: str) -> str:
    """The package a module belongs to (``cvkit.filters`` for ``cvkit.filters._linear``; a
    topic's checks and the sandbox runtime count as packages of their own)."""
    parts = name.split(".")
    if parts[:3] == ["cvkit", "grading", "runtime"] or len(parts) >= 3 and parts[2] == "checks" and parts[1] != "grading":
        return ".".join(parts[:3])
    return ".".join(parts[:2])


def _package(name: str) -> str:
    """The package that owns a private name: ``cvkit.<topic>`` or ``cvkit.grading``."""
    return ".".join(name.split(".")[:2])


@functools.cache
def edges() -> list[tuple[str, str, str, int]]:
    """(importing module, imported module, imported name or "", line) for every import in cvkit/
    (read when a test asks, not while pytest collects)."""
    return [(source, target, imported, line)
            for source, path in MODULES.items() for target, imported, line in _imports(source, path)]


def test_the_modules_and_imports_were_found():
    assert {"cvkit.registry", "cvkit.grading.engine", "cvkit.filters._linear", "cvkit.filters.checks"} <= set(MODULES)
    assert len(edges()) > 100


def _allowed(source: str, target: str) -> bool:
    a, b = layer(source), layer(target)
    if _room(source) == _room(target) or b < a or (source, target) == ("cvkit", "cvkit.registry"):
        return True
    if a == 6 and b == 5:  # the sandbox runs any check's cases without knowing the checks
        return False
    if a == b and a in (2, 5, 8):  # topics build on topics, checks on checks, commands on each other
        return True
    return False


def test_every_import_respects_the_layers():
    wrong = [f"{s} (layer {layer(s)}) imports {t} (layer {layer(t)}) at line {line}"
             for s, t, _, line in edges() if not _allowed(s, t)]
    assert not wrong, "imports against docs/architecture.md:\n" + "\n".join(wrong)


def test_the_runtime_in_the_sandbox_is_self_contained():
    outside = [f"{s} imports {t}" for s, t, _, _ in edges()
               if _room(s) == "cvkit.grading.runtime" and _room(t) != "cvkit.grading.runtime"]
    assert not outside, outside


def test_grading_reaches_the_library_only_through_the_registry():
    direct = [f"{s} imports {t}" for s, t, _, _ in edges()
              if layer(s) in (4, 6) and layer(t) == 2 and _room(t) != "cvkit.data"]
    assert not direct, direct


def test_the_library_never_imports_grading_course_or_commands():
    upward = [f"{s} imports {t}" for s, t, _, _ in edges() if layer(s) <= 2 and layer(t) >= 3]
    assert not upward, upward


def test_no_private_name_crosses_a_package():
    crossing = [f"{s} imports {t}{'.' + n if n else ''} (line {line})" for s, t, n, line in edges()
                if _package(s) != _package(t) and (n.startswith("_") and not n.startswith("__")
                                              or t.rpartition(".")[2].startswith("_") and _room(t) != t
                                              and layer(t) != 0)]
    assert not crossing, "private names used across packages:\n" + "\n".join(crossing)


def test_no_import_cycles_between_packages():
    graph: dict[str, set[str]] = {}
    for s, t, _, _ in edges():
        if _room(s) != _room(t) and t != "cvkit" and s != "cvkit":
            graph.setdefault(_room(s), set()).add(_room(t))
    state: dict[str, int] = {}
    cycle: list[str] = []

    def visit(node: str, path: list[str]) -> bool:
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                cycle.extend(path + [node, nxt])
                return True
            if nxt not in state and visit(nxt, path + [node]):
                return True
        state[node] = 2
        return False

    for node in sorted(graph):
        if node not in state and visit(node, []):
            break
    assert not cycle, " -> ".join(cycle)


def _top_level_imports(name: str, path: Path) -> set[str]:
    """The cvkit modules ``name`` imports when it is imported: the imports of its body (also
    inside a top-level ``try`` or ``if``), not those of functions or ``if TYPE_CHECKING:``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    lines = set()
    for node in tree.body:
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            lines.add(node.lineno)
        elif isinstance(node, (ast.Try, ast.If)):
            lines |= {n.lineno for n in ast.walk(node) if isinstance(n, (ast.Import, ast.ImportFrom))}
    return {t for t, _, line in _imports(name, path) if line in lines and t in MODULES and t != name}


def _cycle(graph: dict[str, set[str]]) -> list[str]:
    """A cycle of ``graph`` (module → the modules it imports), as a path, or []."""
    state: dict[str, int] = {}

    def visit(node: str, path: list[str]) -> list[str]:
        state[node] = 1
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return path + [node, nxt]
            if nxt not in state:
                found = visit(nxt, path + [node])
                if found:
                    return found
        state[node] = 2
        return []

    for node in sorted(graph):
        if node not in state:
            cycle = visit(node, [])
            if cycle:
                return cycle
    return []


def test_no_import_cycle_between_modules_at_import_time():
    """No module of cvkit imports, at import time, a module that imports it back (directly or
    through others): every module can be read, and loaded, after the ones it needs."""
    graph = {name: _top_level_imports(name, path) for name, path in MODULES.items()}
    assert not _cycle(graph), "import cycle: " + " -> ".join(_cycle(graph))
    assert sum(len(v) for v in graph.values()) > 200  # the graph was read


@functools.cache
def _type_only_lines(path: Path) -> frozenset[int]:
    """The lines of a module's ``if TYPE_CHECKING:`` imports (read by type checkers, never run)."""
    lines = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            lines |= {n.lineno for n in ast.walk(node) if isinstance(n, (ast.Import, ast.ImportFrom))}
    return frozenset(lines)


def test_no_import_cycle_between_modules_anywhere():
    """The same with every import that runs: those of a module's functions too (made when they
    run), not only those of its body. Only ``if TYPE_CHECKING:`` imports (annotations) are left
    out. A package's ``__init__`` re-exports its modules and is imported by none of them, so it
    is a module like the others here."""
    graph: dict[str, set[str]] = {name: set() for name in MODULES}
    for source, target, _, line in edges():
        if target in MODULES and target != source and line not in _type_only_lines(MODULES[source]):
            graph[source].add(target)
    assert not _cycle(graph), "import cycle: " + " -> ".join(_cycle(graph))


def test_grading_and_sandbox_know_no_course():
    """The engine and the sandbox serve the course, never the other way round: neither imports
    ``cvkit.course`` (nbgrader, notebooks' grade ids, course folders) or the commands."""
    upward = [f"{s} imports {t} (line {line})" for s, t, _, line in edges()
              if s.startswith(("cvkit.grading", "cvkit.sandbox")) and (t.startswith("cvkit.course") or t in COMMANDS)]
    assert not upward, upward


def test_the_course_facade_is_imported_only_by_the_commands():
    """``cvkit.course.course`` (the :class:`Course` façade) is at the top of the course: the
    course's modules depend on the course state (``cvkit.course.state``), and only the commands
    and the package's ``__init__`` (its public name) import the façade."""
    users = sorted({s for s, t, _, _ in edges() if t == "cvkit.course.course"})
    assert set(users) <= COMMANDS | {"cvkit.course"}, users


def test_no_dynamic_import_crosses_the_layers():
    """``importlib.import_module("cvkit....")`` and ``__import__`` obey the same rules as ``import``:
    the test above cannot see them, so they are read here."""
    wrong = []
    for name, path in MODULES.items():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.Call) or not node.args or not isinstance(node.args[0], ast.Constant):
                continue
            called = ast.unparse(node.func)
            target = node.args[0].value
            if called not in ("importlib.import_module", "import_module", "__import__") or not isinstance(target, str) \
                    or not target.startswith("cvkit"):
                continue
            runtime_leaves = _room(name) == "cvkit.grading.runtime" and _room(target) != "cvkit.grading.runtime"
            if runtime_leaves or not _allowed(name, target):
                wrong.append(f"{name} imports {target} dynamically at line {node.lineno}")
    assert not wrong, "\n".join(wrong)


@pytest.mark.parametrize("source, target, ok", [
    ("cvkit.filters._linear", "cvkit.grading.engine", False),
    ("cvkit.filters.checks", "cvkit.grading.compare", True),
    ("cvkit.grading.engine", "cvkit.course", False),
    ("cvkit.calibration._zhang", "cvkit.camera._projection", True),
    ("cvkit.registry", "cvkit.filters", False),
])
def test_the_rules_themselves(source, target, ok):
    assert _allowed(source, target) is ok
