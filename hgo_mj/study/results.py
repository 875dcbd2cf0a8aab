"""A study's folder: ``study.json``, ``results.parquet/`` (partitions), ``summary.parquet``,
``summary.md`` and the figures.

``results.parquet`` is a folder of Parquet files with one schema, one file per finished
chunk, each written to a temporary name and renamed into place: a kill leaves every finished
partition readable, and ``pandas.read_parquet(DIR / "results.parquet")`` (or
``polars.read_parquet(f"{DIR}/results.parquet/*.parquet")``) reads them all without hgo_mj.
One row per cell x seed x observer x plant state; the columns:

* one per swept axis, named by its dotted path (a float for numbers, else the value as JSON);
* ``cell`` (the cell's index), ``seed``, ``observer``, ``state``, ``estimated``;
* the metrics of :func:`hgo_mj.metrics.observer_metrics`: ``rmse`` (after the transient),
  ``peak``, ``settling_time`` (seconds; ``inf``: never settled), ``final``,
  ``undefined_samples``, ``update_time`` (seconds per observer-step, the batch's mean); null
  where the observer does not estimate the state or the run diverged;
* ``cost`` and ``peak_input``: a closed loop's cost ``sum_k (x_k' Q x_k + u_k' R u_k) Ts``
  over the sample rows (the controller's weights) and its largest ``|u|``, the same in every
  row of a run; null for an open loop;
* ``diverged`` and ``message`` (why; null when it finished);
* ``diag.<name>``: each diagnostic's final value (e.g. the adaptive gain's ``diag.k``), null
  where the observer has no such diagnostic.
"""

from __future__ import annotations

import json
import uuid
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .. import manifest
from .._io import atomic_path, write_text
from ..exceptions import DesignError
from .engine import METRICS, RUN_METRICS
from .spec import StudySpec, axis_kind, column_value

#: per metric, the statistics of the summary
SUMMARY_STATS = ("median", "q25", "q75", "iqr", "mean", "std", "min", "max")
#: the metrics summarized
SUMMARY_METRICS = ("rmse", "peak", "final", "settling_time", "cost", "peak_input")


def schema(spec: StudySpec, diagnostics: Sequence[str]) -> Any:
    """The one Arrow schema of every partition of a study."""
    import pyarrow as pa

    types = {"number": pa.float64(), "bool": pa.bool_(), "text": pa.string()}
    fields = [pa.field(a.path, types[axis_kind(a.values)]) for a in spec.axes]
    fields += [pa.field("cell", pa.int64()), pa.field("seed", pa.int64()),
               pa.field("observer", pa.string()), pa.field("state", pa.string()),
               pa.field("estimated", pa.bool_())]
    fields += [pa.field(m, pa.float64()) for m in (*METRICS, *RUN_METRICS)]
    fields += [pa.field("diverged", pa.bool_()), pa.field("message", pa.string())]
    fields += [pa.field(f"diag.{d}", pa.float64()) for d in diagnostics]
    return pa.schema(fields, metadata={"hgo_mj": json.dumps(
        {"axes": [a.path for a in spec.axes], "units": {"settling_time": "s",
                                                        "update_time": "s"}})})


