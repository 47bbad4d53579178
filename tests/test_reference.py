"""Reference results inside the FMUs, and the check users put in their CI."""

from __future__ import annotations

import shutil
import zipfile

import pytest
from fmpy.validation import validate_fmu

from gyro_fmu.cli import main
from gyro_fmu.fmu.build import FMU_NAMES
from gyro_fmu.fmu.reference import LS_REF_DIR, MANIFEST


@pytest.mark.parametrize("name", FMU_NAMES)
def test_every_fmu_carries_reference_results_that_it_reproduces(models_dir, name, capsys):
    path = models_dir / f"{name}.fmu"
    names = zipfile.ZipFile(path).namelist()
    assert MANIFEST in names and f"{LS_REF_DIR}/{name}_out.csv" in names
    assert validate_fmu(str(path)) == []  # the extra folder keeps the FMU valid
    assert main(["validate", str(path)]) == 0
    out = capsys.readouterr().out
    assert "FAIL" not in out and "all outputs match" in out


def _tamper(src, dst, name, column, factor):
    """Copy the FMU, scaling one reference column by `factor`."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item)
            if item.filename == f"{LS_REF_DIR}/{name}_out.csv":
                lines = data.decode().splitlines()
                header = lines[0].split(",")
                j = header.index(f'"{column}"') if f'"{column}"' in header else header.index(column)
                rows = [lines[0]]
                for line in lines[1:]:
                    cells = line.split(",")
                    cells[j] = repr(float(cells[j]) * factor)
                    rows.append(",".join(cells))
                data = ("\n".join(rows) + "\n").encode()
            zout.writestr(item, data)


def test_a_changed_model_fails_the_check_and_exits_nonzero(models_dir, tmp_path, capsys):
    bad = tmp_path / "GyroPlant.fmu"
    _tamper(models_dir / "GyroPlant.fmu", bad, "GyroPlant", "y", 1.001)
    assert main(["validate", str(bad)]) == 1
    out = capsys.readouterr().out
    assert "FAIL  y" in out and "pass  x " in out


def test_an_fmu_without_references_fails_clearly(models_dir, tmp_path, capsys):
    bare = tmp_path / "Bare.fmu"
    shutil.copy(models_dir / "TwoToneDrive.fmu", bare)
    with zipfile.ZipFile(models_dir / "TwoToneDrive.fmu") as zin, \
            zipfile.ZipFile(bare, "w") as zout:
        for item in zin.infolist():
            if not item.filename.startswith("extra/"):
                zout.writestr(item, zin.read(item))
    assert main(["validate", str(bare)]) == 1
    assert "carries no reference results" in capsys.readouterr().out


def test_the_reference_inputs_are_the_declarations_whatever_the_flavour():
    """The inputs of an FMU's reference run come from its declaration (FmuInterface), one
    place for both flavours: a pythonfmu slave source names only its variables, and the
    reference inputs need no pythonfmu (issue 47)."""
    from gyro_fmu.fmu import build
    from gyro_fmu.fmu.interfaces import NATIVE_INTERFACES
    from gyro_fmu.fmu.reference import reference_inputs
    from gyro_fmu.pythonfmu import slaves

    assert sorted(build.PYTHONFMU_NAMES) == sorted(
        p.stem for p in slaves.source_dir().glob("[!_]*.py"))
    for name in build.PYTHONFMU_NAMES:
        source = (slaves.source_dir() / f"{name}.py").read_text()
        assert "reference_inputs" not in source and "DOCTOR_CHECK" not in source, name
        ours = reference_inputs(name, 1e-4, 5e-6)
        declared = NATIVE_INTERFACES[name].reference_inputs(1e-4, 5e-6)
        assert (ours is None and declared is None) or (ours == declared).all(), name
    table = reference_inputs("GyroPlant", 1e-4, 5e-6)
    assert table.dtype.names == ("time", "ux", "uy", "Omega_z") and table.size == 21
    assert reference_inputs("TwoToneDrive", 1e-4, 5e-6) is None
    assert reference_inputs("NoSuchModel", 1e-4, 5e-6) is None  # none of ours: no inputs
