"""The package's import graph has no cycle.

Every module under ``src/pfslam`` is read with :mod:`ast` (nothing is imported). Its imports
at module level and inside functions and classes are edges: ``import pfslam.x.y`` to
``pfslam.x.y``; ``from pfslam.x import y`` to ``pfslam.x.y`` when that is a module, else to
``pfslam.x``; relative imports resolved the same way. Imports under ``if TYPE_CHECKING:`` are
left out (they never run: that is how a type-only reference avoids a cycle), and so is the
implicit import of the parent packages (importing ``pfslam.io.common`` runs
``pfslam/io/__init__.py`` first, but that is no edge to ``pfslam.io``).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"


def module_files(root: Path, package: str) -> dict[str, Path]:
    """Module name -> file, for the package ``package`` in the folder ``root``."""
    out: dict[str, Path] = {}
    for path in sorted((root / package.replace(".", "/")).rglob("*.py")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _imports(tree: ast.AST) -> list[ast.Import | ast.ImportFrom]:
    """Every import statement of ``tree`` at any depth, except under ``if TYPE_CHECKING:``."""
    found: list[ast.Import | ast.ImportFrom] = []

    def visit(node: ast.AST) -> None:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            found.append(node)
        elif isinstance(node, ast.If) and _is_type_checking(node.test):
            for child in node.orelse:  # the else branch does run
                visit(child)
            return
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return found


def import_graph(root: Path, package: str) -> dict[str, set[str]]:
    """module -> the modules of ``package`` it imports (see the module docstring)."""
    files = module_files(root, package)
    graph: dict[str, set[str]] = {}
    for name, path in files.items():
        is_package = path.name == "__init__.py"
        edges: set[str] = set()
        for node in _imports(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                if node.level:
                    here = name.split(".") if is_package else name.split(".")[:-1]
                    base_parts = here[: len(here) - (node.level - 1)]
                    base = ".".join(base_parts + ([node.module] if node.module else []))
                else:
                    base = node.module or ""
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in files else base for a in node.names]
            edges |= {t for t in targets if t in files}
        graph[name] = edges
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A cycle of ``graph`` as [a, b, ..., a], or None if it has none."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def dfs(node: str) -> list[str] | None:
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state and (cycle := dfs(nxt)) is not None:
                return cycle
        path.pop()
        state[node] = 2
        return None

    for start in sorted(graph):
        if start not in state and (cycle := dfs(start)) is not None:
            return cycle
    return None


def test_the_package_has_no_import_cycle():
    graph = import_graph(SRC, "pfslam")
    # The reader sees the package: its modules, and edges that are known to exist.
    assert {"pfslam", "pfslam.cli", "pfslam.config", "pfslam.filters.single", "pfslam.kernels.raycast",
            "pfslam.io.common"} <= set(graph)
    assert "pfslam.kernels.raycast" in graph["pfslam.maps.grid"]  # from pfslam.kernels.raycast import ...
    assert "pfslam.filters.single" in graph["pfslam.pipeline"]  # imported inside a function
    assert "pfslam.errors" in graph["pfslam.cli"]
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


def _package(root: Path, files: dict[str, str]) -> None:
    for rel, text in files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)


def test_a_cycle_is_found_and_named(tmp_path):
    # a imports b at module level; b imports a inside a function: still a cycle.
    _package(tmp_path, {
        "fake/__init__.py": "",
        "fake/a.py": "from fake import b\n",
        "fake/b.py": "import os\n\ndef f():\n    from fake.a import thing\n    return thing\n",
        "fake/c.py": "from .b import f\n",
    })
    graph = import_graph(tmp_path, "fake")
    assert graph == {"fake": set(), "fake.a": {"fake.b"}, "fake.b": {"fake.a"}, "fake.c": {"fake.b"}}
    assert find_cycle(graph) == ["fake.a", "fake.b", "fake.a"]


def test_parent_packages_type_checking_and_names_are_no_edges(tmp_path):
    _package(tmp_path, {
        "fake/__init__.py": "from fake.sub import leaf\n",
        "fake/sub/__init__.py": "from .leaf import VALUE\n",
        "fake/sub/leaf.py": "VALUE = 1\n",
        # Imports a module of fake.sub: runs fake/__init__.py first, which imports leaf;
        # that implicit parent import is no edge back to fake.
        "fake/user.py": ("from typing import TYPE_CHECKING\n"
                         "import fake.sub.leaf\n"
                         "from fake.sub import VALUE\n"
                         "if TYPE_CHECKING:\n    from fake import user\n"),
    })
    graph = import_graph(tmp_path, "fake")
    assert graph["fake.user"] == {"fake.sub.leaf", "fake.sub"}  # VALUE is a name of fake.sub
    assert graph["fake"] == {"fake.sub.leaf"} and graph["fake.sub"] == {"fake.sub.leaf"}
    assert find_cycle(graph) is None
    # The same import outside TYPE_CHECKING is a self-cycle.
    (tmp_path / "fake/user.py").write_text("from fake import user\n")
    assert find_cycle(import_graph(tmp_path, "fake")) == ["fake.user", "fake.user"]


@pytest.mark.parametrize("graph, has_cycle", [
    ({"a": {"b"}, "b": {"c"}, "c": set()}, False),
    ({"a": {"b", "c"}, "b": {"c"}, "c": set()}, False),  # a diamond is no cycle
    ({"a": {"b"}, "b": {"c"}, "c": {"a"}}, True),
])
def test_find_cycle_on_small_graphs(graph, has_cycle):
    cycle = find_cycle(graph)
    assert (cycle is not None) == has_cycle
    if cycle:
        assert cycle[0] == cycle[-1] and all(b in graph[a] for a, b in zip(cycle, cycle[1:]))
