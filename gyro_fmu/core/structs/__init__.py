"""Every C struct the Python side sees, declared once (fields, C types, shapes, units,
meaning; for an FMU's settings also defaults and bounds). From here come:

- the core's header gyro_structs.h (`header()`; written into the build folder and every
  FMU's sources/ by gyro_fmu.fmu.native, never committed), which the C headers include;
- the ctypes mirrors (`Struct.ctypes()`) the library passes to the core;
- the settings dataclasses' fields (`declared`: GyroParameters, ObserverTuning,
  ResonatorParameters, LoopSettings), hence the FMU parameters and the docs;
- the copies from an FMU's variables into a struct (`copy_function`, in variables.h).

The core's constant tables (`tables`) are computed here too, into gyro_tables.h.

Structs only C uses (the plant's cached maps, the sensor) stay in their C headers.
"""

from __future__ import annotations

from . import master, observer, plant, selfcal, tables
from .base import Constant, Field, Struct, c_number, copy_function, declared

CONSTANTS: tuple[Constant, ...] = (*plant.CONSTANTS, *observer.CONSTANTS, *selfcal.CONSTANTS,
                                   *master.CONSTANTS)
#: In dependency order (a struct after those it holds).
STRUCTS: tuple[Struct, ...] = (*plant.STRUCTS, *observer.STRUCTS, *selfcal.STRUCTS,
                               *master.STRUCTS)

__all__ = ["CONSTANTS", "GENERATED", "STRUCTS", "Constant", "Field", "Struct", "copy_function",
           "declared", "header"]


def header() -> str:
    """gyro_structs.h: the constants and typedefs above, in C."""
    lines = ["/* The C core's structs that Python sees, generated from their one declaration",
             " * (gyro_fmu/core/structs/) by gyro_fmu.fmu.native: do not edit. */",
             "#ifndef GYRO_STRUCTS_H", "#define GYRO_STRUCTS_H", "", "#include <stddef.h>",
             "#include <stdint.h>", ""]
    for c in CONSTANTS:
        value = c_number(c.value) if isinstance(c.value, float) else str(c.value)
        lines.append(f"#define {c.name} {value} /* {c.doc} */")
    lines += ["", "/* One field of a struct, for messages that name it. */",
              "typedef struct {", "    const char *name, *label, *unit;", "    double nominal;",
              "} GyroFieldInfo;", "", "/* The master's calls (gyro_master.h). */",
              *master.FUNCTION_TYPES]
    for s in STRUCTS:
        lines += ["", *s.c_typedef()]
    return "\n".join([*lines, "", "#endif", ""])


#: The core's generated headers by file name (the build folder and every FMU's sources/).
GENERATED = {"gyro_structs.h": header, "gyro_tables.h": tables.header}
