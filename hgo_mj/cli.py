"""The ``hgo-mj`` command: ``run``, ``sweep``, ``tune``, ``bench``, ``check``, ``list``,
``reproduce``, ``demo`` (:data:`DESCRIPTION` says each in ``hgo-mj --help``).

``hgo-mj sweep STUDY.toml --out DIR`` runs a study (a scenario with a ``[sweep]`` table; see
:mod:`hgo_mj.study`) and writes ``results.parquet``, ``summary.parquet``, ``summary.md`` and its
figures into ``DIR``; Ctrl-C leaves every finished partition, and ``--resume`` goes on.

``hgo-mj run scenario.toml`` or ``hgo-mj run --plant NAME --observer KIND:k=v,... ...`` runs a
headless study and writes ``trajectory.npz``, ``trajectory.parquet`` and ``metrics.parquet``
(tidy tables with units in the schema, :mod:`hgo_mj.tidy`; ``--format npz|parquet|csv``,
repeatable, chooses), ``metrics.json``, ``figure.png`` and ``summary.txt`` into ``--out``;
``--rrd FILE.rrd`` also records it to that rerun file (the name must end in ``.rrd``),
written in chunks of ``RRD_CHUNK_SECONDS`` (5) simulated seconds as the run
goes, so a run stopped with Ctrl-C (exit status 130) leaves a readable recording up to its last
chunk. ``--seeds N`` (or ``seeds = N`` in the scenario's ``[run]``) repeats the run at the seeds
``SEED ... SEED+N-1`` (the seeds after the first as a study, :mod:`hgo_mj.study`, ``--jobs J``)
and also writes ``metrics_mc.json``, ``summary_mc.txt``, ``mc.png`` and ``seeds/`` (the study's
rows); the other files are the first seed's.
Long jobs show their progress on stderr (:mod:`hgo_mj.progress`; ``--quiet``: none);
``hgo-mj reproduce`` prints the reproduction's report. ``hgo-mj demo``
writes ``runs/demo-run/demo.rrd`` unless ``--no-rrd``. Bad input exits with status 2 and one line
naming the parameter, what was expected and what was found; a fault of the machine (a
recording or result that cannot be written: full disk) exits with status 1 and one line.
Multi-run commands (``--seeds N --jobs J``, ``sweep --jobs J``) run their workers so that they
die with the command (:mod:`hgo_mj.study.backends`).
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import re
import sys
from pathlib import Path
from typing import Any

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

from . import manifest
from ._io import check_disk, check_writable, save_figure, write_text
from ._json import write_json
from ._validate import positive_int
from .exceptions import DesignError, DivergenceError, HgoError, RecordingError
from .schema import check_scenario

#: a bare word in a value (not a number's exponent, not inside a quoted string)
_BARE_WORD = re.compile(r"(?<![\w.+\-\"'])([A-Za-z_][\w\-]*)(?![\w\"'])")
_TOML_WORDS = {"true", "false", "inf", "nan"}


def parse_value(text: str) -> Any:
    """Parse one ``key=value`` value as a TOML value (``1e-3``, ``[1, 2]``, ``true``, ``"s"``);
    a bare word that is no TOML value is taken as a string, alone or inside a list or table
    (``[stiffness, damping]`` is ``["stiffness", "damping"]``)."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except RecursionError:
        raise DesignError(f"value {text[:40]!r}... is nested too deeply") from None
    except tomllib.TOMLDecodeError:
        if text.replace("_", "").replace("-", "").isalnum():
            return text
    if '"' not in text and "'" not in text:  # bare words quoted, then TOML again
        quoted = _BARE_WORD.sub(lambda m: m.group(1) if m.group(1) in _TOML_WORDS
                                else f'"{m.group(1)}"', text)
        try:
            return tomllib.loads(f"v = {quoted}")["v"]
        except (tomllib.TOMLDecodeError, RecursionError):
            pass
    raise DesignError(f"cannot parse value {text!r}; expected a number, [list], true/false "
                      f"or a word (alone or in a list)")


def parse_spec(spec: str, key: str) -> dict[str, Any]:
    """``"kind:a=1,b=[1,2]"`` -> ``{key: "kind", "a": 1, "b": [1, 2]}``; the kind may be the
    user's own class, ``"module:Class"`` (``"mymod:MyObserver:k=10"``)."""
    kind, _, rest = spec.partition(":")
    head, colon, tail = rest.partition(":")
    if head and "=" not in head and "," not in head:  # module:Class[:params]
        kind, rest = f"{kind}:{head}", tail
    out: dict[str, Any] = {key: kind.strip()}
    depth, item, items = 0, "", []
    for ch in rest:
        depth += ch in "[{"
        depth -= ch in "]}"
        if ch == "," and depth == 0:
            items.append(item)
            item = ""
        else:
            item += ch
    if item.strip():
        items.append(item)
    for it in items:
        name, eq, value = it.partition("=")
        if not eq:
            raise DesignError(f"expected key=value in {spec!r}; found {it!r}")
        out[name.strip()] = parse_value(value.strip())
    return out


def load_scenario_file(name: str) -> dict[str, Any]:
    """A scenario TOML file, its sections checked as tables (not yet for required keys)."""
    path = Path(name)
    if not path.is_file():
        raise DesignError(f"scenario file {str(path)!r} does not exist")
    with open(path, "rb") as fh:
        try:
            sc = tomllib.load(fh)
        except tomllib.TOMLDecodeError as exc:
            raise DesignError(f"scenario file {str(path)!r} is not valid TOML: {exc}") from None
        except UnicodeDecodeError as exc:
            raise DesignError(f"scenario file {str(path)!r} is not UTF-8 text (a binary file?): "
                              f"{exc}") from None
        except RecursionError:
            raise DesignError(f"scenario file {str(path)!r} is nested too deeply (arrays or "
                              f"tables inside each other beyond Python's recursion limit)"
                              ) from None
    check_scenario(sc, required=False)  # its sections are tables before flags go in
    return sc


