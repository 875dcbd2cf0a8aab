"""The study engine: runs planned by what they share, each chunk on the one loop.

**Planning** (:func:`plan`). Runs are grouped by what they share. Cells whose plant, input and
periods agree form a *group*: in an open-loop study the plant's trajectory depends on neither
the noise seed nor the observers, so a chunk simulates each distinct initial state of its
members once (all of them as one batch of plants, :class:`~hgo_mj.loop.Loop` without sensor or
observers). Inside a group, cells whose sensor chain and observers agree (they differ at most
in ``plant.x0``) form a *bucket*: all its members (cell x seed) run as one batch. A chunk is a
piece of one group (its buckets one after the other): at most ``size`` members.

**Running a chunk** (:func:`run_chunk`). The plant runs once for the chunk; its rows are
replayed to each bucket's members by a :class:`ReplayPlant` (member ``b`` sees the trajectory
of its initial state), the sensor chain
draws one seeded stream per member, and every observer advances over all members, on
:class:`~hgo_mj.loop.Loop` as ``simulate`` does: member ``b`` equals ``simulate`` of its cell at
its seed (the same kernels on the same numbers). The metrics of :func:`hgo_mj.metrics.
observer_metrics` are accumulated segment by segment (:class:`Metrics`, on the one accumulator
:class:`hgo_mj.metrics.MetricsBatch`), so no trajectory is
kept: every metric equals the single run's bit for bit (the RMSE's sum of squares is the same
compensated (Neumaier) sum, row by row, in both; equal to ``numpy.mean``'s pairwise sum to
rounding).

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
from ..metrics import MetricsBatch
from ..observers.base import Observer
from ..plants.base import Plant
from ..scenario import scenario_run

Array = NDArray[np.float64]

#: samples per segment (as ``simulate``) ...
SEGMENT = 1024
#: ... at most: a segment's arrays hold members x samples values, bounded by this
SEGMENT_VALUES = 2 ** 18


def segment_length(B: int) -> int:
    """Samples per segment for B members: :data:`SEGMENT`, fewer for large batches (memory
    flat in B; at least 64 samples, where the per-segment overhead is small)."""
    return max(64, min(SEGMENT, SEGMENT_VALUES // max(B, 1)))
#: the metric columns of a result row, in order
METRICS = ("rmse", "peak", "settling_time", "final", "undefined_samples", "update_time")
#: the closed loop's metrics of a run (the same in every row of the run): the cost
#: ``sum_k (x_k' Q x_k + u_k' R u_k) Ts`` over the sample rows and the peak ``|u|``
RUN_METRICS = ("cost", "peak_input")


# ------------------------------------------------------------------- planning
def _group_key(sc: Mapping[str, Any]) -> str:
    """What decides a plant's trajectory apart from its initial state (open loop: plant,
    input, periods; a closed loop's controller too)."""
    plant = {k: v for k, v in sc.get("plant", {}).items() if k != "x0"}
    run = {k: v for k, v in sc.get("run", {}).items()
           if k in ("duration", "sample_period", "control_period")}
    return json.dumps([plant, sc.get("input"), sc.get("controller"), run], sort_keys=True)


def _bucket_key(sc: Mapping[str, Any]) -> str:
    """What decides the loop around the plant: the sensor chain and the observers."""
    return json.dumps([sc.get("sensor"), sc.get("observers")], sort_keys=True)


@dataclass
class Chunk:
    """A piece of work: members ``(cell, seed)`` of one group (its buckets one after the
    other), every cell's scenario and the metric settings (``t_transient``, ``band``). Plain
    data (pickled to worker processes and Ray tasks)."""

    id: int
    members: list[tuple[int, int]]
    scenarios: dict[int, dict[str, Any]]
    metric_kw: dict[str, Any] = field(default_factory=dict)

    @property
    def n_runs(self) -> int:
        return len(self.members)


