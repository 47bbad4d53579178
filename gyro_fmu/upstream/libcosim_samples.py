"""libcosimpy 0.0.6: `CosimObserver.slave_real_samples` drops a sample.

Its wrapper trims the result of cosim_observer_slave_get_real_samples by counting the
step numbers equal to 0, which drops one sample whenever step 0 (the initial values) is
in the range asked for. `get_real_samples` declares the C function itself, so every
sample arrives. Canary: tests/test_upstream.py::test_libcosimpy_still_drops_a_sample.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable


def get_real_samples() -> Callable[..., int]:
    """cosim_observer_slave_get_real_samples(observer, slave, value_ref, from_step, n,
    values, step_numbers, times) -> samples read, typed through ctypes."""
    from libcosimpy._internal import libcosimc

    fn = libcosimc().cosim_observer_slave_get_real_samples
    fn.restype = ctypes.c_int64
    fn.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_uint32, ctypes.c_int64,
                   ctypes.c_size_t, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
    return fn
