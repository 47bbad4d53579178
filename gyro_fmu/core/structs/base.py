"""How a C struct is declared once: its fields (C type, shape, unit, meaning, and for the
settings an FMU takes, default and bounds), from which come the C typedef (the generated
header gyro_structs.h), the ctypes mirror, the settings dataclass's fields and the copies
from an FMU's variables into the struct."""

from __future__ import annotations

import ctypes
import dataclasses
import functools
import inspect
import math
import textwrap
from dataclasses import dataclass
from typing import Any

#: C type -> ctypes type (pointers as c_void_p-sized POINTERs of their target).
_SCALARS = {"double": ctypes.c_double, "int32_t": ctypes.c_int32, "int64_t": ctypes.c_int64,
            "uint64_t": ctypes.c_uint64, "char": ctypes.c_char}
_VOIDS = ctypes.POINTER(ctypes.c_void_p)
_POINTERS = {"double *": ctypes.POINTER(ctypes.c_double),
             "const double *": ctypes.POINTER(ctypes.c_double),
             "const int64_t *": ctypes.POINTER(ctypes.c_int64),
             # arrays of addresses: the master's components, value references, functions
             "void **": _VOIDS, "const uint32_t **": _VOIDS, "GyroFmi2GetSetReal *": _VOIDS,
             "GyroFmi2DoStep *": _VOIDS}


@dataclass(frozen=True)
class Constant:
    """A #define the structs' shapes (or the C code) use: name, value, meaning."""

    name: str
    value: int | float
    doc: str

    def __int__(self) -> int:
        return int(self.value)


@dataclass(frozen=True)
class Field:
    """One member: C type (a scalar above, a pointer, or another Struct), array shape, and
    for a setting: unit, meaning, default, bounds (FMU min/max/nominal) and its Python type."""

    name: str
    ctype: Any = "double"
    shape: tuple = ()
    unit: str = ""
    doc: str = ""
    default: Any = None
    min: float | None = None
    max: float | None = None
    nominal: float | None = None
    min_exclusive: bool = False
    #: Python type of the setting (bool for an Integer 0/1); None: from the C type.
    pytype: type | None = None
    #: padding or an internal member: in the struct, not among the settings
    hidden: bool = False
    #: a short noun for messages ("x-axis stiffness"); the doc when empty
    label: str = ""

    @property
    def dims(self) -> tuple[int, ...]:
        return tuple(int(d) for d in self.shape)

    @property
    def integer(self) -> bool:
        return self.ctype in ("int32_t", "int64_t", "uint64_t")

    @property
    def python_type(self) -> type:
        return self.pytype or (int if self.integer else float)

    def metadata(self) -> dict:
        """What dataclass_parameters puts into an FMU variable (unit, description, bounds)."""
        meta = {"unit": self.unit or "1", "description": self.doc}
        for key in ("min", "max", "nominal"):
            if getattr(self, key) is not None:
                meta[key] = getattr(self, key)
        if self.min_exclusive:
            meta["min_exclusive"] = True
        return meta

    def c_decl(self) -> str:
        ctype = self.ctype.name if isinstance(self.ctype, Struct) else self.ctype
        dims = "".join(f"[{d.name if isinstance(d, Constant) else d}]" for d in self.shape)
        space = "" if ctype.endswith("*") else " "
        return f"{ctype}{space}{self.name}{dims};"

    def c_member(self) -> str:
        """The member's line in its typedef, with unit and meaning as a comment wrapped at
        92 columns."""
        parts = [p for p in (self.unit, self.doc) if p]
        if not parts:
            return f"    {self.c_decl()}"
        return textwrap.fill(", ".join(parts) + " */", 92,
                             initial_indent=f"    {self.c_decl()} /* ",
                             subsequent_indent="     * ")

    def ctypes_type(self):
        if isinstance(self.ctype, Struct):
            base = self.ctype.ctypes()
        else:
            base = _SCALARS.get(self.ctype) or _POINTERS[self.ctype]
        for d in reversed(self.dims):
            base = base * d
        return base


@dataclass(frozen=True)
class Struct:
    """A C struct: typedef name, what it is (a C comment), its fields in memory order."""

    name: str
    doc: str
    fields: tuple[Field, ...]
    #: also give C the fields' names, labels, units and nominals: #define <info>
    #: {{"kxx", "x-axis stiffness", "1/s2", 1e8}, ...} (GyroFieldInfo rows), for messages
    info: str = ""

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.fields)

    @property
    def settings(self) -> tuple[Field, ...]:
        """The fields a user sets (not padding, not internal)."""
        return tuple(f for f in self.fields if not f.hidden)

    def ctypes(self) -> type[ctypes.Structure]:
        """The ctypes mirror (one class per Struct, made on first use)."""
        return self._ctypes_class

    @functools.cached_property
    def _ctypes_class(self) -> type[ctypes.Structure]:
        return type(self.name, (ctypes.Structure,), {
            "_fields_": [(f.name, f.ctypes_type()) for f in self.fields],
            "__doc__": f"{self.name} of the C core (generated: gyro_fmu.core.structs)."})

    def c_typedef(self) -> list[str]:
        doc = textwrap.fill(self.doc, 86, initial_indent="/* ", subsequent_indent=" * ")
        lines = [doc + " */", "typedef struct {"]
        lines += [f.c_member() for f in self.fields]
        lines.append(f"}} {self.name};")
        if self.info:
            rows = [f'{{"{f.name}", "{f.label or f.doc}", "{f.unit or "1"}", '
                    f'{c_number(f.nominal if f.nominal is not None else 0.0)}}}'
                    for f in self.settings]
            lines += [f"/* {self.name}'s fields: name, label, unit, nominal (GyroFieldInfo). */",
                      f"#define {self.info} {{ \\", *(f"    {r}, \\" for r in rows), "}"]
        return lines


def declared(struct: Struct):
    """Class decorator: a frozen dataclass whose fields are the struct's settings, in its
    order, with their defaults and metadata (unit, description, bounds). The class body
    adds methods only."""

    def wrap(cls: type) -> type:
        annotations = {}
        for f in struct.settings:
            annotations[f.name] = f.python_type
            kwargs = {"metadata": f.metadata()}
            if f.default is not None:
                kwargs["default"] = f.default
            setattr(cls, f.name, dataclasses.field(**kwargs))
        cls.__annotations__ = {**annotations, **inspect.get_annotations(cls)}
        return dataclass(frozen=True)(cls)

    return wrap


def c_number(value: float) -> str:
    """A double literal C reads back to the same value."""
    if math.isinf(value):
        return "INFINITY" if value > 0 else "-INFINITY"
    text = f"{float(value):g}"
    return text if float(text) == value and ("." in text or "e" in text) else repr(float(value))


def copy_function(function: str, struct: Struct, variables: set[str], rename: dict[str, str],
                  zero: tuple[str, ...] = ()) -> list[str]:
    """A C function `function(const Variables *v)` returning the struct filled from the
    FMU's variables: field f from variable rename.get(f, f) (rename may be a format with
    {}); fields in `zero` and hidden ones 0. Raises when a field has no variable."""
    body = [f"static inline {struct.name} {function}(const Variables *v) {{",
            f"    {struct.name} s = {{0}};"]
    pattern = rename.get("*", "{}")
    for f in struct.fields:
        if f.hidden or f.name in zero:
            continue
        var = rename.get(f.name, pattern.format(f.name))
        if var not in variables:
            raise ValueError(f"{function}: {struct.name}.{f.name} has no variable {var!r}")
        body.append(f"    s.{f.name} = v->{var};")
    return [*body, "    return s;", "}"]
