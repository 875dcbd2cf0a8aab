"""Where a recording puts each signal, how it is styled, and the default blueprint.

Pure functions: names in, entity paths and rerun archetype or blueprint objects out. Nothing
here writes to a stream, so the layout is tested without a file.

Entities (names escaped with :func:`rerun.escape_entity_path_part`). The truth and the
estimates of one plant state share an entity, one scalar series each (instances of one
``Scalars`` row, each named by the entity's ``SeriesLines`` style), so that a state's plot
compares them and a reviewer can still show, hide and query each series on its own::

    /state/<state>              series [<state> true, <state> <obs 1>, <state> <obs 2>, ...]:
                                the true state and each observer's estimate of it (the
                                observers that estimate that plant state, in order)
    /error/<state>              series [<state> error <obs 1>, ...]: x - x_hat, for those observers
    /observer/<obs>/estimate/<name>   an estimate that is not a plant state (the observer's
                                own state names: an order-only observer's z1, z2, ..., the
                                derivatives of a multi-output observer, ...)
    /sensor/<output>            series [<output> clean, <output> measured]: the plant's output
                                before the sensor chain, and what the observers saw (a
                                dropout is NaN)
    /input/<input>              scalar u
    /observer/<obs>/gain        the gain diagnostic (``k``, ``gain``, ``gamma``; ``k_<x>`` -> gain/<x>)
    /observer/<obs>/theta/<p>   parameter estimates (diagnostics ``theta...``), next to
    /plant/param/<p>            the true parameter, when the system has one of that name
    /observer/<obs>/diagnostics/<key>   every other diagnostic (dropouts: recorded only where
                                the sensor chain has a dropout stage, or is not known)
    /env/<name>                 environment extras (reward, ...)
    /world/true/<body>/<geom>   the MuJoCo model's geometry posed from the true state
    /world/estimate/<obs>/<body>/<geom>   translucent ghost posed from that observer's estimate
    /scenario, /metrics         text documents (:mod:`hgo_mj.record.documents`)

Units: every series is named with its unit in brackets (``angle fast [rad]``, ``torque [N m]``,
``[-]`` dimensionless; :mod:`hgo_mj.units`, from the plant's system), and so is every view of
states, errors, inputs and outputs (``angle [rad]: true vs estimated``). A quantity whose unit
no system declares (an observer's gain, a parameter estimate) has no bracket.

Each entity row costs about 20 bytes of row id and time on top of its values: sharing an
entity per state (rather than one per observer and state) keeps the 10 s, 1 kHz pendulum
recording with two observers under 2.35 MB (BENCHMARKS.md, ``scripts/bench_record.py``).

Estimates are matched to the plant's states by name (:func:`estimate_layout`): each observer's
columns are named by its ``state_names``; an observer given none names the plant's states when
its estimate has their number, else ``x_hat_1, x_hat_2, ...``. A plant state no observer
estimates has a truth-only ``/state`` entity and no ``/error`` entity.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache

import rerun as rr
import rerun.blueprint as rrb

from ..exceptions import DesignError

SIM_TIME = "sim_time"
STEP = "step"
EPISODE = "episode"

#: colour of the true signals (the true robot keeps the MJCF's colours)
TRUE_COLOR = (230, 230, 230)
MEASURED_COLOR = (130, 130, 130)
INPUT_COLOR = (255, 196, 0)
EXTRA_COLOR = (120, 200, 255)
#: one colour per observer, in order (tab10 without its grey)
OBSERVER_COLORS = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
                   (140, 86, 75), (227, 119, 194), (188, 189, 34), (23, 190, 207))
#: alpha of the estimate ghosts in the 3D view (0-255)
GHOST_ALPHA = 90

#: root of the geometry posed from the true state
TRUE_ROOT = "/world/true"

_GAIN_KEYS = ("k", "gain", "gamma")
_THETA_PREFIXES = ("theta_hat_", "theta_hat", "theta_", "theta")


def part(name: object) -> str:
    """``name`` as one entity path part (escaped)."""
    return rr.escape_entity_path_part(str(name))


def observer_color(i: int) -> tuple[int, int, int]:
    """Colour of the ``i``-th observer of a recording (the same in every view).

    Parameters
    ----------
    i : int
        The observer's position in the recorder's ``observers`` (0 first).

    Returns
    -------
    tuple of int
        ``(r, g, b)`` in 0-255, from :data:`OBSERVER_COLORS` (tab10 without its grey),
        repeating after 9 observers.

    Examples
    --------
    >>> observer_color(0), observer_color(1), observer_color(9) == observer_color(0)
    ((31, 119, 180), (255, 127, 14), True)
    """
    return OBSERVER_COLORS[i % len(OBSERVER_COLORS)]


#: the roots of the entities holding one series per source (truth, observers, clean and
#: measured), whatever their number (:func:`hgo_mj.record.read` names their columns so)
SERIES_ROOTS = ("/state/", "/error/", "/sensor/")
#: the truth's series under ``/state/<state>`` (``<state> true``: no observer may take the name)
TRUE = "true"


def label(name: str, unit: str | None) -> str:
    """A series or view name with its unit: ``"angle [rad]"``, ``"k [-]"`` for a dimensionless
    quantity; ``name`` alone when the unit is not known (``None``)."""
    return name if unit is None else f"{name} [{unit or '-'}]"


def state_path(state: str) -> str:
    """The entity of a plant state: its truth and every observer's estimate of it.

    Parameters
    ----------
    state : str
        A plant state's name (escaped as one path part).

    Returns
    -------
    str
        ``/state/<state>``.

    Examples
    --------
    >>> state_path("angle")
    '/state/angle'
    >>> print(state_path("x/y"))  # escaped: one part
    /state/x\\/y
    """
    return f"/state/{part(state)}"


def error_path(state: str) -> str:
    """``x - x_hat`` of every observer that estimates a plant state.

    Parameters
    ----------
    state : str
        A plant state's name.

    Returns
    -------
    str
        ``/error/<state>``.

    Examples
    --------
    >>> error_path("angle")
    '/error/angle'
    """
    return f"/error/{part(state)}"


def own_estimate_path(observer: str, name: str) -> str:
    """An estimate of ``observer`` that is not a plant state.

    Parameters
    ----------
    observer : str
        The observer's name.
    name : str
        The estimate's name in the observer's ``state_names`` (``z1``, ``angle_d2``, ...).

    Returns
    -------
    str
        ``/observer/<observer>/estimate/<name>``.

    Examples
    --------
    >>> own_estimate_path("hgo", "z1")
    '/observer/hgo/estimate/z1'
    """
    return f"/observer/{part(observer)}/estimate/{part(name)}"


def sensor_path(output: str) -> str:
    """The clean and measured values of an output.

    Parameters
    ----------
    output : str
        An output's name (``plant.output_names``).

    Returns
    -------
    str
        ``/sensor/<output>``: the series ``<output> clean`` (before the sensor chain) and
        ``<output> measured`` (what the observers saw).

    Examples
    --------
    >>> sensor_path("angle")
    '/sensor/angle'
    """
    return f"/sensor/{part(output)}"


def input_path(name: str) -> str:
    """The input ``name`` (scalar ``u``).

    Parameters
    ----------
    name : str
        An input's name (``plant.input_names``).

    Returns
    -------
    str
        ``/input/<name>``.

    Examples
    --------
    >>> input_path("torque")
    '/input/torque'
    """
    return f"/input/{part(name)}"


def extra_path(name: str) -> str:
    return f"/env/{part(name)}"


def param_path(param: str) -> str:
    """The true value of a system parameter, next to its estimates."""
    return f"/plant/param/{param}"


def ghost_root(observer: str) -> str:
    """Root of the geometry posed from ``observer``'s estimate."""
    return f"/world/estimate/{part(observer)}"


