"""Adaptive observers against the EKF/UKF baselines on the MuJoCo plants (issue 4).

Usage::

    python scripts/compare_adaptive.py                 # writes docs/results/adaptive.md + figures
    python scripts/compare_adaptive.py --quick         # 1 seed, shorter runs (a smoke test)
    python scripts/compare_adaptive.py --jobs 2 --out docs/results
    python scripts/compare_adaptive.py --cache runs.pkl           # also keep the raw runs
    python scripts/compare_adaptive.py --render-only --cache runs.pkl  # rewrite the report only

Every method sees the *same* measurement stream in each run: a run is two ``simulate`` calls
with the same plant, input and sensor seed (bit-identical measurements over their common time),
one for the adaptive observers over the plant's whole ``duration`` and one for the Kalman
filters over ``kalman_duration``. The filters identify the parameters within about 1 s (0.4 s
on the one-joint plants), so on the pendulum and the elastic joint they are run for the first
5 s only: their final error and state RMSE are taken at the end of those 5 s (the table's
"run" column), the adaptive observers' at the end of the whole run. The two halves of every
run go to ``--jobs`` worker processes (default 2), longest first.
Plants: the MuJoCo pendulum (unknown gravity-to-length ratio ``a = m g l_c / J`` and input gain
``b/J``, damping known) and the MuJoCo elastic joint (unknown stiffness ``K`` and load ``MgL``
from the link angle alone). Conditions: two noise levels (Gaussian, std 1e-4 rad and 1e-3 rad),
five sensor seeds each, and a model mismatch at the low noise level: the observers' model has
the inertia 10 % too large (pendulum: ``J``; elastic joint: the link inertia ``I``) -- a
parameter every method assumes known. Methods: ``besancon`` (paper 001), ``bastin_gevers``
(paper 002), ``jo_son`` (paper 003) where their canonical forms exist (otherwise the table says
why, from the observer's own error), ``ekf``/``ukf`` on the analytic model, ``ekf_mujoco``/
``ukf_mujoco`` whose model is the MJCF. Tunings are fixed below, the same for every seed and
condition; every method starts from the same wrong parameters (pendulum 50 % low, elastic
joint 30 % low).

Reported per method: relative parameter error over time (figures: median over seeds), time to
5 % (after which every parameter stays within 5 %), final relative error, state RMSE over the
second half, and cost per update (mean wall time of ``update``; these runs share 2 cores, see
BENCHMARKS.md for the side-by-side timings).
"""

from __future__ import annotations

import argparse
import copy
import math
import os
import pickle
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from hgo_mj._bench import versions_line
from hgo_mj.exceptions import DesignError, DimensionError
from hgo_mj.inputs import Multisine
from hgo_mj.metrics import settling_time
from hgo_mj.observers import make_observer
from hgo_mj.observers.besancon import BesanconObserver
from hgo_mj.plants import make_plant
from hgo_mj.progress import track
from hgo_mj.sensors import GaussianNoise, SensorChain
from hgo_mj.simulate import simulate

NOISES = (1e-4, 1e-3)
SEEDS = (1, 2, 3, 4, 5)
ADAPTIVE = ("besancon", "bastin_gevers", "jo_son")
KALMAN = ("ekf", "ukf", "ekf_mujoco", "ukf_mujoco")
METHODS = ADAPTIVE + KALMAN
PLANTS = {
    "pendulum": {"duration": 10.0, "kalman_duration": 5.0, "x0": (0.5, 0.0), "x_hat0": (0.5, 0.0),
                 "input": ([0.3, 0.2, 0.1], [0.3, 0.7, 1.9]), "params": ("g_over_l", "b_over_J"),
                 "initial": 0.5, "mismatch": "inertia"},
    "elastic_joint": {"duration": 20.0, "kalman_duration": 5.0, "x0": (0.3, 0.25, 0.5, -0.5),
                      "x_hat0": (0.3, 0.3, 0.0, 0.0),
                      "input": ([0.4, 0.3, 0.2, 0.05, 0.05], [0.4, 1.1, 2.7, 6.0, 9.0]),
                      "params": ("stiffness", "MgL"), "initial": 0.7, "mismatch": "link_inertia"},
    "elastic_joint_2link": {"duration": 10.0, "kalman_duration": 10.0,
                            "x0": (0.3, -0.2, 0.3, -0.2, 0.0, 0.0, 0.0, 0.0),
                            "x_hat0": None, "input": "two_link_input",
                            "params": ("stiffness1", "stiffness2"), "initial": 0.7,
                            "mismatch": "link1_inertia"},
}
#: methods not run on a plant (cost), with the reason
NOT_RUN = {"elastic_joint_2link": {
    "ukf": "not run here: 21 sigma points of a 10-state model per sample (about 1 ms an update)",
    "ukf_mujoco": "not run here: 21 MuJoCo sigma-point steps per sample"}}


