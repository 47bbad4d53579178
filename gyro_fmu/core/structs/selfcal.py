"""The self-calibration instrument's structs (US 9,482,553; fmu_src/core/gyro_resonator.h,
gyro_loops.h, gyro_demod.h): the resonator's parameters and the loops' settings (the FMU
parameters GyroResonator and GyroLoops declare from them, the fields of
ResonatorParameters and LoopSettings), and the state the library steps."""

from __future__ import annotations

from .base import Constant, Field, Struct
from .plant import RNG

RES_N = Constant("GYRO_RES_N", 10, "the resonator's states")
RES_FORCED = Constant("GYRO_RES_FORCED", 6,
                      "states the force noise reaches: x, y, vx, vy, zx, zy")
DEMOD_ORDER = Constant("GYRO_DEMOD_ORDER", 5, "cascaded boxcars of the demodulator")
DEMOD_CHANNELS = Constant("GYRO_DEMOD_CHANNELS", 4, "Vx, Vy, Vpx, Vpy")
NOISE_MAX = Constant("GYRO_RES_NOISE_MAX", 1e3, "V: the most pick-off or drive noise per "
                     "sample (the carriers are about 1 V)")

RESONATOR_PARAMS = Struct(
    "GyroResonatorParams", "The resonator's parameters (ResonatorParameters in Python; SI "
    "units).", (
    Field('f_x', default=4000.0, unit='Hz', min=0.0,
          doc='x-mode resonant frequency'),
    Field('f_y', default=4000.25, unit='Hz', min=0.0,
          doc='y-mode resonant frequency'),
    Field('Q_x', default=20000.0, min=0.0,
          doc='x-mode quality factor'),
    Field('Q_y', default=19000.0, min=0.0,
          doc='y-mode quality factor'),
    Field('dxy', default=0.00272, unit='1/s',
          doc='cross damping (bias = dxy / (2 kappa))'),
    Field('kxy', default=7000.0, unit='1/s2',
          doc='cross stiffness (quadrature = kxy / (2 kappa omega))'),
    Field('kappa', default=0.8, min=0.0,
          doc='Bryant factor'),
    Field('Bx', default=0.05, unit='m/s2/V', min=0.0,
          doc='x forcer gain'),
    Field('By', default=0.048, unit='m/s2/V', min=0.0,
          doc='y forcer gain'),
    Field('alpha_x', default=0.002, unit='rad',
          doc='x forcer misalignment into y'),
    Field('alpha_y', default=-0.001, unit='rad',
          doc='y forcer misalignment into x'),
    Field('Px', default=1000000.0, unit='V/m', min=0.0, nominal=1000000.0,
          doc='x pick-off gain'),
    Field('Py', default=1030000.0, unit='V/m', min=0.0, nominal=1000000.0,
          doc='y pick-off gain'),
    Field('phi_x', default=0.02, unit='rad', min=0.0, max=1.5,
          doc='x pick-off electronics phase lag at f_x'),
    Field('phi_y', default=0.022, unit='rad', min=0.0, max=1.5,
          doc='y pick-off electronics phase lag at f_x'),
    Field('Exx', default=0.002,
          doc='feed-through of Vx into the x pick-off'),
    Field('Exy', default=0.0005,
          doc='feed-through of Vy into the x pick-off'),
    Field('Eyx', default=0.001,
          doc='feed-through of Vx into the y pick-off'),
    Field('Eyy', default=0.002,
          doc='feed-through of Vy into the y pick-off'),
    Field('c_ring', default=1e-07, unit='m/V', nominal=1e-07,
          doc='ring voltage seen by the pick-offs'),
    Field('k3x', default=0.0, unit='1/(m2.s2)',
          doc='1/(m^2 s^2), cubic stiffness of x (eq. 20; 4.2e17 = +1 Hz at 1 um)'),
    Field('k3y', default=0.0, unit='1/(m2.s2)',
          doc='1/(m^2 s^2), cubic stiffness of y (eq. 21)'),
    Field('cubic_substeps', 'int32_t', default=4, min=1, max=1000,
          doc='splitting substeps per step when k3x or k3y is not 0'),
    Field('ring_amplitude', default=0.0, unit='V',
          doc='each ring excitation tone (0 = off)'),
    Field('ring_frequency_1', default=3740.0, unit='Hz',
          doc='first ring tone (off resonance)'),
    Field('ring_frequency_2', default=4260.0, unit='Hz',
          doc='second ring tone'),
    Field('noise', default=0.0, unit='V', min=0.0, max=NOISE_MAX.value,
          doc='std of white noise on each pick-off sample'),
    Field('beta_x', default=0.0, unit='rad', min=-0.5, max=0.5,
          doc='x pick-off sensing axis tilted toward +y (non-orthogonality)'),
    Field('beta_y', default=0.0, unit='rad', min=-0.5, max=0.5,
          doc='y pick-off sensing axis tilted toward +x'),
    Field('k3xy', default=0.0, unit='1/(m2.s2)',
          doc='1/(m^2 s^2), cross-cubic stiffness, k3xy y^3 in the x equation (eq. 22)'),
    Field('k3yx', default=0.0, unit='1/(m2.s2)',
          doc='1/(m^2 s^2), cross-cubic stiffness, k3yx x^3 in the y equation (eq. 23)'),
    Field('m_modal', default=0.0, unit='kg', min=0.0,
          doc='modal mass of the thermomechanical force noise (0 = no noise)'),
    Field('temperature', default=300.0, unit='K', min=0.0,
          doc='resonator temperature at the start of the run'),
    Field('drive_noise', default=0.0, unit='V', min=0.0, max=NOISE_MAX.value,
          doc='std of white noise on each held drive voltage sample'),
    Field('temperature_rate', default=0.0, unit='K/s',
          doc='temperature ramp during the run'),
    Field('tc_f', default=0.0, unit='1/K',
          doc='relative change of f_x and f_y per kelvin (e.g. -30e-6)'),
    Field('tc_Q', default=0.0, unit='1/K',
          doc='relative change of Q_x and Q_y per kelvin'),
    Field('thermal_update_steps', 'int32_t', default=4000, min=1, max=2147483647,
          doc='steps between re-discretizations during a ramp'),
    Field('warmup_span', default=0.0, unit='K',
          doc='warmup_span'),
    Field('warmup_tau', default=600.0, unit='s',
          doc="the warm-up's time constant"),
    Field('temperature_noise', default=0.0, unit='K', min=0.0,
          doc='std of white noise on each temperature-sensor sample'),))

