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
  ``jobs`` CPUs bound to 127.0.0.1 without dashboard; with ``address`` (``ray start --head``
  on the head node prints it, e.g. ``192.168.1.10:6379``), that cluster: every node needs
  hgo_mj installed, and only the chunk specs and the rows move over the network.
"""

from __future__ import annotations

import multiprocessing
import os
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any

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
    try:
        import ray  # noqa: F401
    except ImportError:
        raise DesignError('--backend ray needs Ray: pip install "hgo_mj[ray]"') from None
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
    :func:`worker_init`). This process takes chunks from the front of the queue while the
    workers (which start in about a second: an interpreter, hgo_mj, the compiled kernels from
    their cache) are fed from the back, one chunk ahead each. ``run`` (a module-level function;
    default :func:`~hgo_mj.study.engine.run_chunk`, looked up at the call) computes a chunk's
    rows."""
    if run is None:
        run = run_chunk
    if jobs == 1 or len(chunks) <= 1:
        for c in chunks:
            yield c, run(c)
        return
    queue = deque(chunks)
    workers = min(jobs - 1, len(chunks) - 1)
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                               initializer=worker_init, initargs=(os.getpid(),))
    pending: dict[Future[Rows], Any] = {}
    try:
        while queue or pending:
            while queue and len(pending) < workers:
                c = queue.pop()
                pending[pool.submit(run, c)] = c
            for f in [f for f in pending if f.done()]:
                yield pending.pop(f), f.result()
            if queue:
                c = queue.popleft()
                yield c, run(c)
            elif pending:
                wait(pending, return_when=FIRST_COMPLETED)
    except BaseException:  # Ctrl-C or an error: stop the workers now, not after their chunks
        for proc in list(getattr(pool, "_processes", {}).values()):
            proc.kill()
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)


def ray_init(jobs: int, address: str | None) -> None:
    """Connect to ``address``, or start a local instance (127.0.0.1, ``jobs`` CPUs, no
    dashboard) unless one is running in this process."""
    import ray

    if ray.is_initialized():
        return
    try:
        if address is None:
            ray.init(num_cpus=jobs, include_dashboard=False, _node_ip_address="127.0.0.1",
                     log_to_driver=False, configure_logging=False)
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
__all__ = ["BACKENDS", "WORKERS_WORTH_S"]
