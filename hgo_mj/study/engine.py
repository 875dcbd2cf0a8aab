"""The study engine: runs planned by what they share, each chunk on the one loop.

**Planning** (:func:`plan`). Runs are grouped by what they share. Cells whose plant, input and
periods agree form a *group*: in an open-loop study the plant's trajectory depends on neither
the noise seed nor the observers, so a chunk simulates each distinct initial state of its
members once (all of them as one batch of plants, :class:`~hgo_mj.loop.Loop` without sensor or
observers). Inside a group, cells whose sensor chain and observers agree (they differ at most
in ``plant.x0``) form a *bucket*: all its members (cell x seed) run as one batch. A chunk is a
piece of one bucket: at most ``size`` members.

**Running a chunk** (:func:`run_chunk`). The plant rows are replayed to the bucket's members by
a :class:`ReplayPlant` (member ``b`` sees the trajectory of its initial state), the sensor chain
draws one seeded stream per member, and every observer advances over all members, on
:class:`~hgo_mj.loop.Loop` as ``simulate`` does: member ``b`` equals ``simulate`` of its cell at
its seed (the same kernels on the same numbers). The metrics of :func:`hgo_mj.metrics.
observer_metrics` are accumulated segment by segment (:class:`Metrics`), so no trajectory is
kept: peak, final error, settling time and the undefined-sample count equal the single run's
bit for bit; the RMSE sums its squares per segment, equal to ``numpy.mean`` over the whole
window to rounding (relative 1e-12).

**Failures are rows.** An observer whose update fails (a :class:`~hgo_mj.loop.LoopFailure`) is
taken out of the batch, the others rerun without it (the same numbers: the streams are seeded),
and its members are bisected until each failing member is alone; an estimate that leaves the
finite numbers without an error is found by the metrics. Either way the run's row says
``diverged`` with the message ``simulate`` would give; other observers and members are kept. A
plant that fails (MuJoCo's bad state) makes every run of that initial state a diverged row.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..loop import Drive, Loop, LoopFailure, Periods
from ..observers.base import Observer
from ..plants.base import Plant

Array = NDArray[np.float64]

#: samples per segment (as ``simulate``)
SEGMENT = 1024
#: the metric columns of a result row, in order
METRICS = ("rmse", "peak", "settling_time", "final", "undefined_samples", "update_time")


# ------------------------------------------------------------------- planning
def _group_key(sc: Mapping[str, Any]) -> str:
    plant = {k: v for k, v in sc.get("plant", {}).items() if k != "x0"}
    run = {k: v for k, v in sc.get("run", {}).items()
           if k in ("duration", "sample_period", "control_period")}
    return json.dumps([plant, sc.get("input"), run], sort_keys=True)


def _bucket_key(sc: Mapping[str, Any]) -> str:
    return json.dumps([sc.get("sensor"), sc.get("observers")], sort_keys=True)


@dataclass
class Chunk:
    """A piece of work: members ``(cell, seed)`` of one bucket, with every cell's scenario.
    Plain data (pickled to worker processes and Ray tasks)."""

    id: int
    members: list[tuple[int, int]]
    scenarios: dict[int, dict[str, Any]]
    metric_kw: dict[str, Any] = field(default_factory=dict)

    @property
    def n_runs(self) -> int:
        return len(self.members)


def plan(cells: Sequence[Any], seeds: Sequence[int], *, done: set[tuple[int, int]] | None = None,
         jobs: int = 1, size: int = 256, metric_kw: Mapping[str, Any] | None = None
         ) -> list[Chunk]:
    """Chunks of the runs ``cells x seeds`` not in ``done`` (pairs ``(cell, seed)``), grouped
    as the module docstring says; at most ``size`` members a chunk, and pieces small enough
    that ``jobs`` workers get at least two chunks each where the study allows."""
    done = done or set()
    buckets: dict[tuple[str, str], list[tuple[int, int]]] = {}
    scen: dict[int, dict[str, Any]] = {}
    for cell in cells:
        key = (_group_key(cell.scenario), _bucket_key(cell.scenario))
        todo = [(cell.index, s) for s in seeds if (cell.index, s) not in done]
        if todo:
            buckets.setdefault(key, []).extend(todo)
            scen[cell.index] = cell.scenario
    total = sum(len(m) for m in buckets.values())
    if total == 0:
        return []
    want = max(1, math.ceil(total / (2 * max(jobs, 1)))) if jobs > 1 else total
    piece = max(1, min(size, want))
    chunks: list[Chunk] = []
    for members in buckets.values():
        n = math.ceil(len(members) / piece)
        step = math.ceil(len(members) / n)
        for i in range(0, len(members), step):
            part = members[i:i + step]
            chunks.append(Chunk(len(chunks), part, {c: scen[c] for c, _ in part},
                                dict(metric_kw or {})))
    return chunks


# ------------------------------------------------------------------- the replayed plant
class ReplayPlant(Plant):
    """The rows of plants already simulated, served to B members: member ``b`` sees the
    trajectory ``rows[b]`` of ``X`` ``(G, N + 1, n)`` and ``Yc`` ``(G, N + 1, p)``. Its
    inputs are those the trajectories were simulated with (the loop's drive makes the same
    ones); what ``run`` is given is not applied again."""

    def __init__(self, plant: Plant, X: Array, Yc: Array, rows: Array) -> None:
        self.system, self.dt = plant.system, plant.dt
        self._names = (plant.state_names, plant.input_names, plant.output_names)
        self.X, self.Yc, self.rows = X, Yc, np.asarray(rows, dtype=np.intp)
        self._one = bool(np.all(self.rows == self.rows[0]))
        self.k, self.t = 0, 0.0

    @property
    def state_names(self) -> tuple[str, ...]:
        return self._names[0]

    @property
    def input_names(self) -> tuple[str, ...]:
        return self._names[1]

    @property
    def output_names(self) -> tuple[str, ...]:
        return self._names[2]

    def reset(self, x0: Any = None, *, batch: int | None = None) -> None:
        self.batch, self.batched, self.k, self.t = self.rows.size, True, 0, 0.0

    def _rows(self, A: Array, a: int, b: int) -> Array:
        if self._one:  # one trajectory for every member: a read-only view, no copy
            return np.broadcast_to(A[self.rows[0], a:b], (self.batch, b - a, A.shape[2]))
        return A[self.rows, a:b]

    def run(self, U: Any, steps: int) -> tuple[Array, Array]:
        T = int(np.shape(U)[1])
        out = self._rows(self.X, self.k, self.k + T), self._rows(self.Yc, self.k, self.k + T)
        self.k += T
        return out

    @property
    def state(self) -> Array:
        return np.array(self._rows(self.X, self.k, self.k + 1)[:, 0])

    def outputs(self) -> Array:
        return np.array(self._rows(self.Yc, self.k, self.k + 1)[:, 0])


def plant_rows(plant: Plant, inputs: Any, periods: Periods, N: int, x0s: Array
               ) -> tuple[Array, Array]:
    """The true states and clean outputs ``(G, N + 1, .)`` of G plants from the initial states
    ``x0s`` ``(G, n)`` under the open-loop input, on the loop (no sensor, no observers)."""
    loop = Loop(plant, None, {}, periods, exact=False)
    drive = Drive.of(inputs, {}, plant, periods)
    loop.reset(x0s, batch=x0s.shape[0])
    G, n, p = x0s.shape[0], len(plant.state_names), len(plant.output_names)
    X, Yc = np.empty((G, N + 1, n)), np.empty((G, N + 1, p))
    while loop.k < N:
        k, T = loop.k, drive.length(loop.k, N, SEGMENT)
        seg = loop.segment(drive.inputs(loop, T))
        X[:, k:k + T], Yc[:, k:k + T] = seg.x, seg.y_clean
    Xl, Ycl, _ = loop.sample()
    X[:, N], Yc[:, N] = Xl[:, 0], Ycl[:, 0]
    return X, Yc


# ------------------------------------------------------------------- streamed metrics
class Metrics:
    """:func:`hgo_mj.metrics.observer_metrics` of B runs of one observer, accumulated over the
    rows as they come (row ``k``: the true state at ``t_k`` and the estimate before
    ``y(t_k)``), without keeping them. ``scale`` ``(B, n)`` is the band's scale (the true
    state's range for a relative band)."""

    def __init__(self, observer: Observer, state_names: Sequence[str], B: int, Ts: float,
                 t_transient: float, band: Array) -> None:
        own = {s: j for j, s in enumerate(observer.state_names)}
        self.est = np.array([s in own for s in state_names])
        self.cols = np.array([own[s] for s in state_names if s in own], dtype=np.intp)
        self.idx = np.flatnonzero(self.est)
        self.Ts, self.t_transient, self.band = Ts, t_transient, band[:, self.idx]
        k = self.idx.size
        self.sumsq, self.count = np.zeros((B, k)), np.zeros((B, k), dtype=np.int64)
        self.peak = np.full((B, k), -np.inf)
        self.undefined = np.zeros((B, k), dtype=np.int64)
        self.last_out = np.full((B, k), -1, dtype=np.int64)
        self.final = np.full((B, k), np.nan)
        self.bad_row = np.full(B, -1, dtype=np.int64)  # first row with a non-finite z_hat
        self.rows = 0

    def add(self, k0: int, X: Array, Xh: Array, Zh: Array) -> None:
        """Rows ``k0 ...``: true states ``X`` ``(B, T, n)``, estimates ``Xh`` ``(B, T, n_x)``
        and ``Zh`` ``(B, T, n_z)`` (the observer's layout)."""
        T = X.shape[1]
        bad = ~np.all(np.isfinite(Zh), axis=2) | np.any(np.isinf(Xh), axis=2)
        hit = bad.any(axis=1) & (self.bad_row < 0)
        self.bad_row[hit] = k0 + np.argmax(bad[hit], axis=1)
        with np.errstate(over="ignore", invalid="ignore"):
            e = X[:, :, self.idx] - Xh[:, :, self.cols]
            finite = np.isfinite(e)
            ae = np.abs(e)
            t = (k0 + np.arange(T)) * self.Ts
            win = (t >= self.t_transient)[None, :, None] & finite
            self.sumsq += (np.where(win, e, 0.0) ** 2).sum(axis=1)
            self.count += win.sum(axis=1)
            self.peak = np.maximum(self.peak, np.where(finite, ae, -np.inf).max(axis=1))
            self.undefined += (~finite).sum(axis=1)
            outside = ~(np.where(finite, ae, np.inf) <= self.band[:, None, :])
            any_out = outside.any(axis=1)
            last = T - 1 - np.argmax(outside[:, ::-1], axis=1)
            self.last_out = np.where(any_out, k0 + last, self.last_out)
            self.final = ae[:, -1]
        self.rows = k0 + T

    def result(self, n: int, update_time: float) -> dict[str, Array]:
        """Per metric ``(B, n)`` arrays over the plant's states (NaN: not estimated)."""
        B = self.sumsq.shape[0]
        out = {m: np.full((B, n), np.nan) for m in METRICS}
        with np.errstate(invalid="ignore", divide="ignore"):
            rmse = np.where(self.count > 0, np.sqrt(self.sumsq / np.maximum(self.count, 1)),
                            np.nan)
        peak = np.where(np.isfinite(self.peak), self.peak, np.nan)
        last = self.last_out
        settle = np.where(last < 0, 0.0,
                          np.where(last + 1 < self.rows, (last + 1) * self.Ts, np.inf))
        for key, val in (("rmse", rmse), ("peak", peak), ("settling_time", settle),
                         ("final", self.final), ("undefined_samples", self.undefined)):
            out[key][:, self.idx] = val
        out["update_time"][:, self.idx] = update_time
        return out


