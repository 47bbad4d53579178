"""Online state observer of the single-axis-drive gyroscope (US 2011/0314910 A1, eqs. 5-9).

The observer of eq. 8, x^' = f(x^) + B U + L C (X - X^), run as an extended Kalman filter
on the augmented state of eq. 5, X = [x, x', y, y', Omega_z, kxx, kyy, kxy, dxx, dyy, dxy, m]
(with 1/m in place of m), from the measured pair of eqs. 6 and 9 / claim 4: positions
(x, y) or velocities (x', y'). Each step corrects with the measurement at t (eq. 8, gain
from the covariance), then predicts to t + h with ux, uy and Omega_z held, exactly as
the plant steps (eq. 5). Every per-step computation is the C core's
(fmu_src/core/gyro_observer*.c, the one GyroObserver.fmu runs); this class holds its
struct and shows its arrays as numpy views. Units: k's 1/s^2, d's 1/s, m kg, Omega_z
rad/s, forces N. Why it is built this way, with measurements: docs/observer-design.md;
why it stays sound at any step, start and signal scale (Joseph update, signal-scaled
priors, the divergence monitor, the status and the named errors):
docs/observer-soundness.md.
"""

from __future__ import annotations

import ctypes
import warnings
from dataclasses import asdict

import numpy as np

from ..core import observer as cobs
from ..core.library import Params
from ..model.measurement import UNKNOWNS, MeasuredPair
from ..model.parameters import GyroParameters
from . import observer_rate as rate
from .observer_monitor import CoarseStepWarning, ObserverDivergedError, ObserverStepError
from .observer_state import HELD_FIELDS, STATE_VERSION, fields, restore
from .observer_tuning import ObserverTuning

__all__ = ["CoarseStepWarning", "GyroStateObserver", "ObserverDivergedError",
           "ObserverStepError", "ObserverTuning"]

N_PAR = cobs.NPAR  #: kxx, kyy, kxy, dxx, dyy, dxy, b = 1/m
I_PAR = cobs.IPAR  #: filter-state row of the first parameter
I_OM = cobs.IOM  #: filter-state row of Omega_z
N_MON = 16  #: numbers of the monitor in get_state() (core.observer.Monitor's fields)
N_OUTPUTS = 4 + 8 + 8  #: outputs of output_row(): state estimate, UNKNOWNS, their 1-sigmas
_P = ctypes.POINTER(ctypes.c_double)


def _ptr(a: np.ndarray):
    return a.ctypes.data_as(_P)


