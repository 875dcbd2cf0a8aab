"""Extended and unscented Kalman filters, continuous-discrete, with parameter augmentation.

The baselines the adaptive observers of papers 001-003 measure themselves against. The state
is the physical state of a :class:`~hgo_mj.systems.base.System` augmented with the
parameters named in ``estimate`` (constant, driven by a small random walk):

.. math::

    \\dot x = f(x, u, \\theta) + w_x, \\qquad \\dot\\theta = w_\\theta, \\qquad
    y_k = h(x(t_k)) + v_k, \\qquad
    E[w w^T] = Q\\,\\delta(t - s), \\quad E[v_k v_k^T] = R.

``update(y, u, dt)`` first corrects the prediction with ``y(t_k)`` (the measurement update),
then predicts to ``t_k + dt`` with ``u`` held (the time update), so that, as every observer of
the package, it returns the estimate of ``x(t_k + dt)`` and row ``k`` of a trajectory is the
prediction made before ``y(t_k)`` was seen.

**Time update** over ``substeps`` steps ``h``: the mean by RK4 (or Euler) of
:math:`f` with :math:`u` held; the covariance by
:math:`P \\leftarrow \\Phi P \\Phi^T + Q h` with :math:`\\Phi = T_4(hF)` (RK4: the degree-4
Taylor polynomial of :math:`e^{hF}`, which is exactly RK4's transition on a linear system) or
:math:`I + hF` (Euler), :math:`F = \\partial f/\\partial x` at the start of the step. On a
linear system the filter *is* the discrete Kalman filter of the RK4 (or Euler) discretization
(tested against a textbook Kalman filter, and against the exact discretization as
:math:`h \\to 0`).

**Jacobians**: analytic where the system provides ``jacobian(t, x, u, p)`` (and
``param_jacobian(t, x, u, p, names)`` for augmented parameters), else central finite
differences. The MuJoCo variants (:class:`MujocoExtendedKalmanFilter`,
:class:`MujocoUnscentedKalmanFilter`) use the MJCF itself as the model: the mean by stepping a
private ``MjData`` of a copy of the ``MjModel``, the EKF's transition matrix from
``mujoco.mjd_transitionFD``.

**Measurement update**: where the measured outputs are state components (all systems of the
package: ``y = x[j]``), :math:`H` is a selection, the EKF update is exact and the UKF's
unscented update reduces to the same formula (the unscented transform is exact for a linear
map), so both use it. Otherwise (a general :math:`h`) the EKF linearizes by finite
differences and the UKF uses sigma points.

**Speed.** Per-sample cost matters (``BENCHMARKS.md``): up to ``FAST_MAX`` augmented states
with a selection output and a diagonal :math:`R` the filters run in generated straight-line
float code (no small-array numpy); larger ones in numpy.

References
----------
.. [J70] A. H. Jazwinski, *Stochastic Processes and Filtering Theory*, Academic Press 1970,
   sec. 8.3 (continuous-discrete extended Kalman filter).
.. [JU97] S. J. Julier, J. K. Uhlmann, "A new extension of the Kalman filter to nonlinear
   systems", Proc. AeroSense 1997; [WM00] E. A. Wan, R. van der Merwe, "The unscented Kalman
   filter for nonlinear estimation", IEEE AS-SPCC 2000 (scaled sigma points, weights).
.. [S06] D. Simon, *Optimal State Estimation*, Wiley 2006, sec. 13.2 (parameter estimation by
   state augmentation).
.. [MJ] MuJoCo documentation, ``mjd_transitionFD`` (finite-differenced transition matrices).
"""

from __future__ import annotations

import copy
import functools
import math
import re
from collections.abc import Callable, Sequence
from typing import Any

import mujoco
import numpy as np

from .._validate import (
    finite_scalar,
    one_of,
    positive_definite,
    positive_int,
    positive_semidefinite,
    vector,
)
from ..exceptions import DesignError, DivergenceError
from ..systems.base import System
from ._adaptive import measured_channels
from .base import Array, Observer

__all__ = ["ExtendedKalmanFilter", "FAST_MAX", "MujocoExtendedKalmanFilter",
           "MujocoUnscentedKalmanFilter", "UnscentedKalmanFilter"]

METHODS = ("rk4", "euler")
JACOBIANS = ("auto", "analytic", "fd")
#: augmented dimension up to which the float code path is used
FAST_MAX = 6


def _as_array(f: Callable[..., Any], t: float, x: Any, u: Any, p: Any) -> Array:
    """``f(t, x, u, p)`` as a float array (for dynamics that return lists)."""
    return np.asarray(f(t, x, u, p), dtype=float)


def _central_differences(f: Callable[[Array], Array], x: Array, rows: int, cols: int) -> Array:
    """Central-difference Jacobian ``(rows, cols)`` of ``f`` at ``x`` in its first ``cols``
    components (relative step ``1e-6``)."""
    J = np.zeros((rows, cols))
    for j in range(cols):
        e = 1e-6 * max(1.0, abs(float(x[j])))
        xp, xm = x.copy(), x.copy()
        xp[j] += e
        xm[j] -= e
        J[:, j] = (f(xp) - f(xm)) / (2.0 * e)
    return J


def _taylor4(A: Array) -> Array:
    """``I + A + A^2/2 + A^3/6 + A^4/24`` (Horner)."""
    n = A.shape[0]
    eye = np.eye(n)
    B = eye + A / 4.0
    B = eye + (A @ B) / 3.0
    B = eye + (A @ B) / 2.0
    return eye + A @ B


def _probe_selection(output: Callable[[Array, Any], Array], params: Any, n: int,
                     channels: Sequence[int]) -> list[int] | None:
    """State index ``j`` with ``h_c(x) = x_j`` for each channel, or ``None`` if ``h`` is not a
    selection (probed at two random points)."""
    rng = np.random.default_rng(12345)
    xs = [rng.uniform(-2.0, 2.0, n) for _ in range(2)]
    ys = [np.asarray(output(x, params), dtype=float).reshape(-1) for x in xs]
    idx = []
    for c in channels:
        hit = [j for j in range(n) if all(y[c] == x[j] for x, y in zip(xs, ys))]
        if len(hit) != 1:
            return None
        idx.append(hit[0])
    return idx


# ======================================================================================
# models: the system's ODE, or the MJCF stepped by MuJoCo
# ======================================================================================


