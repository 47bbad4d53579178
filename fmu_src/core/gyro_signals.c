#include "gyro_signals.h"

#include <math.h>
#include <stdio.h>

#define GYRO_TWO_PI 6.283185307179586

double gyro_drive_ux(const GyroTwoToneDrive *d, double t) {
    return d->A1 * sin(GYRO_TWO_PI * d->f1 * t) + d->A2 * sin(GYRO_TWO_PI * d->f2 * t);
}

int gyro_drive_problems(const GyroTwoToneDrive *d, char *msg, size_t n) {
    if (n) msg[0] = '\0';
    if (!(isfinite(d->A1) && isfinite(d->f1) && isfinite(d->A2) && isfinite(d->f2))) {
        snprintf(msg, n, "drive A1=%g, f1=%g, A2=%g, f2=%g must be finite", d->A1, d->f1,
                 d->A2, d->f2);
        return 1;
    }
    if (d->f1 < 0.0 || d->f2 < 0.0) {
        snprintf(msg, n, "tone frequencies f1=%g, f2=%g Hz must be >= 0", d->f1, d->f2);
        return 1;
    }
    return 0;
}

double gyro_rate_Omega_z(const GyroRateProfile *r, double t) {
    if (r->kind == GYRO_RATE_CONSTANT || t < r->t_start) return r->offset;
    const double tau = t - r->t_start;
    if (r->kind == GYRO_RATE_STEP) return r->offset + r->amplitude;
    if (r->kind == GYRO_RATE_RAMP) return r->offset + r->slope * tau;
    return r->offset + r->amplitude * sin(GYRO_TWO_PI * r->frequency * tau);
}

int gyro_rate_problems(const GyroRateProfile *r, char *msg, size_t n) {
    if (n) msg[0] = '\0';
    if (r->kind < GYRO_RATE_CONSTANT || r->kind > GYRO_RATE_SINE) {
        snprintf(msg, n, "rate kind=%d is invalid: use 1 constant, 2 step, 3 ramp or 4 sine",
                 (int)r->kind);
        return 1;
    }
    const double v[5] = {r->offset, r->amplitude, r->frequency, r->slope, r->t_start};
    for (int i = 0; i < 5; i++)
        if (!isfinite(v[i])) {
            snprintf(msg, n, "rate profile values must be finite (offset=%g, amplitude=%g, "
                     "frequency=%g, slope=%g, t_start=%g)", v[0], v[1], v[2], v[3], v[4]);
            return 1;
        }
    if (r->frequency < 0.0) {
        snprintf(msg, n, "rate frequency=%g Hz must be >= 0", r->frequency);
        return 1;
    }
    return 0;
}

int gyro_drive_nyquist_problem(const GyroTwoToneDrive *d, double h, char *msg, size_t n) {
    const double nyquist = 0.5 / h;
    if (n) msg[0] = '\0';
    for (int k = 0; k < 2; k++) {
        const double f = k ? d->f2 : d->f1, A = k ? d->A2 : d->A1;
        if (A != 0.0 && fabs(f) >= nyquist) {
            snprintf(msg, n, "drive tone f%d=%g Hz is at or above the Nyquist frequency %g Hz "
                     "of the %g s communication step: it aliases (the plant sees another "
                     "frequency); use a step below %g s or a tone below %g Hz", k + 1, f,
                     nyquist, h, 0.5 / fabs(f), nyquist);
            return 1;
        }
    }
    return 0;
}

int gyro_rate_nyquist_problem(const GyroRateProfile *r, double h, char *msg, size_t n) {
    const double nyquist = 0.5 / h;
    if (n) msg[0] = '\0';
    if (r->kind == GYRO_RATE_SINE && r->amplitude != 0.0 && r->frequency >= nyquist) {
        snprintf(msg, n, "rate frequency=%g Hz is at or above the Nyquist frequency %g Hz of "
                 "the %g s communication step: it aliases (the gyro sees another rate); use a "
                 "step below %g s or a frequency below %g Hz", r->frequency, nyquist, h,
                 0.5 / r->frequency, nyquist);
        return 1;
    }
    return 0;
}
