"""A run compiles each numba kernel once (issue 28): the loop's warm-up hands the kernels the
layouts a segment does (two members, two samples), and the metrics one layout of the true
states, so no kernel gets a second specialisation that differs only in an array's layout (a
compile of 0.3-4 s each, on the first run). In a fresh interpreter: nothing else has called
the kernels there."""

from __future__ import annotations

import json
import subprocess
import sys

PROBE = r"""
import json, sys
import numba.core.registry as reg
from hgo_mj.bench.runner import observer_spec
from hgo_mj.tune import evaluate, setup

sc = {"plant": {"name": "pendulum", "dt": 0.002, "x0": [0.3, 0.0]},
      "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
      "observers": [observer_spec(t, "pendulum") for t in sys.argv[1:]],
      "input": {"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
      "run": {"duration": 0.5}}
for t in sys.argv[1:]:
    evaluate(setup(sc, t), [{}], seeds=[1, 2, 3], consistency=True)
    evaluate(setup(sc, t), [{}, {}], seeds=[4, 5])
import gc
found = {}
for d in gc.get_objects():
    # a kernel generated from source text (hgo_mj's derived models) has no module, its file
    # is "<hgo_mj derived ...>"
    mod = d.py_func.__module__ or d.py_func.__code__.co_filename if isinstance(d, reg.CPUDispatcher) else ""
    if mod.startswith(("hgo_mj", "<hgo_mj")):
        if d.signatures:
            found[mod + "." + d.py_func.__qualname__] = [str(s) for s in d.signatures]
print(json.dumps(found))
"""


def test_a_batch_run_compiles_each_kernel_once():
    families = ["high_gain", "extended_luenberger", "adaptive_gain", "riccati", "ekf"]
    proc = subprocess.run([sys.executable, "-c", PROBE, *families], capture_output=True,
                          text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr[-4000:]
    found = json.loads(proc.stdout.strip().splitlines()[-1])
    assert any("_ekf_block" in k for k in found) and any("_accumulate" in k for k in found)
    twice = {k: v for k, v in found.items() if len(v) > 1}
    assert not twice, twice