class SystemModel:
    """A :class:`System`'s ODE with the parameters ``estimate`` appended to the state.

    Parameters
    ----------
    system : System
        Gives ``dynamics``, ``output``, the known parameters and (optionally) the analytic
        ``jacobian`` / ``param_jacobian``.
    estimate : sequence of str
        Names of ``system.param_names`` to estimate by augmentation.
    jacobian : {"auto", "analytic", "fd"}
        ``auto``: analytic where the system provides it, else central finite differences.
    """

    kind = "system"

    def __init__(self, system: System, estimate: Sequence[str] = (), jacobian: str = "auto") -> None:
        if not isinstance(system, System):
            raise DesignError(f"system must be a System instance; found {type(system).__name__}")
        self.system = system
        self.names = tuple(str(e) for e in estimate)
        unknown = [e for e in self.names if e not in system.param_names]
        if unknown or len(set(self.names)) != len(self.names):
            raise DesignError(f"estimate must name distinct parameters of {type(system).__name__} "
                              f"{list(system.param_names)}; found {list(self.names)}")
        if jacobian not in JACOBIANS:
            raise DesignError(f"jacobian must be one of {list(JACOBIANS)}; found {jacobian!r}")
        has_x = callable(getattr(system, "jacobian", None))
        has_p = callable(getattr(system, "param_jacobian", None))
        if jacobian == "analytic" and (not has_x or (self.names and not has_p)):
            need = ["jacobian"] + (["param_jacobian"] if self.names else [])
            raise DesignError(f"jacobian='analytic' needs {type(system).__name__}.{' and .'.join(need)}"
                              f"(t, x, u, p{', names' if self.names else ''}); it has "
                              f"{[m for m in need if callable(getattr(system, m, None))] or 'none'}")
        self.analytic = jacobian != "fd" and has_x and (has_p or not self.names)
        self.n = len(system.state_names)
        self.q = len(self.names)
        self.N = self.n + self.q
        self.base = dict(system.params)
        self._dyn = system.dynamics
        self._out = system.output
        self.state_names = tuple(system.state_names)
        self.output_names = tuple(system.output_names)
        self.n_inputs = len(system.input_names)

    # --------------------------------------------------------------------- parameters
    def params(self, xa: Any) -> dict[str, float]:
        if not self.q:
            return self.base
        p = dict(self.base)
        n = self.n
        for j, nm in enumerate(self.names):
            p[nm] = float(xa[n + j])
        return p

    # --------------------------------------------------------------------- dynamics
    def deriv(self, xa: Array, u: Array) -> Array:
        """:math:`(f(x, u, \\theta), 0)`, shape (N,)."""
        fx = np.asarray(self._dyn(0.0, xa[:self.n], u, self.params(xa)), dtype=float)
        if self.q:
            return np.concatenate((fx, np.zeros(self.q)))
        return fx

    def jac(self, xa: Array, u: Array) -> Array:
        """:math:`\\partial (f, 0) / \\partial (x, \\theta)`, shape (N, N)."""
        n, N = self.n, self.N
        if self.analytic:
            p = self.params(xa)
            A = np.zeros((N, N))
            A[:n, :n] = self.system.jacobian(0.0, xa[:n], u, p)  # type: ignore[attr-defined]
            if self.q:
                A[:n, n:] = self.system.param_jacobian(0.0, xa[:n], u, p, self.names)  # type: ignore[attr-defined]
            return A
        return _central_differences(lambda z: self.deriv(z, u), xa, N, N)

    def step(self, xa: Array, u: Array, h: float, method: str) -> Array:
        """One RK4 (or Euler) step of ``h`` with ``u`` held."""
        d = self.deriv
        if method == "euler":
            return xa + h * d(xa, u)
        k1 = d(xa, u)
        k2 = d(xa + 0.5 * h * k1, u)
        k3 = d(xa + 0.5 * h * k2, u)
        k4 = d(xa + h * k3, u)
        return xa + (h / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)

    def transition(self, xa: Array, u: Array, h: float, method: str) -> tuple[Array, Array]:
        """``(x(t + h), Phi)`` with ``Phi = T4(h F)`` (rk4) or ``I + h F`` (euler)."""
        hF = h * self.jac(xa, u)
        Phi = _taylor4(hF) if method == "rk4" else np.eye(self.N) + hF
        return self.step(xa, u, h, method), Phi

    def output(self, xa: Array) -> Array:
        return np.asarray(self._out(xa[:self.n], self.params(xa)), dtype=float).reshape(-1)

    def selection(self, channels: Sequence[int]) -> list[int] | None:
        return _probe_selection(self._out, self.base, self.n, channels)


_ALIASES: dict[str, dict[str, str]] = {
    "Pendulum": {"gear": "actuator_gear[torque]", "damping": "dof_damping[hinge]",
                 "g": "opt.gravity"},
    "ElasticJoint": {"stiffness": "tendon_stiffness[spring]", "gear": "actuator_gear[torque]",
                     "link_damping": "dof_damping[link]", "motor_damping": "dof_damping[motor]",
                     "g": "opt.gravity"},
    "ElasticJoint2Link": {"stiffness1": "tendon_stiffness[spring1]",
                          "stiffness2": "tendon_stiffness[spring2]", "g": "opt.gravity"},
    "CartPendulum": {"g": "opt.gravity"},
}
_FIELDS = {"tendon_stiffness": mujoco.mjtObj.mjOBJ_TENDON,
           "actuator_gear": mujoco.mjtObj.mjOBJ_ACTUATOR,
           "dof_damping": mujoco.mjtObj.mjOBJ_JOINT,
           "dof_armature": mujoco.mjtObj.mjOBJ_JOINT,
           "body_mass": mujoco.mjtObj.mjOBJ_BODY}


