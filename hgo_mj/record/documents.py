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
    strict JSON.

    Parameters
    ----------
    metadata : mapping
        A run's metadata (``Trajectory.metadata``); every key optional.

    Returns
    -------
    str
        Markdown: a ``# <scenario>`` heading (``# run`` without one), the listed keys, the
        ``## Observers`` and ``## Versions`` sections where present, then ``## All metadata``
        as a JSON block (NaN and infinities written as ``null``).

    Examples
    --------
    >>> meta = {"scenario": "demo", "plant": "Pendulum", "seed": 3, "x0": [0.5, 0.0],
    ...         "observers": {"k40": {"type": "HighGainObserver", "k": 40.0}}}
    >>> doc = scenario_document(meta)
    >>> print("\\n".join(doc.splitlines()[:9]))
    # demo
    <BLANKLINE>
    - **plant**: `"Pendulum"`
    - **seed**: `3`
    - **x0**: `[0.5, 0.0]`
    <BLANKLINE>
    ## Observers
    <BLANKLINE>
    - **k40**: `{"type": "HighGainObserver", "k": 40.0}`
    >>> import json
    >>> json.loads(doc.split("```json")[1].split("```")[0])["seed"]
    3
    """
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
    """The recording properties of a run (scenario, plant, seed, observers, versions; as text).

    Parameters
    ----------
    metadata : mapping
        A run's metadata (``Trajectory.metadata``).

    Returns
    -------
    dict of str to str
        The keys ``scenario``, ``plant``, ``seed``, ``observers``, ``versions`` that
        ``metadata`` has; strings as they are, other values as JSON.

    Examples
    --------
    >>> meta = {"scenario": "demo", "plant": "Pendulum", "seed": 3, "x0": [0.5, 0.0],
    ...         "observers": {"k40": {"type": "HighGainObserver", "k": 40.0}}}
    >>> props = scenario_properties(meta)
    >>> sorted(props), props["seed"]
    (['observers', 'plant', 'scenario', 'seed'], '3')
    >>> props["observers"]
    '{"k40": {"type": "HighGainObserver", "k": 40.0}}'
    """
    return {k: metadata[k] if isinstance(metadata[k], str) else json.dumps(metadata[k], default=str)
            for k in _PROPERTY_KEYS if k in metadata}


def metrics_document(metrics: Mapping[str, Mapping[str, Any]],
                     units: Mapping[str, str] | None = None) -> str:
    """The ``/metrics`` document of a run: :func:`hgo_mj.metrics.format_table`, then JSON.

    Parameters
    ----------
    metrics : mapping observer -> mapping
        As :func:`hgo_mj.metrics.all_metrics` returns them (keys ``states``, ``rmse``,
        ``peak``, ``settling_time``, ``final``, ``update_time``, ...).
    units : mapping of str to str, optional
        ``{state: unit}`` for the table's unit column.

    Returns
    -------
    str
        Markdown: ``# Metrics``, the table in a code block, then the metrics as a JSON block
        (NaN written as ``null``).

    Examples
    --------
    >>> m = {"hgo": {"states": ["angle"], "estimated": [True], "rmse": [0.1],
    ...              "peak": [float("nan")], "settling_time": [1.0], "final": [0.01],
    ...              "update_time": 2e-6}}
    >>> doc = metrics_document(m, {"angle": "rad"})
    >>> print(doc.splitlines()[6])
    hgo      angle rad    0.1   nan   0.01           1            2
    >>> import json
    >>> json.loads(doc.split("```json")[1].split("```")[0])["hgo"]["peak"]
    [None]
    """
    from ..metrics import format_table

    table = {str(k): dict(v) for k, v in metrics.items()}
    return ("# Metrics\n\nerror e = x - x_hat per observer and state\n\n```\n"
            + format_table(table, dict(units or {})) + "\n```\n\n```json\n"
            + json.dumps(strict_json(table), indent=2, default=float) + "\n```\n")


def _cell(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return "-" if v is None else str(v)


def episode_metrics_document(episodes: Sequence[Mapping[str, Any]]) -> str:
    """The ``/metrics`` document of an environment: a table with one row per episode
    (``episode``, ``seed``, ``steps``, ``return``, ``terminated`` and, per state, ``rmse``:
    each a key of the episode's mapping, ``rmse`` a mapping state -> value), then JSON.

    Parameters
    ----------
    episodes : sequence of mapping
        One mapping per episode; a missing key is written ``-``.

    Returns
    -------
    str
        Markdown: ``# Metrics``, a sentence defining return and rmse, the table (floats to 4
        significant digits, one ``rmse <state>`` column per state of any episode), then the
        episodes as a JSON block.

    Examples
    --------
    >>> doc = episode_metrics_document([
    ...     {"episode": 0, "seed": 1, "steps": 200, "return": -3.5, "terminated": False,
    ...      "rmse": {"angle": 0.012345}},
    ...     {"episode": 1, "seed": 2, "steps": 57, "terminated": True}])
    >>> print("\\n".join(doc.splitlines()[4:8]))
    | episode | seed | steps | return | terminated | rmse angle |
    |---|---|---|---|---|---|
    | 0 | 1 | 200 | -3.5 | False | 0.01235 |
    | 1 | 2 | 57 | - | True | - |
    """
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