# ------------------------------------------------------------------- one chunk
def _x0_rows(scenarios: Mapping[int, Mapping[str, Any]], members: Sequence[tuple[int, int]],
             plant: Plant) -> tuple[Array, Array]:
    """The distinct initial states ``(G, n)`` of the members and each member's row."""
    default = np.asarray(plant.system.default_x0, dtype=float)
    keys: dict[tuple[float, ...], int] = {}
    rows = []
    for cell, _ in members:
        x0 = scenarios[cell].get("plant", {}).get("x0")
        v = default if x0 is None else np.asarray(x0, dtype=float)
        rows.append(keys.setdefault(tuple(v.tolist()), len(keys)))
    return np.array(list(keys), dtype=float).reshape(len(keys), -1), np.array(rows)


def _observe(build: Any, members: list[int], names: list[str], exact: bool = False
             ) -> dict[str, tuple[dict[str, Array], Array, list[str | None]]]:
    """Run the observers ``names`` over the members (indices into the chunk) on the loop;
    isolate failures (module docstring). Per observer: metrics, final diagnostics, messages."""
    if not names or not members:
        return {}
    try:
        return build.run(members, names, exact)
    except LoopFailure as failure:
        bad = str(failure.observer)
        out = _observe(build, members, [n for n in names if n != bad])
        if len(members) == 1:
            if not exact:
                return {**out, **_observe(build, members, [bad], exact=True)}
            msg = (f"observer {bad!r} failed in its update at t={failure.t:g} (row "
                   f"{failure.row}): {type(failure.cause).__name__}: {failure.cause}")
            out[bad] = build.failed(1, bad, msg)
            return out
        half = len(members) // 2
        a = _observe(build, members[:half], [bad])[bad]
        b = _observe(build, members[half:], [bad])[bad]
        out[bad] = ({k: np.concatenate([a[0][k], b[0][k]]) for k in a[0]},
                    np.concatenate([a[1], b[1]]), a[2] + b[2])
        return out


