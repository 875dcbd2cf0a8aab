"""
An adaptive gain that finds itself
==================================

The adaptive-gain observer of paper 000 (eq. 4-5) raises its gain ``k`` while the output
error leaves the dead zone ``[lam, lam_hat]`` and stops once the error stays inside it, so it
needs no tuning beyond a bound on the noise. Here on the elastic joint (n = 4, only the link
angle measured through an encoder): the gain settles, and the run-time quantity ``k`` is a
diagnostic of the trajectory (``traj.observers[name].diagnostics``).
"""

from hgo_mj.inputs import Multisine
from hgo_mj.observers import AdaptiveGainObserver
from hgo_mj.plants import make_plant
from hgo_mj.plotting import subplots
from hgo_mj.sensors import SensorChain, encoder
from hgo_mj.simulate import simulate

# %%
# The elastic joint through an encoder
# ------------------------------------
#
# A 16-bit encoder with a little noise on the link angle; the gain starts at ``k0 = 20`` and may
# rise to ``k_max = 300``.

plant = make_plant("elastic_joint", dt=0.001)
sensor = SensorChain(encoder(counts_per_rev=65536, std=1e-4))
obs = AdaptiveGainObserver(plant.system, lam=4e-4, lam_hat=4e-3, gamma=2e7, k0=20.0, k_max=300.0)
u = Multisine(amplitudes=[0.4, 0.15], frequencies=[0.5, 1.7], phases=[0.0, 1.0])
traj = simulate(plant, sensor, {"adaptive": obs}, u, duration=4.0, x0=[0.3, 0.3, 0.0, 0.0],
                seed=0)

# %%
# The gain and the errors
# -----------------------
#
# The gain rises while the output error is outside the dead zone and then stays; the errors of
# all four states fall with it (log scale).

rec = traj.observers["adaptive"]
fig, (ax_k, ax_e) = subplots(2, 1, figsize=(7, 5), layout="constrained",
                              sharex=True)
ax_k.plot(traj.t, rec.diagnostics["k"])
ax_k.set_ylabel("gain k [1/s]")
ax_k.set_title("adaptive-gain observer (paper 000) on the elastic joint")
err = traj.error("adaptive")
for i, name in enumerate(traj.state_names):
    unit = "rad" if "angle" in name else "rad/s"
    ax_e.semilogy(traj.t, abs(err[:, i]) + 1e-12, lw=0.8, label=f"{name} [{unit}]")
ax_e.set_ylabel("|error|")
ax_e.set_xlabel("time [s]")
ax_e.legend(fontsize=8, ncol=2)
