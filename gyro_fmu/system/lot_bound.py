"""A sweep's lot against the Cramer-Rao bound: each gyro's bound at the deadline, the
efficient estimator's expected fractions, the within-tolerance curve (docs/sweep-bound.md)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..estimation.metrics import ESTIMATED
from .scenario import Scenario

if TYPE_CHECKING:  # annotations only: sweep imports this module
    from .sweep import SweepSpec


#: Gaussian draws per gyro for the joint probabilities of an efficient estimator.
JOINT_DRAWS = 20000


#: Points of the within-tolerance curve, evenly spaced up to the deadline (and the
#: draws per point for an efficient estimator's curve).
CURVE_POINTS, CURVE_DRAWS = 40, 4000


def bound_figures(sc: Scenario, result, spec: SweepSpec, noise, k_dead: int, out: dict,
           seed: int = 0) -> dict:
    """Cramer-Rao 1-sigma at the deadline for this gyro's inputs and noise, err / CRB, and
    what an efficient estimator would reach (module docstring)."""
    from ..estimation.identify import crb_at, record_from_result

    pair = ("x", "y") if sc.measured_pair == 1 else ("vx", "vy")
    std = tuple(float(getattr(noise, c)) for c in pair)
    # the estimate at t_k has used the measurements at t_0 .. t_{k-1}
    record = record_from_result(result, sc.measured_pair).head(max(k_dead, 10))
    crb = crb_at(sc.params, spec.Omega_z, record, std)
    row: dict = {"noise_std_z1": std[0], "noise_std_z2": std[1]}
    sig = np.array([crb[n] for n in ESTIMATED])
    tol = np.array([out[f"tol_{n}"] for n in ESTIMATED])
    err = np.array([out[f"err_dead_{n}"] for n in ESTIMATED])
    finite = bool(np.all(np.isfinite(sig)) and np.all(sig > 0))
    for j, name in enumerate(ESTIMATED):
        row[f"crb_{name}"] = float(sig[j])
        row[f"err_over_crb_{name}"] = float(err[j] / sig[j]) if sig[j] > 0 else None
        row[f"p_eff_{name}"] = float(math.erf(tol[j] / (math.sqrt(2.0) * sig[j]))) \
            if sig[j] > 0 else 1.0
    row["within_2crb_all"] = bool(np.all(np.abs(err) <= 2.0 * sig))
    row["p_eff_all"] = row["p_eff_2crb_all"] = None
    if finite:
        J = weighted_sensitivities(sc, spec.Omega_z, record, std)
        corr = correlation(fisher_covariance(J))
        e = gaussian_draws(corr, np.random.default_rng(seed))  # in units of each CRB
        row["p_eff_all"] = float(np.mean(np.all(np.abs(e) * sig <= tol, axis=1)))
        row["p_eff_2crb_all"] = float(np.mean(np.all(np.abs(e) <= 2.0, axis=1)))
        row["p_eff_all_curve"] = efficient_curve(J, curve_indices(k_dead), tol, seed)
    if spec.batch:
        row.update(batch_figures(sc, record, std, sig, tol))
    return row


def batch_figures(sc: Scenario, record, std, sig: np.ndarray, tol: np.ndarray) -> dict:
    """The batch ML identifier on the same samples: its errors, in tolerances and CRBs."""
    from ..estimation.identify import identify
    from ..model.parameters import GyroParameters

    try:
        ident = identify(record, GyroParameters(**sc.initial_guess), sc.Omega_z_0,
                         noise_std=std)
    except Exception as exc:  # recorded: the observer's row stays valid
        return {"batch_reason": f"{type(exc).__name__}: {exc}"[:300]}
    err = ident.error(sc.params, float(sc.rate.Omega_z(0.0)))
    row: dict = {"batch_success": ident.success}
    for j, name in enumerate(ESTIMATED):
        row[f"batch_err_{name}"] = float(err[name])
        row[f"batch_err_over_crb_{name}"] = float(err[name] / sig[j]) if sig[j] > 0 else None
    e = np.array([err[n] for n in ESTIMATED])
    row["batch_within_all"] = bool(np.all(np.abs(e) <= tol))
    row["batch_within_2crb_all"] = bool(np.all(np.abs(e) <= 2.0 * sig))
    return row


def curve_indices(k_dead: int, points: int = CURVE_POINTS) -> np.ndarray:
    """Sample indices of the within-tolerance curve: evenly spaced, the last the deadline."""
    return np.unique(np.clip(np.round(np.arange(1, points + 1) * k_dead / points), 1,
                             max(k_dead, 1)).astype(int))


def curve_times(spec: SweepSpec) -> list[float]:
    k_dead = round(min(spec.the_deadline, spec.stop_time) / spec.step)
    return [float(k * spec.step) for k in curve_indices(k_dead)]


def weighted_sensitivities(sc: Scenario, Omega_z: float, record, std) -> np.ndarray:
    """(N, 2, 8) c_i dz/dtheta_i / noise std: the exact sensitivities crb_at uses (its
    Jacobian, in the units of the scales c_i), sample by sample."""
    from ..estimation.sensitivity import ScaledSensitivitySystem
    from ..model.measurement import MeasuredPair

    sys = ScaledSensitivitySystem.build(sc.params, Omega_z, record.h)
    sigma = sys.simulate(np.zeros(sys.Phi.shape[0]), record.u)
    _, dS = sys.unscale(sigma)  # (N, 8, 4): c_i ds/dtheta_i
    rows = list(MeasuredPair(record.measured_pair).state_rows)
    dz = np.moveaxis(dS[:, :, rows], 1, 2) / np.asarray(std, float)[None, :, None]
    return dz / sys.scales  # SI: dz/dtheta_i / std


def fisher_covariance(J: np.ndarray, n: int | None = None) -> np.ndarray:
    """Cramer-Rao covariance (SI) from the first n samples of weighted_sensitivities."""
    from ..estimation import fisher

    J = J if n is None else J[:n]
    return fisher.covariance(J.reshape(-1, J.shape[-1]))


def correlation(cov: np.ndarray) -> np.ndarray:
    d = np.sqrt(np.diag(cov))
    return cov / d[:, None] / d[None, :]


def bound_correlation(sc: Scenario, Omega_z: float, record, std) -> np.ndarray:
    """Correlation matrix of the Cramer-Rao bound of the 8 unknowns (crb_at gives the
    diagonal only): the same exact sensitivities, weighted by the noise stds."""
    return correlation(fisher_covariance(weighted_sensitivities(sc, Omega_z, record, std)))


def efficient_curve(J: np.ndarray, k_curve: np.ndarray, tol: np.ndarray,
                     seed: int) -> list[float | None]:
    """P(all 8 within tolerance) for an efficient estimator at each point of the curve:
    the bound from the samples before that point (None where it is not finite)."""
    rng = np.random.default_rng(seed)
    out: list[float | None] = []
    for k in k_curve:
        cov = fisher_covariance(J, int(k))
        sig = np.sqrt(np.diag(cov))
        if not (np.all(np.isfinite(sig)) and np.all(sig > 0)):
            out.append(None)
            continue
        e = gaussian_draws(correlation(cov), rng, CURVE_DRAWS)
        out.append(float(np.mean(np.all(np.abs(e) * sig <= tol, axis=1))))
    return out


def gaussian_draws(corr: np.ndarray, rng: np.random.Generator,
                    n: int = JOINT_DRAWS) -> np.ndarray:
    """n draws of N(0, corr) (corr may be near singular)."""
    w, V = np.linalg.eigh(corr)
    root = V * np.sqrt(np.clip(w, 0.0, None))
    return rng.standard_normal((n, corr.shape[0])) @ root.T