RESONATOR_MAPS = Struct(
    "GyroResonatorMaps", "One held step's maps, for (Omega_z, h, dT): s' = Phi s + Gamma V "
    "(+ L w). With cubic stiffness Phi, Gamma are over h / (2 n).", (
        Field("Phi", shape=(RES_N, RES_N)), Field("Gamma", shape=(RES_N, 2)),
        Field("L", shape=(RES_N, RES_FORCED), doc="force noise input over h (0 without)"),
        Field("Omega_z", unit="rad/s"), Field("h", unit="s"), Field("dT", unit="K"),
        Field("valid", "int32_t"), Field("reserved", "int32_t", hidden=True)))

RESONATOR = Struct("GyroResonator", "A resonator as the library and GyroResonator.fmu step "
                   "it.", (
    Field("p", RESONATOR_PARAMS), Field("seed", "uint64_t"), Field("s", shape=(RES_N,)),
    Field("out", shape=(2,), unit="V", doc="Vpx, Vpy at the current time"),
    Field("T_sensor", unit="K", doc="the temperature sensor at the current time"),
    Field("k", "int64_t", doc="steps taken: the temperature ramp's clock"),
    Field("noise_rng", RNG, doc="pick-off noise"),
    Field("force_rng", RNG, doc="force and drive noise"),
    Field("sensor_rng", RNG, doc="temperature-sensor noise (its own stream)"),
    Field("maps", RESONATOR_MAPS)))

