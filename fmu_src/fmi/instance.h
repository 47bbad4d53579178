/* The FMI layer's instance, written once for FMI 2.0 and 3.0 Co-Simulation and every
 * model. fmi2.c and fmi3.c only translate their API into these calls. Every call checks
 * the instance and the state machine first: a call the standard does not allow in the
 * current state returns an error with a logged reason and changes nothing. */
#ifndef GYRO_INSTANCE_H
#define GYRO_INSTANCE_H

#include <stddef.h>
#include <stdint.h>

#include "model.h"

/* Same numbers as fmi2Status and fmi3Status. */
typedef enum { ST_OK = 0, ST_WARNING = 1, ST_DISCARD = 2, ST_ERROR = 3, ST_FATAL = 4 } Status;

typedef enum {
    MODE_INSTANTIATED = 1,
    MODE_INITIALIZATION = 2,
    MODE_STEP = 4,
    MODE_TERMINATED = 8,
    MODE_ERROR = 16,   /* a step or the initialization failed: reset, restore or free */
    MODE_FATAL = 32
} Mode;

typedef struct Instance Instance;
typedef void (*LogFunction)(Instance *inst, Status status, const char *category,
                            const char *message);

typedef struct StateCopy StateCopy;

struct Instance {
    uint32_t magic;
    int fmi_version;             /* 2 or 3 */
    const GyroModel *model;
    char *name;
    char *resources;             /* decoded resource folder, may be NULL */
    LogFunction log;
    void *log_env;               /* fmi2 callbacks or fmi3 environment */
    void *log_fn;
    int logging_on;
    Mode mode;
    double start_time, time;
    char failed[GYRO_MESSAGE_SIZE]; /* why the instance is in MODE_ERROR; "" otherwise */
    StateCopy *states;           /* live FMU states of this instance */
    unsigned char *data;         /* the model's struct, model->data_size bytes */
};

/* Allocate, register and set the start values; NULL (after logging through log) on
 * failure. */
Instance *inst_new(const GyroModel *model, int fmi_version, const char *name,
                   const char *token, const char *resources, LogFunction log, void *log_fn,
                   void *log_env, int logging_on);
/* Free a live instance; a pointer that is not one is ignored (a double free). */
void inst_free(void *ptr);
/* The instance behind ptr if it is live and `call` allowed in one of `modes`; else NULL
 * (logged when the instance is live). */
Instance *inst_check(void *ptr, const char *call, unsigned modes);

void inst_logf(Instance *inst, Status status, const char *fmt, ...);

Status inst_enter_initialization(Instance *inst, double start_time);
Status inst_exit_initialization(Instance *inst);
Status inst_do_step(Instance *inst, double t, double h);
Status inst_terminate(Instance *inst);
Status inst_reset(Instance *inst);

Status inst_get_float64(Instance *inst, const uint32_t vr[], size_t n, double values[]);
Status inst_set_float64(Instance *inst, const uint32_t vr[], size_t n, const double values[]);
Status inst_get_int32(Instance *inst, const uint32_t vr[], size_t n, int32_t values[]);
Status inst_set_int32(Instance *inst, const uint32_t vr[], size_t n, const int32_t values[]);

/* FMU states: copies owned by the instance, checked on every use. */
Status inst_get_state(Instance *inst, void **state);
Status inst_set_state(Instance *inst, void *state);
Status inst_free_state(Instance *inst, void **state);
Status inst_serialized_size(Instance *inst, void *state, size_t *size);
Status inst_serialize(Instance *inst, void *state, unsigned char *out, size_t size);
Status inst_deserialize(Instance *inst, const unsigned char *in, size_t size, void **state);

Status inst_unsupported(Instance *inst, const char *call);

/* Decode a file: URI (percent-encoding, file:///C:/ on Windows) into a path; NULL on
 * failure. The caller frees it. */
char *decode_file_uri(const char *uri);

#endif
