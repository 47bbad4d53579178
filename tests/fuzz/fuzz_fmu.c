/* libFuzzer target over one native FMU's own sources (its model.c, the FMI layer, the
 * core), built by tests/fuzz_harness.py with clang -fsanitize=fuzzer,address,undefined.
 *
 * An input is a program of FMI 2.0 calls: set a parameter or input (a chosen variable,
 * an interesting or raw value), enter/exit initialization, step (a chosen or raw h),
 * get every output, save and restore a state, save a state and restore it with bytes
 * patched (the deserialize checks), reset, terminate. The first byte's low bit starts
 * from an initialized instance that has stepped three times (so that patched states
 * reach the step mode's checks at once). Any sanitizer report, crash or time-out is a
 * finding; statuses are not judged (a refusal is a right answer). */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "instance.h"
#include "model.h"

fmi2Component fmi2Instantiate(fmi2String, fmi2Type, fmi2String, fmi2String,
                              const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean);
void fmi2FreeInstance(fmi2Component);
fmi2Status fmi2SetupExperiment(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean,
                               fmi2Real);
fmi2Status fmi2EnterInitializationMode(fmi2Component);
fmi2Status fmi2ExitInitializationMode(fmi2Component);
fmi2Status fmi2Terminate(fmi2Component);
fmi2Status fmi2Reset(fmi2Component);
fmi2Status fmi2GetReal(fmi2Component, const fmi2ValueReference[], size_t, fmi2Real[]);
fmi2Status fmi2GetInteger(fmi2Component, const fmi2ValueReference[], size_t, fmi2Integer[]);
fmi2Status fmi2SetReal(fmi2Component, const fmi2ValueReference[], size_t, const fmi2Real[]);
fmi2Status fmi2SetInteger(fmi2Component, const fmi2ValueReference[], size_t,
                          const fmi2Integer[]);
fmi2Status fmi2GetFMUstate(fmi2Component, fmi2FMUstate *);
fmi2Status fmi2SetFMUstate(fmi2Component, fmi2FMUstate);
fmi2Status fmi2FreeFMUstate(fmi2Component, fmi2FMUstate *);
fmi2Status fmi2SerializedFMUstateSize(fmi2Component, fmi2FMUstate, size_t *);
fmi2Status fmi2SerializeFMUstate(fmi2Component, fmi2FMUstate, fmi2Byte[], size_t);
fmi2Status fmi2DeSerializeFMUstate(fmi2Component, const fmi2Byte[], size_t, fmi2FMUstate *);
fmi2Status fmi2DoStep(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);

/* Steps one input may take: the whole input stays far below libFuzzer's time-out unless
 * one step does unbounded work (the kind of finding this target is for). */
#define MAX_STEPS 64
/* Simulated time one input may ask for (s): GyroSensor does h / 5 us internal steps per
 * call, bounded by the core (GYRO_SENSOR_MAX_STEPS, 1 s) but seconds of CPU under the
 * sanitizers; the bound itself is tested in tests/test_sensor.py. */
#define MAX_TIME 0.02
/* The serialized header before the model's data (fmu_src/fmi/instance.c). */
#define SERIAL_HEADER (8 + 4 + 4 + 64 + 4 + 16 + GYRO_MESSAGE_SIZE)

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...) {
    (void)env, (void)name, (void)status, (void)category;
    char buf[4096];
    va_list ap;
    va_start(ap, message);
    vsnprintf(buf, sizeof buf, message, ap); /* the formatting itself runs under ASan */
    va_end(ap);
}

static const fmi2CallbackFunctions CALLBACKS = {logger, calloc, free, NULL, NULL};

typedef struct {
    const uint8_t *p;
    size_t n;
} Reader;

static uint8_t u8(Reader *r) {
    if (!r->n) return 0;
    r->n--;
    return *r->p++;
}

static uint32_t u32(Reader *r) {
    uint32_t v = 0;
    for (int i = 0; i < 4; i++) v |= (uint32_t)u8(r) << (8 * i);
    return v;
}

static double raw_double(Reader *r) {
    uint64_t bits = 0;
    for (int i = 0; i < 8; i++) bits |= (uint64_t)u8(r) << (8 * i);
    double v;
    memcpy(&v, &bits, sizeof v);
    return v;
}

/* Values a hostile or careless user gives: the fuzz trials' own among them. */
static const double INTERESTING[] = {
    0.0, -0.0, 1.0, -1.0, 0.5, 2.0, 1e-22, 1e-16, 1e-9, 1e-6, 5e-6, 1e-3, 1e3, 1e6, 1e9,
    1e13, 1e20, 1e300, -1e300, 4e-324, 2147483647.0, -2147483648.0, 1.0 / 0.0, -1.0 / 0.0};
static const int32_t INTEGERS[] = {0, 1, 2, 3, 4, -1, 15, 1000, 1001, 2000000000, 2147483647,
                                   -2147483647 - 1};

