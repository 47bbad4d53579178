/* The FMI layer's instance: registry of live instances, logging, the life cycle and its
 * state machine, resource URIs. Values are in instance_values.c, FMU states in
 * instance_states.c (instance_internal.h: what they share). */
#include "instance.h"
#include "instance_internal.h"

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

Status inst_exit_initialization(Instance *inst) {
    const GyroModel *m = inst->model;
    char msg[GYRO_MESSAGE_SIZE], why[GYRO_MESSAGE_SIZE + 64];
    for (size_t i = 0; i < m->n_variables; i++) {
        const GyroVariable *v = &m->variables[i];
        if (v->causality == GYRO_OUTPUT) continue;
        const double value = v->type == GYRO_FLOAT64 ? *(double *)(inst->data + v->offset)
                                                     : *(int32_t *)(inst->data + v->offset);
        if (inst_range_problem(v, value, msg, sizeof msg)) {
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
                     v->name, gyro_real_text(value, num));
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
