"""The README's fenced code blocks, each with the install it needs: a block right after the
line ``<!-- needs: EXTRA -->`` runs after ``pip install 'hgo_mj[EXTRA]'``, any other after the
runtime install alone (``tests/test_readme.py``; the wheel test in ``tests/test_install.py``
runs the runtime ones in a venv with only the runtime, then each marked one after adding its
extra alone)."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"
_FENCE = re.compile(r"^(?:<!-- needs: ([a-z_,]+) -->\n)?```(\w+)\n(.*?)^```", re.S | re.M)


@dataclass(frozen=True)
class Block:
    """One fenced block: its language, code, the extras it needs, its first line and the
    heading of its section (a block may use what the blocks before it in its section made)."""

    lang: str
    code: str
    needs: tuple[str, ...]
    line: int
    section: str


def blocks(text: str | None = None) -> list[Block]:
    """Every fenced block of the README (or of ``text``), in order."""
    text = README.read_text() if text is None else text
    out = []
    for m in _FENCE.finditer(text):
        heads = re.findall(r"^## (.*)$", text[:m.start()], re.M)
        out.append(Block(m.group(2), m.group(3), tuple(m.group(1).split(",")) if m.group(1) else (),
                         text.count("\n", 0, m.start(2)) + 1, heads[-1] if heads else ""))
    return out


def extra_script(extra: str, text: str | None = None) -> str:
    """A Python script that runs each ``python``/``py`` block needing only ``extra``, each after
    the unmarked blocks before it in its section, in one namespace; it prints ``RAN <line>``
    after each (an error stops it)."""
    bs = [b for b in blocks(text) if b.lang in ("python", "py")]
    lines = ["scope = {}"]
    for i, b in enumerate(bs):
        if b.needs != (extra,):
            continue
        for a in bs[:i]:
            if a.section == b.section and not a.needs:
                lines.append(f"exec(compile({a.code!r}, 'README.md:{a.line}', 'exec'), scope)")
        lines += [f"exec(compile({b.code!r}, 'README.md:{b.line}', 'exec'), scope)",
                  f"print('RAN {b.line}')"]
    return "\n".join(lines) + "\n"


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
