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

static GyroResonatorParams params_of(const Variables *v) {
    GyroResonatorParams p;
    p.f_x = v->f_x, p.f_y = v->f_y, p.Q_x = v->Q_x, p.Q_y = v->Q_y, p.dxy = v->dxy;
    p.kxy = v->kxy, p.kappa = v->kappa, p.Bx = v->Bx, p.By = v->By, p.alpha_x = v->alpha_x;
    p.alpha_y = v->alpha_y, p.Px = v->Px, p.Py = v->Py, p.phi_x = v->phi_x, p.phi_y = v->phi_y;
    p.Exx = v->Exx, p.Exy = v->Exy, p.Eyx = v->Eyx, p.Eyy = v->Eyy, p.c_ring = v->c_ring;
    p.k3x = v->k3x, p.k3y = v->k3y, p.cubic_substeps = v->cubic_substeps;
    p.ring_amplitude = v->ring_amplitude, p.ring_frequency_1 = v->ring_frequency_1;
    p.ring_frequency_2 = v->ring_frequency_2, p.noise = v->noise, p.beta_x = v->beta_x;
    p.beta_y = v->beta_y, p.k3xy = v->k3xy, p.k3yx = v->k3yx, p.m_modal = v->m_modal;
    p.temperature = v->temperature, p.drive_noise = v->drive_noise;
    p.temperature_rate = v->temperature_rate, p.tc_f = v->tc_f, p.tc_Q = v->tc_Q;
    p.thermal_update_steps = v->thermal_update_steps;
    p.warmup_span = v->warmup_span, p.warmup_tau = v->warmup_tau;
    p.temperature_noise = v->temperature_noise;
    return p;
}

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