def body_path(root: str, body: str) -> str:
    return f"{root}/{part(body)}"


def geom_path(root: str, body: str, geom: str) -> str:
    return f"{root}/{part(body)}/{part(geom)}"


def diagnostic_path(observer: str, key: str, param_names: Sequence[str] = ()) -> tuple[str, str]:
    """Entity path and kind (``"gain"``, ``"theta"`` or ``"other"``) of one diagnostic.

    ``k``, ``gain`` and ``gamma`` go to ``/observer/<obs>/gain`` (``k_<x>``, ... below it); a key
    that is a parameter name of the system, or starts with ``theta`` (``theta_hat_<p>``,
    ``theta_<p>``, ``theta<p>``), to ``/observer/<obs>/theta/<p>``; anything else to
    ``/observer/<obs>/diagnostics/<key>``.

    Parameters
    ----------
    observer : str
        The observer's name.
    key : str
        A key of its diagnostics (``ObserverRecord.diagnostics``).
    param_names : sequence of str
        The system's parameter names: a key among them is a parameter estimate.

    Returns
    -------
    path : str
        The diagnostic's entity path.
    kind : str
        ``"gain"``, ``"theta"`` or ``"other"`` (which view of the blueprint shows it).

    Examples
    --------
    >>> diagnostic_path("k40", "k")
    ('/observer/k40/gain', 'gain')
    >>> diagnostic_path("adaptive", "theta_hat_mass")
    ('/observer/adaptive/theta/mass', 'theta')
    >>> diagnostic_path("adaptive", "mass", ["mass"])
    ('/observer/adaptive/theta/mass', 'theta')
    >>> diagnostic_path("k40", "dropouts")
    ('/observer/k40/diagnostics/dropouts', 'other')
    """
    o = part(observer)
    low = key.lower().rstrip("_")
    if low in _GAIN_KEYS:
        return f"/observer/{o}/gain", "gain"
    for g in _GAIN_KEYS:
        if low.startswith(g + "_"):
            return f"/observer/{o}/gain/{part(key[len(g) + 1:])}", "gain"
    if key in param_names:
        return f"/observer/{o}/theta/{part(key)}", "theta"
    for pre in _THETA_PREFIXES:
        if low.startswith(pre) and len(key) > len(pre):
            param = key[len(pre):].strip("_")
            return f"/observer/{o}/theta/{part(param or key)}", "theta"
    if low == "theta":
        return f"/observer/{o}/theta/theta", "theta"
    return f"/observer/{o}/diagnostics/{part(key)}", "other"