def plan(cells: Sequence[Any], seeds: Sequence[int], *, done: set[tuple[int, int]] | None = None,
         jobs: int = 1, size: int = 1024, metric_kw: Mapping[str, Any] | None = None
         ) -> list[Chunk]:
    """Chunks of the runs ``cells x seeds`` not in ``done`` (pairs ``(cell, seed)``): the
    members of one group (bucket after bucket), at most ``size`` a chunk, and pieces small
    enough that ``jobs`` workers get at least two chunks each where the study allows."""
    done = done or set()
    groups: dict[str, dict[str, list[tuple[int, int]]]] = {}
    scen: dict[int, dict[str, Any]] = {}
    for cell in cells:
        todo = [(cell.index, s) for s in seeds if (cell.index, s) not in done]
        if todo:
            bucket = groups.setdefault(_group_key(cell.scenario), {})
            bucket.setdefault(_bucket_key(cell.scenario), []).extend(todo)
            scen[cell.index] = cell.scenario
    total = sum(len(m) for g in groups.values() for m in g.values())
    if total == 0:
        return []
    want = math.ceil(total / (2 * jobs)) if jobs > 1 else total
    piece = max(1, min(size, want))
    chunks: list[Chunk] = []
    for buckets in groups.values():
        members = [m for ms in buckets.values() for m in ms]  # bucket after bucket
        n = math.ceil(len(members) / min(piece, _closed_piece(scen[members[0][0]])))
        step = math.ceil(len(members) / n)
        for i in range(0, len(members), step):
            part = members[i:i + step]
            chunks.append(Chunk(len(chunks), part, {c: scen[c] for c, _ in part},
                                dict(metric_kw or {})))
    return chunks


#: a closed loop keeps its members' errors until the end (:meth:`Metrics.settle`): at most
#: this many member-samples a chunk (with 4 states, 64 MiB a chunk and observer)
CLOSED_VALUES = 2 ** 21