def two_link_input(t: float) -> np.ndarray:
    """Both torques: low-frequency sines plus a little near each joint's resonance."""
    w = 2 * math.pi
    return np.array([0.5 * math.sin(w * 0.5 * t) + 0.3 * math.sin(w * 1.3 * t) + 0.05 * math.sin(w * 7 * t),
                     0.2 * math.sin(w * 0.7 * t + 1) + 0.1 * math.sin(w * 1.9 * t)
                     + 0.03 * math.sin(w * 11 * t)])


def truth(name: str, p: dict[str, float]) -> dict[str, float]:
    if name == "elastic_joint_2link":
        return {"stiffness1": p["stiffness1"], "stiffness2": p["stiffness2"]}
    if name == "pendulum":
        return {"g_over_l": p["mass"] * p["g"] * p["com_distance"] / p["inertia"],
                "b_over_J": p["gear"] / p["inertia"]}
    return {"stiffness": p["stiffness"], "MgL": p["mass"] * p["g"] * p["com_distance"]}


def build(name: str, plant: Any, sensor: Any, mismatch: bool) -> tuple[dict[str, Any], dict[str, str], dict]:
    """Observers (tuned once, here) with the maps from their diagnostics to the physical
    parameters; methods that do not apply with the reason."""
    cfg = PLANTS[name]
    true_sys = plant.system
    p = dict(true_sys.params)
    if mismatch:
        p[cfg["mismatch"]] *= 1.1
    model_sys = type(true_sys)(**p)  # what the observers believe
    tr = truth(name, true_sys.params)
    f0 = cfg["initial"]
    obs: dict[str, Any] = {}
    maps: dict[str, Any] = {}
    skipped: dict[str, str] = {}
    # the MJCF copy the MuJoCo filters use (10 % more inertia through the joint's armature)
    mj = copy.deepcopy(plant.model)
    if mismatch and name != "elastic_joint_2link":
        jname = "hinge" if name == "pendulum" else "link"
        dof = mj.jnt_dofadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, jname)]
        mj.dof_armature[dof] += 0.1 * true_sys.params[cfg["mismatch"]]
    if mismatch and name == "elastic_joint_2link":
        dof = mj.jnt_dofadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, "link1")]
        mj.dof_armature[dof] += 0.1 * true_sys.params["link1_inertia"]
    if name == "elastic_joint_2link":
        return _two_link(model_sys, true_sys, sensor, mj, tr, f0, cfg)
    xh0 = list(cfg["x_hat0"])
    if name == "pendulum":
        J, gl, m = p["inertia"], p["g"] * p["com_distance"], p["mass"]
        a0, b0 = f0 * tr["g_over_l"], f0 * tr["b_over_J"]
        kf = dict(sensor=sensor, Q=[1e-8, 1e-2], Q_theta=1e-6, P0=[1e-6, 1.0], x_hat0=xh0)
        obs["besancon"] = BesanconObserver(model_sys, lam=20.0, gain=100.0, hold="innovation",
                                           theta_hat0=[a0, b0], x_hat0=xh0)
        maps["besancon"] = lambda d: (d["theta_g_over_l"], d["theta_b_over_J"])
        for k in ("bastin_gevers", "jo_son"):
            try:
                obs[k] = make_observer(k, model_sys, c1=5.0, gamma=1000.0, theta_hat0=[a0, b0]) \
                    if k == "bastin_gevers" else make_observer(k, model_sys)
                maps[k] = lambda d: (d["theta_g_over_l"], d["theta_b_over_J"])
            except (DesignError, DimensionError) as exc:
                skipped[k] = str(exc)
        th_s = [f0 * true_sys.params["mass"], f0 * true_sys.params["gear"]]
        for k in ("ekf", "ukf"):
            obs[k] = make_observer(k, model_sys, estimate=("mass", "gear"), theta_hat0=th_s,
                                   P0_theta=[(0.5 * m) ** 2, 0.25], **kf)
            maps[k] = lambda d, J=J, gl=gl: (d["theta_mass"] * gl / J, d["theta_gear"] / J)
        th_m = [f0 * true_sys.params["g"], f0 * true_sys.params["gear"]]
        mJ = J  # the MuJoCo filters' model inertia (with the armature added when mismatched)
        for k in ("ekf_mujoco", "ukf_mujoco"):
            obs[k] = make_observer(k, model_sys, estimate=("g", "gear"), theta_hat0=th_m,
                                   P0_theta=[25.0, 0.25], model=mj, **kf)
            maps[k] = lambda d, mJ=mJ, m=true_sys.params["mass"], lc=true_sys.params["com_distance"]: (
                m * d["theta_g"] * lc / mJ, d["theta_gear"] / mJ)
        return obs, skipped, maps
    # elastic joint
    K, mgl = tr["stiffness"], tr["MgL"]
    gL = p["g"] * p["com_distance"]
    obs["besancon"] = BesanconObserver(model_sys, lam=100.0, gain=[6e-5, 9e-7, 1.5e-6],
                                       theta_hat0=[f0 * mgl, f0 * K, f0 * f0 * K * mgl],
                                       x_hat0=xh0, X=2e4, Theta=30.0, hold="innovation",
                                       excitation_window=5.0)
    maps["besancon"] = lambda d: (d["theta_stiffness"], d["theta_MgL"])
    for k in ("bastin_gevers", "jo_son"):
        try:
            obs[k] = make_observer(k, model_sys)
            maps[k] = None
        except (DesignError, DimensionError) as exc:
            skipped[k] = str(exc)
    kf = dict(sensor=sensor, Q=[1e-10, 1e-10, 1e-6, 1e-6], Q_theta=1e-8, P0=[1e-6, 1e-2, 1.0, 1.0],
              x_hat0=xh0)
    m = true_sys.params["mass"]
    for k in ("ekf", "ukf"):
        obs[k] = make_observer(k, model_sys, estimate=("stiffness", "mass"),
                               theta_hat0=[f0 * K, f0 * m], P0_theta=[(0.3 * K) ** 2, (0.3 * m) ** 2],
                               **kf)
        maps[k] = lambda d, gL=gL: (d["theta_stiffness"], d["theta_mass"] * gL)
    for k in ("ekf_mujoco", "ukf_mujoco"):
        obs[k] = make_observer(k, model_sys, estimate=("stiffness", "g"),
                               theta_hat0=[f0 * K, f0 * true_sys.params["g"]],
                               P0_theta=[(0.3 * K) ** 2, 9.0], model=mj, **kf)
        maps[k] = lambda d, mL=m * true_sys.params["com_distance"]: (d["theta_stiffness"], d["theta_g"] * mL)
    return obs, skipped, maps