LOOP_SETTINGS = Struct(
    "GyroLoopSettings", "The loops' settings (LoopSettings in Python; SI units; tuning uses "
    "nominal plant values, not the true ones).", (
    Field('mode', 'int32_t', default=1, min=0, max=2,
          doc='0 loops off (feed-forward tones), 1 x oscillator / y rebalanced, 2 reversed'),
    Field('f_nominal', default=4000.0, unit='Hz', min=0.0,
          doc='NCO centre frequency'),
    Field('amplitude', default=1.0, unit='V', min=0.0,
          doc='primary pick-off amplitude setpoint (LoopSettings.amplitude)'),
    Field('q_nominal', default=20000.0, min=0.0,
          doc='nominal Q, for the drive feed-forward'),
    Field('plant_gain', default=1.0, unit='1/s', min=0.0,
          doc='nominal P B / (2 omega) of each axis, for tuning'),
    Field('pll_bandwidth', default=20.0, unit='Hz', min=0.0,
          doc='bandwidth of the phase-locked loop'),
    Field('agc_bandwidth', default=3.0, unit='Hz', min=0.0,
          doc='bandwidth of the amplitude control'),
    Field('rebalance_bandwidth', default=100.0, unit='Hz', min=0.0,
          doc='bandwidth of the force rebalance loop'),
    Field('demod_cutoff', default=500.0, unit='Hz', min=0.0,
          doc='cutoff of each of the 3 low-pass sections of the PLL and AGC demodulators'),
    Field('rebalance_cutoff', default=2000.0, unit='Hz', min=0.0,
          doc='cutoff of each of the 2 low-pass sections of the rebalance demodulator'),
    Field('drive_limit', default=5.0, unit='V', min=0.0,
          doc='largest oscillator drive amplitude'),
    Field('osc_phase', default=0.0, unit='rad',
          doc='oscillator loop phase away from 90 deg'),
    Field('sideband_index', default=0.0, min=0.0,
          doc='modulation index of each sideband tone'),
    Field('sideband_spacing', default=0.1, unit='Hz', min=0.0,
          doc='spacing df of the sideband tones'),
    Field('sideband_first', 'int32_t', default=1, min=0, max=1000000,
          doc='first harmonic k of df'),
    Field('sideband_count', 'int32_t', default=15, min=0, max=1000,
          doc='number of tones'),
    Field('sideband_start', default=0.0, unit='s',
          doc='modulation switches on here'),
    Field('ff_xx', default=0.0,
          doc='feed-forward correction of Vx in the x pick-off'),
    Field('ff_xy', default=0.0,
          doc='feed-forward correction of Vy in the x pick-off'),
    Field('ff_yx', default=0.0,
          doc='feed-forward correction of Vx in the y pick-off'),
    Field('ff_yy', default=0.0,
          doc='feed-forward correction of Vy in the y pick-off'),
    Field('excitation_amplitude', default=0.2, unit='V',
          doc='mode 0: amplitude of each tone on Vx and Vy'),
    Field('excitation_offset_x', default=200.0, unit='Hz',
          doc='mode 0: Vx tones at f_nominal -/+ this'),
    Field('excitation_offset_y', default=230.0, unit='Hz',
          doc='mode 0: Vy tones at f_nominal -/+ this'),))

LOOP_GAINS = Struct("GyroLoopGains", "Gains derived once from the settings (gyro_loops_init).", (
    Field("w_nominal", unit="rad/s"),
    Field("pll_kp", doc="PLL: 2 pi B"), Field("pll_ki", doc="PLL: (2 pi B)^2 / 4"),
    Field("agc_kp", doc="AGC: 2 zeta wn / c (zeta 0.7)"), Field("agc_ki", doc="AGC: wn^2 / c"),
    Field("agc_feedforward", unit="V", doc="amplitude / (c tau), tau = Q / (pi f)"),
    Field("rebalance_gain", doc="2 pi B / c"),
    Field("rebalance_wi", unit="1/s", doc="2 pi B / 5")))

