"""The import graph of hgo_mj (``hgo_mj.envs`` included) has no circle.

The modules' imports are read with :mod:`ast`, not run: every ``import hgo_mj.x`` and
``from .x import y`` / ``from hgo_mj.x import y``, at module level and inside functions alike (a
function-level import is still an arrow: one made late only to dodge a circle is a circle).
Imports under ``if TYPE_CHECKING:`` are left out (they never run). ``from .pkg import name`` is an
arrow to the submodule ``pkg.name`` when there is one, else to the package (its ``__init__``).
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"hgo_mj": ROOT / "hgo_mj", "hgo_mj.envs": ROOT / "envs", "hgo_mj.models": ROOT / "models"}


def modules() -> dict[str, Path]:
    """Every module of the package, by dotted name (``hgo_mj.envs.*`` from ``envs/``,
    ``hgo_mj.models`` from ``models/``)."""
    found: dict[str, Path] = {}
    for prefix, folder in PACKAGES.items():
        for path in sorted(folder.rglob("*.py")):
            rel = path.relative_to(folder).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            if prefix == "hgo_mj" and parts[:1] in (["envs"], ["models"]):
                continue  # the symlinks hgo_mj/envs and hgo_mj/models (read from envs/ and models/)
            found[".".join([prefix, *parts])] = path
    return found


def _type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _imports(tree: ast.AST) -> list[ast.Import | ast.ImportFrom]:
    """The import statements of a module, at any depth, outside ``if TYPE_CHECKING:``."""
    out: list[ast.Import | ast.ImportFrom] = []
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, ast.If) and _type_checking(node):
            stack.extend(node.orelse)
            continue
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            out.append(node)
        stack.extend(ast.iter_child_nodes(node))
    return out


def arrows(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """The modules of the package that the module ``name`` imports."""
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    out: set[str] = set()
    for node in _imports(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
            bases: list[tuple[str, list[str]]] = [(t, []) for t in targets]
        else:
            if node.level:
                base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
                base = f"{base}.{node.module}" if node.module else base
            else:
                base = node.module or ""
            bases = [(base, [alias.name for alias in node.names])]
        for base, names in bases:
            subs = [f"{base}.{n}" for n in names if f"{base}.{n}" in known]
            if subs:
                out.update(subs)
            if len(subs) < len(names) or not names:
                while base and base not in known:  # import a.b.c of a module a.b
                    base = base.rpartition(".")[0]
                if base:
                    out.add(base)
    out.discard(name)
    return out


@functools.lru_cache(maxsize=1)
def graph() -> dict[str, set[str]]:
    """Module -> the package's modules it imports (read once per test session)."""
    known = modules()
    return {name: arrows(name, path, known) for name, path in known.items()}


def cycles(g: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(g[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(g):
        if v not in index:
            visit(v)
    return out


def test_the_graph_is_read():
    g = graph()
    assert "hgo_mj.cli" in g and "hgo_mj.envs.core" in g
    assert "hgo_mj.scenario" in g["hgo_mj.cli"]
    assert "hgo_mj.observers" in g["hgo_mj.envs.core"]


def test_cycles_are_found():
    g = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert cycles(g) == [["a", "b", "c"]]


@pytest.mark.parametrize("source, seen", [
    ("def f():\n    from .b import x\n", {"hgo_mj.b"}),
    ("import hgo_mj.b\n", {"hgo_mj.b"}),
    ("from . import b\n", {"hgo_mj.b"}),
    ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .b import x\n", set()),
])
def test_function_level_imports_count(tmp_path, source, seen):
    path = tmp_path / "a.py"
    path.write_text(source)
    known = {"hgo_mj": tmp_path / "__init__.py", "hgo_mj.a": path, "hgo_mj.b": tmp_path / "b.py"}
    assert arrows("hgo_mj.a", path, known) == seen


@pytest.mark.parametrize("importer, imported", [
    ("hgo_mj.study", "hgo_mj.cli"),  # the study builds its runs with hgo_mj.scenario
    ("hgo_mj.systems", "hgo_mj.plants"),  # a system finds its model with hgo_mj.models
    ("hgo_mj.observers", "hgo_mj.scenario"),
])
def test_no_arrow_runs_back_up(importer, imported):
    def under(name: str, package: str) -> bool:
        return name == package or name.startswith(package + ".")

    found = sorted(f"{a} -> {b}" for a, bs in graph().items() if under(a, importer)
                   for b in bs if under(b, imported))
    assert not found, found


@pytest.mark.parametrize("form", ["hgo_mj.systems.jo_son_form", "hgo_mj.systems.aocf",
                                  "hgo_mj.systems.affine_form"])
def test_a_form_module_imports_no_concrete_system(form):
    """A concrete system declares its form by importing the form module, never the other way."""
    systems = {m for m in graph()[form] if m.startswith("hgo_mj.systems")}
    assert systems <= {"hgo_mj.systems.base"}, systems


def test_no_import_cycle():
    found = cycles(graph())
    assert not found, "import cycles among hgo_mj's modules:\n" + "\n".join(
        " <-> ".join(c) for c in found)
