"""Write the benchmark's documentation from a benchmark run (issue 26).

Usage: ``python scripts/bench_docs.py RESULTS [--docs docs/benchmark]``, where ``RESULTS`` is
the ``--out`` folder of ``hgo-mj bench`` (e.g. the full suite:
``hgo-mj bench --suite full --out docs/benchmark/results``).

Writes ``DOCS/index.md`` (what the benchmark is, how scores and ranks are made, how to submit
an observer or a task, and the current leaderboard from ``RESULTS/leaderboard.md``) and one
page per task, ``DOCS/tasks/<task>.md`` (the plant, the sensor and its datasheet parameters,
the observers' model, the seeds, the hash, what makes it hard, and its figures from
``RESULTS``).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from hgo_mj._io import write_text
from hgo_mj.bench import PRESETS, SUITES, TASKS, task_hash
from hgo_mj.bench.tasks import SUPERSEDED

INTRO = """# The nonlinear observer benchmark

No maintained benchmark of nonlinear state observers exists: the nonlinear system-identification
benchmarks have no hidden-state truth, and the one published side-by-side comparison of
high-gain, sliding-mode and Kalman observers ran on a single engine simulator. hgo_mj has the
plants, a realistic sensor chain, the truth, the observer families of five papers and baselines
from outside them, and an engine that runs thousands of runs in seconds: `hgo-mj bench` gives a
new observer a row in a known table with one command, and a practitioner reads which observer
to use for a plant and a sensor like theirs.

## What a task fixes

