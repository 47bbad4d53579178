"""The C core's observer (fmu_src/core/gyro_observer.h) as ctypes Structures, same names.

`GyroObserver` is the whole filter in one plain struct: the Python library
(gyro_fmu.estimation.observer.GyroStateObserver) holds one and looks at its arrays
through numpy views; GyroObserver.fmu holds the same struct in its model data.
"""

from __future__ import annotations

import ctypes
import functools
from ctypes import POINTER, c_char_p, c_double, c_int, c_size_t

from .library import Params, RateProfile, TwoToneDrive, core
from .structs import observer as structs

NPAR, NMAX, MMAX, RMAX = (int(c) for c in (structs.NPAR, structs.NMAX, structs.MMAX,
                                           structs.RMAX))
IPAR, IOM = 4, 11  # gyro_observer.h: filter-state rows of the first parameter, of Omega_z
#: Result codes of gyro_observer_step / update / predict.
STEP_OK, STEP_WARNING, STEP_LOST, BAD_INPUT, TOO_COARSE, REFUSED = 0, 1, 2, -1, -2, -3
#: GyroObserverTuning's Integer fields (the rest are doubles).
INTEGER_FIELDS = tuple(f.name for f in structs.TUNING.settings if f.integer)
_D = c_double


#: The structs, as ctypes mirrors of their one declaration (gyro_fmu.core.structs).
Tuning, MonitorLimits, Monitor, Refit, HeldMaps, Wander, Observer = (
    s.ctypes() for s in (structs.TUNING, structs.MONITOR_LIMITS, structs.MONITOR,
                         structs.REFIT, structs.HELD, structs.WANDER, structs.OBSERVER))


_O = POINTER(Observer)
_DP = POINTER(c_double)
FUNCTIONS = {
    "gyro_observer_size": (c_size_t, []),
    "gyro_observer_rough_grades": (c_int, [_DP, c_int]),
    "gyro_observer_tuning_problems": (c_int, [POINTER(Tuning), c_char_p, c_size_t]),
    "gyro_observer_init": (c_int, [_O, POINTER(Params), _D, c_int, POINTER(Tuning), c_char_p,
                                   c_size_t]),
    "gyro_observer_step": (c_int, [_O, _D, _D, _D, _D, _D, c_char_p, c_size_t]),
    "gyro_observer_update": (c_int, [_O, _D, _D, _D, c_char_p, c_size_t]),
    "gyro_observer_predict": (c_int, [_O, _D, _D, _D, c_char_p, c_size_t]),
    "gyro_observer_held_step": (None, [_O, _DP, _D, _DP, _D, _D, _D, _DP, _DP, _DP]),
    "gyro_observer_outputs": (None, [_O, _DP]),
    "gyro_observer_rate_probabilities": (None, [_O, _DP]),
    "gyro_observer_warning": (c_int, [_O, c_char_p, c_size_t]),
    "gyro_observer_restart_message": (c_int, [_O, c_char_p, c_size_t]),
    "gyro_observer_step_warning": (c_int, [_O, _D, c_char_p, c_size_t]),
    "gyro_observer_set_scaling": (None, [_O, _D, _D, _DP, _DP]),
    "gyro_observer_set_step": (None, [_O, _D]),
    "gyro_observer_state_restored": (c_int, [_O, c_char_p, c_size_t]),
    "gyro_observer_cholesky_ok": (c_int, [_DP, c_int]),
    "gyro_observer_factorial": (_D, [c_int]),
    "gyro_observer_beta": (_D, [c_int, c_int]),
    "gyro_observer_mix": (None, [_O]),
    "gyro_observer_combine": (None, [_O, _DP, _DP, _DP]),
    "gyro_observer_complete_covariance": (None, [_O]),
    # the standard system in one C loop (gyro_chain.h): drive, rate, plant, observer
    "gyro_chain_run": (ctypes.c_int64, [POINTER(TwoToneDrive), POINTER(RateProfile),
                                        ctypes.c_void_p, _O, c_int, _D, ctypes.c_int64, _DP,
                                        POINTER(c_int), c_char_p, c_size_t]),
}


@functools.cache
def observer_core() -> ctypes.CDLL:
    """The core library with the observer's functions typed (its struct size checked)."""
    lib = core()
    for name, (restype, argtypes) in FUNCTIONS.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, argtypes
    if lib.gyro_observer_size() != ctypes.sizeof(Observer):
        raise ImportError(f"gyro_fmu.core.observer.Observer is {ctypes.sizeof(Observer)} bytes, "
                          f"the core's GyroObserver {lib.gyro_observer_size()}: rebuild the core "
                          "(python build_fmu.py --native)")
    return lib


def rough_grades() -> tuple[float, ...]:
    """The adaptive set's graded rough models: intensities as multiples of the rough one's."""
    buf = (c_double * MMAX)()
    m = observer_core().gyro_observer_rough_grades(buf, MMAX)
    return tuple(buf[:m])


def prior_fraction() -> float:
    """gyro_observer_prior_fraction: the drive-started prior's share of the deflection."""
    return c_double.in_dll(observer_core(), "gyro_observer_prior_fraction").value


def tuning_problem(values: dict[str, float]) -> str | None:
    """The core's verdict on a tuning (field name -> value): the first problem or None."""
    msg = ctypes.create_string_buffer(1024)
    t = Tuning(**values)
    return msg.value.decode() if observer_core().gyro_observer_tuning_problems(
        ctypes.byref(t), msg, len(msg)) else None


def cholesky_ok(P) -> bool:
    """The monitor's test of a covariance (n x n, n <= NMAX): a Cholesky factor exists."""
    import numpy as np

    n = P.shape[0]
    padded = np.zeros((NMAX, NMAX))
    padded[:n, :n] = P
    return bool(observer_core().gyro_observer_cholesky_ok(
        padded.ctypes.data_as(_DP), n))


__all__ = [
    "Monitor",
    "MonitorLimits",
    "Observer",
    "Tuning",
    "cholesky_ok",
    "observer_core",
    "prior_fraction",
    "tuning_problem",
]
