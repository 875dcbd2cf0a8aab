"""``python -m hgo_mj``: the ``hgo-mj`` command (:func:`hgo_mj.cli.main`)."""

from __future__ import annotations

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
