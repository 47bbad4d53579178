"""Divergence monitor of GyroStateObserver: its limits, its verdicts in words, its error.

The compiled check (observer_kernels.check) runs after every step and judges:

- the estimate and covariance are finite;
- the covariance has a Cholesky factor (is symmetric positive definite);
- the parameters stay physical (kxx, kyy, 1/m > 0, K positive definite) and within a
  factor RATIO of the guess (kxx, kyy, 1/m), |d| <= D_MAX, |Omega_z| below the guessed
  natural frequency (a gyro's rate is far below its resonance);
- the innovations over blocks of BLOCK corrections: with absolute noise stds given
  (sigma_z1, sigma_z2), the mean normalized innovation squared (NIS, chi-square with 2
  dof per correction: mean 2) against its chi-square band: above the 0.9999 quantile a
  warning (status 1), above NIS_LOST lost; in relative mode (R adapts to the innovations,
  so NIS says little) the RMS innovation relative to each signal's running peak at the
  end of the block (early in a run the signal is still building up):
  above REL_LOST lost (the one-step predictions miss by that
  fraction of the signal), a warning above REL_WARN.

A lost filter raises ObserverDivergedError (a GyroFmuError) naming the cause and the
remedies; every later step raises it again. Thresholds and measurements:
docs/observer-soundness.md.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from gyro_fmu.errors import GyroFmuError

from . import observer_kernels as kern
from .observer_kernels import (
    C_BOUNDS,
    C_INNOVATIONS,
    C_NONFINITE,
    C_NOT_SPD,
    C_OK,
    C_WARN,
    I_OM,
    I_PAR,
    M_AC,
    M_BLOCK,
    M_CAUSE,
    M_COUNT,
    M_LAST_CORR,
    M_LAST_NIS,
    M_LAST_REL,
    M_NIS,
    M_SQ,
    M_STATUS,
    M_VALUE,
    M_WHICH,
    N_PAR,
)

#: Corrections per block of the innovation tests (1 ms at the default 5 us step).
BLOCK = 200
#: Warning above the chi-square quantile of this normal quantile (p = 1e-4 per block).
NIS_WARN_Z = 3.719
#: Lost when the block mean NIS exceeds this (innovations ~70 sigma RMS; expected 2): a
#: noise 10x larger than told gives ~200 (a warning), a diverged filter 1e6 and more.
NIS_LOST = 1.0e4
#: Relative mode (the noise estimated from the innovations): warning above REL_WARN, lost
#: above REL_LOST, block RMS innovations relative to each signal's peak. The noise is
#: estimated, so innovations above noise_rel are no warning; a slow misfit is caught by
#: the whiteness test.
REL_WARN = 0.02
REL_LOST = 0.2
#: Warning when an innovation sequence's lag-1 autocorrelation over a block exceeds
#: CORR_WARN (white: 0 +- 0.07) while the mean NIS exceeds NIS_MIN: the innovations are
#: a slowly varying misfit, not noise, so the sigmas (which assume white noise) are too
#: small. A converged noise-free filter has NIS ~1e-8 and is not flagged.
CORR_WARN = 0.5
NIS_MIN = 0.1
#: kxx, kyy and 1/m must stay within this factor of their initial guesses.
RATIO = 100.0

_NAMES = ("kxx", "kyy", "kxy", "dxx", "dyy", "dxy", "1/m", "Omega_z")
_UNITS = ("1/s^2", "1/s^2", "1/s^2", "1/s", "1/s", "1/s", "1/kg", "rad/s")


class MonitorLimits(NamedTuple):
    """Limits of the divergence monitor (observer_monitor.limits builds them)."""

    block: int  #: innovation statistics are judged over blocks of this many corrections
    absolute: bool  #: absolute noise stds given: judge NIS against chi-square
    nis_warn: float  #: warning above this block mean of NIS (2 dof per step)
    nis_lost: float  #: lost above this block mean of NIS
    rel_warn: float  #: relative mode: warning above this block RMS innovation / peak
    rel_lost: float  #: relative mode: lost above this block RMS innovation / peak
    ratio: float  #: lost when kxx, kyy or 1/m leave [theta0 / ratio, theta0 ratio]
    d_max: float  #: lost when |dxx|, |dyy| or |dxy| exceed this (1/s)
    omega_max: float  #: lost when |Omega_z| exceeds this (rad/s)
    corr_warn: float  #: warning above this lag-1 autocorrelation of the innovations ...
    nis_min: float  #: ... when their block mean NIS is above this (not negligible)


class ObserverDivergedError(GyroFmuError):
    """The observer lost its numerical footing or the gyro: its estimates are meaningless.

    The message names the check that tripped and the remedies; the observer refuses
    every later step (restore an earlier state or build a new one).
    """


class ObserverStepError(GyroFmuError, ValueError):
    """A communication step the observer cannot use (too coarse for the gyro's resonance);
    the observer is unchanged: a smaller step goes on (in the FMU: fmi2Discard)."""


#: Largest omega h accepted: the sampling must be 25 % faster than the Nyquist rate of the
#: guessed resonance (omega h = pi). Beyond, the resonance aliases: measured at 200 us
#: (omega h 4.6) runs from 10 % off ended wrong with status 0; at 100 us (2.3) they
#: converged or were refused.
OMEGA_H_MAX = 2.5


def step_too_coarse(h: float, omega: float) -> None:
    """Raise ObserverStepError if omega h > OMEGA_H_MAX (omega: guessed natural frequency)."""
    if omega * h > OMEGA_H_MAX:
        raise ObserverStepError(
            f"communication step {h:.4g} s too coarse for the observer: it samples the "
            f"gyro's guessed resonance ({omega / (2 * math.pi):.5g} Hz) at omega h = "
            f"{omega * h:.3g} > {OMEGA_H_MAX:g} (aliasing: the motion cannot be told from "
            f"the samples); use a step <= {OMEGA_H_MAX / omega:.3g} s")


def chi2_quantile(dof: int, z: float) -> float:
    """Wilson-Hilferty approximation of the chi-square quantile at normal quantile z."""
    a = 2.0 / (9.0 * dof)
    return dof * (1.0 - a + z * math.sqrt(a)) ** 3


def limits(model: kern.ObserverModel, tuning, pair) -> tuple:
    """The MonitorLimits of an observer, as a plain tuple (numba calls it faster)."""
    absolute = tuning.sigma_z1 > 0.0 and tuning.sigma_z2 > 0.0
    # 0.9999 quantile of chi-square with 2 BLOCK dof, as a mean per correction
    nis_warn = chi2_quantile(2 * BLOCK, NIS_WARN_Z) / BLOCK
    w_max = math.sqrt(max(model.theta0[0], model.theta0[1]))
    w_min = math.sqrt(min(model.theta0[0], model.theta0[1]))
    d_max = max(2.0 * w_max, RATIO * float(model.scale[3]))
    return tuple(MonitorLimits(
        block=BLOCK, absolute=absolute, nis_warn=nis_warn, nis_lost=NIS_LOST,
        rel_warn=REL_WARN, rel_lost=REL_LOST, ratio=RATIO, d_max=d_max,
        omega_max=w_min, corr_warn=CORR_WARN, nis_min=NIS_MIN))


def _cause(mon, lim: MonitorLimits) -> str:
    cause, which, value = int(mon[kern.M_CAUSE]), int(mon[kern.M_WHICH]), mon[kern.M_VALUE]
    if cause == kern.C_NONFINITE:
        return f"its estimate or covariance became non-finite (filter state row {which})"
    if cause == kern.C_NOT_SPD:
        return ("its covariance lost positive definiteness (no Cholesky factor): "
                "the linearization no longer holds")
    if cause == kern.C_BOUNDS:
        name, unit = _NAMES[which], _UNITS[which]
        if which in (0, 1, 6):
            why = f"must be > 0 and within x{lim.ratio:g} of its initial guess"
        elif which == 2:
            why = "K = [[kxx, kxy], [kxy, kyy]] must stay positive definite"
        elif which == 7:
            why = f"a rate beyond the gyro's natural frequency ({lim.omega_max:.4g} rad/s)"
        else:
            why = f"|d| must stay <= {lim.d_max:.4g} 1/s"
        return f"its estimate {name}={value:.4g} {unit} left the physical range ({why})"
    if which == 0:
        return (f"its innovations are inconsistent: mean normalized innovation squared "
                f"{value:.3g} over {lim.block} corrections (expected 2, lost above "
                f"{lim.nis_lost:g})")
    return (f"its one-step predictions miss the measurements by {100 * value:.3g} % RMS of "
            f"the signal over {lim.block} corrections (lost above {100 * lim.rel_lost:g} %)")


def lost_message(mon, observer, h: float) -> str:
    """Why the filter is lost and what to do, in one line."""
    lim = MonitorLimits(*observer._lim)
    coarse = max(observer.wx, observer.wy) * h
    hints = []
    if coarse > 0.5:
        hints.append(f"the communication step {h:.3g} s is too coarse for the observer "
                     f"(omega h = {coarse:.2g}; use omega h < 0.5)")
    hints += ["the initial rate guess Omega_z_0 too far from the true rate or the "
              "parameter guesses too far (start within ~10 %)",
              "a smaller communication step",
              "measurement noise larger than the observer was told (sigma_z1, sigma_z2, "
              "noise_rel)"]
    return (f"observer lost at t={observer.t:.6g} s (the step from {observer.t - h:.6g} s): "
            f"{_cause(mon, lim)}. Likely causes and "
            f"remedies: {'; '.join(hints)}. Its estimates are meaningless from here: "
            f"restore an earlier state or start anew")


def warning_message(mon, lim_t: tuple, t: float) -> str:
    """The warning of status 1 (innovations above their band), in one line."""
    lim = MonitorLimits(*lim_t)
    value = mon[M_VALUE]
    if int(mon[M_WHICH]) == 2:
        what = (f"its innovations are not white (lag-1 autocorrelation {value:.2g} over "
                f"{lim.block} corrections): a misfit the sigmas do not count")
    elif lim.absolute:
        what = (f"mean normalized innovation squared {value:.3g} over {lim.block} "
                f"corrections, above its chi-square 0.9999 band ({lim.nis_warn:.3g})")
    else:
        what = (f"one-step predictions miss by {value:.3g} RMS of the signal, above "
                f"{lim.rel_warn:.3g}")
    return (f"observer at t={t:.6g} s: {what}: the estimates may be off (initial guesses "
            f"far, noise larger than told, or a rate jump faster than its rate models)")


@njit(cache=True)
def _lost(mon, cause, which, value):  # pragma: no cover
    mon[M_STATUS] = cause
    mon[M_CAUSE] = cause
    mon[M_WHICH] = which
    mon[M_VALUE] = value
    return cause


@njit(cache=True)
def cholesky_ok(P, L):  # pragma: no cover
    """True if P (symmetric) has a Cholesky factor P = L L': positive pivots, or a pivot
    exactly 0 with its whole column 0 (a state known exactly, e.g. at rest before the
    first signal: semidefinite, but only in that structural way)."""
    n = P.shape[0]
    for j in range(n):
        acc = P[j, j]
        for k in range(j):
            acc -= L[j, k] * L[j, k]
        if acc == 0.0:
            for i in range(j + 1, n):
                r = P[i, j]
                for k in range(j):
                    r -= L[i, k] * L[j, k]
                if r != 0.0:
                    return False
                L[i, j] = 0.0
            L[j, j] = 0.0
            continue
        if not acc > 0.0:
            return False
        d = math.sqrt(acc)
        L[j, j] = d
        for i in range(j + 1, n):
            acc = P[i, j]
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            L[i, j] = acc / d
    return True


@njit(cache=True)
def check(model, lim, x, P, L, peak, mon):  # pragma: no cover
    """Divergence monitor after a step: 0 ok, 1 warning, >= 2 lost (C_*), verdict in mon.

    Lost: a non-finite estimate or covariance, a covariance without a Cholesky factor
    (not positive definite), parameters outside the physical range (K not positive
    definite, 1/m <= 0) or far outside the guess's (MonitorLimits), and innovations
    far outside their distribution over a block of corrections.
    """
    n = x.shape[0]
    for i in range(n):
        if not (math.isfinite(x[i]) and math.isfinite(P[i, i])):
            return _lost(mon, C_NONFINITE, i, x[i])
    if not cholesky_ok(P, L):
        return _lost(mon, C_NOT_SPD, -1, 0.0)
    th = np.empty(N_PAR)
    for i in range(N_PAR):
        th[i] = model.theta0[i] + model.scale[i] * x[I_PAR + i]
    for i in (0, 1, 6):  # kxx, kyy, 1/m: positive and within a factor of the guess
        if not (th[i] > 0.0 and model.theta0[i] / lim.ratio <= th[i] <= model.theta0[i]
                * lim.ratio):
            return _lost(mon, C_BOUNDS, i, th[i])
    if not th[0] * th[1] > th[2] * th[2]:
        return _lost(mon, C_BOUNDS, 2, th[2])
    for i in (3, 4, 5):
        if not abs(th[i]) <= lim.d_max:
            return _lost(mon, C_BOUNDS, i, th[i])
    if not abs(x[I_OM]) <= lim.omega_max:
        return _lost(mon, C_BOUNDS, 7, x[I_OM])
    count = mon[M_COUNT]
    if count >= lim.block:
        nis = mon[M_NIS] / count
        rel = 0.0  # RMS innovation / the running peak at the block's end, worse signal
        corr = 0.0  # the larger lag-1 autocorrelation of the two innovation sequences
        for j in range(2):
            if peak[j] > 0.0:
                rel = max(rel, math.sqrt(mon[M_SQ + j] / count) / peak[j])
            if mon[M_SQ + j] > 0.0:
                corr = max(corr, mon[M_AC + j] / mon[M_SQ + j])
            mon[M_AC + j] = 0.0
            mon[M_SQ + j] = 0.0
        mon[M_LAST_CORR] = corr
        mon[M_NIS] = 0.0
        mon[M_COUNT] = 0.0
        mon[M_BLOCK] += 1.0
        mon[M_LAST_NIS] = nis
        mon[M_LAST_REL] = rel
        status = C_OK
        if lim.absolute:
            if nis > lim.nis_lost:
                return _lost(mon, C_INNOVATIONS, 0, nis)
            if nis > lim.nis_warn:
                status = C_WARN
        else:
            if rel > lim.rel_lost:
                return _lost(mon, C_INNOVATIONS, 1, rel)
            if rel > lim.rel_warn:
                status = C_WARN
        if status == C_WARN:
            mon[M_WHICH] = 0 if lim.absolute else 1
            mon[M_VALUE] = nis if lim.absolute else rel
        elif corr > lim.corr_warn and nis > lim.nis_min:
            status = C_WARN
            mon[M_WHICH] = 2
            mon[M_VALUE] = corr
        mon[M_STATUS] = status
    return int(mon[M_STATUS])
