"""How well the observer did: errors, RMS and convergence times for summary.json.

Judged over the tail (the last 20 % of the run): convergence means within tolerance from
a time before the tail starts to the end; sigma is reported as its RMS over the tail
beside the last sample's.

Tolerance rule ("within 1%"): 1% of |truth| for each parameter; where the truth
is 0 (e.g. dyy of Table 1) an absolute 0.1 1/s for dampings; for Omega_z, whose
truth may cross zero, 1% of the largest |Omega_z| of the run.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from ..model.measurement import UNKNOWNS
from ..model.parameters import GyroParameters

ESTIMATED = UNKNOWNS
RELATIVE_TOLERANCE = 0.01
ZERO_DAMPING_TOLERANCE = 0.1  #: 1/s, where a damping's truth is 0


def tolerance(name: str, truth: np.ndarray) -> float:
    """Allowed |error| for `name` (same unit), by the rule in the module docstring."""
    scale = float(np.max(np.abs(truth)))
    if scale == 0.0:
        return ZERO_DAMPING_TOLERANCE if name.startswith("d") else RELATIVE_TOLERANCE
    return RELATIVE_TOLERANCE * scale


def convergence_time(time: np.ndarray, error: np.ndarray, tol: float,
                     judged_from: float | None = None) -> float | None:
    """First time after which |error| stays within tol to the end; None if never, or if
    that time is later than judged_from (the start of the judged tail: an error that only
    comes within tol in the tail's last samples has not converged)."""
    outside = np.nonzero(~(np.abs(error) <= tol))[0]
    if outside.size == 0:
        return float(time[0])
    if outside[-1] == time.size - 1:
        return None
    t = float(time[outside[-1] + 1])
    return None if judged_from is not None and t > judged_from else t


def summarize(
    time: np.ndarray,
    estimates: Mapping[str, np.ndarray],
    sigmas: Mapping[str, np.ndarray],
    truth: GyroParameters,
    Omega_true: np.ndarray,
    tail: float = 0.2,
) -> dict:
    """Metrics of summary.json; `tail` is the final fraction of the run (0.2: last 20%)."""
    last = time >= time[0] + (1.0 - tail) * (time[-1] - time[0])
    out: dict = {"tail_window_s": [float(time[last][0]), float(time[-1])], "unknowns": {}}
    for name in ESTIMATED:
        true_series = Omega_true if name == "Omega_z" else np.full(time.shape, getattr(truth, name))
        err = estimates[name] - true_series
        tol = tolerance(name, true_series)
        scale = float(np.max(np.abs(true_series[last])))
        tail_err = float(np.max(np.abs(err[last])))
        sigma_rms = float(np.sqrt(np.mean(sigmas[name][last] ** 2)))
        entry = {
            "truth_final": float(true_series[-1]),
            "estimate_final": float(estimates[name][-1]),
            "sigma_final": float(sigmas[name][-1]),
            "sigma_rms_tail": sigma_rms,
            "tolerance": tol,
            # the observer's own sigma sits at the Cramer-Rao bound (0.97-1.08 of it,
            # docs/observer-soundness.md): a tolerance below it is luck, not a target
            "tolerance_below_sigma": bool(tol < sigma_rms),
            "max_abs_error_tail": tail_err,
            "max_rel_error_tail": tail_err / scale if scale > 0 else None,
            "converged_within_tolerance_at_s": convergence_time(time, err, tol,
                                                                float(time[last][0])),
            "error_over_sigma_rms_tail": _ratio_rms(err[last], sigmas[name][last]),
        }
        if name == "Omega_z":
            entry["rms_error_tail"] = float(np.sqrt(np.mean(err[last] ** 2)))
            entry["rms_error_tail_rel_to_peak"] = (
                entry["rms_error_tail"] / scale if scale > 0 else None)
        out["unknowns"][name] = entry
    out["all_within_tolerance_in_tail"] = all(
        u["max_abs_error_tail"] <= u["tolerance"] for u in out["unknowns"].values()
    )
    return out


def _ratio_rms(err: np.ndarray, sigma: np.ndarray) -> float | None:
    ok = sigma > 0
    if not ok.any():
        return None
    value = float(np.sqrt(np.mean((err[ok] / sigma[ok]) ** 2)))
    return value if math.isfinite(value) else None
