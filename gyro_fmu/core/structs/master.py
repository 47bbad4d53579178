"""The co-simulation master's plan and outcome (fmu_src/core/gyro_master.h; the loop
gyro_fmu.cosim.stepping runs): what the C loop calls through the FMUs' own function
pointers, and where the values go."""

from __future__ import annotations

from .base import Field, Struct

#: fmi2GetReal / fmi2SetReal and fmi2DoStep as the loop calls them (emitted before the
#: structs: the plan holds arrays of them).
FUNCTION_TYPES = (
    "typedef int (*GyroFmi2GetSetReal)(void *component, const uint32_t *vrs, size_t n,",
    "                                  double *values);",
    "typedef int (*GyroFmi2DoStep)(void *component, double t, double h, int no_set_prior_state);",
)

PLAN = Struct("GyroMasterPlan", "What the loop calls and where the values go (the master "
              "builds it once per run).", (
    Field("n_get", "int64_t", doc="getReal calls (FMU i: get_n[i] values at get_col[i] on)"),
    Field("get_fn", "GyroFmi2GetSetReal *"),
    Field("get_comp", "void **"),
    Field("get_vrs", "const uint32_t **"),
    Field("get_n", "const int64_t *"),
    Field("get_col", "const int64_t *"),
    Field("n_set", "int64_t", doc="setReal calls (FMU i: set_n[i] values, from set_col[i] "
          "on,"),
    Field("set_fn", "GyroFmi2GetSetReal *"),
    Field("set_comp", "void **"),
    Field("set_vrs", "const uint32_t **"),
    Field("set_n", "const int64_t *"),
    Field("set_col", "const int64_t *"),
    Field("set_first", "const int64_t *", doc="or gathered from columns gather[set_first[i]..]"),
    Field("gather", "const int64_t *"),
    Field("buf", "double *", doc="into buf, where not consecutive)"),
    Field("n_step", "int64_t", doc="doStep calls, in this order"),
    Field("step_fn", "GyroFmi2DoStep *"),
    Field("step_comp", "void **"),
))

OUTCOME = Struct("GyroMasterOutcome", "Result of a refused call (status above fmi2Warning); "
                 "phase -1 when none was.", (
    Field("k", "int64_t", doc="communication point of the refusal (or the last one filled)"),
    Field("phase", "int64_t", doc="0 getReal, 1 setReal, 2 doStep, -1 none"),
    Field("index", "int64_t", doc="which call of that phase"),
    Field("status", "int64_t", doc="the fmi2Status it returned"),
))

CONSTANTS = ()
STRUCTS = (PLAN, OUTCOME)
