/* GyroPlant.fmu: the 2-DOF MEMS gyroscope of US 2011/0314910 A1 (eqs. 3-5) over the core's
 * exact held-input step (core/gyro_plant.h). Inputs ux, uy, Omega_z are held over each
 * communication step; outputs are the measured x, vx, y, vy (seeded white noise when
 * noise_* > 0) and the accelerations ax, ay. */
#include <stddef.h>

#include "gyro_plant.h"
#include "model.h"
#include "variables.h"

typedef struct {
    Variables v; /* first: the variable table's offsets are into it */
    GyroPlant plant;
} ModelData;

static void publish(ModelData *d) {
    double out[6];
    gyro_plant_outputs(&d->plant, out);
    Variables *v = &d->v;
    v->x = out[0], v->vx = out[1], v->y = out[2], v->vy = out[3], v->ax = out[4], v->ay = out[5];
}

static GyroHookStatus setup(void *data, double start_time, char *msg, size_t n) {
    (void)start_time;
    ModelData *d = data;
    const Variables *v = &d->v;
    const GyroParams p = params_of(v);
    if (gyro_params_problems(&p, msg, n)) return GYRO_HOOK_ERROR;
    const GyroPickoffNoise sigma = noise_of(v);
    gyro_plant_init(&d->plant, &p, &sigma, (uint64_t)v->seed, NULL);
    publish(d);
    return gyro_params_warning(&p, msg, n) ? GYRO_HOOK_WARNING : GYRO_HOOK_OK;
}

static GyroHookStatus step(void *data, double t, double h, char *msg, size_t n) {
    (void)t;
    ModelData *d = data;
    const Variables *v = &d->v;
    const GyroParams p = params_of(v);
    if (gyro_rate_problem(&p, "Omega_z", v->Omega_z, msg, n)) return GYRO_HOOK_ERROR;
    gyro_plant_step(&d->plant, d->v.ux, d->v.uy, d->v.Omega_z, h);
    publish(d);
    return GYRO_HOOK_OK;
}

static GyroHookStatus restored(void *data, char *msg, size_t n) {
    ModelData *d = data;
    const Variables *v = &d->v;
    const GyroParams p = params_of(v);
    const GyroPickoffNoise sigma = noise_of(v);
    if (gyro_plant_restored_problem(&d->plant, &p, &sigma, msg, n)) return GYRO_HOOK_ERROR;
    return GYRO_HOOK_OK;
}

typedef char variables_first[offsetof(ModelData, v) == 0 ? 1 : -1];

const GyroModel GYRO_MODEL = {MODEL_IDENTIFIER, MODEL_TOKEN, VARIABLES, N_VARIABLES,
                              sizeof(ModelData), setup, step, restored};
