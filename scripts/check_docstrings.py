"""Check that every public name of hgo_mj carries its numpydoc sections.

Public means: listed in its module's ``__all__`` (every module of the package declares one; the
API reference documents exactly these names). For each public function, class and public method
of a public class:

- an Examples section with at least one doctest (``>>>``);
- a Parameters section naming every parameter of the signature (a class: of ``__init__``);
- a Returns (or Yields) section, unless the function is annotated ``-> None``;
- a Raises section where the function's own body raises.

A method that overrides a method of a base class is held to the base's contract: the base method
(defined where the contract is, e.g. ``System.phi`` or ``Observer.update``) carries the sections,
and the override's docstring says what this class computes (its equations and paper reference)
without repeating them.

Run ``python scripts/check_docstrings.py [MODULE ...]``: prints one line per missing section and
exits 1 if any is missing. ``tests/test_docs.py`` calls :func:`problems` on the whole package and
runs every public name's doctests.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil
import sys
import textwrap
import warnings
from collections.abc import Callable, Iterator
from types import ModuleType

from numpydoc.docscrape import ClassDoc, FunctionDoc

import hgo_mj


def modules(names: list[str] | None = None) -> list[ModuleType]:
    """The package's modules (those whose dotted names have no part starting with '_')."""
    if names:
        return [importlib.import_module(n) for n in names]
    import hgo_mj.envs

    found = [hgo_mj]
    walk = [*pkgutil.walk_packages(hgo_mj.__path__, "hgo_mj."),
            *pkgutil.walk_packages(hgo_mj.envs.__path__, "hgo_mj.envs.")]
    for info in walk:
        if any(p.startswith("_") for p in info.name.split(".")[1:]):
            continue
        found.append(importlib.import_module(info.name))
    return found


def public_objects(module: ModuleType) -> Iterator[tuple[str, object]]:
    """(dotted name, object) of the module's own public functions, classes and their methods."""
    for name in getattr(module, "__all__", []):
        obj = getattr(module, name)
        if not (inspect.isfunction(obj) or inspect.isclass(obj)):
            continue
        if getattr(obj, "__module__", None) != module.__name__:
            continue  # re-exported: checked where it is defined
        yield f"{module.__name__}.{name}", obj
        if inspect.isclass(obj):
            for attr, member in vars(obj).items():
                if attr.startswith("_"):
                    continue
                if isinstance(member, (staticmethod, classmethod)):
                    member = member.__func__
                if inspect.isfunction(member) and not overrides(obj, attr):
                    yield f"{module.__name__}.{name}.{attr}", member


def overrides(cls: type, attr: str) -> bool:
    """Whether ``cls.attr`` overrides a method of one of the class's bases."""
    return any(attr in vars(base) for base in cls.__mro__[1:] if base is not object)


def raises_itself(func: Callable) -> bool:
    """Whether the function's own body (not a nested function's) has a ``raise`` statement."""
    try:
        source = textwrap.dedent(inspect.getsource(func))
    except (OSError, TypeError):
        return False
    tree = ast.parse(source)
    top = tree.body[0]
    stack = list(ast.iter_child_nodes(top))
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
            continue
        if isinstance(node, ast.Raise) and node.exc is not None:
            return True
        stack.extend(ast.iter_child_nodes(node))
    return False


def signature_parameters(obj: object) -> list[str]:
    """The parameters of a function, or of calling a class (its ``__init__`` or, for a named
    tuple, its ``__new__``), without ``self``/``cls``."""
    try:
        params = inspect.signature(obj).parameters  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return []
    return [p for p in params if p not in ("self", "cls")]


def missing_sections(dotted: str, obj: object) -> list[str]:
    """The problems of one object's docstring, one string each (empty: complete)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        doc = ClassDoc(obj) if inspect.isclass(obj) else FunctionDoc(obj)
    found: list[str] = []
    if not doc["Examples"] or ">>>" not in "\n".join(doc["Examples"]):
        found.append(f"{dotted}: no Examples section with a doctest")
    params = signature_parameters(obj)
    named = {n.strip().lstrip("*") for p in doc["Parameters"] for n in p.name.split(",")}
    if inspect.isclass(obj):
        named |= {n.strip() for p in doc["Attributes"] for n in p.name.split(",")}
    undocumented = [p for p in params if p not in named]
    if undocumented:
        found.append(f"{dotted}: parameters without an entry: {', '.join(undocumented)}")
    if not inspect.isclass(obj):
        returns_none = inspect.signature(obj).return_annotation in (None, "None")  # type: ignore[arg-type]
        if not returns_none and not (doc["Returns"] or doc["Yields"]):
            found.append(f"{dotted}: no Returns section")
        if raises_itself(obj) and not doc["Raises"]:  # type: ignore[arg-type]
            found.append(f"{dotted}: raises, but no Raises section")
    return found


def problems(names: list[str] | None = None) -> list[str]:
    """Every missing section of every public name of the given modules (default: all)."""
    found: list[str] = []
    for module in modules(names):
        if module is not hgo_mj and not hasattr(module, "__all__"):
            found.append(f"{module.__name__}: no __all__")
        for dotted, obj in public_objects(module):
            found.extend(missing_sections(dotted, obj))
    return found


def main(argv: list[str]) -> int:
    found = problems(argv or None)
    for line in found:
        print(line)
    print(f"{len(found)} problem(s)", file=sys.stderr)
    return 1 if found else 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
