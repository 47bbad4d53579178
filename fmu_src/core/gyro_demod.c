/* The streaming demodulator: see gyro_demod.h. */
#include "gyro_demod.h"

#include "gyro_carrier.h"
#include "gyro_text.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* Record columns read (gyro_carrier.h: time, 9 loop outputs, Vpx, Vpy). */
enum { COL_VX = 1, COL_VY = 2, COL_THETA = 3, COL_AMPLITUDE = 5, COL_PHASE_ERROR = 6,
       COL_GAIN = 7, COL_VPX = 10, COL_VPY = 11 };
static const int CHANNEL_COLUMN[GYRO_DEMOD_CHANNELS] = {COL_VX, COL_VY, COL_VPX, COL_VPY};

static double wrap_pi(double a) { return a - 2.0 * GYRO_PI * nearbyint(a / (2.0 * GYRO_PI)); }

void gyro_demod_kernel(int64_t B, double *kernel) {
    const int64_t len = GYRO_DEMOD_ORDER * B;
    memset(kernel, 0, (size_t)len * sizeof(double));
    for (int64_t j = 0; j < B; j++) kernel[j] = 1.0 / (double)B;
    int64_t have = B; /* support of the convolution so far */
    for (int stage = 1; stage < GYRO_DEMOD_ORDER; stage++) {
        /* in place, from the end: kernel[j] <- sum of the old kernel[j - B + 1 .. j] / B,
         * the window's sum kept running (old values saved before they are overwritten) */
        double sum = kernel[have - 1];
        for (int64_t j = have + B - 2; j >= 0; j--) {
            const double old = kernel[j];
            kernel[j] = sum / (double)B;
            if (j <= have - 1) sum -= old;
            if (j - B >= 0) sum += kernel[j - B];
        }
        have += B - 1;
    }
}

/* Index of the first step of output 0's window: its centre r0 + (B - 1) / 2 less half the
 * (ORDER (B - 1) + 1)-step support; whole because ORDER is odd. */
static int64_t first_window(const GyroDemod *d) {
    return d->r0 - (GYRO_DEMOD_ORDER - 1) * (d->B - 1) / 2;
}

int64_t gyro_demod_first_step(const GyroDemod *d) { return first_window(d); }

int64_t gyro_demod_last_step(const GyroDemod *d) {
    return first_window(d) + (d->n / d->B - 1 + GYRO_DEMOD_ORDER) * d->B - 1;
}

int gyro_demod_init(GyroDemod *d, double omega0, double h, int64_t r0, int64_t n, int64_t B,
                    int64_t tail, double drive_limit, double *base, double *theta,
                    double *tail_po, const double *kernel, char *msg, size_t msg_size) {
    memset(d, 0, sizeof(*d));
    if (!(isfinite(omega0) && isfinite(h) && h > 0.0 && B >= 1 && n >= B && n % B == 0 &&
          tail >= 0 && tail <= n && r0 - (GYRO_DEMOD_ORDER - 1) * (B - 1) / 2 >= 0 &&
          !isnan(drive_limit))) {
        snprintf(msg, msg_size, "gyro_demod_init: omega0 %g rad/s, step %g s, a record of "
                 "%lld steps from %lld, decimation %lld, tail %lld: the record must be a "
                 "whole number (>= 1) of decimation blocks starting at least %d blocks into "
                 "the run, the tail within it",
                 omega0, h, (long long)n, (long long)r0, (long long)B, (long long)tail,
                 (GYRO_DEMOD_ORDER - 1) / 2);
        return 1;
    }
    d->omega0 = omega0, d->h = h, d->r0 = r0, d->n = n, d->B = B, d->tail = tail;
    d->drive_limit = drive_limit;
    d->base = base, d->theta = theta, d->tail_po = tail_po, d->kernel = kernel;
    d->next = first_window(d);
    return 0;
}

