#include "instance.h"

#include "gyro_text.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
static SRWLOCK registry_lock = SRWLOCK_INIT;
#define LOCK() AcquireSRWLockExclusive(&registry_lock)
#define UNLOCK() ReleaseSRWLockExclusive(&registry_lock)
#else
#include <pthread.h>
static pthread_mutex_t registry_lock = PTHREAD_MUTEX_INITIALIZER;
#define LOCK() pthread_mutex_lock(&registry_lock)
#define UNLOCK() pthread_mutex_unlock(&registry_lock)
#endif

#define INSTANCE_MAGIC 0x47595231u /* "GYR1" */
#define STATE_MAGIC 0x47595353u    /* "GYSS" */
#define SERIAL_MAGIC "GYROFMU\x01"
#define TOKEN_BYTES 64

struct StateCopy {
    uint32_t magic;
    Instance *owner;
    StateCopy *next;
    Mode mode;
    double start_time, time;
    char failed[GYRO_MESSAGE_SIZE];
    unsigned char data[]; /* model->data_size bytes */
};

/* ---- registry of live instances: a freed or foreign pointer is never used ---- */
typedef struct Node {
    Instance *inst;
    struct Node *next;
} Node;
static Node *live = NULL;

static int registry_has(const void *ptr) {
    int found = 0;
    LOCK();
    for (Node *n = live; n; n = n->next)
        if (n->inst == ptr) {
            found = 1;
            break;
        }
    UNLOCK();
    return found;
}

static int registry_add(Instance *inst) {
    Node *n = malloc(sizeof *n);
    if (!n) return 0;
    LOCK();
    n->inst = inst;
    n->next = live;
    live = n;
    UNLOCK();
    return 1;
}

static int registry_remove(const void *ptr) {
    int found = 0;
    LOCK();
    for (Node **p = &live; *p; p = &(*p)->next)
        if ((*p)->inst == ptr) {
            Node *dead = *p;
            *p = dead->next;
            free(dead);
            found = 1;
            break;
        }
    UNLOCK();
    return found;
}

/* ---- logging ---- */
static const char *category_of(Status status) {
    switch (status) {
    case ST_OK: return "logEvents";
    case ST_WARNING: return "logStatusWarning";
    case ST_DISCARD: return "logStatusDiscard";
    case ST_ERROR: return "logStatusError";
    default: return "logStatusFatal";
    }
}

void inst_logf(Instance *inst, Status status, const char *fmt, ...) {
    if (!inst || !inst->log) return;
    if (status == ST_OK && !inst->logging_on) return;
    char msg[2 * GYRO_MESSAGE_SIZE];
    int used = snprintf(msg, sizeof msg, "%s: ", inst->model->identifier);
    va_list args;
    va_start(args, fmt);
    vsnprintf(msg + used, sizeof msg - (size_t)used, fmt, args);
    va_end(args);
    inst->log(inst, status, category_of(status), msg);
}

static const char *real_text(double v, char buf[GYRO_REAL_TEXT]) {
    return gyro_real_text(v, buf);
}

static const char *mode_name(Mode mode) {
    switch (mode) {
    case MODE_INSTANTIATED: return "instantiated";
    case MODE_INITIALIZATION: return "initialization mode";
    case MODE_STEP: return "step mode";
    case MODE_TERMINATED: return "terminated";
    case MODE_ERROR: return "error (a failed step or initialization)";
    default: return "fatal";
    }
}

/* ---- life cycle ---- */
static void apply_start_values(Instance *inst) {
    const GyroModel *m = inst->model;
    memset(inst->data, 0, m->data_size);
    for (size_t i = 0; i < m->n_variables; i++) {
        const GyroVariable *v = &m->variables[i];
        if (v->type == GYRO_FLOAT64)
            *(double *)(inst->data + v->offset) = v->start;
        else
            *(int32_t *)(inst->data + v->offset) = (int32_t)v->start;
    }
    inst->failed[0] = '\0';
    inst->start_time = inst->time = 0.0;
    inst->mode = MODE_INSTANTIATED;
}