def _two_link(model_sys: Any, true_sys: Any, sensor: Any, mj: Any, tr: dict[str, float], f0: float,
              cfg: dict[str, Any]) -> tuple[dict[str, Any], dict[str, str], dict]:
    """The two-link arm: the two-output Besançon observer (eq. 24) and the EKFs."""
    obs: dict[str, Any] = {}
    maps: dict[str, Any] = {}
    skipped: dict[str, str] = dict(NOT_RUN["elastic_joint_2link"])
    th0 = [f0 * tr["stiffness1"], f0 * tr["stiffness2"]]
    x0 = cfg["x0"]
    z0 = np.zeros(8)
    z0[0], z0[4] = x0[0], x0[1]  # link angles measured; their derivatives unknown (zero)
    obs["besancon"] = BesanconObserver(model_sys, lam=100.0, gain=[1.8e-5, 8.6e-7], theta_hat0=th0,
                                       z_hat0=z0, X=1e5, Theta=100.0, hold="innovation",
                                       adapt_after=0.3, excitation_window=5.0)
    maps["besancon"] = lambda d: (d["theta_stiffness1"], d["theta_stiffness2"])
    for k in ("bastin_gevers", "jo_son"):
        try:
            obs[k] = make_observer(k, model_sys)
            maps[k] = None
        except (DesignError, DimensionError) as exc:
            skipped[k] = str(exc)
    xh0 = [x0[0], x0[1], x0[0], x0[1], 0.0, 0.0, 0.0, 0.0]
    # the arm starts at rest (velocities known, as for the Besançon observer's z_hat0); a
    # random walk of the stiffnesses lets the EKF leave the wrong value it locks onto in the
    # first 0.2 s with Q_theta = 1e-8 (its covariance collapses there in 3 seeds of 5)
    kf = dict(sensor=sensor, Q=[1e-10] * 4 + [1e-6] * 4, Q_theta=1e-2,
              P0=[1e-6, 1e-6, 1e-2, 1e-2, 1e-4, 1e-4, 1e-4, 1e-4], x_hat0=xh0, theta_hat0=th0,
              estimate=("stiffness1", "stiffness2"), P0_theta=[(0.3 * v) ** 2 for v in tr.values()])
    obs["ekf"] = make_observer("ekf", model_sys, **kf)
    obs["ekf_mujoco"] = make_observer("ekf_mujoco", model_sys, model=mj, **kf)
    for k in ("ekf", "ekf_mujoco"):
        maps[k] = lambda d: (d["theta_stiffness1"], d["theta_stiffness2"])
    return obs, skipped, maps


