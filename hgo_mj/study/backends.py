"""Where a study's chunks run: this process, local worker processes, or Ray.

Every backend hands out the same chunks (:class:`~hgo_mj.study.engine.Chunk`: plain data, the
cells' scenarios and the members) and gets back their result rows (small: metrics, no
trajectories); the parent writes each chunk's rows as one Parquet partition as it arrives. The
results do not depend on the backend or on the number of workers.

* ``local``: ``jobs = 1`` runs the chunks in this process; ``jobs > 1`` in this process and
  ``jobs - 1`` worker processes (``spawn``: safe with MuJoCo and threads), when the plan
  estimates at least :data:`WORKERS_WORTH_S` seconds of single-core work (a shorter study is
  done before the workers would have started; the plants already run on MuJoCo's threads:
  :func:`local_jobs`). The workers die with the parent (Linux: ``PR_SET_PDEATHSIG``, so a
  killed command leaves no orphans computing) and ignore SIGINT: a Ctrl-C reaches the parent,
  which stops them (:func:`worker_init`).
* ``ray``: ``pip install "hgo_mj[ray]"``. Without ``address``, a local Ray instance with
  ``jobs`` CPUs and no dashboard whose every process listens on 127.0.0.1 only, asks no
  public DNS server for its address, reports no usage statistics (:data:`LOCAL_RAY_ENV`) and
  ends with this process, also when it is killed (:func:`ray_init`); with ``address``
  (``ray start --head`` on the head node prints it, e.g. ``192.168.1.10:6379``), that cluster:
  every node needs hgo_mj installed, and only the chunk specs and the rows move over the
  network.
"""

from __future__ import annotations

import contextlib
import functools
import multiprocessing
import os
import subprocess
import sys
import threading
import uuid
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from queue import SimpleQueue
from typing import Any

from .._extras import require
from ..exceptions import DesignError
from .engine import Chunk, run_chunk

Rows = list[dict[str, Any]]
#: ``backend(chunks)``: the chunks' rows as they finish
Backend = Callable[[list[Chunk]], Iterator[tuple[Chunk, Rows]]]
BACKENDS = ("local", "ray")
#: local workers start only for single-core work (sensors, observers, metrics: the batched
#: plant runs on threads already) estimated at this many seconds or more: a spawned worker
#: needs 1-3 s before its first chunk (interpreter, hgo_mj, cached kernels)
WORKERS_WORTH_S = 10.0


def local_jobs(jobs: int, serial_s: float) -> int:
    """The processes the local backend uses for ``serial_s`` seconds of single-core work:
    ``jobs``, or 1 for less than :data:`WORKERS_WORTH_S`."""
    return jobs if serial_s >= WORKERS_WORTH_S else 1


def backend_for(name: Any, *, address: str | None = None, jobs: int = 1) -> Backend:
    """The backend called ``name`` (checked before any work: Ray must import, the address
    must accept a connection)."""
    if name not in BACKENDS:
        raise DesignError(f"backend must be one of {list(BACKENDS)}; found {name!r}")
    if name == "local":
        if address is not None:
            raise DesignError("--address is for --backend ray")
        return lambda chunks: _local(chunks, jobs)
    require("ray", "ray", "--backend ray")
    if address is not None:
        _check_reachable(address)
    return lambda chunks: _ray(chunks, jobs, address)


#: ``prctl`` option: the signal a process gets when its parent dies (``<sys/prctl.h>``)
_PR_SET_PDEATHSIG = 1


def worker_init(parent: int) -> None:
    """Run in each local worker process as it starts: die with the parent ``parent`` (a pid)
    and leave SIGINT to it.

    On Linux, ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` makes the kernel kill the worker when the
    process that started it dies, also by SIGKILL (elsewhere the executor's own pipe ends idle
    workers). A parent that died before the call is found by the worker's parent pid. A Ctrl-C
    in a terminal reaches the whole process group: the workers ignore it, so that the parent
    alone reports it and stops them (no tracebacks, no broken pipes from workers).
    """
    import os
    import signal
    import sys

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    if os.getppid() != parent:  # the parent died before the call
        os._exit(1)