static void record_statistics(GyroDemod *d, const double *row, int64_t k) {
    const double pe = fabs(row[COL_PHASE_ERROR]);
    if (!isnan(d->worst_phase_error) && (isnan(pe) || pe > d->worst_phase_error))
        d->worst_phase_error = pe;
    d->sum_amplitude += row[COL_AMPLITUDE];
    d->pinned += row[COL_GAIN] >= d->drive_limit;
    if (!isnan(d->gain_peak) && !(row[COL_GAIN] <= d->gain_peak))
        d->gain_peak = row[COL_GAIN]; /* a NaN sticks */
    d->sum_gain += row[COL_GAIN];
    d->counted++;
    const int64_t t0 = d->r0 + d->n - d->tail;
    if (k >= t0) {
        d->tail_po[2 * (k - t0)] = row[COL_VPX];
        d->tail_po[2 * (k - t0) + 1] = row[COL_VPY];
    }
}

int gyro_demod_feed(GyroDemod *d, const double *rows, int64_t k_first, int64_t count,
                    char *msg, size_t msg_size) {
    const int64_t first = first_window(d), last = gyro_demod_last_step(d), B = d->B;
    const int64_t M = d->n / B;
    for (int64_t j = 0; j < count; j++) {
        const int64_t k = k_first + j;
        if (k < d->next) continue; /* before the first step read */
        if (k > d->next) {
            snprintf(msg, msg_size, "gyro_demod_feed: step %lld fed where %lld was expected",
                     (long long)k, (long long)d->next);
            return 1;
        }
        d->next = k + 1;
        if (k > last) continue;
        const double *row = rows + j * GYRO_CARRIER_COLUMNS;
        /* the NCO phase's departure from omega0 t, unwrapped (a small number, so that
         * its sum keeps its precision over 1e8 steps) */
        const double th = row[COL_THETA];
        if (d->has_theta) {
            d->phase_departure += wrap_pi(th - d->theta_last - d->omega0 * d->h);
        } else {
            d->phase_departure = wrap_pi(th - fmod(d->omega0 * ((double)k * d->h), 2.0 * GYRO_PI));
            d->has_theta = 1;
        }
        d->theta_last = th;
        if (k >= d->r0 && k < d->r0 + d->n) {
            record_statistics(d, row, k);
        }
        if (k < first) continue;
        /* mix down and add into the ORDER windows holding step k */
        const double phi = d->omega0 * ((double)k * d->h), c = cos(phi), s = -sin(phi);
        const int64_t p = k - first, newest = p / B, q = p % B;
        for (int w = 0; w < GYRO_DEMOD_ORDER; w++) {
            const int64_t b = newest - w;
            if (b < 0 || b >= M) continue;
            const double g = d->kernel[q + w * B];
            double (*acc)[2] = d->acc[b % GYRO_DEMOD_ORDER];
            for (int ch = 0; ch < GYRO_DEMOD_CHANNELS; ch++) {
                const double v = g * row[CHANNEL_COLUMN[ch]];
                acc[ch][0] += v * c, acc[ch][1] += v * s;
            }
            d->acc_theta[b % GYRO_DEMOD_ORDER] += g * d->phase_departure;
        }
        if (q == B - 1) { /* the oldest window is whole */
            const int64_t b = newest - (GYRO_DEMOD_ORDER - 1);
            if (b >= 0 && b < M) {
                double (*acc)[2] = d->acc[b % GYRO_DEMOD_ORDER];
                memcpy(d->base + b * GYRO_DEMOD_CHANNELS * 2, acc, sizeof(d->acc[0]));
                memset(acc, 0, sizeof(d->acc[0]));
                d->theta[b] = d->acc_theta[b % GYRO_DEMOD_ORDER];
                d->acc_theta[b % GYRO_DEMOD_ORDER] = 0.0;
                d->emitted++;
            }
        }
    }
    return 0;
}

double gyro_demod_response(const GyroDemod *d, double f) {
    const double x = GYRO_PI * f * d->h, sx = sin(x);
    if (fabs(sx) < 1e-300) return 1.0;
    return pow(sin((double)d->B * x) / ((double)d->B * sx), GYRO_DEMOD_ORDER);
}

size_t gyro_demod_size(void) { return sizeof(GyroDemod); }