def run_one(job: tuple[str, float, int, bool, float, str]) -> dict[str, Any]:
    """One half of a run: the methods of ``group`` (``"adaptive"`` or ``"kalman"``) on the
    measurements of ``seed`` (the other half sees the same ones)."""
    name, noise, seed, mismatch, duration, group = job
    cfg = PLANTS[name]
    plant = make_plant(name, 0.001)
    sensor = SensorChain([GaussianNoise(std=noise)], seed=seed)
    obs, skipped, maps = build(name, plant, sensor, mismatch)
    members = ADAPTIVE if group == "adaptive" else KALMAN
    obs = {k: v for k, v in obs.items() if k in members}
    if cfg["input"] == "two_link_input":
        u: Any = two_link_input
    else:
        amps, freqs = cfg["input"]
        u = Multisine(amps, freqs)
    t0 = time.perf_counter()
    traj = simulate(plant, sensor, obs, u, duration, x0=cfg["x0"], seed=seed)
    wall = time.perf_counter() - t0
    tr = truth(name, plant.system.params)
    true_v = np.array([tr[k] for k in cfg["params"]])
    half = traj.t >= duration / 2
    out: dict[str, Any] = {"plant": name, "noise": noise, "seed": seed, "mismatch": mismatch,
                           "group": group, "wall": wall, "skipped": skipped, "methods": {},
                           "y_meas": traj.y_meas[::10].copy()}
    stride = 100
    for k, rec in traj.observers.items():
        if maps.get(k) is None:
            continue
        est = np.column_stack(maps[k](rec.diagnostics))
        rel = np.abs(est - true_v) / np.abs(true_v)
        err = traj.x - rec.x_hat
        out["methods"][k] = {
            "t": traj.t[::stride], "rel": rel[::stride],
            "t5": float(settling_time(traj.t, rel, 0.05).max()), "final": rel[-1].tolist(),
            "rmse": np.sqrt(np.mean(err[half] ** 2, axis=0)).tolist(),
            "cost_us": rec.update_time * 1e6, "duration": duration,
        }
    return out


def check_same_measurements(results: list[dict[str, Any]]) -> None:
    """The two halves of each run must have seen the same measurements (common samples)."""
    first: dict[tuple, np.ndarray] = {}
    for r in results:
        key = (r["plant"], r["noise"], r["seed"], r["mismatch"])
        y = r["y_meas"]
        if key in first:
            n = min(len(y), len(first[key]))
            if not np.array_equal(y[:n], first[key][:n]):
                raise RuntimeError(f"the two halves of run {key} saw different measurements")
        else:
            first[key] = y


def aggregate(results: list[dict[str, Any]]) -> dict[tuple, dict[str, Any]]:
    check_same_measurements(results)
    groups: dict[tuple, dict[str, list]] = {}
    for r in results:
        key = (r["plant"], r["noise"], r["mismatch"])
        g = groups.setdefault(key, {"runs": [], "skipped": r["skipped"]})
        g["runs"].append(r)
    return groups


