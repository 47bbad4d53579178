/* TwoToneDrive.fmu: ux = A1 sin(2 pi f1 t) + A2 sin(2 pi f2 t), uy = 0 (US 2011/0314910 A1
 * eq. 10, core/gyro_signals.h). The outputs at the end of each step are those of t + h. */
#include <math.h>
#include <stddef.h>

#include "gyro_signals.h"
#include "model.h"
#include "variables.h"

typedef struct {
    Variables v;
    GyroTwoToneDrive drive;
    double checked_step; /* the last step size checked against the Nyquist frequency */
} ModelData;

static GyroHookStatus setup(void *data, double start_time, char *msg, size_t n) {
    ModelData *d = data;
    d->drive = drive_of(&d->v);
    if (gyro_drive_problems(&d->drive, msg, n)) return GYRO_HOOK_ERROR;
    d->v.ux = gyro_drive_ux(&d->drive, start_time);
    d->v.uy = 0.0;
    return GYRO_HOOK_OK;
}

static GyroHookStatus step(void *data, double t, double h, char *msg, size_t n) {
    ModelData *d = data; /* a step that aliases: warned once per step size */
    const int aliases = gyro_new_step_size(&d->checked_step, h)
                        && gyro_drive_nyquist_problem(&d->drive, h, msg, n);
    d->v.ux = gyro_drive_ux(&d->drive, t + h);
    return aliases ? GYRO_HOOK_WARNING : GYRO_HOOK_OK;
}

static GyroHookStatus restored(void *data, char *msg, size_t n) {
    ModelData *d = data;
    const GyroTwoToneDrive want = drive_of(&d->v);
    return gyro_restored_matches(&want, &d->drive, sizeof want, isfinite(d->v.ux),
                                 "drive (A1, f1, A2, f2)", msg, n);
}

typedef char variables_first[offsetof(ModelData, v) == 0 ? 1 : -1];

const GyroModel GYRO_MODEL = {MODEL_IDENTIFIER, MODEL_TOKEN, VARIABLES, N_VARIABLES,
                              sizeof(ModelData), setup, step, restored};
