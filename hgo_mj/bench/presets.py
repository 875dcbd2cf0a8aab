"""Sensor presets of the benchmark, written from datasheet-style parameters.

Each preset turns the parameters a datasheet gives into the stages of a
:class:`~hgo_mj.sensors.SensorChain` (the scenario's ``[sensor] stages``), for a sensor that
reads the plant's measured output (an angle, a position, a concentration):

* ``encoder``: an incremental encoder of ``counts_per_rev`` counts per revolution, read with a
  small electrical noise; the error is dominated by quantization (``q / sqrt(12)``,
  ``q = 2 pi / counts``).
* ``mems``: a MEMS inclinometer-like sensor: white noise of density ``noise_density`` (units
  per sqrt(Hz); the standard deviation at the sample rate ``f_s`` is ``density sqrt(f_s / 2)``),
  a turn-on bias drawn per seed (``bias_repeatability``, 1 sigma), a bias instability modelled
  as a random walk (``bias_walk``, units per sqrt(s)) and a group ``delay``.
* ``vision``: a camera tracker: positions at ``rate`` Hz (held between frames), ``latency``
  seconds old, a fraction ``dropouts`` of frames lost (NaN), a fraction ``outliers`` of
  frames off by ``outlier_size``, and a pixel-level noise ``std``.
* ``analog``: an analog sensor through an ADC: Gaussian noise ``std``, a gain error-free
  reading clipped to ``[low, high]`` (saturation), quantized to ``bits`` over that range.

:func:`preset` returns the stages and the measurement's effective standard deviation (what
the benchmark's noise amplification divides by).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from ..exceptions import DesignError

__all__ = ["PRESETS", "preset"]

#: preset name -> its parameters and their defaults
PRESETS: dict[str, dict[str, float]] = {
    "encoder": {"counts_per_rev": 4096.0, "noise": 1e-4},
    "mems": {"noise_density": 2e-4, "sample_rate": 1000.0, "bias_repeatability": 2e-3,
             "bias_walk": 1e-3, "delay": 0.002},
    "vision": {"rate": 30.0, "latency": 0.04, "dropouts": 0.05, "outliers": 0.01,
               "outlier_size": 0.05, "std": 2e-3},
    "analog": {"std": 2e-3, "low": -1.0, "high": 1.0, "bits": 12.0},
}


def _values(name: str, params: Mapping[str, Any] | None) -> dict[str, float]:
    if name not in PRESETS:
        raise DesignError(f"unknown sensor preset {name!r}; valid: {sorted(PRESETS)}")
    given = dict(params or {})
    bad = sorted(set(given) - set(PRESETS[name]))
    if bad:
        raise DesignError(f"sensor preset {name!r}: unknown parameter(s) {bad}; valid: "
                          f"{sorted(PRESETS[name])}")
    out = {**PRESETS[name]}
    for k, v in given.items():
        signed = k in ("low", "high")  # an analog range may be negative
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or (
                v < 0 and not signed):
            want = "a finite number" if signed else "a finite number >= 0"
            raise DesignError(f"sensor preset {name!r}: {k} must be {want}; found {v!r}")
        out[k] = float(v)
    if name == "analog" and not out["low"] < out["high"]:
        raise DesignError(f"sensor preset 'analog': low must be < high; found {out['low']} >= "
                          f"{out['high']}")
    return out


def preset(name: str, params: Mapping[str, Any] | None = None) -> tuple[list[dict[str, Any]],
                                                                         float]:
    """The sensor chain's stages of a preset and the measurement's standard deviation.

    Parameters
    ----------
    name : str
        One of :data:`PRESETS`.
    params : mapping, optional
        Datasheet parameters overriding the preset's defaults.

    Returns
    -------
    stages : list of dict
        ``[sensor] stages`` of a scenario.
    std : float
        The standard deviation of the measurement error in steady state, from white noise
        and quantization (bias, delay and dropouts left out), in output units.

    Raises
    ------
    DesignError
        An unknown preset or parameter (the valid ones listed), a negative or non-finite
        value.

    Examples
    --------
    >>> stages, std = preset("encoder", {"counts_per_rev": 1024})
    >>> [s["stage"] for s in stages], round(std, 6)
    (['gaussian', 'quantize'], 0.001774)
    >>> preset("laser")
    Traceback (most recent call last):
    ...
    hgo_mj.exceptions.DesignError: unknown sensor preset 'laser'; valid: ['analog', ...]
    """
    v = _values(name, params)
    if name == "encoder":
        q = 2.0 * math.pi / v["counts_per_rev"]
        stages = [{"stage": "gaussian", "std": v["noise"]},
                  {"stage": "quantize", "counts_per_rev": int(v["counts_per_rev"])}]
        return stages, math.hypot(v["noise"], q / math.sqrt(12.0))
    if name == "mems":
        std = v["noise_density"] * math.sqrt(v["sample_rate"] / 2.0)
        stages = [{"stage": "gaussian", "std": std},
                  {"stage": "drift", "sigma": v["bias_walk"],
                   "initial_std": v["bias_repeatability"]}]
        if v["delay"] > 0:
            stages.append({"stage": "delay", "delay": v["delay"]})
        return stages, std
    if name == "vision":
        stages = [{"stage": "gaussian", "std": v["std"]},
                  {"stage": "outliers", "p": v["outliers"], "magnitude": v["outlier_size"]},
                  {"stage": "sample_hold", "period": 1.0 / v["rate"]},
                  {"stage": "delay", "delay": v["latency"]},
                  {"stage": "dropout", "p": v["dropouts"]}]
        return stages, v["std"]
    lsb = (v["high"] - v["low"]) / 2.0 ** v["bits"]
    stages = [{"stage": "gaussian", "std": v["std"]},
              {"stage": "saturate", "low": v["low"], "high": v["high"]},
              {"stage": "quantize", "resolution": lsb}]
    return stages, math.hypot(v["std"], lsb / math.sqrt(12.0))
