"""Reliability figures (issue 14), regenerated into docs/reliability.md and its figure.

Usage: ``python scripts/reliability.py [--durations 60 600 3600] [--soak-steps N] [--out docs]``;
``--page-from docs/reliability.json --rerun-memory --out docs`` measures the memory rows again.

Measured, each in a fresh process so that peak memory is the run's own:

* **Memory against duration**: ``hgo-mj run`` of the pendulum at 1 kHz with one high-gain
  observer, keeping every row in memory (short runs only), streaming every row to Parquet
  (``--stream``) or keeping every 1000th (``--store-every``); the peak resident set size
  (``ru_maxrss``) against the simulated duration, beside a 1 s run (what the libraries a run
  loads take).
* **Soak**: every hgo_mj environment for ``N`` random-action steps (resetting at episode ends):
  the resident set size before and after, and whether every observation was finite.
* **Bad inputs and faults**: the counts of the fuzz, bad-input and fault suites as pytest runs
  them (each generated document or regression case either runs or gets one clear line).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

RUN = """
import json, resource, sys, time
from hgo_mj.cli import main
argv = json.loads(sys.argv[1])
t = time.perf_counter()
rc = main(argv) if argv else 0
print(json.dumps({"rc": rc, "seconds": time.perf_counter() - t,
                  "rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""

SOAK = """
import json, resource, sys
import gymnasium as gym, numpy as np
import hgo_mj.envs
name, steps = sys.argv[1], int(sys.argv[2])
env = gym.make(name)
env.action_space.seed(0)
env.reset(seed=0)
def rss():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
before, finite, resets = None, True, 0
for k in range(steps):
    obs, _, term, trunc, _ = env.step(env.action_space.sample())
    finite &= bool(np.all(np.isfinite(obs)))
    if term or trunc:
        env.reset()
        resets += 1
    if k == min(1000, steps - 1):
        before = rss()
print(json.dumps({"rss_after_1000_mb": before, "rss_end_mb": rss(), "finite": finite,
                  "episodes": resets}))
"""


def _child(code: str, *args: str) -> dict:
    out = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                         cwd=ROOT, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


#: the ways a run keeps its rows: label -> extra hgo-mj run arguments
MODES = {"kept": ["--format", "npz", "parquet"], "stream": ["--stream"],
         "every 1000th": ["--store-every", "1000", "--format", "npz"]}
#: the longest run kept whole in memory (0.3 GB at 3600 s)
KEPT_MAX = 600.0


def memory(durations: list[float]) -> list[dict]:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for d, mode in [(1.0, "every 1000th"), *((d, m) for d in durations for m in MODES
                                                 if m != "kept" or d <= KEPT_MAX)]:
            argv = ["run", "--plant", "pendulum", "--dt", "0.001", "--observer",
                    "high_gain:k=20", "--duration", str(d), "--quiet", *MODES[mode],
                    "--out", str(Path(tmp) / f"{d}_{mode}")]
            if mode == "kept":
                argv = [a for a in argv if a != "parquet"]  # npz: one copy of the rows
            rows.append({"duration": d, "mode": mode, **_child(RUN, json.dumps(argv))})
    return rows


def soak(steps: int, names: list[str] | None = None) -> dict[str, dict]:
    from hgo_mj.envs import ENVIRONMENTS

    return {name: _child(SOAK, name, str(steps)) for name in (names or sorted(ENVIRONMENTS))}


#: the suites whose counts the page gives; the fault suites' tests are listed one by one
SUITES = ("tests/test_fuzz_scenarios.py", "tests/test_bad_inputs.py",
          "tests/test_trajectory_file.py",
          "tests/systems/test_symbolic.py::test_oversized_or_non_real_expressions_are_one_line_in_seconds",
          "tests/test_faults.py", "tests/test_isolation.py", "tests/test_stream.py",
          "tests/test_manifest.py", "tests/study/test_ray.py")
FAULT_SUITES = ("tests/test_faults.py", "tests/test_isolation.py", "tests/test_stream.py",
                "tests/test_manifest.py", "tests/study/test_ray.py")


def totals(counts: dict[str, str]) -> tuple[int, int]:
    """The tests run and those that failed, summed over pytest's summary lines ``counts``
    (each test fails on a traceback, a silent accept or a file lost)."""
    import re

    run = failed = 0
    for line in counts.values():
        for n, what in re.findall(r"(\d+) (passed|failed|error)", line):
            run += int(n)
            failed += int(n) if what != "passed" else 0
    return run, failed


def suites(paths: Sequence[str] = SUITES) -> tuple[dict[str, str], list[dict[str, str]]]:
    """pytest's summary line of each suite of ``paths``, and every fault test: its name, the
    first line of its docstring (what it injects and asserts) and its outcome (JUnit XML)."""
    import ast
    import xml.etree.ElementTree as ET

    counts, faults = {}, []
    with tempfile.TemporaryDirectory() as tmp:
        for path in paths:
            xml = Path(tmp) / "r.xml"
            r = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                                f"--junitxml={xml}", path], capture_output=True, text=True,
                               cwd=ROOT)
            counts[path] = r.stdout.strip().splitlines()[-1]
            if path not in FAULT_SUITES:
                continue
            docs = {n.name: (ast.get_docstring(n) or "").split("\n")[0]
                    for n in ast.parse((ROOT / path).read_text()).body
                    if isinstance(n, ast.FunctionDef) and n.name.startswith("test_")}
            for case in ET.parse(xml).getroot().iter("testcase"):
                name = case.get("name", "")
                outcome = ("failed" if case.find("failure") is not None
                           or case.find("error") is not None else
                           "skipped" if case.find("skipped") is not None else "passed")
                faults.append({"suite": path, "test": name, "outcome": outcome,
                               "what": docs.get(name.split("[")[0], "")})
    return counts, faults


def figure(rows: list[dict], path: Path) -> None:
    from hgo_mj._io import save_figure
    from hgo_mj.plotting import subplots

    fig, ax = subplots(1, 1, figsize=(10, 4))
    floor = rows[0]["rss_mb"]
    for mode, style in zip(MODES, ("o-", "s-", "^-")):
        pts = [(r["duration"], r["rss_mb"]) for r in rows[1:] if r["mode"] == mode]
        if pts:
            label = {"kept": "every row kept in memory", "stream": "every row streamed (--stream)",
                     "every 1000th": "every 1000th row kept (--store-every 1000)"}[mode]
            ax.plot(*zip(*pts), style, label=label)
    ax.axhline(floor, color="0.5", ls="--", label=f"a 1 s run ({floor:.0f} MB)")
    ax.axhline(200, color="tab:red", ls=":", label="issue 14's target (200 MB)")
    ax.set_xscale("log")
    ax.set_xlabel("simulated duration [s] (1 kHz)")
    ax.set_ylabel("peak RSS [MB]")
    ax.set_title("hgo-mj run, pendulum + high-gain observer: peak memory")
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=9)
    fig.tight_layout()
    save_figure(fig, path)


