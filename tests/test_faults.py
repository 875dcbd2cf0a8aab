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
from hgo_mj.record import Recorder

RUN = ["run", "--plant", "pendulum", "--dt", "0.001", "--observer", "high_gain:k=20",
       "--duration", "3", "--quiet"]


def rerun_binary() -> str:
    """The ``rerun`` command installed with rerun-sdk (beside this interpreter, else on PATH)."""
    beside = Path(sys.executable).parent / "rerun"
    found = str(beside) if beside.is_file() else shutil.which("rerun")
    assert found, "rerun-sdk installs the `rerun` command"
    return found


def full_file(tmp_path: Path) -> Path:
    """A path ending in .rrd on which every write fails with ENOSPC (a full disk)."""
    assert Path("/dev/full").exists(), "Linux provides /dev/full"
    link = tmp_path / "full.rrd"
    link.symlink_to("/dev/full")
    return link


def test_recorder_on_a_full_disk_raises_recording_error(tmp_path):
    with pytest.raises(RecordingError, match=r"full\.rrd.*No space left on device"):
        Recorder(full_file(tmp_path), state_names=["x"], output_names=["y"], input_names=["u"])


def test_cli_recording_on_a_full_disk_exits_1_with_one_line(tmp_path, capsys):
    rrd = full_file(tmp_path)
    code = main([*RUN, "--out", str(tmp_path / "out"), "--rrd", str(rrd)])
    err = capsys.readouterr()
    assert code == 1
    lines = err.err.strip().splitlines()
    assert len(lines) == 1 and "No space left on device" in lines[0], err.err
    assert "wrote" not in err.out
    assert not (tmp_path / "out" / "trajectory.npz").exists()


def test_recording_whose_sink_fails_part_way_is_an_error(tmp_path):
    """The file sink fails after 40 kB (a file size limit: the disk fills during the run):
    the command exits 1 naming the recording and reports nothing as written."""
    script = tmp_path / "limited.py"
    script.write_text(textwrap.dedent(f"""
        import resource, signal, sys
        import hgo_mj.record.recorder as recorder
        from hgo_mj.cli import main
        recorder.CLOSE_TIMEOUT_S = 3.0
        # the same run once without a limit, so that numba's cache holds its kernels
        assert main({[*RUN, "--out", str(tmp_path / "warm")]!r}) == 0
        print("LIMITED", flush=True)
        print("LIMITED", file=sys.stderr, flush=True)
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # writes beyond the limit fail (EFBIG)
        resource.setrlimit(resource.RLIMIT_FSIZE, (40_000, 40_000))
        sys.exit(main({[*RUN, "--out", str(tmp_path / "out"), "--rrd",
                        str(tmp_path / "run.rrd")]!r}))
    """))
    res = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 1, res.stderr
    out, err = res.stdout.split("LIMITED")[1], res.stderr.split("LIMITED")[1]
    ours = [ln for ln in err.splitlines() if ln.startswith("hgo-mj:")]
    assert len(ours) == 1 and "run.rrd" in ours[0] and "could not be written" in ours[0], err
    assert "Traceback" not in err and "wrote" not in out, err
    assert not (tmp_path / "out" / "trajectory.npz").exists()


def test_finished_recording_passes_rerun_rrd_verify(tmp_path, capsys):
    rrd = tmp_path / "run.rrd"
    assert main([*RUN, "--out", str(tmp_path / "out"), "--rrd", str(rrd)]) == 0
    assert str(rrd) in capsys.readouterr().out
    res = subprocess.run([rerun_binary(), "rrd", "verify", str(rrd)], capture_output=True,
                         text=True, timeout=120)
    assert res.returncode == 0, res.stderr


def test_verify_rejects_a_torn_recording_as_the_recorder_does(tmp_path, capsys):
    """The check the recorder makes at close (the footer) agrees with ``rerun rrd verify``."""
    from hgo_mj.record.recorder import check_finalized

    rrd = tmp_path / "run.rrd"
    assert main([*RUN, "--out", str(tmp_path / "out"), "--rrd", str(rrd)]) == 0
    torn = tmp_path / "torn.rrd"
    torn.write_bytes(rrd.read_bytes()[: rrd.stat().st_size // 2])
    res = subprocess.run([rerun_binary(), "rrd", "verify", str(torn)], capture_output=True,
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
