"""The text documents of a recording: ``/scenario`` (a run's metadata) and ``/metrics``.

Markdown for rerun's text view, each ending in a block of strict JSON (a non-finite value is
written as ``null``: NaN is not JSON), so the document parses with any JSON reader. Pure
functions: data in, text out.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

from .._json import strict_json

#: keys of a run's metadata listed at the top of the scenario document, in order
_SCENARIO_KEYS = ("plant", "seed", "duration", "sample_period", "control_period", "x0", "sensor",
                  "system_params")
#: keys of a run's metadata also sent as recording properties
_PROPERTY_KEYS = ("scenario", "plant", "seed", "observers", "versions")
_EPISODE_COLUMNS = ("episode", "seed", "steps", "return", "terminated")


def _code(value: Any) -> str:
    return f"`{json.dumps(value, default=str)}`"


def scenario_document(metadata: Mapping[str, Any]) -> str:
    """The ``/scenario`` document: scenario, plant, seed, periods, sensor, system parameters,
    observers with their parameters, input, package versions, then all of ``metadata`` as
    strict JSON."""
    md = dict(metadata)
    lines = [f"# {md.get('scenario', 'run')}", ""]
    lines += [f"- **{key}**: {_code(md[key])}" for key in _SCENARIO_KEYS if key in md]
    if md.get("observers"):
        lines += ["", "## Observers", ""]
        lines += [f"- **{k}**: {_code(v)}" for k, v in md["observers"].items()]
    if md.get("input"):
        lines += ["", f"**input**: {_code(md['input'])}"]
    if md.get("versions"):
        lines += ["", "## Versions", ""]
        lines += [f"- {k} {v}" for k, v in md["versions"].items()]
    lines += ["", "## All metadata", "", "```json",
              json.dumps(strict_json(md), indent=2, default=str), "```"]
    return "\n".join(lines)


def scenario_properties(metadata: Mapping[str, Any]) -> dict[str, str]:
    """The recording properties of a run (scenario, plant, seed, observers, versions; as text)."""
    return {k: metadata[k] if isinstance(metadata[k], str) else json.dumps(metadata[k], default=str)
            for k in _PROPERTY_KEYS if k in metadata}


def metrics_document(metrics: Mapping[str, Mapping[str, Any]]) -> str:
    """The ``/metrics`` document of a run: :func:`hgo_mj.metrics.format_table`, then JSON."""
    from ..metrics import format_table

    table = {str(k): dict(v) for k, v in metrics.items()}
    return ("# Metrics\n\nerror e = x - x_hat per observer and state\n\n```\n"
            + format_table(table) + "\n```\n\n```json\n"
            + json.dumps(strict_json(table), indent=2, default=float) + "\n```\n")


def _cell(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return "-" if v is None else str(v)


def episode_metrics_document(episodes: Sequence[Mapping[str, Any]]) -> str:
    """The ``/metrics`` document of an environment: a table with one row per episode
    (``episode``, ``seed``, ``steps``, ``return``, ``terminated`` and, per state, ``rmse``:
    each a key of the episode's mapping, ``rmse`` a mapping state -> value), then JSON."""
    states: list[str] = []
    for ep in episodes:
        states += [s for s in ep.get("rmse", {}) if s not in states]
    head = list(_EPISODE_COLUMNS)
    lines = ["# Metrics", "", f"{len(episodes)} episode(s); return: sum of the step rewards; "
             "rmse: root mean square of e = x - x_hat over the episode's rows (its reset "
             "and every step)", "",
             "| " + " | ".join(head + [f"rmse {s}" for s in states]) + " |",
             "|" + "---|" * (len(head) + len(states))]
    for ep in episodes:
        rmse = ep.get("rmse", {})
        lines.append("| " + " | ".join([_cell(ep.get(k)) for k in head]
                                       + [_cell(rmse.get(s)) for s in states]) + " |")
    lines += ["", "```json", json.dumps(strict_json([dict(ep) for ep in episodes]), indent=2,
                                           default=float), "```", ""]
    return "\n".join(lines)


__all__ = ["episode_metrics_document", "metrics_document", "scenario_document",
           "scenario_properties"]