static char *copy_text(const char *text) {
    if (!text) return NULL;
    char *out = malloc(strlen(text) + 1);
    if (out) strcpy(out, text);
    return out;
}

Instance *inst_new(const GyroModel *model, int fmi_version, const char *name,
                   const char *token, const char *resources, LogFunction log, void *log_fn,
                   void *log_env, int logging_on) {
    Instance probe = {0}; /* for messages before the instance exists */
    probe.model = model;
    probe.name = (char *)(name ? name : "");
    probe.log = log;
    probe.log_fn = log_fn;
    probe.log_env = log_env;
    probe.fmi_version = fmi_version;
    if (!token || strcmp(token, model->token) != 0) {
        inst_logf(&probe, ST_ERROR,
                  "instantiation token/guid '%s' is not this FMU's '%s': the host read another "
                  "model description than the one of this binary; re-import the FMU",
                  token ? token : "(null)", model->token);
        return NULL;
    }
    Instance *inst = calloc(1, sizeof *inst);
    unsigned char *data = calloc(1, model->data_size);
    if (!inst || !data) {
        free(inst);
        free(data);
        inst_logf(&probe, ST_ERROR, "out of memory");
        return NULL;
    }
    *inst = probe;
    inst->magic = INSTANCE_MAGIC;
    inst->data = data;
    inst->name = copy_text(name ? name : "");
    inst->resources = copy_text(resources);
    inst->logging_on = logging_on;
    apply_start_values(inst);
    if (!inst->name || !registry_add(inst)) {
        free(inst->name);
        free(inst->resources);
        free(data);
        free(inst);
        inst_logf(&probe, ST_ERROR, "out of memory");
        return NULL;
    }
    inst_logf(inst, ST_OK, "instantiated (FMI %d.0), resources at %s", fmi_version,
              resources ? resources : "(none given)");
    return inst;
}

void inst_free(void *ptr) {
    if (!ptr || !registry_remove(ptr)) return; /* NULL, foreign or already freed */
    Instance *inst = ptr;
    for (StateCopy *s = inst->states; s;) {
        StateCopy *next = s->next;
        s->magic = 0;
        free(s);
        s = next;
    }
    inst->magic = 0;
    free(inst->name);
    free(inst->resources);
    free(inst->data);
    free(inst);
}

Instance *inst_check(void *ptr, const char *call, unsigned modes) {
    if (!ptr || !registry_has(ptr)) return NULL;
    Instance *inst = ptr;
    if (inst->magic != INSTANCE_MAGIC) return NULL;
    if (!(inst->mode & modes)) {
        if (inst->mode == MODE_ERROR)
            inst_logf(inst, ST_ERROR, "%s refused: the instance failed (%s); reset it, restore "
                      "an FMU state saved before, or instantiate anew", call, inst->failed);
        else
            inst_logf(inst, ST_ERROR, "%s is not allowed in %s (FMI %d.0 state machine)", call,
                      mode_name(inst->mode), inst->fmi_version);
        return NULL;
    }
    return inst;
}

static void outputs_not_a_number(Instance *inst) {
    const GyroModel *m = inst->model;
    for (size_t i = 0; i < m->n_variables; i++)
        if (m->variables[i].causality == GYRO_OUTPUT && m->variables[i].type == GYRO_FLOAT64)
            *(double *)(inst->data + m->variables[i].offset) = NAN;
}

static Status fail(Instance *inst, const char *why) {
    snprintf(inst->failed, sizeof inst->failed, "%s", why);
    inst->mode = MODE_ERROR;
    outputs_not_a_number(inst);
    inst_logf(inst, ST_ERROR, "%s", why);
    return ST_ERROR;
}

Status inst_enter_initialization(Instance *inst, double start_time) {
    if (!isfinite(start_time)) {
        inst_logf(inst, ST_ERROR, "start time %g s is not finite: give a finite start time",
                  start_time);
        return ST_ERROR;
    }
    inst->start_time = inst->time = start_time;
    inst->mode = MODE_INITIALIZATION;
    return ST_OK;
}

