/* The resonator and its loops at carrier rate, in process, in the FMUs' Jacobi order: at
 * every communication point t_k = k h both publish their outputs, each takes the other's,
 * and both step to t_k + h, exactly what a master does with GyroResonator.fmu and
 * GyroLoops.fmu (the self-calibration library runs its long records here). */
#ifndef GYRO_CARRIER_H
#define GYRO_CARRIER_H

#include <stdint.h>

#include "gyro_loops.h"
#include "gyro_resonator.h"

/* Columns of a recorded row: time, the 9 loop outputs, Vpx, Vpy. */
#define GYRO_CARRIER_COLUMNS 12

/* Steps k0 .. k0 + n - 1 with Omega_z held; rows of points k >= r0 go to rec[k - r0],
 * rec holding rows rows. 1 (and msg) when the resonator refuses a step or a row would
 * fall outside rec (nothing is written there); *done then counts the steps taken. */
int gyro_carrier_run(GyroResonator *r, GyroLoops *l, int64_t k0, int64_t n, double h,
                     double Omega_z, double *rec, int64_t rows, int64_t r0, int64_t *done,
                     char *msg, size_t msg_size);

#endif
