"""`gyro-fmu validate` as a library call: every FMU named is checked, each failure is one
line `<file>: FAIL: <reason and remedy>`, and the FMUs after a bad one are still checked
(CI wants the whole list, not the first traceback)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from pathlib import Path

from .reference import ReferenceResultError, validate_reference


def validate_files(paths: Iterable[str | Path], dy: float = 1e-6, dx: int = 1,
                   write: Callable[[str], object] = print) -> int:
    """Validate each FMU against its reference results; exit code 1 if anything failed,
    else 0. Only deliberate refusals (ReferenceResultError) become FAIL lines: any other
    exception is a bug of gyro_fmu and keeps its traceback."""
    if not (math.isfinite(dy) and 0.0 < dy < 1.0):
        raise ValueError(f"band dy={dy!r} must be a fraction in (0, 1) of each signal's range: "
                         "a NaN or zero band compares nothing, one of the whole range passes "
                         "anything")
    if isinstance(dx, bool) or not isinstance(dx, int) or dx < 1:
        raise ValueError(f"band dx={dx!r} must be a whole number of samples >= 1")
    failed = 0
    for fmu in paths:
        try:
            checks = validate_reference(Path(fmu), dy=dy, dx=dx)
        except ReferenceResultError as exc:
            write(f"{fmu}: FAIL: {exc}")
            failed += 1
            continue
        write(f"{fmu}: band dy={dy:g} of each signal's range, dx={dx} samples")
        for c in checks:
            write(f"  {'pass' if c.passed else 'FAIL'}  {c.name:<16} {c.outliers:>6} of "
                  f"{c.samples} samples outside, max |deviation| {c.max_abs_deviation:.3g}")
        failed += sum(not c.passed for c in checks)
    write("all outputs match their reference results" if not failed
          else f"{failed} check(s) failed")
    return 1 if failed else 0