LOOP_STATE = Struct("GyroLoopState", "The loop state: NCO, integrators, low-pass sections "
                    "(re, im pairs), held drives.", (
    Field("theta", unit="rad", doc="NCO phase in [0, 2 pi)"),
    Field("omega", unit="rad/s", doc="NCO frequency"),
    Field("pll_integral"), Field("agc_integral"),
    Field("agc_lowpass", shape=(3, 2), doc="the PLL/AGC demodulator's 3 sections"),
    Field("rebalance_lowpass", shape=(2, 2)), Field("rebalance_integral", shape=(2,)),
    Field("v_held", shape=(2,), unit="V", doc="Vx, Vy of this hold"),
    Field("v_previous", shape=(2,), unit="V",
          doc="of the previous hold (feed-forward removal)")))

#: The loops' outputs, in order (GyroLoops.fmu's outputs).
LOOP_OUTPUT_NAMES = ("Vx", "Vy", "theta", "omega", "amplitude", "phase_error", "gain", "rate",
                     "quad")
LOOP_OUTPUTS = Struct("GyroLoopOutputs", "The loops' outputs of the last step.",
                      tuple(Field(n) for n in LOOP_OUTPUT_NAMES))

LOOPS = Struct("GyroLoops", "The loops as the library and GyroLoops.fmu step them.", (
    Field("settings", LOOP_SETTINGS), Field("gains", LOOP_GAINS), Field("state", LOOP_STATE),
    Field("out", LOOP_OUTPUTS)))

_I64 = "int64_t"
DEMOD = Struct("GyroDemod", "A self-calibration record demodulated while it runs "
               "(gyro_demod.h): settings, the caller's output arrays, running sums.", (
    Field("omega0", unit="rad/s", doc="mixing frequency"), Field("h", unit="s", doc="step"),
    Field("r0", _I64, doc="first step of the record"),
    Field("n", _I64, doc="steps in the record (a multiple of B)"),
    Field("B", _I64, doc="decimation"),
    Field("tail", _I64, doc="full-rate pick-off steps kept at the record's end (<= n)"),
    Field("drive_limit", unit="V", doc="the gain counted as pinned at or above it"),
    Field("base", "double *", doc="M x CHANNELS x 2: (re, im) of each filtered channel"),
    Field("theta", "double *", doc="M: NCO phase less omega0 t, filtered like the channels"),
    Field("tail_po", "double *", doc="tail x 2: Vpx, Vpy of the last `tail` record steps"),
    Field("kernel", "const double *", doc="ORDER * B weights (gyro_demod_kernel), the "
          "caller's"),
    Field("acc", shape=(DEMOD_ORDER, DEMOD_CHANNELS, 2)),
    Field("acc_theta", shape=(DEMOD_ORDER,)),
    Field("next", _I64, doc="the step expected next"),
    Field("theta_last"), Field("phase_departure"),
    Field("has_theta", "int32_t"), Field("reserved", "int32_t", hidden=True),
    Field("worst_phase_error"), Field("sum_amplitude"), Field("gain_peak"), Field("sum_gain"),
    Field("pinned", _I64), Field("counted", _I64), Field("emitted", _I64)))

CONSTANTS = (RES_N, RES_FORCED, DEMOD_ORDER, DEMOD_CHANNELS, NOISE_MAX)
STRUCTS = (RESONATOR_PARAMS, RESONATOR_MAPS, RESONATOR, LOOP_SETTINGS, LOOP_GAINS, LOOP_STATE,
           LOOP_OUTPUTS, LOOPS, DEMOD)
