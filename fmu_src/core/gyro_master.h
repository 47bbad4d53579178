/* The co-simulation master's stepping loop (gyro_fmu.cosim.master runs it): FMI 2.0
 * fmi2GetReal / fmi2SetReal / fmi2DoStep called through the FMUs' own function pointers,
 * Jacobi order, no Python per call. Per communication point t_k: one getReal per FMU with
 * outputs (straight into the result row), then, but at the last point, one setReal per
 * connected FMU and one doStep per FMU. */
#ifndef GYRO_MASTER_H
#define GYRO_MASTER_H

#include <stddef.h>
#include <stdint.h>

/* GyroMasterPlan (what the loop calls and where the values go), GyroMasterOutcome (a
 * refused call) and the function types: generated from gyro_fmu/core/structs/master.py. */
#include "gyro_structs.h"

/* Fill the rows of points first..last (point k, t_k = start_time + k h, in row k - row0 of
 * data, ncol columns: t_k, then the outputs) and step every FMU from each t_k but the
 * final one (k = n, the run's last point). row0 = 0 with n + 1 rows holds the whole run;
 * a master that hands each chunk on reuses one buffer with row0 = first. */
GyroMasterOutcome gyro_master_steps(double *data, int64_t row0, int64_t n, int64_t ncol,
                                    double start_time, double h, int64_t first, int64_t last,
                                    const GyroMasterPlan *plan);

#endif
