"""scripts/bench_envs.py's N = 64 block: the bare batched physics it compares against steps
the environment's own model by its physics steps per control period, and the table holds
every environment's ratio and target line (no timing asserted)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import mujoco
import numpy as np

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "bench_envs.py"


def _load():
    spec = importlib.util.spec_from_file_location("bench_envs", SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_bare_physics_steps_the_environments_model():
    bench = _load()
    bare = bench.BarePhysics("hgo_mj/FurutaBalance-v0", 3)
    assert bare.nstep == 10 and len(bare.datas) == 3
    bare.reset()
    bare.step(np.full((3, 1), 0.5))
    d = mujoco.MjData(bare.model)
    d.ctrl[:] = 0.5
    mujoco.mj_step(bare.model, d, 10)
    np.testing.assert_array_equal(bare.datas[2].qpos, d.qpos)
    assert bare.datas[0].time == d.time


def test_vector_table_has_the_physics_limit_of_every_environment():
    bench = _load()
    res = {f"{bench.VEC_REFERENCE} SyncVectorEnv": (1000.0, 1000.0)}
    for i, env_id in enumerate(bench.VEC_IDS):
        res[f"{env_id} native"] = (20_000.0, 12_000.0)
        # the target's like-for-like ratio: both on one thread (the 2-thread native is faster)
        res[f"{env_id} native, nthread=1"] = (10_000.0, 12_000.0)
        res[f"{env_id} SyncVectorEnv"] = (1000.0, 1000.0)
        res[f"{env_id} bare mj_step"] = (12_000.0 + 2000.0 * i, 0.0)
    text = bench.vector_table(res, 2, 40)
    assert f"| {bench.VEC_IDS[0]}: at most 1.3x | met (1.20x) |" in text
    assert f"| {bench.VEC_IDS[2]}: at most 1.3x | NOT met (1.60x) |" in text
    assert text.count("at most 1.3x") == len(bench.VEC_IDS)