def scenario_from_args(args: argparse.Namespace) -> dict[str, Any]:
    sc = load_scenario_file(args.scenario) if args.scenario else {}
    sc.setdefault("plant", {})
    sc.setdefault("run", {})
    if args.plant:
        sc["plant"]["name"] = args.plant
    if args.model:  # --model replaces a scenario file's registered plant
        if not args.plant:
            sc["plant"].pop("name", None)
        sc["plant"]["model"] = args.model
    for key in ("outputs", "inputs"):
        if getattr(args, key):
            sc["plant"][key] = list(getattr(args, key))
    if args.observer:
        sc["observers"] = [parse_spec(s, "type") for s in args.observer]
    if args.sensor:
        sc["sensor"] = {"stages": [parse_spec(s, "stage") for s in args.sensor]}
    if args.input:  # one signal, or one per actuator
        specs = [parse_spec(s, "type") for s in args.input]
        sc["input"] = specs[0] if len(specs) == 1 else specs
    for key in ("duration", "sample_period", "control_period", "seed", "out", "t_transient",
                "band"):
        v = getattr(args, key)
        if v is not None:
            sc["run"][key] = v
    if args.dt is not None:
        sc["plant"]["dt"] = args.dt
    if args.x0 is not None:
        sc["plant"]["x0"] = parse_value(args.x0)
    if args.seeds is not None:
        sc["run"]["seeds"] = _flag_int(args.seeds, "--seeds")
    if args.store_every is not None:
        sc["run"]["store_every"] = _flag_int(args.store_every, "--store-every")
    if args.stream:
        sc["run"]["stream"] = True
    return sc


#: simulated seconds per chunk of a recording made during a run (at least 200 samples a chunk)
#: and of a streamed run's Parquet parts; a chunk of a recording costs about 1-2 ms of CPU
#: while the run goes on (BENCHMARKS.md, the bench_record notes: a 10 s, 1 kHz run recorded in
#: 1, 2, 5 and 10 s chunks added 53, 38, 33 and 31%), and a run cut short keeps its whole chunks
RRD_CHUNK_SECONDS = 5.0


def plant_label(pl: dict[str, Any]) -> str:
    """A scenario's plant for titles: its registered name, or its MJCF file's name."""
    if "f" in pl:
        return "ODE y = " + str(pl["h"])
    return str(pl.get("name") or Path(pl["model"]).name)


#: what ``hgo-mj run --format`` can write: the trajectory as ``.npz``
#: (:meth:`~hgo_mj.simulate.Trajectory.save`), or as a tidy table with the metrics beside it
#: (``trajectory.parquet`` and ``metrics.parquet``, units in the schema; or ``.csv``)
FORMATS = ("npz", "parquet", "csv")
#: written when ``--format`` is not given: the npz and Parquet beside it
DEFAULT_FORMATS = ("npz", "parquet")
#: the formats of a streamed run (``--stream``): its table is written chunk by chunk
STREAM_FORMATS = ("parquet",)


def check_formats(formats: Any) -> tuple[str, ...]:
    """``formats`` as a tuple of distinct names from :data:`FORMATS`, in the order given."""
    if (not isinstance(formats, (list, tuple)) or not formats
            or not all(isinstance(f, str) for f in formats)):
        raise DesignError(f"formats must be a non-empty list of {list(FORMATS)}; found "
                          f"{formats!r}")
    bad = [f for f in formats if f not in FORMATS]
    if bad:
        raise DesignError(f"--format must be one of {list(FORMATS)}; found {bad[0]!r}")
    return tuple(dict.fromkeys(formats))


def write_results(traj: Any, metrics: dict[str, Any], out: Path,
                  formats: tuple[str, ...], table: bool = True) -> list[str]:
    """Write the run's trajectory and metrics in ``formats`` into ``out``; ``metrics.json``
    always. ``table=False``: the trajectory's table is there already (a streamed run).
    Returns the names of the files written."""
    written = []
    if "npz" in formats:
        traj.save(out / "trajectory.npz")
        written.append("trajectory.npz")
    write_json(out / "metrics.json", metrics)
    written.append("metrics.json")
    if not {"parquet", "csv"} & set(formats):
        return written  # pandas is not loaded for an npz run
    from .metrics import metrics_frame, metrics_rows
    from .tidy import write_rows_parquet, write_table
    from .units import units_of

    units = units_of(traj)[0]
    for fmt in ("parquet", "csv"):
        if fmt in formats:
            if table:
                write_table(traj, out / f"trajectory.{fmt}", fmt)
            if fmt == "parquet":  # without pandas (a streamed run loads none)
                write_rows_parquet(*metrics_rows(metrics, units), out / "metrics.parquet")
            else:
                write_text(out / "metrics.csv", metrics_frame(metrics, units).to_csv(index=False))
            written += [f"trajectory.{fmt}", f"metrics.{fmt}"]
    return written


def run_scenario(sc: dict[str, Any], name: str = "run", rrd: str | Path | None = None, *,
                 formats: Any = None) -> tuple[Any, dict[str, Any], Path]:
    """Build everything a scenario names, simulate, and write the results. Returns
    ``(trajectory, metrics, out_dir)``. ``formats`` (:data:`FORMATS`) chooses the files of the
    trajectory and metrics (:func:`write_results`); ``metrics.json``, ``figure.png`` and
    ``summary.txt`` are always written.

    With ``rrd``, the run is also recorded to that rerun file (:class:`hgo_mj.record.Recorder`)
    chunk by chunk while it runs; the file is closed even when the run is interrupted.
    ``run.seeds`` is read by :func:`run_study`; this runs the one seed ``run.seed``."""
    from .metrics import all_metrics, format_table
    from .plotting import plot_trajectory
    from .scenario import scenario_run
    from .simulate import simulate

    kw = scenario_run(sc, name)
    plant, observers, pl, run = kw["plant"], kw["observers"], sc["plant"], sc["run"]
    stream = run.get("stream", False)
    formats = check_formats(formats if formats is not None
                            else STREAM_FORMATS if stream else DEFAULT_FORMATS)
    if stream and formats != STREAM_FORMATS:
        raise DesignError(f"--stream (run.stream) writes the trajectory as Parquet only; found "
                          f"--format {' '.join(formats)}: leave --format out or give parquet")
    seed = run.get("seed", 0)
    out = check_writable("--out (run.out)", run.get("out", f"runs/{name}"), folder=True)
    every = run.get("store_every", 1)
    if not stream:  # the rows a kept run holds in memory (simulate checks it again)
        from .simulate import check_memory

        rows, width = output_shape(kw, every)
        check_memory(run_memory(rows, width), int(rows))
    check_disk("--out (run.out)", out, output_bytes(kw, every, formats))
    if rrd is not None:
        check_writable("--rrd", rrd, folder=False)
    if stream:
        from .stream import check_no_parts

        check_no_parts(out / "trajectory.parquet")
    clear_stale(out, rrd)
    rec = None
    if rrd is not None:
        from .record import Recorder
        from .simulate import package_versions

        rec = Recorder.for_plant(rrd, plant, list(observers),
                                 recording_name=str(sc.get("name", name)),
                                 dropouts=kw["sensor"].has_dropouts)
    chunk_s = max(RRD_CHUNK_SECONDS, 200 * float(run.get("sample_period") or plant.dt))
    mkw = {k: run[k] for k in ("t_transient", "band") if k in run}
    try:
        on_chunk = None
        if rec is not None:
            # what is known before the run, in case it is cut short; replaced at the end
            rec.log_metadata({"scenario": sc.get("name", name), "seed": seed,
                              "scenario_spec": sc, "versions": package_versions()})
            on_chunk = (chunk_s, rec.write_chunk)
        if stream:
            from .stream import stream_run

            manifest.begin(out)  # the folder's files change from here on
            traj, metrics = stream_run({**kw, "store_every": run.get("store_every", 1)},
                                       out / "trajectory.parquet", seed=seed,
                                       chunk_seconds=chunk_s, **mkw,
                                       also=None if rec is None else rec.write_chunk)
        else:
            traj = simulate(**kw, seed=seed, on_chunk=on_chunk,
                            store_every=run.get("store_every", 1), isolate=True)
            metrics = all_metrics(traj, **mkw)
        if rec is not None:
            rec.log_metadata(traj.metadata)
            rec.log_metrics(metrics)
    finally:
        if rec is not None:
            rec.close()
    out.mkdir(parents=True, exist_ok=True)
    if not stream:
        manifest.begin(out)  # the folder's files change from here on
    written = write_results(traj, metrics, out, formats, table=not stream)
    every = traj.metadata.get("figure_every", 1)
    save_figure(plot_trajectory(traj, title=f"{sc.get('name', name)}: {plant_label(pl)}, seed {seed}"
                                + (f" (every {every}-th sample shown)" if every > 1 else "")),
                out / "figure.png")
    from .units import units_of

    write_text(out / "summary.txt", format_table(metrics, *units_of(traj)) + "\n")
    manifest.finish(out, [*written, "figure.png", "summary.txt"])
    for ob, d in traj.diverged.items():  # the run isolates a failing observer: say so
        print(f"hgo-mj: observer {ob!r} diverged at t = {d['t']:g} s ({d['error']}); its "
              f"estimate is NaN from there on, the other observers ran to the end",
              file=sys.stderr)
    return traj, metrics, out


