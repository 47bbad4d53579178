"""The frequency-domain estimator of US 9,482,553 (eqs. 15-19) and the rate read-out (eq. 8).

In each mode the drive phasors D = (Vx, Vy) and the feed-forward-corrected pick-off
phasors PO = (Vpx, Vpy) at the carrier and its sidebands obey PO = H(omega) D, with

    H(omega) = diag(1, rho) M(omega)^-1 B zoh(omega) + E_res exp(-i omega h)
    M(omega) = K - omega^2 I + i omega (D + 2 kappa Omega_z J),  J = [[0, -1], [1, 0]]

(eq. 1 in the frequency domain). rho = relative pick-off gain and phase (measured with
the ring excitation, eq. 4's relative angle), B = forcer gains and misalignments times
the x pick-off gain (complex: electronics phases), C = [[1, beta_s], [beta_s, 1]] the
pick-offs' non-orthogonality (H = diag(1, rho) C M^-1 B ...), zoh = the hold's transfer, E_res =
feed-through left after the correction. The fit minimises J of eq. 19,
sum over modes and frequencies of |PO_measured - H D_measured|^2, with
scipy.optimize.least_squares; stiffnesses enter as the mode frequencies.

The rate read-out then follows from the fitted H alone: with the primary pick-off held
at amplitude A on the reference phase and the secondary nulled, the rebalance command
is u = A (H^-1)_21 exp(-i omega h / 2) and the rate output is Im(u) (eq. 8), affine in
Omega_z: its slope is the scale factor, its value at zero the bias. The Bryant factor
kappa is the one number taken from the factory (seed: assumed constant after it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares, nnls

#: Names of the fitted parameters, in vector order (SI: rad/s, 1/s, V/V).
CORE = ("dw_x", "dw_y", "dxx", "dyy", "dxy", "kxy_over_w", "Omega_z")
FORCER = ("B_xx", "B_xy", "B_yx", "B_yy")
#: The pick-offs' non-orthogonality (beta_x + beta_y) / 2, rad: each pick-off also
#: senses the other axis, x_s = x + beta_s y, y_s = y + beta_s x. Their common rotation
#: (beta_x = -beta_y) is absorbed by the other parameters (it rotates K and D, which
#: stay symmetric, and leaves J alone); this part is not.
PICKOFF = ("beta_s",)
#: Cubic stiffness at the operating amplitude a, eqs. 20-23 linearized about the carrier
#: (eqs. 24-27), 1/s^2: mode 1 auto (k3x) and cross (k3yx, x^3 in the y equation),
#: mode 2 auto (k3y) and cross (k3xy); gamma = (3/4) k3 |q0|^2 in the fit's units.
CUBIC = ("gamma_x1", "gamma_yx1", "gamma_y2", "gamma_xy2")
#: Slots of x.
I_BETA = 15
I_CUBIC = slice(16, 20)
I_FEEDTHROUGH = slice(20, 28)
RESIDUAL_FEEDTHROUGH = ("E_xx", "E_xy", "E_yx", "E_yy")
#: The name of each slot of x (complex gains as real and imaginary parts, _complex4).
SLOT_NAMES = (CORE + tuple(f"{p}.{c}" for p in FORCER for c in ("re", "im")) + PICKOFF
              + CUBIC + tuple(f"{p}.{c}" for p in RESIDUAL_FEEDTHROUGH for c in ("re", "im")))


@dataclass
class ModeData:
    """Phasors of one mode's sideband record."""

    mode: int
    omega: np.ndarray  #: rad/s, absolute frequency of each phasor
    D: np.ndarray  #: (n, 2) complex drive phasors (Vx, Vy), V
    PO: np.ndarray  #: (n, 2) complex corrected pick-off phasors (Vpx, Vpy), V
    omega_osc: float  #: rad/s, mean oscillation frequency
    amplitude: float  #: V, primary pick-off amplitude
    t_center: float = 0.0  #: s, the record's middle on the sequence's clock
    #: 1/s, relative drift of the carrier over the record, d(omega_osc)/dt / omega_osc
    #: (the temperature moving: tc_f dT/dt)
    drift: float = 0.0
    #: frequency scale of this record against the first: the resonator's f_x and f_y in
    #: this record are (1 + shift) times the fitted ones (the temperature moved between
    #: the records; phasors.carrier_shifts)
    shift: float = 0.0
    sigma_shift: float = 0.0  #: uncertainty of shift (the drift's change between records)
    #: rad/s, the FFT bins between the grid's tones (phasors.off_grid), and the drive
    #: and corrected pick-off content there (k x 2 each, rectangular phasors): noise
    off_omega: np.ndarray = field(default_factory=lambda: np.zeros(0))
    off_D: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), complex))
    off_PO: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), complex))


