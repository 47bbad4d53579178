"""What a GyroStateObserver's get_state() / set_state() carry of the core's structs: the
state's version, which fields of the held-step cache travel, and the copies of a ctypes
struct's named fields to and from plain floats and lists (JSON-able)."""

from __future__ import annotations

import ctypes
from collections.abc import Iterable

import numpy as np

STATE_VERSION = 5  # 5: nu2 holds the covariance's noise EWMA too (0.4.0)
#: The held-step cache's watch fields a state keeps (its maps are rebuilt from them).
HELD_FIELDS = ("valid", "h", "xc", "steady", "tol")


def fields(struct: ctypes.Structure, names: Iterable[str] | None = None) -> dict:
    """The struct's fields `names` (default: all) as floats and (nested) lists."""
    names = [n for n, _ in struct._fields_] if names is None else names
    return {n: np.ctypeslib.as_array(v).tolist() if isinstance(v := getattr(struct, n),
                                                                 ctypes.Array) else v
            for n in names}


def restore(struct: ctypes.Structure, values: dict) -> None:
    """Each of `values` into the struct's field of that name (arrays by their shape)."""
    for name, value in values.items():
        if isinstance(field := getattr(struct, name), ctypes.Array):
            view = np.ctypeslib.as_array(field)
            view[...] = np.array(value, dtype=float).reshape(view.shape)
        else:
            setattr(struct, name, float(value))
