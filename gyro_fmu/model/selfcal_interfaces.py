"""The FMU interfaces of the self-calibration instrument (US 9,482,553), declared once:
GyroResonator (the resonator of gyro_fmu.model.resonator) and GyroLoops (the electronics
of gyro_fmu.model.loops). Their parameters are the fields of ResonatorParameters and
LoopSettings (`parameter_variables`: same name and default, the unit named here, the
description from the field's `#:` comment), so a new field cannot be forgotten: the
build fails until its unit is given.
"""

from __future__ import annotations

import dataclasses
import inspect
import re
from collections.abc import Mapping

import numpy as np

from .interfaces import SEED_MAX, FmuInterface, Var, dataclass_parameters, input_table
from .loops import OUTPUTS as LOOP_OUTPUTS
from .loops import LoopSettings
from .resonator import ResonatorParameters

#: LoopSettings fields whose FMU parameter has another name: the setpoint `amplitude`
#: would clash with the loops' output `amplitude` (the measured one).
LOOPS_RENAMED = {"amplitude": "amplitude_setpoint"}
#: 10 samples per 4 kHz carrier cycle; 0.02 s is the reference run stored in the FMUs.
SELFCAL_EXPERIMENT = (0.02, 25e-6)

_FIELD_COMMENT = re.compile(r"^\s+(\w+)\s*:[^=\n]+=[^#\n]*#:\s*(.+?)\s*$", re.MULTILINE)


def field_comments(cls: type) -> dict[str, str]:
    """The `#:` comment of each field of a dataclass, without a leading unit ("Hz, ...").

    A comment's first comma-separated part is taken for a unit when it has no space
    ("m/s^2/V, x forcer gain" -> "x forcer gain"; "0 loops off, 1 ..." stays whole).
    Empty when the source cannot be read.
    """
    try:
        source = inspect.getsource(cls)
    except (OSError, TypeError):
        return {}
    out = {}
    for name, comment in _FIELD_COMMENT.findall(source):
        head, _, rest = comment.partition(", ")
        if " " not in head:  # a unit: "Hz, NCO centre frequency" or a bare "Hz"
            comment = rest
        if comment:
            out[name] = comment
    return out


def parameter_variables(
    cls: type,
    units: Mapping[str, str],
    descriptions: Mapping[str, str] | None = None,
    bounds: Mapping[str, Mapping[str, float]] | None = None,
    renamed: Mapping[str, str] | None = None,
) -> tuple[Var, ...]:
    """FMU parameters for every field of the dataclass cls (keyed by field name below).

    units: the FMI unit (a key of gyro_fmu.fmu.slave.UNITS) of every float field; integer
    fields are Integer parameters without unit. descriptions: replacements of field
    comments that do not read well alone. bounds: {"min": ..., "max": ..., "nominal": ...}
    per field, refused at set time by the FMU. renamed: FMU names of fields whose own
    name is taken by another variable of the FMU.
    """
    comments = field_comments(cls)
    descriptions, bounds, renamed = descriptions or {}, bounds or {}, renamed or {}
    out = []
    for v in dataclass_parameters(cls):
        if not v.integer and v.name not in units:
            raise KeyError(f"{cls.__name__}.{v.name}: give its FMI unit in the FMU's table")
        text = descriptions.get(v.name) or comments.get(v.name) or v.name
        out.append(dataclasses.replace(
            v, name=renamed.get(v.name, v.name), unit=None if v.integer else units[v.name],
            description=text, **bounds.get(v.name, {}),
        ))
    return tuple(out)


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


#: FMI unit of every field of ResonatorParameters.
_RESONATOR_UNITS = {
    "f_x": "Hz", "f_y": "Hz", "Q_x": "1", "Q_y": "1", "dxy": "1/s", "kxy": "1/s2",
    "kappa": "1", "Bx": "m/s2/V", "By": "m/s2/V", "alpha_x": "rad", "alpha_y": "rad",
    "Px": "V/m", "Py": "V/m", "phi_x": "rad", "phi_y": "rad",
    "Exx": "1", "Exy": "1", "Eyx": "1", "Eyy": "1", "c_ring": "m/V",
    "ring_amplitude": "V", "ring_frequency_1": "Hz", "ring_frequency_2": "Hz", "noise": "V",
    "k3x": "1/(m2.s2)", "k3y": "1/(m2.s2)", "k3xy": "1/(m2.s2)", "k3yx": "1/(m2.s2)",
    "beta_x": "rad", "beta_y": "rad", "m_modal": "kg", "temperature": "K", "drive_noise": "V",
    "temperature_rate": "K/s", "tc_f": "1/K", "tc_Q": "1/K", "warmup_span": "K",
    "warmup_tau": "s", "temperature_noise": "K",
}
#: Declared bounds (check_resonator states the strict ones at initialization).
_RESONATOR_BOUNDS = {
    **{n: {"min": 0.0} for n in ("f_x", "f_y", "Q_x", "Q_y", "kappa", "Bx", "By", "Px", "Py",
                                 "noise", "drive_noise", "m_modal", "temperature",
                                 "temperature_noise")},
    **{n: {"min": -0.5, "max": 0.5} for n in ("beta_x", "beta_y")},
    **{n: {"min": 0.0, "max": 1.5} for n in ("phi_x", "phi_y")},
    "Px": {"min": 0.0, "nominal": 1e6}, "Py": {"min": 0.0, "nominal": 1e6},
    "c_ring": {"nominal": 1e-7},
    # maxima: bounded work a step (cubic_substeps, GYRO_CUBIC_SUBSTEPS_MAX in
    # gyro_resonator.h); thermal_update_steps is a count, the int32 range
    "cubic_substeps": {"min": 1, "max": 1000},
    "thermal_update_steps": {"min": 1, "max": 2147483647},
}




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
        *parameter_variables(ResonatorParameters, _RESONATOR_UNITS, bounds=_RESONATOR_BOUNDS),
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
    core_sources=("gyro_rng.c", "gyro_resonator.c"),
    default_experiment=SELFCAL_EXPERIMENT,
)

