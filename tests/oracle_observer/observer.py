"""Online state observer of the single-axis-drive gyroscope (US 2011/0314910 A1, eqs. 5-9).

The observer of eq. 8, x^' = f(x^) + B U + L C (X - X^), run as an extended Kalman filter
on the augmented state of eq. 5, X = [x, x', y, y', Omega_z, kxx, kyy, kxy, dxx, dyy, dxy, m]
(with 1/m in place of m), from the measured pair of eqs. 6 and 9 / claim 4: positions
(x, y) or velocities (x', y'). Each step corrects with the measurement at t (eq. 8, gain
from the covariance), then predicts to t + h with ux, uy and Omega_z held, exactly as
the plant steps (eq. 5; kernels in observer_kernels). Units: k's 1/s^2, d's 1/s, m kg,
Omega_z rad/s, forces N. Why it is built this way, with measurements:
docs/observer-design.md; why it stays sound at any step, start and signal scale (Joseph
update, signal-scaled priors, the divergence monitor of observer_monitor, the status
and the named errors): docs/observer-soundness.md.
"""

from __future__ import annotations

import math
from dataclasses import asdict

import numpy as np
from numba import njit

from gyro_fmu.estimation.observer_tuning import ObserverTuning
from gyro_fmu.model.measurement import UNKNOWNS, MeasuredPair
from gyro_fmu.model.parameters import GyroParameters, check_parameters

from . import observer_kernels as kern
from . import observer_rate as rate
from .observer_kernels import I_OM, I_PAR, KMAX, N_MON, N_PAR, NoiseModel, ObserverModel
from .observer_monitor import (
    MonitorLimits,
    ObserverDivergedError,
    ObserverStepError,
    check,
    limits,
    lost_message,
    step_too_coarse,
    warning_message,
)

__all__ = ["GyroStateObserver", "ObserverDivergedError", "ObserverStepError", "ObserverTuning"]

_STATE_VERSION = 3
#: Auto prior of [x, vx, y, vy] started by the drive (plant at rest): this fraction of the
#: static deflection (m); 10 % or more let the velocity-pair filter converge to Omega -5.
PRIOR_FRACTION = 0.01
#: ... started by a measurement above its noise (a plant not known at rest): its size.
#: 1 % there made relative-noise runs overconfident (dyy error/sigma 3.4, 300 ms) since
#: the innovation floor of R never saw a large early innovation.
PRIOR_FRACTION_MEASURED = 1.0
#: Outputs of output_row(): state estimate, UNKNOWNS, their 1-sigmas.
N_OUTPUTS = 4 + 8 + 8


@njit(cache=True)
def _ekf_step(model, noise, lim, xs, Ps, c, mu, x, P, L, peak, nu2, mon, Fr, Qr, Pi, qpar,
              ux, uy, z1, z2, h, pv, pk0, pk1):  # pragma: no cover
    """step() in one compiled call: correct at t, predict to t + h, monitor (its verdict).

    xs, Ps, c, mu: the rate models' filters and probabilities (observer_rate); x, P their
    combination. pv > 0: the auto prior starts here, after the correction (as predict()
    starts it): variance pv on [x, vx, y, vy], running peaks at least pk0, pk1.

    model and noise arrive as plain tuples (numba types those 0.6 us faster per call
    than NamedTuples) and are given their field names here.
    """
    m = ObserverModel(*model)
    rate.update(m, NoiseModel(*noise), xs, Ps, c, mu, x, P, peak, nu2, mon, z1, z2, h)
    if pv > 0.0:
        peak[0] = max(peak[0], pk0)
        peak[1] = max(peak[1], pk1)
        for i in range(4):  # on every filter; P is their mixture again after the predict
            for j in range(xs.shape[0]):
                Ps[j, i, i] += pv
    rate.predict(m, xs, Ps, mu, c, Pi, x, P, Fr, Qr, qpar, peak, ux, uy, h)
    return check(m, MonitorLimits(*lim), x, P, L, peak, mon)


