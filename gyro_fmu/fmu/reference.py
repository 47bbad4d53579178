"""Reference results inside each FMU (fmi-ls-ref) and the check users run in their CI.

Layout, as in the Modelica Reference-FMUs: under
`extra/org.fmi-standard.fmi-ls-ref/` every FMU carries `fmi-ls-manifest.xml`
(layered standard 1.0.0-alpha.1) naming `<Model>_out.csv`, the outputs of the
FMU's default experiment, and, for FMUs with inputs, `<Model>_in.csv`, the
inputs of that run (one row per communication point). The build writes them by
simulating the freshly built FMU with fmpy; `validate_reference` re-simulates
and compares every output with fmpy's tolerance-band check.
"""

from __future__ import annotations

import tempfile
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from xml.etree.ElementTree import Element, SubElement, fromstring, tostring

import numpy as np
from fmpy import read_model_description, simulate_fmu
from fmpy.util import read_csv, validate_signal, write_csv

from ..errors import GyroFmuError
from .build import load_slave

LS_REF_DIR = "extra/org.fmi-standard.fmi-ls-ref"
MANIFEST = f"{LS_REF_DIR}/fmi-ls-manifest.xml"
_LS = "http://fmi-standard.org/fmi-ls-manifest"


class ReferenceResultError(GyroFmuError, RuntimeError):
    """An FMU without usable reference results."""


def input_table(time: np.ndarray, columns: Mapping[str, np.ndarray]) -> np.ndarray:
    """Reference inputs as fmpy takes them: a structured array, 'time' first, then
    `columns` in their order."""
    table = np.zeros(time.size, dtype=[("time", float)] + [(n, float) for n in columns])
    table["time"] = time
    for name, column in columns.items():
        table[name] = column
    return table


def reference_inputs(model_name: str, stop_time: float, step: float) -> np.ndarray | None:
    """Inputs of an FMU's reference run (see `input_table`), or None for none.

    Each slave declares its own (`reference_inputs(stop_time, step)` of its class in
    the slave-source folder, found by `gyro_fmu.fmu.build.load_slave`); an FMU without
    a slave source there, or a slave that declares nothing, runs without inputs.
    """
    slave = load_slave(model_name)
    declared = getattr(slave, "reference_inputs", None)
    return None if declared is None else declared(stop_time, step)


def _experiment(fmu: Path) -> tuple[str, float, float]:
    md = read_model_description(str(fmu))
    de = md.defaultExperiment
    if de is None or de.stopTime is None or de.stepSize is None:
        raise ReferenceResultError(
            f"{fmu.name} has no DefaultExperiment with stopTime and stepSize")
    return md.coSimulation.modelIdentifier, float(de.stopTime), float(de.stepSize)


def _simulate(fmu: Path, inputs: np.ndarray | None, stop_time: float, step: float) -> np.ndarray:
    return simulate_fmu(str(fmu), stop_time=stop_time, output_interval=step, input=inputs)


def write_reference(fmu: Path) -> list[str]:
    """Simulate the FMU's default experiment and store the result inside the FMU."""
    fmu = Path(fmu)
    name, stop_time, step = _experiment(fmu)
    inputs = reference_inputs(name, stop_time, step)
    result = _simulate(fmu, inputs, stop_time, step)
    root = Element("fmiReferences", {"xmlns:fmi-ls": _LS,
                                     "fmi-ls:fmi-ls-name": "org.fmi-standard.fmi-ls-ref",
                                     "fmi-ls:fmi-ls-version": "1.0.0-alpha.1"})
    files: dict[str, np.ndarray] = {f"{name}_out.csv": result}
    SubElement(root, "Related", type="text/csv", source=f"{name}_out.csv", role="result",
               description="Outputs of the default experiment")
    if inputs is not None:
        files[f"{name}_in.csv"] = inputs
        SubElement(root, "Related", type="text/csv", source=f"{name}_in.csv", role="input",
                   description="Inputs of the default experiment, one row per step")
    with tempfile.TemporaryDirectory() as tmp, zipfile.ZipFile(fmu, "a") as z:
        for filename, table in files.items():
            path = Path(tmp) / filename
            write_csv(str(path), table)
            z.write(path, f"{LS_REF_DIR}/{filename}")
        z.writestr(MANIFEST, b'<?xml version="1.0" encoding="UTF-8"?>\n' + tostring(root))
    return sorted(files)


@dataclass(frozen=True)
class SignalCheck:
    """One output against its reference band."""

    name: str
    outliers: int
    samples: int
    max_abs_deviation: float

    @property
    def passed(self) -> bool:
        return self.outliers == 0


def _read_related(z: zipfile.ZipFile, tmp: Path) -> dict[str, np.ndarray]:
    try:
        manifest = fromstring(z.read(MANIFEST))
    except KeyError:
        raise ReferenceResultError(
            f"no {MANIFEST}: this FMU carries no reference results") from None
    tables = {}
    for rel in manifest.iter("Related"):
        path = tmp / rel.get("source")
        path.write_bytes(z.read(f"{LS_REF_DIR}/{rel.get('source')}"))
        tables[rel.get("role")] = read_csv(str(path))
    if "result" not in tables:
        raise ReferenceResultError(f"{MANIFEST} names no reference result (role='result')")
    return tables


def validate_reference(fmu: Path, dy: float = 1e-6, dx: int = 1) -> list[SignalCheck]:
    """Re-simulate the FMU's default experiment and check every output against its band.

    The band is fmpy.util.validate_signal's: the reference widened by dx samples in
    time and by dy times the signal's range in value. dy = 1e-6 passes rounding
    differences between machines and fails any change of the model itself. dx = 1
    (no widening in time): the communication points are exact, and a 2.5 kHz tone
    sampled at 200 kHz moves by a quarter of its amplitude in 3 samples, so any
    time widening would hide a 0.1% model change (measured by the tests).
    """
    fmu = Path(fmu)
    _, stop_time, step = _experiment(fmu)
    with tempfile.TemporaryDirectory() as tmp, zipfile.ZipFile(fmu) as z:
        tables = _read_related(z, Path(tmp))
    reference = tables["result"]
    result = _simulate(fmu, tables.get("input"), stop_time, step)
    t_ref = np.array(reference["time"], dtype=float)
    checks = []
    for var in reference.dtype.names[1:]:
        y_ref = np.array(reference[var], dtype=float)
        y = np.array(result[var], dtype=float)
        _, _, _, outside = validate_signal(result["time"], y, t_ref.copy(), y_ref,
                                           num=t_ref.size, dx=dx, dy=dy)
        deviation = float(np.max(np.abs(y - y_ref))) if y.shape == y_ref.shape else float("inf")
        checks.append(SignalCheck(var, int(np.sum(outside)), int(y.size), deviation))
    return checks