class MujocoModel:
    """The MJCF as the filter's model: ``MjData`` stepping for the mean,
    ``mujoco.mjd_transitionFD`` for the transition matrix.

    Parameters
    ----------
    system : System
        Names the state (``joints``: ``qpos`` then ``qvel``), inputs (``actuators``) and
        outputs (``output`` must be a selection of the state).
    model : mujoco.MjModel, MujocoPlant or None
        The model (copied: the filter never touches the plant's); default the system's shipped
        MJCF. A deliberately wrong copy models a parameter error.
    estimate : sequence of str
        Parameters to estimate, each a model field ``"tendon_stiffness[spring]"``,
        ``"actuator_gear[torque]"``, ``"dof_damping[joint]"``, ``"dof_armature[joint]"``,
        ``"body_mass[body]"`` or ``"opt.gravity"`` (the magnitude :math:`g`; all gravity
        torques scale with it, so on the pendulum and the elastic joint it carries
        :math:`m g l` and :math:`MgL`), or a system parameter name with an alias (elastic joint:
        ``stiffness``, ``gear``, ``link_damping``, ``motor_damping``, ``g``).
    jacobian : {"transition_fd", "fd"}
        ``transition_fd``: ``mujoco.mjd_transitionFD`` (forward differences of one physics
        step). It refuses the RK4 integrator (``mjd_transitionFD: RK4 integrator is not
        supported`` in MuJoCo 4.0), so for an RK4 model it is evaluated on a twin model with
        the Euler integrator at the same timestep (the mean is still the RK4 step), and the
        continuous Jacobian recovered from its velocity rows gives RK4's transition
        :math:`T_4(hF)` (:meth:`_rk4_transition`; using the Euler twin's matrix as is was
        :math:`O(h^2 K/J)` off, enough to wreck the two-link arm's stiffness estimates).
        ``fd``: central differences of the model's own step (:math:`2N` steps). Parameter
        columns are always finite differences of the step.
    """

    kind = "mujoco"

    def __init__(self, system: System, model: Any = None, estimate: Sequence[str] = (),
                 jacobian: str = "transition_fd") -> None:
        from ..plants.mujoco import MujocoPlant, model_path

        if not isinstance(system, System):
            raise DesignError(f"system must be a System instance; found {type(system).__name__}")
        if system.model_file is None:
            raise DesignError(f"{type(system).__name__} is not a MuJoCo system (model_file is None); "
                              f"use the System-based filter")
        if model is None:
            model = mujoco.MjModel.from_xml_path(str(model_path(system.model_file)))
        elif isinstance(model, MujocoPlant):
            model = model.model
        if not isinstance(model, mujoco.MjModel):
            raise DesignError(f"model must be a mujoco.MjModel or a MujocoPlant; found "
                              f"{type(model).__name__}")
        if jacobian not in ("transition_fd", "fd"):
            raise DesignError(f"jacobian must be 'transition_fd' or 'fd'; found {jacobian!r}")
        self.jacobian_kind = jacobian
        self.system = system
        m = copy.deepcopy(model)
        self.m = m
        self.d = mujoco.MjData(m)
        self.ts = float(m.opt.timestep)
        joints = system.joints
        jids = []
        for j in joints:
            i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, j)
            if i < 0:
                raise DesignError(f"the model has no joint named {j!r} (needed by "
                                  f"{type(system).__name__})")
            jids.append(i)
        if m.nq != m.nv or m.nv != len(joints) or m.na != 0:
            raise DesignError(f"the MuJoCo filter needs a model whose only degrees of freedom are "
                              f"the hinge/slide joints {list(joints)} and no activations; found "
                              f"nq={m.nq}, nv={m.nv}, na={m.na}")
        self.qadr = np.array([m.jnt_qposadr[i] for i in jids], dtype=np.intp)
        self.vadr = np.array([m.jnt_dofadr[i] for i in jids], dtype=np.intp)
        nv = m.nv
        #: our state index -> index in MuJoCo's tangent state (dq, dv)
        self.perm = np.concatenate((self.vadr, nv + self.vadr))
        self.aid = []
        for a in system.actuators:
            i = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, a)
            if i < 0:
                raise DesignError(f"the model has no actuator named {a!r}")
            self.aid.append(int(i))
        self.n = 2 * len(joints)
        self.state_names = tuple(system.state_names)
        self.output_names = tuple(system.output_names)
        self.n_inputs = len(system.actuators)
        # parameters
        aliases = _ALIASES.get(type(system).__name__, {})
        self.names = tuple(str(e) for e in estimate)
        if len(set(self.names)) != len(self.names):
            raise DesignError(f"estimate must be distinct; found {list(self.names)}")
        self._specs = [self._resolve(aliases.get(e, e), e, aliases) for e in self.names]
        self.q = len(self.names)
        self.N = self.n + self.q
        self.twin = None
        if jacobian == "transition_fd":
            tw = copy.deepcopy(m)
            self._rk4 = tw.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
            if self._rk4:
                tw.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
            self.twin = tw
            self.dt_ = mujoco.MjData(tw)
            self._A = np.zeros((2 * nv, 2 * nv))
            self._M = np.zeros((nv, nv))
        self._last: list[tuple[float, ...] | None] = [None, None]  # stepping model, twin
        # our joint order -> MuJoCo's (the model has exactly these joints, checked above)
        self._sorted = bool(np.all(self.qadr == np.arange(nv)) and np.all(self.vadr == np.arange(nv)))
        self._inv_q = np.argsort(self.qadr)
        self._inv_v = np.argsort(self.vadr) + len(joints)
        self._pix = np.ix_(self.perm, self.perm)
        self._eyeN = np.eye(self.N)
        self._down = None
        g = np.array(m.opt.gravity, dtype=float)
        if np.linalg.norm(g) > 0:
            self._down = g / np.linalg.norm(g)

    def _resolve(self, spec: str, name: str, aliases: dict[str, str]) -> tuple[str, int]:
        m = self.m
        if spec == "opt.gravity":
            if not np.linalg.norm(m.opt.gravity) > 0:
                raise DesignError("estimating g needs a model with gravity")
            return ("gravity", 0)
        mt = re.fullmatch(r"(\w+)\[(\w+)\]", spec)
        if mt is None or mt.group(1) not in _FIELDS:
            raise DesignError(f"cannot estimate {name!r}: give a model field "
                              f"{sorted(_FIELDS)}[element name] or 'opt.gravity', or one of the "
                              f"aliases {sorted(aliases)}; found {spec!r}")
        field, elem = mt.group(1), mt.group(2)
        i = mujoco.mj_name2id(m, _FIELDS[field], elem)
        if i < 0:
            raise DesignError(f"cannot estimate {name!r}: the model has no "
                              f"{_FIELDS[field].name[6:].lower()} named {elem!r}")
        if field in ("dof_damping", "dof_armature"):
            i = int(m.jnt_dofadr[i])
        return (field, int(i))

    # --------------------------------------------------------------------- parameters
    def get_params(self) -> Array:
        out = np.zeros(self.q)
        for j, (field, i) in enumerate(self._specs):
            if field == "gravity":
                out[j] = float(np.linalg.norm(self.m.opt.gravity))
            elif field == "actuator_gear":
                out[j] = float(self.m.actuator_gear[i, 0])
            else:
                out[j] = float(getattr(self.m, field)[i])
        return out

    def _set_params(self, th: Sequence[float], twin: bool = False) -> None:
        """Write the parameter values into the stepping model (and the Jacobian twin); each
        model remembers what it holds, so an unchanged value costs a tuple comparison."""
        key = tuple(th.tolist()) if isinstance(th, np.ndarray) else tuple(map(float, th))
        targets = ((self.m, 0), (self.twin, 1)) if twin and self.twin is not None else ((self.m, 0),)
        for mm, slot in targets:
            if self._last[slot] == key:
                continue
            self._last[slot] = key
            for (field, i), v in zip(self._specs, key):
                if field == "gravity":
                    g = self._down * v
                    mm.opt.gravity[0], mm.opt.gravity[1], mm.opt.gravity[2] = g[0], g[1], g[2]
                elif field == "actuator_gear":
                    mm.actuator_gear[i, 0] = v
                else:
                    getattr(mm, field)[i] = v

    def _load(self, d: Any, x: Array, u: Array) -> None:
        nj = self.n // 2
        d.time = 0.0
        if self._sorted:
            d.qpos[:] = x[:nj]
            d.qvel[:] = x[nj:self.n]
        else:
            d.qpos[:] = x[self._inv_q]
            d.qvel[:] = x[self._inv_v]
        ctrl = d.ctrl
        for k, a in enumerate(self.aid):
            ctrl[a] = u[k]

    def _steps(self, h: float) -> int:
        k = round(h / self.ts)
        if k < 1 or abs(h / self.ts - k) > 1e-9 * max(1.0, h / self.ts):
            raise DesignError(f"the MuJoCo filter's step {h:g} must be a multiple of the model "
                              f"timestep {self.ts:g}")
        return int(k)

    def step(self, xa: Array, u: Array, h: float, method: str = "") -> Array:
        """MuJoCo's own step(s) over ``h`` from ``xa`` with ``u`` held."""
        if self.q:
            self._set_params(xa[self.n:])
        d = self.d
        self._load(d, xa, u)
        for _ in range(self._steps(h)):
            mujoco.mj_step(self.m, d)
        out = xa.copy()
        nj = self.n // 2
        out[:nj] = d.qpos[self.qadr]
        out[nj:self.n] = d.qvel[self.vadr]
        return out

    def transition(self, xa: Array, u: Array, h: float, method: str = "") -> tuple[Array, Array]:
        n = self.n
        k = self._steps(h)
        Phi = self._eyeN
        x = xa
        ts = self.ts
        for _ in range(k):
            if self.q:
                self._set_params(x[n:], twin=True)
            if self.twin is not None:
                self._load(self.dt_, x, u)
                if self._rk4:
                    mujoco.mj_forward(self.twin, self.dt_)  # the mass matrix at x
                mujoco.mjd_transitionFD(self.twin, self.dt_, 1e-6, False, self._A, None, None, None)
                Ax = self._A if self._rk4 else self._A[self._pix]
                if self._rk4:
                    Ax = self._rk4_transition(Ax, ts)[self._pix]
            else:
                Ax = _central_differences(lambda z: self.step(z, u, ts)[:n], x, n, n)
            x1 = self.step(x, u, ts)
            A = self._eyeN.copy()
            A[:n, :n] = Ax
            for j in range(self.q):
                e = 1e-6 * max(1.0, abs(float(x[n + j])))
                xp = x.copy()
                xp[n + j] += e
                A[:n, n + j] = (self.step(xp, u, ts)[:n] - x1[:n]) / e
            if self.q:
                self._set_params(x[n:])  # undo the perturbation
            Phi = A @ Phi
            x = x1
        return x, Phi

    def _rk4_transition(self, AE: Array, h: float) -> Array:
        """RK4's transition from the Euler twin's (MuJoCo's order, tangent space).

        MuJoCo's Euler step is semi-implicit and implicit in the joint damping :math:`D`:
        :math:`v^+ = v + h (M + hD)^{-1} f`, :math:`q^+ = q + h v^+`. Its velocity rows are
        :math:`G = h (M + hD)^{-1} \\partial f/\\partial x`, so the acceleration Jacobian is
        :math:`a_x = (I + h M^{-1} D)\\, G / h`, the continuous Jacobian
        :math:`F = [[0, I], [a_q, a_v]]` and :math:`\\Phi = T_4(hF)`, RK4's linearization (the
        twin's own position rows differ from RK4's by :math:`h^2 a_q / 2`, which matters for
        stiff springs)."""
        k = AE.shape[0] // 2
        d = self.dt_
        M = self._M
        mujoco.mj_fullM(self.twin, d, M)  # MuJoCo 4: mj_fullM(m, d, dst), after mj_forward
        G = AE[k:].copy()
        G[:, k:] -= np.eye(k)
        ax = (np.eye(k) + h * np.linalg.solve(M, np.diag(self.twin.dof_damping))) @ G / h
        F = np.zeros_like(AE)
        F[:k, k:] = np.eye(k)
        F[k:] = ax
        return _taylor4(h * F)

    def output(self, xa: Array) -> Array:
        return np.asarray(self.system.output(xa[:self.n], self.system.params), dtype=float).reshape(-1)

    def selection(self, channels: Sequence[int]) -> list[int] | None:
        return _probe_selection(self.system.output, self.system.params, self.n, channels)


