"""The resonator of US 9,482,553 (eq. 1): two lightly coupled modes, voltages in and out.

Per unit modal mass, with q = (x, y):

    x'' + dxx x' + (dxy - 2 kappa Omega_z) y' + kxx x + kxy y = fx
    y'' + dyy y' + (dxy + 2 kappa Omega_z) x' + kyy y + kxy x = fy
    fx = Bx (Vx + alpha_y Vy),   fy = By (Vy + alpha_x Vx)

kappa is the Bryant factor (Coriolis mass over modal mass, 0.8 for an n = 2 ring);
alpha_x, alpha_y are the forcer misalignments (coupling of the x forcer into y and of
the y forcer into x). Each pick-off has gain P and electronics modelled by a first-order
lag tau whose phase at the mode frequency is phi (tan phi = omega tau): its voltage is
V_p = P z, tau z' = q - z + c_ring V_ring, plus feed-through E V of the drive
voltages and white noise. V_ring = ring_amplitude (cos w1 t + cos w2 t) excites the
pick-offs electrically without moving the ring (the seed's off-resonant ring
excitation that reveals the relative pick-off phase). It is generated inside the
resonator (two oscillator states) because a held, staircase ring voltage would pass
the fast pick-off lags unseen at the sampling instants.

Optional cubic stiffness (eqs. 20-21): k3x x^3 and k3y y^3 add to the restoring
forces. Without it each step is the exact held-input solution (one matrix
exponential); with it the step is split symmetrically (Strang): exact linear flow over
h/2n, a cubic velocity kick over h/n, exact linear flow over h/2n, n times. The
splitting is time-reversible, so it adds no artificial damping, and its error is
second order in h/n on the (small) cubic force alone. Cross-cubic terms (eqs. 22-23)
are not modelled.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace

import numpy as np
from numba import njit
from scipy.linalg import expm

from ..errors import GyroFmuError

#: Order of the resonator's state vector.
STATE = ("x", "y", "vx", "vy", "zx", "zy", "ring1_cos", "ring1_sin", "ring2_cos", "ring2_sin")
#: Order of its held inputs.
INPUTS = ("Vx", "Vy")
N_STATE = len(STATE)
#: Earth's rotation rate, rad/s.
EARTH_RATE = 7.2921150e-5


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
        return replace(
            self, f_x=self.f_x + delta_f, f_y=self.f_y + delta_f,
            Q_x=self.Q_x * (self.f_x + delta_f) / self.f_x / damping_factor,
            Q_y=self.Q_y * (self.f_y + delta_f) / self.f_y / damping_factor,
            dxy=self.dxy * damping_factor,
        )

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
    if p.cubic_substeps < 1:
        problems.append(f"cubic_substeps={p.cubic_substeps!r} must be >= 1")
    if p.noise < 0.0:
        problems.append(f"noise={p.noise!r} V must be >= 0")
    if not problems and p.kxy**2 >= p.kxx * p.kyy:
        problems.append(
            f"kxy={p.kxy!r} 1/s^2 makes the stiffness indefinite (kxy^2 >= kxx kyy): "
            "use |kxy| well below the mode stiffnesses"
        )
    return problems


def system_matrices(p: ResonatorParameters, Omega_z: float) -> tuple[np.ndarray, np.ndarray]:
    """Continuous A (10x10) and B (10x2) of the resonator, pick-off lags and ring tones."""
    A = np.zeros((N_STATE, N_STATE))
    A[0, 2] = A[1, 3] = 1.0
    A[2, 0], A[2, 1], A[2, 2], A[2, 3] = -p.kxx, -p.kxy, -p.dxx, -(p.dxy - 2 * p.kappa * Omega_z)
    A[3, 0], A[3, 1], A[3, 2], A[3, 3] = -p.kxy, -p.kyy, -(p.dxy + 2 * p.kappa * Omega_z), -p.dyy
    B = np.zeros((N_STATE, 2))
    B[2:4, 0:2] = p.forcer
    for j, f in ((6, p.ring_frequency_1), (8, p.ring_frequency_2)):
        A[j, j + 1], A[j + 1, j] = -2 * math.pi * f, 2 * math.pi * f
    ring = p.c_ring * p.ring_amplitude
    for i, tau in ((0, p.tau_x), (1, p.tau_y)):
        if tau > 0.0:
            A[4 + i, i] = 1.0 / tau
            A[4 + i, 4 + i] = -1.0 / tau
            A[4 + i, 6] = A[4 + i, 8] = ring / tau
    return A, B


def discretize(p: ResonatorParameters, Omega_z: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold step: s(t+h) = Phi s(t) + Gamma V (Van Loan).

    A pick-off with zero lag (tau = 0) has its z set algebraically to q.
    """
    A, B = system_matrices(p, Omega_z)
    n = N_STATE
    M = np.zeros((n + 2, n + 2))
    M[:n, :n], M[:n, n:] = A * h, B * h
    E = expm(M)
    Phi, Gamma = E[:n, :n].copy(), E[:n, n:].copy()
    for i, tau in ((0, p.tau_x), (1, p.tau_y)):
        if tau <= 0.0:  # z = q + c_ring V_ring, instantaneous
            Phi[4 + i] = Phi[i]
            Phi[4 + i] += p.c_ring * p.ring_amplitude * (Phi[6] + Phi[8])
            Gamma[4 + i] = Gamma[i]
    return Phi, Gamma


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
def resonator_step(Phi, Gamma, s, V, gains, E, noise, out, cubic, nsub, h):  # pragma: no cover
    """Advance s in place over one held step h and write the pick-off voltages to out.

    gains = (Px, Py); E = feed-through (2x2) of the held V = (Vx, Vy); noise = 2 samples.
    cubic = (k3x, k3y): if both are 0, Phi, Gamma are the exact step over h; otherwise
    over h / (2 nsub), and the step is nsub Strang splittings around cubic kicks.
    """
    s_new = np.empty(s.size)
    if cubic[0] == 0.0 and cubic[1] == 0.0:
        _linear(Phi, Gamma, s, V, s_new)
    else:
        dt = h / nsub
        for _ in range(nsub):
            _linear(Phi, Gamma, s, V, s_new)
            s[2] -= cubic[0] * s[0] ** 3 * dt
            s[3] -= cubic[1] * s[1] ** 3 * dt
            _linear(Phi, Gamma, s, V, s_new)
    for i in range(2):
        out[i] = gains[i] * s[4 + i] + E[i, 0] * V[0] + E[i, 1] * V[1] + noise[i]


