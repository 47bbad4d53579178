"""GyroLoops: the closed-loop electronics of US 9,482,553, one sample at a time.

- Oscillator loop (primary axis): a PLL locks the NCO phase theta to the primary
  pick-off (I/Q demodulation, three low-pass sections, PI on the phase error) and the
  drive is regenerated 90 deg ahead of it, -g sin(theta + phi_osc), so the mode runs at
  its resonance; a PI amplitude control (AGC) sets g to hold the pick-off amplitude.
- Sideband excitation: the *position* signal used by the amplitude control is
  amplitude-modulated, (1 + sum_k m sin(2 pi k df t + psi_k)) with Schroeder phases
  (seed: "the position signal rather than the force signal is modulated"), so the
  drive acquires sidebands at k df around the carrier.
- Force rebalance (secondary axis): demodulate, PI-compensate with a -90 deg rotation
  (the resonator's envelope responds to force as -i/(2 omega)), remodulate (eq. 7);
  the in-phase command Im(u) is the rate output, Re(u) the quadrature output.
- Feed-forward removal: the measured feed-through E_hat of the drive voltages is
  subtracted from the pick-offs before anything else (seed: "feed forward errors are
  removed from the position signal rather than from the force rebalance").
- Mode 1: x oscillates, y is rebalanced; mode 2 swaps them (mode reversal);
  mode 0: loops off, off-resonant tones on Vx and Vy (feed-forward measurement; the
  resonator's ring tones, switched on with it, give the relative pick-off phase).

Drive outputs are computed at the middle of the hold interval (theta + omega h / 2),
which removes the zero-order hold's half-sample carrier delay.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from numba import njit

from .resonator import non_finite_fields

#: Outputs of one loops step, in order.
OUTPUTS = ("Vx", "Vy", "theta", "omega", "amplitude", "phase_error", "gain",
           "rate", "quad")
N_STATE = 26


class LoopsError(ValueError):
    """A loop setting is unusable; the message names it and the remedy."""


@dataclass(frozen=True)
class LoopSettings:
    """Electronics settings; tuning uses nominal plant values, not the true ones."""

    mode: int = 1  #: 0 loops off, 1 x oscillator / y rebalanced, 2 reversed
    f_nominal: float = 4000.0  #: Hz, NCO centre frequency
    amplitude: float = 1.0  #: V, primary pick-off amplitude setpoint
    q_nominal: float = 2.0e4  #: nominal Q, for the drive feed-forward
    plant_gain: float = 1.0  #: 1/s, nominal P B / (2 omega) of each axis, for tuning
    pll_bandwidth: float = 20.0  #: Hz
    agc_bandwidth: float = 3.0  #: Hz
    rebalance_bandwidth: float = 100.0  #: Hz
    demod_cutoff: float = 500.0  #: Hz, each of 3 low-pass sections (PLL, AGC)
    rebalance_cutoff: float = 2000.0  #: Hz, each of 2 low-pass sections (rebalance)
    drive_limit: float = 5.0  #: V, largest oscillator drive amplitude
    osc_phase: float = 0.0  #: rad, oscillator loop phase away from 90 deg
    sideband_index: float = 0.0  #: modulation index of each sideband tone
    sideband_spacing: float = 0.1  #: Hz, df
    sideband_first: int = 1  #: first harmonic k of df
    sideband_count: int = 15  #: number of tones
    sideband_start: float = 0.0  #: s, modulation switches on here
    ff_xx: float = 0.0  #: V/V, feed-forward correction of Vx in the x pick-off
    ff_xy: float = 0.0  #: V/V, of Vy in the x pick-off
    ff_yx: float = 0.0  #: V/V, of Vx in the y pick-off
    ff_yy: float = 0.0  #: V/V, of Vy in the y pick-off
    excitation_amplitude: float = 0.2  #: V, mode 0 tones on Vx and Vy
    excitation_offset_x: float = 200.0  #: Hz, Vx tones at f_nominal -/+ this
    excitation_offset_y: float = 230.0  #: Hz, Vy tones

    def problems(self) -> list[str]:
        """Problems (empty when usable), each naming the value and the remedy."""
        out = non_finite_fields(self)
        if out:
            return out
        if self.mode not in (0, 1, 2):
            out.append(f"mode={self.mode!r} must be 0 (off), 1 (x oscillator) or 2 (y)")
        for name in ("f_nominal", "amplitude", "q_nominal", "plant_gain", "pll_bandwidth",
                     "agc_bandwidth", "rebalance_bandwidth", "demod_cutoff",
                     "rebalance_cutoff", "drive_limit", "sideband_spacing"):
            if not getattr(self, name) > 0.0:
                out.append(f"{name}={getattr(self, name)!r} must be > 0")
        if self.sideband_index < 0.0 or self.sideband_count < 0 or self.sideband_first < 0:
            out.append("sideband_index, sideband_count and sideband_first must be >= 0")
        return out

    def as_array(self) -> np.ndarray:
        problems = self.problems()
        if problems:
            raise LoopsError("; ".join(problems))
        w = 2 * math.pi
        c = self.plant_gain
        zeta, wn = 0.7, w * self.agc_bandwidth
        tau = self.q_nominal / (math.pi * self.f_nominal)
        return np.array([
            self.mode, w * self.f_nominal, self.amplitude, self.demod_cutoff,
            self.rebalance_cutoff, w * self.pll_bandwidth, (w * self.pll_bandwidth) ** 2 / 4,
            2 * zeta * wn / c, wn**2 / c, w * self.rebalance_bandwidth / c,
            w * self.rebalance_bandwidth / 5, self.drive_limit, self.osc_phase,
            self.sideband_index, self.sideband_spacing, self.sideband_first,
            self.sideband_count, self.sideband_start, self.ff_xx, self.ff_xy, self.ff_yx,
            self.ff_yy, self.excitation_amplitude, self.excitation_offset_x,
            self.excitation_offset_y, 0.0, 0.0, self.amplitude / (c * tau),
        ])

    def as_dict(self) -> dict:
        return asdict(self)


def sideband_phases(count: int) -> np.ndarray:
    """Schroeder phases psi_k = -pi k (k - 1) / count: a low crest factor multisine."""
    k = np.arange(1, count + 1)
    return -np.pi * k * (k - 1) / max(count, 1)


def initial_state(settings: LoopSettings) -> np.ndarray:
    st = np.zeros(N_STATE)
    st[1] = 2 * math.pi * settings.f_nominal
    return st


@njit(cache=True)
def _wrap(angle):  # pragma: no cover
    """angle in [0, 2 pi): keeps the NCO phase exact over long records."""
    return angle - 2.0 * math.pi * math.floor(angle / (2.0 * math.pi))


@njit(cache=True)
def _lowpass(st, first, sections, alpha, re, im):  # pragma: no cover
    for k in range(sections):
        i = first + 2 * k
        st[i] += alpha * (re - st[i])
        st[i + 1] += alpha * (im - st[i + 1])
        re, im = st[i], st[i + 1]
    return re, im


@njit(cache=True)
def loops_step(px, py, t, h, par, st, out):  # pragma: no cover
    """Consume the pick-offs sampled at t; write the outputs for the hold from t + h."""
    mode = int(par[0])
    w_nom, a_set = par[1], par[2]
    two_pi = 2.0 * math.pi
    # feed-forward removal: the pick-off at t holds E V of the hold that ended at t
    pcx = px - (par[18] * st[18] + par[19] * st[19])
    pcy = py - (par[20] * st[18] + par[21] * st[19])
    t_next = t + h
    if mode == 0:
        f0 = w_nom / two_pi
        a = par[22]
        vx = a * (math.cos(two_pi * (f0 - par[23]) * t_next)
                  + math.cos(two_pi * (f0 + par[23]) * t_next))
        vy = a * (math.cos(two_pi * (f0 - par[24]) * t_next)
                  + math.cos(two_pi * (f0 + par[24]) * t_next))
        st[0] = _wrap(st[0] + w_nom * h)
        st[1] = w_nom
        g = 0.0
        rate = quad = amp = perr = 0.0
    else:
        p1, p2 = (pcx, pcy) if mode == 1 else (pcy, pcx)
        th = st[0]
        c, s = math.cos(th), math.sin(th)
        alpha1 = 1.0 - math.exp(-two_pi * par[3] * h)
        a_re, a_im = _lowpass(st, 4, 3, alpha1, 2.0 * p1 * c, -2.0 * p1 * s)
        amp = math.hypot(a_re, a_im)
        perr = math.atan2(a_im, a_re)
        # PLL: PI on the phase error drives the NCO frequency
        st[2] += par[6] * perr * h
        omega = w_nom + par[5] * perr + st[2]
        # amplitude control on the sideband-modulated position signal
        m = 0.0
        if par[13] > 0.0 and t >= par[17]:
            n = int(par[16])
            for j in range(n):
                k = par[15] + j
                psi = -math.pi * (j + 1) * j / n
                m += par[13] * math.sin(two_pi * k * par[14] * t + psi)
        e = a_set - amp * (1.0 + m)
        g = par[27] + par[7] * e + st[3]
        if 0.0 < g < par[11]:
            st[3] += par[8] * e * h
        g = min(max(g, 0.0), par[11])
        # force rebalance: u = -i K (b + w_i int b)
        alpha2 = 1.0 - math.exp(-two_pi * par[4] * h)
        b_re, b_im = _lowpass(st, 10, 2, alpha2, 2.0 * p2 * c, -2.0 * p2 * s)
        st[14] += b_re * h
        st[15] += b_im * h
        v_re = b_re + par[10] * st[14]
        v_im = b_im + par[10] * st[15]
        u_re, u_im = par[9] * v_im, -par[9] * v_re
        # NCO advance; outputs at the middle of the next hold
        th_next = _wrap(th + omega * h)
        st[0], st[1] = th_next, omega
        psi_mid = th_next + 0.5 * omega * h
        v1 = -g * math.sin(psi_mid + par[12])
        v2 = u_re * math.cos(psi_mid) - u_im * math.sin(psi_mid)
        vx, vy = (v1, v2) if mode == 1 else (v2, v1)
        rate = u_im if mode == 1 else -u_im
        quad = u_re
    st[18], st[19] = st[16], st[17]
    st[16], st[17] = vx, vy
    out[0], out[1] = vx, vy
    out[2], out[3], out[4], out[5] = st[0], st[1], amp, perr
    out[6], out[7], out[8] = g, rate, quad


class LoopsModel:
    """The electronics as a stepping model: what GyroLoops.fmu wraps."""

    def __init__(self, settings: LoopSettings) -> None:
        self.settings = settings
        self.par = settings.as_array()
        self.st = initial_state(settings)
        self.out = np.zeros(len(OUTPUTS))
        self.out[2], self.out[3] = self.st[0], self.st[1]

    def step(self, px: float, py: float, t: float, h: float) -> np.ndarray:
        loops_step(px, py, t, h, self.par, self.st, self.out)
        return self.out

    def get_state(self) -> dict:
        return {"st": self.st.tolist(), "out": self.out.tolist()}

    def set_state(self, state: dict) -> None:
        self.st[:] = state["st"]
        self.out[:] = state["out"]
