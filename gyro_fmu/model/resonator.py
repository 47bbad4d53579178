"""The resonator of US 9,482,553 (eq. 1): two lightly coupled modes, voltages in and out.

Its parameters, declared here; its equations and step live in the C core
(fmu_src/core/gyro_resonator.h), which GyroResonator.fmu steps too.

Per unit modal mass, with q = (x, y):

    x'' + dxx x' + (dxy - 2 kappa Omega_z) y' + kxx x + kxy y = fx
    y'' + dyy y' + (dxy + 2 kappa Omega_z) x' + kyy y + kxy x = fy
    fx = Bx (Vx + alpha_y Vy),   fy = By (Vy + alpha_x Vx)

kappa is the Bryant factor (Coriolis mass over modal mass, 0.8 for an n = 2 ring);
alpha_x, alpha_y are the forcer misalignments (coupling of the x forcer into y and of
the y forcer into x). Each pick-off has gain P and electronics modelled by a first-order
lag tau whose phase at the mode frequency is phi (tan phi = omega tau): its voltage is
V_p = P z, tau z' = q_s - z + c_ring V_ring, plus feed-through E V of the drive
voltages and white noise. V_ring = ring_amplitude (cos w1 t + cos w2 t) excites the
pick-offs electrically without moving the ring (the seed's off-resonant ring
excitation that reveals the relative pick-off phase), generated inside (two oscillator
states): a held, staircase ring voltage would pass the fast lags unseen at the samples.

The sensed displacement (non-orthogonal pick-offs): x_s = cos(beta_x) x + sin(beta_x) y,
y_s = cos(beta_y) y + sin(beta_y) x; beta_x = -beta_y is a pure rotation of both.

Optional cubic stiffness (eqs. 20-23): k3x x^3 + k3xy y^3 adds to the x restoring
force, k3y y^3 + k3yx x^3 to the y one. Without it each step is the exact held-input
solution (one matrix exponential); with it the step is split symmetrically (Strang):
exact linear flow over h/2n, a cubic velocity kick over h/n, exact linear flow over
h/2n, n times (time-reversible; error second order in h/n on the cubic force alone).

Thermomechanical force noise (m_modal > 0), white drive-voltage noise (drive_noise)
and a temperature ramp (temperature_rate, tc_f, tc_Q: the step matrices recomputed
every thermal_update_steps steps at the interval's mid temperature) are derived in
docs/resonator-physics.md; their noise has its own seeded stream.
"""

from __future__ import annotations

import ctypes
import math
from dataclasses import asdict, fields, replace

import numpy as np

from ..core import selfcal as c
from ..core.structs import declared
from ..core.structs.selfcal import RESONATOR_PARAMS
from ..errors import GyroFmuError

#: Order of the resonator's state vector.
STATE = ("x", "y", "vx", "vy", "zx", "zy", "ring1_cos", "ring1_sin", "ring2_cos", "ring2_sin")
#: Order of its held inputs.
INPUTS = ("Vx", "Vy")
N_STATE = len(STATE)
#: Earth's rotation rate, rad/s.
EARTH_RATE = 7.2921150e-5
#: States the force noise reaches (x, y, vx, vy, zx, zy); Boltzmann constant, J/K.
N_FORCED, K_B = 6, 1.380649e-23


class ResonatorError(GyroFmuError, ValueError):
    """A resonator parameter is unusable; the message names it and the remedy."""


