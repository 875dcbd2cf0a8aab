"""sympy expressions compiled into numba row functions (the derived systems' kernels, issue 12).

:func:`row_function` turns a list of sympy expressions into a numba function of one row,
``fn(a, u, c, out)``, writing the expressions' values into ``out`` (the signature of the
:class:`~hgo_mj.systems.base.CompiledModel` row functions, so the Kalman filters' kernels call
it without returning to Python). The expressions' common subexpressions are computed once
(``sympy.cse``).

**No user text reaches the generated source.** The expressions come from
:func:`hgo_mj.systems.symbolic.parse`, which builds them from a checked syntax tree (numbers,
declared names, arithmetic, the functions of ``FUNCTIONS``). Before printing, every symbol is
renamed to a positional local of this module's choosing (``_a0 = a[0]``, ``_u0``, ``_c0``), so
the source holds only those names, numbers, operators and ``math`` functions, printed by
sympy's own code printer.

Division by zero and ``sqrt`` of a negative number give ``inf``/``nan`` as in numpy
(``error_model="numpy"``), never an exception inside a kernel.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from typing import Any

import numba
import sympy
from sympy.printing.pycode import PythonCodePrinter

_PRINTER = PythonCodePrinter({"fully_qualified_modules": True, "strict": True})
_counter = itertools.count()


def _printable(expr: Any) -> Any:
    """``expr`` with the Dirac deltas that derivatives of ``abs`` bring in set to zero (they
    vanish away from the kink, where the kernels evaluate)."""
    if not isinstance(expr, sympy.Basic):  # a Python number from a derivative
        expr = sympy.Float(expr) if isinstance(expr, float) else sympy.Integer(int(expr))
    return expr.replace(sympy.DiracDelta, lambda *a: sympy.Integer(0))


def source(name: str, exprs: Sequence[Any], shape: tuple[int, ...],
           args: Sequence[tuple[str, Sequence[Any]]]) -> str:
    """The Python source of ``def name(<args>, out)`` writing ``exprs`` (flattened row-major
    into ``shape``) into ``out``; ``args`` are ``(argument name, its symbols)``, one symbol per
    entry of that argument."""
    rename: dict[Any, Any] = {}
    lines = [f"def {name}({', '.join(a for a, _ in args)}, out):"]
    for arg, syms in args:
        for i, sym in enumerate(syms):
            local = sympy.Symbol(f"_{arg}{i}", real=True)
            rename[sym] = local
            lines.append(f"    {local} = {arg}[{i}]")
    flat = [_printable(e).xreplace(rename) for e in exprs]
    reps, reduced = sympy.cse(flat, symbols=sympy.numbered_symbols("_t"))
    for sym, expr in reps:
        lines.append(f"    {sym} = {_PRINTER.doprint(expr)}")
    for index, expr in zip(itertools.product(*(range(s) for s in shape)), reduced):
        where = ", ".join(str(i) for i in index)
        lines.append(f"    out[{where}] = {_PRINTER.doprint(expr)}")
    lines.append("    return")
    return "\n".join(lines) + "\n"


def row_function(label: str, exprs: Sequence[Any], shape: tuple[int, ...],
                 args: Sequence[tuple[str, Sequence[Any]]]) -> Callable[..., None]:
    """``exprs`` compiled: a numba function ``fn(<args>, out)`` (callable from Python and
    inlined into the kernels that call it). ``label`` names it in tracebacks."""
    name = f"_{label}_{next(_counter)}"
    namespace: dict[str, Any] = {"math": math}
    exec(compile(source(name, exprs, shape, args), f"<hgo_mj derived {label}>", "exec"),  # noqa: S102
         namespace)
    return numba.njit(error_model="numpy")(namespace[name])  # type: ignore[no-any-return]


__all__: list[str] = []
