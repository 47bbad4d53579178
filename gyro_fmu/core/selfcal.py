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
from ctypes import POINTER, c_char_p, c_double, c_int, c_int64, c_size_t, c_uint64

from .library import core
from .structs import selfcal as structs
from .structs.plant import RNG

N_STATE, N_FORCED = int(structs.RES_N), int(structs.RES_FORCED)
N_DRAWS, CARRIER_COLUMNS = 8, 12  # gyro_resonator.h GYRO_RES_DRAWS; gyro_carrier.h
_D = c_double
_N = N_STATE

#: Fields of ResonatorParameters and LoopSettings, their Integer ones, the loops' outputs.
RESONATOR_FIELDS = tuple(f.name for f in structs.RESONATOR_PARAMS.settings)
LOOP_FIELDS = tuple(f.name for f in structs.LOOP_SETTINGS.settings)
RESONATOR_INTEGERS = tuple(f.name for f in structs.RESONATOR_PARAMS.settings if f.integer)
LOOP_INTEGERS = tuple(f.name for f in structs.LOOP_SETTINGS.settings if f.integer)
LOOP_OUTPUTS = structs.LOOP_OUTPUT_NAMES
DEMOD_ORDER, DEMOD_CHANNELS = int(structs.DEMOD_ORDER), int(structs.DEMOD_CHANNELS)

#: The structs, as ctypes mirrors of their one declaration (gyro_fmu.core.structs).
Rng = RNG.ctypes()
(ResonatorParams, ResonatorMaps, Resonator, LoopSettings, LoopGains, LoopState, LoopOutputs,
 Loops, Demod) = (s.ctypes() for s in (
    structs.RESONATOR_PARAMS, structs.RESONATOR_MAPS, structs.RESONATOR, structs.LOOP_SETTINGS,
    structs.LOOP_GAINS, structs.LOOP_STATE, structs.LOOP_OUTPUTS, structs.LOOPS, structs.DEMOD))


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