def _fmt_t(v: list[float]) -> str:
    v = np.array(v)
    if np.all(np.isinf(v)):
        return "never"
    med = float(np.median(v))
    n_inf = int(np.sum(np.isinf(v)))
    s = f"{med:.2f}" if math.isfinite(med) else "never"
    return s + (f" ({n_inf}/{v.size} never)" if n_inf and math.isfinite(med) else "")


def write_report(groups: dict, out: Path, args: Any, elapsed: float) -> None:
    from hgo_mj._io import save_figure
    from hgo_mj.plotting import subplots

    out.mkdir(parents=True, exist_ok=True)
    lines = [
        "# Adaptive observers against EKF/UKF on the MuJoCo plants",
        "",
        "Generated by `python scripts/compare_adaptive.py` "
        f"({'quick run, ' if args.quick else ''}"
        f"{f'{args.duration:g}-s runs, ' if getattr(args, 'duration', None) else ''}"
        f"{len(args.seeds)} seed(s) per condition, "
        f"wall {elapsed / 60:.1f} min on {args.jobs} process(es)); do not edit by hand.",
        versions_line() + ".",
        "",
        "Each run feeds every method the same measurements; numbers are medians over the seeds "
        "(run: the simulated time of the method -- the Kalman filters, which settle within about "
        "1 s, see the first 5 s of the pendulum and elastic-joint runs, the adaptive observers "
        "all of it; time to 5 %: the time after which every parameter stays within 5 % of the "
        "truth; final: relative error of each parameter at the end of the method's run; state "
        "RMSE over the second half of the method's run, per physical state; cost: mean wall "
        "time of one `update`, in a shared process -- see BENCHMARKS.md for side-by-side "
        "timings). Figures: median over the seeds. Setup and tunings: the docstring of "
        "`scripts/compare_adaptive.py`.",
        "",
        INTRO,
        "",
    ]
    for (plant, noise, mismatch), g in sorted(groups.items(), key=lambda kv: (kv[0][0], kv[0][2], kv[0][1])):
        cfg = PLANTS[plant]
        runs = g["runs"]
        title = f"{plant}, noise std {noise:g} rad" + (
            f", observers' {cfg['mismatch']} +10 % (model mismatch)" if mismatch else "")
        lines += [f"## {title}", "",
                  f"| method | run [s] | time to 5 % [s] | final rel. error "
                  f"{', '.join(cfg['params'])} | state RMSE ({', '.join(_state_names(plant))}) "
                  "| cost [us] |",
                  "|---|---:|---:|---|---|---:|"]
        fig, axes = subplots(1, len(cfg["params"]), figsize=(11, 3.6), sharey=True,
                             layout="constrained", squeeze=False)
        axes = axes[0]
        for mname in METHODS:
            if mname in g["skipped"]:
                continue
            rs = [r["methods"][mname] for r in runs if mname in r["methods"]]
            if not rs:
                continue
            t5 = [r["t5"] for r in rs]
            fin = np.median(np.array([r["final"] for r in rs]), axis=0)
            rmse = np.median(np.array([r["rmse"] for r in rs]), axis=0)
            cost = float(np.median([r["cost_us"] for r in rs]))
            lines.append(f"| {mname} | {rs[0]['duration']:g} | {_fmt_t(t5)} | "
                         f"{', '.join(f'{v:.2g}' for v in fin)} | "
                         f"{', '.join(f'{v:.2g}' for v in rmse)} | {cost:.0f} |")
            rel = np.median(np.array([r["rel"] for r in rs]), axis=0)
            for i, ax in enumerate(np.atleast_1d(axes)):
                ax.semilogy(rs[0]["t"], np.maximum(rel[:, i], 1e-6), lw=1.1, label=mname)
        for i, ax in enumerate(np.atleast_1d(axes)):
            ax.axhline(0.05, color="0.5", ls=":", lw=0.8)
            ax.set_title(f"|{cfg['params'][i]} error| / truth")
            ax.set_xlabel("t [s]")
            ax.set_ylim(1e-6, 3.0)
        axes[0].legend(fontsize=7, loc="lower left")
        axes[0].set_ylabel("|estimate - true| / true [-]")
        fig.suptitle(title, fontsize=10)
        fname = f"adaptive_{plant}_{noise:g}{'_mismatch' if mismatch else ''}.png"
        save_figure(fig, out / fname, dpi=100)
        lines += ["", f"![{title}]({fname})", ""]
        for mname in METHODS:
            if mname in g["skipped"]:
                lines.append(f"- `{mname}` does not apply: {g['skipped'][mname]}")
        if any(m in g["skipped"] for m in METHODS):
            lines.append("")
    shows, details = summary_text(groups)
    lines += ["## What it shows", "", shows, ""]
    if details:
        lines += ["### Details", "", details, ""]
    (out / "adaptive.md").write_text("\n".join(lines))