@dataclass
class SidebandFit:
    """The fitted model and its uncertainty."""

    x: np.ndarray
    cov: np.ndarray
    omega_ref: float
    rho: complex
    kappa: float
    h: float
    fit_feedthrough: bool
    rms_residual: float
    names: tuple[str, ...] = field(default=())
    #: smallest / largest singular value of the column-normalized Jacobian at the optimum
    #: (near 0: a direction of the parameters the records do not determine)
    conditioning: float = 1.0
    #: the fitted parameters that make up that direction, largest share first
    weakest: tuple[str, ...] = field(default=())
    noise: NoiseModel | None = None  #: the residuals' variance the fit was weighted by
    #: sqrt(chi^2 / dof) of the weighted fit: near 1 when the model and the noise model
    #: hold (nan for an unweighted fit)
    misfit: float = math.nan

    def sigma(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.cov), 0.0, None))

    def physical(self) -> dict[str, float]:
        """Mode frequencies (Hz), dampings (1/s), kxy (1/s^2), Omega_z (rad/s)."""
        x, s = self.x, self.sigma()
        w = self.omega_ref
        out = {
            "f_x": (w + x[0]) / (2 * math.pi), "f_y": (w + x[1]) / (2 * math.pi),
            "dxx": x[2], "dyy": x[3], "dxy": x[4], "kxy": x[5] * w, "Omega_z": x[6],
        }
        sig = {"f_x": s[0] / (2 * math.pi), "f_y": s[1] / (2 * math.pi), "dxx": s[2],
               "dyy": s[3], "dxy": s[4], "kxy": s[5] * w, "Omega_z": s[6]}
        return {**out, **{f"sigma_{k}": v for k, v in sig.items()}}


def zoh(omega: np.ndarray, h: float) -> np.ndarray:
    """Transfer of a held sample to the fundamental, relative to the hold's start."""
    x = omega * h
    return (1.0 - np.exp(-1j * x)) / (1j * x)


def _complex4(v: np.ndarray) -> np.ndarray:
    return (v[0::2] + 1j * v[1::2]).reshape(2, 2)


def _dynamics(x: np.ndarray, omega: np.ndarray, omega_ref: float, kappa: float,
              Omega_z: float | None = None, shift: float = 0.0) -> np.ndarray:
    """M(omega) (n x 2 x 2) of eq. 1, the linear part; Omega_z overrides the fitted rate;
    shift scales both mode frequencies by 1 + shift (a record at another temperature;
    the dampings are held: a tc_Q is not modelled, docs/self-calibration.md)."""
    wx, wy = (omega_ref + x[0]) * (1.0 + shift), (omega_ref + x[1]) * (1.0 + shift)
    dxx, dyy, dxy, kxy = x[2], x[3], x[4], x[5] * omega_ref
    Om = x[6] if Omega_z is None else Omega_z
    iw = 1j * omega
    M = np.empty((len(omega), 2, 2), complex)
    M[:, 0, 0] = (wx - omega) * (wx + omega) + iw * dxx
    M[:, 1, 1] = (wy - omega) * (wy + omega) + iw * dyy
    M[:, 0, 1] = kxy + iw * (dxy - 2 * kappa * Om)
    M[:, 1, 0] = kxy + iw * (dxy + 2 * kappa * Om)
    return M


