"""The resonator of US 9,482,553 (eq. 1): two lightly coupled modes, voltages in and out.

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

import contextlib
import math
from dataclasses import asdict, dataclass, fields, replace

import numpy as np
from numba import njit
from scipy.linalg import expm

from gyro_fmu.errors import GyroFmuError

from .noise import NoiseStream, white_noise_covariance

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


@dataclass(frozen=True)
class ResonatorParameters:
    """Near mode-matched high-Q resonator with electrostatic forcers and pick-offs.

    Default: 4 kHz, Q 2e4 (0.2 Hz half-power width, ring-down time 1.6 s), 0.25 Hz
    split, bias from cross damping 1.7e-3 rad/s (0.1 deg/s), quadrature 0.17 rad/s
    (10 deg/s), 3 % pick-off gain mismatch with 2 mrad relative phase, mrad forcer
    misalignments and 1e-3 V/V feed-through: every imperfection of the seed on.
    """

    f_x: float = 4000.0  #: Hz, x-mode resonant frequency
    f_y: float = 4000.25  #: Hz, y-mode resonant frequency
    Q_x: float = 2.0e4  #: x-mode quality factor
    Q_y: float = 1.9e4  #: y-mode quality factor
    dxy: float = 2.72e-3  #: 1/s, cross damping (bias = dxy / (2 kappa))
    kxy: float = 7.0e3  #: 1/s^2, cross stiffness (quadrature = kxy / (2 kappa omega))
    kappa: float = 0.8  #: Bryant factor
    Bx: float = 0.05  #: m/s^2/V, x forcer gain
    By: float = 0.048  #: m/s^2/V, y forcer gain
    alpha_x: float = 2.0e-3  #: rad, x forcer misalignment into y
    alpha_y: float = -1.0e-3  #: rad, y forcer misalignment into x
    Px: float = 1.0e6  #: V/m, x pick-off gain
    Py: float = 1.03e6  #: V/m, y pick-off gain
    phi_x: float = 0.020  #: rad, x pick-off electronics phase lag at f_x
    phi_y: float = 0.022  #: rad, y pick-off electronics phase lag at f_x
    Exx: float = 2.0e-3  #: V/V, feed-through of Vx into the x pick-off
    Exy: float = 5.0e-4  #: V/V, feed-through of Vy into the x pick-off
    Eyx: float = 1.0e-3  #: V/V, feed-through of Vx into the y pick-off
    Eyy: float = 2.0e-3  #: V/V, feed-through of Vy into the y pick-off
    c_ring: float = 1.0e-7  #: m/V, ring voltage seen by the pick-offs
    k3x: float = 0.0  #: 1/(m^2 s^2), cubic stiffness of x (eq. 20; 4.2e17 = +1 Hz at 1 um)
    k3y: float = 0.0  #: 1/(m^2 s^2), cubic stiffness of y (eq. 21)
    cubic_substeps: int = 4  #: splitting substeps per step when k3x or k3y is not 0
    ring_amplitude: float = 0.0  #: V, each ring excitation tone (0 = off)
    ring_frequency_1: float = 3740.0  #: Hz, first ring tone (off resonance)
    ring_frequency_2: float = 4260.0  #: Hz, second ring tone
    noise: float = 0.0  #: V, std of white noise on each pick-off sample
    beta_x: float = 0.0  #: rad, x pick-off sensing axis tilted toward +y (non-orthogonality)
    beta_y: float = 0.0  #: rad, y pick-off sensing axis tilted toward +x
    k3xy: float = 0.0  #: 1/(m^2 s^2), cross-cubic stiffness, k3xy y^3 in the x equation (eq. 22)
    k3yx: float = 0.0  #: 1/(m^2 s^2), cross-cubic stiffness, k3yx x^3 in the y equation (eq. 23)
    m_modal: float = 0.0  #: kg, modal mass of the thermomechanical force noise (0 = no noise)
    temperature: float = 300.0  #: K, resonator temperature at the start of the run
    drive_noise: float = 0.0  #: V, std of white noise on each held drive voltage sample
    temperature_rate: float = 0.0  #: K/s, temperature ramp during the run
    tc_f: float = 0.0  #: 1/K, relative change of f_x and f_y per kelvin (e.g. -30e-6)
    tc_Q: float = 0.0  #: 1/K, relative change of Q_x and Q_y per kelvin
    thermal_update_steps: int = 4000  #: steps between re-discretizations during a ramp

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

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def non_finite_fields(settings: object) -> list[str]:
    """One problem per field of a settings dataclass that is not a finite number."""
    return [f"{f.name}={v!r} is not finite: give a finite number"
            for f in fields(settings) if not math.isfinite(v := getattr(settings, f.name))]


def check_resonator(p: ResonatorParameters) -> list[str]:
    """Problems with p (empty when usable), each naming the value and the remedy."""
    problems = non_finite_fields(p)
    if problems:
        return problems
    for name in ("f_x", "f_y", "Q_x", "Q_y", "kappa", "Bx", "By", "Px", "Py"):
        if not getattr(p, name) > 0.0:
            problems.append(f"{name}={getattr(p, name)!r} must be > 0")
    for name in ("phi_x", "phi_y"):
        if not 0.0 <= getattr(p, name) < 1.5:
            problems.append(f"{name}={getattr(p, name)!r} rad must lie in [0, 1.5): a "
                            "pick-off lag (0 = none)")
    for name in ("beta_x", "beta_y"):
        if not abs(getattr(p, name)) < 0.5:
            problems.append(f"{name}={getattr(p, name)!r} rad must lie in (-0.5, 0.5): a "
                            "small tilt of the pick-off's axis (0 = on its mode axis)")
    for name in ("cubic_substeps", "thermal_update_steps"):
        if getattr(p, name) < 1:
            problems.append(f"{name}={getattr(p, name)!r} must be >= 1")
    for name, unit in (("noise", "V"), ("drive_noise", "V"), ("m_modal", "kg"),
                       ("temperature", "K")):
        if getattr(p, name) < 0.0:
            problems.append(f"{name}={getattr(p, name)!r} {unit} must be >= 0")
    if not problems and p.kxy**2 >= p.kxx * p.kyy:
        problems.append(
            f"kxy={p.kxy!r} 1/s^2 makes the stiffness indefinite (kxy^2 >= kxx kyy): "
            "use |kxy| well below the mode stiffnesses"
        )
    if not problems and p.m_modal > 0.0 and p.dxy**2 >= p.dxx * p.dyy:
        problems.append(f"dxy={p.dxy!r} 1/s makes the damping indefinite (dxy^2 >= dxx dyy): "
                        "thermomechanical noise needs a dissipative damping matrix")
    return problems


def at_temperature(p: ResonatorParameters, dT: float) -> tuple[float, float, float, float]:
    """(kxx, kyy, dxx, dyy) dT kelvin from the start temperature (tc_f, tc_Q)."""
    if dT == 0.0:
        return p.kxx, p.kyy, p.dxx, p.dyy
    sf, sq = 1.0 + p.tc_f * dT, 1.0 + p.tc_Q * dT
    if not (sf > 0.0 and sq > 0.0):
        raise ResonatorError(f"the temperature ramp reached {dT:+g} K, where f or Q would be "
                             f"<= 0 (tc_f={p.tc_f!r}, tc_Q={p.tc_Q!r}): shorten the run")
    wx, wy = p.omega_x * sf, p.omega_y * sf
    return wx**2, wy**2, wx / (p.Q_x * sq), wy / (p.Q_y * sq)


def _sensing(p: ResonatorParameters) -> tuple[tuple[int, float, float, float, float], ...]:
    """(index, tau, beta, weight of own and of other displacement) of each pick-off."""
    return tuple((i, tau, b, math.cos(b), math.sin(b))
                 for i, (tau, b) in enumerate(((p.tau_x, p.beta_x), (p.tau_y, p.beta_y))))


def system_matrices(p: ResonatorParameters, Omega_z: float,
                    dT: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Continuous A (10x10) and B (10x2) of the resonator, pick-off lags and ring tones,
    dT kelvin from the start temperature."""
    kxx, kyy, dxx, dyy = at_temperature(p, dT)
    A = np.zeros((N_STATE, N_STATE))
    A[0, 2] = A[1, 3] = 1.0
    A[2, 0], A[2, 1], A[2, 2], A[2, 3] = -kxx, -p.kxy, -dxx, -(p.dxy - 2 * p.kappa * Omega_z)
    A[3, 0], A[3, 1], A[3, 2], A[3, 3] = -p.kxy, -kyy, -(p.dxy + 2 * p.kappa * Omega_z), -dyy
    B = np.zeros((N_STATE, 2))
    B[2:4, 0:2] = p.forcer
    for j, f in ((6, p.ring_frequency_1), (8, p.ring_frequency_2)):
        A[j, j + 1], A[j + 1, j] = -2 * math.pi * f, 2 * math.pi * f
    ring = p.c_ring * p.ring_amplitude
    for i, tau, beta, own, other in _sensing(p):
        if tau > 0.0:
            A[4 + i, i] = 1.0 / tau if beta == 0.0 else own / tau
            A[4 + i, 1 - i] = other / tau
            A[4 + i, 4 + i] = -1.0 / tau
            A[4 + i, 6] = A[4 + i, 8] = ring / tau
    return A, B


