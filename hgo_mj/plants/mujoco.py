"""MuJoCo as the true plant, for one member or a batch of B members.

Batched runs (:meth:`MujocoPlant.run`) step every member with ``mj_step``, through one of two
paths that give the same bits (both call ``mj_step`` on the same state; tested):

* a Python loop over the samples calling ``mj_step(m, d, steps * substeps)`` on the plant's one
  ``MjData`` (one member: a short block; B > 1 members are loaded into it one after the other:
  blocks of a single physics step, and models whose constraints use the solver's warm start);
* ``mujoco.rollout.Rollout(nthread=...)``: the whole block, every member, in MuJoCo's thread
  pool, the control held for ``steps * substeps`` physics steps. The state is read from the
  returned full physics state (``mjSTATE_FULLPHYSICS``: time, qpos, qvel, ...), position and
  velocity stage sensors from the returned ``sensordata`` (taken inside the first ``mj_step``
  of each sample, i.e. at the sample instant), acceleration-stage sensors by ``mj_forward`` at
  the sample instant with the control held before it (as :meth:`MujocoPlant.outputs` does).
  The rollout does not return ``qacc_warmstart``; it is used only by the constraint solver, so
  the rollout serves only models that cannot hold constraints (no joint or tendon limits,
  equality constraints, friction loss or possible contacts; or the warm start or constraints
  disabled): every shipped model. Long blocks are cut into chunks of bounded memory. The
  rollout stops a member at its first MuJoCo warning; such a member (seen as a time column
  that stops advancing or resets) is stepped again in the Python loop, which raises the
  :class:`DivergenceError` for a bad-state reset and otherwise gives what ``mj_step`` gives.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import mujoco
import mujoco.batch
import mujoco.rollout
import numpy as np
from numpy.typing import NDArray

from .._binding import Binding
from .._validate import finite_scalar, integer_multiple, vector
from ..exceptions import DesignError, DimensionError, DivergenceError
from ..systems.base import System
from .base import Array, Plant, check_block, divergence, initial_states

_mj_step = mujoco.mj_step
_FULL = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
#: a block of one member with fewer physics steps runs in the Python loop (the rollout's fixed
#: cost is about that of this many loop samples; measured in scripts/bench_batch.py)
_ROLLOUT_MIN_STEPS = 64
#: doubles in the rollout's buffers (controls, states, sensors) per chunk: 32 MiB
_CHUNK_DOUBLES = 1 << 22

#: MuJoCo's mjMAXVAL: a larger control is zeroed with the warning mjWARN_BADCTRL (a larger
#: position or velocity resets the data with mjWARN_BADQPOS / mjWARN_BADQVEL)
_MAX_CTRL = 1e10
#: a state of at most this many entries is recorded entry by entry (else by slices)
_SCALAR_STATE = 8

_DIRECT_SENSORS = {
    int(mujoco.mjtSensor.mjSENS_JOINTPOS): "qpos",
    int(mujoco.mjtSensor.mjSENS_JOINTVEL): "qvel",
}


__all__ = ["MujocoPlant"]


def _constraint_free(m: Any) -> bool:
    """Whether the model can never hold a constraint that the solver's warm start affects
    (then a state without ``qacc_warmstart`` continues exactly)."""
    flags, d = int(m.opt.disableflags), mujoco.mjtDisableBit
    if flags & (int(d.mjDSBL_CONSTRAINT) | int(d.mjDSBL_WARMSTART)):
        return True
    limits = not flags & int(d.mjDSBL_LIMIT) and (bool(np.any(m.jnt_limited))
                                                  or bool(np.any(m.tendon_limited)))
    equality = not flags & int(d.mjDSBL_EQUALITY) and m.neq > 0
    friction = not flags & int(d.mjDSBL_FRICTIONLOSS) and (
        bool(np.any(m.dof_frictionloss)) or bool(np.any(m.tendon_frictionloss)))
    contype = int(np.bitwise_or.reduce(m.geom_contype)) if m.ngeom else 0
    conaff = int(np.bitwise_or.reduce(m.geom_conaffinity)) if m.ngeom else 0
    contact = not flags & int(d.mjDSBL_CONTACT) and (
        m.npair > 0 or getattr(m, "nflex", 0) > 0 or (contype & conaff) != 0)
    return not (limits or equality or friction or contact)


def _usable(U: Array) -> bool:
    """Whether every input of ``U`` ``(B, T, m)`` is finite and below ``mjMAXVAL`` (MuJoCo
    zeroes any other)."""
    return bool(-_MAX_CTRL < U.item() < _MAX_CTRL if U.size == 1 else  # one input, one sample
                U.size == 0 or float(np.abs(U).max()) < _MAX_CTRL)


def _as_slice(idx: NDArray[np.intp]) -> Any:
    """``idx`` as a slice where its entries are consecutive (a batch's state rows are read and
    written at every short block: a slice's copies cost less than an index array's), else
    ``idx``.

    Examples
    --------
    >>> _as_slice(np.array([3, 4, 5])), _as_slice(np.array([1, 3])).tolist()
    (slice(3, 6, None), [1, 3])
    """
    if idx.size and np.array_equal(idx, np.arange(idx[0], idx[0] + idx.size)):
        return slice(int(idx[0]), int(idx[0]) + idx.size)
    return idx


def _earliest(fails: list[tuple[int, int, float, str]], X: Array, Yc: Array) -> DivergenceError:
    """The :class:`DivergenceError` of the earliest of ``fails`` ((sample, member, time,
    message) each), the rows of ``X`` and ``Yc`` after it NaN."""
    j, b, t, msg = min(fails)
    X[:, j + 1:] = np.nan  # nothing recorded after the earliest failure
    Yc[:, j + 1:] = np.nan
    return divergence(f"member {b} at t={t:g}: {msg}", b, t, j + 1, X, Yc)


class MujocoPlant(Plant):
    """An MJCF model simulated by MuJoCo, with the state and outputs of a :class:`System`.

    Parameters
    ----------
    system : type[System]
        A MuJoCo system class (``model_file`` set); its parameters are read from the compiled
        model with ``from_mjmodel``.
    dt : float
        Control period: ``step(u)`` holds ``u`` for ``dt`` and runs ``dt / physics_dt`` MuJoCo
        steps. Must be a multiple of ``physics_dt``.
    physics_dt : float, optional
        MuJoCo timestep; default: the MJCF's ``<option timestep>``.
    outputs : sequence of str, optional
        MJCF sensor names to return from :meth:`outputs`; default ``system.output_names``.
    model_file : str or Path, optional
        Another MJCF file for the same system (e.g. a modified copy); default the shipped one.
    nthread : int, optional
        Threads of the batched rollout (``mujoco.rollout.Rollout``); default
        ``min(2, os.cpu_count())``.
    model_fields : mapping, optional
        Values written into the compiled model before anything else, ``"field[element]"`` ->
        value (:mod:`hgo_mj.plants.fields`), e.g. ``{"dof_frictionloss[hinge]": 0.02}``: Coulomb
        friction the system's equations (and so the observers' model) do not have.

    Notes
    -----
    ``jointpos``/``jointvel`` sensors are read straight from ``qpos``/``qvel`` (exactly what
    MuJoCo's sensor computes, without a second ``mj_forward``); other sensor types trigger
    ``mj_forward`` before ``sensordata`` is read.

    Examples
    --------
    >>> from hgo_mj.systems import SYSTEMS
    >>> plant = MujocoPlant(SYSTEMS["pendulum"], dt=0.01)
    >>> plant.reset([0.5, 0.0])
    >>> plant.step([0.0])
    >>> plant.state.shape, plant.outputs().shape, bool(plant.state[0] < 0.5)
    ((2,), (1,), True)
    """

    def __init__(self, system: type[System], dt: float = 0.001, *, physics_dt: float | None = None,
                 outputs: Any = None, model_file: str | Path | None = None,
                 nthread: int | None = None, model_fields: Any = None) -> None:
        if system.model_file is None:
            raise DesignError(f"{system.__name__} is not a MuJoCo system; use OdePlant")
        path = Path(model_file) if model_file is not None else Path(system.model_file)
        self.model = (mujoco.MjModel.from_xml_path(str(path)) if model_file is not None
                      else system.load_model())
        if model_fields:
            from .fields import set_fields

            set_fields(self.model, model_fields)
        if physics_dt is not None:
            self.model.opt.timestep = finite_scalar("physics_dt", physics_dt, positive=True)
        self.physics_dt = float(self.model.opt.timestep)
        self.dt = finite_scalar("dt", dt, positive=True)
        self.substeps = integer_multiple("dt", self.dt, self.physics_dt, "physics_dt")
        self.data = mujoco.MjData(self.model)
        self.system = system.from_mjmodel(self.model)
        m = self.model
        #: the model's names bound to ids and addresses (the one binding)
        self.binding = names = Binding(m, path.name)
        self._qadr, self._vadr = names.qpos(system.joints), names.dofs(system.joints)
        # contiguous joints (the usual case) are read with slices, cheaper than fancy indexing
        self._slices = None
        if np.all(np.diff(self._qadr) == 1) and np.all(np.diff(self._vadr) == 1):
            self._slices = (slice(int(self._qadr[0]), int(self._qadr[-1]) + 1),
                            slice(int(self._vadr[0]), int(self._vadr[-1]) + 1))
        self._aid = names.ids("actuator", system.actuators).tolist()
        self._nq = len(system.joints)
        if outputs is not None and (not isinstance(outputs, (list, tuple))
                                    or not all(isinstance(o, str) for o in outputs)):
            raise DesignError(f"outputs must be a list of sensor names; found {outputs!r:.60}")
        self._output_names = tuple(outputs) if outputs is not None else system.output_names
        self._sensor_src: list[tuple[str, int]] = []
        self._needs_forward = False
        for name in self._output_names:
            s, _ = names.sensor(name)
            kind = _DIRECT_SENSORS.get(int(m.sensor_type[s]))
            if kind is not None and m.sensor_objtype[s] == mujoco.mjtObj.mjOBJ_JOINT:
                j = m.sensor_objid[s]
                adr = m.jnt_qposadr[j] if kind == "qpos" else m.jnt_dofadr[j]
                self._sensor_src.append((kind, int(adr)))
            else:
                self._sensor_src.append(("sensordata", names.sensordata(name)))
                self._needs_forward = True
        self._x0 = vector("system.default_x0", system.default_x0, 2 * self._nq)
        if nthread is None:
            nthread = min(2, os.cpu_count() or 1)
        if isinstance(nthread, bool) or not isinstance(nthread, (int, np.integer)) or nthread < 1:
            raise DesignError(f"nthread must be a positive integer; found {nthread!r}")
        self.nthread = int(nthread)
        self._aid_arr = np.array(self._aid, dtype=np.intp)
        self._batch_layout()
        #: the one actuator's ctrl index (-1: several, set through ``_aid_arr``)
        self._a0 = int(self._aid[0]) if len(self._aid) == 1 else -1
        self._rollout: Any = None
        self._rdata: list[Any] = []
        self._mjbatch: Any = None
        self._cache()
        self.reset()

    def _batch_layout(self) -> None:
        """The batched paths' addresses, looked up once: in the full physics state (time
        first, then qpos and qvel), in ``sensordata``, and which sensors need the
        acceleration stage."""
        m = self.model
        self._nstate = int(mujoco.mj_stateSize(m, _FULL))
        self._sq = 1 + self._qadr
        self._sv = 1 + m.nq + self._vadr
        self._rollout_ok = _constraint_free(m)
        acc = int(mujoco.mjtStage.mjSTAGE_ACC)
        #: per output: ("state", column in the full state) | ("sensor", sensordata address) |
        #: ("acc", sensordata address)
        self._batch_src: list[tuple[str, int]] = []
        for name, (kind, a) in zip(self._output_names, self._sensor_src):
            if kind == "qpos":
                self._batch_src.append(("state", 1 + a))
            elif kind == "qvel":
                self._batch_src.append(("state", 1 + m.nq + a))
            else:
                s = self.binding.sensor(name)[0]
                stage = "acc" if int(m.sensor_needstage[s]) >= acc else "sensor"
                self._batch_src.append((stage, a))
        self._batch_map = self._batch_mapping() if self._rollout_ok else None
        #: the outputs' columns in the full physics state where every output is a joint's
        #: position or velocity (read from a batch's states at once); else None
        self._state_cols = (np.array([a for _, a in self._batch_src], dtype=np.intp)
                            if all(k == "state" for k, _ in self._batch_src) else None)

    def _batch_mapping(self) -> tuple[Any, Any, Any] | None:
        """Where the full physics state, the controls and the warm start lie in a
        ``mujoco.batch`` state row (``mjSTATE_INTEGRATION``), found by writing distinct
        values and reading them back; None unless every output is a joint's position or
        velocity (the short-block path reads the outputs from the state rows)."""
        m = self.model
        if not all(k == "state" for k, _ in self._batch_src):
            return None
        d = mujoco.MjData(m)
        full = np.arange(1.0, self._nstate + 1.0)
        mujoco.mj_setState(m, d, full, _FULL)
        d.ctrl[:] = -np.arange(1.0, m.nu + 1.0)
        d.qacc_warmstart[:] = -1000.0 - np.arange(m.nv)
        row = np.empty(mujoco.mj_stateSize(m, int(mujoco.mjtState.mjSTATE_INTEGRATION)))
        mujoco.mj_getState(m, d, row, int(mujoco.mjtState.mjSTATE_INTEGRATION))

        def where(vals: Array) -> Any:
            return np.array([int(np.flatnonzero(row == v)[0]) for v in vals], dtype=np.intp)

        F, C, W = where(full), where(np.array(d.ctrl)), where(np.array(d.qacc_warmstart))
        ys = np.array([a for _, a in self._batch_src], dtype=np.intp)
        self._batch_cols = tuple(_as_slice(c) for c in (F[self._sq], F[self._sv], F[ys],
                                                         C[self._aid_arr]))
        w = mujoco.mjtWarning
        self._bad_lo, self._bad_hi = int(w.mjWARN_BADQPOS), int(w.mjWARN_BADQACC) + 1
        return _as_slice(F), _as_slice(C), _as_slice(W)

    @property
    def output_names(self) -> tuple[str, ...]:
        return self._output_names

    def reset(self, x0: Any = None, *, batch: int | None = None) -> None:
        """Time zero and the state ``x0`` (``(n,)`` for every member, or ``(B, n)``; default
        ``system.default_x0``), ``batch`` members (see :mod:`hgo_mj.plants.base`).

        One member lives in :attr:`data`; B > 1 members are kept as full physics states
        ``(B, nstate)`` with their controls, and are loaded into :attr:`data` to be read.

        Raises
        ------
        DesignError
            A state MuJoCo cannot take (an entry beyond its ``mjMAXVAL`` = 1e10, or one its
            ``mj_forward`` flags as a bad position, velocity or acceleration, which it would
            silently replace by its reset state): the entry is named with its value."""
        if batch is None and type(x0) is list and self._reset_floats(x0):
            return
        if x0 is not None and batch is None and np.ndim(x0) <= 1:
            # one state for one unbatched member, checked (a fresh finite (n,) array) once
            X0, self.batched = vector("x0", x0, 2 * self._nq).reshape(1, -1), False
        else:
            X0, self.batched = initial_states(x0, batch, self._x0, 2 * self._nq)
        big = np.argwhere(np.abs(X0) > _MAX_CTRL)
        if big.size:
            b, i = (int(v) for v in big[0])
            raise DesignError(f"x0{f'[{b}]' if X0.shape[0] > 1 else ''}: "
                              f"{self.state_names[i]} = {X0[b, i]:g} is a state MuJoCo cannot "
                              f"take (|entry| <= {_MAX_CTRL:g}, its mjMAXVAL)")
        self.batch = B = X0.shape[0]
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[self._qadr] = X0[0, : self._nq]
        d.qvel[self._vadr] = X0[0, self._nq:]
        mujoco.mj_forward(m, d)
        if any(w.number for w in self._bad):
            d.warning.number[:] = 0
            raise DesignError(f"x0 = {X0[0].tolist()} is a state MuJoCo cannot take: "
                              f"mj_forward flags a bad position, velocity or acceleration "
                              f"(and would reset it to zero)")
        if B > 1:
            # the members' full physics states: the reset one with their qpos and qvel
            # (mj_forward changes none of it), zero controls and warm starts
            s0 = np.empty(self._nstate)
            mujoco.mj_getState(m, d, s0, _FULL)
            self._S = np.repeat(s0[None], B, axis=0)
            self._S[:, self._sq] = X0[:, : self._nq]
            self._S[:, self._sv] = X0[:, self._nq:]
            self._C = np.zeros((B, m.nu))
            self._W = np.zeros((B, m.nv))
            self._mjbatch = None  # made again on the model as it is now

    def _reset_floats(self, x0: list[Any]) -> bool:
        """:meth:`reset` of one unbatched member from a list of Python floats (an
        environment's initial state), without arrays: each entry written into MjData's
        ``qpos``/``qvel`` where the state is short (:attr:`_xsrc`). False, with nothing done,
        where that does not apply or an entry is not a float within MuJoCo's ``mjMAXVAL``
        (NaN included): the checked path then gives the error."""
        src = self._xsrc
        if src is None or len(x0) != len(src):
            return False
        for v in x0:
            if type(v) is not float or not -_MAX_CTRL <= v <= _MAX_CTRL:
                return False
        m, d, _, bad = self._hot
        mujoco.mj_resetData(m, d)
        for (arr, a), v in zip(src, x0):
            arr[a] = v
        mujoco.mj_forward(m, d)
        if any(bad):
            return False  # the checked path resets again and names the bad state
        self.batch, self.batched = 1, False
        return True

    def reset_members(self, idx: Any, X0: Any) -> None:
        """Restart the members ``idx`` of a batch (B > 1) from the states ``X0``
        ``(len(idx), n)``, as :meth:`reset` starts a member (MuJoCo's reset data with that
        ``qpos`` and ``qvel``, zero controls and warm start); the others go on. The restarted
        members keep the batch's clock (``time`` in their physics state), so that the batch
        still runs as one rollout: no shipped model reads the time.

        Parameters
        ----------
        idx : sequence of int
            The members (rows of the batch) to restart.
        X0 : array_like, shape (len(idx), n)
            Their new states.

        Raises
        ------
        DesignError
            Not a batch of several members, or a state MuJoCo cannot take (see :meth:`reset`).
        DimensionError
            ``X0`` not one state per member.

        Examples
        --------
        >>> from hgo_mj.systems import SYSTEMS
        >>> plant = MujocoPlant(SYSTEMS["pendulum"], dt=0.01)
        >>> plant.reset([[0.1, 0.0], [0.2, 0.0]])
        >>> plant.step([[0.0], [0.0]])
        >>> plant.reset_members([1], [[0.5, 0.0]])
        >>> plant.state[1].tolist(), round(plant.t, 6)
        ([0.5, 0.0], 0.01)
        """
        if self.batch < 2:
            raise DesignError(f"reset_members needs a batch of several members; this plant has "
                              f"{self.batch} (use reset)")
        rows = [int(b) for b in idx]
        X0 = np.asarray(X0, dtype=np.float64)
        if X0.shape != (len(rows), 2 * self._nq):
            raise DimensionError(f"X0 must have shape ({len(rows)}, {2 * self._nq}); found "
                                 f"{X0.shape}")
        m, d = self.model, self.data
        s0 = np.empty(self._nstate)
        for b, x in zip(rows, X0):
            big = np.flatnonzero(~(np.abs(x) <= _MAX_CTRL))
            if big.size:
                i = int(big[0])
                raise DesignError(f"x0[{b}]: {self.state_names[i]} = {x[i]:g} is a state "
                                  f"MuJoCo cannot take (finite, |entry| <= {_MAX_CTRL:g})")
            mujoco.mj_resetData(m, d)
            d.qpos[self._qadr] = x[: self._nq]
            d.qvel[self._vadr] = x[self._nq:]
            mujoco.mj_forward(m, d)
            if any(w.number for w in self._bad):
                d.warning.number[:] = 0
                raise DesignError(f"x0[{b}] = {x.tolist()} is a state MuJoCo cannot take: "
                                  f"mj_forward flags a bad position, velocity or acceleration")
            mujoco.mj_getState(m, d, s0, _FULL)
            s0[0] = self._S[b, 0]
            self._S[b] = s0
            self._C[b] = 0.0
            self._W[b] = 0.0

    def _cache(self) -> None:
        """What :meth:`_run_loop` needs, in one attribute each: MjData's arrays are views of
        buffers that live as long as the MjData (made once, and again after a copy)."""
        m, d = self.model, self.data
        w = mujoco.mjtWarning
        self._bad = tuple(d.warning[int(k)] for k in (w.mjWARN_BADQPOS, w.mjWARN_BADQVEL,
                                                       w.mjWARN_BADQACC))
        # a live view of the three counters (consecutive in mjtWarning: BADQPOS, BADQVEL, BADQACC)
        lo = int(w.mjWARN_BADQPOS)
        bad = d.warning.number[lo:int(w.mjWARN_BADQACC) + 1]
        # read through a memoryview (of the same memory): any() over it costs half of tolist()
        self._hot = (m, d, d.ctrl, memoryview(bad))
        srcs = {"qpos": d.qpos, "qvel": d.qvel, "sensordata": d.sensordata}
        #: each output's (array, address), views of this MjData's buffers
        self._out = tuple((srcs[k], a) for k, a in self._sensor_src)
        #: each state entry's (array, address) where the state is short (one scalar copy each
        #: costs less than two slice copies up to about 8 entries); None: read by slices
        self._xsrc = (tuple([(d.qpos, int(a)) for a in self._qadr]
                            + [(d.qvel, int(a)) for a in self._vadr])
                      if 2 * self._nq <= _SCALAR_STATE else None)

    def __getstate__(self) -> dict[str, Any]:
        """Copy or pickle without the cached views (they would be detached from the copy's
        MjData); :meth:`__setstate__` rebuilds them."""
        state = self.__dict__.copy()
        for key in ("_bad", "_hot", "_out", "_xsrc"):
            state.pop(key, None)
        state["_rollout"], state["_rdata"] = None, []  # a thread pool: made again when needed
        state["_mjbatch"] = None
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._cache()

    @staticmethod
    def _bad_input(i: int, ui: float) -> DivergenceError:
        return DivergenceError(f"input u[{i}] must be finite and below {_MAX_CTRL:g} in "
                               f"magnitude (MuJoCo would zero it); found {ui}")

    @property
    def t(self) -> float:  # type: ignore[override]
        if self.batch > 1:
            return float(self._S[0, 0])
        return float(self.data.time)

    @property
    def state(self) -> Array:
        if self.batch > 1:
            return np.concatenate((self._S[:, self._sq], self._S[:, self._sv]), axis=1)
        if self.batched:
            return self._state1()[None]
        return self._state1()

    def _state1(self) -> Array:
        if self._xsrc is not None:
            return np.array([src.item(a) for src, a in self._xsrc])
        d = self.data
        if self._slices is not None:
            qs, vs = self._slices
            return np.concatenate((d.qpos[qs], d.qvel[vs]))
        x = np.empty(2 * self._nq)
        x[: self._nq] = d.qpos[self._qadr]
        x[self._nq:] = d.qvel[self._vadr]
        return x

    def outputs(self) -> Array:
        if self.batch > 1:
            cols = self._state_cols
            if cols is not None:  # every output a joint's position or velocity: the states
                return self._S[:, cols]
            out = np.empty((self.batch, len(self._output_names)))
            for b in range(self.batch):
                self._load(b)
                out[b] = self._outputs1()
            return out
        if self.batched:
            return self._outputs1()[None]
        return self._outputs1()

    def _outputs1(self) -> Array:
        if self._needs_forward:
            mujoco.mj_forward(self.model, self.data)
        return np.array([src.item(a) for src, a in self._out])

    # ------------------------------------------------------------------ batched paths
    def _load(self, b: int) -> None:
        """Put member ``b`` (B > 1) into :attr:`data`: its full physics state, controls and
        warm start; its warning counters start at zero."""
        if self.batch == 1:
            return
        m, d = self.model, self.data
        mujoco.mj_setState(m, d, self._S[b], _FULL)
        d.ctrl[:] = self._C[b]
        d.qacc_warmstart[:] = self._W[b]
        d.warning.number[:] = 0  # one view of the counters (a loop over the structs: 60 us)

    def _save(self, b: int) -> None:
        """Copy :attr:`data` back into member ``b`` (B > 1)."""
        if self.batch == 1:
            return
        m, d = self.model, self.data
        mujoco.mj_getState(m, d, self._S[b], _FULL)
        self._C[b] = d.ctrl
        self._W[b] = d.qacc_warmstart

    def run(self, U: Any, steps: int) -> tuple[Array, Array]:
        """Advance ``T`` samples of ``steps`` plant steps (``steps * substeps`` MuJoCo steps)
        for every member (see :meth:`Plant.run` and the module docstring for the two paths).

        Raises
        ------
        DivergenceError
            An input not finite or not below MuJoCo's ``mjMAXVAL`` (1e10) in magnitude
            (MuJoCo would zero it), or MuJoCo's reset of a non-finite or huge state; the
            message names the member and the sample time (the earliest failure of the block).
        """
        U, steps = check_block(U, steps, self.batch, len(self._aid))
        B, T, _ = U.shape
        X = np.empty((B, T, 2 * self._nq))
        Yc = np.empty((B, T, len(self._output_names)))
        if _usable(U):  # every input usable (usual)
            jbad, ok, bad = T, None, None
        else:                                             # NaN, inf or too large somewhere
            ok = np.abs(U) < _MAX_CTRL                    # False for NaN
            bad = ~np.all(ok, axis=2)
            jbad = int(np.argmax(bad.any(axis=0))) if bad.any() else T
        nstep = steps * self.substeps
        fails: list[tuple[int, int, float, str]] = []     # (sample, member, time, message)
        if jbad:
            if (B > 1 and self._batch_map is not None and jbad * nstep < _ROLLOUT_MIN_STEPS
                    and self._run_batch(U[:, :jbad], nstep, X, Yc)):
                pass  # a short block of a batch: mujoco.batch, done (no warning)
            elif self._rollout_ok and (B > 1 or jbad * nstep >= _ROLLOUT_MIN_STEPS):
                self._run_rollout(U[:, :jbad], nstep, X, Yc, fails)
            elif B == 1:  # one member lives in self.data
                self._run_loop(0, U[0] if jbad == T else U[0, :jbad], nstep, X[0], Yc[0], fails)
            else:
                for b in range(B):
                    self._load(b)
                    self._run_loop(b, U[b, :jbad], nstep, X[b], Yc[b], fails)
                    self._save(b)
        if not fails and jbad < T:
            b = int(np.argmax(bad[:, jbad]))  # type: ignore[index]
            i = int(np.argmax(~ok[b, jbad]))  # type: ignore[index]
            self._record_now(X, Yc, jbad)
            t = self.t
            fails.append((jbad, b, t, str(self._bad_input(i, float(U[b, jbad, i])))))
        if fails:
            raise _earliest(fails, X, Yc)
        return X, Yc

    def bind_run(self, U: Array, steps: int, X: Array, Yc: Array) -> Any:
        """See :meth:`Plant.bind_run`: the one member in :attr:`data` through
        :meth:`_run_loop`, the path :meth:`run` takes for it; None where :meth:`run` would take
        another (several members, or a block long enough for ``mujoco.rollout``)."""
        T = U.shape[1]
        nstep = steps * self.substeps
        if self.batch != 1 or (self._rollout_ok and T * nstep >= _ROLLOUT_MIN_STEPS):
            return None
        U0, X0, Y0 = U[0], X[0], Yc[0]

        def run() -> bool:
            if not _usable(U):
                return False
            fails: list[tuple[int, int, float, str]] = []
            self._run_loop(0, U0, nstep, X0, Y0, fails)
            if fails:
                raise _earliest(fails, X.copy(), Yc.copy())
            return True

        return run

    def _record_now(self, X: Array, Yc: Array, j: int) -> None:
        """Record every member's current state and outputs as sample ``j``."""
        for b in range(self.batch):
            self._load(b)
            X[b, j] = self._state1()
            Yc[b, j] = self._outputs1()

    def _run_loop(self, b: int, U: Array, nstep: int, X: Array, Yc: Array,
                  fails: list[tuple[int, int, float, str]]) -> None:
        """Member ``b`` (loaded in :attr:`data`) through the samples of ``U`` ``(T, m)`` with
        ``mj_step``, recording into ``X`` ``(T, n)`` and ``Yc`` ``(T, p)``."""
        m, d, ctrl, bad = self._hot
        aid_arr, a0 = self._aid_arr, self._a0
        xsrc, out, forward = self._xsrc, self._out, self._needs_forward
        if xsrc is None:
            qpos, qvel = d.qpos, d.qvel
            qa, va, nq = self._qadr, self._vadr, self._nq
            if self._slices is not None:
                qa, va = self._slices  # type: ignore[assignment]  # contiguous joints: a view
        for j in range(U.shape[0]):
            if xsrc is not None:
                for c, (src, a) in enumerate(xsrc):
                    X[j, c] = src[a]
            else:
                X[j, :nq] = qpos[qa]
                X[j, nq:] = qvel[va]
            if forward:
                mujoco.mj_forward(m, d)
            for c, (src, a) in enumerate(out):
                Yc[j, c] = src[a]
            t = float(d.time)
            if a0 >= 0:
                ctrl[a0] = U[j, 0]
            else:
                ctrl[aid_arr] = U[j]
            _mj_step(m, d, nstep)
            if any(bad):
                which = [n for n, w in zip(("QPOS", "QVEL", "QACC"), self._bad) if w.number]
                fails.append((j, b, t, f"MuJoCo found a non-finite or huge value and reset the "
                                       f"simulation (mjWARN_BAD{which[0]}); input was "
                                       f"{U[j].tolist()}"))
                return

    def _run_batch(self, U: Array, nstep: int, X: Array, Yc: Array) -> bool:
        """A short block of every member (B > 1) through ``mujoco.batch.Batch``: one ``step``
        of ``nstep`` physics steps per sample on its thread pool, the state and the outputs
        (joint positions and velocities, :attr:`_state_cols`) read from its state rows at
        each sample instant. ``mj_step`` on the same state gives the same bits. False (and
        nothing changed) where a member raised a MuJoCo warning: the caller steps the block
        again on its other path, which reports it."""
        bt, (F, C, W) = self._mjbatch_pool()
        st = bt.state
        st[:, F] = self._S
        st[:, C] = self._C
        st[:, W] = self._W
        iq, iv, iy, ic = self._batch_cols
        nq = self._nq
        for j in range(U.shape[1]):
            X[:, j, :nq] = st[:, iq]
            X[:, j, nq:] = st[:, iv]
            Yc[:, j] = st[:, iy]
            st[:, ic] = U[:, j]
            bt.step(nstep=nstep)
        if bt.warning[:, self._bad_lo:self._bad_hi, 0].any():
            bt.warning[:] = 0
            return False
        self._S[:] = st[:, F]
        self._C[:] = st[:, C]
        self._W[:] = st[:, W]
        return True

    def _mjbatch_pool(self) -> tuple[Any, tuple[Any, Any, Any]]:
        """The ``mujoco.batch.Batch`` of this batch's size (made at the first short block
        after a reset, on the model as it is then) and where the full physics state, the
        controls and the warm start lie in its state rows."""
        if self._mjbatch is None or self._mjbatch.nsim != self.batch:
            self._mjbatch = mujoco.batch.Batch(self.model, self.batch, nthread=self.nthread)
        F, C, W = self._batch_map  # type: ignore[misc]
        return self._mjbatch, (F, C, W)

    def _rollout_pool(self) -> tuple[Any, list[Any]]:
        if self._rollout is None:
            self._rollout = mujoco.rollout.Rollout(nthread=self.nthread)
            self._rdata = [mujoco.MjData(self.model) for _ in range(self.nthread)]
        return self._rollout, self._rdata

    def _run_rollout(self, U: Array, nstep: int, X: Array, Yc: Array,
                     fails: list[tuple[int, int, float, str]]) -> None:
        """Every member through the samples of ``U`` ``(B, T, m)`` with
        ``mujoco.rollout``, in chunks of samples of bounded memory."""
        m = self.model
        B, T, _ = U.shape
        ns, nsd, nu = self._nstate, m.nsensordata, m.nu
        if B == 1:
            S0 = np.empty((1, ns))
            mujoco.mj_getState(m, self.data, S0[0], _FULL)
            C0 = np.array(self.data.ctrl, dtype=float)[None]
        else:
            S0, C0 = self._S.copy(), self._C.copy()
        if not np.all(S0[:, 0] == S0[0, 0]):
            raise DesignError("the members' clocks differ (a member failed before): reset the "
                              "plant")
        pool, datas = self._rollout_pool()
        models = [m] * B
        per_sample = B * nstep * (ns + nsd + nu)
        chunk = max(1, min(T, _CHUNK_DOUBLES // max(per_sample, 1)))
        h = float(m.opt.timestep)
        sq, sv, nq = self._sq, self._sv, self._nq
        uses_sd = any(k == "sensor" for k, _ in self._batch_src)
        acc = [(i, a) for i, (k, a) in enumerate(self._batch_src) if k == "acc"]
        broken = np.zeros(B, dtype=bool)
        for j0 in range(0, T, chunk):
            j1 = min(T, j0 + chunk)
            n = (j1 - j0) * nstep
            S0 = np.ascontiguousarray(S0)
            ctrl = np.repeat(C0[:, None, :], n, axis=1)
            ctrl[:, :, self._aid_arr] = np.repeat(U[:, j0:j1], nstep, axis=1)
            state = np.empty((B, n, ns))
            sens = np.empty((B, n, nsd)) if uses_sd else None
            # shapes and dtypes are made here: MuJoCo's own checks are skipped
            pool.rollout(models, datas, S0, ctrl, nstep=n, state=state, sensordata=sens,
                         skip_checks=True)
            # the sample instants: the chunk's initial state, then the end of each sample
            inst = np.concatenate((S0[:, None], state[:, nstep - 1:n - 1:nstep]), axis=1)
            X[:, j0:j1, :nq] = inst[:, :, sq]
            X[:, j0:j1, nq:] = inst[:, :, sv]
            for i, (kind, a) in enumerate(self._batch_src):
                if kind == "state":
                    Yc[:, j0:j1, i] = inst[:, :, a]
                elif kind == "sensor":
                    Yc[:, j0:j1, i] = sens[:, ::nstep, a]  # type: ignore[index]
            if acc:
                prev = np.concatenate((C0[:, None], ctrl[:, nstep - 1:n - 1:nstep]), axis=1)
                self._acc_outputs(inst, prev, acc, Yc[:, j0:j1])
            # a member the rollout stopped (a MuJoCo warning) has a time column that resets
            # or stops: step it again in the loop, from the chunk's start
            times = np.add.accumulate(np.concatenate(([S0[0, 0]], np.full(n, h))))[1:]
            stopped = np.flatnonzero(np.any(state[:, :, 0] != times, axis=1) & ~broken)
            for b in stopped.tolist():
                self._redo(b, S0[b], C0[b], U[b, j0:j1], nstep, X[b, j0:j1], Yc[b, j0:j1],
                           j0, fails, state[b, -1])
                broken[b] = any(f[1] == b for f in fails)
            S0 = state[:, -1].copy()
            C0 = ctrl[:, -1].copy()
        if B == 1:
            d = self.data
            mujoco.mj_setState(m, d, S0[0], _FULL)
            d.ctrl[:] = C0[0]
            mujoco.mj_forward(m, d)  # the derived quantities (poses, ...) of that state
        else:
            self._S[:] = S0
            self._C[:] = C0

    def _redo(self, b: int, s0: Array, c0: Array, U: Array, nstep: int, X: Array, Yc: Array,
              j0: int, fails: list[tuple[int, int, float, str]], end: Array) -> None:
        """Step member ``b`` of a chunk again with ``mj_step`` from its chunk start ``s0``
        (controls ``c0``), overwriting its records and its end state ``end``."""
        m, d = self.model, self.data
        if self.batch > 1:
            keep = (self._S[b].copy(), self._C[b].copy(), self._W[b].copy())
            self._S[b], self._C[b], self._W[b] = s0, c0, 0.0
            self._load(b)
        else:
            mujoco.mj_setState(m, d, s0, _FULL)
            d.ctrl[:] = c0
            d.warning.number[:] = 0
        before = len(fails)
        self._run_loop(b, U, nstep, X, Yc, fails)
        for k in range(before, len(fails)):
            j, bb, t, msg = fails[k]
            fails[k] = (j + j0, bb, t, msg)
        mujoco.mj_getState(m, d, end, _FULL)
        if self.batch > 1:
            self._S[b], self._C[b], self._W[b] = keep

    def _acc_outputs(self, inst: Array, prev: Array, acc: list[tuple[int, int]],
                     Yc: Array) -> None:
        """Acceleration-stage sensors at the sample instants ``inst`` ``(B, T, nstate)`` with
        the controls held before them ``prev`` ``(B, T, nu)``: ``mj_forward`` on :attr:`data`
        (what :meth:`outputs` does at a sample)."""
        m, d = self.model, self.data
        keep = np.empty(self._nstate)
        mujoco.mj_getState(m, d, keep, _FULL)
        keep_ctrl = np.array(d.ctrl)
        for b in range(inst.shape[0]):
            for j in range(inst.shape[1]):
                mujoco.mj_setState(m, d, inst[b, j], _FULL)
                d.ctrl[:] = prev[b, j]
                mujoco.mj_forward(m, d)
                for i, a in acc:
                    Yc[b, j, i] = d.sensordata[a]
        mujoco.mj_setState(m, d, keep, _FULL)
        d.ctrl[:] = keep_ctrl