class _Bucket:
    """Builds and runs the loop of a chunk's members (any subset, any of its observers)."""

    def __init__(self, chunk: Chunk) -> None:
        from ..cli import scenario_run

        first = chunk.scenarios[chunk.members[0][0]]
        self.kw = scenario_run(first)
        self.chunk = chunk
        self.first = first
        plant: Plant = self.kw["plant"]
        self.plant = plant
        self.periods = Periods.of(plant, self.kw["sample_period"], self.kw["control_period"])
        duration = float(self.kw["duration"])
        self.N = int(round(duration / self.periods.sample))
        self.seeds = [s for _, s in chunk.members]
        self.x0s, self.member_rows = _x0_rows(chunk.scenarios, chunk.members, plant)
        self.state_names = tuple(plant.state_names)
        mkw = chunk.metric_kw
        t_end = self.N * self.periods.sample
        tt = mkw.get("t_transient")
        self.t_transient = 0.2 * t_end if tt is None else float(tt)
        self.band, self.relative = float(mkw.get("band", 0.05)), bool(mkw.get("relative", True))
        self.plant_failed: dict[int, str] = {}
        self._simulate_plants()

    def _simulate_plants(self) -> None:
        """The plant rows of every distinct initial state; a failing one alone, its message
        kept (its members' runs are diverged rows)."""
        try:
            self.X, self.Yc = plant_rows(self.plant, self.kw["inputs"], self.periods, self.N,
                                         self.x0s)
            return
        except LoopFailure:
            pass
        G, n, p = self.x0s.shape[0], len(self.state_names), len(self.plant.output_names)
        self.X, self.Yc = np.full((G, self.N + 1, n), np.nan), np.full((G, self.N + 1, p), np.nan)
        for g in range(G):
            try:
                X, Yc = plant_rows(self.plant, self.kw["inputs"], self.periods, self.N,
                                   self.x0s[g:g + 1])
                self.X[g], self.Yc[g] = X[0], Yc[0]
            except LoopFailure as exc:
                self.plant_failed[g] = f"simulation stopped at t={exc.t:g}: {exc.cause}"

    def run(self, members: list[int], names: list[str], exact: bool
            ) -> dict[str, tuple[dict[str, Array], Array, list[str | None]]]:
        from ..cli import scenario_run

        kw = scenario_run(self.first)
        obs = {n: kw["observers"][n] for n in names}
        rows = self.member_rows[members]
        plant = ReplayPlant(self.plant, self.X, self.Yc, rows)
        loop = Loop(plant, kw["sensor"], obs, self.periods, exact=exact)
        drive = Drive.of(kw["inputs"], obs, plant, self.periods)
        loop.reset(None, seed=[self.seeds[i] for i in members], batch=len(members))
        n = len(self.state_names)
        if self.relative:
            with np.errstate(invalid="ignore"):
                scale = np.ptp(self.X[rows], axis=1)
            scale = np.where(scale > 0, scale, 1.0)
        else:
            scale = np.ones((len(members), n))
        band = self.band * scale
        acc = {name: Metrics(ob, self.state_names, len(members), self.periods.sample,
                             self.t_transient, band) for name, ob in obs.items()}
        prev = {name: (x, z) for name, (x, z, _) in loop.estimates().items()}
        while loop.k < self.N:
            k0, T = loop.k, drive.length(loop.k, self.N, SEGMENT)
            seg = loop.segment(drive.inputs(loop, T))
            for name, blk in seg.blocks.items():
                px, pz = prev[name]
                Xh = np.concatenate([px[:, None], blk.x_hat[:, :-1]], axis=1)
                Zh = np.concatenate([pz[:, None], blk.z_hat[:, :-1]], axis=1)
                acc[name].add(k0, seg.x, Xh, Zh)
                prev[name] = (blk.x_hat[:, -1], blk.z_hat[:, -1])
        Xl = np.reshape(plant.state, (len(members), 1, -1))
        out = {}
        for name, (x, z, d) in loop.estimates().items():
            acc[name].add(self.N, Xl, x[:, None], z[:, None])
            wall = loop.wall[name] / (max(self.N, 1) * len(members))
            res = acc[name].result(n, wall)
            msgs: list[str | None] = [None] * len(members)
            for i, r in enumerate(acc[name].bad_row):
                if r >= 0:
                    msgs[i] = (f"observer {name!r} estimate left the finite numbers at "
                               f"t={r * self.periods.sample:g} (row {int(r)})")
            out[name] = (res, d, msgs)
        return out

    def failed(self, B: int, name: str, msg: str
               ) -> tuple[dict[str, Array], Array, list[str | None]]:
        n = len(self.state_names)
        nd = len(self.kw["observers"][name].family_diagnostics) + 1
        return ({m: np.full((B, n), np.nan) for m in METRICS}, np.full((B, nd), np.nan),
                [msg] * B)