#: the files ``hgo-mj run`` may write into its folder
RUN_FILES = ("trajectory.npz", "trajectory.parquet", "trajectory.csv", "metrics.parquet",
             "metrics.csv", "metrics.json", "figure.png", "summary.txt", "manifest.json",
             "metrics_mc.json", "summary_mc.txt", "mc.png")


def clear_stale(out: Path, rrd: str | Path | None) -> None:
    """Remove the temporaries a killed earlier run left of the files of ``out`` (saying so on
    stderr); report, and keep, those of the recording ``rrd`` (the torn rows of a killed
    recording, which :func:`hgo_mj.record.read` reads)."""
    from ._io import stale_temporaries

    stale = [f for name in RUN_FILES for f in stale_temporaries(out / name)]
    for f in stale:
        f.unlink(missing_ok=True)
    if stale:
        print(f"hgo-mj: removed {len(stale)} temporary file(s) a killed earlier run left in "
              f"{out}: {', '.join(f.name for f in stale)}", file=sys.stderr)
    torn = stale_temporaries(rrd) if rrd is not None else []
    if torn:
        print(f"hgo-mj: {', '.join(str(f) for f in torn)}: the recording of a killed earlier run "
              f"(kept: hgo_mj.record.read reads its rows; remove it when done)", file=sys.stderr)


#: bytes a stored value takes in each trajectory format (CSV: its text, about 20 characters)
BYTES_PER_VALUE = {"npz": 8, "parquet": 8, "csv": 20}


def output_shape(kw: dict[str, Any], every: int) -> tuple[float, int]:
    """The rows a run stores and its columns (an observer's ``x_hat``, ``z_hat`` and
    diagnostics counted as columns)."""
    plant = kw["plant"]
    ts = float(kw.get("sample_period") or plant.dt)
    rows = float(kw["duration"]) / ts / every + 1
    width = len(plant.state_names) + 2 * len(plant.output_names) + len(plant.input_names) + 1
    width += sum(2 * len(ob.state_names) + len(ob.diagnostic_names)
                 for ob in kw["observers"].values())
    return rows, width


#: the memory a ``hgo-mj run`` keeping its rows adds at its peak (simulation, metrics, the
#: files and the figure), per byte of its stored columns (``8 x rows x columns``), and what it
#: adds whatever its length (the libraries loaded after the check: pandas, pyarrow,
#: matplotlib, numba's kernels): measured by ``python scripts/memory_calibration.py``
#: (BENCHMARKS.md: slopes of 4.0 to 4.6 and 228 to 254 MiB), rounded up
RUN_MEMORY_FACTOR = 5.0
RUN_MEMORY_BASE = 288 * 2**20


def run_memory(rows: float, width: int) -> float:
    """The bytes a ``hgo-mj run`` of ``rows`` rows and ``width`` columns (:func:`output_shape`)
    needs beyond what the process holds before it: :data:`RUN_MEMORY_BASE` plus
    :data:`RUN_MEMORY_FACTOR` times its stored columns' bytes."""
    return RUN_MEMORY_BASE + RUN_MEMORY_FACTOR * 8 * rows * width


def output_bytes(kw: dict[str, Any], every: int, formats: tuple[str, ...]) -> float:
    """An upper estimate of the bytes the trajectory files of a run take: rows x columns x
    :data:`BYTES_PER_VALUE` per format (:func:`output_shape`)."""
    rows, width = output_shape(kw, every)
    return rows * width * sum(BYTES_PER_VALUE[f] for f in formats)


#: the most seeds ``hgo-mj run --seeds`` runs; more are a study (``hgo-mj sweep``)
MAX_SEEDS = 100_000


def _flag_int(value: Any, where: str) -> int:
    """A command-line flag's text as an integer >= 1 (``--seeds``, ``--jobs``)."""
    if isinstance(value, str) and value.strip().lstrip("+").isdigit():
        value = int(value.strip())
    return positive_int(where, value, floats=False)


def _flag_seed(value: str) -> int:
    """``--seed``: an integer >= 0."""
    if not value.strip().lstrip("+").isdigit():
        raise DesignError(f"--seed must be an integer >= 0; found {value!r}")
    return int(value.strip())


