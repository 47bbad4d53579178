"""The C core's self-calibration resonator, loops, carrier run and streaming demodulator
(fmu_src/core/gyro_resonator.h, gyro_loops.h, gyro_carrier.h, gyro_demod.h) as ctypes
Structures, same names.

The library (gyro_fmu.model.resonator, gyro_fmu.model.loops, gyro_fmu.selfcal.inprocess)
holds one `Resonator` and one `Loops` and steps them here; GyroResonator.fmu and
GyroLoops.fmu hold the same structs in their model data. The settings structs follow the
field order of ResonatorParameters and LoopSettings (a test holds it).
"""

from __future__ import annotations

import ctypes
import functools
from ctypes import POINTER, c_char_p, c_double, c_int, c_int32, c_int64, c_size_t, c_uint64

from .library import core

N_STATE, N_FORCED, N_DRAWS, CARRIER_COLUMNS = 10, 6, 8, 12
_D = c_double
_N = N_STATE

#: Integer fields of ResonatorParameters and LoopSettings (the rest are doubles).
RESONATOR_INTEGERS = ("cubic_substeps", "thermal_update_steps")
LOOP_INTEGERS = ("mode", "sideband_first", "sideband_count")
RESONATOR_FIELDS = (
    "f_x", "f_y", "Q_x", "Q_y", "dxy", "kxy", "kappa", "Bx", "By", "alpha_x", "alpha_y", "Px",
    "Py", "phi_x", "phi_y", "Exx", "Exy", "Eyx", "Eyy", "c_ring", "k3x", "k3y",
    "cubic_substeps", "ring_amplitude", "ring_frequency_1", "ring_frequency_2", "noise",
    "beta_x", "beta_y", "k3xy", "k3yx", "m_modal", "temperature", "drive_noise",
    "temperature_rate", "tc_f", "tc_Q", "thermal_update_steps", "warmup_span", "warmup_tau",
    "temperature_noise")
LOOP_FIELDS = (
    "mode", "f_nominal", "amplitude", "q_nominal", "plant_gain", "pll_bandwidth",
    "agc_bandwidth", "rebalance_bandwidth", "demod_cutoff", "rebalance_cutoff", "drive_limit",
    "osc_phase", "sideband_index", "sideband_spacing", "sideband_first", "sideband_count",
    "sideband_start", "ff_xx", "ff_xy", "ff_yx", "ff_yy", "excitation_amplitude",
    "excitation_offset_x", "excitation_offset_y")
#: GyroLoopOutputs, in order.
LOOP_OUTPUTS = ("Vx", "Vy", "theta", "omega", "amplitude", "phase_error", "gain", "rate",
                "quad")


def _fields(names: tuple[str, ...], integers: tuple[str, ...]) -> list:
    return [(n, c_int32 if n in integers else _D) for n in names]


class ResonatorParams(ctypes.Structure):
    _fields_ = _fields(RESONATOR_FIELDS, RESONATOR_INTEGERS)


class Rng(ctypes.Structure):
    _fields_ = [("s", c_uint64 * 4), ("spare", _D), ("has_spare", c_int32),
                ("reserved", c_int32)]


class ResonatorMaps(ctypes.Structure):
    _fields_ = [("Phi", _D * _N * _N), ("Gamma", _D * 2 * _N), ("L", _D * N_FORCED * _N),
                ("Omega_z", _D), ("h", _D), ("dT", _D), ("valid", c_int32),
                ("reserved", c_int32)]


class Resonator(ctypes.Structure):
    _fields_ = [("p", ResonatorParams), ("seed", c_uint64), ("s", _D * _N), ("out", _D * 2),
                ("T_sensor", _D), ("k", c_int64), ("noise_rng", Rng), ("force_rng", Rng),
                ("sensor_rng", Rng), ("maps", ResonatorMaps)]


class LoopSettings(ctypes.Structure):
    _fields_ = _fields(LOOP_FIELDS, LOOP_INTEGERS)


class LoopGains(ctypes.Structure):
    _fields_ = [(n, _D) for n in ("w_nominal", "pll_kp", "pll_ki", "agc_kp", "agc_ki",
                                  "agc_feedforward", "rebalance_gain", "rebalance_wi")]


class LoopState(ctypes.Structure):
    _fields_ = [("theta", _D), ("omega", _D), ("pll_integral", _D), ("agc_integral", _D),
                ("agc_lowpass", _D * 2 * 3), ("rebalance_lowpass", _D * 2 * 2),
                ("rebalance_integral", _D * 2), ("v_held", _D * 2), ("v_previous", _D * 2)]


class LoopOutputs(ctypes.Structure):
    _fields_ = [(n, _D) for n in LOOP_OUTPUTS]


class Loops(ctypes.Structure):
    _fields_ = [("settings", LoopSettings), ("gains", LoopGains), ("state", LoopState),
                ("out", LoopOutputs)]


#: gyro_demod.h: GYRO_DEMOD_ORDER, GYRO_DEMOD_CHANNELS.
DEMOD_ORDER, DEMOD_CHANNELS = 5, 4


