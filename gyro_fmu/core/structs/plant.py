"""The plant's structs (US 2011/0314910 A1, eqs. 3-4 and 10): parameters in the patent's
normalized form, pick-off noise, state, drive, rate profile; and the sensor's readout and
the platform example's parameters."""

from __future__ import annotations

from .base import Constant, Field, Struct

#: Largest |stiffness| (1/s^2) and |damping| (1/s) the model integrates accurately: beyond
#: them the eigenvalues of the system matrix lose all precision in double arithmetic
#: (dxx=1e300 gave "math range error"). 1.6 GHz and 1e10 1/s are far beyond any MEMS part.
K_MAX = Constant("GYRO_K_MAX", 1e20, "largest |stiffness| the model integrates, 1/s^2")
D_MAX = Constant("GYRO_D_MAX", 1e10, "largest |damping| the model integrates, 1/s")


def _k(name: str, label: str, **bounds) -> Field:
    return Field(name, unit="1/s2", doc=f"{label} / m", label=label, max=K_MAX.value, **bounds)


def _d(name: str, label: str, **bounds) -> Field:
    return Field(name, unit="1/s", doc=f"{label} / m", label=label, max=D_MAX.value, **bounds)


RNG = Struct("GyroRng", "xoshiro256** seeded through splitmix64, normals by Marsaglia's "
             "polar method (gyro_rng.h).", (
    Field("s", "uint64_t", shape=(4,), doc="xoshiro256** state"),
    Field("spare", doc="second normal of the last polar pair"),
    Field("has_spare", "int32_t", doc="1 when spare is unused"),
    Field("reserved", "int32_t", hidden=True)))

#: Main-axis stiffnesses and the mass are > 0 (min_exclusive: FMI's min is inclusive, the
#: FMU refuses the min itself too), main-axis dampings >= 0; cross terms may be negative.
PARAMS = Struct("GyroParams", "The gyroscope's parameters, normalized by the proof mass "
                "(eqs. 3-4): k's 1/s^2, d's 1/s, m kg (only as the input gain 1/m).", (
    _k("kxx", "x-axis stiffness", min=0.0, min_exclusive=True, nominal=1e8),
    _k("kyy", "y-axis stiffness", min=0.0, min_exclusive=True, nominal=1e8),
    _k("kxy", "cross-axis stiffness", nominal=1e7),
    _d("dxx", "x-axis damping", min=0.0, nominal=10.0),
    _d("dyy", "y-axis damping", min=0.0, nominal=10.0),
    _d("dxy", "cross-axis damping", nominal=1.0),
    Field("m", unit="kg", doc="proof mass", label="mass", min=0.0, min_exclusive=True,
          nominal=1e-7)), info="GYRO_PARAMS_INFO")

PICKOFF_NOISE = Struct(
    "GyroPickoffNoise", "Standard deviations of white Gaussian noise on each measured "
    "signal (m, m/s).", tuple(Field(n, unit=u) for n, u in
                              (("x", "m"), ("vx", "m/s"), ("y", "m"), ("vy", "m/s"))))

STATE = Struct("GyroState", "The plant's state [x, x', y, y'] (m, m/s).",
               tuple(Field(n, unit=u) for n, u in
                     (("x", "m"), ("vx", "m/s"), ("y", "m"), ("vy", "m/s"))))

TWO_TONE_DRIVE = Struct(
    "GyroTwoToneDrive", "ux = A1 sin(2 pi f1 t) + A2 sin(2 pi f2 t), uy = 0 (eq. 10): two "
    "distinct tones make W_kd of eq. 7 full rank, so the 8 unknowns can be separated.", (
        Field("A1", unit="N", doc="amplitude of tone 1"),
        Field("f1", unit="Hz", doc="frequency of tone 1"),
        Field("A2", unit="N", doc="amplitude of tone 2"),
        Field("f2", unit="Hz", doc="frequency of tone 2")))

RATE_PROFILE = Struct("GyroRateProfile", "A rate profile Omega_z(t) (gyro_signals.h).", (
    Field("kind", "int32_t", doc="GyroRateKind"),
    Field("reserved", "int32_t", hidden=True),
    Field("offset", unit="rad/s"), Field("amplitude", unit="rad/s"),
    Field("frequency", unit="Hz"), Field("slope", unit="rad/s2"), Field("t_start", unit="s")))

READOUT = Struct("GyroReadout", "The sensor's readout: its internal step, output filter, "
                 "range and quantization (gyro_sensor.h).", (
    Field("internal_step", unit="s", doc="0: auto, GYRO_SENSOR_STEP_MAX"),
    Field("bandwidth", unit="Hz", doc="-3 dB of the output filter"),
    Field("full_scale", unit="rad/s", doc="the output's limit"),
    Field("resolution", unit="rad/s", doc="per least significant bit (0: not quantized)")))

PLATFORM_PARAMS = Struct("GyroPlatformParams", "The stabilized platform (gyro_platform.h).", (
    Field("J", unit="kg.m2", doc="inertia, > 0"),
    Field("c", unit="N.m.s/rad", doc="bearing friction, > 0"),
    Field("Kp", unit="N.m.s/rad", doc="proportional gain, >= 0"),
    Field("Ki", unit="N.m/rad", doc="integral gain, >= 0")))

CONSTANTS = (K_MAX, D_MAX)
STRUCTS = (RNG, PARAMS, PICKOFF_NOISE, STATE, TWO_TONE_DRIVE, RATE_PROFILE, READOUT,
           PLATFORM_PARAMS)
