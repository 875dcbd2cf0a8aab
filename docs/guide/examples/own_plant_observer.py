"""Your own plant and observer: the Van der Pol oscillator and an Euler-Luenberger observer.

Run it with ``python docs/guide/examples/own_plant_observer.py``; ``tests/test_docs.py`` runs
it too, so this page cannot go stale.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from hgo_mj.inputs import Multisine
from hgo_mj.metrics import all_metrics, format_table
from hgo_mj.observers import HighGainObserver, Observer, make_observer, register
from hgo_mj.observers.base import Params, State
from hgo_mj.plants import OdePlant
from hgo_mj.sensors import GaussianNoise, SensorChain
from hgo_mj.simulate import simulate
from hgo_mj.systems import System
from hgo_mj.units import units_of


# --- a plant: the analytic model as a System; OdePlant integrates it as the true plant -----
class VanDerPol(System):
    """x1' = x2, x2' = mu (1 - x1^2) x2 - x1 + u, y = x1 (already in normal form: z = x)."""

    name: ClassVar[str] = "van_der_pol"
    summary: ClassVar[str] = "Van der Pol oscillator, y = x1"
    state_names: ClassVar[tuple[str, ...]] = ("position", "velocity")
    state_units: ClassVar[tuple[str, ...]] = ("m", "m/s")
    input_names: ClassVar[tuple[str, ...]] = ("force",)
    input_units: ClassVar[tuple[str, ...]] = ("N",)
    output_names: ClassVar[tuple[str, ...]] = ("position",)
    param_names: ClassVar[tuple[str, ...]] = ("mu",)
    default_params: ClassVar[Mapping[str, float]] = {"mu": 1.0}
    default_x0: ClassVar[tuple[float, ...]] = (1.0, 0.0)
    normal_form_order: ClassVar[int | None] = 2

    @staticmethod
    def dynamics(t: float, x: np.ndarray, u: np.ndarray, p: Mapping[str, float]) -> np.ndarray:
        return np.array([x[1], p["mu"] * (1.0 - x[0] ** 2) * x[1] - x[0] + u[0]])

    @staticmethod
    def output(x: np.ndarray, p: Mapping[str, float]) -> np.ndarray:
        return np.array([x[0]])

    def to_normal(self, x: Any, u: Any = None) -> np.ndarray:
        return np.asarray(x, dtype=float).copy()  # z = (y, y') = x

    def from_normal(self, z: Any, u: Any = None) -> np.ndarray:
        return np.asarray(z, dtype=float).copy()

    def phi(self, z: Any, u: Any = None) -> float:
        u0 = 0.0 if u is None else float(np.ravel(u)[0])
        return float(self.params["mu"] * (1.0 - z[0] ** 2) * z[1] - z[0] + u0)


# --- an observer: state and parameters as data, the algorithm in _step --------------------
@register
class EulerLuenberger(Observer):
    """z' = A z + L (y - z1) + e_n phi(z, u), integrated by forward Euler, L = (2w, w^2)."""

    name: ClassVar[str] = "euler_luenberger"
    summary: ClassVar[str] = "Luenberger observer with the model term, forward Euler"

    def __init__(self, system: System | None = None, *, w: float = 10.0,
                 outputs: Any = (0,)) -> None:
        super().__init__(system, outputs=outputs)
        self.w = float(w)

    def _parameters(self) -> dict[str, Any]:  # tunable, per member in a batch
        return {"w": self.w}

    def _init(self, p: Params, x0: np.ndarray | None, z0: np.ndarray | None,
              u0: np.ndarray) -> dict[str, np.ndarray]:
        if z0 is not None:
            z = np.array(z0, dtype=float)
        elif x0 is not None:
            z = np.array([self.system.to_normal(x, u) for x, u in zip(x0, u0)])
        else:
            z = np.zeros((u0.shape[0], self.n))
        return {"z": z}  # the state: (B, ...) arrays

    def _step(self, p: Params, s: State, Y: np.ndarray, U: np.ndarray, dt: float,
              X: np.ndarray, Z: np.ndarray, D: np.ndarray) -> None:
        w = float(p.w)  # one member's parameters (the base groups members by parameters)
        gains = np.array([2.0 * w, w ** 2])
        for j in range(Y.shape[1]):
            e = np.nan_to_num(Y[:, j, 0] - s.z[:, 0])  # a dropout (NaN): no correction
            rate = np.column_stack([s.z[:, 1], self.system.phi_batch(s.z, U[:, j])])
            s.z = s.z + dt * (rate + gains * e[:, None])
            Z[:, j] = s.z
            X[:, j] = s.z  # from_normal is the identity here

    def _current(self, p: Params, s: State) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return s.z.copy(), s.z.copy(), np.zeros((s.z.shape[0], 0))


plant = OdePlant(VanDerPol(mu=1.0), dt=0.001)
observers = {
    "luenberger": make_observer("euler_luenberger", plant.system, w=10.0),
    "hgo": HighGainObserver(plant.system, k=10.0, model=True),
}
traj = simulate(plant, SensorChain([GaussianNoise(std=1e-3)], seed=0), observers,
                Multisine(amplitudes=[0.5], frequencies=[0.3]), duration=10.0,
                x0=[2.0, 0.0], seed=0)
metrics = all_metrics(traj, t_transient=2.0)
print(format_table(metrics, *units_of(traj)))
assert all(np.all(np.asarray(m["rmse"]) < 0.05) for m in metrics.values())

# --- many tunings as one batch: member i runs with w[i], each equal to its single run -------
ob = observers["luenberger"]
params = ob.parameters(3, w=[5.0, 10.0, 20.0])
state = ob.init(3, [2.0, 0.0], params=params)
y = traj.y_meas[None, :200].repeat(3, axis=0)
u = traj.u[None, :200].repeat(3, axis=0)
state, rows = ob.step(params, state, y, u, 0.001)
single = ob.parameters(1, w=20.0)
_, alone = ob.step(single, ob.init(1, [2.0, 0.0], params=single), y[:1], u[:1], 0.001)
assert np.array_equal(rows.x_hat[2], alone.x_hat[0])
