/* GyroObserver.fmu: the state observer of US 2011/0314910 A1 (eqs. 5-9) over the core's
 * observer (core/gyro_observer.h). Each step corrects with the measured pair at t and
 * predicts to t + h with ux, uy held; outputs at t + h are predictions from data up to t.
 * A step too coarse for the guessed resonance is refused with fmi2Discard (nothing
 * changes: a smaller step goes on); a lost filter refuses its step with fmi2Discard (status
 * 2, the other outputs NaN) and every later one with fmi2Error. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>

#include "gyro_excitation.h"
#include "gyro_observer.h"
#include "model.h"
#include "variables.h"

/* Status-1 warnings logged per instance (a noisy run may enter and leave status 1 often),
 * and re-fit restarts logged (each is an action on the estimate). */
#define MAX_WARNINGS 3
#define MAX_RESTARTS_LOGGED 10

typedef struct {
    Variables v; /* first: the variable table's offsets are into it */
    GyroObserver observer;
    int32_t warnings_logged, restarts_logged;
    double coarse_h; /* the last step size warned of as coarse (0: none) */
    int32_t drive_checked, reserved; /* the tones f1, f2 judged (at the first step) */
} ModelData;

/* guess_of and tuning_of (variables.h) fill GyroParams from kxx_0 .. m_0 and
 * GyroObserverTuning from the tuning parameters. */

static void publish(ModelData *d) {
    double out[20], p[4];
    gyro_observer_outputs(&d->observer, out);
    gyro_observer_rate_probabilities(&d->observer, p);
    Variables *v = &d->v;
    v->x_hat = out[0], v->vx_hat = out[1], v->y_hat = out[2], v->vy_hat = out[3];
    v->Omega_hat = out[4], v->kxx_hat = out[5], v->kyy_hat = out[6], v->kxy_hat = out[7];
    v->dxx_hat = out[8], v->dyy_hat = out[9], v->dxy_hat = out[10], v->m_hat = out[11];
    v->sigma_Omega_z = out[12], v->sigma_kxx = out[13], v->sigma_kyy = out[14];
    v->sigma_kxy = out[15], v->sigma_dxx = out[16], v->sigma_dyy = out[17];
    v->sigma_dxy = out[18], v->sigma_m = out[19];
    v->p_rate_constant = p[0], v->p_rate_rough = p[1], v->p_rate_slow = p[2];
    v->p_rate_agile = p[3];
    v->status = d->observer.status;
}

static GyroHookStatus setup(void *data, double start_time, char *msg, size_t n) {
    (void)start_time;
    ModelData *d = data;
    const GyroParams guess = guess_of(&d->v);
    const GyroObserverTuning tuning = tuning_of(&d->v);
    if (gyro_observer_init(&d->observer, &guess, d->v.Omega_z_0, d->v.measured_pair, &tuning,
                           msg, n))
        return GYRO_HOOK_ERROR;
    d->warnings_logged = 0;
    d->restarts_logged = 0;
    d->coarse_h = 0.0;
    d->drive_checked = 0;
    publish(d);
    return GYRO_HOOK_OK;
}

/* The drive's tones, when the host told them, judged once at the first step (its h is
 * the sampling the bound needs): the warning of gyro_excitation.h, or "". */
static int drive_warning(ModelData *d, double h, char *msg, size_t n) {
    const Variables *v = &d->v;
    d->drive_checked = 1;
    if (!(v->f1 > 0.0 && v->f2 > 0.0)) return 0;
    const GyroParams guess = guess_of(v);
    const GyroTwoToneDrive tones = {1.0, v->f1, 1.0, v->f2}; /* the loss needs no amplitude */
    char text[GYRO_OBS_MESSAGE];
    if (!gyro_drive_warning(&guess, &tones, v->Omega_z_0, h, d->observer.pair, text,
                            sizeof text))
        return 0;
    snprintf(msg, n, "GyroObserver: %s", text);
    return 1;
}

