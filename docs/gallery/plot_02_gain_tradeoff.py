"""
The gain trade-off: speed against noise
=======================================

A high-gain observer's error after the transient is bounded by ``a/k + b sigma k^(n-1)``: the
model term it ignores shrinks with the gain ``k``, the measurement noise grows with it. Here
the velocity RMSE of a model-free observer on the pendulum at nine gains and two noise levels,
all observers on the same measurement stream per noise level (one :func:`simulate` call each).
"""

import numpy as np

from hgo_mj.inputs import Multisine
from hgo_mj.metrics import all_metrics
from hgo_mj.observers import HighGainObserver
from hgo_mj.plants import make_plant
from hgo_mj.plotting import subplots
from hgo_mj.sensors import GaussianNoise, SensorChain
from hgo_mj.simulate import simulate

# %%
# Nine gains on one measurement stream per noise level
# ----------------------------------------------------
#
# The RMSE falls with the gain while the ignored model term dominates, then rises once the
# noise, amplified as ``k^(n-1)``, takes over: the best gain falls as the noise grows.

plant = make_plant("pendulum", dt=0.001)
u = Multisine(amplitudes=[0.8, 0.3], frequencies=[0.4, 1.5], phases=[0.0, 1.0])
gains = np.geomspace(5, 500, 9)
fig, ax = subplots(figsize=(6, 4), layout="constrained")
for std in (1e-4, 1e-3):
    observers = {f"k{k:.0f}": HighGainObserver(plant.system, k=float(k)) for k in gains}
    traj = simulate(plant, SensorChain([GaussianNoise(std=std)], seed=0), observers, u,
                    duration=4.0, x0=[0.3, 0.0], seed=0)
    m = all_metrics(traj, t_transient=1.0)
    rmse = [m[name]["rmse"][1] for name in observers]
    ax.loglog(gains, rmse, "o-", label=f"noise std {std:g} rad")
ax.set_xlabel("gain k [1/s]")
ax.set_ylabel("angular velocity RMSE after 1 s [rad/s]")
ax.set_title("model-free high-gain observer on the pendulum")
ax.legend()