def _local(chunks: list[Any], jobs: int,
           run: Callable[[Any], Rows] | None = None) -> Iterator[tuple[Any, Rows]]:
    """The chunks on ``jobs`` processes: this one and ``jobs - 1`` workers (started with
    :func:`worker_init`), each chunk yielded with its rows as it finishes.

    One queue feeds them all: this process takes chunks from its front, the workers (which
    start in about a second: an interpreter, hgo_mj, the compiled kernels from their cache)
    from its back, each worker its next chunk the moment it finishes one (the finished
    future's callback submits it, also while this process is busy with a chunk of its own).
    A caller that orders its chunks by what they share (the benchmark: one observer family
    after another) so has each process compile its own kernels and reuse them. ``run`` (a
    module-level function; default :func:`~hgo_mj.study.engine.run_chunk`, looked up at the
    call) computes a chunk's rows."""
    if run is None:
        run = run_chunk
    if jobs == 1 or len(chunks) <= 1:
        for c in chunks:
            yield c, run(c)
        return
    queue = deque(chunks)
    lock = threading.Lock()  # guards queue and running
    finished: SimpleQueue[tuple[Future[Rows], Any]] = SimpleQueue()
    running = 0  # chunks submitted to a worker and not yet yielded here
    workers = min(jobs - 1, len(chunks) - 1)
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                               initializer=worker_init, initargs=(os.getpid(),))

    def feed() -> None:
        """Submit the chunk at the back of the queue, if any, to the next free worker."""
        nonlocal running
        with lock:
            if queue:
                c = queue.pop()
                pool.submit(run, c).add_done_callback(functools.partial(done, c=c))
                running += 1

    def done(f: Future[Rows], c: Any) -> None:
        """A worker finished ``c``: hand it the next chunk and ``f`` to this process."""
        try:
            feed()
        except (RuntimeError, BrokenProcessPool):  # stopped, or broken: f tells which
            pass
        finished.put((f, c))

    def take() -> tuple[Any, Rows]:
        nonlocal running
        f, c = finished.get()
        with lock:
            running -= 1
        return c, f.result()

    try:
        for _ in range(workers):
            feed()
        while True:
            while not finished.empty():
                yield take()
            with lock:
                c = queue.popleft() if queue else None
                left = running
            if c is not None:
                yield c, run(c)
            elif left:
                yield take()
            else:
                break
    except BaseException:  # Ctrl-C or an error: stop the workers now, not after their chunks
        with lock:
            queue.clear()
        for proc in list(getattr(pool, "_processes", {}).values()):
            proc.kill()
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)


#: the environment of a local Ray instance's processes (Ray reads these as each one starts):
#: without a cluster, the node's address is 127.0.0.1, so that the GCS, the raylet, the agents,
#: the workers and this driver listen on 127.0.0.1 only (Ray otherwise replaces 127.0.0.1 by
#: the address of the interface its route to a public DNS server, 8.8.8.8, leaves from, and
#: its gRPC servers listen on every interface); no usage statistics (sent to Ray's servers
#: after probing the cloud metadata address 169.254.169.254); ``SPT_NOENV``: Ray's process
#: titles (``ray::DashboardAgent``) do not overwrite /proc/PID/environ, where :data:`_REAPER`
#: finds the instance's processes (without it the agents were missed and outlived the driver)
LOCAL_RAY_ENV = {"RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0", "RAY_USAGE_STATS_ENABLED": "0",
                 "SPT_NOENV": "1"}
#: names the processes of one local Ray instance (in their environment), for :data:`_REAPER`
_INSTANCE_VAR = "HGO_MJ_RAY_INSTANCE"
#: the write end of the pipe the reaper of the local instance reads (``None``: none started)
_reaper_pipe: int | None = None

#: a process that outlives the driver (its own session, forked off) and, when its standard
#: input ends (the driver closed it or died, also by SIGKILL), kills every process whose
#: environment holds ``argv[1]`` (``HGO_MJ_RAY_INSTANCE=<id>``), scanning /proc until four
#: scans half a second apart find none (a worker forked during a scan). Ray ends its GCS and
#: raylet with the driver, its workers and agents with the raylet, but the agents first wait
#: a minute on the dead GCS, listening
_REAPER = r"""
import os, signal, sys, time
if os.fork():
    os._exit(0)
while sys.stdin.buffer.read(4096):
    pass
marker = sys.argv[1].encode()
quiet = 0
for _ in range(120):  # again until 2 s without one: a process forked during a scan
    found = False
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/environ", "rb") as fh:
                if marker in fh.read().split(b"\0"):
                    os.kill(int(pid), signal.SIGKILL)
                    found = True
        except OSError:
            pass
    quiet = 0 if found else quiet + 1
    if quiet == 4:
        break
    time.sleep(0.5)
"""