def cubic_terms(x: np.ndarray, mode: int) -> tuple[float, float]:
    """(auto, cross) cubic stiffness of mode 1 or 2's primary displacement, 1/s^2 (CUBIC)."""
    auto, cross = x[I_CUBIC][0:2] if mode == 1 else x[I_CUBIC][2:4]
    return float(auto), float(cross)


def _cubic(x: np.ndarray, mode: int) -> np.ndarray:
    """Gamma (2 x 2): the cubic terms of the primary axis' displacement in each equation
    (auto on the diagonal, cross in the secondary's row) for mode 1 or 2."""
    g = np.zeros((2, 2))
    p, s = (0, 1) if mode == 1 else (1, 0)
    g[p, p], g[s, p] = cubic_terms(x, mode)
    return g


def _sense(v: np.ndarray, x: np.ndarray, rho: complex) -> np.ndarray:
    """C then diag(1, rho) on axis 1 of v (phasors n x 2, or transfers n x 2 x 2)."""
    v = v + x[I_BETA] * v[:, ::-1]  # C v: each sensed axis picks up beta of the other
    v[:, 1] *= rho
    return v


def _read(q: np.ndarray, D: np.ndarray, omega: np.ndarray, x: np.ndarray, rho: complex,
          h: float, fit_feedthrough: bool) -> np.ndarray:
    """Pick-off phasors (n x 2) from the model displacements q (n x 2): C, rho, E_res."""
    q = _sense(q, x, rho)
    if fit_feedthrough:
        E = _complex4(x[I_FEEDTHROUGH]) * 1e-3
        q = q + np.einsum("ij,nj->ni", E, D) * np.exp(-1j * omega * h)[:, None]
    return q


def transfer(x: np.ndarray, omega: np.ndarray, omega_ref: float, rho: complex, kappa: float,
             h: float, fit_feedthrough: bool, Omega_z: float | None = None,
             carrier_cubic: np.ndarray | None = None) -> np.ndarray:
    """H(omega) (n x 2 x 2) of the linear model for parameter vector x; Omega_z overrides
    the fitted rate; carrier_cubic (Gamma of _cubic) adds the cubic stiffness a steady
    carrier sees (eq. 24's |q0|^2 q0 term)."""
    M = _dynamics(x, omega, omega_ref, kappa, Omega_z)
    if carrier_cubic is not None:
        M = M + carrier_cubic[None]
    B = _complex4(x[7:15]) * (2 * omega_ref)
    G = np.linalg.solve(M, np.broadcast_to(B, M.shape)) * zoh(omega, h)[:, None, None]
    G = _sense(G, x, rho)
    if fit_feedthrough:
        E = _complex4(x[I_FEEDTHROUGH]) * 1e-3
        G += E[None] * np.exp(-1j * omega * h)[:, None, None]
    return G


def predicted_pickoffs(x: np.ndarray, md: ModeData, omega_ref: float, rho: complex,
                       kappa: float, h: float, fit_feedthrough: bool) -> np.ndarray:
    """The model's pick-off phasors (n x 2) for the record's drive phasors md.D.

    Cubic stiffness (eqs. 20-23, the seed's sideband terms eqs. 24-27): the primary's
    k3 x^3 has, at harmonic m of the grid, the phasor (3/4) k3 sum_{j+k-l=m} X_j X_k
    conj(X_l). Its linear part, 2 |X0|^2 X_m + X0^2 conj(X_-m), couples each sideband
    to its mirror; its products of sidebands are 8 % of it with the default 7 tones of
    index 0.04 (measured: the linear part alone left 8 % of the misfit). The sum is
    taken whole, from the measured primary pick-off (cubic_phasors), and the model
    solves M_m q_m = B D_m zoh_m - Gamma[:, p] W_m, the cubic coefficients Gamma scaled
    so that a steady carrier sees Gamma q0 (transfer's carrier_cubic).
    """
    M = _dynamics(x, md.omega, omega_ref, kappa, shift=md.shift)
    B = _complex4(x[7:15]) * (2 * omega_ref)
    F = np.einsum("ij,nj->ni", B, md.D) * zoh(md.omega, h)[:, None]
    g = _cubic(x, md.mode) if md.mode in (1, 2) else np.zeros((2, 2))
    if g.any():
        p = 0 if md.mode == 1 else 1
        F = F - np.outer(cubic_phasors(md, rho), g[:, p])
    q = np.linalg.solve(M, F[..., None])[..., 0]
    return _read(q, md.D, md.omega, x, rho, h, fit_feedthrough)