# ======================================================================================
# generated float code for small filters
# ======================================================================================


def _gen(src: list[str], name: str) -> Callable[..., Any]:
    scope: dict[str, Any] = {}
    exec(compile("\n".join(src) + "\n", f"<kalman_{name}>", "exec"), scope)  # noqa: S102
    return scope[name]


def _gen_phi(N: int, method: str) -> Callable[[list[float], float], list[float]]:
    """``phi(A, h)``: the flat ``N x N`` transition ``T4(hA)`` or ``I + hA`` from flat ``A``."""
    src = ["def phi(A, h):", f"    ({', '.join(f'a{i}_{j}' for i in range(N) for j in range(N))},) = A"]
    for i in range(N):
        for j in range(N):
            src.append(f"    a{i}_{j} *= h")
    if method == "euler":
        out = [f"{'1.0 + ' if i == j else ''}a{i}_{j}" for i in range(N) for j in range(N)]
        src.append(f"    return [{', '.join(out)}]")
        return _gen(src, "phi")
    # Horner: B = I + A/4; B = I + A B/3; B = I + A B/2; Phi = I + A B
    for i in range(N):
        for j in range(N):
            src.append(f"    b{i}_{j} = {'1.0 + ' if i == j else ''}0.25*a{i}_{j}")
    for div, tgt in ((3.0, "c"), (2.0, "b"), (1.0, "c")):
        src_b = "b" if tgt == "c" else "c"
        for i in range(N):
            for j in range(N):
                prod = " + ".join(f"a{i}_{k}*{src_b}{k}_{j}" for k in range(N))
                lead = "1.0 + " if i == j else ""
                src.append(f"    {tgt}{i}_{j} = {lead}({prod})" + (f"*{1.0 / div!r}" if div != 1.0 else ""))
    src.append(f"    return [{', '.join(f'c{i}_{j}' for i in range(N) for j in range(N))}]")
    return _gen(src, "phi")


def _gen_propagate(N: int) -> Callable[[list[float], list[float], list[float]], list[float]]:
    """``prop(P, F, Q)``: flat symmetric ``F P F^T + Q``."""
    src = ["def prop(P, F, Q):",
           f"    ({', '.join(f'p{i}_{j}' for i in range(N) for j in range(N))},) = P",
           f"    ({', '.join(f'f{i}_{j}' for i in range(N) for j in range(N))},) = F"]
    for i in range(N):
        for j in range(N):
            src.append(f"    m{i}_{j} = " + " + ".join(f"f{i}_{k}*p{k}_{j}" for k in range(N)))
    for i in range(N):
        for j in range(i, N):
            src.append(f"    r{i}_{j} = " + " + ".join(f"m{i}_{k}*f{j}_{k}" for k in range(N))
                       + f" + Q[{i * N + j}]")
    src.append(f"    return [{', '.join(f'r{min(i, j)}_{max(i, j)}' for i in range(N) for j in range(N))}]")
    return _gen(src, "prop")


def _gen_correct(N: int, j: int) -> Callable[[list[float], list[float], float, float], None]:
    """``corr(x, P, y, r)``: in place, the scalar update with ``y = x[j] + v``, ``var v = r``."""
    src = ["def corr(x, P, y, r):",
           f"    s = P[{j * N + j}] + r",
           f"    e = (y - x[{j}]) / s"]
    for i in range(N):
        src.append(f"    k{i} = P[{i * N + j}]")
    for i in range(N):
        src.append(f"    x[{i}] += k{i}*e")
    src.append("    w = 1.0 / s")
    for i in range(N):
        for k in range(i, N):
            src.append(f"    P[{i * N + k}] -= k{i}*k{k}*w")
            if k != i:
                src.append(f"    P[{k * N + i}] = P[{i * N + k}]")
    return _gen(src, "corr")


def _gen_step(n: int, N: int, method: str, as_list: bool) -> Callable[..., list[float]]:
    """``step(x, u, h, dyn, p)``: one RK4 (or Euler) step of ``h`` of the augmented state
    (flat list; the parameters ``x[n:]`` are constant), calling ``dyn(0, x[:n], u, p)``."""
    xs = [f"x{i}" for i in range(N)]
    wrap = (lambda e: f"[{e}]") if as_list else (lambda e: f"array(({e},))")

    def call(args: list[str], out: str) -> str:
        lhs = ", ".join(f"{out}{i}" for i in range(n))
        return f"    ({lhs},) = dyn(0.0, {wrap(', '.join(args))}, u, p).tolist()"

    src = ["def step(x, u, h, dyn, p):", f"    ({', '.join(xs)},) = x", call(xs[:n], "a")]
    tail = xs[n:]
    if method == "euler":
        src.append(f"    return [{', '.join([f'x{i} + h*a{i}' for i in range(n)] + tail)}]")
    else:
        src.append("    hh = 0.5*h")
        src.append(call([f"x{i} + hh*a{i}" for i in range(n)], "b"))
        src.append(call([f"x{i} + hh*b{i}" for i in range(n)], "c"))
        src.append(call([f"x{i} + h*c{i}" for i in range(n)], "d"))
        src.append("    h6 = h/6.0")
        final = [f"x{i} + h6*(a{i} + 2.0*(b{i} + c{i}) + d{i})" for i in range(n)]
        src.append(f"    return [{', '.join(final + tail)}]")
    scope: dict[str, Any] = {"array": np.array}
    exec(compile("\n".join(src) + "\n", "<kalman_step>", "exec"), scope)  # noqa: S102
    return scope["step"]