def c_tuning(tuning: ObserverTuning) -> cobs.Tuning:
    """The core's GyroObserverTuning of an ObserverTuning."""
    return cobs.Tuning(**{k: (int(v) if k in cobs.INTEGER_FIELDS else float(v))
                          for k, v in asdict(tuning).items()})


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

    def __init__(self, initial: GyroParameters, Omega_z_0: float = 0.0, measured_pair: int = 1,
                 tuning: ObserverTuning | None = None) -> None:
        pair = MeasuredPair.of(measured_pair)
        if not isinstance(initial, GyroParameters):
            raise ValueError(
                f"initial={initial!r} must be a GyroParameters (e.g. parameters.preset(...))"
            )
        if not isinstance(Omega_z_0, int | float):
            raise ValueError(f"Omega_z_0={Omega_z_0!r} rad/s must be a finite number")
        tun = tuning if tuning is not None else ObserverTuning()
        if not isinstance(tun, ObserverTuning):
            raise ValueError(f"tuning={tun!r} must be an ObserverTuning or None")
        self._c = cobs.Observer()
        self._lib = cobs.observer_core()
        self._msg = ctypes.create_string_buffer(2048)
        guess = Params(*(float(getattr(initial, n)) for n, _ in Params._fields_))
        if self._lib.gyro_observer_init(ctypes.byref(self._c), ctypes.byref(guess),
                                        float(Omega_z_0), int(pair), ctypes.byref(c_tuning(tun)),
                                        self._msg, len(self._msg)):
            raise ValueError(self._msg.value.decode())
        self._ref = ctypes.byref(self._c)
        self.tuning = tun
        self.measured_pair = pair
        self.rate_models = rate.model_names(tun)  #: names of the rate models run

    # ------------------------------------------------------------------ views of the struct
    @property
    def n(self) -> int:
        """Filter states: 4 + 7 + the rate block's."""
        return self._c.n

    @property
    def order(self) -> int:
        """States of the rate block (Omega_z and the derivatives its models use)."""
        return self._c.order

    def _view(self, field: str, *shape: int) -> np.ndarray:
        a = np.ctypeslib.as_array(getattr(self._c, field))
        return a[tuple(slice(0, k) for k in shape)] if shape else a

    @property
    def xhat(self) -> np.ndarray:
        """Combined estimate of the filter state (a view into the core's struct)."""
        return self._view("x", self.n)

    @property
    def P(self) -> np.ndarray:
        """Its covariance (n x n view), made whole first (a step keeps what the next reads)."""
        self._lib.gyro_observer_complete_covariance(ctypes.byref(self._c))
        return self._view("P", self.n, self.n)

    @property
    def xs(self) -> np.ndarray:
        """Each rate model's filter state (M x n view)."""
        return self._view("xs", self._c.n_models, self.n)

    @property
    def Ps(self) -> np.ndarray:
        """Each rate model's covariance (M x n x n view)."""
        return self._view("Ps", self._c.n_models, self.n, self.n)

    @property
    def mu(self) -> np.ndarray:
        """Model probabilities after the last correction."""
        return self._view("mu", self._c.n_models)

    @property
    def c(self) -> np.ndarray:
        """Model probabilities predicted to the next correction."""
        return self._view("c", self._c.n_models)

    @property
    def peak(self) -> np.ndarray:
        """Running peak |z1|, |z2|."""
        return self._view("peak")

    @property
    def theta0(self) -> np.ndarray:
        """Initial guess of theta = [kxx, kyy, kxy, dxx, dyy, dxy, 1/m]."""
        return self._view("theta0").copy()

    @property
    def scale(self) -> np.ndarray:
        """Scale of each parameter deviation: theta = theta0 + scale p."""
        return self._view("scale").copy()

    @property
    def wx(self) -> float:
        return self._c.wx

    @property
    def wy(self) -> float:
        return self._c.wy

    @property
    def t(self) -> float:
        """s since construction."""
        return self._c.t

    @property
    def status(self) -> int:
        """0 ok, 1 warning (innovations above their band), 2 lost."""
        return self._c.status

    @property
    def lost(self) -> str | None:
        """Why the filter is lost (then every step refuses), or None."""
        return self._c.lost_message.decode() if self._c.lost else None

    # ------------------------------------------------------------------ API
    @property
    def c_struct(self) -> cobs.Observer:
        """The core's GyroObserver this object steps (for a C loop over it: core chain)."""
        return self._c

    @property
    def message_buffer(self) -> ctypes.Array:
        """Where the core writes the words of a step's result (check_step reads them)."""
        return self._msg

    def check_step(self, code: int, h: float) -> None:
        """What step() does with the core's result `code` of a step of h done elsewhere
        (a C loop): raise if the filter was lost or the step refused, warn once per h."""
        if code:
            self._result(code)
        if h != getattr(self, "_coarse_h", 0.0):
            self._warn_if_coarse(h)

    def _result(self, code: int) -> None:
        if code >= 0 and code != cobs.STEP_LOST:
            return
        text = self._msg.value.decode()
        if code in (cobs.STEP_LOST, cobs.REFUSED):
            raise ObserverDivergedError(text)
        if code == cobs.TOO_COARSE:
            raise ObserverStepError(text)
        raise ValueError(text)

    def step(self, ux: float, uy: float, z1: float, z2: float, h: float) -> None:
        """Correct with the measured pair (z1, z2) at t, then propagate to t + h.

        ux, uy (N) are the drive force at t, held over [t, t+h] as the plant holds it;
        Omega_z is likewise held at its estimate over the step. h (s) may vary.
        Same as update(z1, z2, h) then predict(ux, uy, h), in one call of the core.
        """
        self.check_step(self._lib.gyro_observer_step(self._ref, ux, uy, z1, z2, h, self._msg,
                                                     2048), h)

    def _warn_if_coarse(self, h: float) -> None:
        """CoarseStepWarning once per step size (GyroObserver.fmu logs the same words)."""
        self._coarse_h = h
        if self._lib.gyro_observer_step_warning(self._ref, float(h), self._msg, 2048):
            warnings.warn(self._msg.value.decode(), CoarseStepWarning, stacklevel=3)

    def update(self, z1: float, z2: float, h: float) -> None:
        """Correct the estimate with the measured pair (z1, z2) at t (eq. 8).

        h (s) is the step that follows: the time base of the innovation average.
        """
        self._result(self._lib.gyro_observer_update(self._ref, float(z1), float(z2), float(h),
                                                    self._msg, 2048))

    def predict(self, ux: float, uy: float, h: float) -> None:
        """Propagate the estimate and its covariance to t + h (eq. 5), ux, uy (N) held."""
        self._result(self._lib.gyro_observer_predict(self._ref, float(ux), float(uy), float(h),
                                                     self._msg, 2048))
        if h != getattr(self, "_coarse_h", 0.0):
            self._warn_if_coarse(h)

    @property
    def warning(self) -> str | None:
        """The latest block's warning in words while status is 1, else None."""
        if self._lib.gyro_observer_warning(self._ref, self._msg, 2048):
            return self._msg.value.decode()
        return None

    @property
    def restarts(self) -> int:
        """How often the re-fit test rejected the estimate and restarted it."""
        return int(self._c.refit.restarts)

    @property
    def restart_message(self) -> str | None:
        """The last re-fit restart in words (what GyroObserver.fmu logs), or None."""
        if self._lib.gyro_observer_restart_message(self._ref, self._msg, 2048):
            return self._msg.value.decode()
        return None

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
              else np.ascontiguousarray(theta, dtype=float))
        om = float(x[I_OM] if Omega_z is None else Omega_z)
        T = np.array([1.0, 1.0 / self.wx, 1.0, 1.0 / self.wy])
        s0 = np.ascontiguousarray(np.asarray(s, dtype=float) * T)
        s1, Phi, S = np.empty(4), np.empty((4, 4)), np.empty((4, 8))
        self._lib.gyro_observer_held_step(self._ref, _ptr(th), om, _ptr(s0), float(ux),
                                          float(uy), float(h), _ptr(s1), _ptr(Phi), _ptr(S))
        return s1 / T, Phi / T[:, None] * T[None, :], S / T[:, None]

    def output_row(self) -> list[float]:
        """[x, vx, y, vy] (m, m/s), UNKNOWNS, then their 1-sigmas: what the FMU publishes."""
        out = (ctypes.c_double * N_OUTPUTS)()
        self._lib.gyro_observer_outputs(self._ref, out)
        return list(out)

    def rate_probabilities(self) -> dict[str, float]:
        """P(the rate is constant / rough / slow / agile) after the last step (observer_rate): the
        IMM's model probabilities; a fixed model: 1 for its kind (agile for tracking),
        0 for the others; expert: all 0."""
        out = (ctypes.c_double * 4)()
        self._lib.gyro_observer_rate_probabilities(self._ref, out)
        return dict(zip(rate.RATE_KINDS, out, strict=True))

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
        mon = self._c.mon
        numbers = [getattr(mon, n) for n in ("nis", "count", "status", "cause", "which",
                                               "value", "block", "last_nis", "last_rel")]
        numbers += [*mon.prev, *mon.ac, *mon.sq, mon.last_corr]
        return {
            "version": STATE_VERSION,
            "measured_pair": int(self.measured_pair),
            "tuning": asdict(self.tuning),
            "wx": self.wx,
            "wy": self.wy,
            "theta0": self.theta0.tolist(),
            "scale": self.scale.tolist(),
            "xhat": self.xhat.tolist(),
            "P": self.P.tolist(),
            "rate_filters": {"x": self.xs.tolist(), "P": self.Ps.tolist(),
                             "mu": self.mu.tolist(), "c": self.c.tolist(),
                             "rate_scale": float(self._c.rate_scale),
                             "wander": fields(self._c.wander)},
            "peak": self.peak.tolist(),
            "nu2": [*self._view("nu2").tolist(), *self._view("nu2_zero").tolist(),  # gain's, P's
                    float(self._c.nu2_mass)],
            "monitor": [*numbers, self.status, self.lost, int(self._c.auto_prior)],
            "refit": fields(self._c.refit),
            "t": self.t,
            "held": fields(self._c.held, HELD_FIELDS),
        }

    def set_state(self, state: dict) -> None:
        """Restore a get_state() snapshot (also into an observer built differently)."""
        if not isinstance(state, dict) or state.get("version") != STATE_VERSION:
            raise ValueError(
                f"observer state must be a dict from get_state() with version "
                f"{STATE_VERSION}; got {type(state).__name__} "
                f"version {state.get('version') if isinstance(state, dict) else None!r}"
            )
        tuning = ObserverTuning(**state["tuning"])
        pair = MeasuredPair.of(int(state["measured_pair"]))
        theta0 = np.array(state["theta0"], dtype=float)
        scale = np.array(state["scale"], dtype=float)
        if theta0.shape != (N_PAR,) or scale.shape != (N_PAR,):
            raise ValueError(f"observer state has theta0 {theta0.shape} and scale "
                             f"{scale.shape}; expected ({N_PAR},) each")
        # a fresh struct of this tuning and pair (a guess from theta0), then the saved numbers
        th = theta0
        guess = GyroParameters(kxx=th[0], kyy=th[1], kxy=th[2], dxx=th[3], dyy=th[4],
                               dxy=th[5], m=1.0 / th[6])
        other = GyroStateObserver(guess, 0.0, int(pair), tuning)
        c = other._c
        n, M = c.n, c.n_models
        xhat = np.array(state["xhat"], dtype=float)
        P = np.array(state["P"], dtype=float)
        if xhat.shape != (n,) or P.shape != (n, n):
            raise ValueError(
                f"observer state has xhat {xhat.shape} and P {P.shape}; expected ({n},) and "
                f"({n}, {n}) for rate_model={tuning.rate_model}, omega_order="
                f"{tuning.omega_order}"
            )
        rf = state["rate_filters"]
        xs, Ps = np.array(rf["x"], dtype=float), np.array(rf["P"], dtype=float)
        mu, cc = np.array(rf["mu"], dtype=float), np.array(rf["c"], dtype=float)
        if xs.shape != (M, n) or Ps.shape != (M, n, n) or mu.shape != (M,) or cc.shape != (M,):
            raise ValueError(
                f"observer state has rate filters x {xs.shape}, P {Ps.shape}, mu {mu.shape}; "
                f"expected ({M}, {n}), ({M}, {n}, {n}), ({M},) for its rate models"
            )
        mon = state["monitor"]
        if not (isinstance(mon, list) and len(mon) == N_MON + 3 and mon[-1] in (0, 1, 2)):
            raise ValueError(f"observer state monitor {mon!r}: expected a list of {N_MON + 3}, "
                             "the last the auto prior's state 0, 1 or 2")
        other._lib.gyro_observer_set_scaling(other._ref, float(state["wx"]), float(state["wy"]),
                                             _ptr(theta0), _ptr(scale))
        other.xhat[:] = xhat
        other.P[:] = P
        other.xs[:] = xs
        other.Ps[:] = Ps
        other.mu[:] = mu
        other.c[:] = cc
        other.peak[:] = np.array(state["peak"], dtype=float)
        nu2 = np.array(state["nu2"], dtype=float).reshape(5)  # [gain's 2, P's 2, weight]
        other._view("nu2")[:], other._view("nu2_zero")[:], c.nu2_mass = nu2[:2], nu2[2:4], nu2[4]
        m = c.mon
        for name, value in zip(("nis", "count", "status", "cause", "which", "value", "block",
                                "last_nis", "last_rel"), mon[:9], strict=True):
            setattr(m, name, float(value))
        m.prev[:], m.ac[:], m.sq[:] = mon[9:11], mon[11:13], mon[13:15]
        m.last_corr = float(mon[15])
        c.status = int(mon[N_MON])
        lost = mon[N_MON + 1]
        c.lost = int(lost is not None)
        c.lost_message = (lost or "").encode()[:1023]
        c.auto_prior = int(mon[N_MON + 2])
        refit = state.get("refit")
        if not isinstance(refit, dict) or set(refit) != {f for f, _ in type(c.refit)._fields_}:
            raise ValueError(f"observer state refit {refit!r}: expected the re-fit test's "
                             "fields W, g, F, weight, last_T, shift, move, restarts, pending")
        restore(c.refit, refit)
        c.t = float(state["t"])
        c.rate_scale = float(rf.get("rate_scale", 0.0))  # rate_model 4's bank (absent: c 1)
        wander = rf.get("wander", {})  # the constant model's wander test (absent: fresh)
        if not set(wander) <= set(names := [f for f, _ in type(c.wander)._fields_]):
            raise ValueError(f"observer state wander {sorted(wander)}: expected the wander "
                             f"test's fields {', '.join(names)}")
        restore(c.wander, wander)
        held = state.get("held")  # absent in states saved before the cache: it starts empty
        if held is not None:
            if not isinstance(held, dict) or set(held) != set(HELD_FIELDS):
                raise ValueError(f"observer state held {held!r}: expected the held-step "
                                 f"cache's fields {', '.join(HELD_FIELDS)}")
            restore(c.held, held)
        if other._lib.gyro_observer_state_restored(ctypes.byref(c), other._msg,
                                                   len(other._msg)):  # the core's checks
            raise ValueError(other._msg.value.decode())
        self._c, self._ref, self._lib, self._msg = c, ctypes.byref(c), other._lib, other._msg
        self.tuning, self.measured_pair, self.rate_models = tuning, pair, other.rate_models

    def __getstate__(self) -> dict:  # pickling and copy: the JSON-able state
        return self.get_state()

    def __setstate__(self, state: dict) -> None:
        self.set_state(state)


def rate_models(tuning, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Fr, Qr, Pi): each model's rate-block transition and process noise over h (M x r x
    r) and the model transition probabilities Pi[i, j] = P(model j at t + h | i at t), as
    the core builds them (gyro_observer_set_step; the guess only sets the scaling)."""
    from ..model.parameters import DEFAULT_PRESET, PRESETS

    obs = GyroStateObserver(PRESETS[DEFAULT_PRESET], 0.0, 1, tuning)
    obs._lib.gyro_observer_set_step(obs._ref, float(h))
    c, M, r = obs._c, len(rate.model_names(tuning)), rate.rate_block_size(tuning)
    Fr = np.ctypeslib.as_array(c.Fr)[:M, :r, :r].copy()
    Qr = np.ctypeslib.as_array(c.Qr)[:M, :r, :r].copy()
    return Fr, Qr, np.ctypeslib.as_array(c.Pi)[:M, :M].copy()
