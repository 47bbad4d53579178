#include "gyro_carrier.h"

#include <stdio.h>

int gyro_carrier_run(GyroResonator *r, GyroLoops *l, int64_t k0, int64_t n, double h,
                     double Omega_z, double *rec, int64_t rows, int64_t r0, int64_t *done,
                     char *msg, size_t msg_size) {
    *done = 0;
    if (n < 0 || k0 < 0 || (n > 0 && k0 + n - 1 >= r0 && (k0 + n - 1 - r0 >= rows || r0 < 0))) {
        snprintf(msg, msg_size, "gyro_carrier_run: steps %lld..%lld from row %lld do not fit "
                 "a record of %lld rows", (long long)k0, (long long)(k0 + n - 1),
                 (long long)r0, (long long)rows);
        return 1;
    }
    for (int64_t j = 0; j < n; j++) {
        const int64_t k = k0 + j;
        const double t = 0.0 + k * h;
        if (k >= r0) {
            double *row = rec + (k - r0) * GYRO_CARRIER_COLUMNS;
            const GyroLoopOutputs *o = &l->out;
            row[0] = t;
            row[1] = o->Vx, row[2] = o->Vy, row[3] = o->theta, row[4] = o->omega;
            row[5] = o->amplitude, row[6] = o->phase_error, row[7] = o->gain;
            row[8] = o->rate, row[9] = o->quad;
            row[10] = r->out[0], row[11] = r->out[1];
        }
        const double px = r->out[0], py = r->out[1];
        if (gyro_resonator_step(r, l->out.Vx, l->out.Vy, Omega_z, h, msg, msg_size)) return 1;
        gyro_loops_step(l, px, py, t, h);
        *done = j + 1;
    }
    return 0;
}
