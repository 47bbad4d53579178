"""Alarms that stop a wrong calibration: lock, misfit, conditioning, uncertainty.

Each check returns a list of problems (empty when fine), each naming what was
measured, the limit, and what to change, like fmpy's validation. `self_calibrate`
raises CalibrationRefusedError with all of them instead of returning a number.

- Lock (per mode record): the PLL phase error stays small (an unlocked PLL slips
  through +-pi), the demodulated primary amplitude holds its setpoint, the drive is
  not pinned at its limit, the rebalance nulls the secondary pick-off.
- Misfit: the rms residual of the eq. 19 fit against the residual white pick-off
  noise alone would leave. A Hann-weighted phasor over N samples of noise of
  variance s^2 has variance 6 s^2 / N, 3 s^2 / N per real component; s is estimated
  from the pick-off record's spectrum above the carrier (median of a Hann
  periodogram, robust to lines). A model that fits leaves a ratio near 1; an
  imperfection the model lacks (force noise: 18.6; a 0.01 K/s temperature ramp: 1e3)
  or unsettled loops leave more (the cubic terms of eqs. 24-27 are in the model).
- Cubic validity: the cubic terms are fitted linearized about one carrier amplitude;
  a cubic frequency shift comparable to the mode's half-width breaks that. Measured on
  a lot of 30 with shifts to 0.1 Hz: cross-cubic shifts of 0.43-0.45 half-widths gave
  bias errors of 11.7 and 48 sigmas (8e-5, 1.1e-4 rad/s) with the misfit at 1.0; those
  of 0.10 or less, and auto-cubic shifts to 1.45 half-widths, stayed within 2.5
  sigmas (an auto shift of 4.9 half-widths: 7.1 sigmas).
- Conditioning and uncertainty: the fit's 1-sigmas must be finite and below the
  targets (the record length was chosen for them; see sequence.choose_record).
- Carrier shift: the temperature moving between the records shifts mode 2's
  frequencies; the shift comes from the carriers' drifts (phasors.carrier_shifts).
  When the drift changes between the records, the shift is uncertain; if that alone
  leaves more than a third of a target, the warm-up is named, not a longer record.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import GyroFmuError

#: rad: largest PLL phase error allowed during a record (locked: about 5e-4).
PLL_PHASE_LIMIT = 0.1
#: relative: largest departure of the mean primary amplitude from its setpoint.
AMPLITUDE_TOLERANCE = 0.1
#: fraction of samples the drive may spend at its limit.
SATURATION_LIMIT = 0.01
#: secondary/primary carrier amplitude the rebalance must reach (locked: ~1e-10).
REBALANCE_LIMIT = 1e-3
#: misfit ratio above which the model is refused (chi-square with ~200 degrees of
#: freedom: a ratio of 1.2 is already 3 sigma of the ratio's own spread).
MISFIT_LIMIT = 2.0
#: relative: model-error floor of a noise-free fit (measured: 1.5e-8 of the amplitude
#: for the linear model, 2.0e-7 with the cubic terms at a 0.01 Hz shift, 8.5e-7 at 0.03 Hz).
MODEL_FLOOR = 3e-7


#: largest cubic shift of the primary mode, in half-widths of that mode
CUBIC_AUTO_LIMIT = 1.5
#: largest cross-cubic shift (primary amplitude acting on the secondary), in half-widths
CUBIC_CROSS_LIMIT = 0.2


class CalibrationRefusedError(GyroFmuError):
    """The calibration cannot be trusted: `problems` names each cause and its remedy;
    `result` is the untrusted SelfCalResult when one was computed (for studies)."""

    def __init__(self, problems: list[str], result: object | None = None) -> None:
        self.problems = list(problems)
        self.result = result
        super().__init__("self-calibration refused: " + "; ".join(self.problems))


def lock_statistics(phase_error: np.ndarray, amplitude: np.ndarray, gain: np.ndarray,
                    drive_limit: float) -> tuple[float, float, float]:
    """(largest |phase error|, mean amplitude, fraction of steps with the drive at its
    limit) of a closed-loop record held whole; a streamed record carries the same
    (stream.StreamedRecord), counted by the core as it runs."""
    worst = float(np.max(np.abs(phase_error))) if len(phase_error) else math.nan
    return worst, float(np.mean(amplitude)), float(np.mean(gain >= drive_limit))


def lock_problems(mode: int, worst: float, mean_amp: float, pinned: float, secondary: float,
                  setpoint: float, drive_limit: float) -> list[str]:
    """Problems of one closed-loop record (empty when the loops held), from its
    lock_statistics and the secondary/primary carrier ratio."""
    out = []
    if not worst <= PLL_PHASE_LIMIT:
        out.append(f"mode {mode}: the PLL did not lock (phase error up to {worst:.2g} rad, "
                   f"limit {PLL_PHASE_LIMIT}): set f_nominal to the resonator's frequency "
                   "(--loop f_nominal=HZ) or widen --loop pll_bandwidth=HZ")
    if not abs(mean_amp / setpoint - 1.0) <= AMPLITUDE_TOLERANCE:
        out.append(f"mode {mode}: the amplitude control did not hold {setpoint:.3g} V (mean "
                   f"{mean_amp:.3g} V): check plant_gain and q_nominal (--loop), or lower "
                   "--loop amplitude=V")
    if pinned > SATURATION_LIMIT:
        out.append(f"mode {mode}: the drive sat at its limit {drive_limit:g} V for "
                   f"{pinned:.0%} of the record: lower --loop amplitude=V or raise "
                   "--loop drive_limit=V")
    if not secondary <= REBALANCE_LIMIT:
        out.append(f"mode {mode}: the force rebalance left the secondary pick-off at "
                   f"{secondary:.2g} of the primary (limit {REBALANCE_LIMIT:g}): check "
                   "--loop plant_gain and rebalance_bandwidth")
    return out


def pickoff_noise(signal: np.ndarray, h: float, f_carrier: float) -> float:
    """White-noise std per sample of a pick-off record, from its periodogram between
    1.6 times the carrier and the Nyquist frequency (median / ln 2: robust to stray
    lines). Below the carrier the rebalanced pick-off also carries the drive noise the
    loops feed back (measured: 1.6 times the white level at 0.2-0.7 f)."""
    n = len(signal)
    window = np.hanning(n)  # the carrier's leakage falls as 1/k^3, not 1/k
    with np.errstate(over="ignore", invalid="ignore"):  # a diverged record: lock_problems
        spec = np.abs(np.fft.rfft((signal - np.mean(signal)) * window)) ** 2  # names it
    f = np.fft.rfftfreq(n, h)
    band = spec[(f > 1.6 * f_carrier) & (f < 0.95 / (2 * h))]
    if band.size < 16:
        return math.nan
    return math.sqrt(float(np.median(band)) / (float(window @ window) * math.log(2.0)))


def misfit_problems(fit) -> tuple[float, list[str]]:
    """(misfit ratio, problems): sqrt(chi^2 / dof) of the eq. 19 fit weighted by its
    noise model (estimator.NoiseModel: white pick-off noise, force noise measured
    between the tones, the model floor); the rms residual is quoted beside it."""
    ratio = fit.misfit
    if not ratio <= MISFIT_LIMIT:
        force = ", ".join(f"{f:.2g}" for f in fit.noise.force) if fit.noise else "none"
        return ratio, [
            f"the eq. 19 model does not fit the sidebands: its residuals (rms "
            f"{fit.rms_residual:.2g} V) are {ratio:.3g} times what the noise model "
            f"leaves (white pick-off noise, force noise {force} measured between the tones, floor "
            f"{fit.noise.floor if fit.noise else math.nan:.2g} V; limit {MISFIT_LIMIT:g}x): "
            "an imperfection the model lacks (cubic or cross-cubic "
            "stiffness: lower the drive --loop amplitude=V; the temperature "
            "moving during the record: let it settle), or loops still settling (--settle)"]
    return ratio, []


def cubic_problems(gamma: dict[tuple[int, str], float], d_primary: dict[int, float],
                   d_secondary: dict[int, float], omega: float) -> list[str]:
    """The fitted cubic terms (1/s^2, per mode: "auto" and "cross") against the mode
    half-widths d / 2 (rad/s): a stiffness gamma shifts the mode by gamma / (2 omega)."""
    out = []
    for (mode, kind), g in gamma.items():
        d = d_primary[mode] if kind == "auto" else d_secondary[mode]
        ratio = abs(g) / (omega * abs(d)) if d else math.inf
        limit = CUBIC_AUTO_LIMIT if kind == "auto" else CUBIC_CROSS_LIMIT
        if not ratio <= limit:
            out.append(
                f"mode {mode}: the {'cubic' if kind == 'auto' else 'cross-cubic'} stiffness "
                f"shifts the mode by {abs(g) / (2 * omega) / (2 * math.pi):.2g} Hz, {ratio:.2g} "
                f"half-widths (limit {limit:g}): beyond where its sideband model holds; "
                "lower the drive (--loop amplitude=V)")
    return out


#: Smallest relative singular value of the sideband fit's (column-normalized) Jacobian
#: accepted. Measured with the default resonator and f_x = 4000 Hz: f_y - f_x = 0 gives
#: 5e-10-1.5e-8 (the fit lands 1.8e-4 rad/s off with a 1-sigma of 5e-9: the pseudo-inverse
#: dropped the direction), 1e-4 Hz gives 1.07e-5 and 1e-3 Hz 1.07e-4 (both agree with the
#: rate table, with honest sigmas of 5.5e-6 and 3.8e-7 rad/s). 1e-5 Hz gives about 1.1e-6
#: and passed a limit of 1e-7, landing 2.43e-5 rad/s off with a 1-sigma of 2.3e-6 (10
#: sigma), so the limit sits at 2e-6, below the 4.3e-6 of 1e-4 Hz with short records.
CONDITIONING_LIMIT = 2e-6


def conditioning_problems(conditioning: float, weakest: tuple[str, ...],
                          split_hz: float) -> list[str]:
    """The sideband fit must determine every parameter it fits (estimator.SidebandFit)."""
    if conditioning >= CONDITIONING_LIMIT:
        return []
    along = " and ".join(weakest) or "some parameters"
    return [f"the sideband fit cannot determine {along} apart (relative singular value "
            f"{conditioning:.2g} of its Jacobian, limit {CONDITIONING_LIMIT:g}): the "
            f"fitted mode split is {split_hz:.3g} Hz, and with the modes matched the "
            "records do not determine them, so the bias and its 1-sigma would be a guess "
            "(measured: 1.8e-4 rad/s off with a 1-sigma of 5e-9); calibrate with the "
            "modes split by at least 1e-4 Hz (a mode-matched design: detune it for the "
            "calibration; in the simulator --set f_y=F with F at least 1e-4 Hz from f_x)"]


def uncertainty_problems(sigma_bias: float, sigma_sf_ppm: float, target_bias: float,
                         target_sf_ppm: float, record: float) -> list[str]:
    """The 1-sigmas must be finite (a conditioned fit) and within the targets."""
    if not (math.isfinite(sigma_bias) and math.isfinite(sigma_sf_ppm)):
        return ["the sideband fit is ill-conditioned (non-finite uncertainty): raise the "
                "sideband index (--index) or check the forcer gains"]
    out = []
    # the 1-sigmas fall as 1 / sqrt(record): the length that would reach each target
    for name, sigma, target, unit, option in (
            ("bias", sigma_bias, target_bias, " rad/s", "--target-bias"),
            ("scale-factor", sigma_sf_ppm, target_sf_ppm, " ppm", "--target-sf-ppm")):
        if sigma > target:
            need = record * (sigma / target) ** 2
            out.append(f"{name} 1-sigma {sigma:.3g}{unit} is above the target "
                       f"{target:.3g}{unit} after {record:g} s records (records of about "
                       f"{need:.3g} s would reach it): allow longer records "
                       f"(--max-record S), lower the noise, or relax {option}")
    return out


def carrier_shift_problems(drifts: list[float], sigma_bias_shift: float,
                           sigma_sf_ppm_shift: float, target_bias: float,
                           target_sf_ppm: float, split_hz: float) -> list[str]:
    """The shift between the records (from the carriers' drifts) must be known well
    enough: its uncertainty alone may take at most a third of each target."""
    if sigma_bias_shift <= target_bias / 3 and sigma_sf_ppm_shift <= target_sf_ppm / 3:
        return []
    return [f"the frequency shift between the records is uncertain (carrier drifts "
            f"{', '.join(f'{d:+.2e}' for d in drifts)} /s), which alone leaves 1-sigmas "
            f"of {sigma_bias_shift:.2g} rad/s and {sigma_sf_ppm_shift:.3g} ppm (a third of "
            "the targets allowed): either the temperature's rate changed between the "
            "records (calibrate once the warm-up has settled to a steady or no ramp, or "
            f"settle longer: --settle S) or the modes are so close (split {split_hz:.3g} "
            "Hz) that even a noise-level drift matters (split them further: --set f_y=F)"]