def cubic_phasors(md: ModeData, rho: complex) -> np.ndarray:
    """sum_{j+k-l=m} q_j q_k conj(q_l) / |q0|^2 over the harmonic grid, q the measured
    primary displacement in the fit's units (x pick-off volts: PO_x, or PO_y / rho)."""
    q = md.PO[:, 0] if md.mode == 1 else md.PO[:, 1] / rho
    n = len(q)
    c = n // 2  # the grid is symmetric about the carrier
    w = np.convolve(np.convolve(q, q), np.conj(q[::-1]))  # harmonics -3c..3c
    return w[2 * c: 2 * c + n] / abs(q[c]) ** 2


def _residuals(free, x_full, mask, modes, omega_ref, rho, kappa, h, fit_ff, scale=None):
    """Real and imaginary parts of PO - H D over every record, bin and channel, each
    divided by its noise's standard deviation per component when scale is given."""
    x = x_full.copy()
    x[mask] = free
    out = []
    for md in modes:
        r = md.PO - predicted_pickoffs(x, md, omega_ref, rho, kappa, h, fit_ff)
        out.append(r.ravel())
    r = np.concatenate(out)
    if scale is not None:
        r = r / scale
    return np.concatenate([r.real, r.imag])


def force_gains(x: np.ndarray, modes: list[ModeData], omega_ref: float, rho: complex,
                kappa: float) -> np.ndarray:
    """|C M^-1|^2 of each record, bin and channel for a force on x and on y (n x 2), in
    the order of _residuals: how a white force noise reaches each residual of eq. 19.
    The residual PO - H D is the force noise through the open-loop plant plus the
    pick-off noise, whatever the loops fed back into D (D is the drive applied)."""
    out = []
    for md in modes:
        M = _dynamics(x, md.omega, omega_ref, kappa, shift=md.shift)
        G = _sense(np.linalg.inv(M), x, rho)  # n x 2 (channel) x 2 (force axis)
        out.append(np.abs(G.reshape(-1, 2)) ** 2)
    return np.concatenate(out)


@dataclass
class NoiseModel:
    """The variance of each residual of eq. 19 (one complex phasor of one record's bin
    and channel): white pick-off noise, a white force on each axis through the
    open-loop plant, and a model-error floor,

        v = white[record, channel] + sum_k |C M^-1|^2_k force[k] + floor^2   (V^2).

    white comes from each record's spectrum above the carrier (alarms.pickoff_noise),
    floor is fixed, force (thermomechanical and drive noise, in the fit's units) is
    measured between the grid's tones (off_grid_force_noise), never from the residuals
    it judges: a model error left at the tones stays visible in the misfit."""

    white: np.ndarray  #: (records, 2) V^2, phasor variance of each pick-off's white noise
    floor: float  #: V, model-error floor of a noise-free fit
    force: np.ndarray = field(default_factory=lambda: np.zeros(2))  #: measured, per axis
    measured: bool = False  #: force has been measured (a refit keeps it)

    def variance(self, gains: np.ndarray, n_bins: list[int]) -> np.ndarray:
        white = np.concatenate([np.tile(w, n) for w, n in zip(self.white, n_bins,
                                                              strict=True)])
        return white + gains @ self.force + self.floor**2


#: E|c|^2 of a Hann phasor on the grid over E|2 Y / n|^2 of a rectangular FFT bin for
#: the same locally white noise (6 s^2 / n against 4 s^2 / n; phasors.off_grid)
HANN_OVER_RECT = 1.5


