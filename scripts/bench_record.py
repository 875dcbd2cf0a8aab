"""What a rerun recording adds to a run: a 10 s, 1 kHz pendulum run with two observers.

Usage: ``python scripts/bench_record.py [--repeats N] [--against REV] [--chunks S ...]
[--write BENCHMARKS.md]``.

Three variants of the same run (same seed, bit-identical trajectories) are timed side by side
in one process, interleaved, ``--repeats`` times each:

* ``plain``: ``simulate`` and ``all_metrics`` (what ``hgo-mj run`` computes anyway);
* ``live``: the same with a :class:`hgo_mj.record.Recorder` fed a chunk every
  ``hgo_mj.cli.RRD_CHUNK_SECONDS`` of simulated time (``on_chunk``, as ``hgo-mj run --rrd``
  does), then the metadata, the metrics table and ``close``;
* ``after``: the same, then :func:`hgo_mj.record.record_trajectory` with those metrics;
* ``live_nofooter``: ``live`` without rerun's footer (``Recorder(footer=False)``), to show
  what the footer costs at ``close`` (not a target variant);
* ``replay``: the recorder alone, ``live``'s chunks replayed from one precomputed run;
* ``floor``: rerun alone, the floor of any recorder on rerun's public API: the same
  per-sample entities and values as ``replay`` (:func:`hgo_mj.record.rows.signal_series`,
  one ``rr.send_columns`` per entity and chunk) sent to a bare stream with a file sink and
  its footer, without styles, diagnostics, poses, blueprint, documents or the closing check;
* ``command`` and ``command_rrd``: the same scenario as a user runs it, ``hgo-mj run ...``
  end to end (simulation, metrics, ``trajectory.npz``, ``metrics.json``, the figure), without
  and with ``--rrd``;
* with ``--against REV``: ``live``, ``after`` and ``replay`` with the recorder of git
  revision ``REV`` (its ``hgo_mj/record/`` package, or the single module
  ``hgo_mj/record.py`` of older revisions, loaded as ``hgo_mj._record_REV`` beside this
  tree's), ``live`` and ``replay`` in the chunks of that revision's ``RRD_CHUNK_SECONDS``:
  e.g. ``main`` before a change to the recorder, or ``3ced465``, whose rows, styles and
  geometry went to rerun as hand-built Arrow record batches carrying rerun's private field
  metadata;
* with ``--chunks S ...``: ``live`` in chunks of ``S`` simulated seconds, for each ``S``
  (what a chunk costs while the run goes on).

The target is read two ways, both reported: against the bare computation (``plain``, the
strict reading) and against the command a user runs (``command``).

Each time covers everything from building the recorder to the file being closed. The figure
reported is the best of the repeats (the machine is shared; noise only adds), the median is
shown beside it, and so is the process's CPU time (all threads: rerun encodes and writes on its
own threads, which a second core absorbs in wall time). Targets (issue 6): recording adds at
most 10% to the run; the issue "State as data" reads it on CPU (all threads), and asks for a
file of at most 2.35 MB (its size before one entity per observer and state). The live
recorders are given ``dropouts=`` as ``hgo-mj run --rrd`` gives it (no dropout stage here: no
dropout series).
"""

from __future__ import annotations

import argparse
import importlib.util
import inspect
import io
import os
import re
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import hgo_mj.record
from hgo_mj._bench import header, write_section
from hgo_mj.cli import RRD_CHUNK_SECONDS
from hgo_mj.inputs import make_signal
from hgo_mj.metrics import all_metrics
from hgo_mj.observers import make_observer
from hgo_mj.plants import make_plant
from hgo_mj.record import Recorder, record_trajectory
from hgo_mj.sensors import SensorChain
from hgo_mj.simulate import simulate

DURATION = 10.0


def setup():
    plant = make_plant("pendulum", 0.001)
    sensor = SensorChain.from_spec([{"stage": "gaussian", "std": 1e-3},
                                    {"stage": "quantize", "counts_per_rev": 4096}], seed=0)
    obs = {"hgo_k15": make_observer("high_gain", plant.system, k=15.0),
           "hgo_k60": make_observer("high_gain", plant.system, k=60.0)}
    inputs = make_signal("multisine", amplitudes=[0.3], frequencies=[0.5])
    return plant, sensor, obs, inputs


