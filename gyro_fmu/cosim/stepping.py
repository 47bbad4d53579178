"""The master's stepping loop: the C core's gyro_master_steps (fmu_src/core/gyro_master.c).

Each FMI call from a Python loop costs ~1-2 us of ctypes work on top of what the FMU
does (measured in 0.2.0, CHANGELOG.md); over 10 calls per communication step that was more than the
whole in-process computation. The loop therefore runs in C and calls the FMUs'
fmi2GetReal / fmi2SetReal / fmi2DoStep through their addresses, as any C master does:
one getReal per FMU with outputs, one setReal per connected FMU, one doStep per FMU,
Jacobi order (master.py builds the plan; tests/test_master.py holds it against a plain
Python loop through fmpy). An FMU written in Python (pythonfmu) takes the GIL for each
call: ctypes releases it around this call, so those FMUs run as they would in any host.
"""

from __future__ import annotations

import ctypes
import functools
from ctypes import POINTER, c_double, c_int64, c_void_p

import numpy as np

from ..core import structs
from ..core.library import core

#: Phase codes returned with a refused call.
GET, SET, STEP = 0, 1, 2
_I64 = POINTER(c_int64)


#: The C structs (declared once: gyro_fmu/core/structs/master.py).
MasterPlan = structs.master.PLAN.ctypes()
MasterOutcome = structs.master.OUTCOME.ctypes()


@functools.cache
def _steps():
    fn = core().gyro_master_steps
    fn.restype = MasterOutcome
    fn.argtypes = [POINTER(c_double), c_int64, c_int64, c_int64, c_double, c_double, c_int64,
                   c_int64, POINTER(MasterPlan)]
    return fn


def _p(a: np.ndarray, kind):
    return a.ctypes.data_as(POINTER(kind))


def make_plan(get_fn, get_comp, get_vrs, get_n, get_col, set_fn, set_comp, set_vrs, set_n,
              set_col, set_first, gather, buf, step_fn, step_comp) -> MasterPlan:
    """The C plan over the master's arrays (int64 addresses, counts and columns; they must
    outlive it: the master keeps them)."""
    return MasterPlan(
        get_fn.size, _p(get_fn, c_void_p), _p(get_comp, c_void_p), _p(get_vrs, c_void_p),
        _p(get_n, c_int64), _p(get_col, c_int64),
        set_fn.size, _p(set_fn, c_void_p), _p(set_comp, c_void_p), _p(set_vrs, c_void_p),
        _p(set_n, c_int64), _p(set_col, c_int64), _p(set_first, c_int64), _p(gather, c_int64),
        _p(buf, c_double), step_fn.size, _p(step_fn, c_void_p), _p(step_comp, c_void_p))


def step_loop(data: np.ndarray, start_time: float, h: float, first: int, last: int,
              plan: MasterPlan, row0: int = 0, final: int | None = None
              ) -> tuple[int, int, int, int]:
    """Fill data[k - row0] for the points k = first..last and step every FMU from each of
    those t_k but the run's final one (`final`, default len(data) - 1): the master calls it
    in chunks, into one array for the whole run (row0 0) or one reused per chunk (row0 =
    first). Returns (k, phase, index, status) of the first call whose status exceeds
    fmi2Warning, or (last, -1, -1, 0)."""
    if not (data.flags.c_contiguous and data.dtype == np.float64):
        raise ValueError("the result array must be C-contiguous float64")
    final = data.shape[0] - 1 if final is None else final
    if not (0 <= first - row0 and last - row0 < data.shape[0] and last <= final):
        raise ValueError(f"points {first}..{last} from row {row0} do not fit the "
                         f"{data.shape[0]} rows of a run ending at point {final}")
    out = _steps()(_p(data, c_double), int(row0), int(final), data.shape[1],
                   float(start_time), float(h), int(first), int(last), ctypes.byref(plan))
    return out.k, out.phase, out.index, out.status
