"""Do-nothing FMUs compiled from C: what the master itself costs per step, without pythonfmu.

build_compiled_null_fmus(pythonfmu_nulls, dest) takes the do-nothing pythonfmu FMUs of
bench.py (same variables as ours) and replaces each one's binary by a C library whose
fmi2GetReal writes the number of steps taken so far into every output (so a test can
see that row k follows exactly k steps) and whose other functions return fmi2OK.
Running the standard wiring over these measures the compiled master loop; the
pythonfmu floor minus this is what pythonfmu and the Python adapter cost.
Needs a C compiler and fmpy's FMI 2.0 headers (both checked by gyro_fmu.doctor.report).
"""

from __future__ import annotations

import subprocess
import tempfile
import zipfile
from pathlib import Path

from gyro_fmu.doctor.report import find_compiler, fmi2_header_dir

_SOURCE = r"""
#include <stdlib.h>
#include "fmi2Functions.h"

/* REFUSE_GET / REFUSE_SET / REFUSE_STEP = 1: that function returns fmi2Error from its
   (REFUSE_AFTER + 1)-th call on, to test how a master reports refusals. */
#ifndef REFUSE_GET
#define REFUSE_GET 0
#endif
#ifndef REFUSE_SET
#define REFUSE_SET 0
#endif
#ifndef REFUSE_STEP
#define REFUSE_STEP 0
#endif
#ifndef REFUSE_AFTER
#define REFUSE_AFTER 0
#endif
typedef struct { int gets, sets, steps; double done; } Null;
#define VERDICT(counter, refuse) \
    ((refuse) && ++((Null*)c)->counter > REFUSE_AFTER ? fmi2Error : fmi2OK)

const char* fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char* fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n,
                               const fmi2String cats[]) { return fmi2OK; }
fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                              fmi2String resources, const fmi2CallbackFunctions* f,
                              fmi2Boolean visible, fmi2Boolean logging) {
    return calloc(1, sizeof(Null));
}
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDefined, fmi2Real tol,
                               fmi2Real start, fmi2Boolean stopDefined, fmi2Real stop) {
    return fmi2OK;
}
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       fmi2Real value[]) {
    for (size_t i = 0; i < n; i++) value[i] = ((Null*)c)->done;  /* steps taken so far */
    return VERDICT(gets, REFUSE_GET);
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                       const fmi2Real value[]) { return VERDICT(sets, REFUSE_SET); }
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    fmi2Status status = VERDICT(steps, REFUSE_STEP);
    if (status == fmi2OK) ((Null*)c)->done += 1.0;
    return status;
}
#define REFUSE(name, ...) fmi2Status name(__VA_ARGS__) { return fmi2Error; }
REFUSE(fmi2GetInteger, fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[])
REFUSE(fmi2GetBoolean, fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[])
REFUSE(fmi2GetString, fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[])
REFUSE(fmi2SetInteger, fmi2Component c, const fmi2ValueReference vr[], size_t n,
       const fmi2Integer v[])
REFUSE(fmi2SetBoolean, fmi2Component c, const fmi2ValueReference vr[], size_t n,
       const fmi2Boolean v[])
REFUSE(fmi2SetString, fmi2Component c, const fmi2ValueReference vr[], size_t n,
       const fmi2String v[])
REFUSE(fmi2GetFMUstate, fmi2Component c, fmi2FMUstate* s)
REFUSE(fmi2SetFMUstate, fmi2Component c, fmi2FMUstate s)
REFUSE(fmi2FreeFMUstate, fmi2Component c, fmi2FMUstate* s)
REFUSE(fmi2SerializedFMUstateSize, fmi2Component c, fmi2FMUstate s, size_t* n)
REFUSE(fmi2SerializeFMUstate, fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n)
REFUSE(fmi2DeSerializeFMUstate, fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate* s)
REFUSE(fmi2GetDirectionalDerivative, fmi2Component c, const fmi2ValueReference u[], size_t nu,
       const fmi2ValueReference z[], size_t nz, const fmi2Real dv[], fmi2Real dz[])
REFUSE(fmi2SetRealInputDerivatives, fmi2Component c, const fmi2ValueReference vr[], size_t n,
       const fmi2Integer order[], const fmi2Real v[])
REFUSE(fmi2GetRealOutputDerivatives, fmi2Component c, const fmi2ValueReference vr[], size_t n,
       const fmi2Integer order[], fmi2Real v[])
REFUSE(fmi2CancelStep, fmi2Component c)
REFUSE(fmi2GetStatus, fmi2Component c, const fmi2StatusKind k, fmi2Status* v)
REFUSE(fmi2GetRealStatus, fmi2Component c, const fmi2StatusKind k, fmi2Real* v)
REFUSE(fmi2GetIntegerStatus, fmi2Component c, const fmi2StatusKind k, fmi2Integer* v)
REFUSE(fmi2GetBooleanStatus, fmi2Component c, const fmi2StatusKind k, fmi2Boolean* v)
REFUSE(fmi2GetStringStatus, fmi2Component c, const fmi2StatusKind k, fmi2String* v)
"""


def build_compiled_null_fmus(models: dict[str, Path], dest: Path, refuse: str | None = None,
                             after: int = 0) -> dict[str, Path]:
    """Instance -> .fmu: each FMU's model description over the do-nothing C library.

    refuse: "get", "set" or "step": that FMI function returns fmi2Error from its
    (after + 1)-th call on (for tests of the master's error reporting).
    """
    cc, headers = find_compiler(), fmi2_header_dir()
    if cc is None or headers is None:
        raise RuntimeError("a C compiler and fmpy's c-code headers are needed: "
                           "`gyro-fmu doctor` says which is missing")
    with tempfile.TemporaryDirectory() as tmp:
        src, lib = Path(tmp, "null.c"), Path(tmp, "null.so")
        src.write_text(_SOURCE)
        flags = [f"-DREFUSE_AFTER={int(after)}"]
        if refuse is not None:
            if refuse not in ("get", "set", "step"):
                raise ValueError(f"refuse={refuse!r}: use 'get', 'set', 'step' or None")
            flags.append(f"-DREFUSE_{refuse.upper()}=1")
        subprocess.run([cc, "-O2", "-shared", "-fPIC", f"-I{headers}", *flags, str(src),
                        "-o", str(lib)], check=True, capture_output=True)
        out = {}
        for instance, fmu in models.items():
            with zipfile.ZipFile(fmu) as z:
                xml = z.read("modelDescription.xml")
            identifier = fmu.stem
            path = dest / f"Compiled{identifier}.fmu"
            with zipfile.ZipFile(path, "w") as z:
                z.writestr("modelDescription.xml", xml)
                z.write(lib, f"binaries/linux64/{identifier}.so")
            out[instance] = path
    return out