def run_plain(path: Path) -> None:
    plant, sensor, obs, inputs = setup()
    traj = simulate(plant, sensor, obs, inputs, DURATION, x0=[0.5, 0.0], seed=1)
    all_metrics(traj)


def run_live_nofooter(path: Path) -> None:
    plant, sensor, obs, inputs = setup()
    rec = Recorder.for_plant(path, plant, list(obs), recording_name="bench_record", footer=False,
                             dropouts=sensor.has_dropouts)
    traj = simulate(plant, sensor, obs, inputs, DURATION, x0=[0.5, 0.0], seed=1,
                    on_chunk=(RRD_CHUNK_SECONDS, rec.write_chunk))
    rec.log_metadata(traj.metadata)
    rec.log_metrics(all_metrics(traj))
    rec.close()


def run_after(path: Path) -> None:
    plant, sensor, obs, inputs = setup()
    traj = simulate(plant, sensor, obs, inputs, DURATION, x0=[0.5, 0.0], seed=1)
    record_trajectory(traj, path, metrics=all_metrics(traj))


def recorder_of(rev: str, tmp: Path) -> object:
    """The recorder of git revision ``rev`` imported inside ``hgo_mj`` as
    ``hgo_mj._record_<rev>``: its package ``hgo_mj/record/`` (exported with ``git archive``),
    or the single module ``hgo_mj/record.py`` of revisions before the package; its relative
    imports find this tree's ``hgo_mj``."""
    root = Path(__file__).resolve().parent.parent
    name = "hgo_mj._record_" + re.sub(r"\W", "_", rev)
    tree = subprocess.run(["git", "-C", str(root), "ls-tree", "--name-only", rev, "hgo_mj/"],
                          capture_output=True, text=True, check=True).stdout.split()
    if "hgo_mj/record" in tree:
        archive = subprocess.run(["git", "-C", str(root), "archive", rev, "hgo_mj/record"],
                                 capture_output=True, check=True).stdout
        with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
            tar.extractall(tmp / name, filter="data")
        init = tmp / name / "hgo_mj" / "record" / "__init__.py"
        spec = importlib.util.spec_from_file_location(
            name, init, submodule_search_locations=[str(init.parent)])
    else:
        src = subprocess.run(["git", "-C", str(root), "show", f"{rev}:hgo_mj/record.py"],
                             capture_output=True, text=True, check=True).stdout
        (tmp / f"{name}.py").write_text(src)
        spec = importlib.util.spec_from_file_location(name, tmp / f"{name}.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


def chunk_seconds_of(rev: str) -> float:
    """``RRD_CHUNK_SECONDS`` of ``hgo_mj/cli.py`` at git revision ``rev``: the chunks its
    ``hgo-mj run --rrd`` recorded in."""
    root = Path(__file__).resolve().parent.parent
    src = subprocess.run(["git", "-C", str(root), "show", f"{rev}:hgo_mj/cli.py"],
                         capture_output=True, text=True, check=True).stdout
    found = re.search(r"^RRD_CHUNK_SECONDS = ([0-9.]+)", src, re.MULTILINE)
    if found is None:
        raise SystemExit(f"{rev}:hgo_mj/cli.py defines no RRD_CHUNK_SECONDS")
    return float(found.group(1))


_RUN: dict[str, object] = {}


def replay_with(mod: object, chunk_seconds: float = RRD_CHUNK_SECONDS):
    """The recorder alone: the chunks ``simulate(on_chunk=...)`` hands ``live``, replayed from
    one precomputed run, then metadata, metrics and ``close`` (no simulation in the time)."""
    def replay(path: Path) -> None:
        if not _RUN:
            plant, sensor, obs, inputs = setup()
            traj = simulate(plant, sensor, obs, inputs, DURATION, x0=[0.5, 0.0], seed=1)
            _RUN.update(plant=plant, obs=list(obs), traj=traj, metrics=all_metrics(traj),
                        dropouts=sensor.has_dropouts)
        traj, rows = _RUN["traj"], len(_RUN["traj"])
        block = int(round(chunk_seconds / float(traj.t[1] - traj.t[0])))
        rec = mod.Recorder.for_plant(path, _RUN["plant"], _RUN["obs"], recording_name="bench_record",
                                     dropouts=_RUN["dropouts"])
        k0 = 0
        while k0 < rows:  # as simulate: a tail under half a chunk joins the last chunk
            k1 = rows if rows - (k0 + block) < block // 2 else k0 + block
            rec.write_chunk(0, traj, slice(k0, k1))
            k0 = k1
        rec.log_metadata(traj.metadata)
        rec.log_metrics(_RUN["metrics"])
        rec.close()

    return replay


def run_floor(path: Path) -> None:
    """rerun alone: ``replay``'s per-sample rows, nothing else (see the module docstring)."""
    import numpy as np
    import rerun as rr

    from hgo_mj.record.layout import estimate_layout
    from hgo_mj.record.rows import Block, signal_series
    from hgo_mj.record.sink import BATCHER, time_columns

    if not _RUN:
        replay_with(hgo_mj.record)(path)
    plant, traj = _RUN["plant"], _RUN["traj"]
    lay = estimate_layout(plant.state_names, _RUN["obs"],
                          {o: traj.observers[o].state_names for o in _RUN["obs"]})
    stream = rr.RecordingStream("hgo_mj", make_default=False, make_thread_default=False,
                                batcher_config=BATCHER)
    stream.save(path)
    rows, block = len(traj), int(round(RRD_CHUNK_SECONDS / float(traj.t[1] - traj.t[0])))
    k0 = 0
    while k0 < rows:
        k1 = rows if rows - (k0 + block) < block // 2 else k0 + block
        r = slice(k0, k1)
        b = Block(traj.t[r], np.arange(k0, k1, dtype=np.int64), None, traj.x[r],
                  traj.y_clean[r], traj.y_meas[r], traj.u[r],
                  {o: traj.observers[o].x_hat[r] for o in _RUN["obs"]}, {}, {})
        clock = time_columns(b.t, b.steps, None)
        for entity, values, on_clock in signal_series(lay, b, plant.output_names,
                                                      plant.input_names, {}):
            rr.send_columns(entity, indexes=clock if on_clock else clock[:1],
                            columns=rr.Scalars.columns(scalars=values), recording=stream)
        k0 = k1
    stream.flush()
    stream.disconnect()


def live_in(chunk_seconds: float):
    """``live`` in chunks of ``chunk_seconds``."""
    def live(path: Path) -> None:
        plant, sensor, obs, inputs = setup()
        rec = Recorder.for_plant(path, plant, list(obs), recording_name="bench_record",
                                 dropouts=sensor.has_dropouts)
        traj = simulate(plant, sensor, obs, inputs, DURATION, x0=[0.5, 0.0], seed=1,
                        on_chunk=(chunk_seconds, rec.write_chunk))
        rec.log_metadata(traj.metadata)
        rec.log_metrics(all_metrics(traj))
        rec.close()

    return live


def variants_of(mod: object, chunk_seconds: float) -> tuple:
    """``live`` (chunks of ``chunk_seconds``) and ``after`` with the recorder module ``mod``."""
    def live(path: Path) -> None:
        plant, sensor, obs, inputs = setup()
        kw = ({"dropouts": sensor.has_dropouts}  # as run_live, where the recorder takes it
              if "dropouts" in inspect.signature(mod.Recorder).parameters else {})
        rec = mod.Recorder.for_plant(path, plant, list(obs), recording_name="bench_record", **kw)
        traj = simulate(plant, sensor, obs, inputs, DURATION, x0=[0.5, 0.0], seed=1,
                        on_chunk=(chunk_seconds, rec.write_chunk))
        rec.log_metadata(traj.metadata)
        rec.log_metrics(all_metrics(traj))
        rec.close()

    def after(path: Path) -> None:
        plant, sensor, obs, inputs = setup()
        traj = simulate(plant, sensor, obs, inputs, DURATION, x0=[0.5, 0.0], seed=1)
        mod.record_trajectory(traj, path, metrics=all_metrics(traj))

    return live, after


COMMAND = ["run", "--plant", "pendulum", "--sensor", "gaussian:std=1e-3",
           "--sensor", "quantize:counts_per_rev=4096", "--observer", "high_gain:name=hgo_k15,k=15",
           "--observer", "high_gain:name=hgo_k60,k=60",
           "--input", "multisine:amplitudes=[0.3],frequencies=[0.5]",
           "--duration", str(DURATION), "--seed", "1"]


def _command(argv: list[str]) -> None:
    import contextlib
    import io

    from hgo_mj.cli import main as cli_main

    with contextlib.redirect_stdout(io.StringIO()):
        if cli_main(argv) != 0:
            raise RuntimeError(f"hgo-mj {' '.join(argv)} failed")


def run_command(path: Path) -> None:
    _command([*COMMAND, "--out", str(path.with_suffix(""))])


def run_command_rrd(path: Path) -> None:
    _command([*COMMAND, "--out", str(path.with_suffix("")), "--rrd", str(path)])


def timed(fn, path: Path) -> tuple[float, float, float]:
    """Wall time, CPU time of the whole process (every thread, rerun's included) and CPU
    time of the calling thread (the run and the recorder's calls; rerun encodes and writes
    on its own threads)."""
    w0, c0, t0 = time.perf_counter(), time.process_time(), time.thread_time()
    fn(path)
    return time.perf_counter() - w0, time.process_time() - c0, time.thread_time() - t0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--against", metavar="REV",
                    help="also time the recorder of this git revision (live, after, replay)")
    ap.add_argument("--chunks", type=float, nargs="*", default=[], metavar="S",
                    help="also record live in chunks of S simulated seconds")
    ap.add_argument("--write", help="replace the bench_record block of this markdown file")
    args = ap.parse_args()
    variants = {"plain": run_plain, "live": live_in(RRD_CHUNK_SECONDS), "after": run_after,
                "live_nofooter": run_live_nofooter, "replay": replay_with(hgo_mj.record),
                "floor": run_floor,
                "command": run_command, "command_rrd": run_command_rrd}
    for sec in args.chunks:
        variants[f"live_{sec:g}"] = live_in(sec)
    times: dict[str, list[float]] = {k: [] for k in variants}
    cpu: dict[str, list[float]] = {k: [] for k in variants}
    main_cpu: dict[str, list[float]] = {k: [] for k in variants}
    sizes: dict[str, int] = {}
    rev_chunk = RRD_CHUNK_SECONDS
    with tempfile.TemporaryDirectory() as tmp:
        if args.against:
            mod = recorder_of(args.against, Path(tmp))
            rev_chunk = chunk_seconds_of(args.against)
            live, after = variants_of(mod, rev_chunk)
            variants.update({"live_rev": live, "after_rev": after,
                             "replay_rev": replay_with(mod, rev_chunk)})
            for d in (times, cpu, main_cpu):
                d.update(live_rev=[], after_rev=[], replay_rev=[])
        for name, fn in variants.items():  # warm-up: imports, first MjModel, rerun's threads
            fn(Path(tmp) / f"warm_{name}.rrd")
        for r in range(args.repeats):
            for name, fn in variants.items():
                path = Path(tmp) / f"{name}_{r}.rrd"
                wall, used, own = timed(fn, path)
                times[name].append(wall)
                cpu[name].append(used)
                main_cpu[name].append(own)
                if path.exists():
                    sizes[name] = path.stat().st_size
    best = {k: min(v) for k, v in times.items()}
    med = {k: statistics.median(v) for k, v in times.items()}
    best_cpu = {k: min(v) for k, v in cpu.items()}
    best_main = {k: min(v) for k, v in main_cpu.items()}
    chunks = (" --chunks " + " ".join(f"{c:g}" for c in args.chunks)) if args.chunks else ""
    lines = [
        "## Issue 6 and 10: rerun recordings",
        "",
        *header(f"`python scripts/bench_record.py --repeats {args.repeats}"
                f"{f' --against {args.against}' if args.against else ''}{chunks}` (each variant run "
                f"{args.repeats} times, interleaved, after one warm-up; best and median)"),
        f"Run: pendulum.xml, {DURATION:g} s at 1 kHz ({int(DURATION * 1000) + 1} samples), sensor "
        "gaussian + quantize, two high-gain observers (k = 15, 60), multisine input.",
        "",
        "| variant | wall, best [ms] | wall, median [ms] | added to the run (wall, best) "
        "| CPU, all threads, best [ms] | added (CPU) | CPU, calling thread, best [ms] "
        "| file [MB] |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    labels = {"plain": "`simulate` and `all_metrics` (the run)",
              "live": f"recorded during the run ({RRD_CHUNK_SECONDS:g} s chunks, as `hgo-mj run --rrd`)",
              "after": "`simulate`, then `record_trajectory`",
              "live_nofooter": "recorded during the run, `Recorder(footer=False)` (for comparison)",
              "command": "`hgo-mj run ...` end to end (npz, metrics.json, figure)",
              "command_rrd": "`hgo-mj run ... --rrd` end to end",
              "replay": "the recorder alone: `live`'s chunks replayed from a precomputed run",
              "floor": "rerun alone: `replay`'s per-sample rows to a bare file stream (the floor)",
              "replay_rev": (f"the recorder alone, the recorder of `{args.against}` "
                             f"({rev_chunk:g} s chunks)"),
              "live_rev": (f"recorded during the run, the recorder of `{args.against}` "
                           f"({rev_chunk:g} s chunks, as its `hgo-mj run --rrd`)"),
              "after_rev": f"`simulate`, then `record_trajectory` of `{args.against}`"}
    labels.update({f"live_{sec:g}": f"recorded during the run, {sec:g} s chunks"
                   for sec in args.chunks})
    base_of = {k: ("command" if k.startswith("command") else "plain") for k in variants}
    order = ["plain", "live", "live_rev", *(f"live_{sec:g}" for sec in args.chunks), "after",
             "after_rev", "live_nofooter", "replay", "replay_rev", "floor", "command",
             "command_rrd"]  # each next to the variants it compares with
    variants = {k: variants[k] for k in order if k in variants}
    for k in variants:
        b = base_of[k]
        added = "" if k == b else f"{100 * (best[k] / best[b] - 1):+.1f}%"
        added_cpu = "" if k == b else f"{100 * (best_cpu[k] / best_cpu[b] - 1):+.1f}%"
        if k.startswith(("replay", "floor")):  # its whole time is what it adds
            added = f"+{100 * best[k] / best[b]:.1f}%"
            added_cpu = f"+{100 * best_cpu[k] / best_cpu[b]:.1f}%"
        size = f"{sizes[k] / 1e6:.2f}" if k in sizes else ""
        lines.append(f"| {labels[k]} | {1e3 * best[k]:.1f} | {1e3 * med[k]:.1f} | {added} | "
                     f"{1e3 * best_cpu[k]:.1f} | {added_cpu} | {1e3 * best_main[k]:.1f} | "
                     f"{size} |")
    ok_t = all(best[k] <= 1.10 * best["plain"] for k in ("live", "after"))
    ok_cpu = all(best_cpu[k] <= 1.10 * best_cpu["plain"] for k in ("live", "after"))
    ok_c = best["command_rrd"] <= 1.10 * best["command"]
    ok_s = all(s <= 2.35e6 for s in sizes.values())
    lines += ["", f"Targets: at most +10% to the run: against the bare computation, wall "
              f"{'met' if ok_t else 'NOT met'}, CPU {'met' if ok_cpu else 'NOT met'}; against "
              f"the command as run (wall) {'met' if ok_c else 'NOT met'}; file at most 2.35 MB: "
              f"{'met' if ok_s else 'NOT met'}. "
              f"Load average at the end: {os.getloadavg()[0]:.2f}."]
    text = "\n".join(lines)
    print(text)
    if args.write:
        write_section(args.write, "bench_record", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
