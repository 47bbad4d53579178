/* The FMI layer's values: get and set by value reference, each value checked against its
 * variable (causality, fixed parameters after initialization, range) before any is
 * stored, so a refused call changes nothing. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "gyro_text.h"
#include "instance.h"
#include "instance_internal.h"

int inst_range_problem(const GyroVariable *v, double value, char *msg, size_t n) {
    char a[40], b[40];
    msg[0] = '\0';
    if (!isfinite(value)) {
        snprintf(msg, n, "%s %s=%s is not finite: give a finite value in %s",
                 v->causality == GYRO_PARAMETER ? "parameter" : "input", v->name,
                 gyro_real_text(value, a), v->unit[0] ? v->unit : "1");
    } else if (value < v->min || (v->min_exclusive && value == v->min)) {
        snprintf(msg, n, "%s=%s %s minimum %g: use %s %g", v->name, gyro_real_text(value, a),
                 value < v->min ? "is below its" : "is its exclusive", v->min,
                 v->min_exclusive ? ">" : ">=", v->min);
    } else if (value > v->max) {
        snprintf(msg, n, "%s=%s is above its maximum %g: use <= %g", v->name,
                 gyro_real_text(value, b), v->max, v->max);
    }
    return msg[0] != '\0';
}

/* ---- values ---- */
/* The variable of value reference vr, or NULL. The generated tables number them from 1
 * in order (gyro_fmu/fmu/native.py: variables[vr - 1] has vr), so it is an index; the
 * search stays for a table built otherwise (a linear search was 4 % of a step). */
static const GyroVariable *find(const Instance *inst, uint32_t vr) {
    const GyroModel *m = inst->model;
    if (vr >= 1 && vr <= m->n_variables && m->variables[vr - 1].vr == vr)
        return &m->variables[vr - 1];
    for (size_t i = 0; i < m->n_variables; i++)
        if (m->variables[i].vr == vr) return &m->variables[i];
    return NULL;
}

static const GyroVariable *find_typed(Instance *inst, uint32_t vr, GyroVarType type,
                                      const char *call) {
    const GyroVariable *v = find(inst, vr);
    const char *want = type == GYRO_FLOAT64 ? (inst->fmi_version == 2 ? "Real" : "Float64")
                                            : (inst->fmi_version == 2 ? "Integer" : "Int32");
    if (!v)
        inst_logf(inst, ST_ERROR, "%s: no variable has value reference %u (see the model "
                  "description's ModelVariables)", call, (unsigned)vr);
    else if (v->type != type)
        inst_logf(inst, ST_ERROR, "%s: value reference %u is %s, not a %s variable", call,
                  (unsigned)vr, v->name, want);
    else
        return v;
    return NULL;
}

static Status get_values(Instance *inst, const uint32_t vr[], size_t n, void *values,
                         GyroVarType type, const char *call) {
    if (n && (!vr || !values)) {
        inst_logf(inst, ST_ERROR, "%s: NULL value reference or value array", call);
        return ST_ERROR;
    }
    for (size_t i = 0; i < n; i++) {
        if (inst->fmi_version == 3 && type == GYRO_FLOAT64 && vr[i] == 0) {
            ((double *)values)[i] = inst->time; /* the independent variable */
            continue;
        }
        const GyroVariable *v = find_typed(inst, vr[i], type, call);
        if (!v) return ST_ERROR;
        if (type == GYRO_FLOAT64)
            ((double *)values)[i] = *(double *)(inst->data + v->offset);
        else
            ((int32_t *)values)[i] = *(int32_t *)(inst->data + v->offset);
    }
    return ST_OK;
}

/* Checks one value for v; "" when it may be set now. */
static int set_problem(Instance *inst, const GyroVariable *v, double value, char *msg,
                       size_t n) {
    char a[40], b[40];
    if (v->causality == GYRO_OUTPUT) {
        snprintf(msg, n, "%s is an output: the FMI standard forbids setting it (refused %s)",
                 v->name, gyro_real_text(value, a));
        return 1;
    }
    if (v->causality == GYRO_PARAMETER &&
        !(inst->mode & (MODE_INSTANTIATED | MODE_INITIALIZATION))) {
        const double kept = v->type == GYRO_FLOAT64 ? *(double *)(inst->data + v->offset)
                                                    : *(int32_t *)(inst->data + v->offset);
        snprintf(msg, n, "%s is a fixed parameter and cannot change after initialization "
                 "(kept %s, refused %s): set it before %s, or instantiate anew", v->name,
                 gyro_real_text(kept, a), gyro_real_text(value, b),
                 inst->fmi_version == 2 ? "fmi2ExitInitializationMode"
                                        : "fmi3ExitInitializationMode");
        return 1;
    }
    if (inst_range_problem(v, value, msg, n)) {
        const double kept = v->type == GYRO_FLOAT64 ? *(double *)(inst->data + v->offset)
                                                    : *(int32_t *)(inst->data + v->offset);
        const size_t used = strlen(msg);
        snprintf(msg + used, n - used, " (kept %s)", gyro_real_text(kept, a));
        return 1;
    }
    return 0;
}

static Status set_values(Instance *inst, const uint32_t vr[], size_t n, const void *values,
                         GyroVarType type, const char *call) {
    if (n && (!vr || !values)) {
        inst_logf(inst, ST_ERROR, "%s: NULL value reference or value array", call);
        return ST_ERROR;
    }
    char msg[GYRO_MESSAGE_SIZE];
    /* all checked before any is stored: a refused call changes nothing */
    for (size_t i = 0; i < n; i++) {
        if (inst->fmi_version == 3 && vr[i] == 0) {
            inst_logf(inst, ST_ERROR, "%s: time (value reference 0) is the independent "
                      "variable and cannot be set", call);
            return ST_ERROR;
        }
        const GyroVariable *v = find_typed(inst, vr[i], type, call);
        if (!v) return ST_ERROR;
        const double value = type == GYRO_FLOAT64 ? ((const double *)values)[i]
                                                  : ((const int32_t *)values)[i];
        if (set_problem(inst, v, value, msg, sizeof msg)) {
            inst_logf(inst, ST_ERROR, "%s", msg);
            return ST_ERROR;
        }
    }
    for (size_t i = 0; i < n; i++) {
        const GyroVariable *v = find(inst, vr[i]);
        if (type == GYRO_FLOAT64)
            *(double *)(inst->data + v->offset) = ((const double *)values)[i];
        else
            *(int32_t *)(inst->data + v->offset) = ((const int32_t *)values)[i];
    }
    return ST_OK;
}

Status inst_get_float64(Instance *inst, const uint32_t vr[], size_t n, double values[]) {
    return get_values(inst, vr, n, values, GYRO_FLOAT64, "get Real");
}
Status inst_set_float64(Instance *inst, const uint32_t vr[], size_t n, const double values[]) {
    return set_values(inst, vr, n, values, GYRO_FLOAT64, "set Real");
}
Status inst_get_int32(Instance *inst, const uint32_t vr[], size_t n, int32_t values[]) {
    return get_values(inst, vr, n, values, GYRO_INT32, "get Integer");
}
Status inst_set_int32(Instance *inst, const uint32_t vr[], size_t n, const int32_t values[]) {
    return set_values(inst, vr, n, values, GYRO_INT32, "set Integer");
}
