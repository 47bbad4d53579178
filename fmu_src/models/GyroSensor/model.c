/* GyroSensor.fmu: the gyroscope as a sensor (core/gyro_sensor.h): Omega_z in, held over
 * the communication step; the drive, the gyro and the observer of US 2011/0314910 A1 at a
 * fixed internal step inside; Omega_meas out through the readout. A communication step
 * shorter than the internal step is refused with fmi2Discard (nothing changes); a lost
 * observer refuses its step with fmi2Discard (outputs NaN) and every later one. */
#include <math.h>
#include <stddef.h>
#include <stdio.h>

#include "gyro_excitation.h"
#include "gyro_sensor.h"
#include "gyro_text.h"
#include "model.h"
#include "variables.h"

/* Observer warnings logged per instance (the status output carries every one). */
#define MAX_WARNINGS 3

typedef struct {
    Variables v; /* first: the variable table's offsets are into it */
    GyroSensor sensor;
    int32_t warnings_logged, saturation_logged;
} ModelData;

/* Everything the sensor is built from, as its variables say. */
typedef struct {
    GyroParams truth, design;
    GyroPickoffNoise noise;
    GyroTwoToneDrive drive;
    GyroReadout readout;
    GyroObserverTuning tuning;
} Settings;

static Settings settings_of(const Variables *v) {
    return (Settings){.truth = truth_of(v), .design = design_of(v), .noise = noise_of(v),
                      .drive = drive_of(v), .readout = readout_of(v), .tuning = tuning_of(v)};
}

static void publish(ModelData *d) {
    double out[5];
    gyro_sensor_outputs(&d->sensor, out);
    Variables *v = &d->v;
    v->Omega_meas = out[0], v->sigma_Omega_meas = out[1], v->Omega_hat = out[2];
    v->status = out[3], v->saturated = out[4];
}

static GyroHookStatus setup(void *data, double start_time, char *msg, size_t n) {
    ModelData *d = data;
    const Variables *v = &d->v;
    const Settings s = settings_of(v);
    if (gyro_sensor_init(&d->sensor, &s.truth, &s.noise, (uint64_t)v->seed, &s.design,
                         v->Omega_z_0, &s.tuning, &s.drive, &s.readout, start_time, msg, n))
        return GYRO_HOOK_ERROR;
    d->warnings_logged = d->saturation_logged = 0;
    publish(d);
    /* a growing mode of the gyro, and a drive that leaves the rate weakly observable
     * (its tones far from the design's modes: gyro_excitation.h), before the run */
    char drive[GYRO_OBS_MESSAGE];
    gyro_params_warning(&s.truth, msg, n); /* "" when none */
    if (gyro_drive_warning(&s.design, &s.drive, v->Omega_z_0, d->sensor.h, 1, drive,
                           sizeof drive))
        gyro_text_add(msg, n, drive);
    return msg[0] ? GYRO_HOOK_WARNING : GYRO_HOOK_OK;
}

static GyroHookStatus step(void *data, double t, double h, char *msg, size_t n) {
    ModelData *d = data;
    const Variables *v = &d->v;
    const double dt = d->sensor.h;
    if (h < dt * (1.0 - 1e-9)) {
        snprintf(msg, n, "GyroSensor: communication step %g s is shorter than the internal "
                 "step %g s: use a step >= internal_step, or a smaller internal_step", h, dt);
        return GYRO_HOOK_DISCARD;
    }
    const int before = d->sensor.observer.status;
    const int code = gyro_sensor_advance(&d->sensor, v->Omega_z, t + h, msg, n);
    switch (code) {
    case GYRO_OBS_TOO_COARSE:
    case GYRO_OBS_BAD_INPUT: return GYRO_HOOK_ERROR;
    case GYRO_OBS_REFUSED: return GYRO_HOOK_ERROR;
    case GYRO_OBS_STEP_LOST:
        publish(d);
        d->v.Omega_meas = d->v.sigma_Omega_meas = d->v.Omega_hat = NAN;
        d->v.status = 2.0;
        return GYRO_HOOK_DISCARD;
    default: break;
    }
    publish(d);
    if (d->v.saturated != 0.0 && !d->saturation_logged) {
        d->saturation_logged = 1;
        snprintf(msg, n, "GyroSensor: the rate is beyond full scale at t=%.9g s (Omega_z=%g "
                 "rad/s, full_scale=%g rad/s): Omega_meas saturates at +-full_scale, as a real "
                 "sensor does, while it lasts (the output 'saturated' says when; logged once)",
                 t + h, v->Omega_z, v->full_scale);
        return GYRO_HOOK_WARNING;
    }
    if (code == GYRO_OBS_STEP_WARNING && before != 1 && d->warnings_logged < MAX_WARNINGS) {
        char warning[GYRO_OBS_MESSAGE];
        gyro_observer_warning(&d->sensor.observer, warning, sizeof warning);
        d->warnings_logged++;
        snprintf(msg, n, "GyroSensor: %s%s", warning,
                 d->warnings_logged == MAX_WARNINGS
                     ? " (further warnings not logged: the status output carries them)" : "");
        return GYRO_HOOK_WARNING;
    }
    return GYRO_HOOK_OK;
}

static GyroHookStatus restored(void *data, char *msg, size_t n) {
    ModelData *d = data;
    const Settings s = settings_of(&d->v);
    if (gyro_sensor_restored_problem(&d->sensor, &s.truth, &s.noise, &s.design, d->v.Omega_z_0,
                                     &s.tuning, &s.drive, &s.readout, msg, n))
        return GYRO_HOOK_ERROR;
    return GYRO_HOOK_OK;
}

typedef char variables_first[offsetof(ModelData, v) == 0 ? 1 : -1];

const GyroModel GYRO_MODEL = {MODEL_IDENTIFIER, MODEL_TOKEN, VARIABLES, N_VARIABLES,
                              sizeof(ModelData), setup, step, restored};