def _algebraic_pickoffs(p: ResonatorParameters, M: np.ndarray) -> None:
    """Rows of a zero-lag pick-off (tau = 0): z = q_s, the sensed displacement."""
    for i, tau, beta, own, other in _sensing(p):
        if tau <= 0.0:
            M[4 + i] = M[i] if beta == 0.0 else own * M[i] + other * M[1 - i]


def discretize(p: ResonatorParameters, Omega_z: float, h: float,
               dT: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold step: s(t+h) = Phi s(t) + Gamma V (Van Loan).

    A pick-off with zero lag (tau = 0) has its z set algebraically to q_s.
    """
    A, B = system_matrices(p, Omega_z, dT)
    n = N_STATE
    M = np.zeros((n + 2, n + 2))
    M[:n, :n], M[:n, n:] = A * h, B * h
    E = expm(M)
    Phi, Gamma = E[:n, :n].copy(), E[:n, n:].copy()
    _algebraic_pickoffs(p, Phi)
    _algebraic_pickoffs(p, Gamma)
    for i, tau, *_ in _sensing(p):
        if tau <= 0.0:  # z = q_s + c_ring V_ring, instantaneous
            Phi[4 + i] += p.c_ring * p.ring_amplitude * (Phi[6] + Phi[8])
    return Phi, Gamma


def _velocity_scale(p: ResonatorParameters) -> np.ndarray:
    return np.array([1.0, 1.0, 1.0 / p.omega_x, 1.0 / p.omega_x, 1.0, 1.0])


def force_noise_covariance(p: ResonatorParameters, Omega_z: float, h: float,
                           dT: float = 0.0) -> np.ndarray:
    """Covariance (6x6) of the increment of (x, y, vx, vy, zx, zy) over h from white
    acceleration of two-sided intensity 2 k_B T D / m_modal, computed with the
    velocities divided by omega_x (noise.white_noise_covariance)."""
    S = _velocity_scale(p)
    A = system_matrices(p, Omega_z, dT)[0][:N_FORCED, :N_FORCED] * S[:, None] / S[None, :]
    _, _, dxx, dyy = at_temperature(p, dT)
    Qc = np.zeros((N_FORCED, N_FORCED))
    Qc[2:4, 2:4] = np.array([[dxx, p.dxy], [p.dxy, dyy]]) * (
        2.0 * K_B * (p.temperature + dT) / p.m_modal / p.omega_x**2)
    Q = white_noise_covariance(A, Qc, h)
    return Q / S[:, None] / S[None, :]


def force_noise_input(p: ResonatorParameters, Omega_z: float, h: float,
                      dT: float = 0.0) -> np.ndarray:
    """L (10 x 6): the force noise's increment over h is L w, w standard normal; L L' is
    force_noise_covariance (factored with velocities / omega_x, so the positions keep
    their precision); a zero-lag pick-off copies its q_s rows."""
    L, S = np.zeros((N_STATE, N_FORCED)), _velocity_scale(p)
    lam, U = np.linalg.eigh(force_noise_covariance(p, Omega_z, h, dT) * np.outer(S, S))
    L[:N_FORCED] = (U * np.sqrt(np.clip(lam, 0.0, None))) / S[:, None]
    _algebraic_pickoffs(p, L)
    return L


@njit(cache=True)
def _linear(Phi, Gamma, s, V, s_new):  # pragma: no cover
    n = s.size
    for i in range(n):
        acc = Gamma[i, 0] * V[0] + Gamma[i, 1] * V[1]
        for j in range(n):
            acc += Phi[i, j] * s[j]
        s_new[i] = acc
    for i in range(n):
        s[i] = s_new[i]


@njit(cache=True)
def resonator_step(Phi, Gamma, s, V, gains, E, noise, out, cubic, nsub, h,
                   L, w, drive_std):  # pragma: no cover
    """Advance s in place over one held step h and write the pick-off voltages to out.

    gains = (Px, Py); E = feed-through (2x2) of the held V = (Vx, Vy); noise = 2 samples.
    cubic = (k3x, k3y, k3xy, k3yx): if all are 0, Phi, Gamma are the exact step over h;
    otherwise over h / (2 nsub), and the step is nsub Strang splittings around cubic
    kicks. w = 8 standard normals: L w[:6] is the force noise's increment over h (L of
    zero size: none), drive_std w[6:8] the drive voltages' noise held over the step.
    """
    s_new = np.empty(s.size)
    if drive_std != 0.0:
        V = np.array([V[0] + drive_std * w[6], V[1] + drive_std * w[7]])
    if cubic[0] == 0.0 and cubic[1] == 0.0 and cubic[2] == 0.0 and cubic[3] == 0.0:
        _linear(Phi, Gamma, s, V, s_new)
    else:
        dt = h / nsub
        for _ in range(nsub):
            _linear(Phi, Gamma, s, V, s_new)
            x, y = s[0], s[1]
            s[2] -= (cubic[0] * x**3 + cubic[2] * y**3) * dt
            s[3] -= (cubic[1] * y**3 + cubic[3] * x**3) * dt
            _linear(Phi, Gamma, s, V, s_new)
    if L.shape[0] > 0:
        for i in range(L.shape[0]):
            acc = 0.0
            for j in range(L.shape[1]):
                acc += L[i, j] * w[j]
            s[i] += acc
    for i in range(2):
        out[i] = gains[i] * s[4 + i] + E[i, 0] * V[0] + E[i, 1] * V[1] + noise[i]


_BLAS: list = []


def _one_blas_thread():  # a ramp's many 12x12 expm: 0.02 ms on one thread, 0.4-5 on two
    if not _BLAS:
        from threadpoolctl import ThreadpoolController

        _BLAS.append(ThreadpoolController())
    return _BLAS[0].limit(limits=1, user_api="blas")


class ResonatorModel:
    """The resonator as a stepping model: what GyroResonator.fmu wraps."""

    def __init__(self, p: ResonatorParameters, seed: int = 0,
                 initial_state: np.ndarray | None = None) -> None:
        problems = check_resonator(p)
        if problems:
            raise ResonatorError("; ".join(problems))
        self.p = p
        if initial_state is None:
            self.s = np.zeros(N_STATE)
            self.s[6] = self.s[8] = 1.0  # ring tones: cos at t = 0
        else:
            self.s = np.array(initial_state, float)
        self.gains = np.array([p.Px, p.Py])
        self.cubic = np.array([p.k3x, p.k3y, p.k3xy, p.k3yx])
        self.nsub = int(p.cubic_substeps)
        self.E = p.feedthrough
        self.noise = NoiseStream(p.noise, seed)
        #: force and drive noise: 6 + 2 normals per step, its own generator
        self.extra = NoiseStream(1.0 if p.m_modal > 0.0 or p.drive_noise > 0.0 else 0.0,
                                 seed, width=N_FORCED + 2, stream=1)
        self.extra.prime()
        self.ramp = p.temperature_rate != 0.0
        self.k = 0  #: steps taken (the temperature ramp's clock)
        self._key: tuple | None = None
        self.out = np.zeros(2)
        ring = p.c_ring * p.ring_amplitude * (self.s[6] + self.s[8])
        z = self.s[:, None].copy()
        _algebraic_pickoffs(p, z)  # a zero-lag pick-off: z = q_s + the ring voltage
        z0 = z[4:6, 0] + np.array([0.0 if tau > 0 else ring for tau in (p.tau_x, p.tau_y)])
        self.out[:] = self.gains * z0 + self.noise.take(1)[0]

    def steps_left(self) -> int:
        """Steps until the temperature ramp changes the step matrices (or a large n)."""
        N = int(self.p.thermal_update_steps)
        return N - self.k % N if self.ramp else 1 << 62

    def temperature_offset(self, h: float) -> float:
        """K from the start temperature of the middle of the current thermal interval."""
        N = int(self.p.thermal_update_steps)
        return self.p.temperature_rate * ((self.k // N) * N + N / 2) * h if self.ramp else 0.0

    def matrices(self, Omega_z: float, h: float) -> tuple[np.ndarray, np.ndarray]:
        """Phi, Gamma over h, or over h / (2 nsub) with cubic stiffness; self.L, the
        force noise's input over h (zero size without force noise), is set alongside."""
        dT = self.temperature_offset(h)
        if self._key != (Omega_z, h, dT):
            linear = not self.cubic.any()
            with _one_blas_thread() if self.ramp else contextlib.nullcontext():
                self._Phi, self._Gamma = discretize(
                    self.p, Omega_z, h if linear else h / (2 * self.nsub), dT)
                self.L = (force_noise_input(self.p, Omega_z, h, dT) if self.p.m_modal > 0.0
                          else np.zeros((0, N_FORCED)))
            self._key = (Omega_z, h, dT)
        return self._Phi, self._Gamma

    def step(self, V: np.ndarray, Omega_z: float, h: float) -> np.ndarray:
        """Hold V = (Vx, Vy) over h; returns (V_px, V_py) at the end."""
        Phi, Gamma = self.matrices(Omega_z, h)
        resonator_step(Phi, Gamma, self.s, V, self.gains, self.E, self.noise.take(1)[0],
                       self.out, self.cubic, self.nsub, h, self.L, self.extra.take(1)[0],
                       self.p.drive_noise)
        self.k += 1
        return self.out

    def get_state(self) -> dict:
        return {"s": self.s.tolist(), "out": self.out.tolist(), "noise": self.noise.get_state(),
                "extra": self.extra.get_state(), "k": self.k}

    def set_state(self, state: dict) -> None:
        self.s[:] = state["s"]
        self.out[:] = state["out"]
        self.noise.set_state(state["noise"])
        self.extra.set_state(state["extra"])
        self.k = int(state["k"])
