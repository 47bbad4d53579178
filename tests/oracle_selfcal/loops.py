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

from gyro_fmu.errors import GyroFmuError

from .resonator import non_finite_fields

#: Outputs of one loops step, in order.
OUTPUTS = ("Vx", "Vy", "theta", "omega", "amplitude", "phase_error", "gain",
           "rate", "quad")
N_STATE = 26  #: slots 20-25 are unused

#: Slots of the settings array `par` (LoopSettings.as_array), by name; numba reads
#: module-level integers as compile-time constants, so named slots cost nothing.
P_MODE = 0
P_W_NOMINAL = 1
P_AMPLITUDE_SET = 2
P_DEMOD_CUTOFF = 3
P_REBALANCE_CUTOFF = 4
P_PLL_KP = 5
P_PLL_KI = 6
P_AGC_KP = 7
P_AGC_KI = 8
P_REBALANCE_GAIN = 9
P_REBALANCE_WI = 10
P_DRIVE_LIMIT = 11
P_OSC_PHASE = 12
P_SIDEBAND_INDEX = 13
P_SIDEBAND_SPACING = 14
P_SIDEBAND_FIRST = 15
P_SIDEBAND_COUNT = 16
P_SIDEBAND_START = 17
P_FF_XX = 18
P_FF_XY = 19
P_FF_YX = 20
P_FF_YY = 21
P_EXCITATION_AMPLITUDE = 22
P_EXCITATION_OFFSET_X = 23
P_EXCITATION_OFFSET_Y = 24
P_AGC_FEEDFORWARD = 27
N_PAR = 28  #: slots 25 and 26 are unused

#: Slots of the loop state `st`: NCO phase and frequency, PI integrators, the low-pass
#: sections (3 complex for the PLL/AGC demodulator, 2 for the rebalance), the drive
#: voltages of this hold and the previous one (for the feed-forward removal).
S_THETA = 0
S_OMEGA = 1
S_PLL_INTEGRAL = 2
S_AGC_INTEGRAL = 3
S_AGC_LOWPASS = 4
S_REBALANCE_LOWPASS = 10
S_REBALANCE_INTEGRAL_RE = 14
S_REBALANCE_INTEGRAL_IM = 15
S_VX_HELD = 16
S_VY_HELD = 17
S_VX_PREVIOUS = 18
S_VY_PREVIOUS = 19


class LoopsError(GyroFmuError, ValueError):
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
        par = np.zeros(N_PAR)
        par[P_MODE] = self.mode
        par[P_W_NOMINAL] = w * self.f_nominal
        par[P_AMPLITUDE_SET] = self.amplitude
        par[P_DEMOD_CUTOFF] = self.demod_cutoff
        par[P_REBALANCE_CUTOFF] = self.rebalance_cutoff
        par[P_PLL_KP] = w * self.pll_bandwidth
        par[P_PLL_KI] = (w * self.pll_bandwidth) ** 2 / 4
        par[P_AGC_KP] = 2 * zeta * wn / c
        par[P_AGC_KI] = wn**2 / c
        par[P_REBALANCE_GAIN] = w * self.rebalance_bandwidth / c
        par[P_REBALANCE_WI] = w * self.rebalance_bandwidth / 5
        par[P_DRIVE_LIMIT] = self.drive_limit
        par[P_OSC_PHASE] = self.osc_phase
        par[P_SIDEBAND_INDEX] = self.sideband_index
        par[P_SIDEBAND_SPACING] = self.sideband_spacing
        par[P_SIDEBAND_FIRST] = self.sideband_first
        par[P_SIDEBAND_COUNT] = self.sideband_count
        par[P_SIDEBAND_START] = self.sideband_start
        par[P_FF_XX], par[P_FF_XY] = self.ff_xx, self.ff_xy
        par[P_FF_YX], par[P_FF_YY] = self.ff_yx, self.ff_yy
        par[P_EXCITATION_AMPLITUDE] = self.excitation_amplitude
        par[P_EXCITATION_OFFSET_X] = self.excitation_offset_x
        par[P_EXCITATION_OFFSET_Y] = self.excitation_offset_y
        par[P_AGC_FEEDFORWARD] = self.amplitude / (c * tau)
        return par

    def as_dict(self) -> dict:
        return asdict(self)


def sideband_phases(count: int) -> np.ndarray:
    """Schroeder phases psi_k = -pi k (k - 1) / count: a low crest factor multisine."""
    k = np.arange(1, count + 1)
    return -np.pi * k * (k - 1) / max(count, 1)


