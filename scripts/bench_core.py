"""The core's per-call costs and memory (issue 24), each as a ratio measured side by side.

Usage: ``python scripts/bench_core.py [--rounds N] [--write BENCHMARKS.md]``.

* **update / mj_step**: one ``HighGainObserver.update`` (the validating single-sample call a
  user's loop or a Gymnasium wrapper makes; model-free, n = 2 and n = 4) against one bare
  ``mujoco.mj_step`` of the shipped pendulum, interleaved bursts of 2,000 calls, the best
  burst of each, on the thread's CPU clock (``time.thread_time``: time descheduled on a
  shared machine does not count). Target: <= 1.0.
* **batch of different gains**: one ``Observer.step`` over B = 1,024 members of T = 100
  samples whose members share one gain, against the same with 16 different gains (64
  members each: a tuning round), ns per member-sample; the groups cost what a Python loop over
  16 kernel calls costs.
* **cost column, first and second**: a fresh process runs ``simulate`` (10 s at 1 kHz) with
  the same observer twice (``first``, ``second``), 7 times, and prints the median of each
  one's ``update_time``; the loop warms each observer's kernels on a throw-away sample before
  it times, and the observers take turns at running first after the plant in each segment
  (the plant's run leaves the caches cold). Target: within 2x.
* **peak RSS**: ``/usr/bin/time -v`` (maximum resident set size) of ``hgo-mj run`` for 1 s and
  3,600 s with ``--stream`` (pendulum, 1 kHz, two observers; npz for the 1 s run, the streamed
  one writes Parquet). Targets: 1 s <= 250 MB, the 3,600 s streamed run within 60 MB of it.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np

from hgo_mj._bench import header, write_section
from hgo_mj.observers import HighGainObserver
from hgo_mj.plants import model_path

BURST = 2000
#: runs of the cost column's simulation in its fresh process; the median of each observer's
#: ``update_time`` (wall time: one preemption on a loaded machine adds milliseconds to one run)
COST_RUNS = 7


def _burst(fn: Callable[[], object], n: int = BURST) -> float:
    t0 = time.thread_time()
    for _ in range(n):
        fn()
    return (time.thread_time() - t0) / n


def update_vs_mj_step(rounds: int) -> dict[str, float]:
    """us per call: HGO update (n = 2, 4) and the bare pendulum mj_step, interleaved."""
    m = mujoco.MjModel.from_xml_path(str(model_path("pendulum.xml")))
    d = mujoco.MjData(m)
    calls: dict[str, Callable[[], object]] = {"mj_step (pendulum)": lambda: mujoco.mj_step(m, d)}
    for n in (2, 4):
        ob = HighGainObserver(order=n, k=20.0)
        y, u = np.array([0.1]), np.zeros(0)
        calls[f"HighGainObserver.update, n={n}"] = (lambda ob=ob, y=y, u=u:
                                                     ob.update(y, u, 0.001))
    best = dict.fromkeys(calls, float("inf"))
    for fn in calls.values():
        _burst(fn, 200)  # warm
    for _ in range(rounds):
        for name, fn in calls.items():
            best[name] = min(best[name], _burst(fn))
    return {k: v * 1e6 for k, v in best.items()}


def grouped_batch(rounds: int) -> dict[str, float]:
    """ns per member-sample of one step over B = 1024, T = 100: one gain, and 16 gains."""
    B, T = 1024, 100
    ob = HighGainObserver(order=2, k=20.0)
    rng = np.random.default_rng(0)
    Y, U = rng.normal(size=(B, T, 1)), np.zeros((B, T, 0))
    cases = {"one gain for all 1,024 members": ob.parameters(B),
             "16 gains x 64 members (a tuning round)":
                 ob.parameters(B, k=np.repeat(np.linspace(10.0, 40.0, 16), B // 16))}
    out = {}
    for name, p in cases.items():
        state = ob.init(B, params=p)
        ob._step_checked(p, state, Y, U, 0.001)  # warm
        best = float("inf")
        for _ in range(max(rounds // 10, 3)):
            t0 = time.thread_time()
            ob._step_checked(p, state, Y, U, 0.001)
            best = min(best, time.thread_time() - t0)
        out[name] = best / (B * T) * 1e9
    return out


def cost_column() -> tuple[float, float]:
    code = (
        "from hgo_mj.inputs import Multisine\n"
        "from hgo_mj.observers import HighGainObserver\n"
        "from hgo_mj.plants import make_plant\n"
        "from hgo_mj.simulate import simulate\n"
        "plant = make_plant('pendulum', dt=0.001)\n"
        "obs = {n: HighGainObserver(plant.system, k=20.0) for n in ('first', 'second')}\n"
        "import numpy as np\n"
        "ts = [simulate(plant, None, obs, Multisine([0.3], [0.5]), duration=10.0,\n"
        "               x0=[0.3, 0.0]).observers for _ in range(RUNS)]\n"
        "print(*(np.median([t[n].update_time for t in ts]) for n in ('first', 'second')))\n"
        ).replace("RUNS", str(COST_RUNS))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    a, b = (float(v) for v in out.stdout.split())
    return a, b


def peak_rss(duration: float, stream: bool) -> float:
    """MB: maximum resident set size of ``hgo-mj run`` (``/usr/bin/time -v``)."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = ["/usr/bin/time", "-v", sys.executable, "-m", "hgo_mj.cli", "run",
               "--plant", "pendulum", "--dt", "0.001", "--sensor", "gaussian:std=1e-3",
               "--observer", "high_gain:name=k20,k=20", "--observer", "high_gain:name=k80,k=80",
               "--input", "multisine:amplitudes=[0.3],frequencies=[0.5]",
               "--duration", str(duration), "--seed", "1",
               "--out", str(Path(tmp) / "run")] + (["--stream"] if stream else
                                                    ["--format", "npz"])
        out = subprocess.run(cmd, capture_output=True, text=True, check=True)
    kb = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", out.stderr).group(1))
    return kb / 1024