def has_dropout_stage(stages: Sequence[Mapping[str, object]] | None) -> bool:
    """Whether a sensor chain (:meth:`hgo_mj.sensors.SensorChain.describe`: a list of
    ``{"stage": name, ...}``; ``None``: no sensor chain) has a dropout stage."""
    return any(isinstance(st, Mapping) and st.get("stage") == "dropout" for st in stages or ())


def theta_param(path: str) -> str:
    """The parameter of a ``/observer/<obs>/theta/<p>`` path."""
    return path.rsplit("/theta/", 1)[1]


# --------------------------------------------------------------------------- estimates
@dataclass(frozen=True)
class EstimateLayout:
    """Which estimate column goes where, fixed at a recording's first block.

    Attributes
    ----------
    state_names, observers : tuple of str
        The plant's states and the observers, in order.
    names : mapping observer -> tuple of str
        The names of each observer's estimate columns.
    est_of : tuple, one entry per plant state
        The ``(observer, column)`` pairs estimating that state, in observer order.
    own : mapping observer -> tuple of (name, column)
        Each observer's columns that are not plant states.
    """

    state_names: tuple[str, ...]
    observers: tuple[str, ...]
    names: Mapping[str, tuple[str, ...]]
    est_of: tuple[tuple[tuple[str, int], ...], ...]
    own: Mapping[str, tuple[tuple[str, int], ...]]

    def joint_observers(self, njoints: int) -> set[str]:
        """The observers estimating at least one of the first ``njoints`` states (the joint
        positions of a MuJoCo plant: they get a ghost)."""
        return {o for ests in self.est_of[:njoints] for o, _ in ests}

    def joint_columns(self, observer: str, njoints: int) -> list[int | None]:
        """Per joint position (the first ``njoints`` states), the column of ``observer``'s
        estimate holding it, or ``None``."""
        cols = {s: j for j, s in enumerate(self.names[observer])}
        return [cols.get(s) for s in self.state_names[:njoints]]


def check_names(observer: str, names: Sequence[object]) -> tuple[str, ...]:
    """The estimate column names of ``observer``: distinct and not empty."""
    out = tuple(str(s) for s in names)
    if not out or len(set(out)) != len(out):
        raise DesignError(f"the estimate names of {observer!r} must be distinct and not empty; "
                          f"found {list(out)}")
    return out


def default_names(state_names: Sequence[str], width: int) -> tuple[str, ...]:
    """Names of an observer's ``width`` estimate columns when it gives none: the plant's
    states when the widths agree, else ``x_hat_1, x_hat_2, ...``."""
    if width == len(state_names):
        return tuple(state_names)
    return tuple(f"x_hat_{j + 1}" for j in range(width))