class NoiseStream:
    """Seeded pick-off noise drawn in blocks: the same sequence however it is consumed,
    so an FMU drawing one sample pair per step equals an in-process run."""

    BLOCK = 4096

    def __init__(self, std: float, seed: int) -> None:
        self.std = std
        self.rng = np.random.Generator(np.random.PCG64(seed))
        self.block = np.zeros((0, 2))
        self.pos = 0

    def take(self, n: int) -> np.ndarray:
        """The next n sample pairs (n x 2)."""
        if self.std == 0.0:
            return np.zeros((n, 2))
        out = np.empty((n, 2))
        filled = 0
        while filled < n:
            if self.pos == len(self.block):
                self.block = self.rng.standard_normal((self.BLOCK, 2)) * self.std
                self.pos = 0
            k = min(n - filled, len(self.block) - self.pos)
            out[filled:filled + k] = self.block[self.pos:self.pos + k]
            filled += k
            self.pos += k
        return out

    def get_state(self) -> dict:
        return {"rng": self.rng.bit_generator.state, "block": self.block.tolist(),
                "pos": self.pos}

    def set_state(self, state: dict) -> None:
        self.rng.bit_generator.state = state["rng"]
        self.block = np.array(state["block"], dtype=float).reshape(-1, 2)
        self.pos = int(state["pos"])


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
        self.cubic = np.array([p.k3x, p.k3y])
        self.nsub = int(p.cubic_substeps)
        self.E = p.feedthrough
        self.noise = NoiseStream(p.noise, seed)
        self._key: tuple[float, float] | None = None
        self.out = np.zeros(2)
        ring = p.c_ring * p.ring_amplitude * (self.s[6] + self.s[8])
        z0 = [self.s[4 + i] if tau > 0 else self.s[i] + ring
              for i, tau in enumerate((p.tau_x, p.tau_y))]
        self.out[:] = self.gains * np.array(z0) + self.noise.take(1)[0]

    def matrices(self, Omega_z: float, h: float) -> tuple[np.ndarray, np.ndarray]:
        """Phi, Gamma over h, or over h / (2 nsub) with cubic stiffness."""
        if self._key != (Omega_z, h):
            linear = self.cubic[0] == 0.0 and self.cubic[1] == 0.0
            self._Phi, self._Gamma = discretize(
                self.p, Omega_z, h if linear else h / (2 * self.nsub))
            self._key = (Omega_z, h)
        return self._Phi, self._Gamma

    def step(self, V: np.ndarray, Omega_z: float, h: float) -> np.ndarray:
        """Hold V = (Vx, Vy) over h; returns (V_px, V_py) at the end."""
        Phi, Gamma = self.matrices(Omega_z, h)
        resonator_step(Phi, Gamma, self.s, V, self.gains, self.E, self.noise.take(1)[0],
                       self.out, self.cubic, self.nsub, h)
        return self.out

    def get_state(self) -> dict:
        return {"s": self.s.tolist(), "out": self.out.tolist(), "noise": self.noise.get_state()}

    def set_state(self, state: dict) -> None:
        self.s[:] = state["s"]
        self.out[:] = state["out"]
        self.noise.set_state(state["noise"])
