"""The local backend (hgo_mj.study.backends._local): every chunk once with its own rows, the
rows of one process, and a worker handed its next chunk as soon as it finishes one."""

from __future__ import annotations

import os
import time
from pathlib import Path

from hgo_mj.study.backends import _local


def square(c: int) -> list[dict[str, int]]:
    """A chunk's rows (module-level: a spawned worker imports it)."""
    return [{"c": c, "square": c * c}]


def marker_or_wait(c: tuple[str, str, int]) -> list[dict[str, int]]:
    """``("mark", folder, i)``: write ``folder/i``; ``("wait", folder, n)``: wait (at most 120
    s) until ``n`` marks are written. Each row names the process that ran the chunk."""
    kind, folder, n = c
    if kind == "mark":
        (Path(folder) / str(n)).write_text("")
        return [{"pid": os.getpid(), "seen": 0}]
    end = time.monotonic() + 120.0
    while len(os.listdir(folder)) < n and time.monotonic() < end:
        time.sleep(0.05)
    return [{"pid": os.getpid(), "seen": len(os.listdir(folder))}]


def test_every_chunk_once_with_the_rows_of_one_process():
    chunks = list(range(9))
    one = list(_local(chunks, 1, run=square))
    two = list(_local(chunks, 2, run=square))
    three = list(_local(chunks, 3, run=square))
    assert [c for c, _ in one] == chunks
    for got in (two, three):
        assert sorted(c for c, _ in got) == chunks  # each once
        assert sorted(got, key=lambda cr: cr[0]) == one  # the same rows with each chunk


def test_a_worker_takes_its_next_chunk_while_this_process_is_busy(tmp_path):
    """This process takes the first chunk, which waits for the four others: the worker must
    get each next chunk as it finishes one, not when this process comes back for results."""
    marks = [("mark", str(tmp_path), i) for i in range(4)]
    got = dict(_local([("wait", str(tmp_path), 4), *marks], 2, run=marker_or_wait))
    wait = got[("wait", str(tmp_path), 4)][0]
    assert wait["pid"] == os.getpid() and wait["seen"] == 4
    assert all(got[m][0]["pid"] != os.getpid() for m in marks)
