/* The gyroscope as a sensor: see gyro_sensor.h for the contract. */
#include "gyro_sensor.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "gyro_text.h"

/* Most full-scale / resolution (quantization levels per sign): rounding y / q stays exact
 * in a double far below 2^52. */
static const double MAX_LEVELS = 1e12;

size_t gyro_sensor_size(void) { return sizeof(GyroSensor); }

double gyro_sensor_step(const GyroReadout *r, const GyroParams *design) {
    if (r->internal_step > 0.0) return r->internal_step;
    const double omega = sqrt(design->kxx > design->kyy ? design->kxx : design->kyy);
    const double h = GYRO_SENSOR_OMEGA_H / omega;
    return h < GYRO_SENSOR_STEP_MAX ? h : GYRO_SENSOR_STEP_MAX;
}

/* The readout's own problems at internal step h (> 0). */
static int readout_problems(const GyroReadout *r, double h, char *msg, size_t n) {
    char a[GYRO_REAL_TEXT], b[GYRO_REAL_TEXT], text[300];
    if (n) msg[0] = '\0';
    if (!(isfinite(r->internal_step) && r->internal_step >= 0.0)) {
        snprintf(text, sizeof text, "internal_step=%s s must be 0 (auto) or finite and > 0",
                 gyro_real_text(r->internal_step, a));
        gyro_text_add(msg, n, text);
    }
    if (!(isfinite(r->bandwidth) && r->bandwidth > 0.0 && r->bandwidth * h < 0.25)) {
        snprintf(text, sizeof text, "bandwidth=%s Hz must be > 0 and below a quarter of the "
                 "internal sample rate (%s Hz): lower it or the internal_step",
                 gyro_real_text(r->bandwidth, a), gyro_real_text(0.25 / h, b));
        gyro_text_add(msg, n, text);
    }
    if (!(isfinite(r->full_scale) && r->full_scale > 0.0)) {
        snprintf(text, sizeof text, "full_scale=%s rad/s must be finite and > 0",
                 gyro_real_text(r->full_scale, a));
        gyro_text_add(msg, n, text);
    }
    if (!(isfinite(r->resolution) && r->resolution >= 0.0 &&
          (r->resolution == 0.0 || r->full_scale / r->resolution <= MAX_LEVELS))) {
        snprintf(text, sizeof text, "resolution=%s rad/s must be 0 (not quantized) or a "
                 "positive step with at most %.0e levels up to full_scale",
                 gyro_real_text(r->resolution, a), MAX_LEVELS);
        gyro_text_add(msg, n, text);
    }
    return msg[0] ? 1 : 0;
}

/* The plant's noise per sample at step h: the same density as `noise` per
 * GYRO_SENSOR_NOISE_STEP. */
static GyroPickoffNoise per_sample(const GyroPickoffNoise *noise, double h) {
    const double f = sqrt(GYRO_SENSOR_NOISE_STEP / h);
    return (GyroPickoffNoise){noise->x * f, noise->vx * f, noise->y * f, noise->vy * f};
}

/* 2nd-order Butterworth low-pass by the bilinear transform, prewarped at f_c. */
static void butterworth(double fc, double h, double b[3], double a[3]) {
    const double K = tan(GYRO_PI * fc * h), K2 = K * K, r2 = sqrt(2.0);
    const double norm = 1.0 / (1.0 + r2 * K + K2);
    b[0] = K2 * norm, b[1] = 2.0 * b[0], b[2] = b[0];
    a[0] = 1.0, a[1] = 2.0 * (K2 - 1.0) * norm, a[2] = (1.0 - r2 * K + K2) * norm;
}

/* The filter at rest at x (its steady state for a constant input x). */
static void filter_rest(GyroSensor *s, double x) {
    s->w[0] = (1.0 - s->b[0]) * x;
    s->w[1] = (s->b[2] - s->a[2]) * x;
    s->y = x;
}

static double filter_step(GyroSensor *s, double x) {
    const double y = s->b[0] * x + s->w[0];
    s->w[0] = s->b[1] * x - s->a[1] * y + s->w[1];
    s->w[1] = s->b[2] * x - s->a[2] * y;
    return y;
}

int gyro_sensor_init(GyroSensor *s, const GyroParams *truth, const GyroPickoffNoise *noise,
                     uint64_t seed, const GyroParams *design, double Omega_z_0,
                     const GyroObserverTuning *tuning, const GyroTwoToneDrive *drive,
                     const GyroReadout *readout, double t0, char *msg, size_t n) {
    char text[GYRO_OBS_MESSAGE];
    if (gyro_params_problems(truth, text, sizeof text)) {
        snprintf(msg, n, "the gyro as fabricated is unusable: %s", text);
        return 1;
    }
    if (gyro_params_problems(design, text, sizeof text)) {
        snprintf(msg, n, "the design values are unusable: %s", text);
        return 1;
    }
    const double h = gyro_sensor_step(readout, design);
    if (gyro_drive_problems(drive, msg, n) || readout_problems(readout, h, msg, n) ||
        gyro_drive_nyquist_problem(drive, h, msg, n))
        return 1;
    if (!isfinite(t0)) {
        snprintf(msg, n, "start time %g s must be finite", t0);
        return 1;
    }
    memset(s, 0, sizeof *s);
    if (gyro_observer_init(&s->observer, design, Omega_z_0, 1, tuning, text, sizeof text)) {
        snprintf(msg, n, "the observer cannot start from the design values: %s", text);
        return 1;
    }
    const double omega = s->observer.wx > s->observer.wy ? s->observer.wx : s->observer.wy;
    if (omega * h > GYRO_OBS_OMEGA_H_WARN) { /* the observer would degrade (and warn) */
        snprintf(msg, n, "internal_step=%g s is too coarse for the gyro's design resonance "
                 "(%.5g Hz, omega h = %.3g > %g): use internal_step <= %.3g s, or 0 (auto)",
                 h, omega / (2.0 * GYRO_PI), omega * h, GYRO_OBS_OMEGA_H_WARN,
                 GYRO_OBS_OMEGA_H_WARN / omega);
        return 1;
    }
    s->drive = *drive;
    s->readout = *readout;
    s->h = h;
    s->t0 = t0;
    const GyroPickoffNoise sigma = per_sample(noise, h);
    gyro_plant_init(&s->plant, truth, &sigma, seed, NULL);
    butterworth(readout->bandwidth, h, s->b, s->a);
    filter_rest(s, Omega_z_0);
    return 0;
}

