"""The observer's model of Omega_z(t): fixed, or adaptive by interacting multiple models.

A user cannot know q_Omega (rad^2/s^5); the observer's innovations tell whether the
rate moves. The adaptive rate model (the default) runs four filters that differ only
in how Omega_z may move, mixed by the IMM algorithm (Blom & Bar-Shalom, IEEE Trans. AC
33(8) 1988; Bar-Shalom, Li & Kirubarajan, "Estimation with Applications to Tracking and
Navigation", 2001, sec. 11.6.6, eqs. 11.6.6-1 to -22):

- constant: Omega_z constant (the Cramer-Rao bound's model);
- rough: random walk sized to follow rate_span at rate_bandwidth / 10 (a rate that
  wanders without a smooth derivative, e.g. a Gauss-Markov process);
- slow: integrated random walk sized to follow rate_span at rate_bandwidth / 10;
- agile: twice-integrated random walk sized to follow rate_span at rate_bandwidth.

Sizing rule: a white noise of intensity q on the r-th derivative of Omega_z, with
q = rate_span^2 (2 pi f)^(2 r - 1) / (2 pi), follows a sine of amplitude rate_span at f
(Hz); it reproduces the best fixed tunings measured by hand (order 2, 10 Hz: 3.9e4
against 1e4-1e5; order 3, 100 Hz: 1.6e13 against ~1e13; docs/observer-rate-model.md).

The four filters share the plant's linearization (the held step of eq. 5 about the
combined estimate: observer_kernels.predict_about), so a step costs one held step, four
corrections and four covariance propagations. A fixed rate model (constant, tracking
at rate_bandwidth, or the expert q_Omega / omega_order) is the same code with one model.
"""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np
from numba import njit

from . import observer_kernels as kern


class RateModel(IntEnum):
    """ObserverTuning.rate_model (the FMU's Integer-valued parameter)."""

    adaptive = 0  #: IMM over constant / rough / slow / agile (the default)
    constant = 1  #: Omega_z constant (as the Cramer-Rao bound assumes)
    tracking = 2  #: one agile model at rate_bandwidth
    expert = 3  #: one model: q_Omega on the omega_order-th derivative


#: Process noise of the plant state per step, relative to each measured signal's running
#: peak: a floor that keeps the covariance positive definite over long runs (predict); far
#: below any pick-off noise (1e-9 of the peak per step).
STATE_NOISE = 1e-9
#: The adaptive set's models (rate_probabilities, the FMU's p_rate_* outputs).
RATE_KINDS = ("constant", "rough", "slow", "agile")
#: Graded rough models after the four (1.0, not 0.3.0: see tests/oracle_observer/__init__.py).
ROUGH_GRADES = (3.0, 10.0, 100.0)
#: The rough and slow models of the adaptive set follow rate_bandwidth divided by this.
SLOW_FRACTION = 10.0


def intensity(order: int, span: float, bandwidth: float) -> float:
    """q (rad^2/s^(2 order + 1)) of white noise on the order-th derivative of Omega_z that
    follows a sine of amplitude span (rad/s) at bandwidth (Hz): span^2 w^(2 order - 1) / 2 pi."""
    w = 2.0 * math.pi * bandwidth
    return span * span * w ** (2 * order - 1) / (2.0 * math.pi)


