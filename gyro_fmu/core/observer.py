"""The C core's observer (fmu_src/core/gyro_observer.h) as ctypes Structures, same names.

`GyroObserver` is the whole filter in one plain struct: the Python library
(gyro_fmu.estimation.observer.GyroStateObserver) holds one and looks at its arrays
through numpy views; GyroObserver.fmu holds the same struct in its model data.
"""

from __future__ import annotations

import ctypes
import functools
from ctypes import POINTER, c_char, c_char_p, c_double, c_int, c_int32, c_size_t

from .library import Params, RateProfile, TwoToneDrive, core

NPAR, IPAR, IOM, NMAX, MMAX, RMAX = 7, 4, 11, 14, 7, 3
#: Result codes of gyro_observer_step / update / predict.
STEP_OK, STEP_WARNING, STEP_LOST, BAD_INPUT, TOO_COARSE, REFUSED = 0, 1, 2, -1, -2, -3
#: GyroObserverTuning's Integer fields (the rest are doubles).
INTEGER_FIELDS = ("rate_model", "omega_order", "joseph")
_D = c_double


class Tuning(ctypes.Structure):
    _fields_ = [*((n, _D) for n in ("noise_rel", "sigma_z1", "sigma_z2", "innov_floor",
                                    "innov_tau")),
                ("rate_model", c_int32), ("omega_order", c_int32),
                *((n, _D) for n in ("rate_bandwidth", "rate_span", "rate_dwell", "q_Omega",
                                    "q_param_rel", "sigma0_k_rel", "sigma0_d_rel",
                                    "sigma0_m_rel", "sigma0_Omega", "sigma0_Omega_rate",
                                    "sigma0_Omega_acc", "sigma0_position", "sigma0_velocity")),
                ("joseph", c_int32), ("reserved", c_int32)]


class MonitorLimits(ctypes.Structure):
    _fields_ = [("block", c_int32), ("absolute", c_int32),
                *((n, _D) for n in ("nis_warn", "nis_lost", "rel_warn", "rel_lost", "ratio",
                                    "d_max", "omega_max", "corr_warn", "nis_min"))]


class Monitor(ctypes.Structure):
    #: In this order they are the 16 numbers of GyroStateObserver.get_state()["monitor"].
    _fields_ = [*((n, _D) for n in ("nis", "count", "status", "cause", "which", "value",
                                    "block", "last_nis", "last_rel")),
                ("prev", _D * 2), ("ac", _D * 2), ("sq", _D * 2), ("last_corr", _D)]


class Refit(ctypes.Structure):
    _fields_ = [("W", _D * 8 * 4), ("g", _D * 8), ("F", _D * 8 * 8), ("weight", _D),
                ("last_T", _D), ("shift", _D * 8), ("move", _D * 8), ("restarts", _D),
                ("pending", _D)]


class HeldMaps(ctypes.Structure):
    _fields_ = [("valid", _D), ("h", _D), ("xc", _D * 8), ("steady", _D), ("tol", _D),
                ("reused", _D), ("built", _D),
                ("norm", _D * 8), ("Phi", _D * 4 * 4), ("psi", _D * 4 * 2),
                ("Sk", _D * 8 * 4 * 6)]


class Observer(ctypes.Structure):
    _fields_ = [("tuning", Tuning),
                *((n, c_int32) for n in ("pair", "n", "order", "n_models", "i0", "auto_prior",
                                         "status", "lost")),
                ("theta0", _D * NPAR), ("scale", _D * NPAR), ("wx", _D), ("wy", _D),
                ("hgain", _D * 2), ("MgT", _D * 16 * 5), ("lim", MonitorLimits),
                ("h_cached", _D), ("qpar", _D),
                ("Fr", _D * RMAX * RMAX * MMAX), ("Qr", _D * RMAX * RMAX * MMAX),
                ("Pi", _D * MMAX * MMAX),
                ("x", _D * NMAX), ("P", _D * NMAX * NMAX), ("xs", _D * NMAX * MMAX),
                ("Ps", _D * NMAX * NMAX * MMAX), ("mu", _D * MMAX), ("c", _D * MMAX),
                ("peak", _D * 2), ("nu2", _D * 2), ("mon", Monitor), ("refit", Refit),
                ("t", _D), ("held", HeldMaps),
                ("lost_message", c_char * 1024)]


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
    "gyro_observer_held_restored": (c_int, [_O, c_char_p, c_size_t]),
    "gyro_observer_cholesky_ok": (c_int, [_DP, c_int]),
    "gyro_observer_factorial": (_D, [c_int]),
    "gyro_observer_beta": (_D, [c_int, c_int]),
    "gyro_observer_mix": (None, [_O]),
    "gyro_observer_combine": (None, [_O, _DP, _DP, _DP]),
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
