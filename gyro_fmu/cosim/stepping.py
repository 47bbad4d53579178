"""The master's stepping loop, compiled: raw FMI 2.0 calls from numba, no Python per call.

Each FMI call from a Python loop costs ~1-2 us of ctypes work on top of what the FMU
does (docs/performance.md); over 10 calls per communication step that was more
than the whole in-process computation. Here the loop is compiled and calls the FMUs'
fmi2GetReal / fmi2SetReal / fmi2DoStep through their addresses, exactly as a C master
would. The calls, their order and their arguments are those of the Python loop it
replaces (master.py: one getReal per FMU with outputs, one setReal per connected FMU,
one doStep per FMU, Jacobi order); an FMU written in Python (pythonfmu) still takes the
GIL for each call, which this thread holds.
"""

from __future__ import annotations

import ctypes

import llvmlite.ir as ir
import numpy as np
from numba import njit, types
from numba.extending import intrinsic

_I32, _I64, _F64 = ir.IntType(32), ir.IntType(64), ir.DoubleType()

# The intrinsics pass pointers and size_t as 64-bit integers.
assert ctypes.sizeof(ctypes.c_void_p) == 8 and ctypes.sizeof(ctypes.c_size_t) == 8, \
    "the compiled master loop needs a 64-bit platform"

#: Phase codes returned with a refused call.
GET, SET, STEP = 0, 1, 2


@intrinsic
def _fmi2_get_set_real(typingctx, function, component, vrs, nvr, values):
    """fmi2Status fmi2GetReal/fmi2SetReal(fmi2Component, const fmi2ValueReference*,
    size_t, fmi2Real*) called at address `function`; pointers passed as 64-bit integers
    (the x86-64 and AArch64 calling conventions pass both in the same registers)."""
    sig = types.int32(types.int64, types.int64, types.int64, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(_I32, [_I64, _I64, _I64, _I64])
        return builder.call(builder.inttoptr(args[0], fnty.as_pointer()), args[1:])

    return sig, codegen


@intrinsic
def _fmi2_do_step(typingctx, function, component, t, h, no_set_state_prior):
    """fmi2Status fmi2DoStep(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean) at `function`."""
    sig = types.int32(types.int64, types.int64, types.float64, types.float64, types.int32)

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(_I32, [_I64, _F64, _F64, _I32])
        return builder.call(builder.inttoptr(args[0], fnty.as_pointer()), args[1:])

    return sig, codegen


@njit(cache=True)
def step_loop(data: np.ndarray, start_time: float, h: float, first: int, last: int,
              get_fn: np.ndarray, get_comp: np.ndarray, get_vrs: np.ndarray,
              get_n: np.ndarray, get_col: np.ndarray,
              set_fn: np.ndarray, set_comp: np.ndarray, set_vrs: np.ndarray,
              set_n: np.ndarray, set_col: np.ndarray, set_first: np.ndarray,
              gather: np.ndarray, buf: np.ndarray,
              step_fn: np.ndarray, step_comp: np.ndarray) -> tuple[int, int, int, int]:
    """Fill data[k] for k = first..last and step every FMU from each of those t_k but
    the final one (k = n = len(data) - 1): the master calls it in chunks.

    Row k: time, then each FMU's outputs read at t_k = start_time + k h. Inputs of FMU i
    come from the row: columns set_col[i].. when consecutive (set_col >= 0), otherwise
    gathered through gather[set_first[i]:set_first[i] + set_n[i]] into buf first.
    Returns (k, phase, index, status) of the first call whose status exceeds fmi2Warning,
    or (last, -1, -1, 0) when every call succeeded.
    """
    n = data.shape[0] - 1
    row_addr = data.ctypes.data
    row_bytes = data.strides[0]
    buf_addr = buf.ctypes.data
    for k in range(first, last + 1):
        t = start_time + k * h
        addr = row_addr + k * row_bytes
        data[k, 0] = t
        for i in range(get_fn.size):
            status = _fmi2_get_set_real(get_fn[i], get_comp[i], get_vrs[i], get_n[i],
                                        addr + 8 * get_col[i])
            if status > 1:
                return k, GET, i, status
        if k == n:
            break
        for i in range(set_fn.size):
            j0 = set_first[i]
            if set_col[i] >= 0:
                values = addr + 8 * set_col[i]
            else:
                for j in range(j0, j0 + set_n[i]):
                    buf[j] = data[k, gather[j]]
                values = buf_addr + 8 * j0
            status = _fmi2_get_set_real(set_fn[i], set_comp[i], set_vrs[i], set_n[i], values)
            if status > 1:
                return k, SET, i, status
        for i in range(step_fn.size):
            status = _fmi2_do_step(step_fn[i], step_comp[i], t, h, 1)
            if status > 1:
                return k, STEP, i, status
    return last, -1, -1, 0
