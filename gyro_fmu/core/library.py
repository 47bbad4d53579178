"""Load the C core (fmu_src/core/*.c) compiled for this platform, through ctypes.

The build (`gyro_fmu.fmu.native`, run by `pip install`) compiles the core for every
platform into gyro_fmu/core/lib/<platform>/; this module picks the one of the running
Python. The C structs appear here as ctypes Structures with the same field names.
"""

from __future__ import annotations

import ctypes
import dataclasses
import functools
import platform
import sys
from ctypes import POINTER, c_char_p, c_double, c_int, c_size_t, c_uint64
from pathlib import Path

from ..errors import GyroFmuError
from .structs import plant as structs

LIB_DIR = Path(__file__).resolve().parent / "lib"
#: Platform folder (FMI 3.0 platform tuple) -> file name of the core library.
LIBRARY_FILES = {
    "x86_64-linux": "libgyro_core.so",
    "aarch64-linux": "libgyro_core.so",
    "x86_64-windows": "gyro_core.dll",
    "x86_64-darwin": "libgyro_core.dylib",
    "aarch64-darwin": "libgyro_core.dylib",
}


class CoreUnavailableError(GyroFmuError, ImportError):
    """The compiled core is missing for this platform."""


def platform_tuple() -> str:
    """FMI 3.0 platform tuple of the running Python, e.g. 'x86_64-linux'."""
    machine = platform.machine().lower()
    arch = {"amd64": "x86_64", "x86_64": "x86_64", "arm64": "aarch64",
            "aarch64": "aarch64"}.get(machine, machine)
    system = {"win32": "windows", "darwin": "darwin"}.get(sys.platform,
                                                          sys.platform.rstrip("0123456789"))
    return f"{arch}-{system}"


#: The structs, as ctypes mirrors of their one declaration (gyro_fmu.core.structs).
Params, PickoffNoise, State, TwoToneDrive, RateProfile = (
    s.ctypes() for s in (structs.PARAMS, structs.PICKOFF_NOISE, structs.STATE,
                         structs.TWO_TONE_DRIVE, structs.RATE_PROFILE))


_D = POINTER(c_double)
#: name -> (restype, argtypes) of every core function the library calls.
CORE_FUNCTIONS = {
    "gyro_system_matrix": (None, [POINTER(Params), c_double, _D]),
    "gyro_held_input_maps": (None, [POINTER(Params), c_double, c_double, _D, _D]),
    "gyro_params_problems": (c_int, [POINTER(Params), c_char_p, c_size_t]),
    "gyro_params_warning": (c_int, [POINTER(Params), c_char_p, c_size_t]),
    "gyro_rate_limit": (c_double, [POINTER(Params)]),
    "gyro_rate_problem": (c_int, [POINTER(Params), c_char_p, c_double, c_char_p, c_size_t]),
    "gyro_max_growth_rate": (c_double, [POINTER(Params), c_double]),
    "gyro_plant_size": (c_size_t, []),
    "gyro_plant_init": (None, [ctypes.c_void_p, POINTER(Params), POINTER(PickoffNoise),
                               c_uint64, POINTER(State)]),
    "gyro_plant_step": (None, [ctypes.c_void_p, c_double, c_double, c_double, c_double]),
    "gyro_plant_outputs": (None, [ctypes.c_void_p, _D]),
    "gyro_plant_restored_problem": (c_int, [ctypes.c_void_p, POINTER(Params),
                                            POINTER(PickoffNoise), c_char_p, c_size_t]),
    "gyro_drive_ux": (c_double, [POINTER(TwoToneDrive), c_double]),
    "gyro_drive_problems": (c_int, [POINTER(TwoToneDrive), c_char_p, c_size_t]),
    "gyro_rate_Omega_z": (c_double, [POINTER(RateProfile), c_double]),
    "gyro_rate_problems": (c_int, [POINTER(RateProfile), c_char_p, c_size_t]),
    "gyro_drive_nyquist_problem": (c_int, [POINTER(TwoToneDrive), c_double, c_char_p,
                                           c_size_t]),
    "gyro_rate_nyquist_problem": (c_int, [POINTER(RateProfile), c_double, c_char_p,
                                          c_size_t]),
    "gyro_drive_rate_bound": (c_double, [POINTER(Params), POINTER(TwoToneDrive), c_double,
                                         c_double, c_int, c_double]),
    "gyro_drive_information_loss": (c_double, [POINTER(Params), POINTER(TwoToneDrive),
                                               c_double, c_double, c_int,
                                               POINTER(TwoToneDrive)]),
    "gyro_drive_warning": (c_int, [POINTER(Params), POINTER(TwoToneDrive), c_double, c_double,
                                   c_int, c_char_p, c_size_t]),
}


def library_path(tuple_: str | None = None) -> Path:
    tuple_ = tuple_ or platform_tuple()
    return LIB_DIR / tuple_ / LIBRARY_FILES.get(tuple_, "libgyro_core.so")


@functools.cache
def core() -> ctypes.CDLL:
    """The core library of this platform, its functions typed (loaded once)."""
    path = library_path()
    if not path.is_file():
        raise CoreUnavailableError(
            f"the compiled gyro_fmu core is missing for {platform_tuple()} ({path}): "
            "reinstall gyro_fmu (pip install gyro_fmu, or pip install -e . in a checkout: "
            "the build compiles it with ziglang), or run `python build_fmu.py --native`")
    lib = ctypes.CDLL(str(path))
    for name, (restype, argtypes) in CORE_FUNCTIONS.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, argtypes
    return lib


class PickledAsFields:
    """A frozen dataclass that keeps the core's struct of its fields (ctypes: not
    picklable) is pickled as its fields, and the struct is made again: a process pool can
    take it."""

    def __reduce__(self):
        return (type(self), tuple(getattr(self, f.name) for f in dataclasses.fields(self)))


def core_text(name: str, *args: object) -> str | None:
    """Call a core check `name(*args, msg, n)` (it returns non-zero with a message when it
    finds something); its message, or None when it returns 0."""
    msg = ctypes.create_string_buffer(4096)
    return msg.value.decode() if getattr(core(), name)(*args, msg, len(msg)) else None