def off_grid_force_noise(x: np.ndarray, modes: list[ModeData], omega_ref: float,
                         rho: complex, kappa: float, h: float, fit_feedthrough: bool,
                         noise: NoiseModel) -> np.ndarray:
    """Force noise (2,) >= 0 from the eq. 19 residual between the grid's tones
    (ModeData.off_*: noise only), PO - H D with H of x, whose variance the NoiseModel
    predicts; iteratively reweighted non-negative least squares on |r|^2 (exponential:
    its spread is its mean). Records without such bins (one FFT bin per grid step)
    add nothing; with none at all the force is 0."""
    rows, power, whites = [], [], []
    for i, md in enumerate(modes):
        if md.off_omega.size == 0:
            continue
        off = ModeData(0, md.off_omega, md.off_D, md.off_PO, md.omega_osc, md.amplitude,
                       shift=md.shift)
        r = off.PO - predicted_pickoffs(x, off, omega_ref, rho, kappa, h, fit_feedthrough)
        rows.append(force_gains(x, [off], omega_ref, rho, kappa))
        power.append(HANN_OVER_RECT * np.abs(r.ravel()) ** 2)
        whites.append(np.tile(noise.white[i], md.off_omega.size))
    if not rows:
        return np.zeros(2)
    A, white = np.concatenate(rows), np.concatenate(whites)
    y = np.concatenate(power) - white
    force = np.zeros(2)
    for _ in range(4):
        spread = white + A @ force + noise.floor**2
        force, _ = nnls(A / spread[:, None], y / spread)
    return force


def initial_guess(modes: list[ModeData], plant_gain: float, q_nominal: float,
                  fit_feedthrough: bool) -> tuple[float, np.ndarray]:
    """Rough start (seed: dampings and forcer gains, the rest zero): each mode's
    frequency from its oscillation, dampings from the nominal Q, B diagonal from the
    nominal P B / (2 omega)."""
    by_mode = {md.mode: md for md in modes}
    w1 = by_mode[1].omega_osc if 1 in by_mode else modes[0].omega_osc
    w2 = by_mode[2].omega_osc / (1.0 + by_mode[2].shift) if 2 in by_mode else w1
    d = w1 / q_nominal
    x = np.zeros(28 if fit_feedthrough else 20)
    x[0], x[1], x[2], x[3] = 0.0, w2 - w1, d, d
    x[7] = x[13] = plant_gain
    return w1, x


