"""What a block of rows becomes in a recording: pure functions, numpy arrays in and out.

A :class:`~hgo_mj.record.Recorder` checks a block (:func:`check_block`), asks the functions
here which entities it fills and with which values (:func:`signal_series`,
:func:`diagnostic_series`), which rows of a piecewise-constant series to keep
(:func:`changes`) and which rows to pose in 3D (:func:`pose_rows`, :func:`pose_sets`), then
hands the answers to its row sink (:mod:`hgo_mj.record.sink`), the one place that talks to
rerun. Nothing here holds state or writes anything, so each answer is tested on its own.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..exceptions import DimensionError
from . import layout
from .layout import TRUE_ROOT, EstimateLayout

Array = NDArray[np.float64]
Steps = NDArray[np.int64]
Mask = NDArray[np.bool_]


@dataclass
class Block:
    """One checked block of ``T`` rows (:func:`check_block`).

    Attributes
    ----------
    t : ndarray, shape (T,)
        Simulated time of each row.
    steps : ndarray of int64, shape (T,)
        The ``step`` of each row.
    episode : int or None
        The ``episode`` timeline's value, or ``None`` (no episode timeline).
    x, y_clean, y_meas, u : ndarray
        True state ``(T, n)``, clean output ``(T, m)`` or ``None``, measured output
        ``(T, m)``, input ``(T, p)``.
    est : dict observer -> ndarray (T, k)
        The estimates given in this block.
    diag : dict observer -> dict key -> ndarray (T,)
        The diagnostics given in this block.
    extra : dict name -> ndarray (T,) or (T, k)
        Further series (reward, ...).

    Examples
    --------
    >>> import numpy as np
    >>> b = Block(np.zeros(2), np.arange(2), None, np.zeros((2, 2)), None, np.zeros((2, 1)),
    ...           np.zeros((2, 1)), {}, {}, {})
    >>> b.x.shape, b.episode
    ((2, 2), None)
    """

    t: Array
    steps: Steps
    episode: int | None
    x: Array
    y_clean: Array | None
    y_meas: Array
    u: Array
    est: dict[str, Array]
    diag: dict[str, dict[str, Array]]
    extra: dict[str, Array]


def as_columns(name: str, a: Any, rows: int, width: int | None = None) -> Array:
    """``a`` as a float array of shape ``(rows, width)`` (``(rows, n)`` when ``width`` is
    ``None``); a 1-D array is one column when ``width`` is 1.

    Parameters
    ----------
    name : str
        What ``a`` is, for the error message.
    a : array_like
        The values.
    rows : int
        The number of rows it must have.
    width : int, optional
        The number of columns it must have.

    Returns
    -------
    ndarray, shape (rows, width)
        ``a`` as float64.

    Raises
    ------
    DimensionError
        ``a`` has another shape.

    Examples
    --------
    >>> as_columns("u", [1.0, 2.0], 2, 1).shape
    (2, 1)
    >>> as_columns("x", [[1.0, 2.0]], 2)
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DimensionError: x must have shape (2, n); found (1, 2)
    """
    arr = np.asarray(a, dtype=float)
    if arr.ndim == 1 and width == 1:
        arr = arr.reshape(-1, 1)
    if arr.ndim != 2 or arr.shape[0] != rows or (width is not None and arr.shape[1] != width):
        want = f"({rows}, {width})" if width is not None else f"({rows}, n)"
        raise DimensionError(f"{name} must have shape {want}; found {arr.shape}")
    return arr


def as_series(name: str, v: Any, rows: int) -> Array:
    """``v`` as a flat float array of ``rows`` entries (a diagnostic).

    Parameters
    ----------
    name : str
        What ``v`` is, for the error message.
    v : array_like
        The values; any shape with ``rows`` entries.
    rows : int
        The number of entries it must have.

    Returns
    -------
    ndarray, shape (rows,)

    Raises
    ------
    DimensionError
        ``v`` has another number of entries.

    Examples
    --------
    >>> as_series("gain", [[1.0], [2.0]], 2).tolist()
    [1.0, 2.0]
    """
    a = np.asarray(v, dtype=float).reshape(-1)
    if a.size != rows:
        raise DimensionError(f"{name} must have {rows} rows; found {a.size}")
    return a


def as_steps(step: Any, rows: int, next_step: int) -> Steps:
    """The ``step`` of each of ``rows`` rows: ``step`` as an array, or counting from ``step``
    (an int), or from ``next_step`` (``step`` is ``None``).

    Parameters
    ----------
    step : array_like of int or int or None
        The steps, or the first one.
    rows : int
        The block's number of rows.
    next_step : int
        The first step when ``step`` is ``None`` (where the last block ended).

    Returns
    -------
    ndarray of int64, shape (rows,)

    Raises
    ------
    DimensionError
        An array ``step`` without ``rows`` entries.

    Examples
    --------
    >>> as_steps(None, 3, 10).tolist(), as_steps(5, 2, 10).tolist()
    ([10, 11, 12], [5, 6])
    """
    if step is None:
        return next_step + np.arange(rows, dtype=np.int64)
    if np.ndim(step) == 0:
        return int(step) + np.arange(rows, dtype=np.int64)
    steps = np.asarray(step, dtype=np.int64).reshape(-1)
    if steps.size != rows:
        raise DimensionError(f"step must have {rows} entries; found {steps.size}")
    return steps


def check_block(t: Array, x: Any, y_clean: Any, y_meas: Any, u: Any,
                est: Mapping[str, Any], names: Mapping[str, Sequence[str]],
                diag: Mapping[str, Mapping[str, Any]], extra: Mapping[str, Any],
                widths: tuple[int, int, int], steps: Steps,
                episode: int | None) -> Block:
    """Check the arrays of a block of ``T = t.size`` rows and return them as a :class:`Block`.

    Parameters
    ----------
    t : ndarray, shape (T,)
        The rows' simulated times.
    x, y_clean, y_meas, u : array_like
        True state, clean output (or ``None``), measured output, input.
    est : mapping observer -> array_like (T, k)
        Estimates, ``k`` the number of ``names[observer]``.
    names : mapping observer -> sequence of str
        Each observer's estimate column names.
    diag : mapping observer -> mapping key -> array_like (T,)
        Diagnostics (the keys to record).
    extra : mapping name -> array_like (T,) or (T, k)
        Further series.
    widths : (int, int, int)
        The numbers of states, outputs and inputs.
    steps : ndarray of int64, shape (T,)
        The rows' steps (:func:`as_steps`).
    episode : int or None
        The episode, or ``None``.

    Returns
    -------
    Block

    Raises
    ------
    DimensionError
        An array whose shape is not ``(T, width)`` of its names.

    Examples
    --------
    >>> import numpy as np
    >>> b = check_block(np.zeros(2), np.zeros((2, 2)), None, np.zeros((2, 1)),
    ...                 np.zeros(2), {"hgo": np.ones((2, 2))}, {"hgo": ("a", "b")},
    ...                 {"hgo": {"k": [40.0, 40.0]}}, {}, (2, 1, 1), np.arange(2), None)
    >>> b.u.shape, b.est["hgo"].shape, b.diag["hgo"]["k"].tolist()
    ((2, 1), (2, 2), [40.0, 40.0])
    """
    T = t.size
    n, m, p = widths
    x = as_columns("x", x, T, n)
    ym = as_columns("y_meas", y_meas, T, m)
    yc = None if y_clean is None else as_columns("y_clean", y_clean, T, m)
    u = as_columns("u", u, T, p)
    estimates = {}
    for o, a in est.items():
        arr = as_columns(f"estimate of {o!r}", a, T)
        if arr.shape[1] != len(names[o]):
            raise DimensionError(f"estimate of {o!r} must have shape ({T}, {len(names[o])}) "
                                 f"(columns {list(names[o])}); found {arr.shape}")
        estimates[o] = arr
    diagnostics = {o: {str(k): as_series(f"diagnostic {k!r} of {o!r}", v, T)
                       for k, v in d.items()} for o, d in diag.items()}
    extras = {str(k): np.asarray(v, dtype=float) for k, v in extra.items()}
    for name, v in extras.items():
        if v.ndim not in (1, 2) or v.shape[0] != T:
            raise DimensionError(f"extra {name!r} must have shape ({T},) or ({T}, k); found "
                                 f"{v.shape}")
    return Block(t, steps, episode, x, yc, ym, u, estimates, diagnostics, extras)


def signal_series(lay: EstimateLayout, b: Block, output_names: Sequence[str],
                  input_names: Sequence[str], extra_paths: Mapping[str, str]
                  ) -> list[tuple[str, Array, bool]]:
    """Every per-sample entity a block fills: ``(path, values, clock)``, one row a sample.

    Each plant state's truth and every observer's estimate of it, as the columns of one
    entity (an observer that gave no estimate in this block: NaN), its errors ``x - x_hat``
    likewise, the observers' own estimates, each output's clean (NaN without one) and
    measured values, the inputs and the extras. ``clock`` is True for the states, the
    entities that carry the ``step`` timeline besides ``sim_time`` (the others carry
    ``sim_time`` alone; :mod:`hgo_mj.record.recorder`).

    Parameters
    ----------
    lay : EstimateLayout
        Which estimate column goes where (:func:`hgo_mj.record.layout.estimate_layout`).
    b : Block
        The block.
    output_names, input_names : sequence of str
        Names of the columns of ``y`` and ``u``.
    extra_paths : mapping name -> str
        The entity path of each extra of the block.

    Returns
    -------
    list of (str, ndarray, bool)
        Entity path, values (shape ``(T,)``, or ``(T, k)`` for an entity of ``k`` series: a
        state with its estimates, errors, an output, an extra of ``k`` columns) and whether
        it carries the ``step`` timeline, in the order they are sent.

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.record.layout import estimate_layout
    >>> lay = estimate_layout(["angle"], ["hgo"], {"hgo": ["angle"]})
    >>> b = Block(np.zeros(2), np.arange(2), None, np.ones((2, 1)), None, np.ones((2, 1)),
    ...           np.zeros((2, 1)), {"hgo": np.full((2, 1), 0.75)}, {}, {})
    >>> for path, v, clock in signal_series(lay, b, ["angle"], ["torque"], {}):
    ...     print(path, v.tolist(), clock)
    /state/angle [[1.0, 0.75], [1.0, 0.75]] True
    /error/angle [[0.25], [0.25]] False
    /sensor/angle [[nan, 1.0], [nan, 1.0]] False
    /input/torque [0.0, 0.0] False
    """
    out: list[tuple[str, Array, bool]] = []
    nan = np.full(b.t.size, np.nan)
    for i, (s, ests) in enumerate(zip(lay.state_names, lay.est_of)):
        # an observer without an estimate in this block: NaN (and no ghost pose)
        est = [b.est[o][:, j] if o in b.est else nan for o, j in ests]
        out.append((layout.state_path(s), np.column_stack([b.x[:, i], *est]), True))
        if est:
            out.append((layout.error_path(s), b.x[:, i, None] - np.column_stack(est), False))
    for o, own in lay.own.items():
        if o in b.est:  # estimates that are not plant states: under the observer's names
            out += [(layout.own_estimate_path(o, name), b.est[o][:, j], False)
                    for name, j in own]
    for j, name in enumerate(output_names):
        clean = b.y_clean[:, j] if b.y_clean is not None else nan
        out.append((layout.sensor_path(name), np.column_stack((clean, b.y_meas[:, j])), False))
    out += [(layout.input_path(name), b.u[:, j], False) for j, name in enumerate(input_names)]
    out += [(extra_paths[name], v, False) for name, v in b.extra.items()]
    return out


def diagnostic_series(b: Block, paths: Mapping[tuple[str, str], tuple[str, str]],
                      params: Mapping[str, float]) -> dict[str, Array]:
    """The block's piecewise-constant series by entity path: each diagnostic, and the true
    value of a parameter next to an estimate of it.

    Parameters
    ----------
    b : Block
        The block.
    paths : mapping (observer, key) -> (path, kind)
        Entity path and kind of every diagnostic
        (:func:`hgo_mj.record.layout.diagnostic_path`).
    params : mapping name -> float
        The system's true parameters.

    Returns
    -------
    dict path -> ndarray (T,)
        The first diagnostic to claim a path keeps it.

    Examples
    --------
    >>> import numpy as np
    >>> b = Block(np.zeros(2), np.arange(2), None, np.zeros((2, 1)), None, np.zeros((2, 1)),
    ...           np.zeros((2, 1)), {}, {"a": {"theta_m": np.array([1.0, 1.5])}}, {})
    >>> paths = {("a", "theta_m"): ("/observer/a/theta/m", "theta")}
    >>> {p: v.tolist() for p, v in diagnostic_series(b, paths, {"m": 2.0}).items()}
    {'/observer/a/theta/m': [1.0, 1.5], '/plant/param/m': [2.0, 2.0]}
    """
    series: dict[str, Array] = {}
    for o, d in b.diag.items():
        for key, v in d.items():
            path, kind = paths[(o, key)]
            series.setdefault(path, v)
            p = layout.theta_param(path) if kind == "theta" else None
            if p is not None and p in params:
                series.setdefault(layout.param_path(p), np.full(b.t.size, params[p]))
    return series


def changes(v: Array, last: float | None, mark_end: bool
            ) -> tuple[Mask | None, float, bool]:
    """The rows of a piecewise-constant series to log: where it changes from the row before
    (from ``last``, the last value of the block before, for the first row), its first row
    ever (``last`` is ``None``), and its last row when ``mark_end``.

    Parameters
    ----------
    v : ndarray, shape (T,)
        The series in this block (NaN equals NaN).
    last : float or None
        The series' last value in the blocks before, ``None`` for its first block.
    mark_end : bool
        Keep the block's last row too.

    Returns
    -------
    keep : ndarray of bool or None
        The rows to log, ``None`` for none.
    last : float
        The series' last value (``v[-1]``), the next block's ``last``.
    pending : bool
        Whether the last row is not logged (it waits for the next block or the end, so that
        the line reaches it).

    Examples
    --------
    >>> import numpy as np
    >>> keep, last, pending = changes(np.array([1.0, 1.0, 2.0, 2.0]), None, False)
    >>> keep.tolist(), last, pending
    ([True, False, True, False], 2.0, True)
    >>> changes(np.array([2.0, 2.0]), 2.0, False)
    (None, 2.0, True)
    >>> changes(np.array([2.0, 2.0]), 2.0, True)[0].tolist()
    [False, True]
    """
    if last is not None and not mark_end:  # unchanged through the block
        same = np.isnan(v).all() if np.isnan(last) else bool((v == last).all())
        if same:
            return None, last, True
    prev = np.empty_like(v)
    prev[0] = np.nan if last is None else last
    prev[1:] = v[:-1]
    keep = ~((v == prev) | (np.isnan(v) & np.isnan(prev)))
    keep[0] |= last is None
    keep[-1] |= mark_end
    return (keep if keep.any() else None), float(v[-1]), not bool(keep[-1])


def pose_rows(t: Array, steps: Steps, pose_rate: float | None) -> Mask:
    """The rows to pose in 3D: those whose step is on the ``pose_rate`` grid (every
    ``round(1 / (pose_rate dt))``-th step, ``dt`` the median step of ``t``), and the last row
    (so that the 3D view ends where the block does); every row with ``pose_rate=None``.

    Parameters
    ----------
    t : ndarray, shape (T,)
        The block's times.
    steps : ndarray of int, shape (T,)
        The block's steps.
    pose_rate : float or None
        Poses per unit of simulated time.

    Returns
    -------
    ndarray of bool, shape (T,)

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(7) * 0.01
    >>> pose_rows(t, np.arange(7), 50.0).nonzero()[0].tolist()
    [0, 2, 4, 6]
    >>> pose_rows(t, np.arange(7), None).all()
    np.True_
    """
    if pose_rate is None or t.size < 2:
        return np.ones(t.size, dtype=bool)
    dt = float(np.median(np.diff(t)))
    stride = max(int(round(1.0 / (pose_rate * dt))), 1) if dt > 0 else 1
    sel = steps % stride == 0
    sel[-1] = True
    return sel


def pose_sets(lay: EstimateLayout, b: Block, posed: Sequence[str], njoints: int,
              sel: Mask) -> dict[str, Array]:
    """The joint positions to pose, by root entity: the truth's, and each posed observer's
    (a joint its estimate does not give, or gives as NaN, on the truth).

    Parameters
    ----------
    lay : EstimateLayout
        Which estimate column goes where.
    b : Block
        The block.
    posed : sequence of str
        The observers with a ghost in this block.
    njoints : int
        The number of joints (the first ``njoints`` states are their positions).
    sel : ndarray of bool, shape (T,)
        The rows to pose (:func:`pose_rows`).

    Returns
    -------
    dict root -> ndarray (rows, njoints)
        ``/world/true`` and ``/world/estimate/<observer>``.

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.record.layout import estimate_layout
    >>> lay = estimate_layout(["a", "b", "va", "vb"], ["o"], {"o": ["a", "va"]})
    >>> b = Block(np.zeros(1), np.arange(1), None, np.array([[1.0, 2.0, 0.0, 0.0]]), None,
    ...           np.zeros((1, 1)), np.zeros((1, 1)), {"o": np.array([[1.5, 0.0]])}, {}, {})
    >>> {r: q.tolist() for r, q in pose_sets(lay, b, ["o"], 2, np.ones(1, bool)).items()}
    {'/world/true': [[1.0, 2.0]], '/world/estimate/o': [[1.5, 2.0]]}
    """
    q_true = b.x[sel, :njoints]
    sets = {TRUE_ROOT: q_true}
    for o in posed:
        q = q_true.copy()
        for i, j in enumerate(lay.joint_columns(o, njoints)):
            if j is not None:
                q[:, i] = b.est[o][sel, j]
        bad = ~np.isfinite(q)
        q[bad] = q_true[bad]
        sets[layout.ghost_root(o)] = q
    return sets


__all__ = ["Block", "as_columns", "as_series", "as_steps", "changes", "check_block",
           "diagnostic_series", "pose_rows", "pose_sets", "signal_series"]