static GyroHookStatus step(void *data, double t, double h, char *msg, size_t n) {
    (void)t;
    ModelData *d = data;
    const Variables *v = &d->v;
    const int pair = d->observer.pair;
    const double z1 = pair == 1 ? v->x_meas : v->vx_meas;
    const double z2 = pair == 1 ? v->y_meas : v->vy_meas;
    const int before = d->observer.status;
    const double restarts = d->observer.refit.restarts;
    const int code = gyro_observer_step(&d->observer, v->ux, v->uy, z1, z2, h, msg, n);
    switch (code) {
    case GYRO_OBS_TOO_COARSE: return GYRO_HOOK_DISCARD; /* nothing changed */
    case GYRO_OBS_BAD_INPUT:
    case GYRO_OBS_REFUSED: return GYRO_HOOK_ERROR;
    case GYRO_OBS_STEP_LOST: /* refused now with fmi2Discard; the next step errs */
        publish(d);
        d->v.x_hat = d->v.vx_hat = d->v.y_hat = d->v.vy_hat = NAN;
        d->v.Omega_hat = d->v.kxx_hat = d->v.kyy_hat = d->v.kxy_hat = NAN;
        d->v.dxx_hat = d->v.dyy_hat = d->v.dxy_hat = d->v.m_hat = NAN;
        d->v.sigma_Omega_z = d->v.sigma_kxx = d->v.sigma_kyy = d->v.sigma_kxy = NAN;
        d->v.sigma_dxx = d->v.sigma_dyy = d->v.sigma_dxy = d->v.sigma_m = NAN;
        d->v.p_rate_constant = d->v.p_rate_rough = d->v.p_rate_slow = NAN;
        d->v.p_rate_agile = NAN;
        d->v.status = 2.0;
        return GYRO_HOOK_DISCARD;
    default: break;
    }
    publish(d);
    if (!d->drive_checked && drive_warning(d, h, msg, n)) return GYRO_HOOK_WARNING;
    if (d->observer.refit.restarts > restarts && d->restarts_logged < MAX_RESTARTS_LOGGED) {
        char text[GYRO_OBS_MESSAGE];
        gyro_observer_restart_message(&d->observer, text, sizeof text);
        d->restarts_logged++;
        snprintf(msg, n, "GyroObserver: %s%s", text,
                 d->restarts_logged == MAX_RESTARTS_LOGGED
                     ? " (further restarts not logged)" : "");
        return GYRO_HOOK_WARNING;
    }
    if (h != d->coarse_h && gyro_observer_step_warning(&d->observer, h, msg, n)) {
        d->coarse_h = h; /* once per step size */
        return GYRO_HOOK_WARNING;
    }
    if (code == GYRO_OBS_STEP_WARNING && before != 1 && d->warnings_logged < MAX_WARNINGS) {
        char warning[GYRO_OBS_MESSAGE];
        gyro_observer_warning(&d->observer, warning, sizeof warning);
        d->warnings_logged++;
        snprintf(msg, n, "GyroObserver: %s%s", warning,
                 d->warnings_logged == MAX_WARNINGS
                     ? " (further warnings not logged: the status output carries them)"
                     : "");
        return GYRO_HOOK_WARNING;
    }
    return GYRO_HOOK_OK;
}

static GyroHookStatus restored(void *data, char *msg, size_t n) {
    ModelData *d = data;
    const GyroParams guess = guess_of(&d->v);
    const GyroObserverTuning tuning = tuning_of(&d->v);
    if (gyro_observer_restored_problem(&d->observer, &guess, d->v.Omega_z_0, d->v.measured_pair,
                                       &tuning, msg, n))
        return GYRO_HOOK_ERROR;
    return GYRO_HOOK_OK;
}

typedef char variables_first[offsetof(ModelData, v) == 0 ? 1 : -1];

const GyroModel GYRO_MODEL = {MODEL_IDENTIFIER, MODEL_TOKEN, VARIABLES, N_VARIABLES,
                              sizeof(ModelData), setup, step, restored};
