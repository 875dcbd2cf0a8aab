"""MuJoCo as the true plant."""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from .._validate import finite_scalar, integer_multiple, vector
from ..exceptions import DesignError, DivergenceError
from ..systems.base import System
from .base import Array, Plant

_mj_step = mujoco.mj_step

#: MuJoCo's mjMAXVAL: a larger control is zeroed with the warning mjWARN_BADCTRL
_MAX_CTRL = 1e10

_DIRECT_SENSORS = {
    int(mujoco.mjtSensor.mjSENS_JOINTPOS): "qpos",
    int(mujoco.mjtSensor.mjSENS_JOINTVEL): "qvel",
}


def model_path(name: str) -> Path:
    """Absolute path of an MJCF file shipped under ``models/`` (works from a wheel install)."""
    path = Path(str(resources.files("hgo_mj.models").joinpath(name)))
    if not path.is_file():
        shipped = sorted(p.name for p in Path(str(resources.files("hgo_mj.models"))).glob("*.xml"))
        raise DesignError(f"no MJCF model named {name!r}; shipped models: {shipped}")
    return path


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

    Notes
    -----
    ``jointpos``/``jointvel`` sensors are read straight from ``qpos``/``qvel`` (exactly what
    MuJoCo's sensor computes, without a second ``mj_forward``); other sensor types trigger
    ``mj_forward`` before ``sensordata`` is read.
    """

    def __init__(self, system: type[System], dt: float = 0.001, *, physics_dt: float | None = None,
                 outputs: Any = None, model_file: str | Path | None = None) -> None:
        if system.model_file is None:
            raise DesignError(f"{system.__name__} is not a MuJoCo system; use OdePlant")
        path = Path(model_file) if model_file is not None else model_path(system.model_file)
        self.model = mujoco.MjModel.from_xml_path(str(path))
        if physics_dt is not None:
            self.model.opt.timestep = finite_scalar("physics_dt", physics_dt, positive=True)
        self.physics_dt = float(self.model.opt.timestep)
        self.dt = finite_scalar("dt", dt, positive=True)
        self.substeps = integer_multiple("dt", self.dt, self.physics_dt, "physics_dt")
        self.data = mujoco.MjData(self.model)
        self.system = system.from_mjmodel(self.model)
        m = self.model

        def _id(kind: Any, name: str, what: str) -> int:
            i = mujoco.mj_name2id(m, kind, name)
            if i < 0:
                raise DesignError(f"{path.name} has no {what} named {name!r}")
            return i

        jids = [_id(mujoco.mjtObj.mjOBJ_JOINT, j, "joint") for j in system.joints]
        self._qadr = np.array([m.jnt_qposadr[j] for j in jids], dtype=np.intp)
        self._vadr = np.array([m.jnt_dofadr[j] for j in jids], dtype=np.intp)
        # contiguous joints (the usual case) are read with slices, cheaper than fancy indexing
        self._slices = None
        if np.all(np.diff(self._qadr) == 1) and np.all(np.diff(self._vadr) == 1):
            self._slices = (slice(int(self._qadr[0]), int(self._qadr[-1]) + 1),
                            slice(int(self._vadr[0]), int(self._vadr[-1]) + 1))
        self._aid = [_id(mujoco.mjtObj.mjOBJ_ACTUATOR, a, "actuator") for a in system.actuators]
        self._nq = len(jids)
        self._output_names = tuple(outputs) if outputs is not None else system.output_names
        self._sensor_src: list[tuple[str, int]] = []
        self._needs_forward = False
        for name in self._output_names:
            s = _id(mujoco.mjtObj.mjOBJ_SENSOR, name, "sensor")
            kind = _DIRECT_SENSORS.get(int(m.sensor_type[s]))
            if kind is not None and m.sensor_objtype[s] == mujoco.mjtObj.mjOBJ_JOINT:
                j = m.sensor_objid[s]
                adr = m.jnt_qposadr[j] if kind == "qpos" else m.jnt_dofadr[j]
                self._sensor_src.append((kind, int(adr)))
            else:
                self._sensor_src.append(("sensordata", int(m.sensor_adr[s])))
                self._needs_forward = True
        self._x0 = vector("system.default_x0", system.default_x0, 2 * self._nq)
        self.reset()

    @property
    def output_names(self) -> tuple[str, ...]:
        return self._output_names

    def reset(self, x0: Any = None) -> None:
        x0 = self._x0 if x0 is None else vector("x0", x0, 2 * self._nq)
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[self._qadr] = x0[: self._nq]
        d.qvel[self._vadr] = x0[self._nq:]
        mujoco.mj_forward(m, d)
        self._cache()

    def _cache(self) -> None:
        """What :meth:`step` and the ``*_list`` readers need, in one attribute each: MjData's
        arrays are views of buffers that live as long as the MjData (rebuilt after a copy)."""
        m, d = self.model, self.data
        w = mujoco.mjtWarning
        self._bad = tuple(d.warning[int(k)] for k in (w.mjWARN_BADQPOS, w.mjWARN_BADQVEL,
                                                       w.mjWARN_BADQACC))
        # a live view of the three counters (consecutive in mjtWarning: BADQPOS, BADQVEL, BADQACC)
        lo = int(w.mjWARN_BADQPOS)
        bad = d.warning.number[lo:int(w.mjWARN_BADQACC) + 1]
        # read through a memoryview (of the same memory): any() over it costs half of tolist()
        aid = tuple(self._aid)
        self._hot = (m, d, d.ctrl, aid, aid[0] if len(aid) == 1 else None, self.substeps,
                     memoryview(bad))
        #: state_list's sources, and whether the joints' slices are the whole qpos and qvel
        sl = self._slices
        self._read = (d.qpos, d.qvel, sl is not None and sl[0] == slice(0, m.nq)
                      and sl[1] == slice(0, m.nv))
        srcs = {"qpos": d.qpos, "qvel": d.qvel, "sensordata": d.sensordata}
        #: outputs_list's sources: (array, address) per output
        self._out = tuple((srcs[k], a) for k, a in self._sensor_src)

    def __getstate__(self) -> dict[str, Any]:
        """Copy or pickle without the cached views (they would be detached from the copy's
        MjData); :meth:`__setstate__` rebuilds them."""
        state = self.__dict__.copy()
        for key in ("_bad", "_hot", "_read", "_out"):
            state.pop(key, None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._cache()

    def step(self, u: Any) -> None:
        m, d, ctrl, aid, a0, substeps, bad = self._hot
        if a0 is not None:  # one actuator (the common case): no loop
            ui = float(u[0])
            if not -_MAX_CTRL < ui < _MAX_CTRL:  # also False for NaN
                raise self._bad_input(0, ui)
            ctrl[a0] = ui
        else:
            for i, a in enumerate(aid):
                ui = float(u[i])
                if not -_MAX_CTRL < ui < _MAX_CTRL:
                    raise self._bad_input(i, ui)
                ctrl[a] = ui
        _mj_step(m, d, substeps)  # the substeps in one call (MuJoCo loops over mj_step)
        if any(bad):
            # MuJoCo found NaN/inf/huge values and silently reset the simulation
            which = [n for n, w in zip(("QPOS", "QVEL", "QACC"), self._bad) if w.number]
            raise DivergenceError(f"MuJoCo found a non-finite or huge value near t={d.time:g} and "
                                  f"reset the simulation (mjWARN_BAD{which[0]}); input was "
                                  f"{[float(v) for v in u]}")

    @staticmethod
    def _bad_input(i: int, ui: float) -> DivergenceError:
        return DivergenceError(f"input u[{i}] must be finite and below {_MAX_CTRL:g} in "
                               f"magnitude (MuJoCo would zero it); found {ui}")

    #: :meth:`step` takes any sequence of floats, a list too
    step_list = step

    @property
    def t(self) -> float:  # type: ignore[override]
        return float(self.data.time)

    @property
    def state(self) -> Array:
        d = self.data
        if self._slices is not None:
            qs, vs = self._slices
            return np.concatenate((d.qpos[qs], d.qvel[vs]))
        x = np.empty(2 * self._nq)
        x[: self._nq] = d.qpos[self._qadr]
        x[self._nq:] = d.qvel[self._vadr]
        return x

    def outputs(self) -> Array:
        d = self.data
        if self._needs_forward:
            mujoco.mj_forward(self.model, d)
        srcs = {"qpos": d.qpos, "qvel": d.qvel, "sensordata": d.sensordata}
        return np.array([srcs[k][a] for k, a in self._sensor_src])

    def state_list(self) -> list[float]:
        """:attr:`state` as a list of Python floats, read without building an array."""
        qpos, qvel, whole = self._read
        if whole:
            return qpos.tolist() + qvel.tolist()  # type: ignore[no-any-return]
        if self._slices is not None:
            qs, vs = self._slices
            return qpos[qs].tolist() + qvel[vs].tolist()  # type: ignore[no-any-return]
        q, v = qpos.tolist(), qvel.tolist()
        return [q[a] for a in self._qadr.tolist()] + [v[a] for a in self._vadr.tolist()]

    def outputs_list(self) -> list[float]:
        """:meth:`outputs` as a list of Python floats, read without building an array."""
        if self._needs_forward:
            mujoco.mj_forward(self.model, self.data)
        out = self._out
        if len(out) == 1:  # one output: no comprehension
            src, a = out[0]
            return [src.item(a)]
        return [src.item(a) for src, a in out]