def _state_names(plant: str) -> tuple[str, ...]:
    from hgo_mj.systems import SYSTEMS

    return SYSTEMS[plant].state_names


INTRO = """## The forms the Besançon observer runs on

* **Pendulum** (`pendulum_form`): `y'' = -(d/J) y' + (-sin y) a + u (b/J)` with `a = m g l_c / J`
  and `b/J` unknown, `d/J` known: the single-output form eq. 9 with `psi = [0, 0; -sin z1, u]`.
* **Elastic joint, link angle only** (`elastic_joint_form`, checked symbolically and against
  `ElasticJoint.phi`): in `z = (y, y', y'', y^(3))`,
  `y^(4) = phi4(z) + psi1 MgL + psi2 K + psi3 K MgL` with
  `psi1 = (sin z1 z2^2 - cos z1 z3 - (d_m/J) cos z1 z2)/I`,
  `psi2 = -z3/I - (z3 + (d_l/I) z2)/J - d_m z2/(I J) + b u/(I J)`, `psi3 = -sin z1/(I J)`,
  `phi4 = -(d_l/I) z4 - (d_m/J)(z4 + (d_l/I) z3)`. It is *not* affine in `(K, MgL)` but it is in
  `theta = (MgL, K, K MgL)`; the observer estimates the three and maps back `K = theta2`,
  `MgL = theta3/theta2` (`theta3`'s regressor needs no estimated derivative).
* **Two-link arm, both link angles** (`elastic_joint_2link_form`): the two-output form eq. 21
  exists (orders 4 and 4): with `L = M(q) q'' + c + g + D q' = -K (q - theta)` and diagonal
  `K, J, D_m`, `q^(4) = M^-1 [-J^-1 D_m L' - 2 M' q^(3) - M'' q'' - c'' - g'' - D q^(3)] +
  M^-1 diag(w) (K1, K2)`, `w = J^-1 (B u - D_m q' - L) - q''`: both stiffnesses enter both
  chains' last rows, equal orders, so eq. 24 applies with `I_lambda = lambda^4 I`.
  The MJCF's motor-2 rotor body inertia `J_r = 1e-12` is neglected (Spong's assumption).
  Its parameter update starts after 0.3 s (`adapt_after`): the peaking of the initial
  transient otherwise kicks `theta_hat` far off.
* Bastin-Gevers (paper 002) is run where its canonical form is derived (the pendulum); Jo-Son
  (paper 003) needs relative degree one from the parameters to the output, which none of these
  link-angle sensors gives (the reasons, from the observers themselves, are under each table).

The MuJoCo filters step a copy of the MjModel for the mean. `mujoco.mjd_transitionFD` refuses
the RK4 integrator the shipped models use ("RK4 integrator is not supported", MuJoCo 4.0), so it
runs on an Euler twin of the model; MuJoCo's Euler is semi-implicit and implicit in the joint
damping, and its raw matrix is `O(h^2 K/J)` off RK4's (enough to wreck the two-link stiffness
estimates), so the filter recovers the continuous Jacobian from the twin's velocity rows and
uses RK4's transition `T4(h F)` (`MujocoModel._rk4_transition`, tested against finite
differences of the RK4 step)."""

PLANT_WORDS = {"pendulum": "the pendulum", "elastic_joint": "the elastic joint",
               "elastic_joint_2link": "the two-link arm"}
METHOD_WORDS = {"besancon": "Besançon", "bastin_gevers": "Bastin-Gevers", "jo_son": "Jo-Son"}