@declared(RESONATOR_PARAMS)
class ResonatorParameters:
    """Near mode-matched high-Q resonator with electrostatic forcers and pick-offs.

    Default: 4 kHz, Q 2e4 (0.2 Hz half-power width, ring-down time 1.6 s), 0.25 Hz
    split, bias from cross damping 1.7e-3 rad/s (0.1 deg/s), quadrature 0.17 rad/s
    (10 deg/s), 3 % pick-off gain mismatch with 2 mrad relative phase, mrad forcer
    misalignments and 1e-3 V/V feed-through: every imperfection of the seed on. The
    fields (defaults, units, meaning) are declared with the core's struct
    (gyro_fmu.core.structs.selfcal.RESONATOR_PARAMS).
    """

    @property
    def omega_x(self) -> float:
        return 2.0 * math.pi * self.f_x

    @property
    def omega_y(self) -> float:
        return 2.0 * math.pi * self.f_y

    @property
    def kxx(self) -> float:
        return self.omega_x**2

    @property
    def kyy(self) -> float:
        return self.omega_y**2

    @property
    def dxx(self) -> float:
        return self.omega_x / self.Q_x

    @property
    def dyy(self) -> float:
        return self.omega_y / self.Q_y

    @property
    def tau_x(self) -> float:
        return math.tan(self.phi_x) / self.omega_x

    @property
    def tau_y(self) -> float:
        return math.tan(self.phi_y) / self.omega_x

    @property
    def forcer(self) -> np.ndarray:
        """B: (fx, fy) = B (Vx, Vy), m/s^2 per V."""
        return np.array([[self.Bx, self.Bx * self.alpha_y],
                         [self.By * self.alpha_x, self.By]])

    @property
    def feedthrough(self) -> np.ndarray:
        return np.array([[self.Exx, self.Exy], [self.Eyx, self.Eyy]])

    def drifted(self, delta_f: float = 0.4, damping_factor: float = 1.05) -> ResonatorParameters:
        """The same instrument after a temperature-like drift: both modes shifted by
        delta_f (Hz), every damping (dxx, dyy, dxy) scaled by damping_factor."""
        if not (math.isfinite(damping_factor) and damping_factor > 0.0):
            raise ResonatorError(f"damping factor {damping_factor!r} must be a finite number "
                                 "> 0 (1.05: every damping 5 % higher)")
        if not math.isfinite(delta_f) or min(self.f_x, self.f_y) + delta_f <= 0.0:
            raise ResonatorError(f"frequency drift {delta_f!r} Hz must be finite and leave "
                                 "both modes above 0 Hz")
        return replace(
            self, f_x=self.f_x + delta_f, f_y=self.f_y + delta_f,
            Q_x=self.Q_x * (self.f_x + delta_f) / self.f_x / damping_factor,
            Q_y=self.Q_y * (self.f_y + delta_f) / self.f_y / damping_factor,
            dxy=self.dxy * damping_factor,
        )

    def without_noise(self) -> ResonatorParameters:
        """The same instrument with every noise off: what a rate table's truth sees."""
        return replace(self, noise=0.0, m_modal=0.0, drive_noise=0.0)

    def later(self, t: float) -> ResonatorParameters:
        """The same instrument t seconds later on its temperature history: temperature,
        f_x, f_y, Q_x, Q_y as the core's gyro_resonator_at_temperature gives them after
        dT = gyro_resonator_temperature_offset(t) (the ramp and the exponential
        warm-up), the history going on from there (the warm-up's remaining rise
        warmup_span exp(-t / warmup_tau)). A calibration sequence runs each record from
        here, so the warm-up runs through the whole sequence (docs/self-calibration.md)."""
        dT = self.temperature_offset(t)
        if dT == 0.0:
            return self
        (kd, pk) = _out(4)
        _call("gyro_resonator_at_temperature", _params(self), dT, pk)
        wx, wy = math.sqrt(kd[0]), math.sqrt(kd[1])
        rest = self.warmup_span * math.exp(-t / self.warmup_tau) if self.warmup_span else 0.0
        return replace(self, temperature=self.temperature + dT, f_x=wx / (2 * math.pi),
                       f_y=wy / (2 * math.pi), Q_x=wx / kd[2], Q_y=wy / kd[3],
                       warmup_span=rest)

    def temperature_offset(self, t: float) -> float:
        """K from the start temperature t seconds on (the core's history)."""
        return float(c.selfcal_core().gyro_resonator_temperature_offset(
            ctypes.byref(_params(self)), t))

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def core_struct(settings: object, struct: type, integers: tuple[str, ...],
                error: type[Exception]) -> ctypes.Structure:
    """The settings dataclass as its core struct; an Integer field given a non-integer, or
    a value that is not a number, is refused by name."""
    out = struct()
    for f in fields(settings):
        value = getattr(settings, f.name)
        if f.name in integers:
            if isinstance(value, bool) or not float(value).is_integer() or \
                    not -2**31 <= value < 2**31:
                raise error(f"{f.name}={value!r} must be a whole number (an Integer "
                            "parameter in [-2^31, 2^31)): give it without a fraction")
            value = int(value)
        else:
            try:
                value = float(value)
            except (TypeError, ValueError):
                raise error(f"{f.name}={value!r} is not a number: give a number") from None
        setattr(out, f.name, value)
    return out


def _params(p: ResonatorParameters) -> c.ResonatorParams:
    return core_struct(p, c.ResonatorParams, c.RESONATOR_INTEGERS, ResonatorError)


def _problems_of(text: str | None) -> list[str]:
    return text.split("; ") if text else []


def _call(name: str, *args: object) -> None:
    """A core function with a trailing (msg, n): ResonatorError with its message on 1."""
    msg = c.message_buffer()
    if getattr(c.selfcal_core(), name)(*args, msg, len(msg)):
        raise ResonatorError(msg.value.decode())


def check_resonator(p: ResonatorParameters) -> list[str]:
    """Problems with p (empty when usable), each naming the value and the remedy (the
    core's gyro_resonator_problems: the FMU refuses the same values with the same words)."""
    try:
        params = _params(p)
    except ResonatorError as exc:
        return [str(exc)]
    msg = c.message_buffer()
    c.selfcal_core().gyro_resonator_problems(params, msg, len(msg))
    return _problems_of(msg.value.decode())


