"""The Ray backend on a real local Ray instance (127.0.0.1, 2 CPUs, no dashboard): the same
rows as the local backend."""

from __future__ import annotations

import pandas as pd
import pytest
import ray

from hgo_mj.cli import main
from hgo_mj.exceptions import DesignError
from hgo_mj.study import Study
from hgo_mj.study.backends import backend_for

BASE = {
    "name": "ray",
    "plant": {"name": "pendulum", "dt": 0.001, "x0": [0.5, 0.0]},
    "sensor": {"stages": [{"stage": "gaussian", "std": 1e-3}]},
    "observers": [{"type": "high_gain", "name": "hgo", "k": 20.0}],
    "input": {"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
    "run": {"duration": 0.5, "seed": 0},
}
AXES = {"observers.hgo.k": [10.0, 40.0], "plant.x0": [[0.5, 0.0], [1.0, 0.0]]}


@pytest.fixture(scope="module")
def local_ray():
    ray.init(num_cpus=2, include_dashboard=False, _node_ip_address="127.0.0.1",
             log_to_driver=False, configure_logging=False)
    yield
    ray.shutdown()


def test_ray_gives_the_rows_of_the_local_backend(local_ray, tmp_path):
    local = Study(BASE, AXES, seeds=3).run(tmp_path / "local", quiet=True).table
    on_ray = Study(BASE, AXES, seeds=3).run(tmp_path / "ray", jobs=2, backend="ray",
                                            quiet=True).table
    cols = [c for c in local.columns if c != "update_time"]
    assert len(local) == 2 * 2 * 3 * 2
    pd.testing.assert_frame_equal(on_ray[cols], local[cols])


def test_an_unknown_backend_and_an_address_without_ray_are_refused():
    with pytest.raises(DesignError, match=r"backend must be one of \['local', 'ray'\]"):
        backend_for("dask")
    with pytest.raises(DesignError, match="--address is for --backend ray"):
        backend_for("local", address="127.0.0.1:6379")


def test_an_unreachable_ray_address_is_one_line(tmp_path, capsys):
    f = tmp_path / "s.toml"
    f.write_text('[plant]\nname = "pendulum"\n[[observers]]\ntype = "high_gain"\nk = 20.0\n'
                 '[run]\nduration = 0.1\n[sweep]\nseeds = 1\n')
    ray.shutdown()  # the command line's process has no Ray instance of its own
    code = main(["sweep", str(f), "--out", str(tmp_path / "o"), "--backend", "ray",
                 "--address", "127.0.0.1:1", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "cannot start or reach Ray at '127.0.0.1:1'" in err


RAY_DRIVER = """
import os, time
import ray
from hgo_mj.study.backends import ray_init

ray_init(2, None)


@ray.remote(num_cpus=1)
def slow():
    time.sleep(300)


refs = [slow.remote() for _ in range(2)]
print("driver", os.getpid(), flush=True)
time.sleep(600)
"""


def _descendants(pid: int) -> dict[int, str]:
    """Every live descendant of ``pid`` and its command line (from /proc)."""
    import os

    kids: dict[int, list[int]] = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as fh:
                    ppid = int(fh.read().rsplit(") ", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            kids.setdefault(ppid, []).append(int(d))
    out, todo = {}, [pid]
    while todo:
        for c in kids.get(todo.pop(), []):
            try:
                with open(f"/proc/{c}/cmdline") as fh:
                    out[c] = fh.read().replace("\0", " ")
            except OSError:
                continue
            todo.append(c)
    return out


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(") ", 1)[1][0] != "Z"
    except OSError:
        return False


def test_a_killed_driver_leaves_no_ray_processes(tmp_path):
    """SIGKILL of the process that started the local Ray instance (ray_init): its GCS,
    raylet, workers and agents all exit (Ray fate-shares them with the driver; its agents
    notice the raylet's death and exit about a minute later), none is left computing."""
    import os
    import signal
    import subprocess
    import sys
    import time

    (tmp_path / "driver.py").write_text(RAY_DRIVER)
    proc = subprocess.Popen([sys.executable, str(tmp_path / "driver.py")],
                            stdout=subprocess.PIPE, text=True, start_new_session=True,
                            cwd=tmp_path)
    ray_procs: dict[int, str] = {}
    try:
        assert proc.stdout is not None and proc.stdout.readline().startswith("driver")
        end = time.monotonic() + 120
        while time.monotonic() < end:  # both tasks running, the agents started
            ray_procs = _descendants(proc.pid)
            names = " ".join(ray_procs.values())
            if names.count("ray::slow") >= 2 and "raylet" in names:
                break
            time.sleep(0.5)
        assert names.count("ray::slow") >= 2, ray_procs
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        end = time.monotonic() + 180
        while time.monotonic() < end and any(_alive(p) for p in ray_procs):
            time.sleep(1.0)
        left = {p: c[:60] for p, c in ray_procs.items() if _alive(p)}
        assert not left, f"left running after the driver was killed: {left}"
    finally:
        if proc.poll() is None:
            proc.kill()
        for p in ray_procs:
            if _alive(p):
                os.kill(p, signal.SIGKILL)


def test_tuning_on_ray_gives_the_local_result(local_ray):
    """``tune(backend="ray")``: a round's trials scored in parts as Ray tasks on the local
    instance (127.0.0.1); the same seed gives the same trials and values as locally."""
    from hgo_mj.tune import tune

    sc = {**BASE, "run": {"duration": 1.0}}
    local = tune(sc, "hgo", budget=8, seeds=2, round_size=4, progress=False)
    on_ray = tune(sc, "hgo", budget=8, seeds=2, round_size=4, backend="ray", jobs=2,
                  progress=False)
    pd.testing.assert_frame_equal(local.trials, on_ray.trials)
    assert local.best == on_ray.best