def _gen_sigma(N: int) -> Callable[[list[float], list[float], float], list[list[float]] | None]:
    """``sigma(x, P, c)``: the ``2N + 1`` points ``x, x + c L_i, x - c L_i`` with ``L`` the
    Cholesky factor of flat ``P`` (straight-line); ``None`` if ``P`` is not positive definite."""
    src = ["def sigma(x, P, c):",
           f"    ({', '.join(f'p{i}_{j}' for i in range(N) for j in range(N))},) = P"]
    for j in range(N):
        acc = " - ".join([f"p{j}_{j}"] + [f"l{j}_{k}*l{j}_{k}" for k in range(j)])
        src.append(f"    d = {acc}")
        src.append("    if not d > 0.0:")
        src.append("        return None")
        src.append(f"    l{j}_{j} = sqrt(d)")
        for i in range(j + 1, N):
            acc = " - ".join([f"p{i}_{j}"] + [f"l{i}_{k}*l{j}_{k}" for k in range(j)])
            src.append(f"    l{i}_{j} = ({acc}) / l{j}_{j}")
    for i in range(N):
        for j in range(N):
            src.append(f"    s{i}_{j} = c*l{i}_{j}" if i >= j else f"    s{i}_{j} = 0.0")
    src.append(f"    ({', '.join(f'x{i}' for i in range(N))},) = x")
    pts = [f"[{', '.join(f'x{i}' for i in range(N))}]"]
    for sign in ("+", "-"):
        for j in range(N):
            pts.append(f"[{', '.join(f'x{i} {sign} s{i}_{j}' for i in range(N))}]")
    src.append(f"    return [{', '.join(pts)}]")
    scope: dict[str, Any] = {"sqrt": math.sqrt}
    exec(compile("\n".join(src) + "\n", "<kalman_sigma>", "exec"), scope)  # noqa: S102
    return scope["sigma"]


def _gen_moments(N: int, Wm: Array, Wc: Array) -> Callable[..., tuple[list[float], list[float]]]:
    """``mom(X, Q)``: weighted mean and flat covariance (plus flat ``Q``) of the points ``X``."""
    M = 2 * N + 1
    src = ["def mom(X, Q):"]
    for k in range(M):
        src.append(f"    ({', '.join(f'x{k}_{i}' for i in range(N))},) = X[{k}]")
    for i in range(N):
        terms = " + ".join(f"{float(Wm[k])!r}*x{k}_{i}" for k in range(M) if Wm[k] != 0.0)
        src.append(f"    m{i} = {terms}")
    for k in range(M):
        if Wc[k] != 0.0:
            for i in range(N):
                src.append(f"    e{k}_{i} = x{k}_{i} - m{i}")
    for i in range(N):
        for j in range(i, N):
            src.append(f"    c{i}_{j} = " + " + ".join(f"{float(Wc[k])!r}*e{k}_{i}*e{k}_{j}" for k in range(M)
                                                      if Wc[k] != 0.0) + f" + Q[{i * N + j}]")
    src.append(f"    return [{', '.join(f'm{i}' for i in range(N))}], "
               f"[{', '.join(f'c{min(i, j)}_{max(i, j)}' for i in range(N) for j in range(N))}]")
    return _gen(src, "mom")


# ======================================================================================
# the filters
# ======================================================================================