def _closed_piece(sc: Mapping[str, Any]) -> int:
    """The most members a chunk of this scenario's group holds: unbounded for an open loop,
    :data:`CLOSED_VALUES` over the run's samples for a closed loop."""
    if "controller" not in sc:
        return 2 ** 62
    run, plant = sc.get("run", {}), sc.get("plant", {})
    period = run.get("sample_period") or plant.get("dt") or 0.001
    samples = int(float(run.get("duration", 1.0)) / float(period)) + 1
    return max(1, CLOSED_VALUES // max(samples, 1))


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
    rows as they come (row ``k``: the true state at ``t_k = k Ts`` and the estimate before
    ``y(t_k)``) by :class:`hgo_mj.metrics.MetricsBatch`, the accumulator
    :class:`~hgo_mj.metrics.RunningMetrics` uses. ``band`` ``(B, n)`` is the band of each
    member and state (times the true state's range for a relative band); None when it is
    known only at the end (a closed loop): then the ``rows`` errors are kept and
    :meth:`settle` finds the settling times."""

    def __init__(self, observer: Observer, state_names: Sequence[str], B: int, Ts: float,
                 t_transient: float, band: Array | None, rows: int = 0) -> None:
        self.acc = MetricsBatch.of(observer.state_names, state_names, B, t_transient, band,
                                   rows if band is None else 0)
        self.Ts = Ts
        self.bad_row = self.acc.bad  # first row with a non-finite z_hat (-1: none)

    def add(self, k0: int, X: Array, prev: tuple[Array, Array], BX: Array, BZ: Array) -> None:
        """Rows ``k0 ...``: true states ``X`` ``(B, T, n)``; the estimate before the block
        ``prev`` (``x_hat``, ``z_hat``, ``(B, .)``) and the block's rows after each sample
        ``BX``, ``BZ`` ``(B, T', .)`` (row ``j`` of the run is ``prev`` for ``j = 0``, else
        the block's row ``j - 1``)."""
        self.acc.add(np.arange(k0, k0 + X.shape[1]) * self.Ts, X, prev, BX, BZ)

    def settle(self, band: Array) -> None:
        """The settling times from the kept errors, once the band ``(B, n)`` is known."""
        self.acc.settle_kept(np.arange(self.acc.rows) * self.Ts, band)

    def result(self, n: int, update_time: float) -> dict[str, Array]:
        """Per metric ``(B, n)`` arrays over the plant's states (NaN: not estimated)."""
        out = self.acc.arrays(n)
        out["update_time"] = np.full_like(out["rmse"], np.nan)
        out["update_time"][:, self.acc.idx] = update_time
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


#: what a loop gives per observer: the metrics (per metric ``(B, n)``, or ``(B,)`` for a
#: run's), the final diagnostics ``(B, d)`` and a message per member (None: finished)
Outcome = tuple[dict[str, Array], Array, list[str | None]]


def _observe(build: Any, members: list[int], names: list[str], exact: bool = False
             ) -> dict[str, Outcome]:
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


def _finish(loop: Loop, acc: dict[str, Metrics], N: int, Xl: Array, *,
            band: Array | None = None, run: dict[str, Array] | None = None
            ) -> dict[str, Outcome]:
    """Each observer's outcome after the last row ``N`` (true state ``Xl``): its last
    estimate accumulated, the settling rows found (``band`` given: a closed loop), the
    metrics with the run's (``run``), a message where the estimate left the finite numbers."""
    B, Ts = Xl.shape[0], loop.periods.sample
    out = {}
    for name, (x, z, d) in loop.estimates().items():
        acc[name].add(N, Xl, (x, z), x[:, None], z[:, None])
        if band is not None:
            acc[name].settle(band)
        res = acc[name].result(Xl.shape[2], loop.wall[name] / (max(N, 1) * B))
        res.update({k: v.copy() for k, v in (run or {}).items()})
        msgs: list[str | None] = [None] * B
        for i, r in enumerate(acc[name].bad_row):
            if r >= 0:
                msgs[i] = (f"observer {name!r} estimate left the finite numbers at "
                           f"t={r * Ts:g} (row {int(r)})")
        out[name] = (res, d, msgs)
    return out


def _failed(n: int, observer: Observer, B: int, msg: str) -> Outcome:
    """The outcome of B members whose run failed with ``msg``: every metric NaN."""
    res: dict[str, Array] = {m: np.full((B, n), np.nan) for m in METRICS}
    res.update({m: np.full(B, np.nan) for m in RUN_METRICS})
    return res, np.full((B, len(observer.diagnostic_names)), np.nan), [msg] * B


class _Plants:
    """The plant side of a chunk: every distinct initial state of its members simulated once
    (a batch of plants); the rows each member replays, the band's scale per trajectory."""

    def __init__(self, chunk: Chunk) -> None:
        kw = scenario_run(chunk.scenarios[chunk.members[0][0]])
        self.plant: Plant = kw["plant"]
        self.periods = Periods.of(self.plant, kw["sample_period"], kw["control_period"])
        self.N = int(round(float(kw["duration"]) / self.periods.sample))
        self.seeds = [s for _, s in chunk.members]
        self.x0s, self.member_rows = _x0_rows(chunk.scenarios, chunk.members, self.plant)
        self.state_names = tuple(self.plant.state_names)
        mkw = chunk.metric_kw
        tt = mkw.get("t_transient")
        # as observer_metrics: 0.2 times the last row's time (the same float)
        self.t_transient = 0.2 * (self.N * self.periods.sample) if tt is None else float(tt)
        band = float(mkw.get("band", 0.05))
        self.failed: dict[int, str] = {}
        self.X, self.Yc = self._simulate(kw["inputs"])
        if bool(mkw.get("relative", True)):  # each trajectory's range, as observer_metrics
            with np.errstate(invalid="ignore"):
                scale = np.ptp(self.X, axis=1)
            self.band = band * np.where(scale > 0, scale, 1.0)
        else:
            self.band = np.full((self.X.shape[0], len(self.state_names)), band)

    def _simulate(self, inputs: Any) -> tuple[Array, Array]:
        """The rows of every distinct initial state; on a failure each alone, the failing
        ones' messages kept in ``failed`` (their members' runs are diverged rows)."""
        try:
            return plant_rows(self.plant, inputs, self.periods, self.N, self.x0s)
        except LoopFailure:
            pass
        G, n, p = self.x0s.shape[0], len(self.state_names), len(self.plant.output_names)
        X, Yc = np.full((G, self.N + 1, n), np.nan), np.full((G, self.N + 1, p), np.nan)
        for g in range(G):
            try:
                Xg, Ycg = plant_rows(self.plant, inputs, self.periods, self.N,
                                     self.x0s[g:g + 1])
                X[g], Yc[g] = Xg[0], Ycg[0]
            except LoopFailure as exc:
                self.failed[g] = f"simulation stopped at t={exc.t:g}: {exc.cause}"
        return X, Yc


class _Bucket:
    """Builds and runs the loop of some members of one bucket (any subset, any of its
    observers) on the chunk's plant rows."""

    def __init__(self, plants: _Plants, scenario: dict[str, Any]) -> None:
        self.p, self.scenario = plants, scenario
        self.kw = scenario_run(scenario)

    def run(self, members: list[int], names: list[str], exact: bool) -> dict[str, Outcome]:
        p = self.p
        kw = scenario_run(self.scenario)  # fresh parts: a run may be repeated after a failure
        obs = {n: kw["observers"][n] for n in names}
        rows = p.member_rows[members]
        plant = ReplayPlant(p.plant, p.X, p.Yc, rows)
        loop = Loop(plant, kw["sensor"], obs, p.periods, exact=exact)
        drive = Drive.of(kw["inputs"], obs, plant, p.periods)
        loop.reset(None, seed=[p.seeds[i] for i in members], batch=len(members))
        acc = {name: Metrics(ob, p.state_names, len(members), p.periods.sample,
                             p.t_transient, p.band[rows]) for name, ob in obs.items()}
        prev = {name: (x, z) for name, (x, z, _) in loop.estimates().items()}
        while loop.k < p.N:
            k0, T = loop.k, drive.length(loop.k, p.N, segment_length(len(members)))
            seg = loop.segment(drive.inputs(loop, T))
            for name, blk in seg.blocks.items():
                acc[name].add(k0, seg.x, prev[name], blk.x_hat, blk.z_hat)
                # copies: the loop (exact=False) writes the next segment into the same block
                prev[name] = (blk.x_hat[:, -1].copy(), blk.z_hat[:, -1].copy())
        Xl = np.reshape(plant.state, (len(members), 1, -1))
        return _finish(loop, acc, p.N, Xl)

    def failed(self, B: int, name: str, msg: str) -> Outcome:
        return _failed(len(self.p.state_names), self.kw["observers"][name], B, msg)


class _ClosedBucket:
    """The members of one closed-loop bucket: B plants, B sensor streams, every observer and
    the controller stepped together on the loop, one control period a segment; the plants'
    range (for the band), the closed loop's cost and peak input accumulated as they come."""

    def __init__(self, chunk: Chunk, scenario: dict[str, Any], idxs: list[int]) -> None:
        self.scenario = scenario
        self.kw = scenario_run(scenario)
        plant: Plant = self.kw["plant"]
        self.periods = Periods.of(plant, self.kw["sample_period"], self.kw["control_period"])
        self.N = int(round(float(self.kw["duration"]) / self.periods.sample))
        self.state_names = tuple(plant.state_names)
        x0s, rows = _x0_rows(chunk.scenarios, chunk.members, plant)
        self.x0 = {i: x0s[rows[i]] for i in idxs}
        self.seeds = {i: chunk.members[i][1] for i in idxs}
        mkw = chunk.metric_kw
        tt = mkw.get("t_transient")
        self.t_transient = 0.2 * (self.N * self.periods.sample) if tt is None else float(tt)
        self.band, self.relative = float(mkw.get("band", 0.05)), bool(mkw.get("relative", True))

    def run(self, members: list[int], names: list[str], exact: bool) -> dict[str, Outcome]:
        kw = scenario_run(self.scenario)
        obs, law = kw["observers"], kw["inputs"]
        loop = Loop(kw["plant"], kw["sensor"], obs, self.periods, exact=exact)
        drive = Drive.of(law, obs, kw["plant"], self.periods)
        B, Ts = len(members), self.periods.sample
        loop.reset(np.array([self.x0[i] for i in members]), seed=[self.seeds[i] for i in members],
                   batch=B)
        acc = {name: Metrics(ob, self.state_names, B, Ts, self.t_transient, None, self.N + 1)
               for name, ob in obs.items()}
        prev = {name: (x, z) for name, (x, z, _) in loop.estimates().items()}
        n = len(self.state_names)
        lo, hi = np.full((B, n), np.inf), np.full((B, n), -np.inf)
        cost, peak_u = np.zeros(B), np.zeros(B)

        def account(X: Array, U: Array) -> None:
            nonlocal lo, hi, cost, peak_u
            lo, hi = np.minimum(lo, X.min(axis=1)), np.maximum(hi, X.max(axis=1))
            cost += (np.einsum("bti,ij,btj->b", X, law.Q, X)
                     + np.einsum("bti,ij,btj->b", U, law.R, U))
            peak_u = np.maximum(peak_u, np.abs(U).max(axis=(1, 2)))

        while loop.k < self.N:
            k0, T = loop.k, drive.length(loop.k, self.N, SEGMENT)
            seg = loop.segment(drive.inputs(loop, T))
            for name, blk in seg.blocks.items():
                acc[name].add(k0, seg.x, prev[name], blk.x_hat, blk.z_hat)
                prev[name] = (blk.x_hat[:, -1].copy(), blk.z_hat[:, -1].copy())
            account(seg.x, seg.u)
        Xl = loop.sample()[0]
        account(Xl, drive.inputs(loop, 1))
        scale = np.where(hi - lo > 0, hi - lo, 1.0) if self.relative else np.ones((B, n))
        return _finish(loop, acc, self.N, Xl, band=self.band * scale,
                       run={"cost": Ts * cost, "peak_input": peak_u})

    def failed(self, B: int, name: str, msg: str) -> Outcome:
        return _failed(len(self.state_names), self.kw["observers"][name], B, msg)


def _closed(build: _ClosedBucket, members: list[int], names: list[str], exact: bool = False
            ) -> dict[str, Outcome]:
    """A closed loop's members, failures isolated by bisection: the observers share the run
    (the controller acts on one of them), so a member whose run fails is a failed run of every
    observer, with the message of :func:`~hgo_mj.simulate.simulate`."""
    try:
        return build.run(members, names, exact)
    except LoopFailure as failure:
        if len(members) == 1:
            if not exact:
                return _closed(build, members, names, exact=True)
            cause = failure.cause
            msg = (f"simulation stopped at t={failure.t:g}: {cause}" if failure.observer is None
                   else f"observer {failure.observer!r} failed in its update at "
                        f"t={failure.t:g} (row {failure.row}): {type(cause).__name__}: {cause}")
            return {n: build.failed(1, n, msg) for n in names}
        half = len(members) // 2
        a, b = _closed(build, members[:half], names), _closed(build, members[half:], names)
        return {n: ({k: np.concatenate([a[n][0][k], b[n][0][k]]) for k in a[n][0]},
                    np.concatenate([a[n][1], b[n][1]]), a[n][2] + b[n][2]) for n in names}


def run_chunk(chunk: Chunk) -> list[dict[str, Any]]:
    """Run a chunk: its result rows, one per member x observer x plant state, each with
    ``cell``, ``seed``, ``observer``, ``state``, ``estimated``, the metrics (None: not
    estimated, or diverged), ``cost`` and ``peak_input`` (a closed loop's; None otherwise),
    ``diverged``, ``message`` and ``diag.<name>`` (each diagnostic's final value). An open
    loop's plant runs once for the chunk; each bucket in it runs its loop."""
    buckets: dict[str, list[int]] = {}
    for i, (cell, _) in enumerate(chunk.members):
        buckets.setdefault(_bucket_key(chunk.scenarios[cell]), []).append(i)
    first = chunk.scenarios[chunk.members[0][0]]
    if "controller" in first:
        return _run_closed(chunk, buckets)
    plants = _Plants(chunk)
    rows: list[dict[str, Any]] = []
    for idxs in buckets.values():
        b = _Bucket(plants, chunk.scenarios[chunk.members[idxs[0]][0]])
        ok = [i for i in idxs if int(plants.member_rows[i]) not in plants.failed]
        got = _observe(b, ok, list(b.kw["observers"]))
        pos = {i: j for j, i in enumerate(ok)}
        for name, ob in b.kw["observers"].items():
            for i in idxs:
                g = int(plants.member_rows[i])
                if g in plants.failed:
                    res, dg, msgs = b.failed(1, name, plants.failed[g])
                    j = 0
                else:
                    (res, dg, msgs), j = got[name], pos[i]
                rows.extend(_rows(chunk.members[i], name, ob, plants.state_names, res, dg[j],
                                  msgs[j], j))
    return rows


def _run_closed(chunk: Chunk, buckets: dict[str, list[int]]) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = []
    for idxs in buckets.values():
        b = _ClosedBucket(chunk, chunk.scenarios[chunk.members[idxs[0]][0]], idxs)
        names = list(b.kw["observers"])
        got = _closed(b, idxs, names)
        for name, ob in b.kw["observers"].items():
            res, dg, msgs = got[name]
            for j, i in enumerate(idxs):
                rows.extend(_rows(chunk.members[i], name, ob, b.state_names, res, dg[j],
                                  msgs[j], j))
    return rows


def _rows(member: tuple[int, int], name: str, ob: Observer, states: Sequence[str],
          res: dict[str, Array], diag: Array, message: str | None, j: int
          ) -> list[dict[str, Any]]:
    """The result rows of one member and observer, one per plant state."""
    own = set(ob.state_names)
    diverged = message is not None
    d = {f"diag.{n}": None if diverged else float(diag[q])
         for q, n in enumerate(ob.diagnostic_names)}
    out = []
    for s, state in enumerate(states):
        est = state in own
        row: dict[str, Any] = {"cell": member[0], "seed": member[1], "observer": name,
                               "state": state, "estimated": est}
        for m in METRICS:
            row[m] = float(res[m][j, s]) if est and (not diverged or m == "update_time") else None
        for m in RUN_METRICS:
            row[m] = float(res[m][j]) if m in res and not diverged else None
        row.update(diverged=diverged, message=message, **d)
        out.append(row)
    return out


#: the engine is driven by :class:`hgo_mj.study.Study` (``plan``, ``run``); its planning and
#: chunk-running functions are internal: public are the names of the result columns
__all__ = ["METRICS", "RUN_METRICS"]