def method_stats(g: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Per method run on a condition: median time to 5 % (``inf``: never, in at least half
    the seeds), seeds that never got there, the largest median final relative error over the
    parameters, and the run's simulated time."""
    stats: dict[str, dict[str, Any]] = {}
    for mname in METHODS:
        rs = [r["methods"][mname] for r in g["runs"] if mname in r["methods"]]
        if mname in g["skipped"] or not rs:
            continue
        t5 = np.array([r["t5"] for r in rs])
        stats[mname] = {"t5": float(np.median(t5)), "never": int(np.sum(np.isinf(t5))), "seeds": t5.size,
                        "final": float(np.max(np.median(np.array([r["final"] for r in rs]), axis=0))),
                        "duration": rs[0]["duration"]}
    return stats


def _pct(v: float) -> str:
    return f"{100 * v:.0f} %" if 100 * v >= 9.5 else f"{100 * v:.2g} %"


def _sec(v: float) -> str:
    return f"{v:.2g} s"


def _range(vals: list[float], fmt: Any) -> str:
    """``"lo-hi unit"`` (one value if both print alike)."""
    lo, hi = fmt(min(vals)), fmt(max(vals))
    return lo if lo == hi else f"{lo.rsplit(' ', 1)[0]}-{hi}"


def _join(items: list[str]) -> str:
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def summary_text(groups: dict[tuple, dict[str, Any]]) -> tuple[str, str]:
    """The "What it shows" paragraph, two sentences with this run's numbers (model right at the
    low noise; the inertia mismatch), and a "Details" paragraph."""
    low, high = NOISES
    plants = [p for p in PLANTS if (p, low, False) in groups]
    if not plants:
        return "No run at the low noise level with the model right: nothing to summarize.", ""
    st = {p: method_stats(groups[(p, low, False)]) for p in plants}
    kal = [(p, m, v) for p in plants for m, v in st[p].items() if m in KALMAN]
    ada = [(p, m, v) for p in plants for m, v in st[p].items() if m in ADAPTIVE]
    kal_t = [v["t5"] for _, _, v in kal if math.isfinite(v["t5"])]
    first = f"With the model right and noise std {low:g} rad, the Kalman filters"
    if kal_t:
        first += (f" come within 5 % of the parameters in {_range(kal_t, _sec)} on "
                  f"{'every plant' if len(plants) > 1 else PLANT_WORDS[plants[0]]} and end within "
                  f"{_pct(max(v['final'] for _, _, v in kal))} of them")
    kal_never = [f"{m} on {PLANT_WORDS[p]}" for p, m, v in kal if not math.isfinite(v["t5"])]
    if kal_never:
        first += f"{' (' if kal_t else ' '}never get there: {_join(kal_never)}{')' if kal_t else ''}"
    got = [(p, m, v) for p, m, v in ada if math.isfinite(v["t5"])]
    missed = [(p, m, v) for p, m, v in ada if not math.isfinite(v["t5"])]
    clauses = []
    if got:
        per = {m: [f"{_sec(v['t5'])} on {PLANT_WORDS[p]}" for p, mm, v in got if mm == m] for m in ADAPTIVE}
        clauses.append(f"the adaptive observers take {_range([v['t5'] for _, _, v in got], _sec)} ("
                       + "; ".join(f"{METHOD_WORDS[m]} {_join(x)}" for m, x in per.items() if x) + ")")
    for m in ADAPTIVE:
        where = [f"{PLANT_WORDS[p]} ({_pct(v['final'])} off after {v['duration']:g} s)"
                 for p, mm, v in missed if mm == m]
        if where:
            clauses.append(f"{METHOD_WORDS[m]} never gets there on "
                           + (where[0] if len(where) == 1 else ", ".join(where[:-1]) + " or " + where[-1]))
    first += (", while " + _join(clauses) if clauses else "") + "."
    pairs = [(p, max(v["final"] for v in st[p].values()),
              max(v["final"] for v in method_stats(groups[(p, low, True)]).values()))
             for p in plants if (p, low, True) in groups and st[p]]
    second = ""
    if pairs:
        second = (" A 10 % error in an inertia the observers take as known moves the worst final "
                  "parameter error (over the methods) "
                  + _join([f"from {_pct(a)} to {_pct(b)} on {PLANT_WORDS[p]}" for p, a, b in pairs])
                  + ": no method can tell a wrong known parameter from a wrong unknown one.")
    # details: the mechanisms, with the higher noise level's numbers
    hi = {p: method_stats(groups[(p, high, False)]) for p in plants if (p, high, False) in groups}
    details = ("The adaptive observers' parameter rate is the excitation level times the adaptation "
               "gain (paper 001, eq. 20), where the Kalman filters' is set by their covariance; on the "
               "elastic joints the Besançon regressor is built from estimated third and fourth "
               "derivatives of the measured angles, which the noise biases")
    bes = [f"{_pct(v['besancon']['final'])} on {PLANT_WORDS[p]}" for p, v in hi.items() if "besancon" in v]
    if bes:
        details += f" (at {high:g} rad Besançon's final error is {_join(bes)})"
    details += ", while on the pendulum it needs only the first derivative"
    if "pendulum" in st and "besancon" in st["pendulum"]:
        kp = [v["final"] for m, v in st["pendulum"].items() if m in KALMAN]
        kd = max((v["duration"] for m, v in st["pendulum"].items() if m in KALMAN), default=0.0)
        details += (f" and ends {_pct(st['pendulum']['besancon']['final'])} off after "
                    f"{st['pendulum']['besancon']['duration']:g} s at {low:g} rad"
                    + (f" (the Kalman filters {_range(kp, _pct)} after {kd:g} s)"
                       if kp else ""))
    details += "."
    kal_hi = [(p, m, v) for p, d in hi.items() for m, v in d.items() if m in KALMAN and v["never"]]
    if kal_hi:
        details += (f" At {high:g} rad some Kalman runs never settle within 5 %: "
                    + _join([f"{m} on {PLANT_WORDS[p]} in {v['never']} of {v['seeds']} seeds"
                             for p, m, v in kal_hi]) + ".")
    details += (" On the pendulum the estimated ratios m g l_c / J and b / J absorb an inertia error "
                "(only the damping term is off); on the elastic joints the inertia enters the "
                "dynamics apart from the estimated parameters, and Besançon's MgL (a ratio of two of "
                "its parameters) is the least sensitive to it.")
    return first + second, details


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "docs" / "results"))
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--quick", action="store_true", help="1 seed, 5 s runs (smoke test)")
    ap.add_argument("--duration", type=float, help="simulated seconds of every run (the Kalman "
                    "filters' at most their plant's kalman_duration); default: the plant's, 5 with --quick")
    ap.add_argument("--plants", nargs="*", default=list(PLANTS))
    ap.add_argument("--cache", help="pickle of the raw runs: written after a run; with "
                                    "--render-only, read instead of running")
    ap.add_argument("--render-only", action="store_true",
                    help="write the report from --cache without running")
    ap.add_argument("--quiet", action="store_true", help="no progress on stderr")
    args = ap.parse_args(argv)
    args.seeds = SEEDS[:1] if args.quick else SEEDS
    jobs = []
    for plant in args.plants:
        cfg = PLANTS[plant]
        dur = args.duration or (5.0 if args.quick else cfg["duration"])
        durations = {"adaptive": dur, "kalman": min(dur, cfg["kalman_duration"])}
        conditions = [(noise, seed, False) for noise in NOISES for seed in args.seeds]
        conditions += [(NOISES[0], seed, True) for seed in args.seeds]
        for noise, seed, mismatch in conditions:
            for group, d in durations.items():
                jobs.append((plant, noise, seed, mismatch, d, group))
    # longest first (seconds per simulated second, roughly), so the last jobs are short ones
    weight = {"adaptive": 0.15, "kalman": 2.0}
    jobs.sort(key=lambda j: -j[4] * weight[j[5]] * (0.4 if j[0] == "elastic_joint_2link" else 1.0))
    t0 = time.perf_counter()
    if args.render_only:
        with open(args.cache, "rb") as fh:
            cached = pickle.load(fh)
        results, elapsed = cached[:2]
        if len(cached) > 2:  # the processes the runs had (older caches: as given now)
            args.jobs = cached[2]
    else:
        if args.jobs > 1:
            with ProcessPoolExecutor(args.jobs) as ex:
                results = list(track(ex.map(run_one, jobs, chunksize=1), total=len(jobs),
                                     desc="compare_adaptive", quiet=args.quiet))
        else:
            results = [run_one(j) for j in track(jobs, desc="compare_adaptive",
                                                  quiet=args.quiet)]
        elapsed = time.perf_counter() - t0
        if args.cache:
            Path(args.cache).parent.mkdir(parents=True, exist_ok=True)
            with open(args.cache, "wb") as fh:
                pickle.dump((results, elapsed, args.jobs), fh)
    write_report(aggregate(results), Path(args.out), args, elapsed)
    print(f"{len(jobs)} simulations in {elapsed:.1f} s -> {Path(args.out) / 'adaptive.md'}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