/* Why `value` is not acceptable for v ("" when fine): gyro_fmu.model.interfaces.Var. */
static int range_problem(const GyroVariable *v, double value, char *msg, size_t n) {
    char a[40], b[40];
    msg[0] = '\0';
    if (!isfinite(value)) {
        snprintf(msg, n, "%s %s=%s is not finite: give a finite value in %s",
                 v->causality == GYRO_PARAMETER ? "parameter" : "input", v->name,
                 real_text(value, a), v->unit[0] ? v->unit : "1");
    } else if (value < v->min || (v->min_exclusive && value == v->min)) {
        snprintf(msg, n, "%s=%s %s minimum %g: use %s %g", v->name, real_text(value, a),
                 value < v->min ? "is below its" : "is its exclusive", v->min,
                 v->min_exclusive ? ">" : ">=", v->min);
    } else if (value > v->max) {
        snprintf(msg, n, "%s=%s is above its maximum %g: use <= %g", v->name,
                 real_text(value, b), v->max, v->max);
    }
    return msg[0] != '\0';
}

Status inst_exit_initialization(Instance *inst) {
    const GyroModel *m = inst->model;
    char msg[GYRO_MESSAGE_SIZE], why[GYRO_MESSAGE_SIZE + 64];
    for (size_t i = 0; i < m->n_variables; i++) {
        const GyroVariable *v = &m->variables[i];
        if (v->causality == GYRO_OUTPUT) continue;
        const double value = v->type == GYRO_FLOAT64 ? *(double *)(inst->data + v->offset)
                                                     : *(int32_t *)(inst->data + v->offset);
        if (range_problem(v, value, msg, sizeof msg)) {
            snprintf(why, sizeof why, "initialization failed: %s", msg);
            return fail(inst, why);
        }
    }
    const GyroHookStatus hook = m->setup(inst->data, inst->start_time, msg, sizeof msg);
    if (hook == GYRO_HOOK_ERROR) {
        snprintf(why, sizeof why, "initialization failed: %s", msg);
        return fail(inst, why);
    }
    inst->mode = MODE_STEP;
    if (hook == GYRO_HOOK_WARNING) {
        inst_logf(inst, ST_WARNING, "%s", msg);
        return ST_WARNING;
    }
    return ST_OK;
}

Status inst_do_step(Instance *inst, double t, double h) {
    if (!(isfinite(h) && h > 0.0) || !isfinite(t)) {
        inst_logf(inst, ST_ERROR, "step from t=%.9g s over h=%g s refused: the communication "
                  "step size must be > 0 and finite (nothing changed)", t, h);
        return ST_ERROR;
    }
    const GyroModel *m = inst->model;
    char msg[GYRO_MESSAGE_SIZE], why[3 * GYRO_MESSAGE_SIZE];
    const GyroHookStatus hook = m->step(inst->data, t, h, msg, sizeof msg);
    if (hook == GYRO_HOOK_ERROR) {
        snprintf(why, sizeof why, "the step from t=%.9g s over %g s failed: %s", t, h, msg);
        return fail(inst, why);
    }
    if (hook == GYRO_HOOK_DISCARD) { /* refused: time stays at t, the instance goes on */
        inst_logf(inst, ST_DISCARD, "the step from t=%.9g s over %g s was refused: %s", t, h,
                  msg);
        return ST_DISCARD;
    }
    /* every Real output finite, or the instance fails naming the outputs and inputs */
    int all_finite = 1;
    for (size_t i = 0; i < m->n_variables && all_finite; i++) {
        const GyroVariable *v = &m->variables[i];
        if (v->causality == GYRO_OUTPUT && v->type == GYRO_FLOAT64)
            all_finite = isfinite(*(double *)(inst->data + v->offset));
    }
    if (!all_finite) {
        char bad[GYRO_MESSAGE_SIZE] = "", held[GYRO_MESSAGE_SIZE] = "", num[40];
        for (size_t i = 0; i < m->n_variables; i++) {
            const GyroVariable *v = &m->variables[i];
            if (v->type != GYRO_FLOAT64) continue;
            const double value = *(double *)(inst->data + v->offset);
            char *list = v->causality == GYRO_OUTPUT  ? bad
                         : v->causality == GYRO_INPUT ? held
                                                      : NULL;
            if (!list || (list == bad && isfinite(value))) continue;
            size_t used = strlen(list);
            snprintf(list + used, GYRO_MESSAGE_SIZE - used, "%s%s=%s", used ? ", " : "",
                     v->name, real_text(value, num));
        }
        snprintf(why, sizeof why,
                 "the step from t=%.9g s over %g s gave non-finite outputs (%s) with %s held "
                 "over the step: the inputs or parameters are out of this model's numeric "
                 "range; restore an earlier FMU state with other inputs, or instantiate anew",
                 t, h, bad, held[0] ? held : "no inputs");
        return fail(inst, why);
    }
    inst->time = t + h;
    if (hook == GYRO_HOOK_WARNING) {
        inst_logf(inst, ST_WARNING, "%s", msg);
        return ST_WARNING;
    }
    return ST_OK;
}

