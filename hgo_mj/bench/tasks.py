"""The benchmark's tasks: named, versioned, frozen by their hash.

A task (``pendulum/encoder-v1``) fixes everything an observer is judged on: the plant, its
initial state and input, the sensor (a preset of :mod:`hgo_mj.bench.presets` with datasheet
parameters), the sample period, the model the observers are given (``mismatch``: the
observers' ``system_params``, empty for the nominal tier), the duration and the transient
window, disjoint **tuning seeds** and **scoring seeds**, and the states scored. Its definition
is frozen: :func:`task_hash` is the SHA-256 of its canonical JSON, and ``tests/bench`` holds
each version's hash, so a change of a task is a new version (``-v2``), never a silent edit.
A field added to :class:`Task` after the first tasks (:data:`_LATER`) enters the hash only
where a task sets it, so adding a field changes no existing task's hash.

**Tiers.** Nominal; *parameter mismatch* (``mismatch``: the observers' model 10 % off, given
to the observers that step an MJCF as ``model_fields``, the same error written into their copy
of the model, since ``system_params`` do not reach an MJCF); *unmodelled Coulomb friction* (the
plant's ``model_fields``: ``dof_frictionloss`` the observers' equations do not have); and the
*sampled* tier. A task that a later version replaces is kept by name (its results stay
reproducible) but left out of the full suite (:data:`SUPERSEDED`).

A user's task is a TOML file of the same tables (:func:`load_task`) and is scored next to the
built-in ones.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from ..exceptions import DesignError
from .presets import preset

__all__ = ["SUITES", "SUITE_OBSERVERS", "SUPERSEDED", "TASKS", "Task", "load_task", "task_hash",
           "tasks_of"]

MECH_INPUT = {"type": "multisine", "amplitudes": [0.3, 0.15], "frequencies": [0.4, 1.1]}


@dataclass(frozen=True)
class Task:
    """One benchmark task (module docstring).

    Parameters
    ----------
    name : str
        ``plant/sensor-vN``.
    plant : dict
        The scenario's ``[plant]`` table (``name`` or ``model``, ``dt``, ``x0``).
    input : dict or list of dict
        The scenario's ``[input]`` (open loop; one table per actuator as a list).
    sensor : str
        A preset of :data:`~hgo_mj.bench.presets.PRESETS`.
    sensor_params : dict
        Its datasheet parameters.
    duration : float
        Seconds.
    t_transient : float
        The steady-state scores start here.
    sample_period : float or None
        The observers' sample period (None: the plant's step).
    mismatch : dict
        Parameters of the observers' model that differ from the plant's (empty: nominal).
    model_fields : dict
        The same mismatch for the observers whose model is the MJCF (``ekf_mujoco``,
        ``ukf_mujoco``): ``"field[element]"`` -> value written into their copy of the model.
    tuning_seeds, scoring_seeds : tuple of int
        Disjoint.
    states : tuple of str
        The scored states (empty: every plant state an observer estimates).
    description : str
        What makes it hard (the docs' task page).

    Examples
    --------
    >>> t = TASKS["pendulum/encoder-v1"]
    >>> t.sensor, t.scoring_seeds[:2], len(task_hash(t))
    ('encoder', (101, 102), 64)
    """

    name: str
    plant: dict[str, Any]
    input: Any
    sensor: str
    sensor_params: dict[str, Any] = field(default_factory=dict)
    duration: float = 10.0
    t_transient: float = 2.0
    sample_period: float | None = None
    mismatch: dict[str, Any] = field(default_factory=dict)
    tuning_seeds: tuple[int, ...] = (1, 2, 3, 4)
    scoring_seeds: tuple[int, ...] = (101, 102, 103, 104, 105, 106, 107, 108)
    states: tuple[str, ...] = ()
    description: str = ""
    model_fields: dict[str, Any] = field(default_factory=dict)

    def scenario(self) -> dict[str, Any]:
        """The task as a scenario without observers (``hgo-mj run``'s tables).

        Returns
        -------
        dict

        Examples
        --------
        >>> sorted(TASKS["pendulum/encoder-v1"].scenario())
        ['input', 'name', 'plant', 'run', 'sensor']
        """
        stages, _ = preset(self.sensor, self.sensor_params)
        run: dict[str, Any] = {"duration": self.duration}
        if self.sample_period is not None:
            run["sample_period"] = self.sample_period
        return {"name": self.name, "plant": json.loads(json.dumps(self.plant)),
                "sensor": {"stages": stages}, "input": json.loads(json.dumps(self.input)),
                "run": run}

    @property
    def sensor_std(self) -> float:
        """The measurement's steady-state standard deviation (the preset's)."""
        return preset(self.sensor, self.sensor_params)[1]


def task_hash(task: Task) -> str:
    """The SHA-256 of the task's canonical JSON (every field; the hash a version is frozen by).

    Parameters
    ----------
    task : Task

    Returns
    -------
    str
        64 hexadecimal digits.

    Examples
    --------
    >>> task_hash(TASKS["pendulum/encoder-v1"]) == task_hash(TASKS["pendulum/encoder-v1"])
    True
    """
    fields = asdict(task)
    for key, default in _LATER.items():
        if fields[key] == default:
            del fields[key]
    doc = json.dumps(fields, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(doc.encode()).hexdigest()


def _t(name: str, plant: dict[str, Any], sensor: str, **kw: Any) -> Task:
    return Task(name=name, plant=plant, input=kw.pop("input", MECH_INPUT), sensor=sensor, **kw)


#: fields added to Task after its first version -> their default (left out of the hash there)
_LATER: dict[str, Any] = {"model_fields": {}}

_PEND = {"name": "pendulum", "dt": 0.001, "x0": [0.5, 0.0]}
#: the pendulum's model 10 % heavier (mass and inertia about the centre of mass: the inertia
#: about the hinge too) and 10 % more damped, as system parameters and as MJCF fields
_PEND_WRONG = {"mass": 0.275, "inertia": 0.05963867708333334, "damping": 0.011}
_PEND_WRONG_MJCF = {"body_mass[pole]": 0.275,
                    "body_inertia[pole]": [0.003951177083333334, 0.003951177083333334,
                                           5.568750000000002e-05],
                    "dof_damping[hinge]": 0.011}
_CART = {"name": "cart_pendulum", "dt": 0.001, "x0": [0.1, 0.0]}
_EJ = {"name": "elastic_joint", "dt": 0.001, "x0": [0.3, 0.3, 0.0, 0.0]}
_EJ2 = {"name": "elastic_joint_2link", "dt": 0.001}
_BIO = {"name": "bioreactor_bullinger", "dt": 0.01, "x0": [0.075, 0.03]}
_BG = {"name": "bioreactor_bastin_gevers", "dt": 0.01, "x0": [1.0, 1.0]}
_BIO_IN = {"type": "multisine", "amplitudes": [0.02], "frequencies": [0.05], "offset": 0.06}
_BG_IN = [{"type": "multisine", "amplitudes": [0.2], "frequencies": [0.1], "offset": 0.5},
          {"type": "constant", "value": 1.0}]
_BES = {"name": "besancon_ex1", "dt": 0.001}
_JS = {"name": "jo_son", "dt": 0.001}
_SINE1 = {"type": "multisine", "amplitudes": [1.0], "frequencies": [0.5]}

#: every built-in task by name
TASKS: dict[str, Task] = {t.name: t for t in (
    _t("pendulum/encoder-v1", _PEND, "encoder",
       description="A pendulum read by a 4096-count encoder: the velocity must come from a "
                   "quantized angle; a high gain amplifies the quantization."),
    _t("pendulum/mems-v1", _PEND, "mems",
       description="A MEMS angle sensor: white noise, a turn-on bias per seed and a random-walk "
                   "bias, 2 ms late: the bias is not zero-mean, so no gain removes it."),
    _t("pendulum/vision-v1", _PEND, "vision", duration=15.0, t_transient=3.0,
       description="A 30 Hz camera, 40 ms late, 5 % frames lost, 1 % outliers: the observer "
                   "runs at 1 kHz on a measurement held for 33 ms."),
    _t("pendulum/analog-v1", _PEND, "analog", sensor_params={"low": -0.6, "high": 0.6},
       description="An analog angle sensor through a 12-bit ADC that saturates at 0.6 rad: "
                   "the swing leaves the range."),
    _t("pendulum/encoder-mismatch-v1", _PEND, "encoder",
       mismatch={"mass": 0.275, "inertia": 0.0596387, "damping": 0.011},
       description="The encoder task with the observers' model 10 % heavier and more damped "
                   "than the plant."),
    _t("pendulum/encoder-sampled-v1", _PEND, "encoder", sample_period=0.01,
       description="The encoder read every 10 ms (a slow fieldbus): near the sampling bound "
                   "paper 004's LMI certifies for the Riccati observer."),
    _t("cart_pendulum/encoder-v1", _CART, "encoder",
       input={"type": "multisine", "amplitudes": [0.5, 0.25], "frequencies": [0.4, 1.1]},
       description="The pendulum on a cart driven by its acceleration (paper 004's plant)."),
    _t("elastic_joint/encoder-v1", _EJ, "encoder", sensor_params={"counts_per_rev": 16384},
       description="A flexible joint (8.6 Hz resonance), only the link angle measured: the "
                   "motor velocity is the third derivative of the measurement."),
    _t("elastic_joint/mems-v1", _EJ, "mems",
       description="The elastic joint read by a biased, delayed MEMS sensor."),
    _t("elastic_joint/encoder-mismatch-v1", _EJ, "encoder",
       sensor_params={"counts_per_rev": 16384}, mismatch={"stiffness": 9.0},
       description="The elastic joint with the observers' stiffness 10 % low."),
    _t("elastic_joint_2link/encoder-v1", _EJ2, "encoder",
       sensor_params={"counts_per_rev": 16384}, duration=8.0,
       input={"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
       description="The two-link elastic arm, both link angles measured."),
    _t("bioreactor_bullinger/analog-v1", _BIO, "analog",
       sensor_params={"std": 1e-4, "low": 0.0, "high": 0.5}, input=_BIO_IN, duration=40.0,
       t_transient=10.0,
       description="Bullinger's bioreactor (paper 000): the substrate from a noisy biomass "
                   "reading, over hours."),
    _t("bioreactor_bastin_gevers/analog-v1", _BG, "analog",
       sensor_params={"std": 1e-3, "low": 0.0, "high": 10.0}, input=_BG_IN, duration=40.0,
       t_transient=10.0,
       description="Bastin and Gevers' bioreactor (their example): adaptive observers "
                   "estimate the kinetics."),
    _t("besancon_ex1/analog-v1", _BES, "analog", sensor_params={"std": 1e-3, "low": -5.0,
                                                                 "high": 5.0},
       input=_SINE1, duration=20.0, t_transient=5.0,
       description="Besançon, Zhang and Hammouri's example 1: state and parameter."),
    _t("jo_son/analog-v1", _JS, "analog", sensor_params={"std": 1e-3, "low": -5.0,
                                                          "high": 5.0},
       input=_SINE1, duration=20.0, t_transient=5.0,
       description="Jo and Son's example: an adaptive observer's parameter convergence."),
    _t("cart_pendulum/vision-v1", _CART, "vision", duration=15.0, t_transient=3.0,
       input={"type": "multisine", "amplitudes": [0.5, 0.25], "frequencies": [0.4, 1.1]},
       description="The cart pendulum tracked by a slow, late camera."),
    _t("pendulum/encoder-mismatch-v2", _PEND, "encoder", mismatch=_PEND_WRONG,
       model_fields=_PEND_WRONG_MJCF,
       description="The encoder task with the observers' model 10 % heavier and more damped "
                   "than the plant, the MJCF filters' model too (v1 gave them the true MJCF)."),
    _t("elastic_joint/encoder-mismatch-v2", _EJ, "encoder",
       sensor_params={"counts_per_rev": 16384}, mismatch={"stiffness": 9.0},
       model_fields={"tendon_stiffness[spring]": 9.0},
       description="The elastic joint with the observers' stiffness 10 % low, the MJCF "
                   "filters' too (v1 gave them the true MJCF)."),
    _t("elastic_joint_2link/encoder-v2", _EJ2, "encoder",
       sensor_params={"counts_per_rev": 16384}, duration=8.0,
       input=[{"type": "multisine", "amplitudes": [0.3], "frequencies": [0.5]},
              {"type": "multisine", "amplitudes": [0.3], "frequencies": [0.8]}],
       description="The two-link elastic arm, both link angles measured, both motors driven "
                   "(v1 gave the two-input arm a one-channel input: no run could start)."),
    _t("pendulum/encoder-friction-v1", {**_PEND, "model_fields": {
        "dof_frictionloss[hinge]": 0.02}}, "encoder",
       description="The encoder task on a pendulum with 0.02 N m of Coulomb friction in its "
                   "bearing (MuJoCo's frictionloss), which no observer's model has: the "
                   "velocity stalls at the turning points."),
)}

#: the lab plants (MJCF, two measured joints, one actuator): what a lab bench has
LAB_TASKS: dict[str, Task] = {t.name: t for t in (
    _t("furuta/encoder-v1", {"name": "furuta", "dt": 0.001, "x0": [0.0, 0.3, 0.0, 0.0]},
       "encoder", input={"type": "multisine", "amplitudes": [1.0, 0.5],
                         "frequencies": [0.4, 1.1]},
       description="A Furuta (rotary) pendulum, arm and pendulum angles read by encoders, "
                   "the arm driven by its motor voltage: the arm's motion couples into the "
                   "pendulum through the Coriolis terms."),
    _t("acrobot/encoder-v1", {"name": "acrobot", "dt": 0.001, "x0": [0.3, 0.0, 0.0, 0.0]},
       "encoder", input={"type": "multisine", "amplitudes": [0.5, 0.25],
                         "frequencies": [0.4, 1.1]},
       description="The acrobot, both joint angles read by encoders, only the elbow driven: "
                   "the shoulder's velocity comes from an unactuated joint."),
    _t("cart_pole/encoder-v1", {"name": "cart_pole", "dt": 0.001, "x0": [0.0, 0.3, 0.0, 0.0]},
       "encoder", input={"type": "multisine", "amplitudes": [0.3, 0.15],
                         "frequencies": [0.4, 1.1]},
       description="A cart-pole pushed by a multisine force, the cart's position (a linear "
                   "encoder of 1.5 mm resolution) and the pole's angle measured."),
)}
TASKS.update(LAB_TASKS)

#: superseded task -> its successor (kept by name, left out of the full suite)
SUPERSEDED: dict[str, str] = {
    "pendulum/encoder-mismatch-v1": "pendulum/encoder-mismatch-v2",
    "elastic_joint/encoder-mismatch-v1": "elastic_joint/encoder-mismatch-v2",
    "elastic_joint_2link/encoder-v1": "elastic_joint_2link/encoder-v2",
}

#: suite -> task names
SUITES: dict[str, tuple[str, ...]] = {
    "quick": ("pendulum/encoder-v1", "pendulum/vision-v1", "elastic_joint/encoder-v1",
              "bioreactor_bullinger/analog-v1"),
    "full": tuple(t for t in TASKS if t not in SUPERSEDED),
}

#: the observers a suite runs when none are named: the quick suite leaves out the filters that
#: step a MuJoCo model per member and sample (``ekf_mujoco``, ``ukf_mujoco``: 10-100x the cost
#: of the others) and the moving-horizon estimator, so that ``make demo`` stays within a minute
SUITE_OBSERVERS: dict[str, tuple[str, ...]] = {
    "quick": ("high_gain", "adaptive_gain", "riccati", "ekf", "ukf", "finite_difference",
              "super_twisting", "extended_luenberger", "bastin_gevers", "besancon"),
}

_FIELDS = {"name", "plant", "input", "sensor", "sensor_params", "duration", "t_transient",
           "sample_period", "mismatch", "tuning_seeds", "scoring_seeds", "states", "description",
           "model_fields"}


def load_task(path: str | Path) -> Task:
    """A user's task from a TOML file with the fields of :class:`Task` (``name``,
    ``[plant]``, ``[input]``, ``sensor``, optional ``[sensor_params]``, ``duration``, ...).

    Parameters
    ----------
    path : path
        The TOML file.

    Returns
    -------
    Task

    Raises
    ------
    DesignError
        A missing file, not TOML, an unknown or missing field, seeds that overlap or are not
        integers, a name without ``-v<N>``, a bad sensor preset, a non-positive duration.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> with tempfile.TemporaryDirectory() as d:
    ...     f = pathlib.Path(d) / "t.toml"
    ...     _ = f.write_text('name = "mine/encoder-v1"\\nsensor = "encoder"\\n'
    ...                      '[plant]\\nname = "pendulum"\\n[input]\\ntype = "constant"\\n')
    ...     load_task(f).name
    'mine/encoder-v1'
    """
    try:
        import tomllib
    except ModuleNotFoundError:  # pragma: no cover - Python 3.10
        import tomli as tomllib  # type: ignore[no-redef]

    p = Path(path)
    if not p.is_file():
        raise DesignError(f"task file {str(p)!r} does not exist")
    try:
        doc = tomllib.loads(p.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise DesignError(f"task file {str(p)!r} is not TOML: {exc}") from None
    return task_from_dict(doc, str(p))


def task_from_dict(doc: Mapping[str, Any], where: str = "task") -> Task:
    """A :class:`Task` from a mapping of its fields, checked (:func:`load_task`)."""
    bad = sorted(set(doc) - _FIELDS)
    if bad:
        raise DesignError(f"{where}: unknown field(s) {bad}; valid: {sorted(_FIELDS)}")
    missing = [k for k in ("name", "plant", "input", "sensor") if k not in doc]
    if missing:
        raise DesignError(f"{where}: missing field(s) {missing} (a task needs name, [plant], "
                          f"[input] and sensor)")
    name = doc["name"]
    if not isinstance(name, str) or "-v" not in name or not name.rsplit("-v", 1)[1].isdigit():
        raise DesignError(f"{where}: name must end in -v<N> (a version), e.g. "
                          f"'pendulum/encoder-v1'; found {name!r}")
    kw = dict(doc)
    for key in ("tuning_seeds", "scoring_seeds"):
        if key in kw:
            kw[key] = _seeds(kw[key], key, where)
    task = Task(**{k: v for k, v in kw.items() if k in _FIELDS})
    if set(task.tuning_seeds) & set(task.scoring_seeds):
        raise DesignError(f"{where}: tuning and scoring seeds must be disjoint; both have "
                          f"{sorted(set(task.tuning_seeds) & set(task.scoring_seeds))}")
    for key in ("duration", "t_transient"):
        v = getattr(task, key)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise DesignError(f"{where}: {key} must be a number >= 0; found {v!r}")
    if not task.t_transient < task.duration:
        raise DesignError(f"{where}: t_transient must be < duration; found {task.t_transient} "
                          f">= {task.duration}")
    preset(task.sensor, task.sensor_params)
    return Task(**{**asdict(task), "states": tuple(task.states)})


def _seeds(seeds: Any, key: str, where: str) -> tuple[int, ...]:
    if not isinstance(seeds, Sequence) or isinstance(seeds, str) or not seeds or not all(
            isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in seeds):
        raise DesignError(f"{where}: {key} must be a non-empty list of integers >= 0; "
                          f"found {seeds!r}")
    return tuple(seeds)


def tasks_of(suite: str | None = None, names: Sequence[str] = (),
             files: Sequence[str | Path] = ()) -> list[Task]:
    """The tasks of a suite, of names and of user task files, in that order, each once.

    Parameters
    ----------
    suite : str, optional
        ``"quick"`` or ``"full"``.
    names : sequence of str
        Built-in task names.
    files : sequence of path
        User task TOML files.

    Returns
    -------
    list of Task

    Raises
    ------
    DesignError
        An unknown suite or task name (the valid ones listed), a bad task file, or nothing.

    Examples
    --------
    >>> [t.name for t in tasks_of("quick")][:2]
    ['pendulum/encoder-v1', 'pendulum/vision-v1']
    """
    out: dict[str, Task] = {}
    if suite is not None:
        if suite not in SUITES:
            raise DesignError(f"unknown suite {suite!r}; valid: {sorted(SUITES)}")
        out.update((n, TASKS[n]) for n in SUITES[suite])
    for n in names:
        if n not in TASKS:
            raise DesignError(f"unknown task {n!r}; valid: {sorted(TASKS)}")
        out[n] = TASKS[n]
    for f in files:
        t = load_task(f)
        out[t.name] = t
    if not out:
        raise DesignError("no task: give a suite, task names or task files")
    return list(out.values())
