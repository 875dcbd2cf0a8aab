"""The analytic model an observer designs against.

A :class:`System` holds, for one plant family,

* the physical ODE ``dx/dt = f(t, x, u, params)`` and output ``y = h(x)``;
* for single-output systems, the observability normal form (paper 000, eq. 1)

  .. math:: z = (y, \\dot y, \\dots, y^{(n-1)}), \\qquad z_n' = \\varphi(z, u)

  with the map ``to_normal`` from physical state to ``z``, its inverse ``from_normal`` and
  ``phi``;
* for MuJoCo plants, the MJCF file and the joints whose ``(qpos, qvel)`` form the state, and
  ``from_mjmodel`` which reads the parameters from the compiled ``MjModel`` so that the model
  and the MJCF cannot drift apart.

Conventions: state vectors are 1-D ``(n,)``; ``dynamics`` is the fast private path (no checks),
``f`` the validating public one.
"""

from __future__ import annotations

from collections import namedtuple
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from .._validate import check_params, vector
from ..exceptions import DesignError
from ..models import model_path

__all__ = ["CompiledModel", "System", "derivative_names"]

Array = NDArray[np.float64]


class CompiledModel(namedtuple("CompiledModel", ())):
    """Base of a system's compiled model: the ODE written once as row functions that numba
    kernels call without returning to Python (the Kalman filters' time update).

    A system module subclasses it next to its equations and sets :attr:`System.compiled` to an
    instance; the subclass holds three ``numba.extending.register_jitable`` functions (plain
    Python from Python, compiled into the kernel that calls them), each of one row ``x``
    ``(n,)``, input ``u`` ``(m,)`` and the parameters ``c`` in the order of
    :attr:`System.param_names`, writing into ``out``:

    * ``dynamics(x, u, c, out)``: ``out (n,) = f(x, u; c)``, the same floating-point
      operations as :meth:`System.dynamics` (so both agree bit for bit);
    * ``jacobian(x, u, c, out)`` (optional, ``None``): ``out[:n, :n] = df/dx`` (``out`` may be
      larger: the augmented ``(N, N)`` Jacobian, whose other entries it leaves alone);
    * ``param_jacobian(x, u, c, out)`` (optional): ``out (n, len(param_names)) = df/dc``.

    A kernel takes the instance as an argument: its numba type names the subclass, so the
    kernel is compiled (and cached) once per system, and the Kalman filters'
    ``model_dynamics``, ``model_jacobian`` and ``model_param_jacobian``
    (:mod:`hgo_mj.observers.kalman`) resolve to the subclass's functions at compile time.

    Parameters
    ----------
    *args, **kwargs
        None accepted: a model has no fields and is built as ``PendulumModel()``.

    Examples
    --------
    The pendulum's compiled model evaluates one row from Python (the same function a numba
    kernel calls):

    >>> import numpy as np
    >>> from hgo_mj.systems import Pendulum
    >>> p = Pendulum()
    >>> out = np.empty(2)
    >>> p.compiled.dynamics(np.array([0.5, 0.0]), np.array([0.0]), p.param_vector(), out)
    >>> out.round(4)
    array([ 0.   , -9.759])
    >>> p.compiled.jacobian is None, type(p.compiled).__name__
    (False, 'PendulumModel')
    """

    __slots__ = ()
    dynamics: ClassVar[Any] = None
    jacobian: ClassVar[Any] = None
    param_jacobian: ClassVar[Any] = None


_DERIVATIVE_WORDS = {"_angle": ("_angle", "_velocity", "_acceleration", "_jerk"),
                     "_position": ("_position", "_velocity", "_acceleration", "_jerk")}
#: outputs named by the bare word: the plants' own names (pendulum: angle, angular_velocity)
_BARE_DERIVATIVE_WORDS = {"angle": ("angle", "angular_velocity", "angular_acceleration", "angular_jerk"),
                          "position": ("position", "velocity", "acceleration", "jerk")}


