"""Gyros that are not presets, as GyroSensor settings: for checking the sensor on the
space of gyros a user may bring (tests/test_sensor.py) and its presets (presets.py).

A random gyro: drive mode 2-8 kHz, sense mode split 1-25 % above or below it, cross
stiffness up to 15 % of sqrt(kxx kyy), Q 300-1e4, cross damping up to 30 % of the
smaller damping, mass 1e-9 to 1e-6 kg. Its sensor: the design values 5 % off in the
stiffnesses and the mass, 20 % in the dampings (GyroObserver's default start); the
default drive's tones at the same ratios to the drive mode (4000 and 1200 Hz against
3000 Hz) and forces giving the default's static deflection; pick-off noise at the
default's 1e-4 of each position's amplitude.
"""

from __future__ import annotations

import math

import numpy as np

from ..model.parameters import INITIAL_GUESS_FACTORS, PARAMETER_UNITS
from .interface import _AMPLITUDE, _TRUTH, NOISE_X, NOISE_Y  # the defaults it scales


def random_gyro(rng: np.random.Generator) -> dict[str, float]:
    """kxx ... m of one random gyro (see the module docstring)."""
    fx = rng.uniform(2e3, 8e3)
    fy = fx * (1.0 + rng.uniform(0.01, 0.25) * rng.choice([-1.0, 1.0]))
    kxx, kyy = (2 * math.pi * fx) ** 2, (2 * math.pi * fy) ** 2
    q = 10 ** rng.uniform(2.5, 4.0)
    dxx = math.sqrt(kxx) / q
    dyy = math.sqrt(kyy) / q * rng.uniform(0.7, 1.3)
    return {"kxx": kxx, "kyy": kyy, "kxy": rng.uniform(-0.15, 0.15) * math.sqrt(kxx * kyy),
            "dxx": dxx, "dyy": dyy, "dxy": rng.uniform(-0.3, 0.3) * min(dxx, dyy),
            "m": 10 ** rng.uniform(-9.0, -6.0)}


def sensor_settings(gyro: dict[str, float], seed: int = 0) -> dict[str, float]:
    """GyroSensor parameters for `gyro` (see the module docstring)."""
    s: dict[str, float] = dict(gyro)
    for name in PARAMETER_UNITS:
        s[f"{name}_0"] = gyro[name] * INITIAL_GUESS_FACTORS[name]
    ratio = math.sqrt(gyro["kxx"] / _TRUTH.kxx)  # drive mode against the default's
    force = _AMPLITUDE * (gyro["m"] * gyro["kxx"]) / (_TRUTH.m * _TRUTH.kxx)
    # the same static deflection as the default, so the default's noise is the same share
    s.update(A1=force, A2=force, f1=4000.0 * ratio, f2=1200.0 * ratio, noise_x=NOISE_X,
             noise_y=NOISE_Y, seed=seed)
    return s
