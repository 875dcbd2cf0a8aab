"""
A recording read back as a table
================================

:func:`hgo_mj.record.record_trajectory` writes a run to a rerun recording (``.rrd``: open it
with ``rerun FILE``); :func:`hgo_mj.record.read` returns its series as a pandas DataFrame, one
column per entity and series, with units in the names. Here the truth and one observer's
estimate of the pendulum's velocity, as a reviewer would query them.
"""

import tempfile
from pathlib import Path

from hgo_mj.inputs import Multisine
from hgo_mj.observers import HighGainObserver
from hgo_mj.plants import make_plant
from hgo_mj.plotting import subplots
from hgo_mj.record import read, record_trajectory
from hgo_mj.sensors import GaussianNoise, SensorChain
from hgo_mj.simulate import simulate

# %%
# Record a run, read it back
# --------------------------
#
# The recording is written to a temporary folder here; the DataFrame outlives it.

plant = make_plant("pendulum", dt=0.001)
traj = simulate(plant, SensorChain([GaussianNoise(std=1e-3)], seed=0),
                {"k40": HighGainObserver(plant.system, k=40.0)},
                Multisine(amplitudes=[0.3], frequencies=[0.5]), duration=2.0, x0=[0.5, 0.0],
                seed=0)
with tempfile.TemporaryDirectory() as tmp:
    df = read(record_trajectory(traj, Path(tmp, "pendulum.rrd")))
velocity = [c for c in df.columns if "angular_velocity" in c and "error" not in c]
print(velocity)

# %%
# The truth and the estimate, from the table
# ------------------------------------------

fig, ax = subplots(figsize=(7, 3.5), layout="constrained")
for column in velocity:
    ax.plot(df["sim_time"], df[column], lw=1, label=column)
ax.set_xlabel("sim_time [s]")
ax.set_ylabel("angular velocity [rad/s]")
ax.legend(fontsize=8)