def run_chunk(chunk: Chunk) -> list[dict[str, Any]]:
    """Run a chunk: its result rows, one per member x observer x plant state, each with
    ``cell``, ``seed``, ``observer``, ``state``, ``estimated``, the metrics (None: not
    estimated, or diverged), ``diverged``, ``message`` and ``diag.<name>`` (each diagnostic's
    final value)."""
    b = _Bucket(chunk)
    names = list(b.kw["observers"])
    ok = [i for i, r in enumerate(b.member_rows) if int(r) not in b.plant_failed]
    got = _observe(b, ok, names)
    pos = {i: j for j, i in enumerate(ok)}
    rows: list[dict[str, Any]] = []
    for name in names:
        ob = b.kw["observers"][name]
        own = set(ob.state_names)
        for i, (cell, seed) in enumerate(chunk.members):
            g = int(b.member_rows[i])
            if g in b.plant_failed:
                res, dg, msgs = b.failed(1, name, b.plant_failed[g])
                j = 0
            else:
                (res, dg, msgs), j = got[name], pos[i]
            message = msgs[j]
            diverged = message is not None
            diag = {f"diag.{d}": None if diverged else float(dg[j, q])
                    for q, d in enumerate(ob.diagnostic_names)}
            for s, state in enumerate(b.state_names):
                estimated = state in own
                row: dict[str, Any] = {"cell": cell, "seed": seed, "observer": name,
                                       "state": state, "estimated": estimated}
                for m in METRICS:
                    keep = estimated and (not diverged or m == "update_time")
                    row[m] = float(res[m][j, s]) if keep else None
                row.update(diverged=diverged, message=message, **diag)
                rows.append(row)
    return rows


__all__ = ["Chunk", "METRICS", "Metrics", "ReplayPlant", "SEGMENT", "plan", "plant_rows",
           "run_chunk"]