def _process(order: int, q: float, size: int, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Transition and process noise (size x size) over h of an order-th random walk of
    intensity q embedded in a rate block of `size` states; unused derivatives are 0."""
    F = np.zeros((size, size))
    Q = np.zeros((size, size))
    for a in range(order):
        for c in range(a, order):
            F[a, c] = h ** (c - a) / math.factorial(c - a)
    for a in range(order):
        for c in range(order):
            pa, pc = order - 1 - a, order - 1 - c
            Q[a, c] = q * h ** (pa + pc + 1) / (
                math.factorial(pa) * math.factorial(pc) * (pa + pc + 1))
    return F, Q


def rate_block_size(tuning) -> int:
    """States of the rate block: Omega_z and the derivatives its models use."""
    kind = RateModel(int(tuning.rate_model))
    if kind is RateModel.constant:
        return 1
    if kind is RateModel.expert:
        return int(tuning.omega_order)
    return 3


def model_names(tuning) -> tuple[str, ...]:
    """Names of the rate models the observer runs (the FMU's p_rate_* outputs)."""
    kind = RateModel(int(tuning.rate_model))
    if kind is RateModel.adaptive:
        return RATE_KINDS + ("rough",) * len(ROUGH_GRADES)
    return (kind.name,)


def rate_models(tuning, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Fr, Qr, Pi): each model's rate-block transition and process noise over h (M x r x
    r) and the model transition probabilities Pi[i, j] = P(model j at t + h | i at t)."""
    kind = RateModel(int(tuning.rate_model))
    r = rate_block_size(tuning)
    span, f = float(tuning.rate_span), float(tuning.rate_bandwidth)
    if kind is RateModel.adaptive:
        slow = f / SLOW_FRACTION
        rough = intensity(1, span, slow)
        specs = [(1, 0.0), (1, rough), (2, intensity(2, span, slow)), (3, intensity(3, span, f)),
                 *((1, grade * rough) for grade in ROUGH_GRADES)]
    elif kind is RateModel.constant:
        specs = [(1, 0.0)]
    elif kind is RateModel.tracking:
        specs = [(3, intensity(3, span, f))]
    else:
        specs = [(int(tuning.omega_order), float(tuning.q_Omega))]
    M = len(specs)
    Fr = np.zeros((M, r, r))
    Qr = np.zeros((M, r, r))
    for j, (order, q) in enumerate(specs):
        Fr[j], Qr[j] = _process(order, q, r, h)
    Pi = np.eye(M)
    if M > 1:
        switch = -math.expm1(-h / float(tuning.rate_dwell))  # P(leave a model within h)
        Pi = np.full((M, M), switch / (M - 1))
        np.fill_diagonal(Pi, 1.0 - switch)
    return Fr, Qr, Pi


@njit(cache=True)
def combine(xs, Ps, w, x, P):  # pragma: no cover
    """x, P (in place) = the mixture of the filters (xs, Ps) with weights w (IMM output,
    Bar-Shalom eqs. 11.6.6-21, -22): mean, and covariance with the spread of the means."""
    M, n = xs.shape
    for i in range(n):
        acc = 0.0
        for j in range(M):
            acc += w[j] * xs[j, i]
        x[i] = acc
    if M == 1:
        P[:, :] = Ps[0]
        return
    for a in range(n):
        for b in range(a + 1):
            acc = 0.0
            for j in range(M):
                acc += w[j] * (Ps[j, a, b] + (xs[j, a] - x[a]) * (xs[j, b] - x[b]))
            P[a, b] = acc
            P[b, a] = acc


@njit(cache=True)
def mix(xs, Ps, mu, Pi, c):  # pragma: no cover
    """IMM interaction (Bar-Shalom eqs. 11.6.6-6 to -10), in place: c = Pi' mu (predicted
    model probabilities) and each filter j restarted from the mixture of all filters with
    weights mu_i Pi[i, j] / c_j. For a uniform switching matrix (stay on the diagonal,
    leave off it: the observer's) in the one-mixture form of 0.4.0, with xbar, T the
    mu-mixture and a_j = (stay - leave) mu_j / c_j:
    x0j = a_j x_j + (1 - a_j) xbar, P0j = a_j P_j + (1 - a_j) T + a_j (1 - a_j) e_j e_j'
    (e_j = x_j - xbar), the same operations in the same order as the C core."""
    M, n = xs.shape
    if M == 1:
        c[0] = 1.0
        return
    stay, leave = Pi[0, 0], Pi[1, 0]
    uniform = True
    for i in range(M):
        for j in range(M):
            if Pi[i, j] != (stay if i == j else leave):
                uniform = False
    if uniform:
        total = 0.0
        for i in range(M):
            total += mu[i]
        w = np.empty(M)
        for i in range(M):
            w[i] = mu[i] / total
        xbar = np.empty(n)
        T = np.empty((n, n))
        combine(xs, Ps, w, xbar, T)
        e = np.empty(n)
        for j in range(M):
            own = (stay - leave) * mu[j]
            c[j] = own + leave * total
            aj = own / c[j]
            bj = 1.0 - aj
            ab = aj * bj
            for a in range(n):
                e[a] = xs[j, a] - xbar[a]
            for a in range(n):
                for b in range(a + 1):  # ab (e_a e_b): the same of (a, b) and (b, a)
                    v = aj * Ps[j, a, b] + bj * T[a, b] + ab * (e[a] * e[b])
                    Ps[j, a, b] = v
                    Ps[j, b, a] = v
                xs[j, a] = aj * xs[j, a] + bj * xbar[a]
        return
    x0 = np.empty((M, n))
    P0 = np.empty((M, n, n))
    wj = np.empty(M)
    for j in range(M):
        acc = 0.0
        for i in range(M):
            acc += Pi[i, j] * mu[i]
        c[j] = acc
        for i in range(M):
            wj[i] = Pi[i, j] * mu[i] / acc
        combine(xs, Ps, wj, x0[j], P0[j])
    xs[:, :] = x0
    Ps[:, :, :] = P0


@njit(cache=True)
def update(model, noise, xs, Ps, c, mu, x, P, peak, nu2, mon, z1, z2, h):  # pragma: no cover
    """IMM correction at t: every filter corrected (eq. 8) with the noise variances of the
    combined prediction (x, P); model probabilities mu = c x likelihood, normalized
    (Bar-Shalom eq. 11.6.6-15 to -19); then x, P = the combined estimate."""
    R0, R1, Rc0, Rc1, nu0, nu1 = kern.noise_variances(model, noise, x, peak, nu2, z1, z2,
                                                      h)
    kern.monitor_innovations(model, mon, P, nu0, nu1, R0, R1)
    M = xs.shape[0]
    ll = np.empty(M)
    for j in range(M):
        nis, logdet = kern.correct_with(model, noise.joseph, xs[j], Ps[j], z1, z2, R0, R1,
                                        Rc0, Rc1)
        ll[j] = -0.5 * (nis + logdet) if nis >= 0.0 else 0.0
    if M > 1:
        top = ll.max()
        total = 0.0
        for j in range(M):
            mu[j] = c[j] * math.exp(ll[j] - top)
            total += mu[j]
        for j in range(M):
            mu[j] /= total
    else:
        mu[0] = 1.0
    combine(xs, Ps, mu, x, P)


@njit(cache=True)
def predict(model, xs, Ps, mu, c, Pi, x, P, Fr, Qr, qpar, peak, ux, uy, h):  # pragma: no cover
    """IMM prediction to t + h: mix, propagate every filter about the combined estimate x
    (one held step, eq. 5), then x, P = their mixture with the predicted probabilities c.

    Each step adds (STATE_NOISE x the running peak of each measured signal, in m)^2 to
    the variances of [x, vx, y, vy]: without it the correlations between the plant state
    and the parameters of a constant-rate filter reach 1 - 1e-16 within seconds and
    rounding breaks positive definiteness (lost at 3.09 s at noise 1e-4)."""
    s1, Phi, S = kern.linearize(model, x, ux, uy, h)
    mix(xs, Ps, mu, Pi, c)
    q0 = (STATE_NOISE * peak[0] / model.hgain[0]) ** 2
    q1 = (STATE_NOISE * peak[1] / model.hgain[1]) ** 2
    for j in range(xs.shape[0]):  # x (the linearization point) is replaced only below
        kern.predict_about(x, s1, Phi, S, xs[j], Ps[j], Fr[j], Qr[j], qpar, q0, q1)
    combine(xs, Ps, c, x, P)
