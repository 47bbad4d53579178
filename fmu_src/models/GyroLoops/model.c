/* GyroLoops.fmu: the closed-loop electronics of US 9,482,553 over the core's loops
 * (core/gyro_loops.h): from the pick-off voltages Vpx, Vpy sampled at t it computes the
 * forcer voltages Vx, Vy held from t (feed-forward removal, PLL and amplitude control of
 * the oscillator, force rebalance with the rate and quadrature outputs, mode reversal). */
#include <stddef.h>

#include "gyro_loops.h"
#include "model.h"
#include "variables.h"

typedef struct {
    Variables v; /* first: the variable table's offsets are into it */
    GyroLoops loops;
} ModelData;

/* settings_of (variables.h) fills GyroLoopSettings from the parameters; the FMU's
 * amplitude_setpoint is LoopSettings.amplitude (its output amplitude is the measured one). */

static void publish(ModelData *d) {
    const GyroLoopOutputs *o = &d->loops.out;
    Variables *v = &d->v;
    v->Vx = o->Vx, v->Vy = o->Vy, v->theta = o->theta, v->omega = o->omega;
    v->amplitude = o->amplitude, v->phase_error = o->phase_error, v->gain = o->gain;
    v->rate = o->rate, v->quad = o->quad;
}

static GyroHookStatus setup(void *data, double start_time, char *msg, size_t n) {
    (void)start_time;
    ModelData *d = data;
    const GyroLoopSettings s = settings_of(&d->v);
    if (gyro_loops_init(&d->loops, &s, msg, n)) return GYRO_HOOK_ERROR;
    publish(d);
    return GYRO_HOOK_OK;
}

static GyroHookStatus step(void *data, double t, double h, char *msg, size_t n) {
    (void)msg, (void)n;
    ModelData *d = data;
    gyro_loops_step(&d->loops, d->v.Vpx, d->v.Vpy, t, h);
    publish(d);
    return GYRO_HOOK_OK;
}

static GyroHookStatus restored(void *data, char *msg, size_t n) {
    ModelData *d = data;
    const GyroLoopSettings s = settings_of(&d->v);
    return gyro_loops_restored_problem(&d->loops, &s, msg, n) ? GYRO_HOOK_ERROR : GYRO_HOOK_OK;
}

typedef char variables_first[offsetof(ModelData, v) == 0 ? 1 : -1];

const GyroModel GYRO_MODEL = {MODEL_IDENTIFIER, MODEL_TOKEN, VARIABLES, N_VARIABLES,
                              sizeof(ModelData), setup, step, restored};
