"""
Input signals
=============

The input signals of :mod:`hgo_mj.inputs` (``hgo-mj list`` names them): a multisine, a chirp,
a maximum-length pseudo-random binary sequence (``prbs``, period ``2^nbits - 1`` clock periods)
and a random telegraph signal (``telegraph``, a level drawn each period). Each is a function of
time; :func:`~hgo_mj.inputs.make_signal` builds one by name, as scenario files do.
"""

import numpy as np

from hgo_mj.inputs import make_signal
from hgo_mj.plotting import subplots

# %%
# Four signals by name
# --------------------
#
# The same keywords as a scenario's ``[input]`` table.

t = np.arange(0.0, 4.0, 0.002)
signals = {
    "multisine": make_signal("multisine", amplitudes=[0.3, 0.1], frequencies=[0.5, 2.0]),
    "chirp": make_signal("chirp", amplitude=0.3, f0=0.2, f1=3.0, duration=4.0),
    "prbs": make_signal("prbs", amplitude=0.3, period=0.1, nbits=5),
    "telegraph": make_signal("telegraph", amplitude=0.3, period=0.1, seed=0),
}
fig, axes = subplots(len(signals), 1, figsize=(7, 6), layout="constrained", sharex=True)
for ax, (name, signal) in zip(axes, signals.items()):
    ax.plot(t, [np.ravel(signal(ti))[0] for ti in t], lw=1)
    ax.set_ylabel("u [N m]")
    ax.set_title(name, fontsize=9)
axes[-1].set_xlabel("time [s]")