A task (`pendulum/encoder-v1`) fixes the plant, its initial state and input, the sensor (a
preset written from datasheet parameters: `hgo_mj.bench.presets`), the sample period, the model
the observers are given (nominal, or off by 10 %: the *mismatch tier*), the duration and the
transient window, disjoint **tuning seeds** and **scoring seeds**, and the scored states. Its
definition is frozen by its SHA-256 (`hgo_mj.bench.task_hash`; `tests/bench` holds every
version's hash): a change is a new version. The **quick suite** (`make demo`) has four tasks,
the **full suite** all {n} below.

`make demo` runs the quick suite as `hgo-mj bench --suite quick --budget 8 --jobs 2`: its ten
cheaper families (`SUITE_OBSERVERS`: the MuJoCo filters and the moving-horizon estimator, 10-100x
the cost of the others, are left out) with 8 tuning trials each, the (task, observer) parts in
two processes (`--jobs J`: this one and J - 1 workers; no score depends on it). Its first run
also compiles the observers' numba kernels, once per kernel and system, and caches them; the
cold and the warm time side by side: BENCHMARKS.md (`scripts/bench_quick.py`).

## Fairness

Every observer is tuned on a task's tuning seeds with the **same budget** of trials
(`hgo-mj tune`: Optuna over the tuning space its class declares, the normalized steady-state
RMSE as objective), then scored on the scoring seeds, which the tuning never saw. The untuned
default is scored too, in its own column. An observer that does not apply to a task (its
`applicability` on the task's system, or a model it cannot be built on) is listed with its
reason, not scored.

## Scores and ranks

Per observer, task, scoring seed and scored state (`scores.parquet`): the steady-state RMSE
over the state's range; the noise amplification (the steady-state RMSE over the sensor's
standard deviation, with its unit); the settling time into a 5 % band; the peak error. Per seed:
the transient (the integral of the normalized error norm over the first second), the peaking
(the largest normalized error over the initial one), the divergence, the warm cost per
update (compile excluded), and for a filter (an observer that keeps a covariance) its
**consistency**: the mean NIS (normalized innovation squared; expected: the number of measured
channels) and the mean NEES (normalized estimation error squared over the plant states it
estimates, read at about 200 instants after the transient; expected: the number of states),
each with the share of its values inside one sample's chi-square 95 % band (about 0.95 for a
consistent filter; Bar-Shalom, Li and Kirubarajan 2001, sec. 5.4.2). An over-confident filter
has NIS and NEES above their expected values and a small share in the band. Per task: the
robustness (the mismatch tier's RMSE
over the nominal tier's) and, for the Riccati observer, the largest sample period paper 004's
LMI certifies at its tuned gain. The leaderboard gives each as the mean over the scoring seeds
with a 95 % bootstrap interval (BCa, the seeds resampled).

**Rank.** On a task, the observers are ranked by their mean normalized steady-state RMSE (a
diverged observer last), ties broken by the transient. The overall rank orders the mean over the
tasks an observer was scored on of its normalized rank (rank - 1) / (n - 1) (0 best, 1 worst):
a family that applies to fewer tasks is neither rewarded nor punished for it, and one RMSE scale
does not dominate another task's. Why not the mean normalized RMSE itself: the tasks' scales
differ by orders of magnitude (a bioreactor against a pendulum), so a mean of values would be a
ranking of the hardest task alone.

## Submit an observer

Write an `Observer` subclass (docs/guide/own_plant_observer.rst: state and parameters as data;
declare its tunable parameters in `_parameters` and, if the default span does not fit, its
`tuning_space`), then

```sh
hgo-mj bench --suite full --observer mypkg.observers:MyObserver --out runs/mine
```

or register it through the entry-point group `hgo_mj.observers` and name it like a built-in
one. A task of your own is a TOML file with the fields of `hgo_mj.bench.Task`
(`--task-file my_task.toml`), scored next to the built-in ones.

## Tasks

{tasks}

```{{toctree}}
:hidden:
:maxdepth: 1

{toc}
```

## Leaderboard

{board}
"""


def task_page(name: str, results: Path, docs: Path) -> str:
    t = TASKS[name]
    slug = name.replace("/", "__")
    params = {**PRESETS[t.sensor], **t.sensor_params}
    lines = [f"# {name}", "", t.description, "",
             f"- hash: `{task_hash(t)}`",
             f"- plant: `{t.plant}`",
             f"- input: `{t.input}`",
             f"- sensor: `{t.sensor}`, " + ", ".join(f"{k} = {v:g}" for k, v in params.items()),
             f"- sample period: {t.sample_period or 'the plant step'}",
             f"- observers' model: {t.mismatch or 'nominal'}",
             f"- duration {t.duration:g} s, transient window {t.t_transient:g} s",
             f"- tuning seeds {list(t.tuning_seeds)}, scoring seeds {list(t.scoring_seeds)}",
             f"- scored states: {list(t.states) or 'every state an observer estimates'}", ""]
    for fig, what in ((f"task_{slug}.png", "each observer's score"),
                      (f"traj_{slug}.png", "the best and the worst observer")):
        if (results / fig).is_file():
            rel = os.path.relpath(results / fig, docs / "tasks")
            lines += [f"![{what}]({rel})", ""]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", type=Path)
    ap.add_argument("--docs", type=Path, default=Path("docs/benchmark"))
    args = ap.parse_args(argv)
    board_file = args.results / "leaderboard.md"
    board = board_file.read_text() if board_file.is_file() else "(no run yet)"
    board = board.replace("\n## ", "\n### ")
    ran = args.results / "tasks.json"
    if ran.is_file():
        import json

        ran_tasks = set(json.loads(ran.read_text()))
        suite = next((s for s in ("full", "quick") if ran_tasks == set(SUITES[s])), None)
        what = (f"the {suite} suite, {len(ran_tasks)} tasks" if suite else
                f"{len(ran_tasks)} of the {len(SUITES['full'])} tasks of the full suite")
        board = (f"The run committed in `{args.results}` covers {what} (the superseded "
                 f"versions, {', '.join(SUPERSEDED)}, are left out).\n\n" + board)
    for name in TASKS:
        write_text(args.docs / "tasks" / (name.replace("/", "__") + ".md"),
                   task_page(name, args.results, args.docs))
    tasks = "\n".join(f"- [{n}](tasks/{n.replace('/', '__')}.md): {t.description}"
                      for n, t in TASKS.items())
    rel = os.path.relpath(args.results / "score_matrix.png", args.docs)
    if (args.results / "score_matrix.png").is_file():
        board = f"![score matrix]({rel})\n\n" + board
    toc = "\n".join(f"tasks/{n.replace('/', '__')}" for n in TASKS)
    write_text(args.docs / "index.md", INTRO.format(n=len(TASKS), tasks=tasks, board=board,
                                                    toc=toc))
    print(f"wrote {args.docs}/index.md and {len(TASKS)} task pages")
    return 0


if __name__ == "__main__":
    sys.exit(main())
