"""A bank of observers run as one: each member reads its own channels of the same measurement,
the estimate is the members' estimates concatenated.

Used for per-channel model-free observers (one chain per measured signal, as in
:class:`~envs.wrappers.ObserverInTheLoop`) and as the two-link arm's fallback when no
multi-output observer is registered.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..exceptions import DesignError, DimensionError
from .base import Array, Observer, Params, State
from .high_gain import derivative_names

__all__ = ["ObserverBank"]


class ObserverBank(Observer):
    """Several observers on the same measurement stream, advanced together; the estimate is
    their concatenation.

    Parameters
    ----------
    observers : sequence of Observer
        The members, each reading its own channels (its ``outputs``) of ``y``. The bank's
        state and parameters hold each member's (fields ``members``), advanced with the
        bank's batch.
    names : sequence of str, optional
        Names of the concatenated estimate; default: each member's ``state_names`` (for a
        single-output member without a system, the derivatives of
        ``output_names[member.outputs[0]]``).
    output_names : sequence of str, optional
        Names of the measured channels, used for the default names (default ``y1, y2, ...``,
        1-based as in :attr:`~hgo_mj.observers.MultiOutputHighGainObserver.output_names`).

    Attributes
    ----------
    members : tuple of Observer
    outputs : tuple of int
        The union of the members' outputs, in order of first appearance.

    Notes
    -----
    ``z_hat`` is the members' ``z_hat`` concatenated (``sum(member.n)`` entries), ``x_hat``
    their ``x_hat`` (``len(state_names)``); the diagnostics are each member's own, suffixed
    with its index (``k_0``, ``k_1``, ...), then the bank's ``dropouts``: samples at which at
    least one of the bank's channels was NaN (each member counts its own in ``dropouts_``).

    Examples
    --------
    >>> import numpy as np
    >>> from hgo_mj.observers import HighGainObserver, ObserverBank
    >>> bank = ObserverBank([HighGainObserver(order=2, k=10.0, outputs=(c,)) for c in (0, 1)])
    >>> bank.state_names
    ('y1', 'y1_d1', 'y2', 'y2_d1')
    >>> bank.update(np.array([1.0, np.nan]), np.zeros(0), 0.01).shape
    (4,)
    """

    name = "bank"
    summary = "several observers on the same measurement, estimates concatenated"
    needs_normal_form = False
    grouped = False  # each member groups its own members by their parameters

    def __init__(self, observers: Sequence[Observer], *, names: Sequence[str] | None = None,
                 output_names: Sequence[str] | None = None) -> None:
        members = tuple(observers)
        if not members or not all(isinstance(o, Observer) for o in members):
            raise DesignError(f"ObserverBank needs a non-empty sequence of Observer instances; "
                              f"found {[type(o).__name__ for o in members]}")
        widths = {o.n_inputs for o in members} - {None}
        if len(widths) > 1:
            raise DimensionError(f"ObserverBank: the members read inputs of different widths "
                                 f"{sorted(widths)}")  # type: ignore[type-var]
        self.members = members
        self._m = widths.pop() if widths else None
        outputs = tuple(dict.fromkeys(c for o in members for c in o.outputs))
        super().__init__(None, order=sum(o.n for o in members), outputs=outputs)
        if names is None:
            built: list[str] = []
            for o in members:
                if o.system is None and len(o.outputs) == 1:
                    c = o.outputs[0]
                    out = f"y{c + 1}" if output_names is None else str(output_names[c])
                    built += derivative_names(out, len(o.state_names))
                else:
                    built += list(o.state_names)
            names = built
        names = tuple(str(s) for s in names)
        n_x = sum(len(o.state_names) for o in members)
        if len(names) != n_x:
            raise DesignError(f"ObserverBank: names must give one name per estimate ({n_x}); "
                              f"found {len(names)}")
        if len(set(names)) != len(names):
            raise DesignError(f"ObserverBank: estimate names must be distinct; found {list(names)}")
        self._names = names
        self.family_diagnostics = tuple(f"{key}_{i}" for i, o in enumerate(members)  # type: ignore[misc]
                                        for key in o.family_diagnostics)
        #: width of the full measurement the members index into
        self._width = max(outputs) + 1

    @property
    def n_inputs(self) -> int | None:
        """The members' input width (None: no member reads an input)."""
        return getattr(self, "_m", None)

    @property
    def state_names(self) -> tuple[str, ...]:
        return self._names

    def parameters(self, batch: int = 1, **values: Any) -> Params:
        """The members' parameters: ``members``, one :class:`Params` per member (a member's
        own are set on the member, or through ``members=``: a sequence of dicts of values)."""
        per = values.pop("members", None)
        if values:
            raise DesignError(f"bank: unknown parameter(s) {sorted(values)}; valid: ['members'] "
                              f"(one dict of values per member)")
        if per is None:
            per = [{}] * len(self.members)
        if not isinstance(per, (list, tuple)) or len(per) != len(self.members) or not all(
                isinstance(v, dict) for v in per):
            raise DesignError(f"bank: members must be one dict of parameter values per member "
                              f"({len(self.members)}); found {per!r}")
        return Params(members=tuple(o.parameters(batch, **v) for o, v in zip(self.members, per)))

    def _check_period(self, p: Params, dt: float) -> None:
        for o, po in zip(self.members, p.members):
            o.check_period(dt, po)

    def _init(self, p: Params, x0: Array | None, z0: Array | None,
              u0: Array) -> dict[str, Any]:
        B = u0.shape[0]
        u = None if self._m is None else u0
        i = 0
        states = []
        for o, po in zip(self.members, p.members):
            if x0 is not None:
                w = len(o.state_names)
                states.append(o.init(B, x0[:, i:i + w], u0=u, params=po))
            elif z0 is not None:
                w = o.n
                states.append(o.init(B, z_hat0=z0[:, i:i + w], u0=u, params=po))
            else:
                w = 0
                states.append(o.init(B, u0=u, params=po))
            i += w
        return {"members": tuple(states)}

    def _step(self, p: Params, s: State, Y: Array, U: Array, dt: float, X: Array, Z: Array,
              D: Array) -> None:
        B, T = Y.shape[0], Y.shape[1]
        full = np.full((B, T, self._width), np.nan)
        full[:, :, self._cols] = Y
        ix = iz = idg = 0
        for o, po, so in zip(self.members, p.members, s.members):
            blk = o._step_checked(po, so, full, U, dt)
            nx, nz, nd = blk.x_hat.shape[2], blk.z_hat.shape[2], len(o.family_diagnostics)
            X[:, :, ix:ix + nx] = blk.x_hat
            Z[:, :, iz:iz + nz] = blk.z_hat
            D[:, :, idg:idg + nd] = blk.diagnostics[:, :, :nd]
            ix, iz, idg = ix + nx, iz + nz, idg + nd

    @property
    def measurement_update(self) -> bool:  # type: ignore[override]
        """Whether any member has a discrete measurement update (:meth:`filtered`)."""
        return any(o.measurement_update for o in self.members)

    def _filtered(self, p: Params, s: State, Y: Array) -> Array:
        return np.concatenate([o._filtered_of(po, so, Y) for o, po, so in
                               zip(self.members, p.members, s.members)], axis=1)

    def _current(self, p: Params, s: State) -> tuple[Array, Array, Array]:
        parts = [o.current(po, so) for o, po, so in zip(self.members, p.members, s.members)]
        return (np.concatenate([x for x, _, _ in parts], axis=1),
                np.concatenate([z for _, z, _ in parts], axis=1),
                np.concatenate([d[:, :len(o.family_diagnostics)] for o, (_, _, d) in
                                zip(self.members, parts)], axis=1))

    def params(self) -> dict[str, Any]:
        return {"members": [{"type": type(o).__name__, **o.params()} for o in self.members],
                "names": list(self._names)}
