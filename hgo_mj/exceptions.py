"""The errors hgo_mj raises.

Every error says what was expected and what was found. They subclass the builtin
errors a caller would catch anyway (``ValueError``, ``RuntimeError``).
"""

from __future__ import annotations


class HgoError(Exception):
    """Base class of every error raised on purpose by hgo_mj."""


class DimensionError(HgoError, ValueError):
    """An array has the wrong shape or length."""


class DesignError(HgoError, ValueError):
    """A parameter, gain or design choice is invalid (not Hurwitz, negative, NaN, unknown...)."""


class DivergenceError(HgoError, RuntimeError):
    """A simulation or an observer left the finite numbers."""


class ModelError(DesignError):
    """A model the user brought (an MJCF file, an ODE) cannot be used: it does not load, names
    an element it does not have, or has a structure hgo_mj does not take."""


class RecordingError(HgoError, RuntimeError):
    """A rerun recording could not be written or finalized (its file sink failed: a full disk,
    an unwritable file); the message names the file and the reason."""