Status inst_terminate(Instance *inst) {
    inst->mode = MODE_TERMINATED;
    return ST_OK;
}

Status inst_reset(Instance *inst) {
    apply_start_values(inst);
    return ST_OK;
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
                 v->name, real_text(value, a));
        return 1;
    }
    if (v->causality == GYRO_PARAMETER &&
        !(inst->mode & (MODE_INSTANTIATED | MODE_INITIALIZATION))) {
        const double kept = v->type == GYRO_FLOAT64 ? *(double *)(inst->data + v->offset)
                                                    : *(int32_t *)(inst->data + v->offset);
        snprintf(msg, n, "%s is a fixed parameter and cannot change after initialization "
                 "(kept %s, refused %s): set it before %s, or instantiate anew", v->name,
                 real_text(kept, a), real_text(value, b),
                 inst->fmi_version == 2 ? "fmi2ExitInitializationMode"
                                        : "fmi3ExitInitializationMode");
        return 1;
    }
    if (range_problem(v, value, msg, n)) {
        const double kept = v->type == GYRO_FLOAT64 ? *(double *)(inst->data + v->offset)
                                                    : *(int32_t *)(inst->data + v->offset);
        const size_t used = strlen(msg);
        snprintf(msg + used, n - used, " (kept %s)", real_text(kept, a));
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

/* ---- FMU states ---- */
static StateCopy *own_state(Instance *inst, void *ptr, const char *call) {
    for (StateCopy *s = inst->states; s; s = s->next)
        if (s == ptr && s->magic == STATE_MAGIC) return s;
    inst_logf(inst, ST_ERROR, "%s: %p is not a live FMU state of this instance (freed "
              "already, or another instance's)", call, ptr);
    return NULL;
}

static StateCopy *new_state(Instance *inst) {
    StateCopy *s = calloc(1, sizeof *s + inst->model->data_size);
    if (!s) return NULL;
    s->magic = STATE_MAGIC;
    s->owner = inst;
    s->next = inst->states;
    inst->states = s;
    return s;
}

static void save_into(const Instance *inst, StateCopy *s) {
    s->mode = inst->mode;
    s->start_time = inst->start_time;
    s->time = inst->time;
    memcpy(s->failed, inst->failed, sizeof s->failed);
    memcpy(s->data, inst->data, inst->model->data_size);
}

Status inst_get_state(Instance *inst, void **state) {
    if (!state) {
        inst_logf(inst, ST_ERROR, "get FMU state: NULL pointer for the state");
        return ST_ERROR;
    }
    StateCopy *s;
    if (*state) {
        if (!(s = own_state(inst, *state, "get FMU state"))) return ST_ERROR;
    } else if (!(s = new_state(inst))) {
        inst_logf(inst, ST_ERROR, "get FMU state: out of memory");
        return ST_ERROR;
    }
    save_into(inst, s);
    *state = s;
    return ST_OK;
}

Status inst_set_state(Instance *inst, void *state) {
    StateCopy *s = own_state(inst, state, "set FMU state");
    if (!s) return ST_ERROR;
    inst->mode = s->mode;
    inst->start_time = s->start_time;
    inst->time = s->time;
    memcpy(inst->failed, s->failed, sizeof s->failed);
    memcpy(inst->data, s->data, inst->model->data_size);
    return ST_OK;
}

Status inst_free_state(Instance *inst, void **state) {
    if (!state || !*state) return ST_OK; /* the standard: freeing NULL does nothing */
    if (!own_state(inst, *state, "free FMU state")) return ST_ERROR;
    for (StateCopy **p = &inst->states; *p; p = &(*p)->next)
        if (*p == *state) {
            StateCopy *dead = *p;
            *p = dead->next;
            dead->magic = 0;
            free(dead);
            break;
        }
    *state = NULL;
    return ST_OK;
}

/* Serialized layout: magic (8), version and data size (4 + 4, little endian as the
 * host), token (64), mode (4), start time and time (8 + 8), failed text, model data. */
static size_t serial_size(const Instance *inst) {
    return 8 + 4 + 4 + TOKEN_BYTES + 4 + 16 + GYRO_MESSAGE_SIZE + inst->model->data_size;
}

Status inst_serialized_size(Instance *inst, void *state, size_t *size) {
    if (!own_state(inst, state, "serialized FMU state size")) return ST_ERROR;
    if (!size) return ST_ERROR;
    *size = serial_size(inst);
    return ST_OK;
}

Status inst_serialize(Instance *inst, void *state, unsigned char *out, size_t size) {
    StateCopy *s = own_state(inst, state, "serialize FMU state");
    if (!s) return ST_ERROR;
    if (!out || size < serial_size(inst)) {
        inst_logf(inst, ST_ERROR, "serialize FMU state: buffer of %lu bytes, %lu needed",
                  (unsigned long)size, (unsigned long)serial_size(inst));
        return ST_ERROR;
    }
    const uint32_t version = 1, data_size = (uint32_t)inst->model->data_size;
    const int32_t mode = (int32_t)s->mode;
    char token[TOKEN_BYTES] = {0};
    strncpy(token, inst->model->token, TOKEN_BYTES - 1);
    unsigned char *p = out;
    memcpy(p, SERIAL_MAGIC, 8), p += 8;
    memcpy(p, &version, 4), p += 4;
    memcpy(p, &data_size, 4), p += 4;
    memcpy(p, token, TOKEN_BYTES), p += TOKEN_BYTES;
    memcpy(p, &mode, 4), p += 4;
    memcpy(p, &s->start_time, 8), p += 8;
    memcpy(p, &s->time, 8), p += 8;
    memcpy(p, s->failed, GYRO_MESSAGE_SIZE), p += GYRO_MESSAGE_SIZE;
    memcpy(p, s->data, data_size);
    return ST_OK;
}

/* A parameter or input of a restored state outside its declared range (as set would have
 * refused it): the models trust their variables after initialization. */
static int stored_range_problem(const GyroModel *m, const unsigned char *data, char *msg,
                                size_t n) {
    char why[GYRO_MESSAGE_SIZE];
    for (size_t i = 0; i < m->n_variables; i++) {
        const GyroVariable *v = &m->variables[i];
        if (v->causality == GYRO_OUTPUT) continue;
        const double value = v->type == GYRO_FLOAT64 ? *(const double *)(data + v->offset)
                                                     : *(const int32_t *)(data + v->offset);
        if (range_problem(v, value, why, sizeof why)) {
            snprintf(msg, n, "it holds %.900s", why);
            return 1;
        }
    }
    return 0;
}

Status inst_deserialize(Instance *inst, const unsigned char *in, size_t size, void **state) {
    const size_t need = serial_size(inst);
    const char *why = NULL;
    uint32_t version = 0, data_size = 0;
    int32_t mode = 0;
    char token[TOKEN_BYTES] = {0};
    if (!state || !in) why = "NULL buffer or state pointer";
    else if (size != need) why = "its size is not this model's";
    else {
        memcpy(&version, in + 8, 4);
        memcpy(&data_size, in + 12, 4);
        memcpy(token, in + 16, TOKEN_BYTES);
        memcpy(&mode, in + 16 + TOKEN_BYTES, 4);
        token[TOKEN_BYTES - 1] = '\0';
        if (memcmp(in, SERIAL_MAGIC, 8) != 0 || version != 1) why = "it is not a gyro_fmu state";
        else if (data_size != inst->model->data_size || strcmp(token, inst->model->token) != 0)
            why = "it was saved by another model or build";
        else if (mode != MODE_INSTANTIATED && mode != MODE_INITIALIZATION && mode != MODE_STEP &&
                 mode != MODE_TERMINATED && mode != MODE_ERROR)
            why = "its mode is invalid";
    }
    if (why) {
        inst_logf(inst, ST_ERROR, "deserialize FMU state refused: %s (%lu bytes given, %lu "
                  "expected); nothing changed", why, (unsigned long)size, (unsigned long)need);
        return ST_ERROR;
    }
    StateCopy *s = new_state(inst);
    if (!s) {
        inst_logf(inst, ST_ERROR, "deserialize FMU state: out of memory");
        return ST_ERROR;
    }
    const unsigned char *p = in + 16 + TOKEN_BYTES + 4;
    s->mode = (Mode)mode;
    memcpy(&s->start_time, p, 8), p += 8;
    memcpy(&s->time, p, 8), p += 8;
    memcpy(s->failed, p, GYRO_MESSAGE_SIZE), p += GYRO_MESSAGE_SIZE;
    s->failed[GYRO_MESSAGE_SIZE - 1] = '\0';
    memcpy(s->data, p, data_size);
    char msg[GYRO_MESSAGE_SIZE];
    msg[0] = '\0';
    if (!(isfinite(s->time) && isfinite(s->start_time)))
        snprintf(msg, sizeof msg, "its times are not finite");
    else if (s->mode == MODE_STEP && stored_range_problem(inst->model, s->data, msg, sizeof msg)) {
        /* msg says which parameter or input */
    } else if (s->mode == MODE_STEP && inst->model->restored &&
             inst->model->restored(s->data, msg, sizeof msg) == GYRO_HOOK_ERROR) {
        /* msg says why */
    }
    if (msg[0]) {
        void *dead = s;
        inst_free_state(inst, &dead);
        inst_logf(inst, ST_ERROR, "deserialize FMU state refused: %s; nothing changed", msg);
        return ST_ERROR;
    }
    *state = s;
    return ST_OK;
}

Status inst_unsupported(Instance *inst, const char *call) {
    inst_logf(inst, ST_ERROR, "%s is not supported by this FMU (see its model description's "
              "capability flags)", call);
    return ST_ERROR;
}

/* ---- resource URIs ---- */
static int hex(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

char *decode_file_uri(const char *uri) {
    if (!uri) return NULL;
    const char *p = uri;
    if (strncmp(p, "file://", 7) == 0) {
        p += 7;
        if (strncmp(p, "localhost/", 10) == 0) p += 9;
    } else if (strncmp(p, "file:", 5) == 0) {
        p += 5;
    }
#ifdef _WIN32
    if (p[0] == '/' && p[1] && (p[2] == ':' || (p[2] == '%' && p[3] == '3'))) p++; /* /C:/ */
#endif
    char *out = malloc(strlen(p) + 1);
    if (!out) return NULL;
    char *q = out;
    while (*p) {
        if (p[0] == '%' && hex(p[1]) >= 0 && hex(p[2]) >= 0) {
            *q++ = (char)(hex(p[1]) * 16 + hex(p[2]));
            p += 3;
        } else {
            *q++ = *p++;
        }
    }
    *q = '\0';
    return out;
}
