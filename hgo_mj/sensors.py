"""Sensor models: turn a plant's clean outputs ``y`` into what a real sensor reports.

A :class:`SensorChain` applies a sequence of :class:`Stage` objects **in the order they are
given** to blocks of samples of B streams at once: :meth:`SensorChain.apply` takes the sample
times ``t`` ``(T,)`` and the clean outputs ``Y`` ``(B, T, p)`` (one run is B = 1) and every stage
is called once per block through :meth:`Stage.apply`. Each stage returns a new array and never
modifies its input; stateful stages (held samples, delay lines, drift, counters) keep one state
per stream across blocks, so a block of ``T`` samples gives what the same samples cut into
any smaller blocks give.

**Where the random numbers come from.** Every random stage (Gaussian, uniform, drift,
outliers, dropout) of every stream draws from a seeded :class:`numpy.random.Generator` of its
own (:func:`stream_generators`): the first random stage from ``default_rng(seed)``, later ones
from generators spawned from the seed. So the same seed gives bit-identical measurements, a
stream is the same alone or in a batch, and a chain with one random stage gives, per stream,
exactly the numbers of ``default_rng(seed)`` drawn in sample order (for a lone Gaussian stage,
``y + std * rng.standard_normal(p)`` sample after sample, bit for bit). The variates are drawn
in blocks per stream (16 at first, doubling up to 1024) and handed out in stream order;
:meth:`SensorChain.restart` clears the stages' state and lets the generators continue
(an environment reset that does not reseed continues the noise sequence), and
:meth:`SensorChain.reset` reseeds them.

The order matters (quantizing then adding a bias is not the same as biasing then quantizing).
The recommended physical order, from the plant to the observer, is::

    delay -> sample_hold -> bias -> drift -> gaussian / uniform noise -> outliers
          -> quantize -> saturate -> dropout

i.e. the signal is transported and sampled, the transducer adds its offset, drift and noise
(and rare spikes), the ADC or encoder quantizes and clips, and finally the link may lose the
sample (a lost sample is NaN, never a silent zero).

Stages (registry name in parentheses): :class:`GaussianNoise` (``gaussian``),
:class:`UniformNoise` (``uniform``), :class:`Bias` (``bias``), :class:`RandomWalkDrift`
(``drift``), :class:`Quantization` (``quantize``), :class:`SampleHold` (``sample_hold``),
:class:`Delay` (``delay``), :class:`Dropout` (``dropout``), :class:`Outliers` (``outliers``),
:class:`Saturation` (``saturate``).  Build them by name with :func:`make_stage` or a whole
chain from a JSON-like list with :meth:`SensorChain.from_spec`.

Parameters marked *per channel* accept a scalar (the same for every output channel) or a 1-D
sequence with one entry per channel; a length that does not match ``y`` raises
:class:`~hgo_mj.exceptions.DimensionError` when the stage is called. Noise given as a power
spectral density follows paper 000 [000]_.

References
----------
.. [000] E. Bullinger, A. Ilchmann, F. Allgöwer, "A simple adaptive observer for nonlinear
   systems", NOLCOS 1998: measurement noise given as a power spectral density (0.25e-6)
   with a sample time (0.01 h), as Simulink's band-limited white noise block, whose variance
   is ``psd / sample_time``.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Mapping, Sequence
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._validate import finite_scalar, numbers_only, reject_unknown
from .exceptions import DesignError, DimensionError

Array = NDArray[np.float64]

__all__ = [
    "STAGES",
    "Bias",
    "Delay",
    "Dropout",
    "GaussianNoise",
    "Outliers",
    "Quantization",
    "RandomWalkDrift",
    "SampleHold",
    "Saturation",
    "SensorChain",
    "Stage",
    "UniformNoise",
    "encoder",
    "make_stage",
]

_EXPECT = {
    "real": "finite",
    "nonneg": ">= 0",
    "positive": "> 0",
    "prob": "in [0, 1]",
    "extended": "a real number or +-inf (not NaN)",
}


def _channel_param(where: str, value: Any, kind: str = "real") -> float | Array:
    """Validate a per-channel parameter: a scalar (all channels) or a 1-D sequence (one each).

    Parameters
    ----------
    where : str
        ``"Class.param"``, used in error messages.
    value : float or array_like
        The value given by the user.
    kind : {"real", "nonneg", "positive", "prob", "extended"}
        ``real``: finite; ``nonneg``: finite and >= 0; ``positive``: finite and > 0;
        ``prob``: in [0, 1]; ``extended``: not NaN (+-inf allowed).

    Returns
    -------
    float or ndarray
        A float for a scalar, otherwise a read-only 1-D float array.

    Raises
    ------
    DesignError
        Not a number, NaN, infinite (unless ``extended``) or out of range.
    DimensionError
        More than one dimension, or an empty sequence.
    """
    if value is None or not numbers_only(value):
        raise DesignError(f"{where} must be a real number or a 1-D sequence of them (one per "
                          f"channel); found {value!r}")
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise DesignError(f"{where} must be a real number or a 1-D sequence of them (one per "
                          f"channel); found {value!r}") from None
    if a.ndim > 1:
        raise DimensionError(f"{where} must be a scalar or 1-D (one entry per channel); "
                             f"found shape {a.shape}")
    if a.ndim == 1 and a.size == 0:
        raise DimensionError(f"{where} must be a scalar or hold one entry per channel; "
                             f"found an empty sequence")
    found = a.item() if a.ndim == 0 else a.tolist()
    if np.any(np.isnan(a)):
        what = "not NaN" if kind == "extended" else "finite"
        raise DesignError(f"{where} must be {what}; found {found}")
    if kind != "extended" and not np.all(np.isfinite(a)):
        raise DesignError(f"{where} must be finite; found {found}")
    bad = ((kind == "nonneg" and np.any(a < 0))
           or (kind == "positive" and np.any(a <= 0))
           or (kind == "prob" and np.any((a < 0) | (a > 1))))
    if bad:
        raise DesignError(f"{where} must be {_EXPECT[kind]}; found {found}")
    if a.ndim == 0:
        return float(a)
    a.setflags(write=False)
    return a


def _json(value: float | Array) -> float | list[float]:
    """A per-channel parameter as plain JSON data (float or list of floats)."""
    return value if isinstance(value, float) else [float(v) for v in value]


def _copy(value: float | Array) -> float | Array:
    return value if isinstance(value, float) else value.copy()


_FIRST_BLOCK, _MAX_BLOCK = 16, 1024


class _Streams:
    """The B generators of one random stage in a batched chain (one per stream) and their
    variates, drawn in blocks ``(B, K)`` and handed out in stream order with one cursor (every
    stream takes the same count at each call). A block of 16 per stream at first, doubling up
    to 1024; a call that needs more than the block holds draws what it needs. The values a
    stream gets are those of consecutive calls of ``getattr(gen, kind)``, however the calls are
    cut, so a batched run does not depend on its block sizes.

    The buffer is kept and reused (fresh megabytes cost page faults at every refill) and kept
    stream-major, each generator filling its own row: a transposed (draw-major) copy cost more
    (about 8 ns a value, measured) than the strided read of one sample's draws.
    """

    __slots__ = ("_block", "_buf", "_carry", "_hold", "_kind", "_pos", "_store", "gens")

    def __init__(self, gens: Sequence[np.random.Generator], kind: str) -> None:
        self.gens = tuple(gens)
        self._kind = kind
        self._store = np.empty((len(self.gens), 0))
        self._buf = self._store
        self._pos = 0
        self._block = _FIRST_BLOCK
        #: streams that do not advance at the next takes (:meth:`SensorChain.hold`)
        self._hold: tuple[int, ...] = ()
        #: per stream, variates drawn from its generator that come before its next draws
        self._carry: dict[int, Array] = {}

    def _refill(self, size: int) -> Array:
        """Draw the next ``size`` variates of every stream into the kept buffer, ``(B, size)``."""
        if size > _MAX_BLOCK:               # a long block: drawn into a buffer of its own
            buf = np.empty((len(self.gens), size))
        else:
            if self._store.shape[1] < size:
                self._store = np.empty((len(self.gens), size))
            buf = self._store[:, :size]
        draw = self._kind
        for b, (row, g) in enumerate(zip(buf, self.gens)):
            carry = self._carry.pop(b, None) if self._carry else None
            if carry is None:
                getattr(g, draw)(size, out=row)
            elif carry.size >= size:
                row[:] = carry[:size]
                if carry.size > size:
                    self._carry[b] = carry[size:]
            else:
                row[:carry.size] = carry
                getattr(g, draw)(size - carry.size, out=row[carry.size:])
        return buf

    def _give_back(self, b: int, served: Array) -> None:
        """Stream ``b`` did not use the variates ``served`` of the last take: they come again,
        in order, before the rest of its sequence (the buffered ones, then the carried)."""
        row = self._buf[b]
        ahead = row[self._pos:]
        seq = np.concatenate((served, ahead, self._carry.get(b, np.empty(0))))
        k = ahead.size
        row[self._pos:] = seq[:k]
        if seq.size > k:
            self._carry[b] = seq[k:]
        else:
            self._carry.pop(b, None)

    def reseed(self, b: int, gen: np.random.Generator) -> None:
        """Stream ``b`` draws from ``gen`` from now on (its buffered variates redrawn)."""
        gens = list(self.gens)
        gens[b] = gen
        self.gens = tuple(gens)
        self._carry.pop(b, None)
        ahead = self._buf[b, self._pos:]
        if ahead.size:
            getattr(gen, self._kind)(ahead.size, out=ahead)

    def take(self, n: int) -> Array:
        """The next ``n`` variates of every stream, ``(B, n)`` (a view, valid until the next
        call: do not write into it)."""
        buf, pos = self._buf, self._pos
        if pos + n <= buf.shape[1]:
            self._pos = pos + n
            out = buf[:, pos:pos + n]
        else:
            rest = buf[:, pos:].copy()          # the kept buffer is about to be drawn into
            need = n - rest.shape[1]
            size = max(need, self._block)
            self._block = min(2 * self._block, _MAX_BLOCK)
            self._buf, self._pos = self._refill(size), need
            head = self._buf[:, :need]
            out = np.concatenate((rest, head), axis=1) if rest.shape[1] else head
        for b in self._hold:   # held streams: what they were served comes again
            self._give_back(b, out[b].copy())
        return out


class Stage:
    """One step of a sensor chain (base class).

    Subclasses implement :meth:`apply` (the one primitive: a block of samples of B streams),
    keeping their per-stream state in ``self._bstate`` through :meth:`_fresh_state` (cleared
    by :meth:`reset`).  They validate their parameters in ``__init__`` and record them (as
    JSON-friendly values) in ``self._params`` for :meth:`params`.

    Attributes
    ----------
    name : str
        Registry key (see :data:`STAGES`).
    summary : str
        One-line description, for ``hgo-mj list``.

    Examples
    --------
    A deterministic stage needs only ``apply`` (and its parameters in ``_params``):

    >>> import numpy as np
    >>> class Scale(Stage):
    ...     name = "scale"
    ...     def __init__(self, factor):
    ...         super().__init__()
    ...         self.factor = float(factor)
    ...         self._params = {"factor": self.factor}
    ...     def apply(self, t, Y, draws):
    ...         return Y * self.factor
    >>> SensorChain([Scale(2.0), Bias(1.0)]).apply([0.0, 0.1], np.ones((1, 2, 1))).ravel()
    array([3., 3.])
    >>> Scale(2.0)
    Scale(factor=2.0)
    """

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    #: the kind of variates a random stage draws (``"standard_normal"`` or ``"random"``, a
    #: method of :class:`numpy.random.Generator`); None for a deterministic stage
    draws: ClassVar[str | None] = None
    #: whether the stage keeps time across samples (held samples, delay lines, drift): its
    #: streams must share one clock, so that one stream alone cannot be restarted
    keeps_time: ClassVar[bool] = False

    def __init__(self) -> None:
        self._params: dict[str, Any] = {}
        #: the batched path's per-member state (None: fresh, see :meth:`reset`)
        self._bstate: Any = None
        self._n: int | None = None      # channel count fixed by per-channel parameters
        self._n_from = ""               # name of the parameter that fixed it

    # -- helpers for subclasses ------------------------------------------------------------
    def _channels(self, **values: float | Array) -> None:
        """Fix the channel count from the per-channel (array) parameters; they must agree."""
        for pname, v in values.items():
            if isinstance(v, float):
                continue
            if self._n is None:
                self._n, self._n_from = v.shape[0], pname
            elif v.shape[0] != self._n:
                cls = type(self).__name__
                raise DimensionError(
                    f"{cls}.{pname} has {v.shape[0]} entries but {cls}.{self._n_from} has "
                    f"{self._n}; per-channel parameters must have the same length")

    def _check_width(self, n: int) -> None:
        """Refuse a measurement of ``n`` channels where the per-channel parameters fix another
        count."""
        if self._n is not None and n != self._n:
            self._mismatch(n)

    def _mismatch(self, n: int) -> None:
        raise DimensionError(
            f"{type(self).__name__}.{self._n_from} has {self._n} entries (one per channel) "
            f"but y has {n} channels")

    # -- interface -------------------------------------------------------------------------
    def reset(self) -> None:
        """Clear the per-stream state (delay lines, drift, held samples, counters): the next
        :meth:`apply` starts fresh, for any number of streams. The generators are the chain's
        (:meth:`SensorChain.reset` reseeds them, :meth:`SensorChain.restart` does not).

        Examples
        --------
        >>> import numpy as np
        >>> delay = Delay(0.01)
        >>> chain = SensorChain([delay])
        >>> chain.apply([0.0, 0.01], np.array([[[1.0], [2.0]]])).ravel()
        array([1., 1.])
        >>> delay.reset()  # the delay line is empty again: time may start over
        >>> chain.apply([0.0], np.array([[[5.0]]])).ravel()
        array([5.])
        """
        self._bstate = None

    def restart_members(self, idx: Sequence[int]) -> None:
        """Clear the state of the streams ``idx`` only (their counters), as :meth:`reset` does
        for all; the others go on.

        Parameters
        ----------
        idx : sequence of int
            The streams (members of the batch) to restart.

        Raises
        ------
        DesignError
            A stage that keeps time (:attr:`keeps_time`): its streams share one clock.

        Examples
        --------
        >>> import numpy as np
        >>> drop = Dropout(1.0)
        >>> chain = SensorChain([drop])
        >>> chain.reset([0, 1])
        >>> _ = chain.apply([0.0], np.zeros((2, 1, 1)))
        >>> drop.restart_members([0])
        >>> drop.counts
        array([0, 1])
        """
        if self.keeps_time:
            raise DesignError(f"{type(self).__name__} keeps time across samples (its streams "
                              f"share one clock): one stream alone cannot be restarted")
        st = self._bstate
        if st is not None and isinstance(st[1], np.ndarray):
            st[1][list(idx)] = 0

    def apply(self, t: Array, Y: Array, draws: _Streams | None) -> Array:
        """The batched primitive: apply the stage to a block of samples of B streams.

        Parameters
        ----------
        t : ndarray, shape (T,)
            Sample times, finite, non-decreasing (shared by the streams).
        Y : ndarray, shape (B, T, p)
            Input samples of every stream (not modified).
        draws : _Streams or None
            The stage's own variates, one generator per stream (random stages; see
            :class:`SensorChain`); None for deterministic stages.

        Returns
        -------
        ndarray, shape (B, T, p)
            A new array. Stateful stages (held samples, delay lines, drift, counters) keep one
            state per stream across blocks, cleared by :meth:`reset`; a block of ``T``
            samples gives what ``T`` blocks of one sample give.

        Raises
        ------
        DesignError
            (The base) a subclass that does not implement it.

        Examples
        --------
        The chain calls it; deterministic stages take ``draws=None``:

        >>> import numpy as np
        >>> Bias(0.5).apply(np.array([0.0, 0.1]), np.zeros((1, 2, 1)), None).ravel()
        array([0.5, 0.5])
        """
        raise DesignError(f"{type(self).__name__} has no batched apply(t, Y, draws); implement "
                          "it to use the stage in a batched chain")

    def _fresh_state(self, B: int, make: Any) -> Any:
        """The per-stream state for ``B`` streams: made by ``make()`` on the first block,
        refused when B changes without :meth:`reset`."""
        st = self._bstate
        if st is None:
            st = self._bstate = (B, make())
        elif st[0] != B:
            raise DimensionError(f"{type(self).__name__}: the batch changed from {st[0]} to {B} "
                                 "streams without reset()")
        return st[1]

    def params(self) -> dict[str, Any]:
        """The constructor parameters, as JSON-friendly values.

        Returns
        -------
        dict
            Parameter name -> float, list of floats (per channel) or int.

        Examples
        --------
        >>> GaussianNoise(std=[0.1, 0.2]).params()
        {'std': [0.1, 0.2]}
        """
        return {k: (list(v) if isinstance(v, list) else v) for k, v in self._params.items()}

    def noise_variance(self) -> float | Array | None:
        """Variance this stage adds as white noise (``None`` if it adds none).

        Used by :meth:`SensorChain.noise_variance` for a default measurement covariance.

        Returns
        -------
        float, (p,) ndarray or None
            Per-channel variance (a float: the same for every channel); None for a stage that
            adds no white noise.

        Examples
        --------
        >>> GaussianNoise(std=0.1).noise_variance()
        0.010000000000000002
        >>> Bias(0.5).noise_variance() is None
        True
        """
        return None

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self._params.items())
        return f"{type(self).__name__}({args})"


class GaussianNoise(Stage):
    """Additive white Gaussian noise.

    Give **either** ``std`` **or** ``psd`` together with ``sample_time``; the latter follows
    Simulink's band-limited white noise block: ``variance = psd / sample_time``.

    Parameters
    ----------
    std : float or array_like, optional
        Standard deviation, >= 0, per channel.
    psd : float or array_like, optional
        Noise power spectral density (height of the PSD), >= 0, per channel.
    sample_time : float, optional
        Sample time of the band-limited noise, > 0 (only with ``psd``).

    Examples
    --------
    >>> import numpy as np
    >>> chain = SensorChain([GaussianNoise(psd=0.25e-6, sample_time=0.01)], seed=0)
    >>> y = chain.apply(np.arange(20000) * 0.01, np.zeros((1, 20000, 1)))
    >>> round(float(y.std()), 4)            # sqrt(psd / sample_time) = 0.005
    0.005
    """

    name = "gaussian"
    summary = "additive white Gaussian noise: std=, or psd= with sample_time= (var = psd/Ts)"
    draws = "standard_normal"

    def __init__(self, std: float | ArrayLike | None = None, *,
                 psd: float | ArrayLike | None = None,
                 sample_time: float | None = None) -> None:
        super().__init__()
        if (std is None) == (psd is None):
            found = "both" if std is not None else "neither"
            raise DesignError("GaussianNoise needs exactly one of std= or psd= (with "
                              f"sample_time=); found {found}")
        if std is not None:
            if sample_time is not None:
                raise DesignError("GaussianNoise.sample_time goes with psd=, not with std=; "
                                  f"found std={std!r} and sample_time={sample_time!r}")
            self._std = _channel_param("GaussianNoise.std", std, "nonneg")
            self._variance = self._std * self._std
            self._params = {"std": _json(self._std)}
            self._channels(std=self._std)
        else:
            if sample_time is None:
                raise DesignError("GaussianNoise.sample_time must be given with psd= "
                                  "(variance = psd / sample_time); found None")
            psd_v = _channel_param("GaussianNoise.psd", psd, "nonneg")
            ts = finite_scalar("GaussianNoise.sample_time", sample_time, positive=True)
            self._variance = psd_v / ts
            self._std = (math.sqrt(self._variance) if isinstance(self._variance, float)
                         else np.sqrt(self._variance))
            self._params = {"psd": _json(psd_v), "sample_time": ts}
            self._channels(psd=psd_v)

    @property
    def variance(self) -> float | Array:
        """Noise variance, per channel (``std**2`` or ``psd / sample_time``)."""
        return _copy(self._variance)

    @property
    def std(self) -> float | Array:
        """Noise standard deviation, per channel."""
        return _copy(self._std)

    def noise_variance(self) -> float | Array:
        return self.variance

    def apply(self, t: Array, Y: Array, draws: _Streams | None) -> Array:
        B, T, p = Y.shape
        self._check_width(p)
        z = draws.take(T * p).reshape(B, T, p)  # type: ignore[union-attr]
        return Y + self._std * z


class UniformNoise(Stage):
    """Additive white noise uniform on ``[-half_width, half_width]``.

    Parameters
    ----------
    half_width : float or array_like
        Half width of the interval, >= 0, per channel.

    Examples
    --------
    >>> import numpy as np
    >>> noise = UniformNoise(0.3)
    >>> round(noise.variance, 6)
    0.03
    >>> y = SensorChain([noise], seed=0).apply(np.arange(1000) * 0.01, np.zeros((1, 1000, 1)))
    >>> bool(np.all(np.abs(y) <= 0.3))
    True
    """

    name = "uniform"
    summary = "additive white noise uniform on [-half_width, half_width] (var = hw^2/3)"
    draws = "random"

    def __init__(self, half_width: float | ArrayLike) -> None:
        super().__init__()
        self._hw = _channel_param("UniformNoise.half_width", half_width, "nonneg")
        self._params = {"half_width": _json(self._hw)}
        self._channels(half_width=self._hw)

    @property
    def variance(self) -> float | Array:
        """Noise variance ``half_width**2 / 3``, per channel."""
        return self._hw * self._hw / 3.0

    def noise_variance(self) -> float | Array:
        return self.variance

    def apply(self, t: Array, Y: Array, draws: _Streams | None) -> Array:
        B, T, p = Y.shape
        self._check_width(p)
        u = draws.take(T * p).reshape(B, T, p)  # type: ignore[union-attr]
        return (u * 2.0 - 1.0) * self._hw + Y  # [0, 1) -> [-1, 1) -> [-hw, hw)


class Bias(Stage):
    """Constant additive offset.

    Parameters
    ----------
    offset : float or array_like
        Offset, per channel.

    Examples
    --------
    >>> import numpy as np
    >>> t, Y = np.arange(5) * 0.01, np.arange(5.0).reshape(1, 5, 1)
    >>> SensorChain([Bias(0.5)]).apply(t, Y).ravel()
    array([0.5, 1.5, 2.5, 3.5, 4.5])
    """

    name = "bias"
    summary = "constant additive offset"

    def __init__(self, offset: float | ArrayLike) -> None:
        super().__init__()
        self._offset = _channel_param("Bias.offset", offset, "real")
        self._params = {"offset": _json(self._offset)}
        self._channels(offset=self._offset)

    def apply(self, t: Array, Y: Array, draws: _Streams | None) -> Array:
        self._check_width(Y.shape[2])
        return Y + self._offset


class RandomWalkDrift(Stage):
    """Bias that performs a random walk (integrated white noise).

    At each sample ``b += N(0, sigma**2 * dt)`` with ``dt`` the time since the previous sample
    (``dt = 0`` on the first sample after construction or :meth:`reset`, which sets ``b =
    initial``); the output is ``y + b``.  Every sample draws ``p`` normal numbers, whatever
    ``dt``, so the generator stream does not depend on the sample times.

    Parameters
    ----------
    sigma : float or array_like
        Random-walk intensity, >= 0, in output units per sqrt(second), per channel.
    initial : float or array_like, default 0
        Initial bias, per channel.
    initial_std : float or array_like, default 0
        A turn-on bias drawn per stream: the initial bias is ``initial + N(0, initial_std**2)``
        (the first sample's draw; a MEMS gyro's bias repeatability), per channel, >= 0.

    Raises
    ------
    DesignError
        When ``t`` decreases, within a block or from one block to the next (call
        :meth:`SensorChain.reset` or :meth:`SensorChain.restart` before restarting); a
        negative ``sigma`` or ``initial_std``.

    Examples
    --------
    >>> import numpy as np
    >>> t, Y = np.arange(5) * 0.01, np.arange(5.0).reshape(1, 5, 1)
    >>> drift = RandomWalkDrift(1.0, initial=0.5)
    >>> SensorChain([drift], seed=0).apply(t, Y).ravel().round(3)
    array([0.5  , 1.487, 2.551, 3.561, 4.508])
    >>> drift.bias.round(3)                  # the current bias of each stream and channel
    array([[0.508]])
    """

    keeps_time = True
    name = "drift"
    summary = "random-walk bias: b += N(0, sigma^2 dt) each call, output y + b"
    draws = "standard_normal"

    def __init__(self, sigma: float | ArrayLike, initial: float | ArrayLike = 0.0,
                 initial_std: float | ArrayLike = 0.0) -> None:
        super().__init__()
        self._sigma = _channel_param("RandomWalkDrift.sigma", sigma, "nonneg")
        self._initial = _channel_param("RandomWalkDrift.initial", initial, "real")
        self._initial_std = _channel_param("RandomWalkDrift.initial_std", initial_std, "nonneg")
        self._params = {"sigma": _json(self._sigma), "initial": _json(self._initial)}
        if np.any(self._initial_std != 0):
            self._params["initial_std"] = _json(self._initial_std)
        self._channels(sigma=self._sigma, initial=self._initial, initial_std=self._initial_std)

    @property
    def bias(self) -> Array | None:
        """Current drift value per stream and channel, ``(B, p)`` (``None`` before the first
        block after construction or :meth:`reset`)."""
        return None if self._bstate is None else self._bstate[1]["b"].copy()

    def apply(self, t: Array, Y: Array, draws: _Streams | None) -> Array:
        """Per stream the bias ``b`` (B, p) and the last time, across blocks; the increments of
        a block are summed in order (``numpy.cumsum``: the same additions as sample by
        sample)."""
        B, T, p = Y.shape
        self._check_width(p)
        st = self._fresh_state(B, lambda: {"b": None, "t": 0.0})
        z = draws.take(T * p).reshape(B, T, p)  # type: ignore[union-attr]
        if st["b"] is not None and st["b"].shape[1] != p:
            raise DimensionError(f"RandomWalkDrift: y changed length from {st['b'].shape[1]} "
                                 f"to {p} without reset()")
        first = st["b"] is None
        prev = np.concatenate(([st["t"]], t[:-1]))
        dt = t - prev
        if first:
            dt[0] = 0.0
        bad = np.flatnonzero(dt < 0)
        if bad.size:
            k = int(bad[0])
            raise DesignError(f"RandomWalkDrift: time must not decrease; found t={t[k]} after "
                              f"t={prev[k]} (call reset() before restarting)")
        inc = z * self._sigma
        inc *= np.sqrt(dt)[None, :, None]
        if first:
            b0 = np.zeros((B, p))
            b0 += self._initial
            if np.any(self._initial_std != 0):  # the turn-on bias: the first sample's draw
                b0 += z[:, 0] * self._initial_std
            inc[:, 0] = b0          # the first sample sets the initial bias
        else:
            inc[:, 0] += st["b"]    # the bias so far plus the first increment
        b = np.cumsum(inc, axis=1)
        st["b"], st["t"] = b[:, -1].copy(), float(t[-1])
        return Y + b


class Quantization(Stage):
    """Round to a resolution: ``resolution * round(y / resolution)``.

    Give **either** ``resolution`` **or** ``counts_per_rev`` (an encoder with ``N`` counts per
    revolution, ``resolution = 2*pi/N``).  Ties round to even (:func:`numpy.rint`).

    Parameters
    ----------
    resolution : float or array_like, optional
        Quantization step, > 0, per channel.
    counts_per_rev : int or array_like of int, optional
        Encoder counts per revolution, a positive integer, per channel.

    Examples
    --------
    >>> import numpy as np
    >>> q = SensorChain([Quantization(resolution=0.1)])
    >>> q.apply(np.zeros(3), np.array([[[0.04], [0.06], [-0.26]]]))[0, :, 0]
    array([ 0. ,  0.1, -0.3])
    """

    name = "quantize"
    summary = "round to a resolution= (or encoder counts_per_rev=, step 2*pi/N)"

    def __init__(self, resolution: float | ArrayLike | None = None, *,
                 counts_per_rev: int | ArrayLike | None = None) -> None:
        super().__init__()
        if (resolution is None) == (counts_per_rev is None):
            found = "both" if resolution is not None else "neither"
            raise DesignError("Quantization needs exactly one of resolution= or "
                              f"counts_per_rev=; found {found}")
        if resolution is not None:
            self._res = _channel_param("Quantization.resolution", resolution, "positive")
            self._params = {"resolution": _json(self._res)}
            self._channels(resolution=self._res)
        else:
            c = _channel_param("Quantization.counts_per_rev", counts_per_rev, "positive")
            ca = np.asarray(c)
            if np.any(ca != np.round(ca)):
                shown = c if isinstance(c, float) else c.tolist()
                raise DesignError("Quantization.counts_per_rev must be a positive integer; "
                                  f"found {shown}")
            self._res = (2.0 * math.pi / c) if isinstance(c, float) else 2.0 * np.pi / c
            self._params = {"counts_per_rev": (int(c) if isinstance(c, float)
                                               else [int(v) for v in c])}
            self._channels(counts_per_rev=c)

    @property
    def resolution(self) -> float | Array:
        """Quantization step, per channel."""
        return _copy(self._res)

    @property
    def variance(self) -> float | Array:
        """Variance of the quantization error under the uniform model, ``resolution**2/12``."""
        return self._res * self._res / 12.0

    def noise_variance(self) -> float | Array:
        return self.variance

    def apply(self, t: Array, Y: Array, draws: _Streams | None) -> Array:
        self._check_width(Y.shape[2])
        return np.rint(Y / self._res) * self._res


class SampleHold(Stage):
    """Sample at its own ``period`` and hold between samples (zero-order hold).

    The stage samples its input at the first sample and whenever ``floor((t + eps) / period)``
    changes, with ``eps = min(1e-9 * max(1, |t|), 1e-3 * period)`` so that times such as
    ``0.1 + 0.1 + 0.1`` sample on time; otherwise it returns the held sample.

    Parameters
    ----------
    period : float
        Sampling period, seconds, > 0.

    Examples
    --------
    >>> import numpy as np
    >>> t, Y = np.arange(5) * 0.01, np.arange(5.0).reshape(1, 5, 1)
    >>> SensorChain([SampleHold(0.02)]).apply(t, Y).ravel()
    array([0., 0., 2., 2., 4.])
    """

    keeps_time = True
    name = "sample_hold"
    summary = "sample every period= seconds and hold in between (zero-order hold)"

    def __init__(self, period: float) -> None:
        super().__init__()
        self._period = finite_scalar("SampleHold.period", period, positive=True)
        self._params = {"period": self._period}

    def apply(self, t: Array, Y: Array, draws: _Streams | None) -> Array:
        """The sample index ``k`` of every time (shared by the streams) decides where a new
        sample is taken; per stream the held sample carries over to the next block."""
        B, T, p = Y.shape
        st = self._fresh_state(B, lambda: {"k": None, "held": None})
        if st["held"] is not None and st["held"].shape[1] != p:
            raise DimensionError(f"SampleHold: y changed length from {st['held'].shape[1]} to "
                                 f"{p} without reset()")
        eps = np.minimum(1e-9 * np.maximum(1.0, np.abs(t)), 1e-3 * self._period)
        k = np.floor((t + eps) / self._period)
        new = np.empty(T, dtype=bool)
        new[0] = st["held"] is None or k[0] != st["k"]
        new[1:] = k[1:] != k[:-1]
        src = np.maximum.accumulate(np.where(new, np.arange(T), -1))
        out = Y[:, np.maximum(src, 0)]
        if src[0] < 0:              # the samples before the block's first new one: held
            out[:, src < 0] = st["held"][:, None]
        st["k"], st["held"] = float(k[-1]), out[:, -1].copy()
        return out


class Delay(Stage):
    """Transport delay of ``delay`` seconds.

    Returns the input that arrived at the latest sample time ``t_k <= t - delay`` (with a
    tolerance of ``1e-9 * max(1, |t|)`` so that exact multiples of the sample period work).
    Before any such input exists, returns the **first** input received since construction or
    :meth:`reset`.  Called every ``Ts`` with ``delay = m * Ts``, the output is exactly the
    input from ``m`` samples ago.  The buffer only keeps the entries still needed.

    Parameters
    ----------
    delay : float
        Delay, seconds, >= 0.

    Raises
    ------
    DesignError
        When ``t`` decreases, within a block or from one block to the next (call
        :meth:`SensorChain.reset` or :meth:`SensorChain.restart` before restarting).

    Examples
    --------
    >>> import numpy as np
    >>> t, Y = np.arange(5) * 0.01, np.arange(5.0).reshape(1, 5, 1)
    >>> SensorChain([Delay(0.02)]).apply(t, Y).ravel()  # two samples late
    array([0., 0., 0., 1., 2.])
    """

    keeps_time = True
    name = "delay"
    summary = "transport delay of delay= seconds (first input until the buffer fills)"

    def __init__(self, delay: float) -> None:
        super().__init__()
        self._delay = finite_scalar("Delay.delay", delay, nonnegative=True)
        self._params = {"delay": self._delay}

    def apply(self, t: Array, Y: Array, draws: _Streams | None) -> Array:
        """The delay line for a block: the times (shared by the streams)
        give, for each sample, the index of the entry it returns (the latest received at or
        before ``t - delay``, never moving back; the first input until one exists); per stream
        the entries still needed carry over to the next block."""
        B, T, p = Y.shape
        st = self._fresh_state(B, lambda: {"t": None, "Y": None})
        if st["t"] is not None:
            if st["Y"].shape[2] != p:
                raise DimensionError(f"Delay: y changed length from {st['Y'].shape[2]} to {p} "
                                     "without reset()")
            times = np.concatenate((st["t"], t))
            vals = np.concatenate((st["Y"], Y), axis=1)
        else:
            times, vals = t, Y
        back = np.flatnonzero(times[1:] < times[:-1])
        if back.size:
            k = int(back[0])
            raise DesignError(f"Delay: time must not decrease; found t={times[k + 1]} after "
                              f"t={times[k]} (call reset() before restarting)")
        H = times.shape[0] - T
        target = t - self._delay + 1e-9 * np.maximum(1.0, np.abs(t))
        idx = np.searchsorted(times, target, side="right") - 1
        idx = np.maximum(np.minimum(idx, H + np.arange(T)), 0)
        idx = np.maximum.accumulate(idx)
        out = vals[:, idx]
        front = int(idx[-1])
        st["t"], st["Y"] = times[front:].copy(), vals[:, front:].copy()
        return out


class Dropout(Stage):
    """Lose samples: with probability ``p`` per sample and channel the sample becomes NaN.

    A lost sample is NaN, never a silent zero; the observer must handle it.

    Parameters
    ----------
    p : float or array_like
        Dropout probability in [0, 1], per channel.

    Attributes
    ----------
    counts : ndarray of int, shape (B,), or None
        Samples dropped per stream since construction or :meth:`reset` (None before the
        first block); :attr:`SensorChain.dropouts` sums them over the stages and streams.

    Examples
    --------
    >>> import numpy as np
    >>> t, Y = np.arange(5) * 0.01, np.arange(5.0).reshape(1, 5, 1)
    >>> chain = SensorChain([Dropout(0.5)], seed=0)
    >>> chain.apply(t, Y).ravel()
    array([ 0., nan, nan, nan,  4.])
    >>> chain.dropouts
    3
    """

    name = "dropout"
    summary = "with probability p= per sample and channel, the sample becomes NaN"
    draws = "random"

    def __init__(self, p: float | ArrayLike) -> None:
        super().__init__()
        self._p = _channel_param("Dropout.p", p, "prob")
        self._params = {"p": _json(self._p)}
        self._channels(p=self._p)

    @property
    def counts(self) -> NDArray[np.int64] | None:
        """Samples dropped per stream by the batched path since :meth:`reset` (None
        before the first block)."""
        return None if self._bstate is None else self._bstate[1].copy()

    def apply(self, t: Array, Y: Array, draws: _Streams | None) -> Array:
        B, T, p = Y.shape
        self._check_width(p)
        counts = self._fresh_state(B, lambda: np.zeros(B, dtype=np.int64))
        hit = draws.take(T * p).reshape(B, T, p) < self._p  # type: ignore[union-attr]
        out = Y.copy()
        out[hit] = np.nan
        counts += np.count_nonzero(hit, axis=(1, 2))
        return out


class Outliers(Stage):
    """Rare spikes: with probability ``p`` per sample and channel, add ``+-magnitude``.

    The sign is random (+ or - with probability 1/2).  Every sample draws ``2 p`` uniform
    numbers, hit or not.

    Parameters
    ----------
    p : float or array_like
        Outlier probability in [0, 1], per channel.
    magnitude : float or array_like
        Size of a spike, >= 0, per channel.

    Attributes
    ----------
    counts : ndarray of int, shape (B,), or None
        Outliers added per stream since construction or :meth:`reset` (None before the first
        block).

    Examples
    --------
    >>> import numpy as np
    >>> t, Y = np.arange(5) * 0.01, np.arange(5.0).reshape(1, 5, 1)
    >>> SensorChain([Outliers(0.5, 10.0)], seed=0).apply(t, Y).ravel()
    array([ 0., -9.,  2.,  3.,  4.])
    """

    name = "outliers"
    summary = "with probability p= per sample and channel, add +-magnitude= (random sign)"
    draws = "random"

    def __init__(self, p: float | ArrayLike, magnitude: float | ArrayLike) -> None:
        super().__init__()
        self._p = _channel_param("Outliers.p", p, "prob")
        self._mag = _channel_param("Outliers.magnitude", magnitude, "nonneg")
        self._params = {"p": _json(self._p), "magnitude": _json(self._mag)}
        self._channels(p=self._p, magnitude=self._mag)

    @property
    def counts(self) -> NDArray[np.int64] | None:
        """Outliers added per stream by the batched path since :meth:`reset` (None
        before the first block)."""
        return None if self._bstate is None else self._bstate[1].copy()

    def apply(self, t: Array, Y: Array, draws: _Streams | None) -> Array:
        """Per sample ``2 p`` uniform numbers (hit, then sign)."""
        B, T, p = Y.shape
        self._check_width(p)
        counts = self._fresh_state(B, lambda: np.zeros(B, dtype=np.int64))
        u = draws.take(T * 2 * p).reshape(B, T, 2, p)  # type: ignore[union-attr]
        hit = u[:, :, 0] < self._p
        spike = np.where(u[:, :, 1] < 0.5, -1.0, 1.0) * self._mag
        counts += np.count_nonzero(hit, axis=(1, 2))
        return np.where(hit, Y + spike, Y)


class Saturation(Stage):
    """Clip to ``[low, high]``.

    Parameters
    ----------
    low, high : float or array_like
        Limits, per channel, ``low < high``; ``-inf`` / ``+inf`` give a one-sided clip.
        NaN samples stay NaN.

    Examples
    --------
    >>> import numpy as np
    >>> t, Y = np.arange(5) * 0.01, np.arange(5.0).reshape(1, 5, 1)
    >>> SensorChain([Saturation(-1.0, 2.5)]).apply(t, Y).ravel()
    array([0. , 1. , 2. , 2.5, 2.5])
    """

    name = "saturate"
    summary = "clip to [low=, high=] (either may be infinite)"

    def __init__(self, low: float | ArrayLike, high: float | ArrayLike) -> None:
        super().__init__()
        self._low = _channel_param("Saturation.low", low, "extended")
        self._high = _channel_param("Saturation.high", high, "extended")
        self._channels(low=self._low, high=self._high)
        if np.any(np.asarray(self._low) >= np.asarray(self._high)):
            raise DesignError(f"Saturation needs low < high; found low={_json(self._low)}, "
                              f"high={_json(self._high)}")
        self._params = {"low": _json(self._low), "high": _json(self._high)}

    def apply(self, t: Array, Y: Array, draws: _Streams | None) -> Array:
        self._check_width(Y.shape[2])
        out = np.maximum(Y, self._low)          # NaN propagates; cheaper than np.clip
        np.minimum(out, self._high, out=out)
        return out


#: Registry of the stages by name (the ``stage`` key of a spec).
STAGES: dict[str, type[Stage]] = {
    cls.name: cls
    for cls in (Delay, SampleHold, Bias, RandomWalkDrift, GaussianNoise, UniformNoise,
                Outliers, Quantization, Saturation, Dropout)
}


def make_stage(name: str, /, **params: Any) -> Stage:
    """Build a stage from its registry name and keyword parameters.

    Parameters
    ----------
    name : str
        A key of :data:`STAGES` (``"gaussian"``, ``"delay"``, ...).
    **params
        The stage's constructor parameters.

    Returns
    -------
    Stage

    Raises
    ------
    DesignError
        Unknown name (the message lists the valid names), unknown or missing keyword (the
        message lists the valid keywords), or an invalid value.

    Examples
    --------
    >>> make_stage("quantize", counts_per_rev=4096)
    Quantization(counts_per_rev=4096)
    >>> make_stage("gaussian", sigma=0.1)
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: GaussianNoise ('gaussian'): unknown parameter(s) ['sigma']; valid: [...]
    """
    cls = STAGES.get(name) if isinstance(name, str) else None
    if cls is None:
        raise DesignError(f"unknown sensor stage {name!r}; valid: {sorted(STAGES)}")
    sig = inspect.signature(cls.__init__)
    accepted = [p for p in list(sig.parameters.values())[1:]
                if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    reject_unknown(f"{cls.__name__} ({name!r})", params, [p.name for p in accepted])
    missing = [p.name for p in accepted if p.default is p.empty and p.name not in params]
    if missing:
        raise DesignError(f"{cls.__name__} ({name!r}): missing parameter(s) {missing}; "
                          f"valid: {sorted(p.name for p in accepted)}")
    return cls(**params)


def encoder(counts_per_rev: int, std: float = 0.0) -> list[Stage]:
    """Stages of an incremental encoder: optional Gaussian noise, then quantization.

    Parameters
    ----------
    counts_per_rev : int
        Counts per revolution (resolution ``2*pi/counts_per_rev`` rad).
    std : float, default 0
        Standard deviation of noise added before quantization (omitted when 0).

    Returns
    -------
    list of Stage

    Raises
    ------
    DesignError
        ``std`` negative or not finite, or ``counts_per_rev`` not a positive integer.

    Examples
    --------
    >>> encoder(4096)
    [Quantization(counts_per_rev=4096)]
    >>> encoder(4096, std=0.001)
    [GaussianNoise(std=0.001), Quantization(counts_per_rev=4096)]
    """
    stages: list[Stage] = []
    if finite_scalar("encoder.std", std, nonnegative=True) > 0:
        stages.append(GaussianNoise(std=std))
    stages.append(Quantization(counts_per_rev=counts_per_rev))
    return stages


def _check_seed(seed: Any) -> int | None:
    if seed is None:
        return None
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise DesignError(f"seed must be a non-negative integer or None; found {seed!r}")
    return int(seed)


def _is_seed_sequence(seed: Any) -> bool:
    """A sequence of seeds (B streams), as opposed to one seed or None."""
    return isinstance(seed, (Sequence, np.ndarray)) and not isinstance(seed, (str, bytes))


def stream_generators(seed: int | None, count: int) -> list[np.random.Generator]:
    """The generators of the ``count`` random stages of one stream with seed ``seed``: the
    first is ``numpy.random.default_rng(seed)`` (the one generator of a chain before the batch
    axis and its per-sample path: a chain with one random stage gives the same numbers as
    then), the ``k``-th one
    after it (``k = 1, 2, ...``) is seeded by the ``(k-1)``-th child of
    ``SeedSequence(seed)`` (``SeedSequence(seed, spawn_key=(k - 1,))``, what
    ``SeedSequence(seed).spawn`` gives), a stream independent of the first. ``seed`` None:
    fresh OS entropy, shared by the stage generators of the stream."""
    root = np.random.SeedSequence(seed)
    gens = [np.random.default_rng(root)] if count else []
    for k in range(1, count):
        child = np.random.SeedSequence(root.entropy, spawn_key=(k - 1,))
        gens.append(np.random.default_rng(child))
    return gens



def _stage_of(i: int, item: Any) -> Stage:
    """Entry ``i`` of a sensor spec as a stage (:meth:`SensorChain.from_spec`)."""
    if isinstance(item, Stage):
        return item
    if isinstance(item, str):
        return make_stage(item)
    if not isinstance(item, Mapping):
        raise DesignError(f"sensor spec[{i}] must be a dict like "
                          f"{{'stage': 'gaussian', 'std': 0.01}}, a stage name or a Stage; "
                          f"found {item!r}")
    if "stage" not in item:
        raise DesignError(f"sensor spec[{i}] has no 'stage' key (one of "
                          f"{sorted(STAGES)}); found keys {sorted(map(str, item))}")
    return make_stage(item["stage"], **{k: v for k, v in item.items() if k != "stage"})


class SensorChain:
    """A sequence of sensor stages applied in order to blocks of B seeded streams.

    Parameters
    ----------
    stages : sequence of Stage, default ()
        Applied in the order given (see the module docstring for the recommended order).
    seed : int or None, default None
        Seed of the one stream the chain starts with (B = 1, see :func:`stream_generators`).
        The same seed gives bit-identical output sequences.  ``None`` draws fresh OS entropy
        (at construction and at every :meth:`reset` without a seed).

    Notes
    -----
    **Streams** (:meth:`reset` with one seed: B = 1; with a sequence of B seeds: B streams;
    then :meth:`apply` on blocks ``(B, T, p)``): every random stage of a stream draws from its
    own generator (:func:`stream_generators`): the first random stage from
    ``default_rng(seed)``, later ones from generators spawned from the seed. So a chain with
    one random stage (e.g. Gaussian noise then quantization) gives, per stream, exactly the
    numbers of ``default_rng(seed)`` drawn sample after sample. Each stream is the same
    whether run alone or in a batch, and whatever the block sizes. One sample of an unbatched
    chain is ``chain.apply([t], y[None, None])[0, 0]``.

    Examples
    --------
    >>> chain = SensorChain([Bias(0.1), GaussianNoise(std=0.01)], seed=0)
    >>> chain.apply([0.0], np.zeros((1, 1, 2))).shape
    (1, 1, 2)
    >>> chain.reset([0, 1, 2])
    >>> chain.apply(np.array([0.0, 0.01]), np.zeros((3, 2, 2))).shape
    (3, 2, 2)
    """

    def __init__(self, stages: Sequence[Stage] = (), seed: int | None = None) -> None:
        stages = tuple(stages)
        for i, s in enumerate(stages):
            if not isinstance(s, Stage):
                raise DesignError(f"SensorChain stage {i} must be a Stage (see make_stage); "
                                  f"found {type(s).__name__}")
        self._stages: tuple[Stage, ...] = stages
        self._seed0 = _check_seed(seed)
        self._seed = self._seed0
        self._dropout_stages = tuple(s for s in stages if isinstance(s, Dropout))
        self._held: tuple[int, ...] = ()
        self._start_streams((self._seed,), batched=False)

    def _start_streams(self, seeds: tuple[int | None, ...], batched: bool) -> None:
        """The batched path's generators: per random stage one :class:`_Streams` of the B
        streams (None for deterministic stages); every stage's per-stream state cleared."""
        random = [s for s in self._stages if s.draws is not None]
        per_stream = [stream_generators(sd, len(random)) for sd in seeds]
        k = 0
        streams: list[_Streams | None] = []
        for s in self._stages:
            if s.draws is None:
                streams.append(None)
            else:
                streams.append(_Streams([g[k] for g in per_stream], s.draws))
                k += 1
            s.reset()
        self._streams = tuple(streams)
        self._seeds = seeds
        self._batched = batched
        self._held = ()

    @property
    def stages(self) -> tuple[Stage, ...]:
        """The stages, in the order they are applied."""
        return self._stages

    @property
    def has_dropouts(self) -> bool:
        """Whether the chain has a :class:`Dropout` stage (else no sample is ever dropped)."""
        return bool(self._dropout_stages)

    @property
    def seed(self) -> int | None:
        """Seed of the current random stream (``None``: OS entropy)."""
        return self._seed

    @property
    def dropouts(self) -> int:
        """Total number of channel samples dropped by the :class:`Dropout` stages since the
        reset, over every stream (:meth:`dropout_counts` per stream)."""
        return int(self.dropout_counts().sum())

    @property
    def batch(self) -> int:
        """Number of streams B of the batched path (1 after a reset with one seed)."""
        return len(self._seeds)

    @property
    def batched(self) -> bool:
        """Whether the chain was reset with a sequence of seeds."""
        return self._batched

    @property
    def seeds(self) -> tuple[int | None, ...]:
        """The seeds of the B streams."""
        return self._seeds

    def dropout_counts(self) -> NDArray[np.int64]:
        """Samples dropped per stream by the :class:`Dropout` stages since the reset, shape
        ``(B,)``.

        Returns
        -------
        (B,) int ndarray
            Dropped channel samples of each stream (zeros without a Dropout stage).

        Examples
        --------
        >>> import numpy as np
        >>> chain = SensorChain([Dropout(0.5)])
        >>> chain.reset([0, 1])
        >>> _ = chain.apply(np.arange(4) * 0.01, np.zeros((2, 4, 1)))
        >>> chain.dropout_counts().shape
        (2,)
        """
        out = np.zeros(self.batch, dtype=np.int64)
        for s in self._dropout_stages:
            c = s.counts
            if c is not None:
                out += c
        return out

    def apply(self, t: ArrayLike, Y: ArrayLike) -> Array:
        """Measure a block: apply every stage in order to the clean outputs of B streams.

        Parameters
        ----------
        t : array_like, shape (T,)
            Sample times, seconds: finite, non-decreasing, continuing the previous block's.
        Y : array_like, shape (B, T, p)
            Clean outputs of every stream at those times (not modified); B is :attr:`batch`.

        Returns
        -------
        ndarray, shape (B, T, p)
            The measurements, a new array (NaN where a sample was dropped). Stream ``b`` is
            what the chain gives alone with seed ``seeds[b]``, and a block of ``T`` samples is
            what the same samples give cut into any smaller blocks.

        Raises
        ------
        DimensionError
            ``t`` not 1-D, ``Y`` not ``(B, T, p)`` with that B and T, or ``p`` not matching a
            per-channel parameter.
        DesignError
            ``t`` not finite, or decreasing where a stage keeps time (drift, delay).

        Examples
        --------
        >>> import numpy as np
        >>> chain = SensorChain([Bias([0.1, -0.1])])
        >>> chain.apply([0.0, 0.01], np.ones((1, 2, 2)))
        array([[[1.1, 0.9],
                [1.1, 0.9]]])
        """
        try:
            tt = np.asarray(t, dtype=np.float64)
            y = np.asarray(Y, dtype=np.float64)
        except (TypeError, ValueError):
            raise DimensionError("SensorChain.apply: t (T,) and Y (B, T, p) must be arrays of "
                                 "numbers") from None
        if tt.ndim != 1:
            raise DimensionError(f"SensorChain.apply: t must be 1-D (T,); found shape "
                                 f"{tt.shape}")
        if y.ndim != 3 or y.shape[0] != self.batch or y.shape[1] != tt.shape[0]:
            raise DimensionError(f"SensorChain.apply: Y must have shape (B, T, p) = "
                                 f"({self.batch}, {tt.shape[0]}, p); found shape {y.shape}")
        if not np.all(np.isfinite(tt)):
            raise DesignError(f"SensorChain.apply: t must be finite; found {tt.tolist()}")
        if tt.shape[0] == 0:
            return y.copy()
        return self._apply(tt, y)

    def _apply(self, t: Array, Y: Array) -> Array:
        """:meth:`apply` without its checks, for the loop (``t`` finite float ``(T,)``, ``Y``
        float ``(B, T, p)`` with this chain's B, T >= 1): a new array."""
        if not self._stages:
            return Y.copy()
        held = self._held
        if held:   # the held streams' counters are kept as they are (their rows are not used)
            kept = [(s._bstate[1], s._bstate[1][list(held)].copy()) for s in self._stages
                    if s._bstate is not None and isinstance(s._bstate[1], np.ndarray)]
        for s, draws in zip(self._stages, self._streams):
            Y = s.apply(t, Y, draws)
        if held:
            for arr, rows in kept:
                arr[list(held)] = rows
        return Y

    def __len__(self) -> int:
        return len(self._stages)

    def __repr__(self) -> str:
        return f"SensorChain({list(self._stages)!r}, seed={self._seed!r})"

    def reset(self, seed: int | Sequence[int | None] | None = None) -> None:
        """Re-seed the generator(s) and reset every stage.

        Parameters
        ----------
        seed : int, None, or sequence of int or None
            New seed; ``None`` re-uses the constructor's seed (which, if itself ``None``,
            means fresh OS entropy). A sequence of B seeds starts B streams for
            :meth:`apply` (a ``None`` entry: fresh OS entropy for that stream).

        Raises
        ------
        DesignError
            An empty sequence of seeds, or a seed that is not a non-negative integer or None.

        Examples
        --------
        >>> import numpy as np
        >>> chain = SensorChain([GaussianNoise(std=1.0)], seed=3)
        >>> a = chain.apply([0.0], np.zeros((1, 1, 1)))
        >>> chain.reset()                     # the constructor's seed again
        >>> bool(np.array_equal(a, chain.apply([0.0], np.zeros((1, 1, 1)))))
        True
        >>> chain.reset([3, 4])
        >>> chain.batch, chain.seeds
        (2, (3, 4))
        """
        if _is_seed_sequence(seed):
            seeds = tuple(_check_seed(sd) for sd in seed)  # type: ignore[union-attr]
            if not seeds:
                raise DesignError("seed: a sequence of seeds needs at least one; found none")
            self._seed = seeds[0]
            batched = True
        else:
            self._seed = self._seed0 if seed is None else _check_seed(seed)
            seeds, batched = (self._seed,), False
        self._start_streams(seeds, batched)

    def restart(self) -> None:
        """Reset every stage's state (held samples, delay lines, drifts, counters) and let the
        generators continue where they are: Gymnasium's ``reset()`` without a seed.

        Examples
        --------
        >>> import numpy as np
        >>> chain = SensorChain([Delay(0.01), GaussianNoise(std=1.0)], seed=0)
        >>> a = chain.apply([0.0, 0.01], np.zeros((1, 2, 1)))
        >>> chain.restart()                  # time may start over; new noise draws
        >>> b = chain.apply([0.0, 0.01], np.zeros((1, 2, 1)))
        >>> bool(np.array_equal(a, b))
        False
        """
        for s in self._stages:
            s.reset()

    def reset_members(self, idx: Sequence[int], seeds: Sequence[int | None]) -> None:
        """Restart the streams ``idx`` only: their stages' state cleared, each reseeded with
        its entry of ``seeds`` (an int: as :meth:`reset` with that seed gives the stream) or
        left to continue (None: as :meth:`restart`). The other streams go on untouched.

        Raises
        ------
        DesignError
            A stage that keeps time (delay, sample-and-hold, drift), a bad seed, or ``seeds``
            not one per member.

        Parameters
        ----------
        idx : sequence of int
            The streams to restart.
        seeds : sequence of int or None
            One per entry of ``idx``: a new seed, or None to let the stream's generators
            continue.

        Examples
        --------
        >>> import numpy as np
        >>> chain = SensorChain([GaussianNoise(std=1.0)])
        >>> chain.reset([7, 8])
        >>> first = chain.apply([0.0], np.zeros((2, 1, 1)))
        >>> chain.reset_members([1], [8])        # stream 1 starts over with seed 8
        >>> again = chain.apply([0.01], np.zeros((2, 1, 1)))
        >>> bool(again[1, 0, 0] == first[1, 0, 0]), chain.seeds
        (True, (7, 8))
        """
        if len(seeds) != len(idx):
            raise DesignError(f"reset_members: one seed (or None) per member; found "
                              f"{len(seeds)} for {len(idx)}")
        checked = [_check_seed(sd) for sd in seeds]
        for s in self._stages:
            s.restart_members(idx)
        random = [st for st in self._streams if st is not None]
        seeds_now = list(self._seeds)
        for b, sd in zip(idx, checked):
            if sd is None:
                continue
            for st, g in zip(random, stream_generators(sd, len(random))):
                st.reseed(int(b), g)
            seeds_now[int(b)] = sd
        self._seeds = tuple(seeds_now)

    def hold(self, idx: Sequence[int]) -> None:
        """The streams ``idx`` do not advance at the next blocks (until ``hold(())``): what
        they are served then comes again, in order (their members' rows are not used).

        Parameters
        ----------
        idx : sequence of int
            The streams to hold; ``()`` releases them all.

        Raises
        ------
        DesignError
            A chain with a stage that keeps time (delay, sample-and-hold, drift).

        Examples
        --------
        >>> import numpy as np
        >>> chain = SensorChain([GaussianNoise(std=1.0)])
        >>> chain.reset([5, 6])
        >>> chain.hold([1])
        >>> a = chain.apply([0.0], np.zeros((2, 1, 1)))
        >>> chain.hold(())
        >>> b = chain.apply([0.01], np.zeros((2, 1, 1)))
        >>> bool(b[1, 0, 0] == a[1, 0, 0])     # stream 1 is served its held draw again
        True
        """
        rows = tuple(int(b) for b in idx)
        if any(s.keeps_time for s in self._stages) and rows:
            raise DesignError("a chain with a stage that keeps time cannot hold streams")
        self._held = rows
        for st in self._streams:
            if st is not None:
                st._hold = rows

    def describe(self) -> list[dict[str, Any]]:
        """The chain as JSON-friendly data: ``[{"stage": name, **params}, ...]``.

        :meth:`from_spec` rebuilds an equivalent chain from it.

        Returns
        -------
        list of dict
            One dict per stage, in order: its registry name under ``"stage"`` and its
            parameters.

        Examples
        --------
        >>> SensorChain([Bias(0.1), GaussianNoise(std=0.01)]).describe()
        [{'stage': 'bias', 'offset': 0.1}, {'stage': 'gaussian', 'std': 0.01}]
        """
        return [{"stage": s.name, **s.params()} for s in self._stages]

    @classmethod
    def from_spec(cls, spec: Any, seed: int | None = None) -> SensorChain:
        """Build a chain from its description: the one reader of a sensor spec (a scenario's
        ``[sensor] stages``, an environment's ``sensor=``).

        Parameters
        ----------
        spec : sequence of (mapping, str or Stage), one of those, or None
            The stages in order, each a mapping such as ``{"stage": "gaussian", "std": 0.01}``
            (a registry name under ``"stage"`` and the stage's parameters), a bare name (a
            stage without required parameters) or a :class:`Stage` (used as is); one stage
            alone; ``None`` or ``[]`` for exact measurements.
        seed : int or None, default None
            Seed of the chain.

        Returns
        -------
        SensorChain

        Raises
        ------
        DesignError
            A malformed entry, a mapping without a ``"stage"`` key, or an invalid stage (see
            :func:`make_stage`).

        Examples
        --------
        >>> SensorChain.from_spec([{"stage": "gaussian", "std": 0.01},
        ...                        {"stage": "quantize", "resolution": 0.001}], seed=0)
        SensorChain([GaussianNoise(std=0.01), Quantization(resolution=0.001)], seed=0)
        >>> SensorChain.from_spec([Bias(0.1), {"stage": "gaussian", "std": 0.01}]).describe()
        [{'stage': 'bias', 'offset': 0.1}, {'stage': 'gaussian', 'std': 0.01}]
        >>> SensorChain.from_spec([{"std": 0.01}])
        Traceback (most recent call last):
        ...
        hgo_mj.exceptions.DesignError: sensor spec[0] has no 'stage' key (one of [...]); found keys ['std']
        """
        if spec is None:
            spec = []
        elif isinstance(spec, (Mapping, str, Stage)):
            spec = [spec]
        elif isinstance(spec, bytes) or not isinstance(spec, Sequence):
            raise DesignError("sensor spec must be a list of stages, each a dict like "
                              f"{{'stage': 'gaussian', 'std': 0.01}}, a stage name or a Stage; "
                              f"found {spec!r}")
        return cls([_stage_of(i, item) for i, item in enumerate(spec)], seed=seed)

    def noise_variance(self, n_outputs: int) -> Array:
        """Per-channel variance of the white noise the chain adds.

        The sum of the variances of the :class:`GaussianNoise` and :class:`UniformNoise`
        stages plus ``resolution**2 / 12`` for each :class:`Quantization` stage; bias, drift,
        outliers, saturation, delay, sample-hold and dropout are not counted.  A default for
        a Kalman filter's measurement covariance.

        Parameters
        ----------
        n_outputs : int
            Number of output channels, >= 1.

        Returns
        -------
        ndarray, shape (n_outputs,)

        Raises
        ------
        DimensionError
            A per-channel parameter whose length is not ``n_outputs``.
        DesignError
            ``n_outputs`` not a positive integer.

        Examples
        --------
        >>> chain = SensorChain([GaussianNoise(std=0.1), Quantization(resolution=0.01)])
        >>> chain.noise_variance(2).round(8)         # 0.1**2 + 0.01**2 / 12
        array([0.01000833, 0.01000833])
        """
        if (isinstance(n_outputs, bool) or not isinstance(n_outputs, (int, np.integer))
                or n_outputs < 1):
            raise DesignError(f"n_outputs must be a positive integer; found {n_outputs!r}")
        var = np.zeros(int(n_outputs))
        for s in self._stages:
            v = s.noise_variance()
            if v is None:
                continue
            if not isinstance(v, float) and v.shape[0] != n_outputs:
                raise DimensionError(f"{type(s).__name__}.{s._n_from} has {v.shape[0]} "
                                     f"entries (one per channel) but n_outputs is {n_outputs}")
            var += v
        return var
