"""The C core's constant tables, computed here once and written into the generated header
gyro_tables.h (gyro_fmu.fmu.native, never committed): the factorials and the weights of
the observer's held step (US 2011/0314910 A1 eq. 5; fmu_src/core/gyro_observer_held.c)."""

from __future__ import annotations

import math

from .base import c_number

#: float(k!) for k < N_FACTORIAL (correctly rounded: Python's int is exact).
N_FACTORIAL = 48
#: Taylor terms of the held step: GYRO_OBS_KMAX in fmu_src/core/gyro_observer.h.
KMAX = 24

FACTORIAL = tuple(float(math.factorial(k)) for k in range(N_FACTORIAL))
#: beta[j][m] = j! m! / (j + m + 1)! in double precision, the Frechet series' weights.
BETA = tuple(tuple(FACTORIAL[j] * FACTORIAL[m] / FACTORIAL[j + m + 1] for m in range(KMAX))
             for j in range(KMAX))


def _rows(values: tuple[float, ...], indent: str) -> list[str]:
    numbers = [c_number(v) for v in values]
    return [indent + ", ".join(numbers[i:i + 4]) + "," for i in range(0, len(numbers), 4)]


def header() -> str:
    """gyro_tables.h: static const tables for the files that include it (no link-time
    symbol; an unused static const in a header draws no warning from gcc or clang)."""
    lines = ["/* The C core's constant tables, generated from gyro_fmu/core/structs/tables.py",
             " * by gyro_fmu.fmu.native: do not edit. */",
             "#ifndef GYRO_TABLES_H", "#define GYRO_TABLES_H", "",
             f"#if GYRO_OBS_KMAX != {KMAX}", '#error "gyro_tables.h: GYRO_OBS_KMAX changed"',
             "#endif", "", f"/* float(k!) for k < {N_FACTORIAL}. */",
             f"static const double GYRO_FACTORIAL[{N_FACTORIAL}] = {{",
             *_rows(FACTORIAL, "    "), "};", "",
             "/* beta[j][m] = j! m! / (j + m + 1)! in double precision for j, m < KMAX: the held",
             " * step's Frechet series weights (no division in the step). */",
             "static const double GYRO_OBS_BETA[GYRO_OBS_KMAX][GYRO_OBS_KMAX] = {"]
    for row in BETA:
        lines += ["    {", *_rows(row, "        "), "    },"]
    return "\n".join([*lines, "};", "", "#endif", ""])
