"""The Ray backend on a real local Ray instance (127.0.0.1, 2 CPUs, no dashboard): the same
rows as the local backend; every process of a local instance listens on loopback only (in a
network namespace with a non-loopback address) and ends with a killed driver."""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd
import pytest
import ray

from hgo_mj.cli import main
from hgo_mj.exceptions import DesignError
from hgo_mj.study import Study
from hgo_mj.study.backends import backend_for, ray_init

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
    ray_init(2, None)
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


def _marked(pid: int) -> bool:
    """Whether /proc/PID/environ holds the instance marker the reaper looks for (gone
    processes count as marked)."""
    try:
        with open(f"/proc/{pid}/environ", "rb") as fh:
            return any(e.startswith(b"HGO_MJ_RAY_INSTANCE=") for e in fh.read().split(b"\0"))
    except OSError:
        return True


def test_a_killed_driver_leaves_no_ray_processes(tmp_path):
    """SIGKILL of the process that started the local Ray instance (ray_init): within 60 s its
    GCS, raylet, workers and both agents have exited (Ray's agents alone would wait a minute on
    the dead GCS, one of them listening), none is left computing or listening."""
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
        unmarked = {p: c[:60] for p, c in ray_procs.items() if not _marked(p)}
        assert not unmarked, f"the reaper cannot find these (environ overwritten): {unmarked}"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        end = time.monotonic() + 60  # ~10 s idle; 30 s was short on a loaded 2-core machine
        while time.monotonic() < end and any(_alive(p) for p in ray_procs):
            time.sleep(0.2)
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


def test_the_benchmark_on_ray_gives_the_local_scores(local_ray):
    """``bench(backend="ray")``: each tuning round's trials as Ray tasks on the local instance;
    the scores (all but the timing columns) equal the local backend's bit for bit."""
    from hgo_mj.bench import bench

    kw = dict(tasks=["pendulum/encoder-v1"], observers=["high_gain", "finite_difference"],
              budget=4, record=False, progress=False)
    local = bench(None, **kw).scores
    on_ray = bench(None, backend="ray", jobs=2, **kw).scores
    timing = [c for c in local.columns if c in ("update_time", "tune_seconds")]
    assert timing and len(local) > 0
    pd.testing.assert_frame_equal(local.drop(columns=timing), on_ray.drop(columns=timing))


NS_DRIVER = """
import os, subprocess, ray
from hgo_mj.study.backends import ray_init

ray_init(2, None)


@ray.remote(num_cpus=1)
def pid():
    return os.getpid()


assert len(set(ray.get([pid.remote() for _ in range(4)]))) >= 1
print(subprocess.run(["ss", "-ltnH"], capture_output=True, text=True, check=True).stdout,
      flush=True)
ray.shutdown()
"""
#: the listening addresses that only this machine can reach
LOOPBACK = ("127.0.0.1", "[::ffff:127.0.0.1]", "[::1]")


@pytest.fixture
def netns():
    """A network namespace with a non-loopback address (10.200.0.1/24 on a veth, a default
    route through it: Ray's routes to public DNS servers lead there); deleted after."""
    import shutil
    import subprocess

    name = f"hgo-ray-{os.getpid()}"
    ip = shutil.which("ip")
    if ip is None or shutil.which("ss") is None:
        pytest.skip("needs iproute2 (ip, ss)")
    if subprocess.run([ip, "netns", "add", name], capture_output=True).returncode != 0:
        pytest.skip("cannot create a network namespace (needs root or CAP_NET_ADMIN)")
    try:
        for cmd in ("link set lo up", "link add v0 type veth peer name v1",
                    "addr add 10.200.0.1/24 dev v0", "link set v0 up", "link set v1 up",
                    "route add default via 10.200.0.254"):
            subprocess.run([ip, "netns", "exec", name, ip, *cmd.split()], check=True)
        yield name
    finally:
        subprocess.run([ip, "netns", "delete", name], check=False)


def test_a_local_instance_listens_on_loopback_only(netns, tmp_path):
    """In a network namespace whose machine has the address 10.200.0.1: every listening socket
    of the local instance (GCS, both raylet ports, the agents, the driver, the workers) is on
    127.0.0.1, and no process asks a public DNS server (8.8.8.8) for the node's address."""
    import shutil
    import subprocess
    import sys

    (tmp_path / "driver.py").write_text(NS_DRIVER)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(Path(__file__).resolve().parents[2]), os.environ.get("PYTHONPATH", "")])}
    trace = tmp_path / "connect.txt"
    strace = shutil.which("strace")
    cmd = [sys.executable, str(tmp_path / "driver.py")]
    if strace:
        cmd = [strace, "-f", "-qq", "-e", "trace=connect", "-o", str(trace), *cmd]
    out = subprocess.run(["ip", "netns", "exec", netns, *cmd], capture_output=True, text=True,
                         env=env, cwd=tmp_path, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    listening = [line.split()[3] for line in out.stdout.splitlines() if line.strip()]
    assert len(listening) >= 6, out.stdout  # GCS, 2 raylet, driver, workers, agent
    exposed = [a for a in listening if a.rpartition(":")[0] not in LOOPBACK]
    assert not exposed, f"listening beyond loopback: {exposed}\n{out.stdout}"
    if strace:
        calls = trace.read_text()
        assert "8.8.8.8" not in calls and "2001:4860:4860" not in calls
        assert "10.200.0.1" not in calls
