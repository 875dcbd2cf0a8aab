"""The errors hgo_mj raises.

Every error says what was expected and what was found. They subclass the builtin
errors a caller would catch anyway (``ValueError``, ``RuntimeError``).
"""

from __future__ import annotations

__all__ = ["DesignError", "DimensionError", "DivergenceError", "HgoError", "ManifestError",
           "MissingExtraError", "ModelError", "RecordingError", "TrajectoryFileError"]


class HgoError(Exception):
    """Base class of every error raised on purpose by hgo_mj.

    Examples
    --------
    >>> from hgo_mj.inputs import make_signal
    >>> try:
    ...     make_signal("sine")
    ... except HgoError as err:
    ...     print(type(err).__name__)
    DesignError
    """


class DimensionError(HgoError, ValueError):
    """An array has the wrong shape or length.

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.sensors import Bias, SensorChain
    >>> SensorChain([Bias([0.1, 0.2])]).apply([0.0], np.zeros((1, 1, 3)))
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DimensionError: Bias.offset has 2 entries (one per channel) but y has 3 channels
    >>> issubclass(DimensionError, ValueError)
    True
    """


class DesignError(HgoError, ValueError):
    """A parameter, gain or design choice is invalid (not Hurwitz, negative, NaN, unknown...).

    Examples
    --------
    >>> from hgo_mj.sensors import GaussianNoise
    >>> GaussianNoise(std=-1.0)
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: GaussianNoise.std must be >= 0; found -1.0
    """


class DivergenceError(HgoError, RuntimeError):
    """A simulation or an observer left the finite numbers.

    Examples
    --------
    >>> from hgo_mj.observers import HighGainObserver
    >>> from hgo_mj.systems import SYSTEMS
    >>> obs = HighGainObserver(SYSTEMS["pendulum"](), k=10.0)
    >>> obs.reset()
    >>> obs.update([float("inf")], [0.0], 0.01)
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DivergenceError: high_gain: measurement y[0] is inf (member 0, sample 0)
    >>> issubclass(DivergenceError, RuntimeError)
    True
    """


class ModelError(DesignError):
    """A model the user brought (an MJCF file, an ODE) cannot be used: it does not load, names
    an element it does not have, or has a structure hgo_mj does not take.

    Examples
    --------
    A subclass of :class:`DesignError`, so one ``except DesignError`` catches both:

    >>> issubclass(ModelError, DesignError), issubclass(ModelError, ValueError)
    (True, True)
    """


class RecordingError(HgoError, RuntimeError):
    """A rerun recording could not be written or finalized (its file sink failed: a full disk,
    an unwritable file); the message names the file and the reason.

    Examples
    --------
    >>> err = RecordingError("run.rrd: No space left on device")
    >>> isinstance(err, HgoError), isinstance(err, RuntimeError)
    (True, True)
    """


class TrajectoryFileError(HgoError, ValueError):
    """A trajectory file (``Trajectory.load``) is not one ``Trajectory.save`` writes: damaged,
    crafted, a pickle (refused) or another format; the message names the file and what is
    wrong.

    Examples
    --------
    >>> err = TrajectoryFileError("run.npz: no column 't'")
    >>> isinstance(err, HgoError), isinstance(err, ValueError)
    (True, True)
    """


class ManifestError(HgoError, ValueError):
    """A folder hgo_mj wrote does not match its manifest (:mod:`hgo_mj.manifest`): the run
    writing it did not finish, or its files come from two runs; the message names the folder,
    the file and what differs.

    Examples
    --------
    >>> err = ManifestError("runs/a: metrics.json differs from the manifest")
    >>> isinstance(err, HgoError), isinstance(err, ValueError)
    (True, True)
    """


class MissingExtraError(HgoError, ImportError):
    """A feature needs an optional dependency that is not installed; the one-line message
    names the extra of ``pyproject.toml`` that installs it (:func:`hgo_mj._extras.require`).

    Parameters
    ----------
    package : str
        The missing distribution's import name (``"sympy"``); also ``ImportError.name``.
    extra : str
        The extra that installs it (``"symbolic"``); also the attribute ``extra``.
    feature : str
        What needs it, the message's first words.

    Examples
    --------
    >>> err = MissingExtraError("sympy", "symbolic", "an ODE plant given as text")
    >>> print(err)
    an ODE plant given as text needs the optional dependency sympy: pip install 'hgo_mj[symbolic]'
    >>> isinstance(err, ImportError), err.name, err.extra
    (True, 'sympy', 'symbolic')
    """

    def __init__(self, package: str, extra: str, feature: str) -> None:
        super().__init__(f"{feature} needs the optional dependency {package}: "
                         f"pip install 'hgo_mj[{extra}]'", name=package)
        self.extra = extra
