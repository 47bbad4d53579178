/* RateProfile.fmu: the angular rate Omega_z(t) applied to the gyroscope
 * (core/gyro_signals.h: constant, step, ramp or sine). */
#include <math.h>
#include <stddef.h>

#include "gyro_signals.h"
#include "model.h"
#include "variables.h"

typedef struct {
    Variables v;
    GyroRateProfile rate;
    double checked_step; /* the last step size checked against the Nyquist frequency */
} ModelData;

static GyroHookStatus setup(void *data, double start_time, char *msg, size_t n) {
    ModelData *d = data;
    const Variables *v = &d->v;
    d->rate = rate_of(v);
    if (gyro_rate_problems(&d->rate, msg, n)) return GYRO_HOOK_ERROR;
    d->v.Omega_z = gyro_rate_Omega_z(&d->rate, start_time);
    return GYRO_HOOK_OK;
}

static GyroHookStatus step(void *data, double t, double h, char *msg, size_t n) {
    ModelData *d = data; /* a step that aliases: warned once per step size */
    const int aliases = gyro_new_step_size(&d->checked_step, h)
                        && gyro_rate_nyquist_problem(&d->rate, h, msg, n);
    d->v.Omega_z = gyro_rate_Omega_z(&d->rate, t + h);
    return aliases ? GYRO_HOOK_WARNING : GYRO_HOOK_OK;
}

static GyroHookStatus restored(void *data, char *msg, size_t n) {
    ModelData *d = data;
    const GyroRateProfile want = rate_of(&d->v);
    return gyro_restored_matches(&want, &d->rate, sizeof want, isfinite(d->v.Omega_z),
                                 "rate profile", msg, n);
}

typedef char variables_first[offsetof(ModelData, v) == 0 ? 1 : -1];

const GyroModel GYRO_MODEL = {MODEL_IDENTIFIER, MODEL_TOKEN, VARIABLES, N_VARIABLES,
                              sizeof(ModelData), setup, step, restored};