def initial_state(settings: LoopSettings) -> np.ndarray:
    st = np.zeros(N_STATE)
    st[S_OMEGA] = 2 * math.pi * settings.f_nominal
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
    mode = int(par[P_MODE])
    w_nom, a_set = par[P_W_NOMINAL], par[P_AMPLITUDE_SET]
    two_pi = 2.0 * math.pi
    # feed-forward removal: the pick-off at t holds E V of the hold that ended at t
    pcx = px - (par[P_FF_XX] * st[S_VX_PREVIOUS] + par[P_FF_XY] * st[S_VY_PREVIOUS])
    pcy = py - (par[P_FF_YX] * st[S_VX_PREVIOUS] + par[P_FF_YY] * st[S_VY_PREVIOUS])
    t_next = t + h
    if mode == 0:
        f0 = w_nom / two_pi
        a = par[P_EXCITATION_AMPLITUDE]
        vx = a * (math.cos(two_pi * (f0 - par[P_EXCITATION_OFFSET_X]) * t_next)
                  + math.cos(two_pi * (f0 + par[P_EXCITATION_OFFSET_X]) * t_next))
        vy = a * (math.cos(two_pi * (f0 - par[P_EXCITATION_OFFSET_Y]) * t_next)
                  + math.cos(two_pi * (f0 + par[P_EXCITATION_OFFSET_Y]) * t_next))
        st[S_THETA] = _wrap(st[S_THETA] + w_nom * h)
        st[S_OMEGA] = w_nom
        g = 0.0
        rate = quad = amp = perr = 0.0
    else:
        p1, p2 = (pcx, pcy) if mode == 1 else (pcy, pcx)
        th = st[S_THETA]
        c, s = math.cos(th), math.sin(th)
        alpha1 = 1.0 - math.exp(-two_pi * par[P_DEMOD_CUTOFF] * h)
        a_re, a_im = _lowpass(st, S_AGC_LOWPASS, 3, alpha1, 2.0 * p1 * c, -2.0 * p1 * s)
        amp = math.hypot(a_re, a_im)
        perr = math.atan2(a_im, a_re)
        # PLL: PI on the phase error drives the NCO frequency
        st[S_PLL_INTEGRAL] += par[P_PLL_KI] * perr * h
        omega = w_nom + par[P_PLL_KP] * perr + st[S_PLL_INTEGRAL]
        # amplitude control on the sideband-modulated position signal
        m = 0.0
        if par[P_SIDEBAND_INDEX] > 0.0 and t >= par[P_SIDEBAND_START]:
            n = int(par[P_SIDEBAND_COUNT])
            for j in range(n):
                k = par[P_SIDEBAND_FIRST] + j
                psi = -math.pi * (j + 1) * j / n
                m += par[P_SIDEBAND_INDEX] * math.sin(
                    two_pi * k * par[P_SIDEBAND_SPACING] * t + psi)
        e = a_set - amp * (1.0 + m)
        g = par[P_AGC_FEEDFORWARD] + par[P_AGC_KP] * e + st[S_AGC_INTEGRAL]
        if 0.0 < g < par[P_DRIVE_LIMIT]:
            st[S_AGC_INTEGRAL] += par[P_AGC_KI] * e * h
        g = min(max(g, 0.0), par[P_DRIVE_LIMIT])
        # force rebalance: u = -i K (b + w_i int b)
        alpha2 = 1.0 - math.exp(-two_pi * par[P_REBALANCE_CUTOFF] * h)
        b_re, b_im = _lowpass(st, S_REBALANCE_LOWPASS, 2, alpha2, 2.0 * p2 * c, -2.0 * p2 * s)
        st[S_REBALANCE_INTEGRAL_RE] += b_re * h
        st[S_REBALANCE_INTEGRAL_IM] += b_im * h
        v_re = b_re + par[P_REBALANCE_WI] * st[S_REBALANCE_INTEGRAL_RE]
        v_im = b_im + par[P_REBALANCE_WI] * st[S_REBALANCE_INTEGRAL_IM]
        u_re, u_im = par[P_REBALANCE_GAIN] * v_im, -par[P_REBALANCE_GAIN] * v_re
        # NCO advance; outputs at the middle of the next hold
        th_next = _wrap(th + omega * h)
        st[S_THETA], st[S_OMEGA] = th_next, omega
        psi_mid = th_next + 0.5 * omega * h
        v1 = -g * math.sin(psi_mid + par[P_OSC_PHASE])
        v2 = u_re * math.cos(psi_mid) - u_im * math.sin(psi_mid)
        vx, vy = (v1, v2) if mode == 1 else (v2, v1)
        rate = u_im if mode == 1 else -u_im
        quad = u_re
    st[S_VX_PREVIOUS], st[S_VY_PREVIOUS] = st[S_VX_HELD], st[S_VY_HELD]
    st[S_VX_HELD], st[S_VY_HELD] = vx, vy
    out[0], out[1] = vx, vy
    out[2], out[3], out[4], out[5] = st[S_THETA], st[S_OMEGA], amp, perr
    out[6], out[7], out[8] = g, rate, quad


class LoopsModel:
    """The electronics as a stepping model: what GyroLoops.fmu wraps."""

    def __init__(self, settings: LoopSettings) -> None:
        self.settings = settings
        self.par = settings.as_array()
        self.st = initial_state(settings)
        self.out = np.zeros(len(OUTPUTS))
        self.out[2], self.out[3] = self.st[S_THETA], self.st[S_OMEGA]

    def step(self, px: float, py: float, t: float, h: float) -> np.ndarray:
        loops_step(px, py, t, h, self.par, self.st, self.out)
        return self.out

    def get_state(self) -> dict:
        return {"st": self.st.tolist(), "out": self.out.tolist()}

    def set_state(self, state: dict) -> None:
        self.st[:] = state["st"]
        self.out[:] = state["out"]