class _KalmanFilter(Observer):
    """Shared construction, validation, measurement update and bookkeeping (see module)."""

    backend = "system"

    def __init__(self, system: System | None = None, *, estimate: Sequence[str] = (),
                 Q: Any = 1e-4, Q_theta: Any = 1e-6, R: Any = None, sensor: Any = None,
                 P0: Any = 1.0, P0_theta: Any = 1.0, x_hat0: Any = None, theta_hat0: Any = None,
                 outputs: Any = None, method: str = "rk4", substeps: int = 1,
                 jacobian: str = "auto", model: Any = None) -> None:
        if system is None or not isinstance(system, System):
            raise DesignError(f"{type(self).__name__} needs a System; found "
                              f"{type(system).__name__}")
        if isinstance(estimate, str):
            estimate = (estimate,)
        if self.backend == "mujoco":
            jac = "transition_fd" if jacobian == "auto" else jacobian
            self.model = MujocoModel(system, model, estimate, jac)
        else:
            if model is not None:
                raise DesignError("model= is for the MuJoCo filters (ekf_mujoco, ukf_mujoco)")
            self.model = SystemModel(system, estimate, jacobian)
        mdl = self.model
        self.system = system
        self.n = mdl.n
        self.q = mdl.q
        self.N = mdl.N
        self.estimate = mdl.names
        self.method = one_of("method", method, METHODS)
        self.substeps = positive_int("substeps", substeps)
        n_out = len(system.output_names)
        chans = list(range(n_out)) if outputs is None else (
            [outputs] if np.ndim(outputs) == 0 else list(outputs))
        if (not chans or any(isinstance(c, bool) or int(c) != c or not 0 <= c < n_out for c in chans)
                or len(set(chans)) != len(chans)):
            raise DesignError(f"outputs must be distinct channel indices of "
                              f"{list(system.output_names)}; found {chans!r}")
        self.outputs = tuple(int(c) for c in chans)
        self.output = self.outputs[0]
        p = len(self.outputs)
        # covariances
        none = np.zeros((0, 0))
        self.Qc = self._augmented(positive_semidefinite("Q", Q, self.n), positive_semidefinite(
            "Q_theta", Q_theta, self.q) if self.q else none)
        if R is None:
            if sensor is not None:
                var = np.asarray(sensor.noise_variance(n_out), dtype=float)[list(self.outputs)]
                if not np.all(var > 0):
                    zero = [system.output_names[c] for c, v in zip(self.outputs, var) if not v > 0]
                    raise DesignError(f"R defaults to the sensor chain's noise variance, which is 0 "
                                      f"for channel(s) {zero}: R must be positive definite; give R=")
                R = var
            else:
                R = 1e-6
        self.R = positive_definite("R", R, p)
        self.P0 = self._augmented(positive_definite("P0", P0, self.n), positive_definite(
            "P0_theta", P0_theta, self.q) if self.q else none)
        if self.q and theta_hat0 is None:
            raise DesignError(f"theta_hat0 is required with estimate={list(self.estimate)} (the "
                              f"initial guess of the estimated parameters)")
        self.sel = mdl.selection(self.outputs)
        self._fast = False
        self._diag_R = bool(np.all(self.R == np.diag(np.diag(self.R))))
        self._r = np.diag(self.R).tolist()
        self.diagnostic_names = tuple(f"theta_{nm}" for nm in self.estimate)
        self._weights()
        self._u = np.zeros(mdl.n_inputs)
        self._init = (x_hat0, theta_hat0)
        self.reset(x_hat0, theta_hat0=theta_hat0)

    def _augmented(self, state: Array, params: Array) -> Array:
        """The block-diagonal ``N x N`` matrix of a state block and a parameter block."""
        out = np.zeros((self.N, self.N))
        out[:self.n, :self.n] = state
        out[self.n:, self.n:] = params
        return out

    # ------------------------------------------------------------------ reset
    def reset(self, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None,
              theta_hat0: Any = None) -> None:
        """Restart from ``x_hat0`` (physical state, default zero) and ``theta_hat0`` with the
        covariance ``P0`` (default: the constructor's values)."""
        if z_hat0 is not None:
            if x_hat0 is not None:
                raise DesignError("give x_hat0 or z_hat0 (the same thing here), not both")
            x_hat0 = z_hat0
        if x_hat0 is None and theta_hat0 is None:
            x_hat0, theta_hat0 = self._init
        x = np.zeros(self.n) if x_hat0 is None else vector("x_hat0", x_hat0, self.n)
        th = np.zeros(0) if not self.q else vector("theta_hat0", theta_hat0, self.q)
        self._x = np.concatenate((x, th))
        self._P = self.P0.copy()
        self._restart_counters()
        self._sync_fast()

    def _sync_fast(self) -> None:
        """Choose the float path (small system-model filters with a selection output and a
        diagonal R: state and covariance kept as flat lists, generated code) or numpy."""
        mdl = self.model
        self._fast = (isinstance(mdl, SystemModel) and self.N <= FAST_MAX and self.sel is not None
                      and self._diag_R)
        if not self._fast:
            return
        if not hasattr(self, "_corr_f"):
            self._as_list = self._list_ok()
            self._hmemo: dict[float, list[float]] = {}
            self._generate()
        self._xl = self._x.tolist()
        self._Pl = self._P.reshape(-1).tolist()

    #: the generated functions of the float path (made with ``exec``: pickle cannot store them)
    _GENERATED = ("_corr_f", "_step_f", "_phi_f", "_prop_f", "_sigma_f", "_mom_f")

    def _generate(self) -> None:
        """Generate the float path's code (on the first reset, and again on unpickling)."""
        N = self.N
        self._corr_f = {j: _gen_correct(N, j) for j in set(self.sel)}  # type: ignore[arg-type]
        self._step_f = _gen_step(self.model.n, N, self.method, self._as_list)
        self._compile_fast()

    def __getstate__(self) -> dict[str, Any]:
        """Pickle without the generated code; :meth:`__setstate__` generates it again (the
        same code from the same design, so the copy continues identically)."""
        return {k: v for k, v in self.__dict__.items() if k not in self._GENERATED}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        if "_as_list" in state:
            self._generate()

    def _compile_fast(self) -> None:
        """Filter-specific generated code (EKF: Phi and F P F^T; UKF: sigma points, moments)."""

    def _weights(self) -> None:
        """UKF: sigma-point weights (before the first reset)."""

    def _list_ok(self) -> bool:
        """Whether the system's ``dynamics`` accepts a list for ``x`` and returns an array
        (checked once; the float path then skips building an array per call)."""
        mdl = self.model
        rng = np.random.default_rng(7)
        x = rng.uniform(-1.0, 1.0, mdl.n)
        u = rng.uniform(-1.0, 1.0, mdl.n_inputs)
        ref = mdl._dyn(0.0, x, u, mdl.base)
        if not isinstance(ref, np.ndarray):
            mdl._dyn = functools.partial(_as_array, mdl._dyn)
            ref = np.asarray(ref, dtype=float)
        try:
            got = mdl._dyn(0.0, x.tolist(), u, mdl.base)
        except Exception:  # noqa: BLE001 - any failure means: pass arrays
            return False
        return isinstance(got, np.ndarray) and got.shape == ref.shape and bool(np.all(got == ref))

    def _correct_fast(self, y: Any) -> None:
        x, P = self._xl, self._Pl
        sel = self.sel
        r = self._r
        corr = self._corr_f
        for c, v in enumerate(measured_channels(self, y, self.outputs)):
            if v == v:
                corr[sel[c]](x, P, v, r[c])  # type: ignore[index]

    def _Qh(self, h: float) -> list[float]:
        Qh = self._hmemo.get(h)
        if Qh is None:
            Qh = (self.Qc * h).reshape(-1).tolist()
            self._hmemo[h] = Qh
        return Qh

    def _check_fast(self) -> None:
        x = self._xl
        for v in x:
            if not v - v == 0.0:
                raise DivergenceError(f"{type(self).__name__} estimate left the finite numbers: {x}")

    def _xvals(self) -> Any:
        """The augmented estimate (an array, or the float path's list)."""
        return self._xl if self._fast else self._x

    def _Parr(self) -> Array:
        return np.array(self._Pl).reshape(self.N, self.N) if self._fast else self._P

    # ------------------------------------------------------------------ update
    def update(self, y: Any, u: Any, dt: float) -> Array:
        """Consume ``y(t_k)``, ``u(t_k)``: correct, then predict over ``dt``; return the
        prediction of ``x(t_k + dt)``."""
        if not isinstance(u, np.ndarray):
            u = np.atleast_1d(np.asarray(u, dtype=float))
        self._u = u
        if self._fast:
            return self._update_fast(y, u, dt)
        idx, vals = self._channels(y)
        if idx:
            self._correct(idx, vals)
        h = dt / self.substeps
        x, P = self._x, self._P
        Qh = self.Qc * h
        for _ in range(self.substeps):
            x, P = self._predict(x, P, u, h, Qh)
        self._x, self._P = x, P
        self._finite()
        return x[:self.n].copy()

    def _update_fast(self, y: Any, u: Array, dt: float) -> Array:
        """The float path of :meth:`update` (filter-specific)."""
        raise NotImplementedError

    def _correct(self, idx: list[int], vals: list[float]) -> None:
        """Measurement update with the present channels ``idx`` (numpy path)."""
        self._correct_numpy(idx, vals)

    def _predict(self, x: Array, P: Array, u: Array, h: float, Qh: Array) -> tuple[Array, Array]:
        """Time update of the mean and covariance over one substep ``h`` (numpy path)."""
        raise NotImplementedError

    # ------------------------------------------------------------------ measurement
    def _channels(self, y: Any) -> tuple[list[int], list[float]]:
        """Indices (into ``outputs``) and values of the channels present in ``y``."""
        idx, vals = [], []
        for c, v in enumerate(measured_channels(self, y, self.outputs)):
            if v == v:
                idx.append(c)
                vals.append(v)
        return idx, vals

    def _correct_numpy(self, idx: list[int], vals: list[float]) -> None:
        """Kalman update (Joseph form) with the channels ``idx``."""
        if not idx:
            return
        x, P = self._x, self._P
        if len(idx) == 1 and self.sel is not None:  # one scalar channel y = x[j]: no matrices
            c = idx[0]
            j = self.sel[c]
            Pj = P[:, j].copy()
            K = Pj / (Pj[j] + self.R[c, c])
            self._x = x + K * (vals[0] - x[j])
            self._P = P - np.outer(K, Pj)
            return
        R = self.R[np.ix_(idx, idx)]
        yv = np.array(vals)
        if self.sel is not None:
            js = [self.sel[c] for c in idx]
            H = np.zeros((len(idx), self.N))
            H[np.arange(len(idx)), js] = 1.0
            yhat = x[js]
        else:
            H, yhat = self._h_linear(x, idx)
        PHt = P @ H.T
        S = H @ PHt + R
        K = np.linalg.solve(S, PHt.T).T
        x = x + K @ (yv - yhat)
        IKH = np.eye(self.N) - K @ H
        P = IKH @ P @ IKH.T + K @ R @ K.T
        self._x, self._P = x, 0.5 * (P + P.T)

    def _h_linear(self, x: Array, idx: list[int]) -> tuple[Array, Array]:
        """Finite-difference Jacobian of ``h`` (channels ``idx``) and ``h(x)``."""
        chans = [self.outputs[c] for c in idx]
        out = self.model.output
        H = _central_differences(lambda z: out(z)[chans], x, len(idx), self.N)
        return H, out(x)[chans]

    # ------------------------------------------------------------------ interface
    def check_period(self, dt: float) -> None:
        """Refuse a sample period the MuJoCo model cannot step (not a multiple of its
        timestep times ``substeps``); the system-model filters take any period."""
        dt = finite_scalar("dt", dt, positive=True)
        if isinstance(self.model, MujocoModel):
            self.model._steps(dt / self.substeps)

    @property
    def state_names(self) -> tuple[str, ...]:
        return self.model.state_names

    @property
    def z_hat(self) -> Array:
        """The physical state estimate (the filter's own coordinates)."""
        return self.x_hat

    @property
    def x_hat(self) -> Array:
        return np.array(self._xvals()[:self.n], dtype=float)

    @property
    def theta_hat_(self) -> Array:
        return np.array(self._xvals()[self.n:], dtype=float)

    @property
    def P_(self) -> Array:
        """Covariance of the augmented estimate, shape (N, N)."""
        return np.array(self._Parr(), dtype=float).reshape(self.N, self.N)

    def diagnostics(self) -> dict[str, float]:
        n = self.n
        x = self._xvals()
        out = {f"theta_{nm}": float(x[n + j]) for j, nm in enumerate(self.estimate)}
        out["dropouts"] = float(self.dropouts_)
        return out

    def params(self) -> dict[str, Any]:
        return {"model": self.model.kind, "estimate": list(self.estimate),
                "Q": self.Qc.tolist(), "R": self.R.tolist(), "P0": self.P0.tolist(),
                "outputs": list(self.outputs), "method": self.method, "substeps": self.substeps,
                "jacobian": getattr(self.model, "jacobian_kind",
                                    "analytic" if getattr(self.model, "analytic", False) else "fd"),
                "fast_path": bool(getattr(self, "_fast", False))}

    def _finite(self) -> None:
        x = self._x
        if not np.all(np.isfinite(x)):
            raise DivergenceError(f"{type(self).__name__} estimate left the finite numbers: "
                                  f"{list(x)}")