def _out(*shape: int) -> tuple[np.ndarray, ctypes.Array]:
    a = np.zeros(shape)
    return a, a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


def system_matrices(p: ResonatorParameters, Omega_z: float,
                    dT: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Continuous A (10x10) and B (10x2) of the resonator, pick-off lags and ring tones,
    dT kelvin from the start temperature (eq. 1)."""
    (A, pa), (B, pb) = _out(N_STATE, N_STATE), _out(N_STATE, 2)
    _call("gyro_resonator_system", _params(p), Omega_z, dT, pa, pb)
    return A, B


def discretize(p: ResonatorParameters, Omega_z: float, h: float,
               dT: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold step: s(t+h) = Phi s(t) + Gamma V (Van Loan); a pick-off
    with zero lag (tau = 0) has its z set algebraically to q_s."""
    (Phi, pp), (Gamma, pg) = _out(N_STATE, N_STATE), _out(N_STATE, 2)
    _call("gyro_resonator_discretize", _params(p), Omega_z, h, dT, pp, pg)
    return Phi, Gamma


def force_noise_covariance(p: ResonatorParameters, Omega_z: float, h: float,
                           dT: float = 0.0) -> np.ndarray:
    """Covariance (6x6) of the increment of (x, y, vx, vy, zx, zy) over h from white
    acceleration of two-sided intensity 2 k_B T D / m_modal."""
    Q, pq = _out(N_FORCED, N_FORCED)
    _call("gyro_resonator_force_covariance", _params(p), Omega_z, h, dT, pq)
    return Q


def white_noise_covariance(A: np.ndarray, Qc: np.ndarray, h: float) -> np.ndarray:
    """Q(h) = integral over [0, h] of e^{As} Qc e^{A's} ds (n <= 6)."""
    A, Qc = (np.ascontiguousarray(m, dtype=float) for m in (A, Qc))
    n = len(A)
    if A.shape != (n, n) or Qc.shape != (n, n) or not 1 <= n <= 6:
        raise ValueError(f"A and Qc must be square and equal, at most 6x6: {A.shape}, "
                         f"{Qc.shape}")
    Q, pq = _out(n, n)
    d = ctypes.POINTER(ctypes.c_double)
    c.selfcal_core().gyro_white_noise_covariance(n, A.ctypes.data_as(d), Qc.ctypes.data_as(d),
                                                 h, pq)
    return Q


def _view(array: ctypes.Array) -> np.ndarray:
    return np.ctypeslib.as_array(array)


class ResonatorModel(c.CoreStructState):
    """The resonator as a stepping model over the core (what GyroResonator.fmu steps)."""

    _state_error = ResonatorError

    def __init__(self, p: ResonatorParameters, seed: int = 0,
                 initial_state: np.ndarray | None = None) -> None:
        problems = check_resonator(p)
        if problems:
            raise ResonatorError("; ".join(problems))
        if not (isinstance(seed, (int, np.integer)) and 0 <= seed < 2**64):
            raise ResonatorError(f"seed={seed!r} must be a whole number in [0, 2^64)")
        self.p = p
        self.core = c.Resonator()
        s0 = None
        if initial_state is not None:
            s0 = np.ascontiguousarray(initial_state, dtype=float)
            if s0.shape != (N_STATE,):
                raise ResonatorError(f"initial_state has shape {s0.shape}: give {N_STATE} "
                                     f"values {STATE}")
            s0 = s0.ctypes.data_as(ctypes.POINTER(ctypes.c_double))
        _call("gyro_resonator_init", ctypes.byref(self.core), _params(p), int(seed), s0)
        #: views of the core's state and pick-off voltages
        self.s, self.out = _view(self.core.s), _view(self.core.out)

    @property
    def k(self) -> int:
        """Steps taken (the temperature ramp's clock)."""
        return self.core.k

    @property
    def T_sensor(self) -> float:
        """K, the temperature sensor at the current time (history plus its noise)."""
        return self.core.T_sensor

    def steps_left(self) -> int:
        """Steps until the temperature ramp changes the step matrices (or a large n)."""
        return c.selfcal_core().gyro_resonator_steps_left(ctypes.byref(self.core))

    def step(self, V: np.ndarray, Omega_z: float, h: float) -> np.ndarray:
        """Hold V = (Vx, Vy) over h; returns (V_px, V_py) at the end (a view)."""
        _call("gyro_resonator_step", ctypes.byref(self.core), float(V[0]), float(V[1]),
              Omega_z, h)
        return self.out

    def __getstate__(self) -> dict:
        return {"p": self.p, **self.get_state()}

    def __setstate__(self, state: dict) -> None:
        self.p = state["p"]
        self.core = c.Resonator()
        self.set_state(state)
        self.s, self.out = _view(self.core.s), _view(self.core.out)