def table(rounds: int) -> str:
    upd = update_vs_mj_step(rounds)
    step = upd["mj_step (pendulum)"]
    grp = grouped_batch(rounds)
    first, second = cost_column()
    rss1, rss3600 = peak_rss(1.0, False), peak_rss(3600.0, True)
    lines = header(f"python scripts/bench_core.py --rounds {rounds}") + [
        "",
        "| what | figure | ratio | target |",
        "|---|---:|---:|---|",
    ]
    for name, us in upd.items():
        if name != "mj_step (pendulum)":
            lines.append(f"| {name} / bare pendulum `mj_step` ({step:.2f} us) | {us:.2f} us | "
                         f"{us / step:.2f}x | <= 1.0 |")
    one = grp["one gain for all 1,024 members"]
    for name, ns in grp.items():
        lines.append(f"| `step`, B = 1,024, T = 100, {name} | {ns:.1f} ns per member-sample | "
                     f"{ns / one:.2f}x | |")
    lines.append(f"| cost column of the same observer, first / second (`update_time`, fresh "
                 f"process) | {first * 1e6:.3f} / {second * 1e6:.3f} us | "
                 f"{first / second:.2f}x | within 2x |")
    lines.append(f"| peak RSS, `hgo-mj run` 1 s, npz | {rss1:.0f} MB | | <= 250 MB |")
    lines.append(f"| peak RSS, `hgo-mj run` 3,600 s `--stream` (Parquet) | {rss3600:.0f} MB | "
                 f"+{rss3600 - rss1:.0f} MB | within 60 MB of the 1 s run |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=30)
    ap.add_argument("--write", type=Path, help="replace the bench_core block of this file")
    args = ap.parse_args(argv)
    text = table(args.rounds)
    print(text)
    if args.write:
        write_section(args.write, "bench_core", text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
