"""
A Kalman filter beside a high-gain observer
===========================================

The extended Kalman filter knows the model and the noise covariance; the model-free high-gain
observer knows neither. On the pendulum with the angle measured through noise, both see the
same measurement stream, sampled at 200 Hz; their errors share one axis per state.
"""

from hgo_mj.inputs import Multisine
from hgo_mj.observers import ExtendedKalmanFilter, HighGainObserver
from hgo_mj.plants import make_plant
from hgo_mj.plotting import plot_trajectory
from hgo_mj.sensors import GaussianNoise, SensorChain
from hgo_mj.simulate import simulate

# %%
# Two observers, one measurement stream
# -------------------------------------
#
# The EKF is given the noise variance ``R`` and a process noise ``Q``; the high-gain observer only
# its gain.

plant = make_plant("pendulum", dt=0.001)
sensor = SensorChain([GaussianNoise(std=2e-3)])
observers = {"hgo": HighGainObserver(plant.system, k=40.0),
             "ekf": ExtendedKalmanFilter(plant.system, Q=1e-2, R=(2e-3) ** 2)}
traj = simulate(plant, sensor, observers, Multisine(amplitudes=[0.3], frequencies=[0.5]),
                duration=3.0, x0=[0.5, 0.0], sample_period=0.005, seed=0)

# %%
# Their errors on shared axes
# ---------------------------

fig = plot_trajectory(traj, title="pendulum: EKF and high-gain observer")
