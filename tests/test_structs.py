"""The C structs Python sees are declared once (gyro_fmu/core/structs/): the generated
gyro_structs.h, as a C compiler lays it out, and the ctypes mirrors agree field by field;
the settings dataclasses and the FMUs' copies follow the same declaration."""

from __future__ import annotations

import ctypes
import dataclasses
import subprocess

import pytest

from gyro_fmu.core import structs
from gyro_fmu.estimation.observer_tuning import ObserverTuning
from gyro_fmu.fmu.native import NATIVE_INTERFACES, generated_headers, zig_command
from gyro_fmu.model.loops import LoopSettings
from gyro_fmu.model.parameters import GyroParameters
from gyro_fmu.model.resonator import ResonatorParameters


def _layout_program() -> str:
    """A C program printing `struct field offset size` for every field, then `struct
    sizeof`."""
    lines = ['#include <stddef.h>', '#include <stdio.h>', '#include "gyro_structs.h"',
             "int main(void) {"]
    for s in structs.STRUCTS:
        for f in s.fields:
            lines.append(f'    printf("{s.name} {f.name} %zu %zu\\n", offsetof({s.name}, '
                         f'{f.name}), sizeof((({s.name} *)0)->{f.name}));')
        lines.append(f'    printf("{s.name} sizeof %zu 0\\n", sizeof({s.name}));')
    return "\n".join([*lines, "    return 0;", "}", ""])


def test_the_compiled_layout_is_the_ctypes_mirrors(tmp_path) -> None:
    gen = generated_headers(tmp_path)
    (tmp_path / "layout.c").write_text(_layout_program())
    exe = tmp_path / "layout"
    subprocess.run([*zig_command(), "-target", "x86_64-linux-gnu", "-std=c11", f"-I{gen}",
                    str(tmp_path / "layout.c"), "-o", str(exe)], check=True,
                   capture_output=True)
    c_layout = {}
    for line in subprocess.run([str(exe)], check=True, capture_output=True,
                               text=True).stdout.splitlines():
        name, field, offset, size = line.split()
        c_layout[name, field] = (int(offset), int(size))
    checked = 0
    for s in structs.STRUCTS:
        mirror = s.ctypes()
        assert c_layout[s.name, "sizeof"][0] == ctypes.sizeof(mirror), s.name
        for f in s.fields:
            descriptor = getattr(mirror, f.name)
            assert c_layout[s.name, f.name] == (descriptor.offset, descriptor.size), \
                (s.name, f.name)
            checked += 1
    assert checked > 200


@pytest.mark.parametrize(("cls", "struct"), [
    (GyroParameters, structs.plant.PARAMS), (ObserverTuning, structs.observer.TUNING),
    (ResonatorParameters, structs.selfcal.RESONATOR_PARAMS),
    (LoopSettings, structs.selfcal.LOOP_SETTINGS)])
def test_the_settings_dataclasses_are_their_structs(cls, struct) -> None:
    fields = dataclasses.fields(cls)
    assert [f.name for f in fields] == [f.name for f in struct.settings]
    for f, d in zip(fields, struct.settings, strict=True):
        assert f.metadata == d.metadata()
        if d.default is not None:
            assert f.default == d.default
    mirror = struct.ctypes()
    hidden = {f.name for f in struct.fields if f.hidden}
    assert {n for n, _ in mirror._fields_} - hidden == {f.name for f in fields}


def test_every_copy_names_existing_variables() -> None:
    """A struct field with no FMU variable stops the build with its name (not a C error)."""
    copies = 0
    for interface in NATIVE_INTERFACES.values():
        names = {v.name for v in interface.variables}
        for copy in interface.struct_copies:
            structs.copy_function(copy.function, copy.struct, names, dict(copy.rename),
                                  copy.zero)
            copies += 1
    assert copies >= 10
    with pytest.raises(ValueError, match=r"GyroParams.m has no variable 'm_0'"):
        structs.copy_function("guess_of", structs.plant.PARAMS,
                              {f"{n}_0" for n in "kxx kyy kxy dxx dyy dxy".split()},
                              {"*": "{}_0"})


def test_every_declaration_module_is_in_the_prebuilt_stamp() -> None:
    """The headers are generated from every module of gyro_fmu/core/structs: each is among
    the files the prebuilt FMUs' staleness stamp hashes, so an edit to one (a table, a
    field) marks the FMUs stale instead of leaving binaries of the old declaration."""
    from pathlib import Path

    from gyro_fmu.fmu.sources import DECLARATION_FILES

    folder = Path(structs.__file__).parent
    modules = {f"core/structs/{p.name}" for p in folder.glob("*.py")}
    assert len(modules) >= 7
    assert modules <= set(DECLARATION_FILES), modules - set(DECLARATION_FILES)