def derivative_names(output: str, order: int) -> tuple[str, ...]:
    """Names of ``(y, y', ..., y^(order-1))`` for an output named ``output``.

    ``link1_angle`` gives ``link1_angle, link1_velocity, link1_acceleration, link1_jerk``
    (``_position`` likewise), a bare ``angle`` gives ``angle, angular_velocity, ...`` (the
    pendulums' state names); higher derivatives and other names get ``<name>_d<j>``.

    Parameters
    ----------
    output : str
        Name of the measured output ``y`` (e.g. ``"link1_angle"``, ``"angle"``, ``"biomass"``).
    order : int
        Number of names to return: ``y`` and its first ``order - 1`` derivatives (the
        normal-form order ``n``).

    Returns
    -------
    tuple of str
        ``order`` names, the first being ``output`` itself.

    Examples
    --------
    >>> derivative_names("link1_angle", 3)
    ('link1_angle', 'link1_velocity', 'link1_acceleration')
    >>> derivative_names("angle", 2)
    ('angle', 'angular_velocity')
    >>> derivative_names("biomass", 3)
    ('biomass', 'biomass_d1', 'biomass_d2')
    """
    if output in _BARE_DERIVATIVE_WORDS:
        words = _BARE_DERIVATIVE_WORDS[output]
        return tuple(words[j] if j < len(words) else f"{output}_d{j}" for j in range(order))
    for suffix, words in _DERIVATIVE_WORDS.items():
        if output.endswith(suffix):
            base = output[: -len(suffix)]
            return tuple(base + words[j] if j < len(words) else f"{base}_d{j}" for j in range(order))
    return tuple(output if j == 0 else f"{output}_d{j}" for j in range(order))