class GyroStateObserver:
    """EKF form of the patent's state observer (eq. 8): Omega_z and the 7 parameters online.

    step(ux, uy, z1, z2, h) = update(z1, z2, h) then predict(ux, uy, h): correct with the
    measured pair at t, propagate to t + h with ux, uy (N) and Omega_z held. Filter state
    [x, vx/wx, y, vy/wy, p_kxx, p_kyy, p_kxy, p_dxx, p_dyy, p_dxy, p_b, Omega_z,
    dOmega_z/dt, d2Omega_z/dt2 (as many as the rate models use)], wx = sqrt(kxx_0),
    wy = sqrt(kyy_0), theta = theta_0 + scale p, b = 1/m. The rate models
    (observer_rate: adaptive by default) each run this filter; xhat, P are their mixture.
    """

    #: The unknowns, in the order of estimates() and sigmas() (model.measurement.UNKNOWNS).
    ESTIMATED: tuple[str, ...] = UNKNOWNS

    def __init__(
        self,
        initial: GyroParameters,
        Omega_z_0: float = 0.0,
        measured_pair: int = 1,
        tuning: ObserverTuning | None = None,
    ) -> None:
        pair = MeasuredPair.of(measured_pair)
        if not isinstance(initial, GyroParameters):
            raise ValueError(
                f"initial={initial!r} must be a GyroParameters (e.g. parameters.preset(...))"
            )
        problems = check_parameters(initial)
        if initial.kyy <= 0.0 and not problems:
            problems.append(f"kyy={initial.kyy} must be > 0")
        if problems:
            raise ValueError(
                "initial parameter guess is unusable: " + "; ".join(problems)
                + ". Give a physical guess (positive m, positive definite K)"
            )
        if not (isinstance(Omega_z_0, int | float) and math.isfinite(Omega_z_0)):
            raise ValueError(f"Omega_z_0={Omega_z_0!r} rad/s must be a finite number")
        tun = tuning if tuning is not None else ObserverTuning()
        if not isinstance(tun, ObserverTuning):
            raise ValueError(f"tuning={tun!r} must be an ObserverTuning or None")
        self.tuning = tun
        self.measured_pair = pair
        self.order = rate.rate_block_size(tun)
        self.n = 4 + N_PAR + self.order
        wx = math.sqrt(initial.kxx)
        wy = math.sqrt(initial.kyy)
        theta0 = np.array([initial.kxx, initial.kyy, initial.kxy, initial.dxx, initial.dyy,
                           initial.dxy, 1.0 / initial.m])
        d_scale = max(abs(initial.dxx), abs(initial.dyy), abs(initial.dxy), 1e-3)
        kxy_scale = max(abs(initial.kxy), 1e-2 * math.sqrt(initial.kxx * initial.kyy))
        scale = np.array([initial.kxx, initial.kyy, kxy_scale, d_scale, d_scale, d_scale,
                          1.0 / initial.m])
        self._build(wx, wy, theta0, scale)
        xhat = np.zeros(self.n)
        xhat[I_OM] = Omega_z_0
        sig = np.zeros(self.n)
        self._auto_prior = int(tun.sigma0_position <= 0.0 or tun.sigma0_velocity <= 0.0)
        if not self._auto_prior:
            sig[[0, 2]] = tun.sigma0_position
            sig[1] = tun.sigma0_velocity / wx
            sig[3] = tun.sigma0_velocity / wy
        sig[4:7] = tun.sigma0_k_rel * np.abs(theta0[:3]) / scale[:3]
        sig[7:10] = tun.sigma0_d_rel
        sig[10] = tun.sigma0_m_rel
        sig[I_OM] = tun.sigma0_Omega
        if self.order >= 2:
            sig[I_OM + 1] = tun.sigma0_Omega_rate
        if self.order >= 3:
            sig[I_OM + 2] = tun.sigma0_Omega_acc
        self.xhat = xhat
        self.P = np.diag(sig**2)
        M = len(self.rate_models)
        self.xs = np.tile(xhat, (M, 1))  # each rate model's filter (observer_rate)
        self.Ps = np.tile(self.P, (M, 1, 1))
        self.mu = np.full(M, 1.0 / M)  # model probabilities after the last correction
        self.c = self.mu.copy()  # ... predicted to the next one
        # running peak |z1|, |z2|, from the prior's scale: R > 0 in relative noise mode
        i0 = self.measured_pair.state_rows[0]
        self.peak = sig[[i0, i0 + 2]] * self._model.hgain
        # EWMA of squared innovations (< 0: not started); [2:4] the same from 0, [4] its weight
        self.nu2 = np.array([-1.0, -1.0, 0.0, 0.0, 0.0])
        self.mon = np.zeros(N_MON)  # divergence monitor (observer_kernels.M_*)
        self.t = 0.0  # s since construction
        self.status = 0  #: 0 ok, 1 warning (innovations above their band), 2 lost
        self.lost: str | None = None  #: why the filter is lost (then every step refuses)

    def _build(self, wx: float, wy: float, theta0: np.ndarray, scale: np.ndarray) -> None:
        """The ObserverModel and caches that depend only on the scaling (set_state too)."""
        self.wx, self.wy = wx, wy
        self.theta0 = theta0
        self.scale = scale
        n = self.n
        r = wy / wx
        # d(A_aug xi)/d(p, Omega): rows 1 and 3 are Mg[0] @ xi and Mg[1] @ xi, xi = [s, 1]
        Mg = np.zeros((2, 8, 5))
        Mg[0, 0, 0] = -scale[0] / wx
        Mg[1, 1, 2] = -scale[1] / wy
        Mg[0, 2, 2] = -scale[2] / wx
        Mg[1, 2, 0] = -scale[2] / wy
        Mg[0, 3, 1] = -scale[3]
        Mg[1, 4, 3] = -scale[4]
        Mg[0, 5, 3] = -scale[5] * r
        Mg[1, 5, 1] = -scale[5] / r
        Mg[0, 7, 3] = 2.0 * r
        Mg[1, 7, 1] = -2.0 / r
        A = np.zeros((5, 5))
        A[0, 1] = wx
        A[2, 3] = wy
        stack = np.zeros((KMAX, 5, 5))
        stack[0] = np.eye(5)
        i0 = self.measured_pair.state_rows[0]
        hgain = np.array([1.0, 1.0] if self.measured_pair is MeasuredPair.POSITIONS
                         else [wx, wy])
        self._model = ObserverModel(
            theta0=theta0, scale=scale, wx=wx, wy=wy, i0=i0, hgain=hgain, A=A,
            MgT=Mg.reshape(16, 5).T.copy(), stack=stack,
            G=np.zeros((KMAX, 16)), Gb=np.zeros((KMAX, 16)))
        tun = self.tuning
        self._noise = NoiseModel(
            sigma_z1=float(tun.sigma_z1), sigma_z2=float(tun.sigma_z2),
            noise_rel=float(tun.noise_rel), innov_floor=float(tun.innov_floor),
            innov_tau=float(tun.innov_tau), joseph=bool(tun.joseph))
        self._model_t, self._noise_t = tuple(self._model), tuple(self._noise)
        self.rate_models = rate.model_names(tun)  #: names of the rate models run
        self._Fr, self._Qr, self._Pi = rate.rate_models(tun, 1.0)
        self._qpar = 0.0
        self._h_cached = -1.0
        self._Tdiag = np.array([1.0, 1.0 / wx, 1.0, 1.0 / wy])
        self._out = np.empty(N_OUTPUTS)
        self._L = np.zeros((n, n))  # Cholesky factor scratch of the monitor
        self._lim = limits(self._model, tun, self.measured_pair)

    def _set_h(self, h: float) -> None:
        """Rate models' transitions and process noise of a step h (cached: h rarely changes)."""
        step_too_coarse(h, max(self.wx, self.wy))
        self._Fr, self._Qr, self._Pi = rate.rate_models(self.tuning, h)
        self._qpar = self.tuning.q_param_rel * h
        self._h_cached = h

    @staticmethod
    def _check_h(h: float) -> None:
        if not (h > 0.0 and math.isfinite(h)):
            raise ValueError(f"step h={h!r} s must be finite and > 0")

    @staticmethod
    def _check_finite(**values: float) -> None:
        if not all(math.isfinite(v) for v in values.values()):
            raise ValueError(
                "non-finite input " + ", ".join(f"{k}={v!r}" for k, v in values.items())
                + ": pass finite forces (N) and measurements"
            )

    # ------------------------------------------------------------------ API
    def step(self, ux: float, uy: float, z1: float, z2: float, h: float) -> None:
        """Correct with the measured pair (z1, z2) at t, then propagate to t + h.

        ux, uy (N) are the drive force at t, held over [t, t+h] as the plant holds it;
        Omega_z is likewise held at its estimate over the step. h (s) may vary.
        Same as update(z1, z2, h) then predict(ux, uy, h), in one compiled call.
        """
        if not (h > 0.0 and math.isfinite(h)):
            self._check_h(h)
        if not (math.isfinite(ux) and math.isfinite(uy) and math.isfinite(z1)
                and math.isfinite(z2)):
            self._check_finite(ux=ux, uy=uy, z1=z1, z2=z2)
        if self.lost is not None:
            raise ObserverDivergedError(self.lost)
        if h != self._h_cached:  # first: a refused step changes nothing
            self._set_h(h)
        pv = pk0 = pk1 = 0.0  # a prior started by the drive, applied before the predict
        if self._auto_prior:  # as update() then predict() start it
            if self._auto_prior == 1:
                self._start_prior(0.0, 0.0, z1, z2)
            if self._auto_prior:
                size = self._prior_size(ux, uy, 0.0, 0.0)
                if size > 0.0:
                    g = self._model.hgain
                    q = PRIOR_FRACTION * size
                    pv, pk0, pk1 = q * q, size * g[0], size * g[1]
                    self._auto_prior = 0
        code = _ekf_step(self._model_t, self._noise_t, self._lim, self.xs, self.Ps, self.c,
                         self.mu, self.xhat, self.P, self._L, self.peak, self.nu2, self.mon,
                         self._Fr, self._Qr, self._Pi, self._qpar, float(ux), float(uy),
                         float(z1), float(z2), float(h), pv, pk0, pk1)
        self.t += h
        if code != self.status:
            self._verdict(code, h)

    def _prior_size(self, ux: float, uy: float, z1: float, z2: float) -> float:
        """The signal size (m) that starts the auto prior (_start_prior); 0: at rest."""
        th, tun = self.theta0, self.tuning
        g = self._model.hgain
        zs = [abs(z) / gj if abs(z) > 3.0 * sz else 0.0
              for z, gj, sz in ((z1, g[0], tun.sigma_z1), (z2, g[1], tun.sigma_z2))]
        return max(*zs, th[6] * abs(ux) / th[0], th[6] * abs(uy) / th[1])

    def _start_prior(self, ux: float, uy: float, z1: float, z2: float) -> None:
        """Scale-invariant prior of [x, vx, y, vy]: at rest (variance 0) until the first
        drive or measurement above its noise (3 sigma_z; any nonzero one in relative noise
        mode), then 1-sigma = PRIOR_FRACTION of the static deflection b |u| / k of the
        guess (drive) or PRIOR_FRACTION_MEASURED of the measured displacement, in m, and
        that times the guessed natural frequency for the velocities. A measurement whose
        noise was not told may be that noise: the drive's prior still follows (2)."""
        size = self._prior_size(ux, uy, z1, z2)
        if not size > 0.0:
            return
        np.maximum(self.peak, size * self._model.hgain, out=self.peak)
        driven = bool(ux or uy)
        size *= PRIOR_FRACTION if driven else PRIOR_FRACTION_MEASURED
        for i in range(4):  # filter units: m for all four (velocities scaled by 1/w)
            self.P[i, i] += size * size
            self.Ps[:, i, i] += size * size
        told = self.tuning.sigma_z1 > 0.0 and self.tuning.sigma_z2 > 0.0
        self._auto_prior = 2 if not driven and self._auto_prior == 1 and not told else 0

    def _verdict(self, code: int, h: float) -> None:
        """Act on a monitor verdict: status 0/1, or lost: the filter refuses from now on."""
        if code < 2:
            self.status = code
            return
        self.status = 2
        self.lost = lost_message(self.mon, self, h)
        raise ObserverDivergedError(self.lost)

    @property
    def warning(self) -> str | None:
        """The latest block's warning in words while status is 1, else None."""
        return warning_message(self.mon, self._lim, self.t) if self.status == 1 else None

    def update(self, z1: float, z2: float, h: float) -> None:
        """Correct the estimate with the measured pair (z1, z2) at t (eq. 8).

        h (s) is the step that follows: the time base of the innovation average.
        """
        self._check_h(h)
        self._check_finite(z1=z1, z2=z2)
        if self.lost is not None:
            raise ObserverDivergedError(self.lost)
        if self._auto_prior == 1:
            self._start_prior(0.0, 0.0, z1, z2)
        rate.update(self._model, self._noise, self.xs, self.Ps, self.c, self.mu, self.xhat,
                    self.P, self.peak, self.nu2, self.mon, float(z1), float(z2), float(h))

    def predict(self, ux: float, uy: float, h: float) -> None:
        """Propagate the estimate and its covariance to t + h (eq. 5), ux, uy (N) held."""
        self._check_h(h)
        self._check_finite(ux=ux, uy=uy)
        if self.lost is not None:
            raise ObserverDivergedError(self.lost)
        if h != self._h_cached:
            self._set_h(h)
        if self._auto_prior:
            self._start_prior(ux, uy, 0.0, 0.0)
        rate.predict(self._model, self.xs, self.Ps, self.mu, self.c, self._Pi, self.xhat,
                     self.P, self._Fr, self._Qr, self._qpar, self.peak, float(ux), float(uy),
                     float(h))
        self.t += h
        code = check(self._model, MonitorLimits(*self._lim), self.xhat, self.P, self._L,
                     self.peak, self.mon)
        if code != self.status:
            self._verdict(code, h)

    def held_step(self, s: np.ndarray, ux: float, uy: float, h: float,
                  theta: np.ndarray | None = None, Omega_z: float | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The observer's exact held-input step (eq. 5) of a plant state, as predict runs it.

        s = [x, vx, y, vy] (m, m/s) at t; ux, uy (N) and Omega_z (rad/s) held over h (s);
        theta = [kxx, kyy, kxy, dxx, dyy, dxy, 1/m] (default: the current estimates).
        Returns s(t+h), Phi = ds(t+h)/ds (4x4) and S = ds(t+h)/d(p, Omega_z) (4x8), where
        p are the filter's scaled parameter deviations, theta = theta_0 + scale p.
        """
        x = self.xhat
        th = (self.theta0 + self.scale * x[I_PAR:I_PAR + N_PAR] if theta is None
              else np.asarray(theta, dtype=float))
        om = float(x[I_OM] if Omega_z is None else Omega_z)
        T = self._Tdiag
        s1, Phi, S = kern.held_step(self._model, np.ascontiguousarray(th), om,
                                    np.asarray(s, dtype=float) * T, float(ux), float(uy),
                                    float(h))
        return s1 / T, Phi / T[:, None] * T[None, :], S / T[:, None]

    def output_row(self) -> list[float]:
        """[x, vx, y, vy] (m, m/s), UNKNOWNS, then their 1-sigmas: what the FMU publishes."""
        kern.output_row(self.theta0, self.scale, self.xhat, self.P, self._Tdiag, self._out)
        return self._out.tolist()

    def rate_probabilities(self) -> dict[str, float]:
        """P(the rate is constant / rough / slow / agile) after the last step (observer_rate): the
        IMM's model probabilities; a fixed model: 1 for its kind (agile for tracking),
        0 for the others; expert: all 0."""
        out = dict.fromkeys(rate.RATE_KINDS, 0.0)
        kind = rate.RateModel(int(self.tuning.rate_model))
        if kind is rate.RateModel.adaptive:
            for name, c in zip(self.rate_models, self.c.tolist(), strict=True):
                out[name] += c  # the graded rough models count as rough
        elif kind is rate.RateModel.constant:
            out["constant"] = 1.0
        elif kind is rate.RateModel.tracking:
            out["agile"] = 1.0
        return out

    def state_estimate(self) -> np.ndarray:
        """[x, vx, y, vy] at the current time (m, m/s)."""
        return np.array(self.output_row()[:4])

    def estimates(self) -> dict[str, float]:
        """Current estimates of UNKNOWNS (k's 1/s^2, d's 1/s, m kg, Omega_z rad/s)."""
        return dict(zip(UNKNOWNS, self.output_row()[4:12], strict=True))

    def sigmas(self) -> dict[str, float]:
        """1-sigma of each of UNKNOWNS from the covariance (m by the delta method from 1/m)."""
        return dict(zip(UNKNOWNS, self.output_row()[12:20], strict=True))

    def get_state(self) -> dict:
        """Everything internal as plain floats / lists (JSON-serializable)."""
        return {
            "version": _STATE_VERSION,
            "measured_pair": int(self.measured_pair),
            "tuning": asdict(self.tuning),
            "wx": self.wx,
            "wy": self.wy,
            "theta0": self.theta0.tolist(),
            "scale": self.scale.tolist(),
            "xhat": self.xhat.tolist(),
            "P": self.P.tolist(),
            "rate_filters": {"x": self.xs.tolist(), "P": self.Ps.tolist(),
                             "mu": self.mu.tolist(), "c": self.c.tolist()},
            "peak": self.peak.tolist(),
            "nu2": self.nu2.tolist(),
            "monitor": [*self.mon.tolist(), self.status, self.lost, self._auto_prior],
            "t": self.t,
        }

    def set_state(self, state: dict) -> None:
        """Restore a get_state() snapshot (also into an observer built differently)."""
        if not isinstance(state, dict) or state.get("version") != _STATE_VERSION:
            raise ValueError(
                f"observer state must be a dict from get_state() with version "
                f"{_STATE_VERSION}; got {type(state).__name__} "
                f"version {state.get('version') if isinstance(state, dict) else None!r}"
            )
        tuning = ObserverTuning(**state["tuning"])
        n = 4 + N_PAR + rate.rate_block_size(tuning)
        xhat = np.array(state["xhat"], dtype=float)
        P = np.array(state["P"], dtype=float)
        if xhat.shape != (n,) or P.shape != (n, n):
            raise ValueError(
                f"observer state has xhat {xhat.shape} and P {P.shape}; expected ({n},) and "
                f"({n}, {n}) for rate_model={tuning.rate_model}, omega_order="
                f"{tuning.omega_order}"
            )
        rf = state["rate_filters"]
        M = len(rate.model_names(tuning))
        xs, Ps = np.array(rf["x"], dtype=float), np.array(rf["P"], dtype=float)
        mu, c = np.array(rf["mu"], dtype=float), np.array(rf["c"], dtype=float)
        if xs.shape != (M, n) or Ps.shape != (M, n, n) or mu.shape != (M,) or c.shape != (M,):
            raise ValueError(
                f"observer state has rate filters x {xs.shape}, P {Ps.shape}, mu {mu.shape}; "
                f"expected ({M}, {n}), ({M}, {n}, {n}), ({M},) for its rate models"
            )
        self.tuning = tuning
        self.measured_pair = MeasuredPair.of(int(state["measured_pair"]))
        self.order = rate.rate_block_size(tuning)
        self.n = n
        self.xs, self.Ps, self.mu, self.c = xs, Ps, mu, c
        self._build(float(state["wx"]), float(state["wy"]),
                    np.array(state["theta0"], dtype=float), np.array(state["scale"], dtype=float))
        self.xhat = xhat
        self.P = P
        self.peak = np.array(state["peak"], dtype=float)
        self.nu2 = np.array(state["nu2"], dtype=float)
        mon = state["monitor"]
        if not (isinstance(mon, list) and len(mon) == N_MON + 3):
            raise ValueError(f"observer state monitor {mon!r}: expected a list of {N_MON + 3}")
        self.mon = np.array(mon[:N_MON], dtype=float)
        self.status, self.lost, self._auto_prior = int(mon[N_MON]), mon[N_MON + 1], \
            int(mon[N_MON + 2])
        self.t = float(state["t"])
