"""Observer helpers of the environments: a bank of observers run as one."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hgo_mj.exceptions import DesignError
from hgo_mj.observers import Observer
from hgo_mj.observers.high_gain import derivative_names

Array = NDArray[np.float64]


class ObserverBank(Observer):
    """Several observers fed the same measurement, run as one; the estimate is their concatenation.

    Used for per-channel model-free observers (one chain per measured signal, as in
    :class:`~envs.wrappers.ObserverInTheLoop`) and as the two-link arm's fallback when no
    multi-output observer is registered.

    Parameters
    ----------
    observers : sequence of Observer
        The members, each reading its own channel (``output``) of ``y``.
    names : sequence of str, optional
        Names of the concatenated estimate; default: each member's ``state_names`` (for a
        member without a system, the derivatives of ``output_names[member.output]``).
    output_names : sequence of str, optional
        Names of the measured channels, used for the default names (default ``y1, y2, ...``,
        1-based as in :attr:`~hgo_mj.observers.MultiOutputHighGainObserver.output_names`).

    Attributes
    ----------
    members : tuple of Observer
    outputs : tuple of int
        The measured channels the members read.
    """

    name = "bank"
    summary = "several observers on the same measurement, estimates concatenated"

    def __init__(self, observers: Sequence[Observer], *, names: Sequence[str] | None = None,
                 output_names: Sequence[str] | None = None) -> None:
        members = tuple(observers)
        if not members or not all(isinstance(o, Observer) for o in members):
            raise DesignError(f"ObserverBank needs a non-empty sequence of Observer instances; "
                              f"found {[type(o).__name__ for o in members]}")
        self.members = members
        self.system = None
        self.n = sum(len(o.state_names) for o in members)
        self.output = members[0].output
        #: the measured channels the members read (a multi-output member's ``outputs``)
        self.outputs = tuple(int(c) for o in members
                             for c in (getattr(o, "outputs", None) or (o.output,)))
        self.dropouts_ = 0
        self.inverse_failures_ = 0
        if names is None:
            built: list[str] = []
            for o in members:
                if o.system is None and output_names is not None:
                    built += derivative_names(str(output_names[o.output]), len(o.state_names))
                elif o.system is None:
                    built += derivative_names(f"y{o.output + 1}", len(o.state_names))
                else:
                    built += list(o.state_names)
            names = built
        names = tuple(str(s) for s in names)
        if len(names) != self.n:
            raise DesignError(f"ObserverBank: names must give one name per estimate ({self.n}); "
                              f"found {len(names)}")
        if len(set(names)) != len(names):
            raise DesignError(f"ObserverBank: estimate names must be distinct; found {list(names)}")
        self._names = names

    @property
    def state_names(self) -> tuple[str, ...]:
        return self._names

    def check_period(self, dt: float) -> None:
        for o in self.members:
            o.check_period(dt)

    def reset(self, x_hat0: Any = None, *, z_hat0: Any = None, u0: Any = None) -> None:
        if x_hat0 is not None or z_hat0 is not None:
            v = np.asarray(x_hat0 if x_hat0 is not None else z_hat0, dtype=float).reshape(-1)
            if v.size != self.n:
                raise DesignError(f"ObserverBank.reset: the initial estimate must have {self.n} "
                                  f"entries; found {v.size}")
            i = 0
            for o in self.members:
                n = len(o.state_names)
                if o.system is None:
                    o.reset(z_hat0=v[i:i + n])
                else:
                    o.reset(v[i:i + n])
                i += n
        else:
            for o in self.members:
                o.reset()

    def update(self, y: Any, u: Any, dt: float) -> Array:
        parts = [o.update(y, u, dt) for o in self.members]
        return np.concatenate(parts)

    @property
    def z_hat(self) -> Array:
        return np.concatenate([o.z_hat for o in self.members])

    @property
    def x_hat(self) -> Array:
        return np.concatenate([o.x_hat for o in self.members])

    def diagnostics(self) -> dict[str, float]:
        out: dict[str, float] = {}
        drop = 0.0
        for i, o in enumerate(self.members):
            for key, value in o.diagnostics().items():
                if key == "dropouts":
                    drop += float(value)
                else:
                    out[f"{key}_{i}"] = value
        out["dropouts"] = drop
        return out

    def params(self) -> dict[str, Any]:
        return {"members": [{"type": type(o).__name__, **o.params()} for o in self.members],
                "names": list(self._names)}
