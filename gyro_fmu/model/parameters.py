"""Gyroscope parameter sets in the patent's normalized form, presets and checks.

Normalization (US 2011/0314910 A1, eqs. 3-4): every stiffness and damping
coefficient is divided by the proof mass, so kxx, kyy, kxy are in 1/s^2 and
dxx, dyy, dxy in 1/s; m (kg) remains only as the input gain 1/m.
"""

from __future__ import annotations

import ctypes
import math
import warnings
from dataclasses import asdict, fields, replace

import numpy as np

from ..core.structs import declared
from ..core.structs.plant import D_MAX as D_MAX_C
from ..core.structs.plant import K_MAX as K_MAX_C
from ..core.structs.plant import PARAMS
from ..errors import GyroFmuError

#: Names of the seven fabrication-dependent parameters, in the patent's order.
PARAMETER_NAMES: tuple[str, ...] = PARAMS.names

#: SI unit of each parameter (normalized form).
PARAMETER_UNITS: dict[str, str] = {f.name: f.unit for f in PARAMS.fields}

#: Largest |stiffness| (1/s^2) and |damping| (1/s) the model integrates accurately
#: (gyro_fmu.core.structs.plant says why).
K_MAX, D_MAX = K_MAX_C.value, D_MAX_C.value

#: FMU min/max/nominal of each parameter: what physics allows, and its usual scale
#: (declared with the struct: gyro_fmu.core.structs.plant.PARAMS).
PARAMETER_BOUNDS: dict[str, dict[str, float | bool]] = {
    f.name: {k: v for k, v in f.metadata().items() if k not in ("unit", "description")}
    for f in PARAMS.fields}

#: What each parameter is ("x-axis stiffness / m"), the FMUs' descriptions.
PARAMETER_DESCRIPTIONS: dict[str, str] = {f.name: f.doc for f in PARAMS.fields}

DEFAULT_PRESET = "park-horowitz"


class ParameterError(GyroFmuError, ValueError):
    """A parameter set that cannot describe a physical gyroscope, or a bad name."""


class UnstablePlantWarning(UserWarning):
    """The parameter set has a growing mode; results stay finite only for short runs."""


@declared(PARAMS)
class GyroParameters:
    """Normalized parameters of the 2-DOF gyroscope (patent eqs. 3-4): kxx, kyy, kxy
    (stiffness / m, 1/s^2), dxx, dyy, dxy (damping / m, 1/s), m (proof mass, kg)."""

    def as_dict(self) -> dict[str, float]:
        return asdict(self)

    def with_overrides(self, **overrides: float) -> GyroParameters:
        """Return a copy with some parameters replaced; unknown names are an error."""
        unknown = sorted(set(overrides) - set(PARAMETER_NAMES))
        if unknown:
            raise ParameterError(
                f"unknown parameter(s) {unknown}: valid names are {list(PARAMETER_NAMES)}"
            )
        values = {k: _as_finite_float(k, v) for k, v in overrides.items()}
        return replace(self, **values)

    @property
    def K(self) -> np.ndarray:
        """Normalized stiffness matrix [[kxx, kxy], [kxy, kyy]], 1/s^2."""
        return np.array([[self.kxx, self.kxy], [self.kxy, self.kyy]])

    @property
    def D(self) -> np.ndarray:
        """Normalized damping matrix [[dxx, dxy], [dxy, dyy]], 1/s."""
        return np.array([[self.dxx, self.dxy], [self.dxy, self.dyy]])

    @property
    def rate_limit(self) -> float:
        """The slowest axis's angular frequency sqrt(min(kxx, kyy)), rad/s: no vibratory
        gyroscope senses a rate that fast (the Coriolis terms 2 Omega_z of eqs. 3-4 would
        outweigh the modes they couple). The core's gyro_rate_limit."""
        from ..core.library import core

        return float(core().gyro_rate_limit(_c_params(self)))

    def rate_problem(self, name: str, value: float) -> str | None:
        """Why `value` (rad/s) cannot be a rate of this gyro, None if it can: the core's
        gyro_rate_problem, with which GyroPlant.fmu and GyroObserver.fmu refuse it too."""
        from ..core.library import core_text

        return core_text("gyro_rate_problem", _c_params(self), name.encode(), float(value))


def _as_finite_float(name: str, value: object) -> float:
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ParameterError(f"parameter {name}={value!r} is not a number") from None
    if not math.isfinite(number):
        raise ParameterError(f"parameter {name}={value!r} must be finite")
    return number


_TWO_PI = 2.0 * math.pi

