"""Fail when a function in hgo_mj/ or envs/ has a cyclomatic complexity above the limit.

    python scripts/check_complexity.py [--limit 25] [PATH ...]

Uses radon's own measure (``radon cc``); run by ``make test``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from radon.complexity import cc_visit

ROOT = Path(__file__).resolve().parents[1]


def too_complex(paths: list[Path], limit: int) -> list[str]:
    """``file:line name (complexity)`` of every block above ``limit``."""
    out = []
    for base in paths:
        for path in sorted(base.rglob("*.py")) if base.is_dir() else [base]:
            for block in cc_visit(path.read_text(encoding="utf-8")):
                if block.complexity > limit:
                    out.append(f"{path.relative_to(ROOT)}:{block.lineno} {block.fullname} "
                               f"({block.complexity})")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--limit", type=int, default=25, help="largest complexity allowed")
    ap.add_argument("paths", nargs="*", type=Path, help="files or folders (default hgo_mj envs)")
    args = ap.parse_args(argv)
    paths = [p.resolve() for p in args.paths] or [ROOT / "hgo_mj", ROOT / "envs"]
    bad = too_complex(paths, args.limit)
    for line in bad:
        print(line)
    print(f"{len(bad)} function(s) above cyclomatic complexity {args.limit}", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
