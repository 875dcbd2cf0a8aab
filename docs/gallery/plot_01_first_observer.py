"""
A first observer: the pendulum's velocity from a noisy encoder
==============================================================

The MuJoCo pendulum (``models/pendulum.xml``) is the true plant; only its angle is measured,
through Gaussian noise and a 4096-count encoder. Two high-gain observers (paper 000, eq. 2)
estimate the angle and the angular velocity from the same measurements: the higher gain
converges faster and passes more noise. :func:`hgo_mj.plotting.plot_trajectory` draws the truth
on top of each estimate and the errors on a shared axis.
"""

from hgo_mj.inputs import Multisine
from hgo_mj.metrics import all_metrics, format_table
from hgo_mj.observers import HighGainObserver
from hgo_mj.plants import make_plant
from hgo_mj.plotting import plot_trajectory
from hgo_mj.sensors import GaussianNoise, Quantization, SensorChain
from hgo_mj.simulate import simulate
from hgo_mj.units import units_of

# %%
# The plant, the sensor chain and two observers
# -----------------------------------------------
#
# The noise is seeded once, by the run (``simulate(..., seed=1)``); both observers see the same
# measurements.

plant = make_plant("pendulum", dt=0.001)
sensor = SensorChain([GaussianNoise(std=1e-3), Quantization(counts_per_rev=4096)])
observers = {"k20": HighGainObserver(plant.system, k=20.0),
             "k80": HighGainObserver(plant.system, k=80.0)}
u = Multisine(amplitudes=[0.3], frequencies=[0.5])  # torque, N m
traj = simulate(plant, sensor, observers, u, duration=5.0, x0=[0.5, 0.0], seed=1)

# %%
# The metrics, with each state's unit
# -----------------------------------
#
# RMSE after the first second, the peak error, the settling time into 5 % of each state's range
# and the final error, per observer and state (:func:`hgo_mj.metrics.format_table`).

print(format_table(all_metrics(traj, t_transient=1.0), *units_of(traj)))

# %%
# The trajectory
# --------------
#
# The truth on top of each estimate (left) and the errors (right); the error axes fit the run
# after its first fifth, so the peaking of the higher gain does not hide the steady state.

fig = plot_trajectory(traj, title="pendulum, two gains")