PRESETS: dict[str, GyroParameters] = {
    # The 2-DOF MEMS benchmark of the adaptive-control literature (Park & Horowitz),
    # m = 1.8e-7 kg, Kxx = 63.955, Kyy = 95.92, Kxy = 12.779 N/m, Dxx = Dyy = 1.8e-6,
    # Dxy = 3.6e-7 N s/m, normalized by m. Positive definite K and D.
    "park-horowitz": GyroParameters(
        kxx=63.955 / 1.8e-7,
        kyy=95.92 / 1.8e-7,
        kxy=12.779 / 1.8e-7,
        dxx=1.8e-6 / 1.8e-7,
        dyy=1.8e-6 / 1.8e-7,
        dxy=3.6e-7 / 1.8e-7,
        m=1.8e-7,
    ),
    # Table 1 of US 2011/0314910 A1 exactly as printed: K is indefinite (unstable).
    "patent-table1": GyroParameters(
        kxx=(_TWO_PI * 3000.0) ** 2,
        kyy=(_TWO_PI * 900.0) ** 2,
        kxy=(_TWO_PI * 3000.0) ** 2,
        dxx=10.0,
        dyy=0.0,
        dxy=10.0,
        m=0.9,
    ),
    # Table 1 with kxy replaced by the benchmark's 12.779 / 1.8e-7 = 7.10e7 1/s^2.
    "patent-table1-corrected": GyroParameters(
        kxx=(_TWO_PI * 3000.0) ** 2,
        kyy=(_TWO_PI * 900.0) ** 2,
        kxy=12.779 / 1.8e-7,
        dxx=10.0,
        dyy=0.0,
        dxy=10.0,
        m=0.9,
    ),
}

#: Per-tone drive amplitude (N) that gives the preset displacements of order 1e-9 m.
#: The patent's eq. 10 uses unit amplitudes with m = 0.9 kg; the benchmark's proof
#: mass is 5e6 times lighter, so its force is scaled to give similar displacements.
PRESET_DRIVE_AMPLITUDE: dict[str, float] = {
    "park-horowitz": 1.0e-7,
    "patent-table1": 1.0,
    "patent-table1-corrected": 1.0,
}


def preset(name: str = DEFAULT_PRESET, **overrides: float) -> GyroParameters:
    """Look up a preset by name and apply per-parameter overrides."""
    try:
        base = PRESETS[name]
    except KeyError:
        raise ParameterError(
            f"unknown preset {name!r}: choose one of {sorted(PRESETS)}"
        ) from None
    return base.with_overrides(**overrides)


def system_matrix(p: GyroParameters, Omega_z: float = 0.0) -> np.ndarray:
    """Continuous-time matrix A of state [x, vx, y, vy] (consistent form of eqs. 3-4).

    The equations are written once, in the C core's gyro_system_matrix (which the plant
    and the observer call); this is its entry point for numpy.
    """
    from ..core.library import core

    A = np.empty((4, 4))
    core().gyro_system_matrix(_c_params(p), float(Omega_z),
                              A.ctypes.data_as(ctypes.POINTER(ctypes.c_double)))
    return A


def _c_params(p: GyroParameters) -> object:
    from ..core.library import Params

    return ctypes.byref(Params(*(float(getattr(p, n)) for n in PARAMETER_NAMES)))


def max_growth_rate(p: GyroParameters, Omega_z: float = 0.0) -> float:
    """Largest real part of the eigenvalues of A (1/s); > 0 means a growing mode (the C
    core's gyro_max_growth_rate, which GyroPlant.fmu uses)."""
    from ..core.library import core

    return float(core().gyro_max_growth_rate(_c_params(p), float(Omega_z)))


def check_parameters(p: GyroParameters) -> list[str]:
    """Problems that make a parameter set unusable for a plant (empty when usable).

    A pure function in the manner of fmpy.validation: it lists, it does not raise. The
    checks and their words are the C core's (gyro_params_problems), the ones GyroPlant.fmu
    refuses with at initialization.
    """
    from ..core.library import core_text

    problem = core_text("gyro_params_problems", _c_params(p))
    return [problem] if problem else []


def validate_for_plant(p: GyroParameters) -> GyroParameters:
    """Raise ParameterError if unusable; warn with the growth rate if a mode grows (the
    core's gyro_params_warning, GyroPlant.fmu's warning at initialization)."""
    from ..core.library import core_text

    problems = check_parameters(p)
    if problems:
        raise ParameterError("; ".join(problems))
    warning = core_text("gyro_params_warning", _c_params(p))
    if warning:
        warnings.warn(warning, UnstablePlantWarning, stacklevel=2)
    return p


def parameter_field_names() -> list[str]:
    return [f.name for f in fields(GyroParameters)]


#: Multipliers from truth to the observer's default initial guess: a part whose
#: every parameter is a few percent to 20% away from what the observer assumes.
INITIAL_GUESS_FACTORS: dict[str, float] = {
    "kxx": 1.05, "kyy": 0.95, "kxy": 1.05, "dxx": 1.2, "dyy": 1.2, "dxy": 0.8, "m": 1.05,
}
#: Initial guess of a damping whose truth is 0 (1/s), where a factor cannot move it.
INITIAL_GUESS_FOR_ZERO_DAMPING = 2.0


def default_initial_guess(p: GyroParameters) -> dict[str, float]:
    """Observer start: truth times INITIAL_GUESS_FACTORS (documented in the README)."""
    guess = {n: getattr(p, n) * f for n, f in INITIAL_GUESS_FACTORS.items()}
    for name in ("dxx", "dyy", "dxy"):
        if getattr(p, name) == 0.0:
            guess[name] = INITIAL_GUESS_FOR_ZERO_DAMPING
    return guess