static double value(Reader *r) {
    const uint8_t k = u8(r);
    if (k < 2 * sizeof INTERESTING / sizeof INTERESTING[0])
        return k & 1 ? -INTERESTING[k >> 1] : INTERESTING[k >> 1];
    if (k == 255) return 0.0 / 0.0;
    return raw_double(r);
}

static int32_t integer(Reader *r) {
    const uint8_t k = u8(r);
    if (k < sizeof INTEGERS / sizeof INTEGERS[0]) return INTEGERS[k];
    return (int32_t)u32(r);
}

static double step_size(Reader *r) {
    static const double H[] = {5e-6, 5e-6, 1e-5, 2e-6, 1e-4, 1e-3, 1e-7, 3.3e-6};
    const uint8_t k = u8(r);
    return k < 8 * 30 ? H[k % 8] : value(r);
}

/* Save a state, patch bytes of its serialization as the input says, restore it. */
static void patched_restore(fmi2Component c, Reader *r) {
    fmi2FMUstate s = NULL;
    size_t size = 0;
    if (fmi2GetFMUstate(c, &s) != fmi2OK) return;
    if (fmi2SerializedFMUstateSize(c, s, &size) == fmi2OK && size > SERIAL_HEADER) {
        fmi2Byte *bytes = malloc(size);
        if (bytes && fmi2SerializeFMUstate(c, s, bytes, size) == fmi2OK) {
            const int patches = 1 + u8(r) % 4;
            for (int k = 0; k < patches; k++) {
                const uint8_t how = u8(r);
                const size_t data = size - SERIAL_HEADER;
                if (how & 1) { /* a double, 8-aligned in the model's data */
                    const size_t at = SERIAL_HEADER + 8 * (u32(r) % (data / 8));
                    const double v = value(r);
                    memcpy(bytes + at, &v, sizeof v);
                } else if (how & 2) { /* an int32 anywhere in the data */
                    const size_t at = SERIAL_HEADER + u32(r) % (data - 3);
                    const int32_t v = integer(r);
                    memcpy(bytes + at, &v, sizeof v);
                } else { /* one byte anywhere */
                    bytes[u32(r) % size] = (fmi2Byte)u8(r);
                }
            }
            fmi2FMUstate t = NULL;
            if (fmi2DeSerializeFMUstate(c, bytes, size, &t) == fmi2OK) {
                fmi2SetFMUstate(c, t);
                fmi2FreeFMUstate(c, &t);
            }
        }
        free(bytes);
    }
    fmi2FreeFMUstate(c, &s);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    Reader r = {data, size};
    const GyroModel *m = &GYRO_MODEL;
    fmi2Component c = fmi2Instantiate("fuzz", fmi2CoSimulation, m->token, NULL, &CALLBACKS,
                                      fmi2False, fmi2True);
    if (!c) return 0;
    fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
    int steps = 0;
    double simulated = 0.0;
    if (u8(&r) & 1) {
        fmi2EnterInitializationMode(c);
        fmi2ExitInitializationMode(c);
        for (int k = 0; k < 3; k++, steps++) fmi2DoStep(c, ((Instance *)c)->time, 5e-6, fmi2True);
    }
    while (r.n) {
        const uint8_t op = u8(&r) % 10;
        const GyroVariable *v = &m->variables[u8(&r) % m->n_variables];
        const fmi2ValueReference vr = v->vr;
        switch (op) {
        case 0:
        case 1: {
            if (v->type == GYRO_INT32) {
                const fmi2Integer x = integer(&r);
                fmi2SetInteger(c, &vr, 1, &x);
            } else {
                const fmi2Real x = value(&r);
                fmi2SetReal(c, &vr, 1, &x);
            }
            break;
        }
        case 2: fmi2EnterInitializationMode(c); break;
        case 3: fmi2ExitInitializationMode(c); break;
        case 4:
        case 5: {
            const double h = step_size(&r);
            if (steps++ < MAX_STEPS && !(h > 0.0 && isfinite(h) && (simulated += h) > MAX_TIME))
                fmi2DoStep(c, ((Instance *)c)->time, h, fmi2True);
            break;
        }
        case 6: {
            for (size_t i = 0; i < m->n_variables; i++) {
                const fmi2ValueReference w = m->variables[i].vr;
                if (m->variables[i].type == GYRO_INT32) {
                    fmi2Integer x;
                    fmi2GetInteger(c, &w, 1, &x);
                } else {
                    fmi2Real x;
                    fmi2GetReal(c, &w, 1, &x);
                }
            }
            break;
        }
        case 7: patched_restore(c, &r); break;
        case 8:
            if (u8(&r) & 1) {
                fmi2Reset(c);
                fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0);
            } else {
                fmi2Terminate(c);
            }
            break;
        default: { /* save, step, restore */
            fmi2FMUstate s = NULL;
            if (fmi2GetFMUstate(c, &s) == fmi2OK) {
                if (steps++ < MAX_STEPS) fmi2DoStep(c, ((Instance *)c)->time, 5e-6, fmi2True);
                fmi2SetFMUstate(c, s);
                fmi2FreeFMUstate(c, &s);
            }
            break;
        }
        }
    }
    fmi2FreeInstance(c);
    return 0;
}