def estimate_layout(state_names: Sequence[str], observers: Sequence[str],
                    names: Mapping[str, Sequence[str]]) -> EstimateLayout:
    """Match every observer's estimate columns (``names``) to the plant's states by name."""
    states, obs = tuple(state_names), tuple(observers)
    named = {o: tuple(names[o]) for o in obs}
    cols = {o: {s: j for j, s in enumerate(named[o])} for o in obs}
    est_of = tuple(tuple((o, cols[o][s]) for o in obs if s in cols[o]) for s in states)
    plant = set(states)
    own = {o: tuple((s, j) for j, s in enumerate(named[o]) if s not in plant) for o in obs}
    return EstimateLayout(states, obs, named, est_of, own)


# --------------------------------------------------------------------------- styles
def series_lines(names: Sequence[str], colors: Sequence[Sequence[int]],
                 widths: Sequence[float] | None = None, *, steps: bool = False) -> rr.SeriesLines:
    """The style of one series entity (``steps``: drawn as a piecewise-constant line)."""
    return _series_lines(tuple(names), tuple(tuple(c) for c in colors),
                         None if widths is None else tuple(widths), steps)


@lru_cache(maxsize=1024)
def _series_lines(names: tuple[str, ...], colors: tuple[tuple[int, ...], ...],
                  widths: tuple[float, ...] | None, steps: bool) -> rr.SeriesLines:
    # built once per process (an archetype costs tens of microseconds to convert); logging
    # the same object again makes new chunks
    return rr.SeriesLines(names=list(names), colors=list(colors),
                          widths=None if widths is None else list(widths),
                          interpolation_mode="StepAfter" if steps else None)


def signal_styles(layout: EstimateLayout, output_names: Sequence[str],
                  input_names: Sequence[str], units: Mapping[str, str] | None = None
                  ) -> list[tuple[str, rr.SeriesLines]]:
    """Entity path and style of every per-sample series: each state's truth and estimates,
    errors, the observers' own estimates, outputs and inputs, each named with its unit
    (``units``: ``{name: unit}`` of states, outputs, inputs and output derivatives)."""
    units = units or {}
    out: list[tuple[str, rr.SeriesLines]] = []
    color = {o: observer_color(i) for i, o in enumerate(layout.observers)}
    for s, ests in zip(layout.state_names, layout.est_of):
        u = units.get(s)
        obs = [o for o, _ in ests]
        out.append((state_path(s), series_lines(
            [label(f"{s} {TRUE}", u)] + [label(f"{s} {o}", u) for o in obs],
            [TRUE_COLOR] + [color[o] for o in obs], [2.0] + [1.0] * len(obs))))
        if obs:
            out.append((error_path(s), series_lines([label(f"{s} error {o}", u) for o in obs],
                                                    [color[o] for o in obs])))
    for o, own in layout.own.items():
        out += [(own_estimate_path(o, name),
                 series_lines([label(f"{name} {o}", units.get(name))], [color[o]]))
                for name, _ in own]
    out += [(sensor_path(y), series_lines([label(f"{y} clean", units.get(y)),
                                           label(f"{y} measured", units.get(y))],
                                          [TRUE_COLOR, MEASURED_COLOR], [1.5, 1.0]))
            for y in output_names]
    out += [(input_path(u), series_lines([label(u, units.get(u))], [INPUT_COLOR]))
            for u in input_names]
    return out


def diagnostic_styles(observer: str, index: int, key: str, params: Collection[str]
                      ) -> list[tuple[str, rr.SeriesLines]]:
    """Entity path and style of one diagnostic of the ``index``-th observer, and of the true
    parameter next to a parameter estimate (both drawn as steps). The dropout count is
    dimensionless; the other diagnostics' units are not declared."""
    path, kind = diagnostic_path(observer, key, tuple(params))
    name = label(f"{observer} {key}", "" if key == "dropouts" else None)
    out = [(path, series_lines([name], [observer_color(index)], steps=True))]
    if kind == "theta" and theta_param(path) in params:
        p = theta_param(path)
        out.append((param_path(p), series_lines([f"{p} true"], [TRUE_COLOR], steps=True)))
    return out


def extra_style(name: str) -> tuple[str, rr.SeriesLines]:
    """Entity path and style of an environment extra (reward, ...)."""
    return extra_path(name), series_lines([name], [EXTRA_COLOR])