class ExtendedKalmanFilter(_KalmanFilter):
    """Continuous-discrete extended Kalman filter with parameter augmentation.

    .. math::

        K_k &= P^- H^T (H P^- H^T + R)^{-1}, \\quad
        \\hat x^+ = \\hat x^- + K_k (y_k - h(\\hat x^-)), \\quad
        P^+ = (I - K_k H) P^- (I - K_k H)^T + K_k R K_k^T, \\\\
        \\hat x^-_{k+1} &= \\mathrm{RK4}_h(\\hat x^+_k), \\quad
        P^-_{k+1} = \\Phi P^+_k \\Phi^T + Q h, \\quad \\Phi = T_4(h F(\\hat x^+_k))

    (per substep ``h``; see the module docstring).

    Parameters
    ----------
    system : System
        The model (physical coordinates), with its known parameter values.
    estimate : sequence of str
        Parameters of the system to estimate by augmentation (``theta_hat0`` then needed).
    Q, Q_theta : float, array_like
        Continuous-time process noise intensity of the state (``n x n``, or scalar / diagonal)
        and of the parameters' random walk (``q x q``); symmetric positive semi-definite.
    R : float, array_like, optional
        Measurement noise covariance of the used channels (positive definite); default the
        ``sensor`` chain's :meth:`~hgo_mj.sensors.SensorChain.noise_variance`, else ``1e-6``.
    sensor : SensorChain, optional
        Only read for the default ``R``.
    P0, P0_theta : float, array_like
        Initial covariance of the state and of the parameters (positive definite).
    x_hat0, theta_hat0 : array_like, optional
        Initial estimates (physical state, default zero; parameters, required with
        ``estimate``).
    outputs : sequence of int, optional
        Measured channels used (default all of the system's outputs).
    method : {"rk4", "euler"}
        Mean propagation and the matching :math:`\\Phi`.
    substeps : int
        Time-update steps per sample.
    jacobian : {"auto", "analytic", "fd"}
        How :math:`F` is obtained (see :class:`SystemModel`).

    Attributes
    ----------
    theta_hat_ : ndarray (q,)
        Parameter estimates (also the diagnostics ``theta_<name>``).
    P_ : ndarray (N, N)
        Covariance of the augmented estimate.
    dropouts_ : int
        Samples with at least one NaN channel (only the present ones correct).

    References
    ----------
    Jazwinski (1970), sec. 8.3; Simon (2006), sec. 13.2 (augmentation).
    """

    name = "ekf"
    summary = "continuous-discrete extended Kalman filter, parameters by state augmentation"
    reference = "Jazwinski 1970 sec. 8.3; Simon 2006 sec. 13.2"

    def _compile_fast(self) -> None:
        self._phi_f = _gen_phi(self.N, self.method)
        self._prop_f = _gen_propagate(self.N)

    def _predict(self, x: Array, P: Array, u: Array, h: float, Qh: Array) -> tuple[Array, Array]:
        x, Phi = self.model.transition(x, u, h, self.method)
        return x, Phi @ P @ Phi.T + Qh

    def _update_fast(self, y: Any, u: Array, dt: float) -> Array:
        self._correct_fast(y)
        x, P = self._xl, self._Pl
        h = dt / self.substeps
        Qh = self._Qh(h)
        mdl = self.model
        dyn, prm, step, jac = mdl._dyn, mdl.params, self._step_f, mdl.jac
        q = self.q
        for _ in range(self.substeps):
            xa = np.array(x)
            p = prm(x) if q else mdl.base
            P = self._prop_f(P, self._phi_f(jac(xa, u).reshape(-1).tolist(), h), Qh)
            x = step(x, u, h, dyn, p)
        self._xl, self._Pl = x, P
        self._check_fast()
        return np.array(x[:self.n])


