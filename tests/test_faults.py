"""Faults of the machine, injected (issue 14, "data loss"): a recording onto a full disk, a
recording that fills its file size limit part-way, a finished recording checked by rerun's own
``rerun rrd verify``, worker processes of a multi-run command killed with their parent, and
Ctrl-C of such a command."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from hgo_mj.cli import main
from hgo_mj.exceptions import DesignError, RecordingError

RUN = ["run", "--plant", "pendulum", "--dt", "0.001", "--observer", "high_gain:k=20",
       "--duration", "3", "--quiet"]


def rerun_command() -> list[str]:
    """The ``rerun`` command installed with rerun-sdk: beside this interpreter, else on PATH,
    else ``python -m rerun`` (the same binary, found through the package)."""
    beside = Path(sys.executable).parent / "rerun"
    found = str(beside) if beside.is_file() else shutil.which("rerun")
    return [found] if found else [sys.executable, "-m", "rerun"]


def verify(rrd: Path) -> subprocess.CompletedProcess[str]:
    """``rerun rrd verify`` on ``rrd``."""
    return subprocess.run([*rerun_command(), "rrd", "verify", str(rrd)], capture_output=True,
                          text=True, timeout=120)


def limited_run(tmp_path: Path, limit: int, rrd: Path) -> subprocess.CompletedProcess[str]:
    """``hgo-mj run --rrd rrd`` in a process whose files cannot grow past ``limit`` bytes (a
    disk that fills: writes beyond fail with EFBIG), after the same run once without a limit
    (numba's cache then holds its kernels). Output after the line ``LIMITED`` is the run's."""
    script = tmp_path / "limited.py"
    script.write_text(textwrap.dedent(f"""
        import resource, signal, sys
        import hgo_mj.record.recorder as recorder
        from hgo_mj.cli import main
        recorder.CLOSE_TIMEOUT_S = 3.0
        assert main({[*RUN, "--out", str(tmp_path / "warm")]!r}) == 0
        print("LIMITED", flush=True)
        print("LIMITED", file=sys.stderr, flush=True)
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # writes beyond the limit fail (EFBIG)
        resource.setrlimit(resource.RLIMIT_FSIZE, ({limit}, {limit}))
        sys.exit(main({[*RUN, "--out", str(tmp_path / "out"), "--rrd", str(rrd)]!r}))
    """))
    return subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          timeout=300)


def temporaries(folder: Path) -> list[Path]:
    """The hidden temporaries hgo_mj left in ``folder``."""
    return sorted(folder.glob(".*.tmp"))


def test_a_full_disk_keeps_the_earlier_recording_and_leaves_no_empty_file(tmp_path, capsys):
    """Issue 27 item 2: no byte can be written; exit 1 in one line, the earlier recording at
    the path untouched (rerun accepts it), no temporary left."""
    rrd = tmp_path / "run.rrd"
    assert main([*RUN, "--out", str(tmp_path / "first"), "--rrd", str(rrd)]) == 0
    before = rrd.read_bytes()
    res = limited_run(tmp_path, 0, rrd)
    assert res.returncode == 1, res.stderr
    ours = [ln for ln in res.stderr.split("LIMITED")[1].splitlines() if ln.startswith("hgo-mj:")]
    assert len(ours) == 1 and "run.rrd" in ours[0] and "File too large" in ours[0], res.stderr
    assert rrd.read_bytes() == before and verify(rrd).returncode == 0
    assert temporaries(tmp_path) == []


def test_a_killed_run_leaves_the_earlier_recording_intact(tmp_path, capsys):
    """Issue 27 item 2: SIGKILL while the new recording is written: the earlier one is still
    at the path and passes ``rerun rrd verify``; the torn rows are in a hidden temporary."""
    rrd = tmp_path / "run.rrd"
    assert main([*RUN, "--out", str(tmp_path / "first"), "--rrd", str(rrd)]) == 0
    before = rrd.read_bytes()
    long = [a if a != "3" else "600" for a in RUN]
    proc = subprocess.Popen([sys.executable, "-c", f"from hgo_mj.cli import main; "
                             f"main({[*long, '--out', str(tmp_path / 'o'), '--rrd', str(rrd)]!r})"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while not any(p.stat().st_size > 50_000 for p in temporaries(tmp_path)):
            assert proc.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
    finally:
        proc.kill()
        proc.wait()
    assert rrd.read_bytes() == before and verify(rrd).returncode == 0
    assert len(temporaries(tmp_path)) == 1


def test_recording_whose_sink_fails_part_way_is_an_error(tmp_path):
    """The file sink fails after 40 kB (a file size limit: the disk fills during the run):
    the command exits 1 naming the recording and reports nothing as written; no recording
    and no temporary are left."""
    res = limited_run(tmp_path, 40_000, tmp_path / "run.rrd")
    assert res.returncode == 1, res.stderr
    out, err = res.stdout.split("LIMITED")[1], res.stderr.split("LIMITED")[1]
    ours = [ln for ln in err.splitlines() if ln.startswith("hgo-mj:")]
    assert len(ours) == 1 and "run.rrd" in ours[0] and "could not be written" in ours[0], err
    assert "Traceback" not in err and "wrote" not in out, err
    assert not (tmp_path / "out" / "trajectory.npz").exists()
    assert not (tmp_path / "run.rrd").exists() and temporaries(tmp_path) == []


def test_finished_recording_passes_rerun_rrd_verify(tmp_path, capsys):
    rrd = tmp_path / "run.rrd"
    assert main([*RUN, "--out", str(tmp_path / "out"), "--rrd", str(rrd)]) == 0
    assert str(rrd) in capsys.readouterr().out
    res = verify(rrd)
    assert res.returncode == 0, res.stderr


def test_verify_rejects_a_torn_recording_as_the_recorder_does(tmp_path, capsys):
    """The check the recorder makes at close (the footer) agrees with ``rerun rrd verify``."""
    from hgo_mj.record.recorder import check_finalized

    rrd = tmp_path / "run.rrd"
    assert main([*RUN, "--out", str(tmp_path / "out"), "--rrd", str(rrd)]) == 0
    torn = tmp_path / "torn.rrd"
    torn.write_bytes(rrd.read_bytes()[: rrd.stat().st_size // 2])
    res = subprocess.run([*rerun_command(), "rrd", "verify", str(torn)], capture_output=True,
                         text=True, timeout=120)
    assert res.returncode != 0
    with pytest.raises(RecordingError, match="torn.rrd"):
        check_finalized(torn)
    check_finalized(rrd)  # the whole file passes


# ---------------------------------------------------------------- worker processes

POOL_SCRIPT = """
import os, sys, time
from hgo_mj.study.backends import _local

def slow(c):
    print(f"worker {{os.getpid()}}", flush=True)
    time.sleep(120)
    return [{{"c": c}}]

if __name__ == "__main__":
    print(f"parent {{os.getpid()}}", flush=True)
    try:
        for _ in _local(list(range(8)), {jobs}, run=slow):
            pass
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        sys.exit(130)
"""


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, dead but not yet reaped, counts as gone)."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().split(") ", 1)[1][0] != "Z"
    except FileNotFoundError:
        return False


def _start_pool(tmp_path: Path, jobs: int) -> tuple[subprocess.Popen[str], list[int]]:
    script = tmp_path / "pool.py"
    script.write_text(POOL_SCRIPT.format(jobs=jobs))
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    workers: list[int] = []
    assert proc.stdout is not None
    while len(workers) < jobs - 1:  # the workers announce themselves as they start a chunk
        line = proc.stdout.readline()
        assert line, proc.stderr.read() if proc.stderr else "no output"
        # two workers writing at once may share a line: "worker 12worker 13\n"
        workers += [int(p) for p in re.findall(r"worker (\d+)", line)
                    if int(p) != proc.pid and int(p) not in workers]
    return proc, workers


def _gone(pids: list[int], within: float = 20.0) -> bool:
    end = time.monotonic() + within
    while time.monotonic() < end:
        if not any(_alive(p) for p in pids):
            return True
        time.sleep(0.1)
    return False


def test_workers_die_with_a_killed_parent(tmp_path):
    proc, workers = _start_pool(tmp_path, jobs=3)
    try:
        assert all(_alive(p) for p in workers)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        assert _gone(workers), f"orphaned workers {workers}"
    finally:
        for p in workers:
            if _alive(p):
                os.kill(p, signal.SIGKILL)


def test_ctrl_c_stops_the_workers_with_one_line(tmp_path):
    """SIGINT to the whole process group, as a terminal's Ctrl-C sends it: the parent alone
    reports it; no worker prints a traceback or a broken pipe."""
    proc, workers = _start_pool(tmp_path, jobs=3)
    try:
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 130, err
        assert err.strip() == "interrupted", err
        assert _gone(workers), f"workers left running {workers}"
    finally:
        for p in workers:
            if _alive(p):
                os.kill(p, signal.SIGKILL)


def test_store_every_thins_a_long_run_and_the_memory_refusal_names_it(tmp_path, capsys,
                                                                     monkeypatch):
    """--store-every K keeps every K-th row (the run still takes every sample); a run whose
    rows would not fit in memory is refused before it starts, naming the estimate and the
    flag; bad values, seeds with it and a study with it are one line each."""
    from hgo_mj.simulate import Trajectory

    assert main(["run", "--plant", "pendulum", "--observer", "high_gain:k=10", "--duration",
                 "2", "--store-every", "10", "--out", str(tmp_path / "a"), "--quiet",
                 "--format", "npz"]) == 0
    tr = Trajectory.load(tmp_path / "a" / "trajectory.npz")
    assert len(tr.t) == 201 and np.allclose(np.diff(tr.t), 0.01)
    monkeypatch.setattr("hgo_mj.simulate.available_memory", lambda: 1e6)
    capsys.readouterr()
    assert main(["run", "--plant", "pendulum", "--duration", "100", "--out",
                 str(tmp_path / "b"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "GiB" in err[0] and "--store-every k" in err[0], err
    assert not (tmp_path / "b").exists()
    for argv, message in [(["--store-every", "2.5"], "--store-every must be a positive integer"),
                          (["--store-every", "2", "--seeds", "3"], "with run.seeds = 3")]:
        assert main(["run", "--plant", "pendulum", "--duration", "1", "--out",
                     str(tmp_path / "c"), "--quiet", *argv]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0], err
    from hgo_mj.study.spec import parse_study

    with pytest.raises(DesignError, match="run.store_every thins the trajectory"):
        parse_study({"plant": {"name": "pendulum"}, "run": {"duration": 1.0, "store_every": 2},
                     "sweep": {"seeds": 2}})


def test_a_run_whose_files_would_not_fit_on_the_disk_is_refused_before_it_starts(
        tmp_path, capsys, monkeypatch):
    """The files' size is estimated before the run (rows x columns x bytes per value and
    format) and compared with the free space of --out's disk: one line, nothing written."""
    import collections
    import shutil as sh

    usage = collections.namedtuple("usage", "total used free")
    monkeypatch.setattr(sh, "disk_usage", lambda p: usage(2**40, 2**40 - 2**20, 2**20))
    out = tmp_path / "o"
    argv = ["run", "--plant", "pendulum", "--dt", "0.001", "--observer", "high_gain:k=20",
            "--duration", "60", "--quiet", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the run's files would take about 11 MiB" in err[0], err
    assert "has 1 MiB free" in err[0] and "--store-every k" in err[0]
    assert not out.exists()
    # every 100th row: a tenth of a MiB, the run goes on
    assert main([*argv, "--store-every", "100", "--format", "npz"]) == 0
