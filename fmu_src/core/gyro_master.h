/* The co-simulation master's stepping loop (gyro_fmu.cosim.master runs it): FMI 2.0
 * fmi2GetReal / fmi2SetReal / fmi2DoStep called through the FMUs' own function pointers,
 * Jacobi order, no Python per call. Per communication point t_k: one getReal per FMU with
 * outputs (straight into the result row), then, but at the last point, one setReal per
 * connected FMU and one doStep per FMU. */
#ifndef GYRO_MASTER_H
#define GYRO_MASTER_H

#include <stddef.h>
#include <stdint.h>

typedef int (*GyroFmi2GetSetReal)(void *component, const uint32_t *vrs, size_t n,
                                  double *values);
typedef int (*GyroFmi2DoStep)(void *component, double t, double h, int no_set_prior_state);

/* What the loop calls and where the values go (the master builds it once per run). */
typedef struct {
    int64_t n_get;           /* getReal calls: FMU i writes get_n[i] values at column */
    GyroFmi2GetSetReal *get_fn;
    void **get_comp;
    const uint32_t **get_vrs;
    const int64_t *get_n, *get_col;
    int64_t n_set;           /* setReal calls: FMU i takes set_n[i] values from the row, */
    GyroFmi2GetSetReal *set_fn; /* from column set_col[i] on if they are consecutive, */
    void **set_comp;         /* else gathered (columns gather[set_first[i]..]) into buf */
    const uint32_t **set_vrs;
    const int64_t *set_n, *set_col, *set_first, *gather;
    double *buf;
    int64_t n_step;          /* doStep calls, in this order */
    GyroFmi2DoStep *step_fn;
    void **step_comp;
} GyroMasterPlan;

/* Result of a refused call (status above fmi2Warning); phase -1 when none was. */
typedef struct {
    int64_t k;      /* communication point of the refusal (or the last one filled) */
    int64_t phase;  /* 0 getReal, 1 setReal, 2 doStep, -1 none */
    int64_t index;  /* which call of that phase */
    int64_t status; /* the fmi2Status it returned */
} GyroMasterOutcome;

/* Fill the rows of points first..last (point k, t_k = start_time + k h, in row k - row0 of
 * data, ncol columns: t_k, then the outputs) and step every FMU from each t_k but the
 * final one (k = n, the run's last point). row0 = 0 with n + 1 rows holds the whole run;
 * a master that hands each chunk on reuses one buffer with row0 = first. */
GyroMasterOutcome gyro_master_steps(double *data, int64_t row0, int64_t n, int64_t ncol,
                                    double start_time, double h, int64_t first, int64_t last,
                                    const GyroMasterPlan *plan);

#endif