# --------------------------------------------------------------------------- blueprint
def _adaptive_views(diagnostics: Sequence[tuple[str, str]],
                    params: Collection[str]) -> list[rrb.TimeSeriesView]:
    """Gains, one view per estimated parameter (with its true value), other diagnostics."""
    gains = [p for p, k in diagnostics if k == "gain"]
    other = [p for p, k in diagnostics if k == "other"]
    thetas: dict[str, list[str]] = {}
    for p, k in diagnostics:
        if k == "theta":
            thetas.setdefault(theta_param(p), []).append(p)
    views = []
    if gains:
        views.append(rrb.TimeSeriesView(origin="/observer", contents=gains, name="gains"))
    for param, paths in thetas.items():
        true = [param_path(param)] if param in params else []
        views.append(rrb.TimeSeriesView(origin="/observer", contents=true + paths,
                                        name=f"{param}: true vs estimated"))
    if other:
        views.append(rrb.TimeSeriesView(origin="/observer", contents=other,
                                        name="other diagnostics"))
    return views


def _with_units(names: Sequence[str], units: Mapping[str, str]) -> str:
    """``"torque [N m]"``, or ``"torque1, torque2 [N m]"`` when they share a unit."""
    found = {units.get(n) for n in names}
    if len(found) == 1:
        return label(", ".join(names), found.pop())
    return ", ".join(label(n, units.get(n)) for n in names)


def blueprint(layout: EstimateLayout, diagnostics: Sequence[tuple[str, str]] = (),
              params: Collection[str] = (), *, extras: bool = False, world: bool = False,
              units: Mapping[str, str] | None = None, output_names: Sequence[str] = (),
              input_names: Sequence[str] = ()) -> rrb.Blueprint:
    """The default layout of a recording: 3D view (``world``) and text documents, one view
    per state (truth and estimates), one per estimated state's errors, the observers' own
    estimates, the adaptive quantities (``diagnostics``: ``(path, kind)`` pairs of
    :func:`diagnostic_path`), inputs, measurements and the environment's ``extras``; the
    views of quantities with a unit (``units``) name it."""
    units = units or {}
    states = [rrb.TimeSeriesView(origin=state_path(s),
                                 name=f"{label(s, units.get(s))}: true vs estimated")
              for s in layout.state_names]
    states += [rrb.TimeSeriesView(origin=f"/observer/{part(o)}/estimate",
                                  name=f"{o}: estimates that are not plant states")
               for o, own in layout.own.items() if own]
    errors = [rrb.TimeSeriesView(origin=error_path(s),
                                 name=f"{label(s, units.get(s))}: error x - x_hat")
              for s, ests in zip(layout.state_names, layout.est_of) if ests]
    side: list[rrb.TimeSeriesView] = _adaptive_views(diagnostics, params)
    side.append(rrb.TimeSeriesView(
        origin="/input", name="inputs" + (f": {_with_units(input_names, units)}"
                                          if input_names else "")))
    side.append(rrb.TimeSeriesView(
        origin="/sensor", name="outputs, clean and measured" + (
            f": {_with_units(output_names, units)}" if output_names else "")))
    if extras:
        side.append(rrb.TimeSeriesView(origin="/env", name="environment"))
    docs = rrb.Tabs(rrb.TextDocumentView(origin="/metrics", name="metrics"),
                    rrb.TextDocumentView(origin="/scenario", name="scenario"))
    left: rrb.Container = docs
    if world:
        left = rrb.Vertical(
            rrb.Spatial3DView(origin="/world", name="robot: true (solid), estimates (ghosts)"),
            docs, row_shares=[3, 2])
    columns: list[rrb.Container] = [left, rrb.Vertical(*states, name="states")]
    if errors:
        columns.append(rrb.Vertical(*errors, name="errors"))
    columns.append(rrb.Vertical(*side, name="adaptive, inputs, outputs"))
    return rrb.Blueprint(rrb.Horizontal(*columns), rrb.TimePanel(timeline=SIM_TIME))


__all__ = ["EPISODE", "SERIES_ROOTS", "SIM_TIME", "STEP", "TRUE", "diagnostic_path",
           "error_path", "input_path", "observer_color", "own_estimate_path", "sensor_path",
           "state_path"]
