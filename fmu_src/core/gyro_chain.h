/* The standard system of patent Fig. 2 (drive, rate, plant, observer) stepped in one C
 * loop: the library's in-process run (gyro_fmu.system.inprocess) without a Python call
 * per step. It computes what the four FMUs under the master compute, bit for bit. */
#ifndef GYRO_CHAIN_H
#define GYRO_CHAIN_H

#include <stddef.h>
#include <stdint.h>

#include "gyro_observer.h"
#include "gyro_plant.h"
#include "gyro_signals.h"

/* A row: t, ux, uy (0), Omega_z, the plant's 6 outputs (x, vx, y, vy measured, ax, ay),
 * the observer's 20 outputs (gyro_observer_outputs), its 4 rate probabilities. */
enum { GYRO_CHAIN_COLUMNS = 4 + 6 + 20 + 4 };

/* Rows of points k = 0..n_steps (t_k = k h) into rows[(n_steps + 1) * GYRO_CHAIN_COLUMNS];
 * between points the plant and the observer step from t_k with the values of t_k held
 * (the master's Jacobi order); the sources are evaluated at t_{k-1} + h as the FMUs do.
 * The observer measures the pair `pair` (1: x, y; 2: vx, vy). Returns the rows filled;
 * *code is the last observer step's result (GYRO_OBS_STEP_OK, ...): a run stops after
 * the step that lost the filter or that refused (code < 0), msg saying why. */
int64_t gyro_chain_run(const GyroTwoToneDrive *drive, const GyroRateProfile *rate,
                       GyroPlant *plant, GyroObserver *obs, int pair, double h,
                       int64_t n_steps, double *rows, int *code, char *msg, size_t n);

#endif
