"""
The sensor chain, stage by stage
================================

A :class:`~hgo_mj.sensors.SensorChain` applies its stages in the order given, each stream drawn
from its own seeded generator. Here a clean sine goes through noise, a 64-count quantizer, a
sample-and-hold at 50 ms, a 30 ms delay and 10 % dropouts (NaN: a missing sample, never a
silent zero).
"""

import numpy as np

from hgo_mj.plotting import subplots
from hgo_mj.sensors import (
    Delay,
    Dropout,
    GaussianNoise,
    Quantization,
    SampleHold,
    SensorChain,
)

# %%
# A clean sine, then one stage more in each panel
# -----------------------------------------------
#
# Each chain is seeded, so every panel draws the same noise for the stages it shares.

t = np.arange(0.0, 1.0, 0.001)
y = np.sin(2 * np.pi * t)[None, :, None]  # (B, T, p) = (1, 1000, 1)
stages = [GaussianNoise(std=0.02), Quantization(counts_per_rev=64), SampleHold(period=0.05),
          Delay(delay=0.03), Dropout(p=0.1)]
fig, axes = subplots(len(stages), 1, figsize=(7, 8), layout="constrained", sharex=True)
for i, ax in enumerate(axes):
    chain = SensorChain(stages[: i + 1], seed=0)
    ax.plot(t, y[0, :, 0], color="0.6", lw=1, label="clean")
    ax.plot(t, chain.apply(t, y)[0, :, 0], lw=1, label="measured")
    ax.set_ylabel("y [rad]")
    ax.set_title("+ " + type(stages[i]).__name__, fontsize=9)
axes[0].legend(loc="upper right", fontsize=8)
axes[-1].set_xlabel("time [s]")