class UnscentedKalmanFilter(_KalmanFilter):
    """Continuous-discrete unscented Kalman filter with parameter augmentation.

    Time update: the :math:`2N + 1` scaled sigma points of Wan and van der Merwe,
    :math:`\\chi_0 = \\hat x`, :math:`\\chi_{\\pm i} = \\hat x \\pm \\sqrt{N + \\kappa'}\\,
    L_i` (:math:`L L^T = P`, :math:`\\kappa' = \\alpha^2 (N + \\kappa) - N`), each propagated by
    the model over the sample (RK4 or Euler substeps; MuJoCo steps for the MuJoCo variant),

    .. math::

        \\hat x^- = \\sum_i W^m_i \\chi_i^+, \\qquad
        P^- = \\sum_i W^c_i (\\chi_i^+ - \\hat x^-)(\\chi_i^+ - \\hat x^-)^T + Q\\, dt,

    :math:`W^m_0 = \\kappa'/(N+\\kappa')`, :math:`W^c_0 = W^m_0 + 1 - \\alpha^2 + \\beta`,
    :math:`W_i = 1/(2(N+\\kappa'))`. Measurement update: for a selection output the exact
    linear update (the unscented transform of a linear map is exact), else the unscented one
    with :math:`P_{yy}, P_{xy}` from sigma points.

    Parameters
    ----------
    alpha, beta, kappa : float
        Sigma-point spread and weights (defaults 1, 2, 0: the points at
        :math:`\\pm\\sqrt{N} L_i`, zero mean weight on the centre).
    **kw
        As :class:`ExtendedKalmanFilter` (``jacobian`` is not used).

    References
    ----------
    Julier and Uhlmann (1997); Wan and van der Merwe (2000); Simon (2006), sec. 14.3.
    """

    name = "ukf"
    summary = "continuous-discrete unscented Kalman filter, parameters by state augmentation"
    reference = "Julier, Uhlmann 1997; Wan, van der Merwe 2000"

    def __init__(self, system: System | None = None, *, alpha: float = 1.0, beta: float = 2.0,
                 kappa: float = 0.0, **kw: Any) -> None:
        self.alpha = finite_scalar("alpha", alpha, positive=True)
        self.beta = finite_scalar("beta", beta)
        self.kappa = finite_scalar("kappa", kappa)
        super().__init__(system, **kw)

    def _weights(self) -> None:
        N = self.N
        lam = self.alpha ** 2 * (N + self.kappa) - N
        if not N + lam > 0:
            raise DesignError(f"alpha^2 (N + kappa) must be > 0 (sigma-point spread); found "
                              f"{N + lam:g} with N = {N}, alpha = {self.alpha:g}, kappa = {self.kappa:g}")
        self._c = math.sqrt(N + lam)
        self.Wm = np.full(2 * N + 1, 0.5 / (N + lam))
        self.Wc = self.Wm.copy()
        self.Wm[0] = lam / (N + lam)
        self.Wc[0] = lam / (N + lam) + 1.0 - self.alpha ** 2 + self.beta

    def _sigma(self, x: Array, P: Array) -> Array:
        try:
            L = np.linalg.cholesky(P)
        except np.linalg.LinAlgError:
            w, V = np.linalg.eigh(0.5 * (P + P.T))
            if w[0] < -1e-9 * max(1.0, w[-1]):
                raise DivergenceError(f"UKF covariance is not positive semi-definite (eigenvalues "
                                      f"{w.tolist()})") from None
            L = V * np.sqrt(np.clip(w, 0.0, None))
        cL = self._c * L
        return np.vstack((x, x + cL.T, x - cL.T))

    def _correct_unscented(self, idx: list[int], vals: list[float]) -> None:
        x, P = self._x, self._P
        chans = [self.outputs[c] for c in idx]
        X = self._sigma(x, P)
        Y = np.array([self.model.output(s)[chans] for s in X])
        yhat = self.Wm @ Y
        dY = Y - yhat
        dX = X - x
        Pyy = (dY.T * self.Wc) @ dY + self.R[np.ix_(idx, idx)]
        Pxy = (dX.T * self.Wc) @ dY
        K = np.linalg.solve(Pyy, Pxy.T).T
        self._x = x + K @ (np.array(vals) - yhat)
        P = P - K @ Pyy @ K.T
        self._P = 0.5 * (P + P.T)

    def _correct(self, idx: list[int], vals: list[float]) -> None:
        if self.sel is not None:  # a selection output: the exact linear update
            self._correct_numpy(idx, vals)
        else:
            self._correct_unscented(idx, vals)

    def _predict(self, x: Array, P: Array, u: Array, h: float, Qh: Array) -> tuple[Array, Array]:
        # sigma points redrawn and Q h added per substep
        step = self.model.step
        method = self.method
        X = self._sigma(x, P)
        out = np.empty_like(X)
        for i in range(X.shape[0]):
            out[i] = step(X[i], u, h, method)
        x = self.Wm @ out
        d = out - x
        P = (d.T * self.Wc) @ d + Qh
        return x, 0.5 * (P + P.T)

    def _compile_fast(self) -> None:
        self._sigma_f = _gen_sigma(self.N)
        self._mom_f = _gen_moments(self.N, self.Wm, self.Wc)

    def _update_fast(self, y: Any, u: Array, dt: float) -> Array:
        self._correct_fast(y)
        h = dt / self.substeps
        mdl = self.model
        dyn, prm, step = mdl._dyn, mdl.params, self._step_f
        q = self.q
        base = mdl.base
        Qh = self._Qh(h)
        x, P = self._xl, self._Pl
        for _ in range(self.substeps):  # sigma points redrawn and Q h added per substep
            X = self._sigma_f(x, P, self._c)
            if X is None:  # not numerically positive definite: the eigen-decomposition fallback
                X = self._sigma(np.array(x), np.array(P).reshape(self.N, self.N)).tolist()
            out = []
            for pt in X:
                out.append(step(pt, u, h, dyn, prm(pt) if q else base))
            x, P = self._mom_f(out, Qh)
        self._xl, self._Pl = x, P
        self._check_fast()
        return np.array(self._xl[:self.n])


class MujocoExtendedKalmanFilter(ExtendedKalmanFilter):
    """:class:`ExtendedKalmanFilter` whose model is the MJCF (see :class:`MujocoModel`).

    The mean is predicted by stepping a private ``MjData`` of a copy of the ``MjModel``
    (``model=``: the plant's, a modified copy, or default the system's shipped MJCF), the
    transition matrix comes from ``mujoco.mjd_transitionFD`` (``jacobian="transition_fd"``,
    default) or central differences of the step (``"fd"``); ``estimate`` names model fields or
    aliases (``MujocoModel``). The update period must be a multiple of the model timestep.
    """

    name = "ekf_mujoco"
    summary = "EKF whose model is the MuJoCo plant (MjData stepping, mjd_transitionFD)"
    reference = "Jazwinski 1970 sec. 8.3; MuJoCo mjd_transitionFD"
    backend = "mujoco"


class MujocoUnscentedKalmanFilter(UnscentedKalmanFilter):
    """:class:`UnscentedKalmanFilter` whose sigma points are stepped by MuJoCo (see
    :class:`MujocoModel`)."""

    name = "ukf_mujoco"
    summary = "UKF whose sigma points are stepped by the MuJoCo plant"
    reference = "Julier, Uhlmann 1997; Wan, van der Merwe 2000"
    backend = "mujoco"


def _full_signature(cls: type) -> None:
    """Show the shared keyword arguments in ``cls.__init__``'s signature (``hgo-mj list``)."""
    import inspect

    own = inspect.signature(cls.__init__)
    base = inspect.signature(_KalmanFilter.__init__)
    params = [p for p in own.parameters.values() if p.kind is not p.VAR_KEYWORD]
    params += [p for n, p in base.parameters.items() if n not in own.parameters]
    cls.__init__.__signature__ = own.replace(parameters=params)  # type: ignore[attr-defined]


_full_signature(UnscentedKalmanFilter)
