/* The standard system in one C loop (gyro_chain.h). */
#include "gyro_chain.h"

int64_t gyro_chain_run(const GyroTwoToneDrive *drive, const GyroRateProfile *rate,
                       GyroPlant *plant, GyroObserver *obs, int pair, double h,
                       int64_t n_steps, double *rows, int *code, char *msg, size_t n) {
    const int first = pair == 1 ? 0 : 1, second = pair == 1 ? 2 : 3; /* x, y or vx, vy */
    double t_eval = 0.0; /* the FMUs evaluate a source at t_prev + h, not k h */
    *code = GYRO_OBS_STEP_OK;
    for (int64_t k = 0; k <= n_steps; k++) {
        double *row = rows + k * GYRO_CHAIN_COLUMNS;
        const double ux = gyro_drive_ux(drive, t_eval), Omega_z = gyro_rate_Omega_z(rate, t_eval);
        row[0] = (double)k * h;
        t_eval = row[0] + h;
        row[1] = ux;
        row[2] = 0.0;
        row[3] = Omega_z;
        gyro_plant_outputs(plant, row + 4);
        gyro_observer_outputs(obs, row + 10);
        gyro_observer_rate_probabilities(obs, row + 30);
        if (k == n_steps) break;
        gyro_plant_step(plant, ux, 0.0, Omega_z, h);
        *code = gyro_observer_step(obs, ux, 0.0, row[4 + first], row[4 + second], h, msg, n);
        if (*code < 0 || *code == GYRO_OBS_STEP_LOST) return k + 1;
    }
    return n_steps + 1;
}
