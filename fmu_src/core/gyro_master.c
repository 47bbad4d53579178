/* The master's stepping loop: see gyro_master.h. */
#include "gyro_master.h"

GyroMasterOutcome gyro_master_steps(double *data, int64_t row0, int64_t n, int64_t ncol,
                                    double start_time, double h, int64_t first, int64_t last,
                                    const GyroMasterPlan *plan) {
    for (int64_t k = first; k <= last; k++) {
        const double t = start_time + (double)k * h;
        double *row = data + (k - row0) * ncol;
        row[0] = t;
        for (int64_t i = 0; i < plan->n_get; i++) {
            const int status = plan->get_fn[i](plan->get_comp[i], plan->get_vrs[i],
                                               (size_t)plan->get_n[i], row + plan->get_col[i]);
            if (status > 1) return (GyroMasterOutcome){k, 0, i, status};
        }
        if (k == n) break;
        for (int64_t i = 0; i < plan->n_set; i++) {
            double *values;
            if (plan->set_col[i] >= 0) {
                values = row + plan->set_col[i];
            } else {
                const int64_t j0 = plan->set_first[i];
                for (int64_t j = j0; j < j0 + plan->set_n[i]; j++)
                    plan->buf[j] = row[plan->gather[j]];
                values = plan->buf + j0;
            }
            const int status = plan->set_fn[i](plan->set_comp[i], plan->set_vrs[i],
                                               (size_t)plan->set_n[i], values);
            if (status > 1) return (GyroMasterOutcome){k, 1, i, status};
        }
        for (int64_t i = 0; i < plan->n_step; i++) {
            const int status = plan->step_fn[i](plan->step_comp[i], t, h, 1);
            if (status > 1) return (GyroMasterOutcome){k, 2, i, status};
        }
    }
    return (GyroMasterOutcome){last, -1, -1, 0};
}
