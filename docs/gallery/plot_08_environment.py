"""
An observer in the loop of a Gymnasium environment
==================================================

``hgo_mj/PendulumSwingUp-v0`` is the MuJoCo pendulum with its angle measured through noise and
a high-gain observer in the loop; the agent sees the estimate. A hand-written energy-pumping
policy acts on that estimate here; ``info_level="full"`` adds the true state and the estimate
to ``info`` at every step.
"""

import gymnasium
import hgo_mj.envs  # noqa: F401  (registers the environments)
import numpy as np

from hgo_mj.plotting import subplots

# %%
# An energy-pumping policy on the estimate
# ----------------------------------------
#
# The observation is ``(cos, sin, angular velocity)`` of the estimate; ``info`` holds the truth.

env = gymnasium.make("hgo_mj/PendulumSwingUp-v0", info_level="full")
obs, info = env.reset(seed=0)
t, true, est = [], [], []
for _ in range(150):
    cos_a, sin_a, w = obs
    action = np.array([1.0 if w * cos_a <= 0 else -1.0], dtype=np.float32)  # pump energy
    obs, reward, terminated, truncated, info = env.step(action)
    t.append(info["time"])
    true.append(info["state"])
    est.append(info["estimate"])
env.close()
true, est = np.array(true), np.array(est)

# %%
# The estimate the agent saw, against the truth
# ---------------------------------------------

fig, axes = subplots(2, 1, figsize=(7, 5), layout="constrained", sharex=True)
for i, (ax, label) in enumerate(zip(axes, ["angle [rad]", "angular velocity [rad/s]"])):
    ax.plot(t, est[:, i], color="C1", lw=1, label="estimate")
    ax.plot(t, true[:, i], color="k", lw=1, ls="--", label="true")
    ax.set_ylabel(label)
axes[0].legend()
axes[0].set_title("PendulumSwingUp-v0: the agent acts on the estimate")
axes[-1].set_xlabel("time [s]")