class Demod(ctypes.Structure):
    _fields_ = [("omega0", _D), ("h", _D), ("r0", c_int64), ("n", c_int64), ("B", c_int64),
                ("tail", c_int64), ("drive_limit", _D), ("base", POINTER(_D)),
                ("theta", POINTER(_D)), ("tail_po", POINTER(_D)), ("kernel", POINTER(_D)),
                ("acc", _D * 2 * DEMOD_CHANNELS * DEMOD_ORDER),
                ("acc_theta", _D * DEMOD_ORDER), ("next", c_int64),
                ("theta_last", _D), ("phase_departure", _D), ("has_theta", c_int32),
                ("reserved", c_int32), ("worst_phase_error", _D), ("sum_amplitude", _D),
                ("gain_peak", _D), ("sum_gain", _D),
                ("pinned", c_int64), ("counted", c_int64), ("emitted", c_int64)]


_P = POINTER(_D)
_R, _L = POINTER(Resonator), POINTER(Loops)
_MSG = [c_char_p, c_size_t]
FUNCTIONS = {
    "gyro_resonator_problems": (c_int, [POINTER(ResonatorParams), *_MSG]),
    "gyro_resonator_at_temperature": (c_int, [POINTER(ResonatorParams), _D, _P, *_MSG]),
    "gyro_resonator_temperature_offset": (_D, [POINTER(ResonatorParams), _D]),
    "gyro_resonator_system": (c_int, [POINTER(ResonatorParams), _D, _D, _P, _P, *_MSG]),
    "gyro_resonator_discretize": (c_int, [POINTER(ResonatorParams), _D, _D, _D, _P, _P, *_MSG]),
    "gyro_resonator_force_covariance": (c_int, [POINTER(ResonatorParams), _D, _D, _D, _P,
                                                *_MSG]),
    "gyro_white_noise_covariance": (None, [c_int, _P, _P, _D, _P]),
    "gyro_expm": (None, [c_int, _P, _P]),
    "gyro_resonator_init": (c_int, [_R, POINTER(ResonatorParams), c_uint64, _P, *_MSG]),
    "gyro_resonator_maps": (c_int, [_R, _D, _D, *_MSG]),
    "gyro_resonator_step": (c_int, [_R, _D, _D, _D, _D, *_MSG]),
    "gyro_resonator_steps_left": (c_int64, [_R]),
    "gyro_resonator_size": (c_size_t, []),
    "gyro_resonator_params_size": (c_size_t, []),
    "gyro_loop_settings_problems": (c_int, [POINTER(LoopSettings), *_MSG]),
    "gyro_loops_init": (c_int, [_L, POINTER(LoopSettings), *_MSG]),
    "gyro_loops_step": (None, [_L, _D, _D, _D, _D]),
    "gyro_loops_size": (c_size_t, []),
    "gyro_loop_settings_size": (c_size_t, []),
    "gyro_carrier_run": (c_int, [_R, _L, c_int64, c_int64, _D, _D, _P, c_int64, c_int64,
                                 POINTER(c_int64), *_MSG]),
    "gyro_demod_kernel": (None, [c_int64, _P]),
    "gyro_demod_init": (c_int, [POINTER(Demod), _D, _D, c_int64, c_int64, c_int64, c_int64, _D,
                                _P, _P, _P, _P, *_MSG]),
    "gyro_demod_first_step": (c_int64, [POINTER(Demod)]),
    "gyro_demod_last_step": (c_int64, [POINTER(Demod)]),
    "gyro_demod_feed": (c_int, [POINTER(Demod), _P, c_int64, c_int64, *_MSG]),
    "gyro_demod_response": (_D, [POINTER(Demod), _D]),
    "gyro_demod_size": (c_size_t, []),
}
_SIZES = {"gyro_resonator_size": Resonator, "gyro_resonator_params_size": ResonatorParams,
          "gyro_loops_size": Loops, "gyro_loop_settings_size": LoopSettings,
          "gyro_demod_size": Demod}


@functools.cache
def selfcal_core() -> ctypes.CDLL:
    """The core library with these functions typed (every struct's size checked)."""
    lib = core()
    for name, (restype, argtypes) in FUNCTIONS.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, argtypes
    for name, struct in _SIZES.items():
        if getattr(lib, name)() != ctypes.sizeof(struct):
            raise ImportError(f"gyro_fmu.core.selfcal.{struct.__name__} is "
                              f"{ctypes.sizeof(struct)} bytes, the core's {getattr(lib, name)()}"
                              ": rebuild the core (python build_fmu.py --native)")
    return lib


def message_buffer() -> ctypes.Array:
    return ctypes.create_string_buffer(4096)


class CoreStructState:
    """State of a library model that holds one core struct in `self.core`: the struct's
    bytes as hex text (the state, the generators and the cached maps, exactly), checked
    for size; `_state_error` names the model's error class."""

    core: ctypes.Structure
    _state_error: type[Exception] = ValueError

    def get_state(self) -> dict:
        return {"core": bytes(self.core).hex()}

    def set_state(self, state: dict) -> None:
        raw = bytes.fromhex(state["core"])
        if len(raw) != ctypes.sizeof(self.core):
            raise self._state_error(f"saved state is {len(raw)} bytes, this "
                                    f"{type(self).__name__}'s {ctypes.sizeof(self.core)}: "
                                    "save it with this version")
        ctypes.memmove(ctypes.byref(self.core), raw, len(raw))