def fit_sidebands(modes: list[ModeData], rho: complex, kappa: float, h: float,
                  plant_gain: float, q_nominal: float, fit_feedthrough: bool = True,
                  fixed_rate: float | None = None, cubic: bool = False,
                  noise: NoiseModel | None = None) -> SidebandFit:
    """Minimise eq. 19 over the parameters; covariance from the Jacobian at the optimum.

    fixed_rate: hold Omega_z at this value instead of fitting it (what a calibration
    without mode reversal must assume; the earth-rate study uses it).
    cubic: also fit the cubic terms at the operating amplitude (CUBIC); otherwise they
    are held at 0 (the seed: "if the hardware indicates their inclusion").
    noise: weight each residual by its variance (NoiseModel; its force noise measured
    between the tones with the model of the fit before, twice); the misfit is then
    sqrt(chi^2 / dof) of the weighted fit. A noise model already measured (a refit:
    fit.noise) is used as given. Without one, the fit is unweighted.
    """
    omega_ref, x0 = initial_guess(modes, plant_gain, q_nominal, fit_feedthrough)
    mask = np.ones(x0.size, bool)
    present = {md.mode for md in modes}
    mask[I_CUBIC] = [cubic and 1 in present, cubic and 1 in present,
                     cubic and 2 in present, cubic and 2 in present]
    if fixed_rate is not None:
        x0[6] = fixed_rate
        mask[6] = False
    n_bins = [len(md.omega) for md in modes]  # bins of each record (2 channels each)
    args = (x0, mask, modes, omega_ref, rho, kappa, h, fit_feedthrough)

    def solve(start: np.ndarray, scale: np.ndarray | None):
        return least_squares(_residuals, start, args=(*args, scale), method="lm",
                             x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15,
                             max_nfev=20000)

    res = solve(x0[mask], None)
    scale = None
    for _ in range(2 if noise is not None else 0):
        x = x0.copy()
        x[mask] = res.x
        measure = not noise.measured
        if measure:  # from the fit before (the unweighted one first)
            noise = replace(noise, force=off_grid_force_noise(
                x, modes, omega_ref, rho, kappa, h, fit_feedthrough, noise), measured=True)
        gains = force_gains(x, modes, omega_ref, rho, kappa)
        scale = np.sqrt(0.5 * noise.variance(gains, n_bins))
        res = solve(res.x, scale)
        if not measure:
            break
    n, p = res.fun.size, res.x.size
    s2 = float(res.fun @ res.fun) / max(n - p, 1)
    cov = np.zeros((x0.size, x0.size))
    cov[np.ix_(mask, mask)] = s2 * np.linalg.pinv(res.jac.T @ res.jac)
    x = x0.copy()
    x[mask] = res.x
    unweighted = res.fun if scale is None else res.fun * np.concatenate([scale, scale])
    rms = math.sqrt(float(unweighted @ unweighted) / max(n - p, 1))
    names = CORE + FORCER + PICKOFF + CUBIC + (RESIDUAL_FEEDTHROUGH if fit_feedthrough else ())
    # pinv above drops a direction the records do not determine, and the sigmas then
    # look small: say how close to singular the fit is, and along what
    norms = np.linalg.norm(res.jac, axis=0)
    _, sv, vt = np.linalg.svd(res.jac / np.where(norms > 0, norms, 1.0), full_matrices=False)
    free = [n for n, m in zip(SLOT_NAMES, mask, strict=True) if m]
    order = np.argsort(-np.abs(vt[-1]))
    weakest = tuple(free[i] for i in order[:2] if i < len(free))
    return SidebandFit(x, cov, omega_ref, rho, kappa, h, fit_feedthrough,
                       rms, names, float(sv[-1] / sv[0]) if sv[0] > 0 else 0.0,
                       weakest, noise, math.sqrt(s2) if noise is not None else math.nan)


def closed_loop_rate(fit: SidebandFit, x: np.ndarray, Omega_z: float, omega_r: float,
                     amplitude: float) -> float:
    """Rate output Im(u) of mode 1 (x oscillates at omega_r, y rebalanced), eq. 8."""
    H = transfer(x, np.array([omega_r]), fit.omega_ref, fit.rho, fit.kappa, fit.h,
                 fit.fit_feedthrough, Omega_z=Omega_z, carrier_cubic=_cubic(x, 1))[0]
    u = amplitude * np.linalg.inv(H)[1, 0] * np.exp(-0.5j * omega_r * fit.h)
    return float(u.imag)


def bias_and_scale_factor(fit: SidebandFit, omega_r: float, amplitude: float,
                          x: np.ndarray | None = None) -> tuple[float, float]:
    """(bias rad/s, scale factor V/(rad/s)) of the mode-1 rate output: out = SF (Omega + bias)."""
    x = fit.x if x is None else x
    d = 0.01
    up = closed_loop_rate(fit, x, d, omega_r, amplitude)
    down = closed_loop_rate(fit, x, -d, omega_r, amplitude)
    zero = closed_loop_rate(fit, x, 0.0, omega_r, amplitude)
    sf = (up - down) / (2 * d)
    return zero / sf, sf


def bias_and_scale_factor_sigma(fit: SidebandFit, omega_r: float,
                                amplitude: float) -> tuple[float, float]:
    """1-sigma of bias and scale factor from the fit's covariance (delta method)."""
    base = np.array(bias_and_scale_factor(fit, omega_r, amplitude))
    grads = np.zeros((2, fit.x.size))
    sig = fit.sigma()
    for i in range(fit.x.size):
        if sig[i] == 0.0:  # held, not fitted
            continue
        step = sig[i] * 1e-3
        x = fit.x.copy()
        x[i] += step
        grads[:, i] = (np.array(bias_and_scale_factor(fit, omega_r, amplitude, x)) - base) / step
    cov = grads @ fit.cov @ grads.T
    return math.sqrt(max(cov[0, 0], 0.0)), math.sqrt(max(cov[1, 1], 0.0))
