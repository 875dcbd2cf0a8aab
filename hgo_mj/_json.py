"""Strict JSON for every file hgo_mj writes (``metrics.json``, ``metrics_mc.json``, the
reproductions' ``summary.json``): readable by ``jq`` and any JSON parser, so a non-finite
float is written as ``null`` (Python's ``json`` would write ``Infinity``/``NaN``, which the
JSON standard does not allow). Where ``null`` stands for ``inf`` (a settling time: never) or
``nan`` (undefined), the file's documentation says so."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ._io import write_text


def strict_json(value: Any) -> Any:
    """``value`` as plain JSON data: dicts (keys as strings), lists (tuples and arrays too),
    ``str``/``int``/``float``/``bool``/``None``; a non-finite float becomes ``None``, a NumPy
    scalar its Python value and a path its string."""
    if isinstance(value, dict):
        return {str(k): strict_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [strict_json(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Path):
        return str(value)
    return value


def write_json(path: str | Path, value: Any) -> Any:
    """Write ``value`` to ``path`` as strict JSON (indented, atomically) and return what was
    written."""
    data = strict_json(value)
    write_text(path, json.dumps(data, indent=2, allow_nan=False) + "\n")
    return data
