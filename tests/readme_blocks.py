"""The README's fenced code blocks, each with the install it needs: a block right after the
line ``<!-- needs: EXTRA -->`` runs after ``pip install 'hgo_mj[EXTRA]'``, any other after the
runtime install alone (``tests/test_readme.py``; the wheel test in ``tests/test_install.py``
runs the runtime ones in a venv with only the runtime)."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"
_FENCE = re.compile(r"^(?:<!-- needs: ([a-z_,]+) -->\n)?```(\w+)\n(.*?)^```", re.S | re.M)


@dataclass(frozen=True)
class Block:
    """One fenced block: its language, code, the extras it needs and its first line."""

    lang: str
    code: str
    needs: tuple[str, ...]
    line: int


def blocks(text: str | None = None) -> list[Block]:
    """Every fenced block of the README (or of ``text``), in order."""
    text = README.read_text() if text is None else text
    return [Block(m.group(2), m.group(3), tuple(m.group(1).split(",")) if m.group(1) else (),
                  text.count("\n", 0, m.start(2)) + 1) for m in _FENCE.finditer(text)]


def runtime_script(text: str | None = None) -> str:
    """A Python script that runs, in one namespace and in order, every ``python``/``py`` block
    that needs no extra (after writing the first TOML block, the scenario file the study block
    loads, to ``scenario.toml``), then tries each block that needs an extra and prints
    ``NEEDS <extras> <line>: <ExceptionType>: <message>`` for it (or ``RAN`` if it ran)."""
    bs = blocks(text)
    scenario = next(b.code for b in bs if b.lang == "toml")
    lines = ["import pathlib", f"pathlib.Path('scenario.toml').write_text({scenario!r})",
             "scope = {}"]
    for b in bs:
        if b.lang not in ("python", "py"):
            continue
        run = f"exec(compile({b.code!r}, 'README.md:{b.line}', 'exec'), scope)"
        if not b.needs:
            lines.append(run)
        else:
            lines += ["try:", f"    {run}", f"    print('RAN {','.join(b.needs)} {b.line}')",
                      "except Exception as exc:",
                      f"    print(f'NEEDS {','.join(b.needs)} {b.line}: "
                      "{type(exc).__name__}: {exc}')"]
    return "\n".join(lines) + "\n"