#: FMI unit of every float field of LoopSettings (mode and sideband_* counts are Integers).
_LOOP_UNITS = {
    "f_nominal": "Hz", "amplitude": "V", "q_nominal": "1", "plant_gain": "1/s",
    "pll_bandwidth": "Hz", "agc_bandwidth": "Hz", "rebalance_bandwidth": "Hz",
    "demod_cutoff": "Hz", "rebalance_cutoff": "Hz", "drive_limit": "V", "osc_phase": "rad",
    "sideband_index": "1", "sideband_spacing": "Hz", "sideband_start": "s",
    "ff_xx": "1", "ff_xy": "1", "ff_yx": "1", "ff_yy": "1",
    "excitation_amplitude": "V", "excitation_offset_x": "Hz", "excitation_offset_y": "Hz",
}
#: Where a field comment does not read well on its own.
_LOOP_DESCRIPTIONS = {
    "mode": "0 loops off (feed-forward tones), 1 x oscillator / y rebalanced, 2 reversed",
    "amplitude": "primary pick-off amplitude setpoint (LoopSettings.amplitude)",
    "plant_gain": "nominal P B / (2 omega) of each axis, for tuning",
    "pll_bandwidth": "bandwidth of the phase-locked loop",
    "agc_bandwidth": "bandwidth of the amplitude control",
    "rebalance_bandwidth": "bandwidth of the force rebalance loop",
    "demod_cutoff": "cutoff of each of the 3 low-pass sections of the PLL and AGC demodulators",
    "rebalance_cutoff": "cutoff of each of the 2 low-pass sections of the rebalance demodulator",
    "sideband_spacing": "spacing df of the sideband tones",
    "ff_xx": "feed-forward correction of Vx in the x pick-off",
    "ff_xy": "feed-forward correction of Vy in the x pick-off",
    "ff_yx": "feed-forward correction of Vx in the y pick-off",
    "ff_yy": "feed-forward correction of Vy in the y pick-off",
    "excitation_amplitude": "mode 0: amplitude of each tone on Vx and Vy",
    "excitation_offset_x": "mode 0: Vx tones at f_nominal -/+ this",
    "excitation_offset_y": "mode 0: Vy tones at f_nominal -/+ this",
}
_LOOP_BOUNDS = {
    "mode": {"min": 0, "max": 2},
    # maxima: GYRO_SIDEBAND_*_MAX in gyro_loops.h (each step sums every tone)
    "sideband_first": {"min": 0, "max": 1000000}, "sideband_count": {"min": 0, "max": 1000},
    **{n: {"min": 0.0} for n in ("f_nominal", "amplitude", "q_nominal", "plant_gain",
                                 "pll_bandwidth", "agc_bandwidth", "rebalance_bandwidth",
                                 "demod_cutoff", "rebalance_cutoff", "drive_limit",
                                 "sideband_index", "sideband_spacing")},
}
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
        *parameter_variables(LoopSettings, _LOOP_UNITS, _LOOP_DESCRIPTIONS, _LOOP_BOUNDS,
                             LOOPS_RENAMED),
        Var("Vpx", "input", 0.0, "V", "x pick-off voltage sampled at the step start"),
        Var("Vpy", "input", 0.0, "V", "y pick-off voltage sampled at the step start"),
        *_LOOP_OUTPUTS,
    ),
    doctor_check=({"Vpx": 1.0, "Vpy": 0.0}, tuple(LOOP_OUTPUTS)),
    reference_inputs=_loops_reference_inputs,
    core_sources=("gyro_loops.c",),
    default_experiment=SELFCAL_EXPERIMENT,
)

#: The self-calibration FMUs, by model identifier.
SELFCAL_INTERFACES: dict[str, FmuInterface] = {i.identifier: i for i in (RESONATOR, LOOPS)}