double gyro_sensor_time(const GyroSensor *s) { return s->t0 + (double)s->k * s->h; }

int gyro_sensor_advance(GyroSensor *s, double Omega_z, double t_end, char *msg, size_t n) {
    char num[GYRO_REAL_TEXT];
    const double h = s->h;
    if (gyro_rate_problem(&s->plant.p, "Omega_z", Omega_z, msg, n)) return GYRO_OBS_BAD_INPUT;
    const double steps = floor((t_end - gyro_sensor_time(s)) / h * (1.0 + 1e-12) + 1e-9);
    if (!(steps <= GYRO_SENSOR_MAX_STEPS)) {
        snprintf(msg, n, "a communication step to t=%s s needs %.4g internal steps of %g s, "
                 "above the %d one call may do: use communication steps of at most %g s",
                 gyro_real_text(t_end, num), steps, h, GYRO_SENSOR_MAX_STEPS,
                 GYRO_SENSOR_MAX_STEPS * h);
        return GYRO_OBS_BAD_INPUT;
    }
    int code = s->observer.status;
    for (int64_t j = 0; j < (int64_t)steps; j++) {
        const double t = gyro_sensor_time(s);
        const double ux = gyro_drive_ux(&s->drive, t);
        double z[6];
        gyro_plant_outputs(&s->plant, z);
        code = gyro_observer_step(&s->observer, ux, 0.0, z[0], z[2], h, msg, n);
        if (code < 0 || code == GYRO_OBS_STEP_LOST) return code;
        gyro_plant_step(&s->plant, ux, 0.0, Omega_z, h);
        s->y = filter_step(s, s->observer.x[GYRO_OBS_IOM]);
        s->k++;
    }
    return code;
}

void gyro_sensor_outputs(const GyroSensor *s, double out[5]) {
    const GyroReadout *r = &s->readout;
    double y = s->y;
    const int saturated = fabs(y) > r->full_scale; /* false for NaN: NaN stays NaN */
    if (saturated) y = y > 0.0 ? r->full_scale : -r->full_scale;
    if (r->resolution > 0.0) y = r->resolution * nearbyint(y / r->resolution);
    double est[20];
    gyro_observer_outputs(&s->observer, est);
    out[0] = y;
    out[1] = sqrt(est[12] * est[12] + r->resolution * r->resolution / 12.0);
    out[2] = est[4];
    out[3] = s->observer.status;
    out[4] = saturated ? 1.0 : 0.0;
}

int gyro_sensor_restored_problem(GyroSensor *s, const GyroParams *truth,
                                 const GyroPickoffNoise *noise, const GyroParams *design,
                                 double Omega_z_0, const GyroObserverTuning *tuning,
                                 const GyroTwoToneDrive *drive, const GyroReadout *readout,
                                 char *msg, size_t n) {
    if (memcmp(&s->drive, drive, sizeof *drive) != 0 ||
        memcmp(&s->readout, readout, sizeof *readout) != 0) {
        snprintf(msg, n, "the saved sensor was built with another drive or readout than this "
                 "instance's: set the parameters it was saved with");
        return 1;
    }
    const double h = gyro_sensor_step(readout, design);
    const GyroPickoffNoise sigma = per_sample(noise, h);
    if (memcmp(&s->h, &h, sizeof h) != 0) {
        snprintf(msg, n, "the saved sensor runs at another internal step than this instance's "
                 "settings give: set the parameters it was saved with");
        return 1;
    }
    if (gyro_plant_restored_problem(&s->plant, truth, &sigma, msg, n)) return 1;
    if (gyro_observer_restored_problem(&s->observer, design, Omega_z_0, 1, tuning, msg, n))
        return 1;
    double b[3], a[3];
    butterworth(readout->bandwidth, h, b, a);
    const int same = memcmp(b, s->b, sizeof b) == 0 && memcmp(a, s->a, sizeof a) == 0;
    if (!same || !isfinite(s->w[0]) || !isfinite(s->w[1]) || !isfinite(s->y) ||
        !isfinite(s->t0) || s->k < 0 || s->k > (int64_t)1 << 52) {
        snprintf(msg, n, "the saved sensor holds a readout filter or clock that this "
                 "instance cannot have: restore a state this FMU saved");
        return 1;
    }
    return 0;
}
