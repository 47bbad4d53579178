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

import logging
import tempfile
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path
from xml.etree.ElementTree import Element, SubElement, fromstring, tostring

import numpy as np
from fmpy import read_model_description, simulate_fmu
from fmpy.util import validate_signal, write_csv

from ..cosim.archives import archive_problem
from ..errors import GyroFmuError
from ..upstream.fmpy_logger import rearm_default_logger

_log = logging.getLogger(__name__)
LS_REF_DIR = "extra/org.fmi-standard.fmi-ls-ref"
MANIFEST = f"{LS_REF_DIR}/fmi-ls-manifest.xml"
_LS = "http://fmi-standard.org/fmi-ls-manifest"


#: Most communication points of a reference run (the shipped ones have 20,001).
MAX_POINTS = 1e7
#: The time band (dx samples) may widen a signal's band by at most this fraction of its
#: range on average: a wider band spans the signal's own time scale and passes a doubled
#: or scaled reference (measured: --dx 300 passed GyroPlant with x doubled).
MAX_BAND_SPREAD = 0.25


class ReferenceResultError(GyroFmuError, RuntimeError):
    """An FMU without usable reference results."""


def reference_inputs(model_name: str, stop_time: float, step: float) -> np.ndarray | None:
    """Inputs of an FMU's reference run (see `input_table`), or None for none: its
    declaration's (FmuInterface.reference_inputs, by model identifier, whatever flavour the
    FMU was built in); an FMU that is none of ours runs without inputs."""
    from .interfaces import NATIVE_INTERFACES

    interface = NATIVE_INTERFACES.get(model_name)
    return None if interface is None else interface.reference_inputs(stop_time, step)


def _experiment(fmu: Path) -> tuple[str, float, float]:
    md = read_model_description(str(fmu))
    de = md.defaultExperiment
    if de is None or de.stopTime is None or de.stepSize is None:
        raise ReferenceResultError(
            f"{fmu.name} has no DefaultExperiment with stopTime and stepSize")
    stop, step = float(de.stopTime), float(de.stepSize)
    if not (np.isfinite(step) and step > 0.0):
        raise ReferenceResultError(f"DefaultExperiment stepSize={de.stepSize} s must "
                                   "be finite and > 0: the FMU is damaged; rebuild it")
    if not (np.isfinite(stop) and stop > 0.0):
        raise ReferenceResultError(f"DefaultExperiment stopTime={de.stopTime} s must "
                                   "be finite and > 0: the FMU is damaged; rebuild it")
    if stop / step > MAX_POINTS:
        raise ReferenceResultError(f"DefaultExperiment stopTime={stop:g} s over "
                                   f"stepSize={step:g} s makes {stop / step:.3g} communication "
                                   f"points, above the {MAX_POINTS:.0e} a reference run may "
                                   "take: the FMU is damaged; rebuild it")
    return md.coSimulation.modelIdentifier, stop, step


def _simulate(fmu: Path, inputs: np.ndarray | None, stop_time: float, step: float) -> np.ndarray:
    """The default experiment through fmpy. What the FMU logs goes to this module's
    logger (DEBUG; a container runtime logs its progress as errors: "[ERROR] Solver
    configure....", fmu-manipulation-toolbox 2.0), and its warnings and errors into the
    exception of a run that fails."""
    said: list[tuple[int, str]] = []

    def collect(*args) -> None:  # fmpy: (instance name, status, category, message)
        status, message = args[-3], args[-1]
        text = (message or b"").decode("utf-8", "replace").replace("%%", "%")
        said.append((int(status), text))
        _log.debug("%s: %s", fmu.name, text)

    # fmpy's default callbacks log through a process-global pointer that an earlier
    # simulate_fmu(logger=...) in this process may have left dangling: keep it pointing at
    # a live printer for the runs after this one (gyro_fmu.upstream.fmpy_logger).
    try:
        return simulate_fmu(str(fmu), stop_time=stop_time, output_interval=step, input=inputs,
                            logger=collect)
    except Exception as exc:
        told = "; ".join(t for s, t in said if s >= 1)[-2000:]
        raise RuntimeError(f"{exc}" + (f"; the FMU said: {told}" if told else "")) from exc
    finally:
        rearm_default_logger()


def write_reference(fmu: Path, inputs_of=None) -> list[str]:
    """Simulate the FMU's default experiment and store the result inside the FMU.
    inputs_of(stop_time, step) gives the inputs (see `input_table`); by default the FMU's
    declaration's (`reference_inputs`)."""
    fmu = Path(fmu)
    name, stop_time, step = _experiment(fmu)
    inputs = (reference_inputs(name, stop_time, step) if inputs_of is None
              else inputs_of(stop_time, step))
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
            z.write(path, f"{LS_REF_DIR}/{filename}", zipfile.ZIP_DEFLATED)
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


