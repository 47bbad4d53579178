/* What one model gives the FMI layer: its variable table (generated from the Python
 * declarations, <Model>/variables.h) and two functions. The layer does everything else
 * for every model alike: the FMI 2.0 and 3.0 state machines, value references, bounds
 * and causality checks, logging, FMU states and their serialization.
 *
 * A model keeps all its data in one plain struct (no pointers), so an FMU state is a
 * copy of it and a serialized state is its bytes. */
#ifndef GYRO_MODEL_H
#define GYRO_MODEL_H

#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <stdint.h>

typedef enum { GYRO_FLOAT64, GYRO_INT32 } GyroVarType;
typedef enum { GYRO_PARAMETER, GYRO_INPUT, GYRO_OUTPUT } GyroCausality;

typedef struct {
    uint32_t vr;
    const char *name;
    GyroVarType type;
    GyroCausality causality;
    size_t offset;            /* of the value in the model's data struct */
    double start;
    double min, max;          /* -inf / +inf when the declaration has none */
    int min_exclusive;        /* min itself is refused too */
    const char *unit;         /* "1" for dimensionless; "" for Int32 */
} GyroVariable;

#define GYRO_MESSAGE_SIZE 1024

/* Status of a model hook: OK, a warning to log (msg), a refused step (msg: the step did
 * not happen, fmi2Discard / fmi3Discard, the instance stays usable: a smaller step, or a
 * restored state, goes on), or an error (msg: the instance fails). */
typedef enum {
    GYRO_HOOK_OK = 0,
    GYRO_HOOK_WARNING = 1,
    GYRO_HOOK_DISCARD = 2,
    GYRO_HOOK_ERROR = 3
} GyroHookStatus;

typedef struct {
    const char *identifier;   /* modelIdentifier */
    const char *token;        /* FMI 2.0 guid = FMI 3.0 instantiationToken */
    const GyroVariable *variables;
    size_t n_variables;
    size_t data_size;
    /* End of initialization: parameters are final; build the model, set the outputs of
     * the start time. msg says why on error (then the instance cannot step). */
    GyroHookStatus (*setup)(void *data, double start_time, char *msg, size_t n);
    /* Advance from t to t + h (h > 0, finite) with the inputs held, set the outputs; a
     * warning (msg) still advances; a discard (msg) does not, time stays at t. */
    GyroHookStatus (*step)(void *data, double t, double h, char *msg, size_t n);
    /* A state deserialized from bytes (data from outside), in step mode: check it against
     * the variables it holds and drop anything cached; NULL when nothing to check. */
    GyroHookStatus (*restored)(void *data, char *msg, size_t n);
} GyroModel;

/* A restored state's check for a model whose state is its parameters' struct: the struct
 * built from the variables (want) equals the saved one (have) byte for byte, and the
 * saved outputs are finite (outputs_finite); else an error naming what. */
static inline GyroHookStatus gyro_restored_matches(const void *want, const void *have,
                                                   size_t size, int outputs_finite,
                                                   const char *what, char *msg, size_t n) {
    if (memcmp(want, have, size) == 0 && outputs_finite) return GYRO_HOOK_OK;
    snprintf(msg, n, "the saved %s does not match its parameters, or is not finite", what);
    return GYRO_HOOK_ERROR;
}

/* 1 the first time the step size h is seen after another (*last: the last one seen):
 * checks that hold per step size (aliasing) run once, not every step. */
static inline int gyro_new_step_size(double *last, double h) {
    const int changed = h != *last;
    *last = h;
    return changed;
}

/* Defined once per FMU, in its model.c. */
extern const GyroModel GYRO_MODEL;

#endif
