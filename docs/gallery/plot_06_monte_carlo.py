"""
One noisy run says little: a Monte Carlo over seeds
===================================================

:func:`hgo_mj.study.monte_carlo` repeats a run at several sensor seeds and aggregates every
run's metrics; :func:`hgo_mj.plotting.plot_monte_carlo` shows each observer's RMSE per seed on
one shared axis per state, so the observers can be compared.
"""

from hgo_mj.inputs import Multisine
from hgo_mj.observers import HighGainObserver
from hgo_mj.plants import make_plant
from hgo_mj.plotting import plot_monte_carlo
from hgo_mj.sensors import GaussianNoise, SensorChain
from hgo_mj.study import format_mc_table, monte_carlo
from hgo_mj.units import system_units

# %%
# One run, as a function of nothing
# ---------------------------------
#
# ``make_run`` builds fresh objects for each seed; the seed is the Monte Carlo's.

def make_run():
    plant = make_plant("pendulum", dt=0.001)
    return {"plant": plant,
            "sensor": SensorChain([GaussianNoise(std=1e-3)]),
            "observers": {"k20": HighGainObserver(plant.system, k=20.0),
                          "k80": HighGainObserver(plant.system, k=80.0)},
            "inputs": Multisine(amplitudes=[0.3], frequencies=[0.5]),
            "duration": 3.0, "x0": [0.5, 0.0]}


# %%
# Eight seeds, aggregated
# -----------------------
#
# The table: RMSE mean, std, median and max per observer and state, with units.

result = monte_carlo(make_run, seeds=range(8), t_transient=1.0)
units = system_units(type(make_run()["plant"].system))
print(format_mc_table(result.aggregate, units))

# %%
# Every seed's RMSE, on one axis per state
# ----------------------------------------

fig = plot_monte_carlo(result, title="pendulum, 8 seeds", units=units)
