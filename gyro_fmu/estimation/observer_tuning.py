"""Tuning of GyroStateObserver (the FMU's tuning parameters, with units and descriptions)."""

from __future__ import annotations

from dataclasses import dataclass, field, fields

from ..core.observer import INTEGER_FIELDS, tuning_problem


def _tuning(default: float, unit: str, description: str, **bounds: float):
    """A tuning field with what dataclass_parameters puts in the FMU (unit, description)."""
    return field(default=default, metadata={"unit": unit, "description": description,
                                            "min": 0.0, **bounds})


def fields_by_name() -> dict:
    """ObserverTuning's dataclass fields by name (their unit and description metadata)."""
    return {f.name: f for f in fields(ObserverTuning)}


@dataclass(frozen=True)
class ObserverTuning:
    """Tuning of GyroStateObserver; the defaults need no knowledge of the rate or the noise.

    The rate model is adaptive and the pick-off noise is estimated from the innovations
    (above a floor of noise_rel x each signal's peak) unless sigma_z1, sigma_z2 are given.
    Units and meaning of each field are in its metadata (they become FMU parameters).
    """

    noise_rel: float = _tuning(
        1.0e-6, "1", "floor of the measurement noise std relative to the running peak of "
        "each measured signal (where sigma_z1, sigma_z2 are 0: the observer then estimates "
        "the noise from its innovations, above this floor; 1e-6 suits noise-free data)")
    sigma_z1: float = _tuning(
        0.0, "m", "absolute measurement noise std of z1 (x; in m/s for vx when "
        "measured_pair = 2); > 0 overrides the estimated noise")
    sigma_z2: float = _tuning(
        0.0, "m", "absolute measurement noise std of z2 (y; in m/s for vy when "
        "measured_pair = 2); > 0 overrides the estimated noise")
    innov_floor: float = _tuning(
        1.0, "1", "noise estimated from the innovations (sigma_z 0): the noise variance is "
        "at least innov_floor times the running mean of the squared innovations (1: "
        "covariance matching)")
    innov_tau: float = _tuning(
        1.0e-3, "s", "time constant of the running mean of the squared innovations")
    rate_model: int = _tuning(
        0, "1", "model of Omega_z(t): 0 adaptive (the observer finds from its innovations "
        "whether the rate is constant, wandering, slow or agile: an interacting-multiple-model "
        "filter, docs/observer-rate-model.md); 1 constant; 2 tracking (follows rate_span at "
        "rate_bandwidth); 3 expert (q_Omega on the omega_order-th derivative)", max=3)
    rate_bandwidth: float = _tuning(
        150.0, "Hz", "fastest rate motion to follow (rate_model 0 and 2): the agile model "
        "follows a sine of amplitude rate_span at this frequency, the slow and rough models at "
        "a tenth")
    rate_span: float = _tuning(
        1.0, "rad/s", "amplitude of the rate motion to follow at rate_bandwidth (rate_model "
        "0 and 2)")
    rate_dwell: float = _tuning(
        100.0, "s", "rate_model 0: mean time the rate keeps one behaviour (constant, rough, "
        "slow, agile) before it may switch")
    q_Omega: float = _tuning(
        1.0e9, "rad2/s5", "rate_model 3 only: spectral density of the white noise driving "
        "the omega_order-th derivative of Omega_z (unit for omega_order 2; rad2/s3 for 1, "
        "rad2/s7 for 3)")
    omega_order: int = _tuning(
        2, "1", "rate_model 3 only: 1 random walk, 2 integrated random walk, 3 twice "
        "integrated random walk", min=1, max=3)
    q_param_rel: float = _tuning(
        0.0, "1/s", "random-walk spectral density of the relative parameter deviations "
        "(0: constant parameters)")
    sigma0_k_rel: float = _tuning(
        0.1, "1", "initial 1-sigma of kxx, kyy, kxy relative to their initial guesses")
    sigma0_d_rel: float = _tuning(
        0.5, "1", "initial 1-sigma of dxx, dyy, dxy relative to the largest |d| guessed")
    sigma0_m_rel: float = _tuning(
        0.1, "1", "initial 1-sigma of m relative to its initial guess")
    sigma0_Omega: float = _tuning(2.0, "rad/s", "initial 1-sigma of Omega_z")
    sigma0_Omega_rate: float = _tuning(
        1.0e3, "rad/s2", "initial 1-sigma of dOmega_z/dt (omega_order 2 and 3)")
    sigma0_Omega_acc: float = _tuning(
        1.0e6, "rad/s3", "initial 1-sigma of d2Omega_z/dt2 (omega_order 3)")
    sigma0_position: float = _tuning(
        0.0, "m", "initial 1-sigma of x and y; 0: scaled to the signal (the state is "
        "taken at rest until the first drive or measurement above its noise, then known to "
        "1 % of the drive's static deflection, or to the size of that measurement)")
    sigma0_velocity: float = _tuning(
        0.0, "m/s", "initial 1-sigma of vx and vy; 0: scaled to the signal like "
        "sigma0_position (times the guessed natural frequency)")
    joseph: bool = _tuning(
        True, "1", "1: Joseph-form covariance update, symmetrized (keeps the covariance "
        "positive definite; docs/observer-soundness.md); 0: P - K H P (loses it at some "
        "steps)", max=1)

    def __post_init__(self) -> None:
        """Whole numbers where the FMU has Integers, numbers elsewhere; then the core's
        rules (gyro_observer_tuning_problems, the ones GyroObserver.fmu refuses with)."""
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, int | float):
                if not (f.name == "joseph" and isinstance(v, bool)):
                    raise ValueError(f"ObserverTuning.{f.name}={v!r} must be a number")
            if f.name in INTEGER_FIELDS and isinstance(v, float) and not v.is_integer():
                raise ValueError(f"ObserverTuning.{f.name}={v!r} must be a whole number "
                                 "(an FMU Integer parameter)")
            if f.name in INTEGER_FIELDS and not -2**31 <= v < 2**31:
                raise ValueError(f"ObserverTuning.{f.name}={v!r} is out of range: see its "
                                 "description for the values it takes")
        values = {f.name: (int(getattr(self, f.name)) if f.name in INTEGER_FIELDS
                           else float(getattr(self, f.name))) for f in fields(self)}
        problem = tuning_problem(values)
        if problem:
            raise ValueError(f"ObserverTuning.{problem}")