def run_study(sc: dict[str, Any], name: str = "run", rrd: str | Path | None = None, *,
              jobs: int = 1, formats: Any = None, quiet: bool = False,
              resume: bool = False) -> tuple[Any, dict[str, Any], Path, Any]:
    """:func:`run_scenario` at ``run.seed``, then, when ``run.seeds`` = N > 1, a Monte Carlo
    over the seeds ``seed, seed + 1, ..., seed + N - 1``: the other seeds as a study of the
    same scenario (:class:`hgo_mj.study.Study`, up to ``jobs`` processes; its rows in
    ``OUT/seeds/results.parquet``), written to ``metrics_mc.json``, ``summary_mc.txt`` and
    ``mc.png``.
    Returns ``(trajectory, metrics, out_dir, mc)``: the first seed's run, and the
    :class:`~hgo_mj.study.MonteCarloResult` of all seeds (``None`` for one seed).

    The first seed's files (and ``rrd``) are exactly those of a single run at that seed.
    ``resume`` keeps the other seeds' finished chunks in ``OUT/seeds`` (an interrupted run)
    and runs only the rest; without it that folder is replaced."""
    import shutil

    run = sc.get("run", {})
    n = positive_int("run.seeds", run.get("seeds", 1), floats=False) if isinstance(run, dict) else 1
    if n > MAX_SEEDS:
        from .study.spec import MAX_RUNS

        raise DesignError(f"run.seeds (--seeds) must be at most {MAX_SEEDS} for `hgo-mj run`; found "
                          f"{n}: run that many as a study, `hgo-mj sweep STUDY.toml` with "
                          f"[sweep] seeds = {n} (and --yes beyond {MAX_RUNS} runs)")
    jobs = positive_int("--jobs", jobs, floats=False)
    if resume and n == 1:
        raise DesignError("--resume goes on with the seeds of an interrupted --seeds N run; "
                          "found one seed (give --seeds N, N > 1)")
    if n > 1 and "store_every" in run:
        raise DesignError("run.store_every (--store-every) keeps every k-th row of one run's "
                          "trajectory, and its metrics are computed from those rows; with "
                          f"run.seeds = {n} the seeds' metrics would not be comparable: give "
                          "one or the other")
    single = {**sc, "run": {k: v for k, v in run.items() if k != "seeds"}} if isinstance(
        run, dict) else sc
    traj, metrics, out = run_scenario(single, name, rrd=rrd, formats=formats)
    if n == 1:
        return traj, metrics, out, None
    from .plotting import plot_monte_carlo
    from .study import MonteCarloResult, Study
    from .study.results import seed_metrics
    from .units import units_of

    # the other seeds' metrics only: nothing of theirs is streamed
    single = {**single, "run": {k: v for k, v in single["run"].items() if k != "stream"}}
    seed = single["run"].get("seed", 0)
    seeds = list(range(seed, seed + n))
    # the other seeds as a study (hgo_mj.study): one plant run, the seeds as one batch; its
    # rows (results.parquet) in OUT/seeds/, replaced by each run as the other files are
    folder = out / "seeds"
    if folder.is_dir() and not resume:
        shutil.rmtree(folder)
    table = Study(single, seeds=seeds[1:]).run(folder, jobs=jobs, quiet=quiet,
                                               resume=resume and folder.is_dir()).table
    done, runs, failed = seed_metrics(table, metrics)
    # the first seed counts as the others do: an observer that diverged in it is left out of
    # that run's metrics only
    first = {k: v for k, v in metrics.items() if k not in traj.diverged}
    if traj.diverged:
        failed = {seed: f"seed {seed}: " + "; ".join(
            f"observer {ob!r} diverged at t={d['t']:g}: {d['error']}"
            for ob, d in traj.diverged.items()), **failed}
    if first:
        done, runs = [seed, *done], [first, *runs]
    if not runs:
        raise DivergenceError(f"every seed diverged ({n} of {n}): {failed[seed]}; nothing to "
                              f"aggregate (the first seed's run is in {out}, every seed's rows "
                              f"in {folder}/results.parquet)")
    mc = MonteCarloResult.from_runs(done, runs, failed)
    listed = manifest.listed(out)  # the first seed's files; the seeds/ study has its own
    manifest.begin(out)
    write_json(out / "metrics_mc.json", mc.to_json())
    units, t_unit = units_of(traj)
    write_text(out / "summary_mc.txt", mc.table(units, t_unit) + "\n")
    save_figure(plot_monte_carlo(mc, title=f"{sc.get('name', name)}: {plant_label(sc['plant'])}, "
                                 f"seeds {seeds[0]}..{seeds[-1]}", units=units), out / "mc.png")
    manifest.finish(out, [*listed, "metrics_mc.json", "summary_mc.txt", "mc.png"])
    return traj, metrics, out, mc


DEMO = {
    "name": "demo",
    "plant": {"name": "elastic_joint", "dt": 0.001, "x0": [0.3, 0.3, 0.0, 0.0]},
    "sensor": {"stages": [
        {"stage": "gaussian", "std": 2e-4},
        {"stage": "quantize", "counts_per_rev": 16384},
    ]},
    "observers": [
        {"type": "high_gain", "name": "hgo_k25", "k": 25.0},
        {"type": "high_gain", "name": "hgo_k200", "k": 200.0},
    ],
    "input": {"type": "multisine", "amplitudes": [0.8, 0.3], "frequencies": [0.4, 1.5],
              "phases": [0.0, 1.0]},
    "run": {"duration": 5.0, "seed": 0, "out": "runs/demo-run", "t_transient": 1.0},
}