_MAX_MEMBER = 64 << 20  # bytes: a reference of this size is far past any default run


def _member(z: zipfile.ZipFile, name: str) -> bytes:
    """One archive member read into memory (at most _MAX_MEMBER bytes, CRC checked)."""
    try:
        with z.open(name) as f:
            data = f.read(_MAX_MEMBER + 1)
    except KeyError:
        raise ReferenceResultError(f"{name} is named but not in the archive: rebuild the "
                                   "FMU with `gyro-fmu build`") from None
    if len(data) > _MAX_MEMBER:
        raise ReferenceResultError(f"{name} is over {_MAX_MEMBER >> 20} MiB: not a reference")
    return data


def parse_csv(data: bytes, name: str) -> np.ndarray:
    """A cross-check CSV (quoted header, one float per cell) from bytes: fmpy's read_csv
    takes only a file name, and nothing taken from an archive is written to disk."""
    try:
        lines = data.decode("utf-8").splitlines()
        header = [h.strip().strip('"') for h in lines[0].split(",")]
        rows = [tuple(float(c) for c in line.split(",")) for line in lines[1:] if line.strip()]
        if len(set(header)) != len(header) or header[0] != "time":
            raise ValueError(f"header {header!r} must start with time and not repeat a name")
        if any(len(r) != len(header) for r in rows):
            raise ValueError(f"a row has not the {len(header)} cells of the header")
        return np.array(rows, dtype=[(h, float) for h in header])
    except (ValueError, IndexError, UnicodeDecodeError) as exc:
        raise ReferenceResultError(f"{name} is not a readable CSV ({exc}): rebuild the FMU "
                                   "with `gyro-fmu build`") from None


def _read_related(z: zipfile.ZipFile) -> dict[str, np.ndarray]:
    """The manifest's tables by role, read by name from inside the ls-ref folder only: a
    source with a folder part (../, /, \\) could name any file, so it is refused."""
    try:
        manifest = fromstring(_member(z, MANIFEST))
    except ReferenceResultError:
        if MANIFEST not in z.namelist():
            raise ReferenceResultError(
                f"no {MANIFEST}: this FMU carries no reference results") from None
        raise
    except Exception as exc:  # ParseError, or expat's errors on entity tricks
        raise ReferenceResultError(f"{MANIFEST} is not XML ({exc}): rebuild the FMU") from None
    tables: dict[str, np.ndarray] = {}
    for rel in manifest.iter("Related"):
        source, role = rel.get("source") or "", rel.get("role")
        if (not source or source in (".", "..") or any(c in source for c in "/\\:\0")
                or source != source.strip()):
            raise ReferenceResultError(
                f"{MANIFEST} names source {source!r}: a reference must be a plain file name "
                f"inside {LS_REF_DIR}/; the FMU is damaged or not trustworthy")
        if role in tables:
            raise ReferenceResultError(f"{MANIFEST} names role {role!r} twice")
        if role in ("result", "input"):
            tables[role] = parse_csv(_member(z, f"{LS_REF_DIR}/{source}"), source)
    if "result" not in tables:
        raise ReferenceResultError(f"{MANIFEST} names no reference result (role='result')")
    return tables


def check_coverage(table: np.ndarray, what: str, names: list[str],
                   stop_time: float, step: float) -> None:
    """Refuse a table that does not cover the run it claims: one row per communication
    point of the default experiment, time strictly increasing from 0 to stop_time,
    exactly the columns `names`, finite values. A cut table would compare nothing."""
    n = round(stop_time / step) + 1
    columns = list(table.dtype.names[1:])
    problems = []
    if set(columns) != set(names):
        missing, unknown = sorted(set(names) - set(columns)), sorted(set(columns) - set(names))
        problems.append(f"columns missing {missing}, unknown {unknown}")
    t = np.asarray(table["time"], dtype=float)
    if t.size != n:
        problems.append(f"{t.size} rows for the {n} communication points")
    elif not (np.all(np.diff(t) > 0) and abs(t[0]) <= 1e-9 * step
              and np.allclose(t, np.arange(n) * step, rtol=1e-9, atol=1e-9 * step)):
        problems.append(f"time not 0, {step:g}, ... {stop_time:g} s strictly increasing")
    if not all(np.all(np.isfinite(table[c])) for c in table.dtype.names):
        problems.append("values that are not finite")
    if problems:
        raise ReferenceResultError(f"reference {what} does not cover the default run: "
                                   + "; ".join(problems) + ": rebuild the FMU")


