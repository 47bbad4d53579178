"""A host-side guard for fmpy's default FMU logger (a use after free in fmpy 0.3.x).

fmpy formats an FMU's variadic log messages in a C proxy (fmpy/logging/<platform>/
logging.so): `addLoggerProxy(callbacks)` stores `callbacks.logger` in ONE process-global
pointer and puts the proxy in its place. fmpy.fmi2.defaultCallbacks, which
`simulate_fmu(...)` without `logger=` and `FMU2Slave.instantiate()` without callbacks
use, went through that proxy at import. Every `simulate_fmu(..., logger=f)` re-points
the global at a ctypes thunk of f that is freed when that call's callbacks are
collected. A later run on the default callbacks then calls freed memory at the FMU's
first log message: a segfault (`logMessage` in logging.so), or "ValueError: PyObject is
NULL". No FMU can tell; any FMU that logs is hit (ours: the loader's fmi2Terminated
answer after a refusal, or any message with debug logging on).

`rearm_default_logger()` points the global back at fmpy's own printer through a thunk
that lives as long as the process, so the default callbacks print as they did at
import. Call it before a run on fmpy's default callbacks; it changes nothing for a run
that passes its own logger (simulate_fmu re-points the global for that run).
"""

from __future__ import annotations

import ctypes

_THUNK = None  #: the permanent thunk of fmpy's printLogMessage


def rearm_default_logger() -> bool:
    """Point fmpy's logger proxy at a live printer; False where fmpy has no such proxy."""
    global _THUNK
    try:
        from fmpy.fmi2 import fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, printLogMessage
        from fmpy.logging import addLoggerProxy
    except Exception:  # no fmpy, or a build without the native proxy
        return False
    if _THUNK is None:
        _THUNK = fmi2CallbackLoggerTYPE(printLogMessage)
    callbacks = fmi2CallbackFunctions()  # a fresh struct: the proxy skips one it already set
    callbacks.logger = _THUNK
    addLoggerProxy(ctypes.byref(callbacks))
    return True