def cmd_list() -> str:
    from .inputs import SIGNALS
    from .observers import OBSERVERS
    from .sensors import STAGES
    from .systems import SYSTEMS

    def sig(cls: Any) -> str:
        ps = [p for p in inspect.signature(cls.__init__).parameters.values()
              if p.name not in ("self", "system") and p.kind != p.VAR_KEYWORD]
        return ", ".join(p.name if p.default is p.empty else f"{p.name}={p.default!r}"
                         for p in ps)

    from .reproduce import PAPERS, REPRODUCTIONS

    def width(names: Any) -> int:
        """The name column of a section: as wide as its longest name."""
        return max((len(n) for n in names), default=0)

    from .plants import LAB_PLANTS

    w = width([*SYSTEMS, *LAB_PLANTS])
    lines = ["PLANTS (hgo-mj run --plant NAME)"]
    for name, system in SYSTEMS.items():
        kind = f"MuJoCo models/{system.model_file}" if system.model_file else "ODE"
        lines.append(f"  {name:<{w}} {system.summary}  [{kind}; {system.reference}]")
    for name, (file, outputs, summary, reference) in LAB_PLANTS.items():
        lines.append(f"  {name:<{w}} {summary}, measured by {', '.join(outputs)}  "
                     f"[MuJoCo models/{file}, generic MJCF path; {reference}]")
    w = width(STAGES)
    lines.append("\nSENSOR STAGES (--sensor NAME:key=value,...; applied in the order given)")
    for name, stage in STAGES.items():
        lines.append(f"  {name:<{w}} {stage.summary}  ({sig(stage)})")
    w = width(OBSERVERS)
    lines.append("\nOBSERVERS (--observer KIND:key=value,...)")
    for name, observer in OBSERVERS.items():
        lines.append(f"  {name:<{w}} {observer.summary}  [{observer.reference}]\n"
                     f"  {'':<{w}} ({sig(observer)})")
    w = width(SIGNALS)
    lines.append("\nINPUTS (--input KIND:key=value,...)")
    for name, signal in SIGNALS.items():
        lines.append(f"  {name:<{w}} {signal.summary}  ({sig(signal)})")
    w = width(REPRODUCTIONS)
    lines.append("\nREPRODUCTIONS (hgo-mj reproduce NAME --out DIR)")
    for name, (_, line) in REPRODUCTIONS.items():
        lines.append(f"  {name:<{w}} {line}")
    lines.append("\nPAPERS (cited above as paper NNN)")
    for number, citation in PAPERS.items():
        lines.append(f"  {number} {citation}")
    return "\n".join(lines)