def page(rows: list[dict], soaks: dict[str, dict], steps: int, counts: dict[str, str],
         cmd: str, faults: list[dict[str, str]] | None = None,
         suites_cmd: str | None = None, memory_cmd: str | None = None) -> str:
    from hgo_mj._bench import header

    lines = ["# Reliability: memory, soak, bad inputs, faults", "",
             f"Generated by `{cmd}` (issue 14); one run on the shared 2-core machine.", "",
             *header(cmd), "", "## Memory against duration", "",
             *([f"Measured again later than the rest of the page, by `{memory_cmd}`.", ""]
               if memory_cmd else []),
             "![peak memory](reliability_memory.png)", "",
             "| duration [s] | rows | rows written | wall [s] | peak RSS [MB] |",
             "|---|---|---|---|---|"]
    for r in rows:
        every = 1000 if r["mode"] == "every 1000th" else 1
        written = int(r["duration"] * 1000 // every) + 1
        lines.append(f"| {r['duration']:g} | {r['mode']} | {written} | {r['seconds']:.1f} | "
                     f"{r['rss_mb']:.0f} |")
    floor = rows[0]["rss_mb"]
    streamed = [r for r in rows if r["mode"] == "stream"]
    kept = [r for r in rows if r["mode"] == "kept"]
    lo, hi = min(streamed, key=lambda r: r["duration"]), max(streamed, key=lambda r: r["duration"])
    verdict = "met" if hi["rss_mb"] < 200 else "not met"
    lines += ["", f"Streamed, the peak memory of a {hi['duration']:g} s run is "
              f"{hi['rss_mb']:.0f} MB against {lo['rss_mb']:.0f} MB at {lo['duration']:g} s "
              f"({hi['duration'] / lo['duration']:g} times the rows, "
              f"{hi['rss_mb'] - lo['rss_mb']:+.0f} MB): "
              + ("flat with the duration" if hi["rss_mb"] - lo["rss_mb"] < 0.1 * lo["rss_mb"]
                 else "NOT flat with the duration") + ". Kept in memory, "
              + ", ".join(f"{r['rss_mb']:.0f} MB at {r['duration']:g} s" for r in kept)
              + f". Issue 14's target, under 200 MB for a 3600 s run with streaming, is "
              f"{verdict}: the libraries a streamed run loads (numba, MuJoCo, matplotlib, "
              f"pyarrow for the Parquet files) take most of it; a 1 s run writing "
              f"only `.npz` peaks at {floor:.0f} MB.",
              "",
              f"## Soak: {steps:,} random-action steps per environment", "",
              "| environment | episodes | RSS after 1000 steps [MB] | RSS at the end [MB] | "
              "all observations finite |", "|---|---|---|---|---|"]
    for name, s in soaks.items():
        lines.append(f"| {name} | {s['episodes']} | {s['rss_after_1000_mb']:.0f} | "
                     f"{s['rss_end_mb']:.0f} | {'yes' if s['finite'] else 'NO'} |")
    lines += ["", "## Bad inputs and faults", "",
              *([f"Suites rerun later than the measurements above, by `{suites_cmd}` (a suite "
                 f"it does not name keeps the first run's count).", ""] if suites_cmd else []),
              "Each fuzz document (hypothesis, 150 derandomized examples per property, no "
              "database) and each regression case either runs or ends in one clear line with "
              "exit 2 and no output files; each mutated trajectory file (120 examples) loads or "
              "is one `TrajectoryFileError` naming the file; each oversized or non-real ODE "
              "expression (`9**9**9`, 100,000 minus signs, a 200,000-term sum, `sqrt(-1)`) is "
              "one `ModelError` line within seconds, and so is each generated ODE expression "
              "that does not build (issue 27). The fault tests kill during a save, fill "
              "the disk under a recording (the earlier recording kept), SIGKILL a recording, "
              "a streamed run (its chunks readable) and a run between two files (its folder "
              "refused by the manifest), kill and Ctrl-C multi-run commands, "
              "make an observer fail or overflow in a run, SIGKILL the driver of a local Ray instance "
              "(none of its processes left after 10 s) and list that instance's listening "
              "sockets in a network namespace with a non-loopback address (127.0.0.1 only).",
              "", "| suite | pytest |", "|---|---|"]
    lines += [f"| `{k}` | {v} |" for k, v in counts.items()]
    run, failed = totals(counts)
    lines += ["", f"Cases tried: {run} tests (each hypothesis property among them runs 150 "
              f"generated documents, trajectory files or ODE expressions). Tracebacks, silent "
              f"accepts and files lost: {failed} (every test fails on any of the three: a "
              f"traceback or an exception of another kind, a bad input that runs, a file or "
              f"row a kill or a full disk destroyed). Target: 0, 0, 0."]
    if faults:
        lines += ["", "### Faults injected, one test each", "",
                  "| test | what it injects and asserts | result |", "|---|---|---|"]
        lines += [f"| `{f['test']}` | {f['what'] or '-'} | {f['outcome']} |" for f in faults]
        bad = [f for f in faults if f["outcome"] != "passed"]
        lines += ["", f"{len(faults) - len(bad)} of {len(faults)} fault tests passed"
                  + (": " + ", ".join(f["test"] for f in bad) if bad else "") + "."]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--durations", nargs="+", type=float, default=[60.0, 600.0, 3600.0])
    ap.add_argument("--soak-steps", type=int, default=1_000_000)
    ap.add_argument("--out", default=None, help="folder for reliability.md, its figure and "
                    "the raw numbers (reliability.json)")
    ap.add_argument("--page-from", metavar="JSON", help="rewrite the page and figure from the "
                    "raw numbers of an earlier run (no measurement)")
    ap.add_argument("--rerun-suites", nargs="*", metavar="SUITE", help="with --page-from: "
                    "run these bad-input and fault suites again (none named: all of them; "
                    "minutes), keep the other numbers of the earlier run")
    ap.add_argument("--rerun-memory", action="store_true", help="with --page-from: measure "
                    "the memory rows again (--durations), keep the other numbers")
    a = ap.parse_args(argv)
    if a.soak_steps < 1001 or any(not d > 0 for d in a.durations):
        print("--soak-steps must be > 1000 and --durations positive", file=sys.stderr)
        return 2
    cmd = ("python scripts/reliability.py --durations "
           + " ".join(f"{d:g}" for d in a.durations) + f" --soak-steps {a.soak_steps}")
    if a.page_from:
        raw = json.loads(Path(a.page_from).read_text())
        rows, soaks, counts, faults, cmd = (raw[k] for k in ("memory", "soak", "suites",
                                                              "faults", "command"))
        steps = raw["soak_steps"]
        suites_cmd, memory_cmd = raw.get("suites_command"), raw.get("memory_command")
        if a.rerun_memory:
            rows = memory(a.durations)
            memory_cmd = (f"python scripts/reliability.py --page-from {a.page_from} "
                          f"--rerun-memory --durations "
                          + " ".join(f"{d:g}" for d in a.durations))
        if a.rerun_suites is not None:
            again = a.rerun_suites or list(SUITES)
            new_counts, new_faults = suites(again)
            counts = {k: new_counts.get(k, counts.get(k, "-")) for k in (*counts, *again)}
            faults = [f for f in faults if f["suite"] not in again] + new_faults
            suites_cmd = (f"python scripts/reliability.py --page-from {a.page_from} "
                          f"--rerun-suites {' '.join(a.rerun_suites)}").rstrip()
    else:
        rows, soaks, (counts, faults) = memory(a.durations), soak(a.soak_steps), suites()
        steps, suites_cmd, memory_cmd = a.soak_steps, None, None
    text = page(rows, soaks, steps, counts, cmd, faults, suites_cmd, memory_cmd)
    print(text)
    if a.out:
        from hgo_mj._io import write_text
        from hgo_mj._json import write_json

        out = Path(a.out)
        figure(rows, out / "reliability_memory.png")
        write_text(out / "reliability.md", text)
        if not a.page_from or a.rerun_suites is not None or a.rerun_memory:
            write_json(out / "reliability.json", {
                "command": cmd, "soak_steps": steps, "memory": rows, "soak": soaks,
                "suites": counts, "faults": faults, "suites_command": suites_cmd,
                "memory_command": memory_cmd})
    return 0


if __name__ == "__main__":
    sys.exit(main())
