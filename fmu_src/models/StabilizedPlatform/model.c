/* StabilizedPlatform.fmu: a single-axis platform on a vehicle, held still in inertial
 * space by a PI rate loop on a gyro's reading (core/gyro_platform.h): the system example
 * for GyroSensor. Inputs w_b (the vehicle's rate), w_meas (the gyro's reading); outputs
 * w (the platform's rate: the gyro's input), theta (the pointing error), tau. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>

#include "gyro_platform.h"
#include "model.h"
#include "variables.h"

typedef struct {
    Variables v;
    GyroPlatformParams p;
    GyroPlatform s;
} ModelData;

static void publish(ModelData *d) {
    d->v.w = d->s.w, d->v.theta = d->s.theta, d->v.tau = d->s.tau;
}

static GyroHookStatus setup(void *data, double start_time, char *msg, size_t n) {
    ModelData *d = data;
    (void)start_time;
    d->p = params_of(&d->v);
    if (gyro_platform_problems(&d->p, msg, n)) return GYRO_HOOK_ERROR;
    d->s = (GyroPlatform){d->v.w_0, 0.0, 0.0, 0.0};
    publish(d);
    return GYRO_HOOK_OK;
}

static GyroHookStatus step(void *data, double t, double h, char *msg, size_t n) {
    ModelData *d = data;
    (void)t;
    if (!isfinite(d->v.w_b) || !isfinite(d->v.w_meas)) {
        snprintf(msg, n, "StabilizedPlatform: inputs w_b=%g and w_meas=%g rad/s must be "
                 "finite", d->v.w_b, d->v.w_meas);
        return GYRO_HOOK_DISCARD;
    }
    GyroPlatform next = d->s;
    gyro_platform_step(&next, &d->p, d->v.w_b, d->v.w_meas, h);
    if (!isfinite(next.w) || !isfinite(next.theta) || !isfinite(next.I)) {
        snprintf(msg, n, "StabilizedPlatform: the step of %g s at t=%g s overflows (w=%g "
                 "rad/s): the loop is unstable at these gains, or the inputs are too large",
                 h, t, next.w);
        return GYRO_HOOK_DISCARD;
    }
    d->s = next;
    publish(d);
    return GYRO_HOOK_OK;
}

static GyroHookStatus restored(void *data, char *msg, size_t n) {
    ModelData *d = data;
    const GyroPlatformParams want = params_of(&d->v);
    const int finite = isfinite(d->s.w) && isfinite(d->s.theta) && isfinite(d->s.I)
                       && isfinite(d->s.tau);
    return gyro_restored_matches(&want, &d->p, sizeof want, finite, "platform", msg, n);
}

typedef char variables_first[offsetof(ModelData, v) == 0 ? 1 : -1];

const GyroModel GYRO_MODEL = {MODEL_IDENTIFIER, MODEL_TOKEN, VARIABLES, N_VARIABLES,
                              sizeof(ModelData), setup, step, restored};
