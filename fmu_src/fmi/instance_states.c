/* The FMI layer's FMU states: copies owned by their instance (checked on every use), and
 * their serialized form (magic, version, size, the model's token, mode, times, failure
 * text, model data), refused whole when it is not this model's or holds values set would
 * have refused. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "instance.h"
#include "instance_internal.h"

#define SERIAL_MAGIC "GYROFMU\x01"
#define TOKEN_BYTES 64

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
        if (inst_range_problem(v, value, why, sizeof why)) {
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
