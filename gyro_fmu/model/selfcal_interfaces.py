"""The FMU interfaces of the self-calibration instrument (US 9,482,553), declared once:
GyroResonator (the resonator of gyro_fmu.model.resonator) and GyroLoops (the electronics
of gyro_fmu.model.loops). Their parameters are the fields of ResonatorParameters and
LoopSettings (`parameter_variables`: name, default, unit, description and bounds from
their structs' one declaration, gyro_fmu.core.structs.selfcal).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from ..core.structs.selfcal import LOOP_SETTINGS, RESONATOR_PARAMS
from .interfaces import (
    SEED_MAX,
    FmuInterface,
    StructCopy,
    Var,
    dataclass_parameters,
    input_table,
)
from .loops import OUTPUTS as LOOP_OUTPUTS
from .loops import LoopSettings
from .resonator import ResonatorParameters

#: LoopSettings fields whose FMU parameter has another name: the setpoint `amplitude`
#: would clash with the loops' output `amplitude` (the measured one).
LOOPS_RENAMED = {"amplitude": "amplitude_setpoint"}
#: 10 samples per 4 kHz carrier cycle; 0.02 s is the reference run stored in the FMUs.
SELFCAL_EXPERIMENT = (0.02, 25e-6)

def parameter_variables(cls: type, renamed: Mapping[str, str] | None = None) -> tuple[Var, ...]:
    """FMU parameters for every field of the declared dataclass cls: name, default, unit,
    description and bounds from its struct's declaration (gyro_fmu.core.structs); renamed:
    FMU names of fields whose own name is taken by another variable of the FMU."""
    renamed = renamed or {}
    return tuple(dataclasses.replace(v, name=renamed.get(v.name, v.name))
                 for v in dataclass_parameters(cls))


def settings_from_parameters(cls: type, slave: object,
                             renamed: Mapping[str, str] | None = None) -> object:
    """The dataclass cls from the parameters of a slave declared by parameter_variables."""
    renamed = renamed or {}
    casts = {"int": int, "bool": bool, "float": float, int: int, bool: bool, float: float}
    return cls(**{f.name: casts.get(f.type, float)(getattr(slave, renamed.get(f.name, f.name)))
                  for f in dataclasses.fields(cls)})


def fmu_parameters(settings: object, renamed: Mapping[str, str] | None = None) -> dict:
    """Parameter values of an FMU declared by parameter_variables, from a dataclass."""
    renamed = renamed or {}
    return {renamed.get(k, k): v for k, v in dataclasses.asdict(settings).items()}


def _resonator_reference_inputs(stop_time: float, step: float) -> np.ndarray:
    """A 0.6 V drive at 4 kHz on x and a constant 1 rad/s."""
    t = np.arange(round(stop_time / step) + 1) * step
    carrier = 2 * np.pi * 4000.0 * t
    return input_table(t, {"Vx": 0.6 * np.sin(carrier), "Vy": 0 * t, "Omega_z": np.ones_like(t)})


RESONATOR = FmuInterface(
    identifier="GyroResonator",
    description=(
        "Near mode-matched resonator of US 9,482,553, eq. 1, per unit modal mass: x'' + dxx x' "
        "+ (dxy - 2 kappa Omega_z) y' + kxx x + kxy y = fx, y'' + dyy y' + (dxy + 2 kappa "
        "Omega_z) x' + kyy y + kxy x = fy, plus optional cubic stiffness k3x x^3 + k3xy y^3, "
        'k3y y^3 + k3yx x^3 (eqs. 20-23), fx = Bx (Vx + alpha_y Vy), fy = By (Vy + alpha_x Vx),'
        ' with kxx = (2 pi f_x)^2, dxx = 2 pi f_x / Q_x (y alike). Pick-offs: Vpx = Px zx + Exx'
        " Vx + Exy Vy + noise, Vpy = Py zy + Eyx Vx + Eyy Vy + noise, first-order lags tau z' ="
        ' q_s - z + c_ring V_ring with tan phi = 2 pi f_x tau, sensed displacements (non-'
        'orthogonal pick-offs) x_s = cos(beta_x) x + sin(beta_x) y, y_s = cos(beta_y) y + '
        'sin(beta_y) x, V_ring = ring_amplitude (cos 2 pi ring_frequency_1 t + cos 2 pi '
        'ring_frequency_2 t) generated inside. Inputs Vx, Vy, Omega_z are held over each '
        'communication step, which is integrated exactly (matrix exponential). Optional '
        'thermomechanical force noise (one-sided PSD 4 k_B T D / m_modal, D the damping '
        'matrix), white noise of std drive_noise on the held Vx, Vy, and a temperature ramp '
        'temperature history dT(t) = temperature_rate t + warmup_span (1 - exp(-t / '
        'warmup_tau)) moving f by tc_f and Q by tc_Q per kelvin (step matrices recomputed '
        'every thermal_update_steps steps), sensed by T_sensor = temperature + dT(t) + white '
        'noise of std temperature_noise (its own stream). The seeded noise (pick-off noise '
        'and, from an independent stream, force and drive noise) equals the in-process '
        'gyro_fmu.selfcal.inprocess run sample for sample (the same C core).'),
    variables=(
        *parameter_variables(ResonatorParameters),
        Var("seed", "parameter", 0, None, "seed of the noise generators", integer=True,
            min=0, max=SEED_MAX),
        Var("Vx", "input", 0.0, "V", "x forcer voltage, held over the step"),
        Var("Vy", "input", 0.0, "V", "y forcer voltage, held over the step"),
        Var("Omega_z", "input", 0.0, "rad/s", "angular rate about z, held over the step"),
        Var("Vpx", "output", 0.0, "V", "x pick-off voltage"),
        Var("Vpy", "output", 0.0, "V", "y pick-off voltage"),
        Var("T_sensor", "output", 300.0, "K", "temperature sensor: the resonator's "
            "temperature plus its white noise"),
    ),
    # 0.6 V on x at 1 rad/s: the pick-offs move
    doctor_check=({"Vx": 0.6, "Vy": 0.0, "Omega_z": 1.0}, ("Vpx", "Vpy")),
    reference_inputs=_resonator_reference_inputs,
    core_sources=("gyro_rng.c", "gyro_linalg.c", "gyro_resonator.c"),
    struct_copies=(StructCopy("params_of", RESONATOR_PARAMS),),
    default_experiment=SELFCAL_EXPERIMENT,
)

#: Outputs, in the order of gyro_fmu.model.loops.OUTPUTS.
_LOOP_OUTPUTS = (
    Var("Vx", "output", 0.0, "V", "x forcer voltage, held over the next step"),
    Var("Vy", "output", 0.0, "V", "y forcer voltage, held over the next step"),
    Var("theta", "output", 0.0, "rad", "NCO phase, wrapped to [0, 2 pi)"),
    Var("omega", "output", 0.0, "rad/s", "NCO frequency"),
    Var("amplitude", "output", 0.0, "V", "demodulated primary pick-off amplitude"),
    Var("phase_error", "output", 0.0, "rad", "PLL phase error"),
    Var("gain", "output", 0.0, "V", "oscillator drive amplitude set by the AGC"),
    Var("rate", "output", 0.0, "V", "in-phase force rebalance command (rate output)"),
    Var("quad", "output", 0.0, "V", "quadrature force rebalance command"),
)




def _loops_reference_inputs(stop_time: float, step: float) -> np.ndarray:
    """A 1 V, 4 kHz primary pick-off and a small secondary one (the PLL locks, the AGC
    and the rebalance act)."""
    t = np.arange(round(stop_time / step) + 1) * step
    carrier = 2 * np.pi * 4000.0 * t
    return input_table(t, {"Vpx": np.cos(carrier + 0.3), "Vpy": 0.01 * np.sin(carrier + 0.1)})


LOOPS = FmuInterface(
    identifier="GyroLoops",
    description=(
        'Closed-loop electronics of US 9,482,553 for GyroResonator: from the pick-off voltages '
        'Vpx, Vpy sampled at t it computes the forcer voltages Vx, Vy held from t. Feed-forward'
        ' removal of the drive feed-through; oscillator loop (PLL on the primary pick-off, '
        'drive -g sin(theta + osc_phase) 90 deg ahead, PI amplitude control on the sideband-'
        'modulated position signal); force rebalance of the secondary axis with the rate (in-'
        'phase) and quadrature outputs; mode 1 x primary, 2 reversed, 0 loops off with off-'
        'resonant tones. Drive outputs are computed at the middle of the hold.'),
    variables=(
        *parameter_variables(LoopSettings, LOOPS_RENAMED),
        Var("Vpx", "input", 0.0, "V", "x pick-off voltage sampled at the step start"),
        Var("Vpy", "input", 0.0, "V", "y pick-off voltage sampled at the step start"),
        *_LOOP_OUTPUTS,
    ),
    doctor_check=({"Vpx": 1.0, "Vpy": 0.0}, tuple(LOOP_OUTPUTS)),
    reference_inputs=_loops_reference_inputs,
    core_sources=("gyro_loops.c",),
    struct_copies=(StructCopy("settings_of", LOOP_SETTINGS, LOOPS_RENAMED),),
    default_experiment=SELFCAL_EXPERIMENT,
)

#: The self-calibration FMUs, by model identifier.
SELFCAL_INTERFACES: dict[str, FmuInterface] = {i.identifier: i for i in (RESONATOR, LOOPS)}