def validate_reference(fmu: Path, dy: float = 1e-6, dx: int = 1) -> list[SignalCheck]:
    """Re-simulate the FMU's default experiment and check every output against its band.

    The band is fmpy.util.validate_signal's: the reference widened by dx samples in
    time and by dy times the signal's range in value. dy = 1e-6 passes rounding
    differences between machines and fails any change of the model itself. dx = 1
    (no widening in time): the communication points are exact, and a 2.5 kHz tone
    sampled at 200 kHz moves by a quarter of its amplitude in 3 samples, so any
    time widening would hide a 0.1% model change (measured by the tests).
    Raises ReferenceResultError (with the reason) for an archive, description or
    reference that cannot be used and for a simulation the FMU refuses.
    """
    fmu = Path(fmu)
    if not fmu.is_file():
        raise ReferenceResultError(f"no FMU file there ({'a folder' if fmu.is_dir() else 'missing'}"
                                   "): name an .fmu file")
    try:
        with zipfile.ZipFile(fmu) as z:
            problem = archive_problem(z)
            if problem:
                raise ReferenceResultError(f"not opened: {problem}; the FMU is damaged or "
                                           "not trustworthy")
            bad = z.testzip()  # every member's CRC, before any code in it is loaded
            if bad is not None:
                raise ReferenceResultError(f"member {bad} fails its CRC check: the archive is "
                                           "damaged; rebuild or copy it again")
            tables = _read_related(z)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, EOFError, ValueError, OSError,
            zlib.error) as exc:  # zlib: a damaged deflated member
        raise ReferenceResultError(f"not a readable FMU archive ({exc}): rebuild it with "
                                   "`gyro-fmu build` or copy it again") from None
    try:
        md = read_model_description(str(fmu))
        _, stop_time, step = _experiment(fmu)
    except ReferenceResultError:
        raise
    except Exception as exc:  # fmpy raises bare Exception, KeyError, lxml errors
        raise ReferenceResultError(f"modelDescription.xml unusable ({exc}): rebuild the "
                                   "FMU") from None
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    reference = tables["result"]
    check_coverage(reference, "result", outputs, stop_time, step)
    if inputs or "input" in tables:
        if "input" not in tables:
            raise ReferenceResultError(f"the FMU has inputs {inputs} but no reference input "
                                       "table (role='input'): rebuild the FMU")
        check_coverage(tables["input"], "input", inputs, stop_time, step)
    try:
        result = _simulate(fmu, tables.get("input"), stop_time, step)
    except Exception as exc:  # the FMU's refusal, as fmpy reports it
        raise ReferenceResultError(f"the simulation of the default experiment failed: "
                                   f"{exc}") from None
    t_ref = np.array(reference["time"], dtype=float)
    band_spread_problem(reference, outputs, dx)
    checks = []
    for var in outputs:
        y_ref = np.array(reference[var], dtype=float)
        y = np.array(result[var], dtype=float)
        if y.shape != y_ref.shape or not np.all(np.isfinite(y)):
            checks.append(SignalCheck(var, int(y_ref.size), int(y_ref.size), float("inf")))
            continue
        t = np.array(result["time"], dtype=float)
        # both ways: the result inside the reference's band and the reference inside the
        # result's, so that a time band cannot hide a scaled signal in either direction
        _, _, _, outside = validate_signal(t, y, t_ref.copy(), y_ref, num=t_ref.size, dx=dx,
                                           dy=dy)
        _, _, _, back = validate_signal(t_ref, y_ref, t.copy(), y, num=t.size, dx=dx, dy=dy)
        checks.append(SignalCheck(var, int(np.sum(outside | back)), int(y.size),
                                  float(np.max(np.abs(y - y_ref)))))
    return checks


def band_spread(y_ref: np.ndarray, dx: int) -> float:
    """Mean width that a time band of dx samples adds to y_ref's band, as a fraction of
    its range (0 for a constant signal)."""
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    span = float(np.max(y_ref) - np.min(y_ref))
    if dx <= 1 or span == 0.0:
        return 0.0
    width = maximum_filter1d(y_ref, size=dx) - minimum_filter1d(y_ref, size=dx)
    return float(np.mean(width)) / span


def band_spread_problem(reference: np.ndarray, outputs: list[str], dx: int) -> None:
    """Refuse a time band that spans a signal's own time scale (MAX_BAND_SPREAD), naming
    the signal and the largest dx that would do."""
    for var in outputs:
        y_ref = np.array(reference[var], dtype=float)
        spread = band_spread(y_ref, dx)
        if spread > MAX_BAND_SPREAD:
            ok = 1
            while ok < dx and band_spread(y_ref, 2 * ok) <= MAX_BAND_SPREAD:
                ok *= 2
            raise ReferenceResultError(
                f"band dx={dx} samples spans the time scale of {var}: it widens {var}'s band "
                f"by {100 * spread:.0f} % of its range on average (at most "
                f"{100 * MAX_BAND_SPREAD:.0f} %), so a scaled or shifted {var} would pass; "
                f"use --dx <= {ok}")