def _version() -> str:
    """The installed distribution's version (what ``pip`` installed), or ``unknown``."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("hgo_mj")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "unknown"


#: ``hgo-mj --help``'s description: what the tool is, and every command (plain text)
DESCRIPTION = (
    "MuJoCo plants, a sensor-noise chain and nonlinear observers. Commands: run (a scenario, "
    "or flags), sweep (a study over axes and seeds), tune (an observer's gains, with Optuna), "
    "bench (the observer benchmark), check (which observer applies to a plant), list (plants, "
    "sensor stages, observers, inputs, reproductions, papers), reproduce (a paper's example), "
    "demo (a first run to look at).")


def _rrd_path(text: str) -> Path:
    """``--rrd FILE``: a path whose name ends in ``.rrd`` (so that a scenario file or a folder
    is never taken for the recording)."""
    if not text.endswith(".rrd"):
        raise argparse.ArgumentTypeError(f"expected a rerun file name ending in .rrd; found "
                                         f"{text!r}")
    return Path(text)


def build_parser() -> argparse.ArgumentParser:
    from .reproduce import REPRODUCTIONS

    ap = argparse.ArgumentParser(prog="hgo-mj", description=DESCRIPTION)
    ap.add_argument("--version", action="version", version=f"%(prog)s {_version()}",
                    help="print the installed version of hgo_mj and exit")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND",
                            help="what to do (hgo-mj COMMAND --help for its flags)")
    r = sub.add_parser("run", help="run a scenario (TOML file and/or flags)")
    r.add_argument("scenario", nargs="?", help="TOML scenario file")
    r.add_argument("--plant", help="plant name (see hgo-mj list)")
    r.add_argument("--model", metavar="FILE.xml",
                   help="any MJCF file as the plant (plant.model), with --outputs")
    r.add_argument("--outputs", nargs="+", metavar="NAME",
                   help="with --model: the measured MJCF sensors, or joints (their position)")
    r.add_argument("--inputs", nargs="+", metavar="NAME",
                   help="with --model: the actuators driven by the input (default all)")
    r.add_argument("--dt", type=float, help="plant step (control hold), seconds")
    r.add_argument("--x0", metavar="[X1,X2,...]",
                   help="initial true state, one value per plant state (plant.x0; default the "
                   "model's)")
    r.add_argument("--observer", action="append",
                   help="KIND:key=value,... e.g. high_gain:k=50 (repeatable)")
    r.add_argument("--sensor", action="append",
                   help="STAGE:key=value,... e.g. gaussian:std=1e-3 (repeatable, in order)")
    r.add_argument("--input", action="append",
                   help="KIND:key=value,... e.g. multisine:amplitudes=[1],frequencies=[0.5]; "
                   "repeat it for one signal per actuator, in the plant's input order")
    r.add_argument("--duration", type=float, help="simulated time, seconds (run.duration)")
    r.add_argument("--sample-period", dest="sample_period", type=float,
                   help="sensor sample period, seconds, a multiple of --dt (default --dt)")
    r.add_argument("--control-period", dest="control_period", type=float,
                   help="period at which the input is computed and held, seconds (default "
                   "--dt)")
    r.add_argument("--seed", type=int, help="seed of the sensor noise (run.seed, default 0)")
    r.add_argument("--t-transient", dest="t_transient", type=float, metavar="S",
                   help="metrics (RMSE, peak, final) over t >= S seconds (run.t_transient; "
                   "default the first 20%% of the run is left out)")
    r.add_argument("--band", type=float, metavar="FRACTION",
                   help="settling band as a fraction of each true state's range (run.band, "
                   "default 0.05)")
    r.add_argument("--store-every", dest="store_every", metavar="K",
                   help="keep every K-th sample row of the trajectory (run.store_every, default "
                   "1): memory and files K times smaller; the run itself and the observers "
                   "still take every sample, the metrics are computed from the kept rows")
    r.add_argument("--stream", action="store_true",
                   help="write the trajectory to OUT/trajectory.parquet chunk by chunk as the "
                   "run goes (run.stream): memory stays flat with the duration; metrics from "
                   "every row, the figure from every k-th (at most 20,000 rows); Parquet only")
    r.add_argument("--seeds", metavar="N",
                   help="Monte Carlo: N runs at the seeds SEED, SEED+1, ..., SEED+N-1; also "
                   "writes metrics_mc.json, summary_mc.txt and mc.png (default 1: one run)")
    r.add_argument("--resume", action="store_true",
                   help="with --seeds: keep the seeds finished by an interrupted run of the same "
                   "scenario (OUT/seeds) and run only the rest")
    r.add_argument("--jobs", metavar="J", default="1",
                   help="processes for the --seeds runs (default 1; the seeds after the first "
                   "run as one batch, so workers start only for 10 s of work or more; results "
                   "do not depend on it)")
    r.add_argument("--out", help="output folder (default runs/run)")
    r.add_argument("--rrd", metavar="FILE.rrd", type=_rrd_path,
                   help="also record to this rerun file (its name ends in .rrd)")
    r.add_argument("--format", dest="formats", action="append", choices=FORMATS,
                   help="files of the trajectory and metrics (repeatable): npz "
                   "(trajectory.npz), parquet (trajectory.parquet and metrics.parquet, units in "
                   "the schema) or csv (trajectory.csv, metrics.csv); default npz and parquet "
                   "(with --stream: parquet only)")
    r.add_argument("--quiet", action="store_true",
                   help="no progress on stderr (the --seeds study's plan line and progress)")
    sw = sub.add_parser("sweep", help="run a study: a scenario file with a [sweep] table of axes "
                        "and seeds (see hgo_mj.study)")
    sw.add_argument("study", help="study TOML file (a scenario with a [sweep] table)")
    sw.add_argument("--out", help="results folder (default runs/STUDY-FILE-NAME)")
    sw.add_argument("--seeds", metavar="N",
                    help="N seeds (SEED..SEED+N-1 of [run] seed) in place of the file's [sweep] "
                    "seeds: a quick look at a study")
    sw.add_argument("--jobs", metavar="N", default="1",
                    help="worker processes, or CPUs of a local Ray instance (default 1; the "
                    "results do not depend on it)")
    sw.add_argument("--backend", choices=["local", "ray"], default="local",
                    help="where the chunks run: local processes (default) or Ray "
                    '(pip install "hgo_mj[ray]")')
    sw.add_argument("--address", help="a Ray cluster's address (with --backend ray; default: "
                    "a local instance on 127.0.0.1)")
    sw.add_argument("--resume", action="store_true",
                    help="skip the (cell, seed) runs already in OUT/results.parquet (the same "
                    "study only)")
    sw.add_argument("--yes", action="store_true",
                    help="run a study of more than 10 million runs (one whose estimated memory "
                    "exceeds the memory available is still refused)")
    sw.add_argument("--quiet", action="store_true", help="no plan line and no progress")
    t = sub.add_parser("tune", help="tune a scenario's observer with Optuna (see hgo_mj.tune)")
    t.add_argument("scenario", help="scenario TOML file (open-loop [input]; the observer in "
                   "[[observers]])")
    t.add_argument("--observer", required=True, metavar="NAME",
                   help="the label of the observer to tune")
    t.add_argument("--budget", default="64", metavar="N",
                   help="trials in all, the untuned default included (default 64)")
    t.add_argument("--objective", action="append", metavar="SCORE",
                   help="rmse (default), peak, settling (ground truth), output_error, "
                   "whiteness, nis (no truth); repeat for a Pareto front")
    t.add_argument("--seeds", default="8", metavar="N", help="tuning seeds 1..N (default 8)")
    t.add_argument("--aggregate", choices=["mean", "worst"], default="mean",
                   help="over the seeds (and model mismatches): mean (default) or worst")
    t.add_argument("--sampler", choices=["tpe", "cmaes", "nsga2", "random"], default="tpe",
                   help="Optuna's sampler (default tpe; several objectives: nsga2)")
    t.add_argument("--seed", default="0", metavar="N", help="the sampler's seed (default 0)")
    t.add_argument("--out", help="results folder (default runs/tune-SCENARIO-OBSERVER)")
    t.add_argument("--resume", action="store_true",
                   help="go on with the study in OUT (the same tuning only)")
    t.add_argument("--backend", choices=["local", "ray"], default="local",
                   help="where the rounds run (default local)")
    t.add_argument("--jobs", default="1", metavar="N", help="Ray workers a round is split over")
    t.add_argument("--address", help="a Ray cluster's address (default a local instance)")
    t.add_argument("--quiet", action="store_true", help="no progress on stderr")
    b = sub.add_parser("bench", help="the nonlinear observer benchmark: every observer tuned by "
                       "the same budget on versioned tasks, scored, ranked (see hgo_mj.bench)")
    b.add_argument("--suite", choices=["quick", "full", "none"], default="quick",
                   help="the built-in suite (default quick; none: only --tasks/--task-file)")
    b.add_argument("--tasks", nargs="+", default=[], metavar="NAME",
                   help="built-in tasks by name, e.g. pendulum/encoder-v1")
    b.add_argument("--task-file", action="append", default=[], metavar="FILE",
                   help="a task of your own (TOML, the fields of hgo_mj.bench.Task); repeatable")
    b.add_argument("--observers", nargs="+", default=None, metavar="NAME",
                   help="registered observers (default every family)")
    b.add_argument("--observer", action="append", default=[], metavar="MODULE:CLASS",
                   help="your own observer (an Observer subclass), added to the observers")
    b.add_argument("--budget", default="24", metavar="N",
                   help="tuning trials per observer and task, the same for all (default 24)")
    b.add_argument("--out", default="runs/bench", help="results folder (default runs/bench)")
    b.add_argument("--resume", action="store_true",
                   help="reuse the finished (task, observer) parts in OUT")
    b.add_argument("--backend", choices=["local", "ray"], default="local",
                   help="where the tunings' rounds run (default local)")
    b.add_argument("--jobs", default="1", metavar="N",
                   help="local: processes the (task, observer) parts run in; ray: workers "
                        "(default 1)")
    b.add_argument("--no-rrd", dest="no_rrd", action="store_true",
                   help="no rerun recordings of each task's best and worst observer")
    b.add_argument("--quiet", action="store_true", help="no progress on stderr")
    c = sub.add_parser("check", help="which observer applies to a plant, and why")
    c.add_argument("target", metavar="PLANT-OR-SCENARIO",
                   help="a registered plant name (see hgo-mj list) or a scenario TOML file")
    c.add_argument("--sample-period", type=float, default=None, metavar="S",
                   help="sample period [s] to check against paper 004's LMI bound (default: "
                        "the scenario's run.sample_period, else the plant's step)")
    sub.add_parser("list", help="plants, sensor stages, observers, inputs, reproductions and papers")
    rp = sub.add_parser("reproduce", help="reproduce a paper's example (see hgo-mj list)")
    rp.add_argument("name", help="the reproduction: " + ", ".join(REPRODUCTIONS))
    rp.add_argument("--out", help="output folder (default runs/reproduce/NAME)")
    rp.add_argument("--rrd", metavar="FILE.rrd", type=_rrd_path,
                    help="also record to this rerun file (its name ends in .rrd)")
    rp.add_argument("--quiet", action="store_true", help="no progress on stderr")
    d = sub.add_parser("demo", help="elastic joint, encoder noise, high-gain observer at two gains")
    d.add_argument("--out", default="runs/demo-run", help="output folder (default runs/demo-run)")
    d.add_argument("--rrd", metavar="FILE.rrd", type=_rrd_path,
                   help="rerun recording (default OUT/demo.rrd)")
    d.add_argument("--no-rrd", dest="no_rrd", action="store_true", help="write no recording")
    return ap


def cmd_tune(args: argparse.Namespace) -> int:
    """``hgo-mj tune SCENARIO --observer NAME``: search the observer's tuning space, write
    trials.parquet, best.toml, summary.txt and figures, print the summary."""
    from .tune import tune
    from .tune.tuner import SCENARIO_TABLES

    sc = load_scenario_file(args.scenario)
    extra = sorted(set(sc) - SCENARIO_TABLES)
    if extra:
        raise DesignError(f"scenario {args.scenario!r}: tables {extra} are not part of a tuning "
                          f"scenario (a [sweep] belongs to hgo-mj sweep)")
    out = Path(args.out or f"runs/tune-{Path(args.scenario).stem}-{args.observer}")
    result = tune(sc, args.observer, objective=args.objective or "rmse",
                  budget=_flag_int(args.budget, "--budget"),
                  seeds=_flag_int(args.seeds, "--seeds"), aggregate=args.aggregate,
                  sampler=args.sampler, seed=_flag_seed(args.seed), out=out,
                  resume=args.resume, backend=args.backend,
                  jobs=_flag_int(args.jobs, "--jobs"), address=args.address,
                  progress=not args.quiet)
    print(result.summary)
    print(f"wrote {out}/trials.parquet ({len(result.trials)} trials), best.toml, summary.txt, "
          f"{', '.join(f'{k}.png' for k in result.figures)} and study.db in "
          f"{result.seconds:.1f} s")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    """``hgo-mj bench``: run the benchmark, print the leaderboard, say where the files are."""
    from .bench import bench

    observers = (list(args.observers) if args.observers else None)
    if args.observer:
        from .bench.report import default_observers

        observers = (observers or default_observers()) + list(args.observer)
    result = bench(None if args.suite == "none" else args.suite, tasks=args.tasks,
                   task_files=args.task_file, observers=observers,
                   budget=_flag_int(args.budget, "--budget"), out=args.out,
                   resume=args.resume, backend=args.backend,
                   jobs=_flag_int(args.jobs, "--jobs"), record=not args.no_rrd,
                   progress=not args.quiet)
    print(result.table)
    print(f"\nwrote {args.out}/leaderboard.md, leaderboard.parquet, scores.parquet "
          f"({len(result.scores)} rows), score_matrix.png, task_*.png, traj_*.png"
          + ("" if args.no_rrd else ", *.rrd") + f" in {result.seconds:.1f} s")
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    """``hgo-mj sweep``: plan, run, summarize and draw a study; print where it went."""
    from .study import Study
    from .study.spec import MAX_RUNS

    seeds = None if args.seeds is None else _flag_int(args.seeds, "--seeds")
    study = Study.from_toml(args.study, max_runs=None if args.yes else MAX_RUNS, seeds=seeds)
    out = check_writable("--out", args.out or f"runs/{Path(args.study).stem}", folder=True)
    jobs = _flag_int(args.jobs, "--jobs")
    result = study.run(out, jobs=jobs, backend=args.backend, address=args.address,
                       resume=args.resume, quiet=args.quiet)
    figures = result.plot(out)
    print(sweep_summary(result))
    names = sorted(p.name for p in out.glob("*.png"))
    print(f"\nthe whole table: {out / 'summary.md'}\n"
          f"wrote {out}/results.parquet ({len(result.table)} rows), summary.parquet, summary.md, "
          f"study.json and {len(figures)} figure(s) ({', '.join(names)}) in "
          f"{result.seconds:.1f} s")
    return 0


def sweep_summary(result: Any) -> str:
    """What ``hgo-mj sweep`` prints: per observer and state the best cell (least median RMSE
    over the seeds) with its swept values and units, and, for a gain x noise study, the fitted
    power law of the best gain (:func:`hgo_mj.study.figures.best_gains`)."""
    from .metrics import text_table
    from .study.figures import _units_of, best_gains, gain_noise_axes

    unit_of, _ = _units_of(result)
    s = result.summary()
    s = s[s["estimated"] & s["rmse_median"].notna()]
    best = s.loc[s.groupby(["observer", "state"], sort=False)["rmse_median"].idxmin()]
    rows = [{"observer": r["observer"], "state": r["state"],
             "unit": unit_of(r["state"]) or "-", "rmse median": r["rmse_median"],
             "rmse iqr": r["rmse_iqr"], "best cell": ", ".join(
                 f"{a} = {r[a]:g}" if isinstance(r[a], float) else f"{a} = {r[a]}"
                 for a in result.axes)} for _, r in best.iterrows()]
    text = (f"{result.study.name}: the best cell per observer and state (least median RMSE "
            f"over the seeds)\n" + text_table(rows, ["observer", "state", "unit", "rmse median", "rmse iqr",
                                                      "best cell"],
                                               ["observer", "state", "unit", "best cell"]))
    if gain_noise_axes(list(result.axes)) is not None:
        per = ["sigma", "k_star", "interior", "rmse_min"]
        bg = best_gains(result)
        bg = bg.drop_duplicates([c for c in bg.columns if c not in per])
        groups = [c for c in bg.columns if c not in (*per, "observer", "state", "slope", "order")]
        lines = [f"  {r['observer']}, " + "".join(f"{c} = {r[c]}, " for c in groups)
                 + f"{r['state']}: k* ~ sigma^{r['slope']:.2f}"
                 + (f" (theory {-1 / r['order']:.2f})" if r["order"] == r["order"] else "")
                 for _, r in bg.iterrows()]
        text += ("\n\nthe best gain per noise level (best_gain.png), its fitted power law:\n"
                 + "\n".join(lines))
    return text


def _reproduction_kwargs(name: str, rrd: Path | None, quiet: bool = False) -> dict[str, Any]:
    """``rrd=`` for a reproduction's ``run()`` when asked for, if that ``run()`` takes it;
    ``quiet=True`` when asked for and taken (a ``run()`` without it shows no progress)."""
    from .reproduce import REPRODUCTIONS

    if name not in REPRODUCTIONS:  # an unknown name is reported by run_reproduction
        return {} if rrd is None else {"rrd": rrd}
    params = inspect.signature(run_of(name)).parameters
    kw: dict[str, Any] = {"quiet": True} if quiet and "quiet" in params else {}
    if rrd is None:
        return kw
    if "rrd" not in params:
        raise DesignError(f"reproduction {name!r} cannot record: expected run(out, *, rrd=None)"
                          f"; found run{inspect.signature(run_of(name))}")
    return {**kw, "rrd": rrd}


def run_of(name: str) -> Any:
    """The ``run`` function of the reproduction called ``name``."""
    import importlib

    from .reproduce import REPRODUCTIONS

    return importlib.import_module(REPRODUCTIONS[name][0]).run


def cmd_reproduce(args: argparse.Namespace) -> int:
    """``hgo-mj reproduce NAME``: run a paper reproduction and print its report."""
    from .reproduce import run_reproduction

    out = Path(args.out or f"runs/reproduce/{args.name}")
    rrd = args.rrd
    run_reproduction(args.name, out, **_reproduction_kwargs(args.name, rrd, args.quiet))
    if (out / "report.txt").is_file():  # the readable report (summary.json: the data)
        print((out / "report.txt").read_text().rstrip("\n"))
    print(f"\nwrote {out}/summary.json, report.txt and figures"
          + (f", {rrd}" if rrd is not None else ""))
    return 0


def cmd_check(target: str, sample_period: float | None = None) -> int:
    """``hgo-mj check PLANT-OR-SCENARIO [--sample-period S]``: which observer applies to the
    plant, and why; the sample period (the flag, else the scenario's ``run.sample_period``, else
    the plant's step) against paper 004's LMI bound, over the region of an ODE plant
    (:func:`hgo_mj.scenario.region_plant`: ``[plant] region`` or the region a short simulation
    visits, with a warning where ``x0`` or the run leaves a given region)."""
    from . import check
    from .scenario import build_plant, region_plant

    notes: list[str] = []
    if target.endswith(".toml"):
        sc = load_scenario_file(target)
        pl = sc.get("plant", {})
        if not any(k in pl for k in ("name", "model", "f")):
            raise DesignError(f"scenario {target!r} has no plant ([plant] name, model or f)")
        plant, notes = region_plant(sc)
        if sample_period is None:
            sample_period = sc.get("run", {}).get("sample_period")
    else:
        plant = build_plant({"name": target})
    if sample_period is None:
        sample_period = getattr(plant, "dt", None)
    print("\n".join([*notes, check.table(plant.system, sample_period)]))
    return 0


def main(argv: list[str] | None = None) -> int:
    """The ``hgo-mj`` console script: parse the command line and run the command (module
    docstring); the results and reports go to stdout, errors to stderr as one line.

    Parameters
    ----------
    argv : list of str, optional
        The arguments after the program name, e.g. ``["run", "scenario.toml"]``; default
        ``sys.argv[1:]``.

    Returns
    -------
    int
        The exit status: 0 done, 2 bad input (a scenario, flag or value refused), 1 a fault
        of the machine (a result or recording that cannot be written), 130 interrupted by
        Ctrl-C. ``argparse`` itself exits (``SystemExit``) on an unknown command or flag and
        for ``--help``.

    Examples
    --------
    >>> main(["list"])
    PLANTS (hgo-mj run --plant NAME)
      pendulum ...
    0
    >>> main(["run", "--plant", "pendulum"])  # no duration: bad input, one line on stderr
    2
    """
    # Arrow's default allocator (mimalloc) keeps what a streamed run's join and settling
    # pass freed (+20 MB at the peak of a 3,600 s run): the C library's, unless the user
    # chose one. Read once, when pyarrow is imported, which no command has done yet.
    os.environ.setdefault("ARROW_DEFAULT_MEMORY_POOL", "system")
    args = build_parser().parse_args(argv)
    rrd: Path | None = None
    try:
        if args.command == "list":
            print(cmd_list())
            return 0
        if args.command == "sweep":
            return cmd_sweep(args)
        if args.command == "tune":
            return cmd_tune(args)
        if args.command == "bench":
            return cmd_bench(args)
        if args.command == "check":
            return cmd_check(args.target, args.sample_period)
        if args.command == "reproduce":
            return cmd_reproduce(args)
        if args.command == "demo":
            sc = json.loads(json.dumps(DEMO))
            jobs, formats, quiet, resume = 1, DEFAULT_FORMATS, False, False
            sc["run"]["out"] = args.out
            name = "demo"
            rrd = None if args.no_rrd else args.rrd or Path(args.out) / "demo.rrd"
        else:
            sc = scenario_from_args(args)
            jobs = _flag_int(args.jobs, "--jobs")
            formats, quiet, resume = args.formats, args.quiet, args.resume
            name = "run"
            rrd = args.rrd
        traj, metrics, out, mc = run_study(sc, name, rrd=rrd, jobs=jobs, formats=formats,
                                           quiet=quiet, resume=resume)
    except RecordingError as exc:  # a fault of the machine (full disk), not of the input
        print(f"hgo-mj: error: {exc}", file=sys.stderr)
        return 1
    except (HgoError, ValueError) as exc:
        print(f"hgo-mj: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # a result that could not be written (full disk, removed folder)
        print(f"hgo-mj: error: cannot write {exc.filename or 'a result'}: "
              f"{exc.strerror or exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("hgo-mj: interrupted" + (f"; {rrd} holds the run up to its last chunk"
                                       if rrd is not None else "")
              + ("; the finished runs are kept: rerun with --resume to go on"
                 if args.command == "sweep" or getattr(args, "seeds", None) else ""),
              file=sys.stderr)
        return 130
    print(_report(traj, metrics, mc, out, rrd, formats, sc["run"].get("stream", False)))
    return 0


def _report(traj: Any, metrics: dict[str, Any], mc: Any, out: Path, rrd: Path | None,
            formats: Any, stream: bool) -> str:
    """What ``hgo-mj run`` prints at the end: the metrics table (and the Monte Carlo one), with
    the plant's units, and the files written."""
    from .metrics import format_table
    from .units import units_of

    units, t_unit = units_of(traj)
    text = format_table(metrics, units, t_unit)
    if mc is not None:
        text += (f"\n\nMonte Carlo over the seeds {mc.seeds[0]}..{mc.seeds[-1]} (the table "
                 f"above: seed {mc.seeds[0]})\n" + mc.table(units, t_unit))
    if formats is None:
        formats = STREAM_FORMATS if stream else DEFAULT_FORMATS
    files = [f for f in ("trajectory.npz", "trajectory.parquet", "metrics.parquet",
                         "trajectory.csv", "metrics.csv") if f.split(".")[1] in formats]
    return (text + f"\n\nwrote {out}/"
            + ", ".join([*files, "metrics.json", "figure.png", "summary.txt"])
            + (", metrics_mc.json, summary_mc.txt, mc.png" if mc is not None else "")
            + (f", {rrd}" if rrd is not None else ""))


#: the console script; the other functions are the command's internals
__all__ = ["main"]


if __name__ == "__main__":
    sys.exit(main())
