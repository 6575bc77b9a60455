"""recon's modules import each other without a cycle: the package reads bottom-up, and no import has to be deferred
into a function body to break one. Only module-level imports count (a deferred import of a heavy dependency,
build123d, is a choice of when to load it, not of structure); ``if TYPE_CHECKING:`` blocks do not count either."""

from __future__ import annotations

import ast
from pathlib import Path

import recon

ROOT = Path(recon.__file__).resolve().parent


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _module_level(body):
    """The import statements run when the module is imported: top level, and inside top-level if/try/with."""
    for node in body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        elif isinstance(node, ast.If):
            test = node.test
            if isinstance(test, ast.Name) and test.id == "TYPE_CHECKING" or \
                    isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING":
                yield from _module_level(node.orelse)
                continue
            yield from _module_level(node.body)
            yield from _module_level(node.orelse)
        elif isinstance(node, ast.Try):
            for block in (node.body, node.orelse, node.finalbody, *(h.body for h in node.handlers)):
                yield from _module_level(block)
        elif isinstance(node, ast.With):
            yield from _module_level(node.body)


def import_graph() -> dict[str, set[str]]:
    """Module name → the recon modules it imports at module level."""
    files = {_module_name(p): p for p in ROOT.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in files.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        out = set()
        for node in _module_level(ast.parse(path.read_text(encoding="utf-8")).body):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                base = package
                for _ in range(node.level - 1):
                    base = base.rpartition(".")[0]
                base = (base + "." + node.module if node.module else base) if node.level else node.module or ""
                # `from . import x`: x is a submodule where one exists, else a name in the package
                targets = [base + "." + a.name if base + "." + a.name in files else base for a in node.names]
            out |= {t for t in targets if t in files and t != name}
        graph[name] = out
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` as a list of nodes (first == last), or None (an iterative depth-first search)."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    for start in sorted(graph):
        if state.get(start):
            continue
        path, stack = [start], [iter(sorted(graph[start]))]
        state[start] = 1
        while stack:
            nxt = next(stack[-1], None)
            if nxt is None:
                state[path.pop()] = 2
                stack.pop()
            elif state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            elif not state.get(nxt):
                state[nxt] = 1
                path.append(nxt)
                stack.append(iter(sorted(graph[nxt])))
    return None


def test_find_cycle_finds_one_and_only_one():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None


def test_the_graph_sees_relative_imports():
    graph = import_graph()
    # (known edges: a failure here means the walk misses imports, not that recon changed shape)
    assert "recon.fit._types" in graph["recon.fit._select"]
    assert "recon.errors" in graph["recon.mesh._clean"]
    assert "recon.segment" in graph["recon.pipeline"]


def test_recon_imports_no_cycle():
    assert find_cycle(import_graph()) is None


def test_array_helpers_import_nothing_of_recon():
    assert import_graph()["recon._array"] == set()


def test_the_mesh_layer_does_not_import_the_fitters():
    graph = import_graph()
    mesh = [m for m in graph if m.startswith("recon.mesh")]
    assert mesh and not any(t.startswith("recon.fit") for m in mesh for t in graph[m])


def test_the_fitters_defer_no_import_of_their_own():
    # the fit package's modules used to import each other inside function bodies to hide a cycle
    # (_bspline ↔ _surfaces ↔ _types ↔ _curves): every import of recon there is now at module level
    deferred = []
    for path in (ROOT / "fit").glob("*.py"):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        top = set(map(id, _module_level(tree.body)))
        deferred += [f"{path.name}:{n.lineno}" for n in ast.walk(tree)
                     if isinstance(n, ast.ImportFrom) and n.level and id(n) not in top]
    assert deferred == []