@contextlib.contextmanager
def _local_ray_env(instance: str) -> Iterator[None]:
    """:data:`LOCAL_RAY_ENV` and ``HGO_MJ_RAY_INSTANCE=instance`` in ``os.environ`` while a
    local Ray instance starts (its processes inherit them), and in this process Ray's value
    of the first (``ENABLE_RAY_CLUSTER``, read when ray was imported: maybe before); restored
    after. The loopback test (tests/study/test_ray.py) catches a Ray that reads it elsewhere."""
    import ray._private.ray_constants as ray_constants

    env = {**LOCAL_RAY_ENV, _INSTANCE_VAR: instance}
    saved = {k: os.environ.get(k) for k in env}
    cluster = getattr(ray_constants, "ENABLE_RAY_CLUSTER", None)
    os.environ.update(env)
    if cluster is not None:
        ray_constants.ENABLE_RAY_CLUSTER = False
    try:
        yield
    finally:
        if cluster is not None:
            ray_constants.ENABLE_RAY_CLUSTER = cluster
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _start_reaper(instance: str) -> None:
    """Start :data:`_REAPER` for the local instance ``instance`` (Linux: it reads /proc), after
    ending the previous one's (which kills what is left of a previous instance)."""
    global _reaper_pipe
    if _reaper_pipe is not None:
        os.close(_reaper_pipe)
        _reaper_pipe = None
    if not sys.platform.startswith("linux"):
        return
    read, write = os.pipe()  # not inherited by the processes Ray starts (close-on-exec)
    try:
        subprocess.run([sys.executable, "-c", _REAPER, f"{_INSTANCE_VAR}={instance}"],
                       stdin=read, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                       start_new_session=True, check=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        os.close(write)  # no reaper: Ray's own clean-up only
    else:
        _reaper_pipe = write
    finally:
        os.close(read)


def ray_init(jobs: int, address: str | None) -> None:
    """Connect to ``address``, or start a local instance (``jobs`` CPUs, no dashboard, every
    process on 127.0.0.1: :data:`LOCAL_RAY_ENV`) unless one is running in this process.

    The local instance's processes end with this one: Ray ends its GCS and raylet with the
    driver and the workers with the raylet; a reaper (:data:`_REAPER`) ends its agents, which
    would otherwise wait a minute on the dead GCS.
    """
    ray = require("ray", "ray", "--backend ray")

    if ray.is_initialized():
        return
    try:
        if address is None:
            instance = uuid.uuid4().hex
            with _local_ray_env(instance):
                ray.init(num_cpus=jobs, include_dashboard=False, dashboard_host="127.0.0.1",
                         _node_ip_address="127.0.0.1", log_to_driver=False,
                         configure_logging=False)
            _start_reaper(instance)
        else:
            ray.init(address=address, log_to_driver=False, configure_logging=False)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        where = "a local Ray instance" if address is None else f"Ray at {address!r}"
        raise DesignError(f"cannot start or reach {where}: {exc}") from None


def _check_reachable(address: str, timeout: float = 5.0) -> None:
    """Refuse a ``host:port`` address that does not accept a connection within ``timeout``
    seconds (Ray itself would retry for minutes). ``auto`` and ``ray://`` addresses are left
    to Ray."""
    import socket

    if address == "auto" or "://" in address:
        return
    host, _, port = address.rpartition(":")
    if not host or not port.isdigit():
        raise DesignError(f"--address must be HOST:PORT (as `ray start --head` prints it); "
                          f"found {address!r}")
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as exc:
        raise DesignError(f"cannot start or reach Ray at {address!r}: {exc}") from None


def _ray(chunks: list[Chunk], jobs: int, address: str | None) -> Iterator[tuple[Chunk, Rows]]:
    import ray

    ray_init(jobs, address)
    task = ray.remote(num_cpus=1)(run_chunk)
    pending = {task.remote(c): c for c in chunks}
    try:
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                yield pending.pop(ref), ray.get(ref)
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)


#: a backend is chosen by name (``Study.run(backend=...)``, ``--backend``); the functions
#: that build and feed it are internal
__all__ = ["BACKENDS", "LOCAL_RAY_ENV", "WORKERS_WORTH_S"]