class ResultsDir:
    """The files of one study in ``out``."""

    def __init__(self, out: str | Path) -> None:
        self.out = Path(out)
        self.parts = self.out / "results.parquet"

    # ------------------------------------------------------------ the study's identity
    def check_resume(self, spec: StudySpec) -> set[tuple[int, int]]:
        """The ``(cell, seed)`` pairs already written, after checking that the folder holds
        this study (``study.json``: the same scenario, axes, mode and store; the seeds may
        differ, to add seeds); a different study is refused, naming the difference."""
        path = self.out / "study.json"
        if not path.is_file():
            if self.parts.exists():
                raise DesignError(f"--resume: {self.out} has results but no study.json; it is not "
                                  f"a study folder hgo_mj wrote")
            return set()
        old = json.loads(path.read_text())
        new = json.loads(json.dumps(spec.to_json()))
        diff = [k for k in new if k != "seeds" and old.get(k) != new.get(k)]
        if diff:  # more (or other) seeds of the same study are welcome
            raise DesignError(f"--resume: {self.out} holds another study: {', '.join(diff)} "
                              f"differ from this one's; use another --out")
        return self.done()

    def start(self, spec: StudySpec, resume: bool) -> set[tuple[int, int]]:
        """Prepare the folder: the pairs done (resume), else refuse to mix with old results."""
        if resume:
            done = self.check_resume(spec)
        else:
            if self.parts.exists() and any(self.parts.glob("*.parquet")):
                raise DesignError(f"{self.parts} exists: resume it with --resume, or choose "
                                  f"another --out")
            done = set()
        self.parts.mkdir(parents=True, exist_ok=True)
        manifest.begin(self.out)  # the folder's files change from here on
        write_text(self.out / "study.json", json.dumps(spec.to_json(), indent=2) + "\n")
        return done

    def seal(self) -> None:
        """Write the folder's manifest (:mod:`hgo_mj.manifest`) naming every file in it."""
        manifest.finish(self.out, [str(f.relative_to(self.out)) for f in self.out.rglob("*")
                                   if f.is_file() and not any(p.startswith(".") for p in
                                                              f.relative_to(self.out).parts)
                                   and f.name != manifest.MANIFEST])

    def done(self) -> set[tuple[int, int]]:
        import pyarrow.parquet as pq

        pairs: set[tuple[int, int]] = set()
        for f in sorted(self.parts.glob("*.parquet")):
            t = pq.read_table(f, columns=["cell", "seed"])
            pairs.update(zip(t.column("cell").to_pylist(), t.column("seed").to_pylist()))
        return pairs

    # ------------------------------------------------------------ rows
    def write(self, rows: Sequence[Mapping[str, Any]], spec: StudySpec,
              cell_values: Mapping[int, Mapping[str, Any]], sch: Any) -> Path:
        """One partition of result rows (atomic)."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        cols: dict[str, list[Any]] = {f.name: [] for f in sch}
        kinds = [(a, axis_kind(a.values)) for a in spec.axes]
        for r in rows:
            vals = cell_values[r["cell"]]
            for a, kind in kinds:
                cols[a.path].append(column_value(vals[a.path], kind))
            for name in cols:
                if name not in vals:
                    cols[name].append(r.get(name))
        table = pa.table({k: pa.array(v, type=sch.field(k).type) for k, v in cols.items()},
                         schema=sch)
        path = self.parts / f"part-{uuid.uuid4().hex[:12]}.parquet"
        with atomic_path(path) as tmp:
            pq.write_table(table, tmp)
        return path

    def table(self) -> Any:
        """Every row written, as a pandas DataFrame (cell, seed, observer, state order)."""
        import pandas as pd

        manifest.check(self.parts)  # a folder mixing two studies is refused
        files = sorted(self.parts.glob("*.parquet"))
        if not files:
            raise DesignError(f"no results in {self.parts}")
        df = pd.concat([pd.read_parquet(f) for f in files], ignore_index=True)
        return df.sort_values(["cell", "seed", "observer", "state"], kind="stable",
                              ignore_index=True)


def seed_metrics(table: Any, template: Mapping[str, Mapping[str, Any]]
                 ) -> tuple[list[int], list[dict[str, dict[str, Any]]], dict[int, str]]:
    """The rows of a seeds-only study as :func:`hgo_mj.metrics.all_metrics` of each run:
    ``(seeds that an observer finished, their metrics, {seed: message} of those where an
    observer diverged)``, in seed order. A run's metrics hold the observers that finished it:
    one that diverged is left out of that run only, so the others keep their statistics.
    ``template`` is ``all_metrics`` of one run of the same scenario (the states, what each
    observer estimates, its extra states and the metric settings)."""
    done, runs, failed = [], [], {}
    for seed, g in table.groupby("seed", sort=True):
        bad = g[g["diverged"]]
        lost = list(dict.fromkeys(bad["observer"]))
        if lost:
            failed[int(seed)] = f"seed {int(seed)}: " + "; ".join(
                str(bad[bad["observer"] == ob]["message"].iloc[0]) for ob in lost)
        run: dict[str, dict[str, Any]] = {}
        for name, t in template.items():
            if name in lost:
                continue
            rows = g[g["observer"] == name].set_index("state")
            m = {k: v for k, v in t.items()}
            for key in ("rmse", "peak", "settling_time", "final"):
                m[key] = [float(rows.at[s, key]) if est else None
                          for s, est in zip(t["states"], t["estimated"])]
            m["undefined_samples"] = [int(rows.at[s, "undefined_samples"]) if est else None
                                      for s, est in zip(t["states"], t["estimated"])]
            m["update_time"] = float(rows["update_time"].max())
            run[name] = m
        if run:
            done.append(int(seed))
            runs.append(run)
    return done, runs, failed


def summarize(df: Any, axes: Sequence[str]) -> Any:
    """Per cell, observer and state over the seeds: ``runs``, ``diverged_fraction``,
    ``settled_fraction`` (of the runs that finished; NaN where not estimated), and per metric
    in :data:`SUMMARY_METRICS` its median, quartiles ``q25``, ``q75``, IQR (their
    difference), mean, std (ddof=1; 0 for one run, NaN for none), min and max over the runs that
    finished
    (a settling time of ``inf``, never settled, is left out of its statistics).

    Parameters
    ----------
    df : pandas.DataFrame
        Result rows (module docstring; e.g. :attr:`hgo_mj.study.StudyResult.table` or
        ``pandas.read_parquet(DIR / "results.parquet")``): at least the axis columns,
        ``cell``, ``observer``, ``state``, ``estimated``, ``diverged`` and
        ``settling_time``; each metric of :data:`SUMMARY_METRICS` present is summarized.
        It is not modified.
    axes : sequence of str
        The swept paths (columns of ``df``) to carry into the summary.

    Returns
    -------
    pandas.DataFrame
        One row per cell, observer and state (sorted by them): the axes, ``cell``,
        ``observer``, ``state``, ``estimated``, ``runs``, ``diverged_fraction``,
        ``settled_fraction`` and ``<metric>_<stat>`` for each metric and each statistic of
        :data:`SUMMARY_STATS`.

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> df = pd.DataFrame({"observers.hgo.k": [10.0, 10.0, 40.0, 40.0], "cell": [0, 0, 1, 1],
    ...                    "seed": [0, 1, 0, 1], "observer": "hgo", "state": "angle",
    ...                    "estimated": True, "rmse": [0.02, 0.04, 0.01, 0.03], "peak": 0.5,
    ...                    "settling_time": [0.3, np.inf, 0.1, 0.2], "final": 0.001,
    ...                    "diverged": False})
    >>> s = summarize(df, ["observers.hgo.k"])
    >>> s[["observers.hgo.k", "runs", "rmse_median", "settled_fraction"]].values.tolist()
    [[10.0, 2.0, 0.03, 0.5], [40.0, 2.0, 0.02, 1.0]]
    >>> s["settling_time_median"].tolist()  # the run that never settled is left out
    [0.3, 0.15]
    """
    import pandas as pd

    keys = ["cell", "observer", "state"]
    d = df.copy()
    metrics = [m for m in SUMMARY_METRICS if m in d]  # results written before a metric existed
    for m in metrics:  # only finite values enter the statistics
        v = d[m].to_numpy(dtype=float)
        d[m] = np.where(np.isfinite(v) & ~d["diverged"].to_numpy(bool), v, np.nan)
    d["_settled"] = np.where(d["diverged"] | ~d["estimated"], np.nan,
                             np.isfinite(df["settling_time"].to_numpy(dtype=float)))
    g = d.groupby(keys, sort=True)
    out = g[[*axes, "estimated"]].first()
    out["runs"] = g.size()
    out["diverged_fraction"] = g["diverged"].mean().astype(float)
    out["settled_fraction"] = g["_settled"].mean()
    for m in metrics:
        c = g[m]
        q25, q75 = c.quantile(0.25), c.quantile(0.75)
        # one finished run: no spread (0); none: NaN, as its mean
        std = c.std(ddof=1).where(c.count() != 1, 0.0)
        for name, col in (("median", c.median()), ("q25", q25), ("q75", q75),
                          ("iqr", q75 - q25), ("mean", c.mean()), ("std", std),
                          ("min", c.min()), ("max", c.max())):
            out[f"{m}_{name}"] = col.astype(float)
    out = out.reset_index()
    return pd.DataFrame(out[[*axes, *keys, *[c for c in out.columns
                                             if c not in (*axes, *keys)]]])


def summary_markdown(summary: Any, axes: Sequence[str], title: str) -> str:
    """The summary as a Markdown table: the swept values, observer, state, RMSE median and
    IQR, peak median, settled and diverged fractions.

    Parameters
    ----------
    summary : pandas.DataFrame
        The output of :func:`summarize`; only its rows with ``estimated`` appear.
    axes : sequence of str
        The swept paths (its first columns).
    title : str
        The Markdown heading.

    Returns
    -------
    str
        The heading, the table (numbers to 4 significant digits, ``-`` for a non-finite
        value) and a note on the columns, ending in a newline.

    Examples
    --------
    >>> import numpy as np, pandas as pd
    >>> df = pd.DataFrame({"observers.hgo.k": [10.0, 10.0, 40.0, 40.0], "cell": [0, 0, 1, 1],
    ...                    "seed": [0, 1, 0, 1], "observer": "hgo", "state": "angle",
    ...                    "estimated": True, "rmse": [0.02, 0.04, 0.01, 0.03], "peak": 0.5,
    ...                    "settling_time": [0.3, np.inf, 0.1, 0.2], "final": 0.001,
    ...                    "diverged": False})
    >>> print(summary_markdown(summarize(df, ["observers.hgo.k"]), ["observers.hgo.k"],
    ...                        "gain sweep"))
    # gain sweep
    <BLANKLINE>
    | observers.hgo.k | observer | state | runs | rmse median | rmse IQR | peak median | settled | diverged |
    |---|---|---|---|---|---|---|---|---|
    | 10 | hgo | angle | 2 | 0.03 | 0.01 | 0.5 | 50% | 0% |
    | 40 | hgo | angle | 2 | 0.02 | 0.01 | 0.5 | 100% | 0% |
    <BLANKLINE>
    Statistics over the seeds of each cell; ...
    """
    def fmt(v: Any) -> str:
        if isinstance(v, float):
            return "-" if not np.isfinite(v) else f"{v:.4g}"
        return str(v)

    head = [*axes, "observer", "state", "runs", "rmse median", "rmse IQR", "peak median",
            "settled", "diverged"]
    lines = [f"# {title}", "", "| " + " | ".join(head) + " |",
             "|" + "|".join("---" for _ in head) + "|"]
    for _, r in summary[summary["estimated"]].iterrows():
        cells = [fmt(r[a]) for a in axes] + [
            r["observer"], r["state"], str(r["runs"]), fmt(r["rmse_median"]), fmt(r["rmse_iqr"]),
            fmt(r["peak_median"]),
            "-" if not np.isfinite(r["settled_fraction"]) else f"{r['settled_fraction']:.0%}",
            f"{r['diverged_fraction']:.0%}"]
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", "Statistics over the seeds of each cell; rmse after the transient, peak over "
              "the run; settled: fraction of finished runs whose error entered the band; "
              "diverged: fraction of runs that diverged (their metrics are left out)."]
    return "\n".join(lines) + "\n"


def write_summary(out: Path, df: Any, axes: Sequence[str], title: str) -> Any:
    """``summary.parquet`` and ``summary.md`` (atomic); returns the summary DataFrame.

    Parameters
    ----------
    out : Path
        The study's folder (it must exist).
    df : pandas.DataFrame
        The result rows, as for :func:`summarize`.
    axes : sequence of str
        The swept paths.
    title : str
        The heading of ``summary.md``.

    Returns
    -------
    pandas.DataFrame
        :func:`summarize` of ``df``, as written to ``out / "summary.parquet"``.

    Examples
    --------
    >>> import os, tempfile
    >>> from pathlib import Path
    >>> import numpy as np, pandas as pd
    >>> df = pd.DataFrame({"observers.hgo.k": [10.0, 10.0, 40.0, 40.0], "cell": [0, 0, 1, 1],
    ...                    "seed": [0, 1, 0, 1], "observer": "hgo", "state": "angle",
    ...                    "estimated": True, "rmse": [0.02, 0.04, 0.01, 0.03], "peak": 0.5,
    ...                    "settling_time": [0.3, np.inf, 0.1, 0.2], "final": 0.001,
    ...                    "diverged": False})
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     summary = write_summary(Path(tmp), df, ["observers.hgo.k"], "gain sweep")
    ...     files = sorted(os.listdir(tmp))
    >>> files, summary.shape
    (['summary.md', 'summary.parquet'], (2, 40))
    """
    summary = summarize(df, axes)
    with atomic_path(out / "summary.parquet") as tmp:
        summary.to_parquet(tmp, index=False)
    write_text(out / "summary.md", summary_markdown(summary, axes, title))
    return summary


#: the folder's reading and writing (:class:`ResultsDir`, :func:`schema`,
#: :func:`seed_metrics`) is internal: a study's results are read through
#: :class:`hgo_mj.study.StudyResult` or pandas
__all__ = ["SUMMARY_METRICS", "SUMMARY_STATS", "summarize", "summary_markdown", "write_summary"]
