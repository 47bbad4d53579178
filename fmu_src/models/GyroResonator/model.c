/* GyroResonator.fmu: the resonator of US 9,482,553 (eq. 1) over the core's exact
 * held-input step (core/gyro_resonator.h). Inputs Vx, Vy, Omega_z are held over each
 * communication step; outputs are the pick-off voltages Vpx, Vpy (seeded noise when
 * noise, m_modal or drive_noise > 0) and the temperature sensor T_sensor. A temperature
 * history that takes f or Q to 0 fails the step with a message naming it. */
#include <stddef.h>

#include "gyro_resonator.h"
#include "model.h"
#include "variables.h"

typedef struct {
    Variables v; /* first: the variable table's offsets are into it */
    GyroResonator resonator;
} ModelData;

/* params_of (variables.h) fills GyroResonatorParams from the parameters. */

static void publish(ModelData *d) {
    d->v.Vpx = d->resonator.out[0], d->v.Vpy = d->resonator.out[1];
    d->v.T_sensor = d->resonator.T_sensor;
}

static GyroHookStatus setup(void *data, double start_time, char *msg, size_t n) {
    (void)start_time;
    ModelData *d = data;
    const GyroResonatorParams p = params_of(&d->v);
    if (gyro_resonator_init(&d->resonator, &p, (uint64_t)d->v.seed, NULL, msg, n))
        return GYRO_HOOK_ERROR;
    publish(d);
    return GYRO_HOOK_OK;
}

static GyroHookStatus step(void *data, double t, double h, char *msg, size_t n) {
    (void)t;
    ModelData *d = data;
    if (gyro_resonator_step(&d->resonator, d->v.Vx, d->v.Vy, d->v.Omega_z, h, msg, n))
        return GYRO_HOOK_ERROR;
    publish(d);
    return GYRO_HOOK_OK;
}

static GyroHookStatus restored(void *data, char *msg, size_t n) {
    ModelData *d = data;
    const GyroResonatorParams p = params_of(&d->v);
    if (gyro_resonator_restored_problem(&d->resonator, &p, msg, n)) return GYRO_HOOK_ERROR;
    d->resonator.maps.valid = 0; /* recomputed from the restored parameters */
    return GYRO_HOOK_OK;
}

typedef char variables_first[offsetof(ModelData, v) == 0 ? 1 : -1];

const GyroModel GYRO_MODEL = {MODEL_IDENTIFIER, MODEL_TOKEN, VARIABLES, N_VARIABLES,
                              sizeof(ModelData), setup, step, restored};