class System:
    """Base class of the analytic models. Subclasses fill in the class attributes below.

    A subclass implements :meth:`dynamics` and :meth:`output` (the fast paths), and, when
    :attr:`normal_form_order` is set, :meth:`to_normal`, :meth:`from_normal` and :meth:`phi`;
    it may override the ``*_unchecked`` and :meth:`phi_batch` fast paths and declare observer
    forms (:meth:`form`).

    Parameters
    ----------
    **params : float
        Parameter values by name (keys of :attr:`param_names`); missing ones are taken from
        :attr:`default_params` (MuJoCo systems: from the shipped MJCF).

    Attributes
    ----------
    params : dict of str to float
        The validated parameters, one entry per name of :attr:`param_names`.

    Raises
    ------
    DesignError
        A parameter is missing, unknown or not a finite number (MuJoCo systems also: a
        parameter that must be positive is not).

    Examples
    --------
    >>> from hgo_mj.systems import Pendulum
    >>> p = Pendulum(damping=0.02)
    >>> p.params["damping"], p.state_names, p.normal_form_order
    (0.02, ('angle', 'angular_velocity'), 2)
    >>> p.f(0.0, [0.5, 0.0], [0.0]).round(4)
    array([ 0.   , -9.759])
    """

    #: registry name, e.g. ``"pendulum"``
    name: ClassVar[str] = ""
    #: one line for ``hgo-mj list``
    summary: ClassVar[str] = ""
    #: paper and equation the model comes from
    reference: ClassVar[str] = ""
    state_names: ClassVar[tuple[str, ...]] = ()
    #: the unit of each state, in the order of ``state_names`` (SI; ``""``: dimensionless or
    #: as the paper leaves it); empty: not declared
    state_units: ClassVar[tuple[str, ...]] = ()
    #: the unit of time of the model (``""``: dimensionless, e.g. in residence times)
    time_unit: ClassVar[str] = "s"
    input_names: ClassVar[tuple[str, ...]] = ()
    #: the unit of each input, in the order of ``input_names`` (``""``: dimensionless or as
    #: the paper leaves it); empty: not declared
    input_units: ClassVar[tuple[str, ...]] = ()
    #: names of the measured outputs; for MuJoCo plants these are MJCF ``<sensor>`` names
    output_names: ClassVar[tuple[str, ...]] = ()
    param_names: ClassVar[tuple[str, ...]] = ()
    #: parameter values used when none are given (ODE systems; MuJoCo systems read the MjModel)
    default_params: ClassVar[Mapping[str, float]] = {}
    #: default initial state of the plant
    default_x0: ClassVar[tuple[float, ...]] = ()
    #: order ``n`` of the observability normal form of the first output, or ``None``
    normal_form_order: ClassVar[int | None] = None
    #: MJCF file under ``models/`` (``None`` for ODE plants)
    model_file: ClassVar[str | None] = None
    #: MJCF joints whose ``qpos`` then ``qvel`` form the state ``x`` (MuJoCo plants)
    joints: ClassVar[tuple[str, ...]] = ()
    #: MJCF actuators driven by ``u``, in order (MuJoCo plants)
    actuators: ClassVar[tuple[str, ...]] = ()
    #: the observer forms this system declares (see :meth:`form`), e.g. ``("affine",)``
    forms: ClassVar[tuple[str, ...]] = ()
    #: the ODE compiled for numba kernels (:class:`CompiledModel`), or ``None``
    compiled: ClassVar[CompiledModel | None] = None

    @classmethod
    def unit(cls, state: str) -> str:
        """The unit of the state called ``state`` (``""`` when not declared).

        Parameters
        ----------
        state : str
            A name of :attr:`state_names`.

        Returns
        -------
        str
            Its unit from :attr:`state_units`; ``""`` when ``state`` is not a state name or
            the system declares no units.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> Pendulum.unit("angular_velocity"), Pendulum.unit("nope")
        ('rad/s', '')
        """
        if state in cls.state_names and len(cls.state_units) == len(cls.state_names):
            return cls.state_units[cls.state_names.index(state)]
        return ""

    def __init__(self, **params: Any) -> None:
        merged = {**self.default_params, **params}
        self.params: dict[str, float] = check_params(type(self).__name__, merged, self.param_names)

    @classmethod
    def _param_columns(cls, names: Sequence[str]) -> list[int]:
        """The indices of ``names`` in :attr:`param_names` (the columns of a parameter
        Jacobian); an unknown name is a :class:`DesignError` listing the valid ones."""
        bad = [nm for nm in names if nm not in cls.param_names]
        if bad:
            raise DesignError(f"{cls.__name__} has no parameter(s) {bad}; valid: "
                              f"{list(cls.param_names)}")
        return [cls.param_names.index(nm) for nm in names]

    def param_vector(self, params: Mapping[str, float] | None = None) -> Array:
        """The parameters (default :attr:`params`) as a vector in the order of
        :attr:`param_names` (the ``c`` of :class:`CompiledModel`).

        Parameters
        ----------
        params : mapping of str to float, optional
            Parameter values containing every name of :attr:`param_names` (extra keys are
            ignored); default: :attr:`params`.

        Returns
        -------
        (P,) ndarray of float
            The values in the order of :attr:`param_names` (``P = len(param_names)``).

        Raises
        ------
        KeyError
            ``params`` lacks a name of :attr:`param_names`.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> p = Pendulum()
        >>> p.param_names
        ('mass', 'com_distance', 'inertia', 'damping', 'gear', 'g')
        >>> p.param_vector().round(4)
        array([0.25  , 0.45  , 0.0542, 0.01  , 1.    , 9.81  ])
        """
        p = self.params if params is None else params
        return np.array([p[k] for k in self.param_names], dtype=float)

    # ---------------------------------------------------------------- dynamics
    @staticmethod
    def dynamics(t: float, x: Array, u: Array, p: Mapping[str, float]) -> Array:
        """Fast path of ``dx/dt``: no validation. Subclasses implement it.

        Parameters
        ----------
        t : float
            Time (in :attr:`time_unit`); autonomous systems ignore it.
        x : (n,) ndarray of float
            State, in the order of :attr:`state_names`.
        u : (m,) ndarray of float
            Input, in the order of :attr:`input_names` (``m = 0``: an empty array).
        p : mapping of str to float
            Parameters by name (all of :attr:`param_names`), not checked.

        Returns
        -------
        (n,) ndarray of float
            ``dx/dt``.

        Raises
        ------
        NotImplementedError
            Called on :class:`System` itself (a subclass does not implement it).

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import Pendulum
        >>> p = Pendulum()
        >>> Pendulum.dynamics(0.0, np.array([0.5, 0.0]), np.array([0.0]), p.params).round(4)
        array([ 0.   , -9.759])
        """
        raise NotImplementedError

    @staticmethod
    def output(x: Array, p: Mapping[str, float]) -> Array:
        """Fast path of ``y = h(x)``. Subclasses implement it.

        Parameters
        ----------
        x : (n,) ndarray of float
            State, in the order of :attr:`state_names`.
        p : mapping of str to float
            Parameters by name, not checked.

        Returns
        -------
        (q,) ndarray of float
            The clean outputs, in the order of :attr:`output_names`.

        Raises
        ------
        NotImplementedError
            Called on :class:`System` itself (a subclass does not implement it).

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import Pendulum
        >>> Pendulum.output(np.array([0.5, 0.0]), Pendulum().params)
        array([0.5])
        """
        raise NotImplementedError

    def f(self, t: float, x: Any, u: Any, params: Mapping[str, float] | None = None) -> Array:
        """``dx/dt = f(t, x, u, params)`` with shapes and finiteness checked.

        Parameters
        ----------
        t : float
            Time (in :attr:`time_unit`).
        x : array_like, shape (n,)
            State, in the order of :attr:`state_names`.
        u : array_like, shape (m,)
            Input, in the order of :attr:`input_names` (``[]`` for a system without inputs).
        params : mapping of str to float, optional
            Parameters to use instead of :attr:`params` (all of :attr:`param_names`).

        Returns
        -------
        (n,) ndarray of float
            ``dx/dt``.

        Raises
        ------
        DesignError
            ``x`` or ``u`` has the wrong length or a non-finite entry, or ``params`` lacks,
            adds or has a non-finite parameter (raised by the validators it calls).

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> p = Pendulum()
        >>> p.f(0.0, [0.5, 0.0], [0.0]).round(4)
        array([ 0.   , -9.759])
        >>> p.f(0.0, [0.5, 0.0], [0.0], params={**p.params, "g": 0.0}).round(4)
        array([0., 0.])
        """
        x = vector("x", x, len(self.state_names))
        u = vector("u", u, len(self.input_names))
        p = self.params if params is None else check_params(
            type(self).__name__, params, self.param_names)
        return np.asarray(self.dynamics(float(t), x, u, p), dtype=float)

    def h(self, x: Any) -> Array:
        """The clean measured outputs ``y = h(x)``.

        Parameters
        ----------
        x : array_like, shape (n,)
            State, in the order of :attr:`state_names`.

        Returns
        -------
        (q,) ndarray of float
            The outputs, in the order of :attr:`output_names`, without noise.

        Raises
        ------
        DesignError
            ``x`` has the wrong length or a non-finite entry (raised by the validator).

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> Pendulum().h([0.5, 0.0])
        array([0.5])
        """
        x = vector("x", x, len(self.state_names))
        return np.asarray(self.output(x, self.params), dtype=float)

    # ------------------------------------------------------------- normal form
    def _require_normal_form(self) -> int:
        if self.normal_form_order is None:
            raise DesignError(
                f"{type(self).__name__} has no single-output observability normal form "
                f"(outputs: {list(self.output_names)})")
        return self.normal_form_order

    def to_normal(self, x: Any, u: Any = None) -> Array:
        """Map the physical state to ``z = (y, y', ..., y^(n-1))``.

        Parameters
        ----------
        x : array_like, shape (n_x,)
            Physical state, in the order of :attr:`state_names`.
        u : array_like, shape (m,), optional
            Input, for systems whose map depends on it; ``None``: not needed.

        Returns
        -------
        (n,) ndarray of float
            ``z``, ``n = normal_form_order``.

        Raises
        ------
        DesignError
            The system has no single-output normal form (:attr:`normal_form_order` is None),
            or ``x``/``u`` fail validation.
        NotImplementedError
            The subclass declares a normal form but does not implement the map.

        Examples
        --------
        >>> from hgo_mj.systems import ElasticJoint
        >>> ElasticJoint().to_normal([0.1, 0.2, 0.0, 0.0]).round(3)
        array([ 0.1  ,  0.   , 29.336, -1.95 ])
        """
        self._require_normal_form()
        raise NotImplementedError

    def from_normal(self, z: Any, u: Any = None) -> Array:
        """Inverse of :meth:`to_normal`.

        Parameters
        ----------
        z : array_like, shape (n,)
            Normal-form coordinates ``(y, y', ..., y^(n-1))``.
        u : array_like, shape (m,), optional
            Input, for systems whose map depends on it; ``None``: not needed.

        Returns
        -------
        (n_x,) ndarray of float
            The physical state, in the order of :attr:`state_names`.

        Raises
        ------
        DesignError
            The system has no single-output normal form, or ``z``/``u`` fail validation.
        NotImplementedError
            The subclass declares a normal form but does not implement the map.

        Examples
        --------
        >>> from hgo_mj.systems import ElasticJoint
        >>> ej = ElasticJoint()
        >>> ej.from_normal(ej.to_normal([0.1, 0.2, 0.0, 0.0])).round(6)
        array([0.1, 0.2, 0. , 0. ])
        """
        self._require_normal_form()
        raise NotImplementedError

    def phi(self, z: Any, u: Any = None) -> float:
        """``y^(n) = phi(z, u)`` in normal-form coordinates.

        Parameters
        ----------
        z : array_like, shape (n,)
            Normal-form coordinates ``(y, y', ..., y^(n-1))``.
        u : array_like, shape (m,)
            Input (systems with inputs require it; ``None`` raises).

        Returns
        -------
        float
            ``y^(n)``, the n-th time derivative of the output.

        Raises
        ------
        DesignError
            The system has no single-output normal form, ``u`` is missing, or ``z``/``u`` fail
            validation.
        NotImplementedError
            The subclass declares a normal form but does not implement ``phi``.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> round(Pendulum().phi([0.5, 0.0], [0.0]), 4)
        -9.759
        """
        self._require_normal_form()
        raise NotImplementedError

    def to_normal_rows(self, X: Array, U: Array) -> Array:
        """:meth:`to_normal` of the rows ``X`` ``(N, n_x)`` with inputs ``U`` ``(N, m)``,
        without validation: an observer's start from rows it has checked. Subclasses override
        it with a fast path.

        Parameters
        ----------
        X : (N, n_x) ndarray of float
            Physical states, not checked.
        U : (N, m) ndarray of float
            Inputs, not checked.

        Returns
        -------
        (N, n) ndarray of float
            ``z`` of each row, a new array.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import ElasticJoint, Pendulum
        >>> Pendulum().to_normal_rows(np.array([[0.5, 0.0]]), np.zeros((1, 1)))
        array([[0.5, 0. ]])
        >>> ElasticJoint().to_normal_rows(np.array([[0.1, 0.2, 0.0, 0.0]]), np.zeros((1, 1))).round(3)
        array([[ 0.1  ,  0.   , 29.336, -1.95 ]])
        """
        return np.array([self.to_normal(x, u) for x, u in zip(X, U)], dtype=float)

    def from_normal_unchecked(self, z: Array, u: Array) -> Array:
        """:meth:`from_normal` without validation, for an observer's per-sample use (``z`` a
        float array of length ``n``). Subclasses override it with a fast path.

        Parameters
        ----------
        z : (n,) ndarray of float
            Normal-form coordinates, not checked.
        u : (m,) ndarray of float
            Input, not checked.

        Returns
        -------
        (n_x,) ndarray of float
            The physical state (may be ``z`` itself when the map is the identity).

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import Pendulum
        >>> Pendulum().from_normal_unchecked(np.array([0.5, 0.0]), np.array([0.0]))
        array([0.5, 0. ])
        """
        return self.from_normal(z, u)

    def phi_unchecked(self, z: Array, u: Array) -> float:
        """:meth:`phi` without validation (the model term of observers). Overridable.

        Parameters
        ----------
        z : (n,) ndarray of float
            Normal-form coordinates, not checked.
        u : (m,) ndarray of float
            Input, not checked.

        Returns
        -------
        float
            ``phi(z, u)``.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import Pendulum
        >>> round(float(Pendulum().phi_unchecked(np.array([0.5, 0.0]), np.array([0.0]))), 4)
        -9.759
        """
        return self.phi(z, u)

    def phi_batch(self, Z: Array, U: Array) -> Array:
        """:meth:`phi_unchecked` of the rows ``Z`` ``(N, n)`` with inputs ``U`` ``(N, m)``, shape
        ``(N,)``: the model term of a batch of observers. Default: one call per row; systems
        override it with vectorized numpy.

        Parameters
        ----------
        Z : (N, n) ndarray of float
            Normal-form coordinates, one row per observer.
        U : (N, m) ndarray of float
            Inputs, one row per observer.

        Returns
        -------
        (N,) ndarray of float
            ``phi(Z[i], U[i])`` for each row.

        Examples
        --------
        >>> import numpy as np
        >>> from hgo_mj.systems import Pendulum
        >>> Pendulum().phi_batch(np.array([[0.5, 0.0], [0.0, 1.0]]), np.zeros((2, 1))).round(4)
        array([-9.759 , -0.1844])
        """
        return np.array([float(self.phi_unchecked(z, u)) for z, u in zip(Z, U)], dtype=float)

    # ------------------------------------------------------------------- forms
    def form(self, kind: str, **options: Any) -> Any:
        """The observer form ``kind`` this system declares (one of :attr:`forms`): observers
        ask for their form by name and never import a concrete system. A system declares
        ``"affine"`` (paper 001, eq. 9/21, for the Besançon observer), ``"aocf"`` (paper 002,
        eq. 2.2, Bastin-Gevers), ``"jo_son"`` (paper 003, Jo-Son) or ``"kalman_fields"`` (the
        MJCF fields an augmented Kalman filter may estimate) by listing it in :attr:`forms`
        and implementing ``_form_<kind>(**options)``.

        Parameters
        ----------
        kind : str
            The form's name, one of :attr:`forms`.
        **options
            Keyword options of the system's ``_form_<kind>`` (e.g. ``unknown=`` for
            ``"affine"``: the parameters to estimate).

        Returns
        -------
        object
            The form: an :class:`~hgo_mj.systems.affine_form.AffineForm` (``"affine"``), an
            :class:`~hgo_mj.systems.aocf.AOCF` (``"aocf"``), a
            :class:`~hgo_mj.systems.jo_son_form.JoSonForm` (``"jo_son"``) or a dict of MJCF
            field names (``"kalman_fields"``).

        Raises
        ------
        DesignError
            The system does not declare ``kind``; the message lists the forms it declares.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> p = Pendulum()
        >>> p.forms
        ('affine', 'kalman_fields', 'aocf')
        >>> p.form("kalman_fields")
        {'gear': 'actuator_gear[torque]', 'damping': 'dof_damping[hinge]', 'g': 'opt.gravity'}
        >>> p.form("affine").theta_names
        ('g_over_l', 'b_over_J')
        """
        if kind not in self.forms:
            raise DesignError(f"{type(self).__name__} does not declare the {kind!r} form; it "
                              f"declares {list(self.forms)}")
        return getattr(self, f"_form_{kind}")(**options)

    # ------------------------------------------------------------------ MuJoCo
    @classmethod
    def load_model(cls) -> Any:
        """The compiled ``mujoco.MjModel`` of a MuJoCo system: its shipped MJCF (the MJCF
        systems of :mod:`hgo_mj.systems.mjcf` compile their edited file).

        Returns
        -------
        mujoco.MjModel
            The model compiled from ``models/<model_file>``.

        Raises
        ------
        DesignError
            The system is not a MuJoCo system (``model_file`` is None).

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> model = Pendulum.load_model()
        >>> model.nq, model.nu
        (1, 1)
        """
        if cls.model_file is None:
            raise DesignError(f"{cls.__name__} is not a MuJoCo system (model_file is None)")
        import mujoco

        return mujoco.MjModel.from_xml_path(str(model_path(cls.model_file)))

    @classmethod
    def from_mjmodel(cls, model: Any) -> System:
        """Read the parameters from a compiled ``mujoco.MjModel``.

        Parameters
        ----------
        model : mujoco.MjModel
            A compiled model with the bodies, joints and actuators the system names
            (:attr:`joints`, :attr:`actuators`).

        Returns
        -------
        System
            An instance of the class with the parameters read from ``model``.

        Raises
        ------
        DesignError
            The system is not a MuJoCo system (this base implementation), or ``model`` lacks
            or mis-structures an element the system reads.

        Examples
        --------
        >>> from hgo_mj.systems import Pendulum
        >>> model = Pendulum.load_model()
        >>> model.dof_damping[0] = 0.05
        >>> Pendulum.from_mjmodel(model).params["damping"]
        0.05
        """
        raise DesignError(f"{cls.__name__} is not a MuJoCo system (model_file is None)")

    def __repr__(self) -> str:
        ps = ", ".join(f"{k}={v:.6g}" for k, v in self.params.items())
        return f"{type(self).__name__}({ps})"
